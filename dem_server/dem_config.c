/* dem_config.c — the DEM scene from its config section (processes.<name>):
 * reads the keys, then calls down to the bed builder (dem_bed.c) and the model
 * (dem_model.c); nothing calls back into it. */
#include "dem_server/dem_internal.h"

#include <float.h>
#include <stdio.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Defaults of keys a section may leave out. */
#define DEM_DEFAULT_GRAVITY_Z (-9.81)         /* m/s^2, standard gravity along -z */
#define DEM_DEFAULT_OVERLAP_TOLERANCE 0.01   /* initial overlap allowed, of the smaller radius */
#define DEM_DEFAULT_MAX_OVERLAP_RATIO 0.5    /* overlap/radius that stops a run as unstable */
#define DEM_DEFAULT_DT_FRACTION 0.1          /* dt / T_R: the low end of common practice, 0.1-0.2 */
#define DEM_MIN_NORMAL_SQ 1e-30              /* squared length below which a wall normal is zero */

/* "pairs": [{"materials": [a, b], "restitution", "friction", "rolling_friction"}]:
 * the values of a material pair (both orders); a value left out keeps the
 * mean of the two materials'. */
typedef struct pair_props {
  double e, mu, mu_roll;
} pair_props;

typedef struct pair_table {
  pair_props p[DEM_MAX_MATERIALS][DEM_MAX_MATERIALS];
  uint8_t seen[DEM_MAX_MATERIALS][DEM_MAX_MATERIALS];
} pair_table;

static int read_pair(dem_model *m, proto_cfg *c, int index, void *ctx) {
  pair_table *t = ctx;
  pair_props (*props)[DEM_MAX_MATERIALS] = t->p;
  uint8_t (*seen)[DEM_MAX_MATERIALS] = t->seen;
  (void)index;
  double ab[2];
  int n = 0;
  if (proto_cfg_vec(c, "materials", PROTO_REQUIRED, ab, 2, 2, &n)) return -1;
  int k[2];
  for (int q = 0; q < 2; q++) {
    k[q] = (int)ab[q];
    if (ab[q] != k[q] || k[q] < 0 || k[q] >= m->n_materials)
      return proto_fail(c->err, "%s.materials[%d]: %g is not a material index in [0, %d)", c->path, q, ab[q],
                        m->n_materials);
  }
  if (seen[k[0]][k[1]])
    return proto_fail(c->err, "%s.materials: pair [%d, %d] given twice", c->path, k[0], k[1]);
  seen[k[0]][k[1]] = seen[k[1]][k[0]] = 1;
  pair_props p = props[k[0]][k[1]];
  if (proto_cfg_num(c, "restitution", PROTO_OPTIONAL, 1e-6, 1.0, &p.e) ||
      proto_cfg_num(c, "friction", PROTO_OPTIONAL, 0.0, 1e3, &p.mu) ||
      proto_cfg_num(c, "rolling_friction", PROTO_OPTIONAL, 0.0, 1e3, &p.mu_roll))
    return -1;
  props[k[0]][k[1]] = props[k[1]][k[0]] = p;
  return proto_cfg_end(c);
}

static int read_material(proto_cfg *c, dem_material *mt) {
  if (proto_cfg_num(c, "density", PROTO_REQUIRED, 1e-300, 1e300, &mt->density) ||
      proto_cfg_num(c, "E", PROTO_REQUIRED, 1e-300, 1e300, &mt->E) ||
      proto_cfg_num_below(c, "nu", PROTO_REQUIRED, 0.0, 0.5, &mt->nu))
    return -1;
  mt->G = mt->E / (2.0 * (1.0 + mt->nu));
  if (proto_cfg_num(c, "G", PROTO_OPTIONAL, 1e-300, 1e300, &mt->G) ||
      proto_cfg_num(c, "restitution", PROTO_REQUIRED, 1e-6, 1.0, &mt->restitution) ||
      proto_cfg_num(c, "friction", PROTO_REQUIRED, 0.0, 1e3, &mt->friction) ||
      proto_cfg_num(c, "rolling_friction", PROTO_OPTIONAL, 0.0, 1e3, &mt->rolling_friction))
    return -1;
  return proto_cfg_end(c);
}

/* Iterates a required/optional list of objects: calls fn on each element. */
typedef int (*elem_fn)(dem_model *m, proto_cfg *elem, int index, void *ctx);
static int each_object(dem_model *m, proto_cfg *c, const char *key, proto_need need,
                       elem_fn fn, void *ctx, proto_err *err) {
  const cJSON *list = proto_cfg_raw(c, key, need);
  char p[320];
  proto_cfg_subpath(c, key, -1, p, sizeof p);
  if (!list) return need == PROTO_REQUIRED ? -1 : 0;
  if (!cJSON_IsArray(list)) return proto_fail(err, "%s: expected a list", p);
  int i = 0;
  for (const cJSON *e = list->child; e; e = e->next, i++) {
    proto_cfg elem;
    proto_cfg_subpath(c, key, i, p, sizeof p);
    if (proto_cfg_open(&elem, e, p, err) || fn(m, &elem, i, ctx)) return -1;
  }
  return i;
}

static int material_index(dem_model *m, proto_cfg *c, int *out) {
  int64_t k = 0;
  if (proto_cfg_int(c, "material", PROTO_OPTIONAL, 0, m->n_materials - 1, &k)) return -1;
  *out = (int)k;
  return 0;
}

static int read_material_elem(dem_model *m, proto_cfg *c, int i, void *ctx) {
  (void)ctx;
  if (i >= DEM_MAX_MATERIALS)
    return proto_fail(c->err, "%s: at most %d materials", c->path, DEM_MAX_MATERIALS);
  m->n_materials = i + 1;
  return read_material(c, &m->mat[i]);
}

static int read_particle(dem_model *m, proto_cfg *c, int i, void *ctx) {
  (void)ctx;
  double r = 0;
  int mat = 0, fix = 0;
  if (proto_cfg_vec(c, "x", PROTO_REQUIRED, &m->x0[3 * i], 3, 3, NULL) ||
      proto_cfg_vec(c, "v", PROTO_OPTIONAL, &m->v0[3 * i], 3, 3, NULL) ||
      proto_cfg_vec(c, "omega", PROTO_OPTIONAL, &m->omega0[3 * i], 3, 3, NULL) ||
      proto_cfg_num(c, "r", PROTO_REQUIRED, -DBL_MAX, DBL_MAX, &r) ||
      material_index(m, c, &mat) ||
      proto_cfg_bool(c, "fix_rotation", PROTO_OPTIONAL, &fix))
    return -1;
  if (!(r > 0)) return proto_fail(c->err, "%s.r: radius must be > 0 (got %g)", c->path, r);
  m->radius[i] = r;
  m->material[i] = mat;
  m->fix_rotation[i] = (uint8_t)fix;
  return proto_cfg_end(c);
}

/* "prepare": {"friction": MU, "rolling_friction": MUR (default 0)}: the laws
 * while the bed settles (dem.h dem_prep; dem_bed_settle). */
static int read_prepare(dem_model *m, proto_cfg *c, dem_prep *p) {
  const cJSON *j = proto_cfg_raw(c, "prepare", PROTO_OPTIONAL);
  *p = (dem_prep){0, 0, 0};
  if (!j) return 0;
  char path[320];
  proto_cfg_subpath(c, "prepare", -1, path, sizeof path);
  if (!cJSON_IsObject(j))
    return proto_fail(c->err, "%s: expected an object {\"friction\": MU, \"rolling_friction\": MUR}", path);
  proto_cfg pc;
  p->on = 1;
  if (proto_cfg_open(&pc, j, path, c->err) ||
      proto_cfg_num(&pc, "friction", PROTO_REQUIRED, 0.0, DEM_PREP_FRICTION_MAX, &p->friction) ||
      proto_cfg_num(&pc, "rolling_friction", PROTO_OPTIONAL, 0.0, DEM_PREP_FRICTION_MAX, &p->rolling) ||
      proto_cfg_end(&pc))
    return -1;
  return dem_prep_check(m, p, path, c->err);
}

/* "substrate": {"diameter": D, "depth": H, "spread": S (default 0),
 * "settle_first": B (default false)}: coarser grains under the paper's layers
 * (dem_bed_substrate), settled alone before the layers when B
 * (dem_bed_presettle). */
static int read_substrate(proto_cfg *c, dem_bed_spec *b, int *first) {
  const cJSON *j = proto_cfg_raw(c, "substrate", PROTO_OPTIONAL);
  if (!j) return 0;
  char path[320];
  proto_cfg_subpath(c, "substrate", -1, path, sizeof path);
  if (!cJSON_IsObject(j))
    return proto_fail(c->err, "%s: expected an object {\"diameter\": D, \"depth\": H, \"spread\": S, "
                      "\"settle_first\": B}", path);
  proto_cfg sc;
  double d = 0, h = 0, spread = 0;
  if (proto_cfg_open(&sc, j, path, c->err) || proto_cfg_num(&sc, "diameter", PROTO_REQUIRED, 1e-5, 10.0, &d) ||
      proto_cfg_num(&sc, "depth", PROTO_REQUIRED, 0.0, 100.0, &h) ||
      proto_cfg_num(&sc, "spread", PROTO_OPTIONAL, 0.0, 10.0, &spread) ||
      proto_cfg_bool(&sc, "settle_first", PROTO_OPTIONAL, first) || proto_cfg_end(&sc))
    return -1;
  if (!(spread < 0.5 * d))
    return proto_fail(c->err, "%s.spread: %g m must be below half the diameter (%g m)", path, spread, 0.5 * d);
  return dem_bed_substrate(b, d, spread, h, path, c->err);
}

static int read_bed(dem_model *m, proto_cfg *c, dem_model_config *ex) {
  dem_bed_spec b;
  double scale = 1.0, seed = 1;
  if (proto_cfg_num(c, "scale", PROTO_OPTIONAL, 1e-6, 10.0, &scale)) return -1;
  dem_bed_paper(&b, scale);
  int mat = 0;
  if (proto_cfg_vec(c, "size", PROTO_OPTIONAL, b.size, 2, 2, NULL) ||
      material_index(m, c, &mat) ||
      proto_cfg_num(c, "gap", PROTO_OPTIONAL, 0.0, 1.0, &b.gap) ||
      proto_cfg_num(c, "seed", PROTO_OPTIONAL, 0, 4e9, &seed) ||
      proto_cfg_num(c, "settle_ke_per_grain", PROTO_OPTIONAL, 0.0, 1e9, &ex->settle_ke) ||
      proto_cfg_num(c, "settle_max_steps", PROTO_OPTIONAL, 0.0, 1e9, &ex->settle_steps) ||
      proto_cfg_str(c, "save", PROTO_OPTIONAL, ex->save_bed, sizeof ex->save_bed) ||
      read_prepare(m, c, &ex->prep))
    return -1;
  if (b.size[0] <= 0 || b.size[1] <= 0)
    return proto_fail(c->err, "%s.size: must be positive", c->path);
  if (read_substrate(c, &b, &ex->substrate_first)) return -1;
  if (ex->prep.on && !(ex->settle_steps > 0))
    return proto_fail(c->err, "%s.prepare: needs settle_max_steps > 0 (the preparation's laws act while the "
                      "bed settles)", c->path);
  b.material = mat;
  b.seed = (uint64_t)seed;
  char gen[16];
  if (proto_cfg_str(c, "generate", PROTO_REQUIRED, gen, sizeof gen)) return -1;
  if (strcmp(gen, "bed") != 0)
    return proto_fail(c->err, "%s.generate: unknown generator '%s' (expected \"bed\")", c->path, gen);
  if (proto_cfg_end(c)) return -1;
  return dem_bed_place(m, &b, c->err);
}

static int read_particles(dem_model *m, proto_cfg *top, dem_model_config *ex, proto_err *err) {
  const cJSON *p = proto_cfg_raw(top, "particles", PROTO_REQUIRED);
  char path[320];
  proto_cfg_subpath(top, "particles", -1, path, sizeof path);
  if (!p) return -1;
  if (cJSON_IsArray(p)) {
    if (dem_model_alloc_grains(m, cJSON_GetArraySize(p), err)) return -1;
    return each_object(m, top, "particles", PROTO_REQUIRED, read_particle, NULL, err) < 0 ? -1 : 0;
  }
  proto_cfg c;
  if (proto_cfg_open(&c, p, path, err)) return -1;
  if (cJSON_GetObjectItemCaseSensitive(p, "file")) {
    /* "state": "continue" (default: the bed's saved state, if it has one,
     * continues the run that saved it; dem_bed_continue) or "positions" */
    static const char *const modes[] = {"continue", "positions", NULL};
    int mode = 0;
    char *file = ex->bed_file;
    if (proto_cfg_str(&c, "file", PROTO_REQUIRED, file, sizeof ex->bed_file) ||
        proto_cfg_enum(&c, "state", PROTO_OPTIONAL, modes, &mode) || proto_cfg_end(&c))
      return -1;
    ex->bed_positions = mode == 1;
    if (dem_bed_load(m, file, err)) return proto_wrap(err, "%s.file", path);
    for (int i = 0; i < m->n_grains; i++)
      if (m->material[i] < 0 || m->material[i] >= m->n_materials)
        return proto_fail(err, "%s.file: grain %d has material %d, only %d defined", path, i,
                          (int)m->material[i], m->n_materials);
    return 0;
  }
  return read_bed(m, &c, ex);
}

static void unit(double *n) {
  double l = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  n[0] /= l; n[1] /= l; n[2] /= l;
}

static int add_plane(dem_model *m, const double *p, const double *n, int mat, proto_err *err,
                     const char *path) {
  if (m->n_planes >= DEM_MAX_PLANES)
    return proto_fail(err, "%s: more than %d wall planes", path, DEM_MAX_PLANES);
  dem_plane *pl = &m->planes[m->n_planes++];
  memcpy(pl->point, p, sizeof pl->point);
  memcpy(pl->normal, n, sizeof pl->normal);
  unit(pl->normal);
  pl->material = mat;
  pl->wall = m->n_walls;
  return 0;
}

static int read_mesh(dem_model *m, proto_cfg *c, dem_wall *w) {
  const cJSON *nodes = proto_cfg_raw(c, "nodes", PROTO_REQUIRED);
  const cJSON *tris = proto_cfg_raw(c, "triangles", PROTO_REQUIRED);
  if (!nodes || !tris) return -1;
  if (!cJSON_IsArray(nodes) || !cJSON_IsArray(tris))
    return proto_fail(c->err, "%s.nodes/triangles: expected lists", c->path);
  int nn = cJSON_GetArraySize(nodes), nt = cJSON_GetArraySize(tris);
  double *x = malloc(sizeof(double) * 3 * (size_t)(nn ? nn : 1));
  int32_t *t = malloc(sizeof(int32_t) * 3 * (size_t)(nt ? nt : 1));
  int i = 0, rc = 0;
  for (const cJSON *e = nodes->child; e && !rc; e = e->next, i++)
    for (int k = 0; k < 3; k++) {
      const cJSON *v = cJSON_GetArrayItem(e, k);
      if (cJSON_GetArraySize(e) != 3 || !cJSON_IsNumber(v) || !isfinite(v->valuedouble)) {
        rc = proto_fail(c->err, "%s.nodes[%d]: expected 3 finite numbers", c->path, i);
        break;
      }
      x[3 * i + k] = v->valuedouble;
    }
  i = 0;
  for (const cJSON *e = tris->child; e && !rc; e = e->next, i++)
    for (int k = 0; k < 3; k++) {
      const cJSON *v = cJSON_GetArrayItem(e, k);
      if (cJSON_GetArraySize(e) != 3 || !cJSON_IsNumber(v) || !(v->valuedouble >= 0) ||
          v->valuedouble >= nn || v->valuedouble != floor(v->valuedouble)) {
        rc = proto_fail(c->err, "%s.triangles[%d]: expected 3 node indices in [0, %d)", c->path, i, nn);
        break;
      }
      t[3 * i + k] = v->valueint;
    }
  double vel[3] = {0, 0, 0};
  if (!rc) rc = proto_cfg_vec(c, "velocity", PROTO_OPTIONAL, vel, 3, 3, NULL);
  if (!rc && m->n_meshes >= DEM_MAX_MESHES)
    rc = proto_fail(c->err, "%s: more than %d meshes", c->path, DEM_MAX_MESHES);
  if (rc) { free(x); free(t); return -1; }
  dem_mesh *me = &m->meshes[m->n_meshes];
  memset(me, 0, sizeof *me);
  me->n_nodes = nn; me->n_tri = nt; me->x0 = x; me->tri = t;
  memcpy(me->velocity, vel, sizeof vel);
  me->material = w->material;
  me->wall = m->n_walls;
  w->mesh = m->n_meshes++;
  return 0;
}

static int read_wall(dem_model *m, proto_cfg *c, int i, void *ctx) {
  (void)ctx;
  static const char *const kinds[] = {"plane", "box", "mesh", NULL};
  int kind = 0;
  if (i >= DEM_MAX_WALLS) return proto_fail(c->err, "%s: at most %d walls", c->path, DEM_MAX_WALLS);
  dem_wall *w = &m->walls[i];
  memset(w, 0, sizeof *w);
  if (proto_cfg_enum(c, "type", PROTO_REQUIRED, kinds, &kind) || material_index(m, c, &w->material))
    return -1;
  w->kind = (dem_wall_kind)kind;
  w->plane0 = m->n_planes;
  w->mesh = -1;
  if (w->kind == DEM_WALL_PLANE) {
    double p[3], n[3];
    if (proto_cfg_vec(c, "point", PROTO_REQUIRED, p, 3, 3, NULL) ||
        proto_cfg_vec(c, "normal", PROTO_REQUIRED, n, 3, 3, NULL))
      return -1;
    if (n[0] * n[0] + n[1] * n[1] + n[2] * n[2] < DEM_MIN_NORMAL_SQ)
      return proto_fail(c->err, "%s.normal: must not be zero", c->path);
    if (add_plane(m, p, n, w->material, c->err, c->path)) return -1;
  } else if (w->kind == DEM_WALL_BOX) {
    int open_top = 0;
    if (proto_cfg_vec(c, "lo", PROTO_REQUIRED, w->lo, 3, 3, NULL) ||
        proto_cfg_vec(c, "hi", PROTO_REQUIRED, w->hi, 3, 3, NULL) ||
        proto_cfg_bool(c, "open_top", PROTO_OPTIONAL, &open_top))
      return -1;
    for (int d = 0; d < 3; d++) {
      if (!(w->hi[d] > w->lo[d])) return proto_fail(c->err, "%s.hi: must exceed lo in every axis", c->path);
      double n[3] = {0, 0, 0};
      n[d] = 1;
      if (add_plane(m, w->lo, n, w->material, c->err, c->path)) return -1;
      n[d] = -1;
      if (!(d == 2 && open_top) && add_plane(m, w->hi, n, w->material, c->err, c->path)) return -1;
    }
  } else if (read_mesh(m, c, w)) {
    return -1;
  }
  w->nplanes = m->n_planes - w->plane0;
  m->n_walls = i + 1;
  return proto_cfg_end(c);
}

/* sleep.distance: one number for x, y and z, or [x, y, z] (each 0 to 1e6 m). */
static int read_distance(proto_cfg *c, double d[3]) {
  const cJSON *j = cJSON_GetObjectItemCaseSensitive(c->obj, "distance");
  if (!j || cJSON_IsNumber(j)) {
    if (proto_cfg_num(c, "distance", PROTO_OPTIONAL, 0.0, 1e6, &d[0])) return -1;
    d[1] = d[2] = d[0];
    return 0;
  }
  char p[320];
  proto_cfg_subpath(c, "distance", -1, p, sizeof p);
  if (!cJSON_IsArray(j) || cJSON_GetArraySize(j) != 3)
    return proto_fail(c->err, "%s: expected a length in m or [x, y, z] (3 lengths)", p);
  if (proto_cfg_vec(c, "distance", PROTO_OPTIONAL, d, 3, 3, NULL)) return -1;
  for (int k = 0; k < 3; k++)
    if (!(d[k] >= 0 && d[k] <= 1e6))
      return proto_fail(c->err, "%s[%d]: %g is outside [0, 1e6] m", p, k, d[k]);
  return 0;
}

/* "sleep": false | true (defaults) | {"velocity", "time", "distance", "overlap", "displacement",
 * "wake_velocity", "force", "halo", "test_steps"}. */
static int read_sleep(proto_cfg *c, dem_sleep_config *sl) {
  const cJSON *j = proto_cfg_raw(c, "sleep", PROTO_OPTIONAL);
  *sl = (dem_sleep_config){0, DEM_SLEEP_VELOCITY, DEM_SLEEP_TIME, DEM_SLEEP_OVERLAP,
                           {DEM_SLEEP_DISTANCE, DEM_SLEEP_DISTANCE, DEM_SLEEP_DISTANCE},
                           DEM_SLEEP_DISPLACEMENT, DEM_WAKE_FACTOR * DEM_SLEEP_VELOCITY, DEM_SLEEP_FORCE,
                           DEM_SLEEP_HALO, DEM_REGION_STEPS};
  if (!j || cJSON_IsFalse(j)) return 0;
  sl->on = 1;
  if (cJSON_IsTrue(j)) return 0;
  sl->wake_velocity = -1; /* from velocity, unless given */
  char p[320];
  proto_cfg_subpath(c, "sleep", -1, p, sizeof p);
  if (!cJSON_IsObject(j)) return proto_fail(c->err, "%s: expected true, false or an object", p);
  proto_cfg sc;
  if (proto_cfg_open(&sc, j, p, c->err) ||
      proto_cfg_num(&sc, "velocity", PROTO_OPTIONAL, 1e-12, 1e3, &sl->velocity) ||
      proto_cfg_num(&sc, "time", PROTO_OPTIONAL, 0.0, 1e6, &sl->time) ||
      read_distance(&sc, sl->distance) ||
      proto_cfg_num(&sc, "overlap", PROTO_OPTIONAL, 0.0, 1.0, &sl->overlap) ||
      proto_cfg_num(&sc, "displacement", PROTO_OPTIONAL, 0.0, 1e6, &sl->displacement) ||
      proto_cfg_num(&sc, "wake_velocity", PROTO_OPTIONAL, 1e-12, 1e3, &sl->wake_velocity) ||
      proto_cfg_num(&sc, "force", PROTO_OPTIONAL, 0.0, 1e6, &sl->force) ||
      proto_cfg_num(&sc, "halo", PROTO_OPTIONAL, 0.0, 1.0, &sl->halo)) /* one cell: dem_asleep_near's reach */
    return -1;
  int64_t every = sl->test_steps; /* the default: with every region update */
  if (proto_cfg_int(&sc, "test_steps", PROTO_OPTIONAL, DEM_REGION_STEPS, 1000000, &every)) return -1;
  if (every % DEM_REGION_STEPS)
    return proto_fail(c->err, "%s.test_steps: %lld is not a multiple of %d (the tests come with the region's "
                      "update)", p, (long long)every, DEM_REGION_STEPS);
  sl->test_steps = (int)every;
  if (sl->wake_velocity < 0) sl->wake_velocity = DEM_WAKE_FACTOR * sl->velocity;
  else if (sl->wake_velocity < sl->velocity)
    return proto_fail(c->err, "%s.wake_velocity: %g m/s is below velocity %g m/s (a grain that may fall asleep "
                      "would wake its neighbours)", p, sl->wake_velocity, sl->velocity);
  return proto_cfg_end(&sc);
}

int dem_model_from_json(dem_model *m, const cJSON *section, const char *path, proto_err *err) {
  memset(m, 0, sizeof *m);
  snprintf(m->key_path, sizeof m->key_path, "%s", path);
  dem_model_config *ex = &m->cfg;
  proto_cfg c;
  char exec[512];
  double g[3] = {0, 0, DEM_DEFAULT_GRAVITY_Z};
  if (proto_cfg_open(&c, section, path, err) ||
      proto_cfg_str(&c, "exec", PROTO_OPTIONAL, exec, sizeof exec))
    goto fail;
  if (each_object(m, &c, "materials", PROTO_REQUIRED, read_material_elem, NULL, err) < 0) goto fail;
  if (m->n_materials == 0) {
    proto_fail(err, "%s.materials: at least one material is needed", path);
    goto fail;
  }
  /* pair values: the mean of the two materials' unless "pairs" says */
  pair_table pt;
  memset(&pt, 0, sizeof pt);
  pair_props (*props)[DEM_MAX_MATERIALS] = pt.p;
  for (int a = 0; a < m->n_materials; a++)
    for (int b = 0; b < m->n_materials; b++) {
      const dem_material *ma = &m->mat[a], *mb = &m->mat[b];
      props[a][b] = (pair_props){0.5 * (ma->restitution + mb->restitution), 0.5 * (ma->friction + mb->friction),
                                 0.5 * (ma->rolling_friction + mb->rolling_friction)};
    }
  if (each_object(m, &c, "pairs", PROTO_OPTIONAL, read_pair, &pt, err) < 0) goto fail;
  int limit_force = 0;
  if (proto_cfg_bool(&c, "limit_force", PROTO_OPTIONAL, &limit_force)) goto fail;
  m->limit_force = limit_force;
  if (proto_cfg_bool(&c, "surface_couple", PROTO_OPTIONAL, &m->surface_couple)) goto fail;
  for (int a = 0; a < m->n_materials; a++)
    for (int b = 0; b < m->n_materials; b++) {
      dem_pair_law_set(&m->mat[a], &m->mat[b], props[a][b].e, props[a][b].mu, props[a][b].mu_roll, limit_force, &m->law[a][b]);
      if (m->law[a][b].mu_roll > 0) m->has_rolling = 1;
    }
  int64_t threads = 0, surf = 0;
  int unsafe = 0, orientation = 0;
  m->overlap_tolerance = DEM_DEFAULT_OVERLAP_TOLERANCE;
  m->max_overlap_ratio = DEM_DEFAULT_MAX_OVERLAP_RATIO;
  ex->dt_fraction = DEM_DEFAULT_DT_FRACTION;
  ex->skin = -1;
  if (proto_cfg_vec(&c, "gravity", PROTO_OPTIONAL, g, 3, 3, NULL) ||
      proto_cfg_num(&c, "dt", PROTO_OPTIONAL, 0.0, 1.0, &ex->dt_given) ||
      proto_cfg_num(&c, "dt_fraction", PROTO_OPTIONAL, 1e-6, 10.0, &ex->dt_fraction) ||
      proto_cfg_num(&c, "skin", PROTO_OPTIONAL, 0.0, 1.0, &ex->skin) ||
      proto_cfg_num(&c, "overlap_tolerance", PROTO_OPTIONAL, 0.0, 1.0, &m->overlap_tolerance) ||
      proto_cfg_num(&c, "max_overlap_ratio", PROTO_OPTIONAL, 1e-6, 1.0, &m->max_overlap_ratio) ||
      proto_cfg_threads(&c, "threads", &threads) || read_sleep(&c, &m->sleep) ||
      proto_cfg_int(&c, "surface_material", PROTO_OPTIONAL, 0, m->n_materials - 1, &surf) ||
      proto_cfg_bool(&c, "unsafe_dt", PROTO_OPTIONAL, &unsafe) ||
      proto_cfg_bool(&c, "orientation", PROTO_OPTIONAL, &orientation))
    goto fail;
  memcpy(m->gravity, g, sizeof g);
  m->threads = (int)threads;
  m->surface_material = (int)surf;
  m->unsafe_dt = unsafe;
  m->orientation = orientation;
  if (each_object(m, &c, "walls", PROTO_OPTIONAL, read_wall, NULL, err) < 0) goto fail;
  if (read_particles(m, &c, ex, err) || proto_cfg_end(&c)) goto fail;
  if (m->n_grains == 0) {
    proto_fail(err, "%s.particles: no grains", path);
    goto fail;
  }
  double rmin = DBL_MAX;
  for (int i = 0; i < m->n_grains; i++)
    if (m->radius[i] < rmin) rmin = m->radius[i];
  m->rayleigh_time = dem_model_rayleigh(m);
  m->skin = ex->skin >= 0 ? ex->skin : 0.5 * rmin;
  double dt;
  /* a substrate settles alone before the layers land on it (dem_bed_presettle) */
  if (dem_model_dt(m, 0.0, &dt, err) == 0 && dem_bed_presettle(m, err) == 0) return 0;
fail:
  dem_model_free(m);
  return -1;
}
