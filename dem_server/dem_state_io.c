/* dem_state_io.c — the whole dynamic state of a run as named arrays
 * ("state.<x>"), and back: for implicit-coupling rollback (export at the start
 * of a coupling step, import to redo it) and for checkpoint/restart files.
 * Importing into a state made by dem_state_init() from the same model and
 * stepping on is bitwise identical to never having stopped: the arrays hold
 * the grains in slot order with their permutation (`id`), the neighbour list
 * with its springs and the reference positions that decide the next rebuild,
 * the plane and mesh contact springs with their keys, the mesh nodes, the
 * clock and the last forces (the next half kick uses them). Everything else in
 * the work struct is scratch or recomputed each step. Not the step s->dt: the
 * importing state keeps its own, which its coupling step decides
 * (dem_state_set_dt). A saved bed (dem_bed.c) holds the same arrays: a run
 * from it continues the run that settled it. `state.model` holds the model's
 * fingerprint by part (grains, materials, walls, meshes, skin, sleep), so a
 * refusal names what differs, and two differences are let through (sleep
 * added; other meshes that no grain touches: `tolerated`). */
#include "dem_server/dem_internal.h"

#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

_Static_assert(sizeof(int) == 4, "neighbour-list indices travel as i4");

#define IO_FORMAT 3 /* bump when the set or meaning of the arrays changes (2: state.model; 3: friction out of it) */
/* IO_C_MESH_FLAGS: bit k = nodes of mesh k set since the list build, bit
 * DEM_MAX_MESHES = lists to rebuild (the rebuild schedule decides the sleep
 * "near" flags, so it travels too) */
enum { IO_C_FORMAT, IO_C_MODEL, IO_C_STEP, IO_C_REBUILDS, IO_C_CONTACTS, IO_C_SLEEPING, IO_C_MESH_FLAGS, IO_NCOUNTERS };
enum { IO_S_T, IO_S_KE, IO_S_ELASTIC, IO_S_OVERLAP, IO_NSCALARS };
#define IO_MAX 40 /* the arrays of one export (PROTO_MAX_ARRAYS) */
/* The parts of the model fingerprint (state.model), named in a refusal. */
enum { IO_M_GRAINS, IO_M_MATERIALS, IO_M_WALLS, IO_M_MESHES, IO_M_SKIN, IO_M_SLEEP, IO_NPARTS };
static const char *const io_part_name[IO_NPARTS] = {
    [IO_M_GRAINS] = "grains (count, radii, materials, fixed rotation)",
    [IO_M_MATERIALS] = "materials (density, stiffness, restitution; pair values; limit_force)",
    [IO_M_WALLS] = "walls (planes: point, normal, material)",
    [IO_M_MESHES] = "meshes (node and triangle counts, triangles, material; the coupled surface included)",
    [IO_M_SKIN] = "skin",
    [IO_M_SLEEP] = "sleep (on or off)"};
_Static_assert(IO_NPARTS <= (int)(sizeof ((struct dem_work *)0)->io_model / sizeof(int64_t)),
               "io_model holds the parts");

typedef struct io_entry {
  const char *name;
  proto_dtype dtype;
  int ndim;
  int64_t shape[PROTO_MAX_NDIM];
  void *data;
  int optional; /* may be missing from a state with no grain asleep: then zero */
  int sleep;    /* the active block's: missing from a state saved with sleep off (then zero: all awake) */
} io_entry;

static const size_t io_size[] = {[PROTO_F8] = 8, [PROTO_I4] = 4, [PROTO_I8] = 8, [PROTO_U1] = 1};

static void add(io_entry *e, int *n, const char *name, proto_dtype dt, void *data, int ndim,
                int64_t a, int64_t b, int64_t c) {
  e[*n] = (io_entry){name, dt, ndim, {a, b, c}, data, 0, 0};
  (*n)++;
}

static size_t entry_bytes(const io_entry *e) {
  size_t k = io_size[e->dtype];
  for (int d = 0; d < e->ndim; d++) k *= (size_t)e->shape[d];
  return k;
}

static int64_t total_nodes(const dem_model *m) {
  int64_t t = 0;
  for (int mi = 0; mi < m->n_meshes; mi++) t += m->meshes[mi].n_nodes;
  return t;
}

/* The arrays of a state whose neighbour list holds npairs pairs. */
static int layout(const dem_model *m, dem_state *s, int64_t npairs, io_entry *e) {
  struct dem_work *w = s->work;
  const int64_t n = s->n, K = DEM_MESH_SLOTS, nodes = total_nodes(m);
  int c = 0;
  add(e, &c, PROTO_P_STATE "counters", PROTO_I8, w->io_counters, 1, IO_NCOUNTERS, 0, 0);
  add(e, &c, PROTO_P_STATE "model", PROTO_I8, w->io_model, 1, IO_NPARTS, 0, 0);
  add(e, &c, PROTO_P_STATE "scalars", PROTO_F8, w->io_scalars, 1, IO_NSCALARS, 0, 0);
  add(e, &c, PROTO_P_STATE "id", PROTO_I4, s->id, 1, n, 0, 0);
  add(e, &c, PROTO_P_STATE "x", PROTO_F8, s->x, 2, n, 3, 0);
  add(e, &c, PROTO_P_STATE "v", PROTO_F8, s->v, 2, n, 3, 0);
  add(e, &c, PROTO_P_STATE "omega", PROTO_F8, s->omega, 2, n, 3, 0);
  add(e, &c, PROTO_P_STATE "q", PROTO_F8, s->q, 2, n, 4, 0);
  add(e, &c, PROTO_P_STATE "force", PROTO_F8, s->force, 2, n, 3, 0);
  add(e, &c, PROTO_P_STATE "torque", PROTO_F8, s->torque, 2, n, 3, 0);
  add(e, &c, PROTO_P_STATE "x_ref", PROTO_F8, w->x_ref, 2, n, 3, 0);
  add(e, &c, PROTO_P_STATE "nl_start", PROTO_I4, w->nl_start, 1, n + 1, 0, 0);
  add(e, &c, PROTO_P_STATE "nl_j", PROTO_I4, w->nl_j, 1, npairs, 0, 0);
  add(e, &c, PROTO_P_STATE "nl_shear", PROTO_F8, w->nl_shear, 2, npairs, 3, 0);
  add(e, &c, PROTO_P_STATE "pair_touch", PROTO_U1, w->pair_touch, 1, npairs, 0, 0);
  add(e, &c, PROTO_P_STATE "wall_force", PROTO_F8, s->wall_force, 2, m->n_walls, 3, 0);
  if (m->n_planes > 0) {
    add(e, &c, PROTO_P_STATE "plane_mask", PROTO_I8, w->plane_mask, 1, n, 0, 0);
    add(e, &c, PROTO_P_STATE "plane_touch", PROTO_I8, w->plane_touch, 1, n, 0, 0);
    add(e, &c, PROTO_P_STATE "wall_shear", PROTO_F8, w->wall_shear, 3, m->n_planes, n, 3);
  }
  if (m->n_meshes > 0) {
    add(e, &c, PROTO_P_STATE "mc_key", PROTO_I8, w->mc_key, 2, n, K, 0);
    add(e, &c, PROTO_P_STATE "mc_mesh", PROTO_U1, w->mc_mesh, 2, n, K, 0);
    add(e, &c, PROTO_P_STATE "mc_shear", PROTO_F8, w->mc_shear, 3, n, K, 3);
    add(e, &c, PROTO_P_STATE "mc_normal", PROTO_F8, w->mc_normal, 3, n, K, 3);
    /* all meshes' nodes one after the other (config order, then the surface) */
    add(e, &c, PROTO_P_STATE "mesh_x", PROTO_F8, w->io_mesh, 2, nodes, 3, 0);
    add(e, &c, PROTO_P_STATE "mesh_v", PROTO_F8, w->io_mesh + 3 * nodes, 2, nodes, 3, 0);
    add(e, &c, PROTO_P_STATE "mesh_force", PROTO_F8, w->io_mesh + 6 * nodes, 2, nodes, 3, 0);
    add(e, &c, PROTO_P_STATE "mesh_xref", PROTO_F8, w->io_mesh + 9 * nodes, 2, nodes, 3, 0);
  }
  const int sleep0 = c;
  if (m->sleep.on) {
    add(e, &c, PROTO_P_STATE "asleep", PROTO_U1, w->asleep, 1, n, 0, 0);
    add(e, &c, PROTO_P_STATE "rest", PROTO_I4, w->rest, 1, n, 0, 0);
    add(e, &c, PROTO_P_STATE "near", PROTO_U1, w->near, 1, n, 0, 0);
    add(e, &c, PROTO_P_STATE "rest_x", PROTO_F8, w->rest_x, 2, n, 3, 0);
    /* the force rule's book (dem_sleep_push.c), by grain id, not slot: absent
     * from the states of earlier versions, which is exact when no grain is
     * asleep (a settled bed: a bed settles all awake) */
    add(e, &c, PROTO_P_STATE "push", PROTO_F8, w->push, 2, n, DEM_PUSH_REC, 0);
    e[c - 1].optional = 1;
  }
  /* ---- the active block (dem_sleep.c): region and the grid of the last full
   * rebuild, which the asleep grains are sorted by (owner: the sleep code) ---- */
  if (m->sleep.on) add(e, &c, PROTO_P_STATE "active", PROTO_F8, w->io_active, 1, DEM_IO_ACTIVE, 0, 0);
  /* ---- end of the active block ---- */
  for (int k = sleep0; k < c; k++) e[k].sleep = 1;
  return c;
}

/* FNV-1a over what a state's arrays depend on and what a continued run
 * needs unchanged: grains, materials, walls, mesh topology, skin (the list's
 * validity), sleep on or off. Not dt, gravity nor the sleep thresholds (a
 * restart may change them), nor the sliding and rolling friction of the
 * materials and pairs: a tangential spring is a displacement whose force the
 * Coulomb limit caps at every evaluation (dem_force.c), and rolling carries
 * no state, so other friction values act from the next step on, as another
 * gravity does (a pair-friction study from one settled bed). Fields one by
 * one: struct padding is not hashed. */
static uint64_t fnv(uint64_t h, const void *p, size_t n) {
  const unsigned char *b = p;
  for (size_t i = 0; i < n; i++) h = (h ^ b[i]) * 0x100000001b3ull;
  return h;
}
#define FNV0 0xcbf29ce484222325ull
#define FNV_VAL(h, v) fnv((h), &(v), sizeof(v))

/* The fingerprint's sleep part: on (1) or off (0). */
static int64_t sleep_part(int on) { return (int64_t)FNV_VAL(FNV0, on); }

static void model_parts(const dem_model *m, int64_t *part) {
  const size_t n = (size_t)m->n_grains;
  uint64_t h = FNV_VAL(FNV0, m->n_grains);
  h = fnv(h, m->radius, n * sizeof *m->radius);
  h = fnv(h, m->material, n * sizeof *m->material);
  part[IO_M_GRAINS] = (int64_t)fnv(h, m->fix_rotation, n);
  h = FNV_VAL(FNV0, m->n_materials);
  for (int a = 0; a < m->n_materials; a++) {
    const dem_material *mt = &m->mat[a];
    const double v[] = {mt->density, mt->E, mt->nu, mt->G, mt->restitution};
    h = fnv(h, v, sizeof v);
    for (int b = 0; b < m->n_materials; b++) {
      const dem_pair_law *l = &m->law[a][b];
      const double lv[] = {l->Estar, l->Gstar, l->beta, l->damp_n, l->damp_t};
      h = fnv(h, lv, sizeof lv);
      h = FNV_VAL(h, l->clamp);
    }
  }
  part[IO_M_MATERIALS] = (int64_t)FNV_VAL(h, m->limit_force);
  h = FNV_VAL(FNV0, m->n_planes);
  for (int p = 0; p < m->n_planes; p++) {
    h = fnv(h, m->planes[p].point, sizeof m->planes[p].point);
    h = fnv(h, m->planes[p].normal, sizeof m->planes[p].normal);
    h = FNV_VAL(h, m->planes[p].material);
  }
  part[IO_M_WALLS] = (int64_t)FNV_VAL(h, m->n_walls);
  h = FNV_VAL(FNV0, m->n_meshes);
  for (int mi = 0; mi < m->n_meshes; mi++) {
    const dem_mesh *me = &m->meshes[mi];
    h = FNV_VAL(h, me->n_nodes);
    h = FNV_VAL(h, me->n_tri);
    h = fnv(h, me->tri, 3 * (size_t)me->n_tri * sizeof *me->tri);
    h = FNV_VAL(h, me->material);
  }
  part[IO_M_MESHES] = (int64_t)h;
  part[IO_M_SKIN] = (int64_t)FNV_VAL(FNV0, m->skin);
  /* sleep on or off: the set of arrays. Not its thresholds: they decide only
   * which grains fall asleep or wake from now on, as dt and gravity decide
   * only the steps from now on (a saved bed serves runs that differ in them) */
  part[IO_M_SLEEP] = sleep_part(m->sleep.on);
}

static int64_t model_fingerprint(const int64_t *part) {
  return (int64_t)fnv(FNV0, part, sizeof(int64_t) * IO_NPARTS);
}

/* The two differences a state may carry into another model; 0 if any other
 * part differs (or the parts do not give the fingerprint: damaged).
 * - sleep off -> on (*from_awake): every grain is awake in the state, so the
 *   active block's arrays it lacks are those of a run whose grains never
 *   slept (zero: awake, no steps at rest, the region not yet placed; the next
 *   rebuild is a full one). A bed settled all awake then serves runs with and
 *   without the active region. Not the other way: a state with grains asleep
 *   needs the active block.
 * - other meshes (*new_meshes): allowed only when no grain touches a mesh in
 *   the state (the caller checks 'state.mc_key'), so that no spring belongs to
 *   a triangle of the old meshes; the grains' state does not depend on a mesh
 *   they do not touch, and the meshes start where this model puts them. A bed
 *   settled under one tread then serves runs with another tread mesh (a mesh
 *   refinement study). */
static int tolerated(const dem_model *m, const int64_t *theirs, const int64_t *mine, int64_t their_print,
                     int *from_awake, int *new_meshes) {
  *from_awake = *new_meshes = 0;
  if (their_print != model_fingerprint(theirs)) return 0;
  for (int k = 0; k < IO_NPARTS; k++) {
    if (theirs[k] == mine[k]) continue;
    if (k == IO_M_SLEEP && m->sleep.on && theirs[k] == sleep_part(0)) *from_awake = 1;
    else if (k == IO_M_MESHES) *new_meshes = 1;
    else return 0;
  }
  return 1;
}

/* The grains touching a mesh in a state: its nonzero 'state.mc_key' entries
 * (none when it has no meshes); -1 if the array is not i8. */
static int64_t mesh_contacts(const proto_msg *in) {
  const proto_array *a = proto_msg_find(in, PROTO_P_STATE "mc_key");
  if (!a) return 0;
  if (a->dtype != PROTO_I8) return -1;
  int64_t n = 0;
  for (size_t k = 0; k < a->nbytes / sizeof(int64_t); k++) {
    int64_t key;
    memcpy(&key, (const char *)a->data + k * sizeof key, sizeof key);
    n += key != 0;
  }
  return n;
}

int dem_state_other_meshes(const dem_model *m, const proto_msg *in) {
  const proto_array *a = proto_msg_find(in, PROTO_P_STATE "model");
  if (!a || a->dtype != PROTO_I8 || a->nbytes != sizeof(int64_t) * IO_NPARTS) return 0;
  int64_t mine[IO_NPARTS], theirs[IO_NPARTS];
  model_parts(m, mine);
  memcpy(theirs, a->data, sizeof theirs);
  return theirs[IO_M_MESHES] != mine[IO_M_MESHES];
}

/* An array of the meshes' part of a state ("state.mc_*", "state.mesh_*"). */
static int mesh_array(const char *name) {
  return !strncmp(name, PROTO_P_STATE "mc_", strlen(PROTO_P_STATE "mc_")) ||
         !strncmp(name, PROTO_P_STATE "mesh_", strlen(PROTO_P_STATE "mesh_"));
}

/* "grains, walls" into out: the parts in which two fingerprints differ. */
static void parts_differ(const int64_t *a, const int64_t *b, char *out, size_t cap) {
  size_t len = 0;
  out[0] = 0;
  for (int k = 0; k < IO_NPARTS; k++)
    if (a[k] != b[k] && len < cap)
      len += (size_t)snprintf(out + len, cap - len, "%s%s", len ? "; " : "", io_part_name[k]);
}

/* Scratch for the mesh nodes, allocated once. */
static int io_scratch(const dem_model *m, dem_state *s, proto_err *err) {
  struct dem_work *w = s->work;
  if (m->n_meshes == 0 || w->io_mesh) return 0;
  w->io_mesh = malloc(sizeof(double) * 12 * (size_t)total_nodes(m) + 1);
  return w->io_mesh ? 0 : proto_fail(err, "out of memory for the state export");
}

int dem_state_export(const dem_model *m, const dem_state *cs, proto_msg *out, proto_err *err) {
  dem_state *s = (dem_state *)cs; /* writes the export scratch, and sums the force rule's */
  struct dem_work *w = s->work;      /* book if the step did not (dem_push_fresh: the same bits) */
  dem_push_fresh(m, s);
  if (io_scratch(m, s, err)) return -1;
  w->io_counters[IO_C_FORMAT] = IO_FORMAT;
  dem_sleep_export(m, s); /* the active block's "state.active" */
  model_parts(m, w->io_model);
  w->io_counters[IO_C_MODEL] = model_fingerprint(w->io_model);
  w->io_counters[IO_C_STEP] = s->step;
  w->io_counters[IO_C_REBUILDS] = s->rebuilds;
  w->io_counters[IO_C_CONTACTS] = s->contacts;
  w->io_counters[IO_C_SLEEPING] = s->sleeping;
  w->io_scalars[IO_S_T] = s->t;
  w->io_scalars[IO_S_KE] = s->kinetic_energy;
  w->io_scalars[IO_S_ELASTIC] = s->elastic_energy;
  w->io_scalars[IO_S_OVERLAP] = s->max_overlap_ratio;
  const int64_t nodes = total_nodes(m);
  int64_t off = 0;
  for (int mi = 0; mi < m->n_meshes; mi++) {
    const size_t b = sizeof(double) * 3 * (size_t)m->meshes[mi].n_nodes;
    memcpy(w->io_mesh + 3 * off, s->mesh_x[mi], b);
    memcpy(w->io_mesh + 3 * (nodes + off), s->mesh_v[mi], b);
    memcpy(w->io_mesh + 3 * (2 * nodes + off), s->mesh_force[mi], b);
    memcpy(w->io_mesh + 3 * (3 * nodes + off), w->mesh_xref[mi], b);
    off += m->meshes[mi].n_nodes;
  }
  int64_t flags = (int64_t)w->lists_dirty << DEM_MAX_MESHES;
  for (int mi = 0; mi < m->n_meshes; mi++) flags |= (int64_t)w->mesh_set[mi] << mi;
  w->io_counters[IO_C_MESH_FLAGS] = flags;
  io_entry e[IO_MAX];
  const int ne = layout(m, s, w->nl_start[s->n], e);
  for (int k = 0; k < ne; k++)
    if (proto_msg_add(out, e[k].name, e[k].dtype, e[k].ndim, e[k].shape, e[k].data))
      return proto_fail(err, "state export: message full at '%s' (%d arrays of at most %d)", e[k].name,
                        ne, PROTO_MAX_ARRAYS);
  return 0;
}

/* ------------------------------------------------------------------ import */

static const void *get(const proto_msg *in, const io_entry *e, proto_err *err) {
  const proto_array *a = proto_msg_get(in, e->name, e->dtype, e->ndim, e->shape, err);
  if (!a) return NULL;
  if (a->nbytes != entry_bytes(e)) {
    proto_fail(err, "state import: array '%s' has %zu bytes, expected %zu", e->name, a->nbytes,
               entry_bytes(e));
    return NULL;
  }
  return a->data;
}

/* Contents that later steps index with: a bad file must not crash a run. */
static int check_contents(const dem_model *m, dem_state *s, const void *const *src, const io_entry *e,
                          int ne, proto_err *err) {
  const int n = s->n;
  const int32_t *id = NULL, *start = NULL, *nj = NULL;
  const uint8_t *touch = NULL, *mesh = NULL, *asleep = NULL, *near = NULL;
  const int32_t *rest = NULL;
  const double *push = NULL;
  const int64_t *key = NULL, *mask = NULL, *ptouch = NULL, *cnt = NULL;
  int64_t npairs = 0;
  for (int k = 0; k < ne; k++) {
    const char *nm = e[k].name;
    if (!strcmp(nm, PROTO_P_STATE "id")) id = src[k];
    else if (!strcmp(nm, PROTO_P_STATE "nl_start")) start = src[k];
    else if (!strcmp(nm, PROTO_P_STATE "nl_j")) { nj = src[k]; npairs = e[k].shape[0]; }
    else if (!strcmp(nm, PROTO_P_STATE "pair_touch")) touch = src[k];
    else if (!strcmp(nm, PROTO_P_STATE "mc_mesh")) mesh = src[k];
    else if (!strcmp(nm, PROTO_P_STATE "mc_key")) key = src[k];
    else if (!strcmp(nm, PROTO_P_STATE "plane_mask")) mask = src[k];
    else if (!strcmp(nm, PROTO_P_STATE "plane_touch")) ptouch = src[k];
    else if (!strcmp(nm, PROTO_P_STATE "counters")) cnt = src[k];
    else if (!strcmp(nm, PROTO_P_STATE "asleep")) asleep = src[k];
    else if (!strcmp(nm, PROTO_P_STATE "rest")) rest = src[k];
    else if (!strcmp(nm, PROTO_P_STATE "near")) near = src[k];
    else if (!strcmp(nm, PROTO_P_STATE "push")) push = src[k];
  }
  int *seen = s->work->old_of; /* scratch outside a rebuild */
  memset(seen, 0, sizeof(int) * (size_t)n);
  for (int i = 0; i < n; i++) {
    if (id[i] < 0 || id[i] >= n || seen[id[i]]++)
      return proto_fail(err, "state import: 'state.id' is not a permutation of 0..%d (slot %d: %d)", n - 1, i,
                        (int)id[i]);
  }
  if (start[0] != 0)
    return proto_fail(err, "state import: 'state.nl_start'[0] = %d, expected 0", (int)start[0]);
  for (int i = 0; i < n; i++) {
    if (start[i + 1] < start[i] || start[i + 1] > npairs)
      return proto_fail(err, "state import: 'state.nl_start' is not a non-decreasing list up to %lld at %d",
                        (long long)npairs, i + 1);
    for (int32_t k = start[i]; k < start[i + 1]; k++)
      if (nj[k] <= i || nj[k] >= n)
        return proto_fail(err, "state import: 'state.nl_j'[%d] = %d outside (%d, %d)", (int)k, (int)nj[k], i, n);
  }
  for (int64_t k = 0; k < npairs; k++)
    if (touch[k] > 1) return proto_fail(err, "state import: 'state.pair_touch'[%lld] is not 0/1", (long long)k);
  const uint64_t planes = m->n_planes >= 64 ? ~0ull : (1ull << m->n_planes) - 1;
  for (int i = 0; mask && i < n; i++)
    if (((uint64_t)mask[i] & ~planes) || ((uint64_t)ptouch[i] & ~planes))
      return proto_fail(err, "state import: 'state.plane_mask'/'state.plane_touch'[%d] names a plane >= %d", i,
                        m->n_planes);
  for (int64_t k = 0; key && k < (int64_t)n * DEM_MESH_SLOTS; k++)
    if (key[k] != 0 && mesh[k] >= m->n_meshes)
      return proto_fail(err, "state import: 'state.mc_mesh'[%lld] = %d, only %d meshes", (long long)k,
                        (int)mesh[k], m->n_meshes);
  for (int i = 0; asleep && i < n; i++)
    if (asleep[i] > 1 || rest[i] < 0 || near[i] > 1)
      return proto_fail(err, "state import: 'state.asleep'/'state.rest'/'state.near'[%d] = %d/%d/%d (expected 0/1, "
                        ">= 0, 0/1)", i, (int)asleep[i], (int)rest[i], (int)near[i]);
  for (int i = 0; push && i < n; i++) {
    const double st = push[DEM_PUSH_REC * i + DEM_PUSH_STATE];
    if (!(st == 0 || st == 1 || st == 2))
      return proto_fail(err, "state import: 'state.push'[%d] has state %g (expected 0, 1 or 2)", i, st);
  }
  if (cnt[IO_C_STEP] < 0 || cnt[IO_C_REBUILDS] < 0)
    return proto_fail(err, "state import: 'state.counters' has a negative step or rebuild count");
  return 0;
}

int dem_state_import(const dem_model *m, dem_state *s, const proto_msg *in, proto_err *err) {
  struct dem_work *w = s->work;
  const int n = s->n;
  if (n != m->n_grains) return proto_fail(err, "state import: the state does not belong to this model");
  /* the model first: the other shapes mean nothing for another model */
  const io_entry counters = {PROTO_P_STATE "counters", PROTO_I8, 1, {IO_NCOUNTERS}, NULL, 0, 0};
  const int64_t *cnt = get(in, &counters, err);
  if (!cnt) return -1;
  if (cnt[IO_C_FORMAT] != IO_FORMAT)
    return proto_fail(err, "state import: 'state.counters' has format %lld, this dem_server reads %d",
                      (long long)cnt[IO_C_FORMAT], IO_FORMAT);
  int64_t mine[IO_NPARTS];
  model_parts(m, mine);
  int from_awake = 0; /* a state saved with sleep off, continued with sleep on */
  int new_meshes = 0; /* a state without mesh contacts, continued with other meshes */
  if (cnt[IO_C_MODEL] != model_fingerprint(mine)) {
    const io_entry parts = {PROTO_P_STATE "model", PROTO_I8, 1, {IO_NPARTS}, NULL, 0, 0};
    const int64_t *theirs = get(in, &parts, err);
    if (!theirs) return -1;
    if (!tolerated(m, theirs, mine, cnt[IO_C_MODEL], &from_awake, &new_meshes)) {
      char what[512];
      parts_differ(theirs, mine, what, sizeof what);
      return proto_fail(err, "state import: 'state.counters' comes from another model (fingerprint %016llx, "
                        "this model %016llx): %s differ%s",
                        (unsigned long long)cnt[IO_C_MODEL], (unsigned long long)model_fingerprint(mine),
                        what[0] ? what : "'state.model' and 'state.counters'", what[0] ? "" : " (damaged)");
    }
    const int64_t touching = new_meshes ? mesh_contacts(in) : 0;
    if (touching < 0)
      return proto_fail(err, "state import: 'state.mc_key' is not i8");
    if (touching > 0)
      return proto_fail(err, "state import: the meshes (node and triangle counts, triangles, material; the "
                        "coupled surface included) differ from the state's, and %lld grain-mesh contacts of "
                        "the state hold springs on the old triangles (a state serves other meshes only when "
                        "no grain touches a mesh)", (long long)touching);
  }
  const io_entry start = {PROTO_P_STATE "nl_start", PROTO_I4, 1, {n + 1}, NULL, 0, 0};
  const int32_t *st = get(in, &start, err);
  if (!st) return -1;
  const int64_t npairs = st[n];
  if (npairs < 0 || npairs > INT_MAX / 8)
    return proto_fail(err, "state import: 'state.nl_start'[%d] = %lld pairs", n, (long long)npairs);
  if (io_scratch(m, s, err)) return -1;
  io_entry e[IO_MAX];
  const void *src[IO_MAX];
  const int ne = layout(m, s, npairs, e);
  for (int k = 0; k < ne; k++) {
    if (new_meshes && mesh_array(e[k].name)) { /* this model's meshes, no contact on them */
      src[k] = NULL;
      continue;
    }
    if ((e[k].optional || (from_awake && e[k].sleep)) && !proto_msg_find(in, e[k].name)) {
      if (cnt[IO_C_SLEEPING] != 0)
        return proto_fail(err, "state import: '%s' is missing and %lld grains are asleep (a state of an earlier "
                          "version can continue only with every grain awake)", e[k].name,
                          (long long)cnt[IO_C_SLEEPING]);
      src[k] = NULL;
      continue;
    }
    if (!(src[k] = get(in, &e[k], err))) return proto_wrap(err, "state import");
  }
  for (int a = 0; a < in->narrays; a++) {
    const char *nm = in->arrays[a].name;
    int known = strncmp(nm, PROTO_P_STATE, strlen(PROTO_P_STATE)) != 0 || (new_meshes && mesh_array(nm));
    for (int k = 0; k < ne && !known; k++) known = !strcmp(nm, e[k].name);
    if (!known) return proto_fail(err, "state import: unexpected array '%s' (not part of this model's state)", nm);
  }
  if (check_contents(m, s, src, e, ne, err)) return -1;
  /* valid: make room, then copy (the layout again: buffers may have moved) */
  if (dem_neigh_reserve(m, s, (int)npairs, err)) return -1;
  layout(m, s, npairs, e);
  for (int k = 0; k < ne; k++) /* empty entries (no pairs yet) may have no buffer */
    if (entry_bytes(&e[k])) { /* with new meshes: the mesh contacts zero, the nodes' scratch unused */
      if (src[k]) memcpy(e[k].data, src[k], entry_bytes(&e[k]));
      else memset(e[k].data, 0, entry_bytes(&e[k]));
    }
  s->step = cnt[IO_C_STEP];
  s->work->sweep_step = -1; /* x, v are not what the last sweeps left */
  s->rebuilds = cnt[IO_C_REBUILDS];
  s->contacts = cnt[IO_C_CONTACTS];
  s->sleeping = cnt[IO_C_SLEEPING];
  s->t = w->io_scalars[IO_S_T];
  s->kinetic_energy = w->io_scalars[IO_S_KE];
  s->elastic_energy = w->io_scalars[IO_S_ELASTIC];
  s->max_overlap_ratio = w->io_scalars[IO_S_OVERLAP];
  /* what follows from the slot order: the grains' constants and the reverse
   * pair index; the meshes' BVH and candidate lists (the contacts and their
   * order do not depend on them) */
  for (int i = 0; i < n; i++) dem_grain_constants(m, s, i, s->id[i]);
  dem_neigh_reverse(s);
  dem_sleep_count(m, s);
  if (w->wake) memset(w->wake, 0, (size_t)n);
  dem_push_import(m, s); /* the force rule's book */
  if (dem_sleep_partners(m, s, err)) return -1;
  w->have_old = 1;
  const int64_t nodes = total_nodes(m);
  int64_t off = 0;
  for (int mi = 0; mi < m->n_meshes; mi++) {
    const dem_mesh *me = &m->meshes[mi];
    const size_t b = sizeof(double) * 3 * (size_t)me->n_nodes;
    if (new_meshes) { /* the nodes where this state has them (dem_state_init: the model's), no force */
      memset(s->mesh_force[mi], 0, b);
    } else {
      memcpy(s->mesh_x[mi], w->io_mesh + 3 * off, b);
      memcpy(s->mesh_v[mi], w->io_mesh + 3 * (nodes + off), b);
      memcpy(s->mesh_force[mi], w->io_mesh + 3 * (2 * nodes + off), b);
      memcpy(w->mesh_xref[mi], w->io_mesh + 3 * (3 * nodes + off), b);
      off += me->n_nodes;
      dem_mesh_velocities_changed(m, s, mi);
      w->mesh_set[mi] = (uint8_t)(cnt[IO_C_MESH_FLAGS] >> mi & 1);
    }
    if (dem_bvh_build(&w->bvh[mi], s->mesh_x[mi], me->tri, me->n_tri))
      return proto_fail(err, "state import: out of memory for the BVH of mesh %d", mi);
  }
  if (new_meshes) { /* lists and schedule anew; again at the next step, with the sleep flags ("near") */
    if (m->n_meshes > 0 && dem_mesh_lists(m, s, err)) return -1;
    w->lists_dirty = 1;
    return 0;
  }
  w->lists_dirty = (int)(cnt[IO_C_MESH_FLAGS] >> DEM_MAX_MESHES & 1);
  /* the candidate lists from the current positions (a superset until the
   * schedule above, which is the exported one, rebuilds them) */
  return m->n_meshes > 0 ? dem_mesh_lists_build(m, s, err) : 0;
}
