/* dem_bed.c — the soil bed of seed 000 (table 2): three layers of grains,
 * placed without overlap on jittered lattices, settled under gravity
 * (dem_bed_settle: with the preparation's laws first if the config has one,
 * dem_model.c's dem_prep_laws, then the scene's; dem_settle_placed); beds
 * saved to and loaded from HDF5: the grains in model order (x, v, omega, r,
 * material: what dem_bed_load puts into the model) and the whole state
 * (/state: dem_state_export's arrays, which dem_bed_continue imports into a
 * fresh state, so a run from the file continues the one that saved it).
 * Through proto's HDF5 writer and reader. */
#include "dem_server/dem_internal.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define DEM_BED_MAX_OVERLAP "max_overlap" /* dataset: largest overlap when saved */
#define DEM_BED_STATE "/state"             /* group: the state.<x> arrays */
#define DEM_BED_SETTLED "settled_with"     /* dataset: dt, gravity x y z of the saving run */
#define DEM_BED_FRICTION "friction_with"   /* dataset [materials², 2]: each pair's μ, μ_r when saved */
#define DEM_BED_TMP ".tmp"                 /* written under path.tmp, then renamed */

void dem_bed_paper(dem_bed_spec *b, double scale) {
  memset(b, 0, sizeof *b);
  /* 1.0 × 1.0 m, 21 812 grains; diameters 15.6, 7.8, 6.9 ± 0.345 mm, the
   * smallest on top. The paper gives no per-layer counts: equal thirds. */
  const double d[3] = {15.6e-3, 7.8e-3, 6.9e-3}, spread[3] = {0, 0, 0.345e-3};
  const int64_t total = (int64_t)llround(21812 * scale);
  b->n_layers = 3;
  for (int k = 0; k < 3; k++) {
    b->layers[k].diameter = d[k];
    b->layers[k].spread = spread[k];
    b->layers[k].count = total / 3 + (k < total % 3);
  }
  b->size[0] = b->size[1] = 1.0 * sqrt(scale);
  b->gap = 0.5e-3;
  b->seed = 1;
}

/* A layer's lattice: its pitch (the largest grain plus the gap) and the
 * whole cells across the footprint in x and y (capped at DEM_MAX_GRAINS: a
 * footprint of 1e30 m must not overflow an int; more would stay empty). */
static double lattice(const dem_bed_spec *b, double diameter, double spread, int *nx, int *ny) {
  const double a = diameter + spread + b->gap;
  *nx = (int)fmin(b->size[0] / a, (double)DEM_MAX_GRAINS);
  *ny = (int)fmin(b->size[1] / a, (double)DEM_MAX_GRAINS);
  return a;
}

int dem_bed_substrate(dem_bed_spec *b, double diameter, double spread, double depth, const char *what,
                      proto_err *err) {
  const int cap = (int)(sizeof b->layers / sizeof *b->layers);
  if (b->n_layers >= cap)
    return proto_fail(err, "%s: the bed has %d layers already (at most %d)", what, b->n_layers, cap);
  int nx, ny;
  const double a = lattice(b, diameter, spread, &nx, &ny), levels = floor(depth / a);
  if (!(nx >= 1 && ny >= 1))
    return proto_fail(err, "%s.diameter: %g m grains do not fit the %g x %g m footprint", what, diameter, b->size[0],
                      b->size[1]);
  if (!(levels >= 1))
    return proto_fail(err, "%s.depth: %g m holds no level of %g m grains (lattice pitch %g m)", what, depth,
                      diameter, a);
  const double count = (double)nx * ny * levels;
  if (count > (double)DEM_MAX_GRAINS)
    return proto_fail(err, "%s: %.0f grains (at most %lld)", what, count, (long long)DEM_MAX_GRAINS);
  memmove(&b->layers[1], &b->layers[0], sizeof *b->layers * (size_t)b->n_layers);
  b->layers[0] = (dem_bed_layer){
      .diameter = diameter, .spread = spread, .count = (int64_t)count, .substrate = 1};
  b->n_layers++;
  return 0;
}

/* splitmix64: reproducible placement from the seed */
static double uniform(uint64_t *st) {
  uint64_t z = (*st += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  z ^= z >> 31;
  return (double)(z >> 11) * (1.0 / 9007199254740992.0);
}

int dem_bed_place(dem_model *m, const dem_bed_spec *b, proto_err *err) {
  int64_t total = 0;
  for (int k = 0; k < b->n_layers; k++) total += b->layers[k].count;
  if (total <= 0 || total > DEM_MAX_GRAINS)
    return proto_fail(err, "bed: %lld grains (1 to %lld)", (long long)total, (long long)DEM_MAX_GRAINS);
  if (dem_model_alloc_grains(m, (int)total, err)) return -1;
  m->cfg.substrate_grains = b->n_layers > 0 && b->layers[0].substrate ? (int)b->layers[0].count : 0;
  uint64_t shared = b->seed, own = b->seed ^ 0xD1B54A32D192ED03ull;
  double z = 0;
  int i = 0;
  for (int k = 0; k < b->n_layers; k++) {
    const dem_bed_layer *L = &b->layers[k];
    uint64_t *stp = L->substrate ? &own : &shared;
    int nx, ny;
    const double a = lattice(b, L->diameter, L->spread, &nx, &ny);
    if (nx < 1 || ny < 1)
      return proto_fail(err, "bed: footprint %g x %g m smaller than one grain of layer %d",
                        b->size[0], b->size[1], k);
    const double ox = L->substrate ? 0.5 * (b->size[0] - nx * a) : 0, /* a substrate's lattice centred */
        oy = L->substrate ? 0.5 * (b->size[1] - ny * a) : 0;
    for (int64_t c = 0; c < L->count; c++, i++) {
      const int64_t cell = c % ((int64_t)nx * ny), level = c / ((int64_t)nx * ny);
      const int ix = (int)(cell % nx), iy = (int)(cell / nx);
      const double d = L->diameter + L->spread * (2 * uniform(stp) - 1);
      const double jit = 0.45 * (a - d); /* stays inside its lattice cell: no overlap */
      m->x0[3 * i] = ox + (ix + 0.5) * a + jit * (2 * uniform(stp) - 1);
      m->x0[3 * i + 1] = oy + (iy + 0.5) * a + jit * (2 * uniform(stp) - 1);
      m->x0[3 * i + 2] = z + (level + 0.5) * a;
      m->radius[i] = 0.5 * d;
      m->material[i] = b->material;
    }
    const int64_t levels = (L->count + (int64_t)nx * ny - 1) / ((int64_t)nx * ny);
    z += levels * a;
  }
  return 0;
}

/* ------------------------------------------------------------ settling */

/* dem_settle's progress over a span of a longer settling: its fraction of
 * [k0, k0 + n) of `total` steps, under `what` (so a settling of two
 * dem_settle calls, or two settlings, reads 0 to 100 % once each, named). */
typedef struct settle_span {
  dem_progress_fn progress;
  void *ctx;
  const char *what;
  double k0, n, total;
} settle_span;

static void span_progress(void *ctx, double fraction, const char *what) {
  const settle_span *sp = ctx;
  sp->progress(sp->ctx, (sp->k0 + fraction * sp->n) / sp->total, sp->what ? sp->what : what);
}

/* `placed`: the grains start at rest on their lattice, and the KE test waits
 * DEM_SETTLE_MIN_TIME; a bed already settled (the scene's laws after the
 * preparation's) is at rest when it starts, and the test may end it at once. */
static int settle_placed(const dem_model *m, dem_state *s, double ke_per_grain, int64_t max_steps,
                         dem_progress_fn progress, void *ctx, const char *what, int placed, proto_err *err) {
  int64_t n_min = placed ? (int64_t)ceil(DEM_SETTLE_MIN_TIME / s->dt) : 0;
  if (n_min > max_steps) n_min = max_steps;
  settle_span sp = {progress, ctx, what, 0, (double)n_min, fmax((double)max_steps, 1)};
  dem_progress_fn fn = progress ? span_progress : NULL;
  if (n_min > 0 && dem_settle(m, s, 0.0, n_min, fn, &sp, err)) return -1;
  sp.k0 = (double)n_min;
  sp.n = (double)(max_steps - n_min);
  return max_steps > n_min ? dem_settle(m, s, ke_per_grain, max_steps - n_min, fn, &sp, err) : 0;
}

int dem_settle_placed(const dem_model *m, dem_state *s, double ke_per_grain, int64_t max_steps,
                      dem_progress_fn progress, void *ctx, proto_err *err) {
  return settle_placed(m, s, ke_per_grain, max_steps, progress, ctx, NULL, 1, err);
}

/* the preparation's settling if any, then the scene's (dem_bed_settle) */
static int settle_awake(const dem_model *m, dem_state *s, dem_progress_fn progress, void *ctx, int64_t *steps,
                        proto_err *err) {
  const dem_model_config *c = &m->cfg;
  const int64_t k0 = s->step, max_steps = (int64_t)c->settle_steps;
  int rc = 0;
  if (c->prep.on) {
    /* the preparation's laws on a copy: the scene's model is never changed,
     * so nothing after this (the save, the run) can see the preparation's.
     * The copy shares the model's arrays (read only, not freed here). */
    dem_model *prepared = malloc(sizeof *prepared);
    if (!prepared) return proto_fail(err, "%s.particles.prepare: out of memory", m->key_path);
    *prepared = *m;
    dem_prep_laws(prepared, &c->prep);
    rc = settle_placed(prepared, s, c->settle_ke, max_steps, progress, ctx,
                       "settling the bed with the preparation's laws (1 of 2)", 1, err);
    free(prepared);
    if (rc) return proto_wrap(err, "%s.particles.prepare (friction %g, rolling friction %g)", m->key_path,
                              c->prep.friction, c->prep.rolling);
  }
  /* the scene's laws (the springs kept; its Coulomb rule and rolling torques
   * from the next step). After the preparation the bed is at rest (its KE
   * below the threshold): no minimum time, the KE test ends this phase once
   * the new laws leave it so. (The 0.1 s it ran before were a quarter of
   * the sand scene's settling and took the bed's KE from just below the
   * threshold to 25-70x below it: a quieter bed is a lower settle_ke_per_grain;
   * bench/results/sand_calibration.md) */
  if (settle_placed(m, s, c->settle_ke, max_steps, progress, ctx,
                    c->prep.on ? "settling the bed with the scene's laws (2 of 2)" : NULL, !c->prep.on, err))
    return -1;
  if (steps) *steps = s->step - k0;
  s->t = 0;
  s->step = 0;
  s->work->sweep_step = -1; /* the sweeps' steps were the settling's */
  return 0;
}

/* A bed settles with every grain awake: the sleep rules ("sleep") wait for
 * the run. A scene may put grains to sleep that are merely slow (the deep
 * scene's bed creeps at about 1.7 mm/s after settling), and a settling bed
 * is slow long before it is at rest: frozen then, it would keep a packing
 * that is not in equilibrium. */
int dem_bed_settle(const dem_model *m, dem_state *s, dem_progress_fn progress, void *ctx, int64_t *steps,
                   proto_err *err) {
  s->work->settling = 1;
  const int rc = settle_awake(m, s, progress, ctx, steps, err);
  s->work->settling = 0;
  return rc;
}

/* ------------------------------------------------------------------ HDF5 */

/* Dataset "/<name>": n rows of cols columns ([n] when rank is 1). */
static int write_ds(proto_h5 *f, const char *name, proto_dtype dtype, int rank, int64_t n,
                    int64_t cols, const void *data, proto_err *err) {
  proto_array a = {.dtype = dtype, .ndim = rank, .shape = {n, cols}, .data = data,
                   .nbytes = (size_t)(n * cols) * proto_dtype_size(dtype)};
  snprintf(a.name, sizeof a.name, "%s", name);
  return proto_h5_write_array(f, "/", &a, err);
}

/* The grains in model order, the largest overlap, the run's dt and gravity. */
static int save_grains(const dem_model *m, const dem_state *s, proto_h5 *f, double *buf, int32_t *mat,
                       proto_err *err) {
  const int64_t n = s->n;
  dem_gather(s, s->x, 3, buf);
  dem_gather(s, s->v, 3, buf + 3 * n);
  dem_gather(s, s->omega, 3, buf + 6 * n);
  int rc = write_ds(f, "x", PROTO_F8, 2, n, 3, buf, err);
  if (!rc) rc = write_ds(f, "v", PROTO_F8, 2, n, 3, buf + 3 * n, err);
  if (!rc) rc = write_ds(f, "omega", PROTO_F8, 2, n, 3, buf + 6 * n, err);
  dem_gather(s, s->radius, 1, buf);
  if (!rc) rc = write_ds(f, "r", PROTO_F8, 1, n, 1, buf, err);
  for (int i = 0; i < s->n; i++) mat[s->id[i]] = s->material[i];
  if (!rc) rc = write_ds(f, "material", PROTO_I4, 1, n, 1, mat, err);
  const double worst = dem_worst_overlap(m, s);
  if (!rc) rc = write_ds(f, DEM_BED_MAX_OVERLAP, PROTO_F8, 1, 1, 1, &worst, err);
  const double with[4] = {s->dt, m->gravity[0], m->gravity[1], m->gravity[2]};
  if (!rc) rc = write_ds(f, DEM_BED_SETTLED, PROTO_F8, 1, 4, 1, with, err);
  double mu[2 * DEM_MAX_MATERIALS * DEM_MAX_MATERIALS];
  const int nm = m->n_materials;
  for (int a = 0; a < nm; a++)
    for (int b = 0; b < nm; b++) {
      mu[2 * (a * nm + b)] = m->law[a][b].mu;
      mu[2 * (a * nm + b) + 1] = m->law[a][b].mu_roll;
    }
  if (!rc) rc = write_ds(f, DEM_BED_FRICTION, PROTO_F8, 2, nm * nm, 2, mu, err);
  return rc;
}

/* The pairs whose friction the bed was saved with differs from the model's,
 * as "0-1: friction 0.3 -> 1.2; ..." into info->friction (empty: the same,
 * or not recorded). Friction is not in the state's fingerprint
 * (dem_state_io.c): the springs continue, capped by the new limit. */
static int saved_friction(const dem_model *m, proto_h5in *f, dem_bed_info *info, proto_err *err) {
  const int nm = m->n_materials;
  info->friction[0] = 0;
  if (!proto_h5in_exists(f, DEM_BED_FRICTION)) return 0;
  int64_t dims[2] = {nm * nm, 2};
  double *mu = NULL;
  if (proto_h5in_read_f8(f, DEM_BED_FRICTION, 2, dims, 2 * nm * nm, &mu, err))
    return proto_wrap(err, "dataset '%s' (%d materials)", DEM_BED_FRICTION, nm);
  size_t len = 0;
  const size_t cap = sizeof info->friction;
  for (int a = 0; a < nm; a++)
    for (int b = a; b < nm; b++) {
      const double *was = &mu[2 * (a * nm + b)], now[2] = {m->law[a][b].mu, m->law[a][b].mu_roll};
      for (int k = 0; k < 2; k++)
        if (was[k] != now[k] && len < cap)
          len += (size_t)snprintf(info->friction + len, cap - len, "%s%d-%d: %s %g -> %g", len ? "; " : "", a,
                                  b, k ? "rolling friction" : "friction", was[k], now[k]);
    }
  free(mu);
  return 0;
}

/* The state.<x> arrays of dem_state_export under /state. */
static int save_state(const dem_model *m, const dem_state *s, proto_h5 *f, proto_err *err) {
  proto_msg msg = {0};
  proto_msg_reset(&msg, "bed", "state", s->step, s->t);
  int rc = dem_state_export(m, s, &msg, err);
  for (int a = 0; a < msg.narrays && !rc; a++) rc = proto_h5_write_array(f, DEM_BED_STATE, &msg.arrays[a], err);
  proto_msg_free(&msg);
  return rc;
}

int dem_bed_save(const dem_model *m, const dem_state *s, const char *path, proto_err *err) {
  const int64_t n = s->n;
  char tmp[sizeof m->cfg.save_bed + sizeof DEM_BED_TMP];
  if (snprintf(tmp, sizeof tmp, "%s%s", path, DEM_BED_TMP) >= (int)sizeof tmp)
    return proto_fail(err, "%s: path too long for a bed file", path);
  double *buf = malloc(sizeof(double) * 9 * (size_t)n + 1);
  int32_t *mat = malloc(sizeof(int32_t) * (size_t)n + 1);
  proto_h5 *f = buf && mat ? proto_h5_create(tmp, err) : NULL;
  if (!f) {
    free(buf);
    free(mat);
    return buf && mat ? proto_wrap(err, "%s: cannot write the bed", path) : proto_fail(err, "%s: out of memory", path);
  }
  int rc = save_grains(m, s, f, buf, mat, err);
  if (!rc) rc = save_state(m, s, f, err);
  if (proto_h5_close(f, rc ? NULL : err) < 0) rc = -1;
  free(buf);
  free(mat);
  if (!rc && rename(tmp, path) != 0)
    rc = proto_fail(err, "cannot rename %s to %s: %s", tmp, path, strerror(errno));
  if (rc) {
    remove(tmp);
    return proto_wrap(err, "%s: cannot write the bed", path);
  }
  return 0;
}

/* A per-grain dataset of n rows and cols columns ([n] or [n, 1] when cols
 * is 1) into out; optional datasets may be absent. */
static int read_grains(proto_h5in *f, const char *name, int64_t n, int cols, int integer,
                       void *out, int optional, proto_err *err) {
  if (!proto_h5in_exists(f, name))
    return optional ? 0 : proto_fail(err, "%s: dataset '%s' missing", proto_h5in_path(f), name);
  int rank = cols == 1 ? proto_h5in_rank(f, name, err) : 2;
  if (rank < 0) return -1;
  if (rank != 1 && rank != 2) rank = 2; /* the reader names the expected rank */
  int64_t dims[2] = {n, cols};
  void *buf = NULL;
  int rc = integer ? proto_h5in_read_i4(f, name, rank, dims, n * cols, (int32_t **)&buf, err)
                   : proto_h5in_read_f8(f, name, rank, dims, n * cols, (double **)&buf, err);
  if (rc == 0) memcpy(out, buf, (size_t)(n * cols) * (integer ? sizeof(int32_t) : sizeof(double)));
  free(buf);
  return rc;
}

int dem_bed_load(dem_model *m, const char *path, proto_err *err) {
  proto_h5in *f = proto_h5in_open(path, err);
  if (!f) return -1;
  int rc = -1;
  /* the grain count from r, bounded before anything is allocated */
  int rank = proto_h5in_exists(f, "r") ? proto_h5in_rank(f, "r", err) : -1;
  int64_t dims[2] = {-1, 1};
  double *r = NULL;
  if (rank < 0) {
    proto_fail(err, "%s: no dataset 'r' (grain radii)", path);
  } else if (proto_h5in_read_f8(f, "r", rank == 2 ? 2 : 1, dims, DEM_MAX_GRAINS, &r, err) == 0) {
    const int64_t n = dims[0];
    if (n == 0) {
      proto_fail(err, "%s: dataset 'r' holds no grains", path);
    } else if (!dem_model_alloc_grains(m, (int)n, err) &&
               !read_grains(f, "x", n, 3, 0, m->x0, 0, err) &&
               !read_grains(f, "v", n, 3, 0, m->v0, 1, err) &&
               !read_grains(f, "omega", n, 3, 0, m->omega0, 1, err) &&
               !read_grains(f, "material", n, 1, 1, m->material, 1, err) &&
               !read_grains(f, DEM_BED_MAX_OVERLAP, 1, 1, 0, &m->bed_max_overlap, 1, err)) {
      memcpy(m->radius, r, (size_t)n * sizeof(double));
      rc = 0;
      if (!(m->bed_max_overlap >= 0 && m->bed_max_overlap < 1))
        rc = proto_fail(err, "%s: %s = %g (expected a fraction in [0, 1))", path, DEM_BED_MAX_OVERLAP,
                        m->bed_max_overlap);
      for (int i = 0; i < m->n_grains && !rc; i++)
        if (!(m->radius[i] > 0))
          rc = proto_fail(err, "%s: grain %d has radius %g (must be > 0)", path, i, m->radius[i]);
    }
  }
  free(r);
  proto_h5in_close(f);
  return rc;
}

/* ------------------------------------------------------------ continue */

typedef struct state_read {
  proto_h5in *f;
  proto_msg *msg;
  void **bufs;
  proto_err *err;
} state_read;

/* One /state/<name> as stored, into the message (as a checkpoint's). */
static int read_state_array(const char *name, void *ctx) {
  state_read *x = ctx;
  proto_msg *m = x->msg;
  if (m->narrays == PROTO_MAX_ARRAYS)
    return proto_fail(x->err, "%s:%s: more than %d arrays", proto_h5in_path(x->f), DEM_BED_STATE,
                      PROTO_MAX_ARRAYS);
  if (strncmp(name, PROTO_P_STATE, strlen(PROTO_P_STATE)) != 0 ||
      proto_name_check(name, PROTO_NAME_DOTTED, "array name", x->err) < 0)
    return proto_fail(x->err, "%s:%s: its arrays are named %s<x>", proto_h5in_path(x->f), DEM_BED_STATE,
                      PROTO_P_STATE);
  char obj[PROTO_NAME_LEN + sizeof DEM_BED_STATE + 1];
  snprintf(obj, sizeof obj, "%s/%s", DEM_BED_STATE, name);
  if (proto_h5in_read_array(x->f, obj, PROTO_MAX_FRAME_BYTES, &m->arrays[m->narrays], &x->bufs[m->narrays],
                            x->err) < 0)
    return -1;
  m->narrays++;
  return 0;
}

/* The file's grains (model order, /x) are the state's (slot order, by id):
 * a file whose two halves disagree was edited or assembled by hand. */
static int same_positions(const dem_model *m, const dem_state *s, const char *path, proto_err *err) {
  for (int i = 0; i < s->n; i++) {
    const int g = s->id[i];
    if (memcmp(&s->x[3 * (size_t)i], &m->x0[3 * (size_t)g], 3 * sizeof(double)) != 0)
      return proto_fail(err, "%s: grain %d: dataset 'x' and %sstate.x differ (the file was edited?)", path,
                        g, DEM_BED_STATE "/");
  }
  return 0;
}

int dem_bed_continue(const dem_model *m, dem_state *s, dem_bed_info *info, proto_err *err) {
  const char *path = m->cfg.bed_file;
  *info = (dem_bed_info){0, 0, NAN, {NAN, NAN, NAN}, {0}, 0};
  proto_h5in *f = proto_h5in_open(path, err);
  if (!f) return -1;
  info->has_state = proto_h5in_exists(f, DEM_BED_STATE);
  double *with = NULL;
  int64_t dims[1] = {4};
  int rc = 0;
  if (proto_h5in_exists(f, DEM_BED_SETTLED)) {
    rc = proto_h5in_read_f8(f, DEM_BED_SETTLED, 1, dims, 4, &with, err);
    if (!rc) {
      info->dt = with[0];
      memcpy(info->gravity, with + 1, sizeof info->gravity);
    }
    free(with);
  }
  if (!rc) rc = saved_friction(m, f, info, err);
  if (rc || !info->has_state || m->cfg.bed_positions) {
    proto_h5in_close(f);
    return rc;
  }
  proto_msg msg = {0};
  void *bufs[PROTO_MAX_ARRAYS] = {0};
  proto_msg_reset(&msg, "bed", "state", 0, 0);
  state_read x = {f, &msg, bufs, err};
  rc = proto_h5in_list(f, DEM_BED_STATE, read_state_array, &x, err);
  proto_h5in_close(f);
  if (!rc && dem_state_import(m, s, &msg, err)) {
    char why[sizeof err->msg];
    snprintf(why, sizeof why, "%s", err->msg);
    rc = proto_fail(err, "%s: the saved state does not fit this scene: %s (set particles.state = "
                    "\"positions\" to start from the grains' positions only)", path, why);
  }
  if (!rc) rc = same_positions(m, s, path, err);
  if (!rc) info->other_meshes = dem_state_other_meshes(m, &msg);
  const int n = msg.narrays;
  msg.narrays = 0; /* the arrays are ours */
  proto_msg_free(&msg);
  for (int a = 0; a < n; a++) free(bufs[a]);
  info->continued = rc == 0;
  return rc;
}

static int ascending(const void *a, const void *b) {
  const double x = *(const double *)a, y = *(const double *)b;
  return (x > y) - (x < y);
}

void dem_footprint(const double *x, int64_t n, double lo[2], double hi[2]) {
  for (int k = 0; k < 2; k++) lo[k] = n > 0 ? INFINITY : -INFINITY, hi[k] = -lo[k];
  for (int64_t i = 0; i < n; i++)
    for (int k = 0; k < 2; k++) {
      lo[k] = fmin(lo[k], x[3 * i + k]);
      hi[k] = fmax(hi[k], x[3 * i + k]);
    }
}

int dem_bed_top(const dem_state *s, const double lo[2], const double hi[2], double percentile,
                double *top, int *count, proto_err *err) {
  return dem_bed_top_of(s->x, s->radius, s->n, lo, hi, percentile, top, count, err);
}

int dem_bed_top_of(const double *xs, const double *r, int ng, const double lo[2], const double hi[2],
                   double percentile, double *top, int *count, proto_err *err) {
  double *tops = malloc(sizeof(double) * (size_t)(ng > 0 ? ng : 1));
  if (!tops) return proto_fail(err, "out of memory (bed top)");
  int n = 0;
  for (int i = 0; i < ng; i++) {
    const double *x = &xs[3 * (size_t)i];
    if (x[0] >= lo[0] && x[0] <= hi[0] && x[1] >= lo[1] && x[1] <= hi[1])
      tops[n++] = x[2] + r[i];
  }
  *count = n;
  *top = NAN;
  if (n > 0) {
    qsort(tops, (size_t)n, sizeof *tops, ascending);
    /* nearest rank: the smallest value with at least `percentile` % at or below it */
    int rank = (int)ceil(percentile / 100.0 * n);
    *top = tops[rank < 1 ? 0 : rank > n ? n - 1 : rank - 1];
  }
  free(tops);
  return 0;
}
