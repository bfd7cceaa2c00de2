/* blk_config.c — the block model from a processes.<name> config section
 * (keys listed in contact_block/README.md). Every error names the key path. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "contact_block/blk.h"

/* Elements per axis from a scene: the matrix-free solver handles 512 × 512
 * on one core in seconds (bench/results/block.md); the model allows 4096. */
enum { BLK_CFG_GRID_MAX = 4096 };

static int read_grid(blk_model *m, proto_cfg *sec, proto_err *err) {
  proto_cfg c;
  int64_t nx = 20, ny = 20;
  double dx = 1e-3, dy = 1e-3;
  int periodic = 0;
  int r = proto_cfg_child(sec, "grid", PROTO_OPTIONAL, &c);
  if (r < 0) return -1;
  if (r == 0) {
    if (proto_cfg_int(&c, "nx", PROTO_OPTIONAL, 1, BLK_CFG_GRID_MAX, &nx) ||
        proto_cfg_int(&c, "ny", PROTO_OPTIONAL, 1, BLK_CFG_GRID_MAX, &ny) ||
        proto_cfg_num(&c, "dx", PROTO_OPTIONAL, 1e-9, 1.0, &dx) ||
        proto_cfg_num(&c, "dy", PROTO_OPTIONAL, 1e-9, 1.0, &dy) ||
        proto_cfg_bool(&c, "periodic", PROTO_OPTIONAL, &periodic) || proto_cfg_end(&c))
      return -1;
  }
  if (blk_model_init(m, (int)nx, (int)ny, dx, dy, err))
    return proto_wrap(err, "%s.grid", sec->path);
  m->periodic = periodic;
  return 0;
}

static int read_green(blk_model *m, proto_cfg *sec, proto_err *err) {
  proto_cfg c;
  if (proto_cfg_child(sec, "green", PROTO_REQUIRED, &c)) return -1;
  static const char *const kinds[] = {"file", "halfspace", "synthetic", NULL};
  int kind = 0;
  int64_t refine = 1;
  if (proto_cfg_enum(&c, "kind", PROTO_REQUIRED, kinds, &kind) ||
      proto_cfg_int(&c, "refine", PROTO_OPTIONAL, 1, 64, &refine))
    return -1;
  int rc = 0;
  if (kind == 0) {
    char path[1024];
    if (proto_cfg_str(&c, "file", PROTO_REQUIRED, path, sizeof path)) return -1;
    rc = blk_green_load(m, path, err);
    if (!rc && refine > 1) rc = blk_green_refine(m, (int)refine, err);
  } else {
    blk_synth s = {.E = 25e6, .nu = 0.49, .rate = 51200, .Q = 256, .f_mode = 2000,
                   .zeta = 0.1, .beta = 0.25, .tau_fast = 2e-5, .point_sampling = 0};
    static const char *const samplings[] = {"zoh", "point", NULL};
    if (proto_cfg_num(&c, "E", PROTO_OPTIONAL, 1.0, 1e12, &s.E) ||
        proto_cfg_num_below(&c, "nu", PROTO_OPTIONAL, 0.0, 0.5, &s.nu))
      return -1;
    if (kind == 1) {
      rc = blk_green_halfspace(m, s.E, s.nu, err);
    } else {
      int64_t Q = s.Q;
      if (proto_cfg_num(&c, "rate", PROTO_OPTIONAL, 1.0, 1e9, &s.rate) ||
          proto_cfg_int(&c, "samples", PROTO_OPTIONAL, 1, 1 << 20, &Q) ||
          proto_cfg_num(&c, "f_mode", PROTO_OPTIONAL, 1e-3, 1e9, &s.f_mode) ||
          proto_cfg_num_below(&c, "zeta", PROTO_OPTIONAL, 1e-6, 1.0, &s.zeta) ||
          proto_cfg_num(&c, "beta", PROTO_OPTIONAL, 0.0, 1.0, &s.beta) ||
          proto_cfg_num(&c, "tau_fast", PROTO_OPTIONAL, 1e-12, 1.0, &s.tau_fast) ||
          proto_cfg_enum(&c, "sampling", PROTO_OPTIONAL, samplings, &s.point_sampling))
        return -1;
      /* refinement of the synthetic function: regenerate at the finer rate */
      s.rate *= (double)refine;
      s.Q = (int)((Q - 1) * refine + 1);
      rc = blk_green_synthetic(m, &s, err);
    }
  }
  if (rc) return proto_wrap(err, "%s", c.path);
  return proto_cfg_end(&c);
}

/* springs.soften: the thesis' second cure (seed 002 ch. 4.2.2) — the `count`
 * stiffest springs by force at compression `at` softened by `factor`, or,
 * without a factor, exchanged for the next `count` (the thesis: 80 at 9 µm). */
static int read_soften(blk_model *m, proto_cfg *springs, proto_err *err) {
  proto_cfg c;
  int r = proto_cfg_child(springs, "soften", PROTO_OPTIONAL, &c);
  if (r) return r < 0 ? -1 : 0;
  int64_t count = 0;
  double at = 9e-6, factor = 0;
  if (proto_cfg_int(&c, "count", PROTO_REQUIRED, 1, INT32_MAX, &count) ||
      proto_cfg_num(&c, "at", PROTO_OPTIONAL, 1e-12, 1.0, &at) ||
      proto_cfg_num(&c, "factor", PROTO_OPTIONAL, 1e-12, 1.0, &factor) || proto_cfg_end(&c))
    return -1;
  if (blk_springs_soften(m, (int)count, at, factor, err)) return proto_wrap(err, "%s", c.path);
  return 0;
}

static int read_springs(blk_model *m, proto_cfg *sec, proto_err *err) {
  proto_cfg c;
  if (proto_cfg_child(sec, "springs", PROTO_REQUIRED, &c)) return -1;
  static const char *const kinds[] = {"file", "linear", "stiffening", "rigid", NULL};
  int kind = 0, rc = 0;
  if (proto_cfg_enum(&c, "kind", PROTO_REQUIRED, kinds, &kind)) return -1;
  if (kind == 3) {
    rc = blk_springs_rigid(m, err);
  } else if (kind == 0) {
    char path[1024];
    if (proto_cfg_str(&c, "file", PROTO_REQUIRED, path, sizeof path)) return -1;
    rc = blk_springs_load(m, path, err);
  } else if (kind == 1) {
    double k = 0;
    if (proto_cfg_num(&c, "k", PROTO_REQUIRED, 1e-6, 1e15, &k)) return -1;
    rc = blk_springs_linear(m, &k, 0, err);
  } else {
    double k0 = 2e5, d0 = 2e-5, spread = 0.5, d_max = 5e-4;
    int64_t seed = 2, knots = 33;
    if (proto_cfg_num(&c, "k0", PROTO_OPTIONAL, 1e-6, 1e15, &k0) ||
        proto_cfg_num(&c, "d0", PROTO_OPTIONAL, 1e-12, 1.0, &d0) ||
        proto_cfg_num_below(&c, "spread", PROTO_OPTIONAL, 0.0, 1.0, &spread) ||
        proto_cfg_num(&c, "d_max", PROTO_OPTIONAL, 1e-12, 1.0, &d_max) ||
        proto_cfg_int(&c, "seed", PROTO_OPTIONAL, 0, INT64_MAX, &seed) ||
        proto_cfg_int(&c, "knots", PROTO_OPTIONAL, 2, 100000, &knots))
      return -1;
    rc = blk_springs_stiffening(m, k0, d0, spread, (uint64_t)seed, d_max, (int)knots, err);
  }
  if (rc) return proto_wrap(err, "%s", c.path);
  double sigma = 0;
  int64_t lseed = 3;
  int has = proto_cfg_raw(&c, "lognormal", PROTO_OPTIONAL) != NULL;
  if (has && (proto_cfg_num(&c, "lognormal", PROTO_OPTIONAL, 0.0, 10.0, &sigma) ||
              proto_cfg_int(&c, "lognormal_seed", PROTO_OPTIONAL, 0, INT64_MAX, &lseed)))
    return -1;
  if (has && blk_springs_lognormal(m, sigma, (uint64_t)lseed, err))
    return proto_wrap(err, "%s", c.path);
  if (read_soften(m, &c, err)) return -1;
  return proto_cfg_end(&c);
}

static int read_road(blk_model *m, proto_cfg *sec, proto_err *err) {
  proto_cfg c;
  int r = proto_cfg_child(sec, "road", PROTO_OPTIONAL, &c);
  if (r < 0) return -1;
  if (r == 1) return 0; /* flat, or the heights of a springs file */
  static const char *const kinds[] = {"flat", "paraboloid", "random", "springs_file",
                                      "values", "world", NULL};
  int kind = 0, rc = 0;
  if (proto_cfg_enum(&c, "kind", PROTO_OPTIONAL, kinds, &kind) ||
      proto_cfg_num(&c, "z_free", PROTO_OPTIONAL, -1.0, 1.0, &m->z_free))
    return -1;
  if (kind == 1) {
    double R = 0.1;
    if (proto_cfg_num(&c, "radius", PROTO_REQUIRED, 1e-9, 1e9, &R)) return -1;
    rc = blk_road_paraboloid(m, R, err);
  } else if (kind == 2) {
    double rms = 2e-5;
    int64_t seed = 1;
    if (proto_cfg_num(&c, "rms", PROTO_OPTIONAL, 0.0, 1.0, &rms) ||
        proto_cfg_int(&c, "seed", PROTO_OPTIONAL, 0, INT64_MAX, &seed))
      return -1;
    rc = blk_road_random(m, rms, (uint64_t)seed, err);
  } else if (kind == 4) {
    const cJSON *v = proto_cfg_raw(&c, "z", PROTO_REQUIRED);
    if (!v) return -1;
    if (!cJSON_IsArray(v) || cJSON_GetArraySize(v) != m->M)
      return proto_fail(err, "%s.z: expected an array of nx*ny = %d numbers", c.path, m->M);
    int e = 0;
    for (const cJSON *it = v->child; it; it = it->next, e++) {
      if (!cJSON_IsNumber(it))
        return proto_fail(err, "%s.z[%d]: expected number", c.path, e);
      m->z_road[e] = it->valuedouble;
    }
    rc = blk_road_set(m, m->z_road, err);
  } else if (kind == 5) { /* lug_block: the heights follow the lug (blk_road_world) */
    char path[1024] = "";
    if (proto_cfg_str(&c, "file", PROTO_OPTIONAL, path, sizeof path)) return -1;
    if (path[0]) { /* a surface file: no hashed field beside it */
      if (proto_cfg_raw(&c, "rms", PROTO_OPTIONAL) || proto_cfg_raw(&c, "seed", PROTO_OPTIONAL))
        return proto_fail(err, "%s: 'file' gives the road's heights; 'rms' and 'seed' (the "
                          "hashed road's) cannot be given with it", c.path);
      rc = blk_road_world_map(m, path, err);
    } else {
      double rms = 2e-5;
      int64_t seed = 1;
      if (proto_cfg_num(&c, "rms", PROTO_OPTIONAL, 0.0, 1.0, &rms) ||
          proto_cfg_int(&c, "seed", PROTO_OPTIONAL, 0, INT64_MAX, &seed))
        return -1;
      m->road_world = 1, m->road_rms = rms, m->road_seed = (uint64_t)seed;
      blk_road_world(m, 0, 0);
    }
  } else if (kind == 0) {
    for (int e = 0; e < m->M; e++) m->z_road[e] = 0;
  } else if (kind == 3) { /* the springs file's heights, highest point at 0 */
    double top = -INFINITY;
    for (int e = 0; e < m->M; e++) top = fmax(top, m->z_road[e]);
    for (int e = 0; e < m->M; e++) m->z_road[e] -= top;
  }
  if (rc) return proto_wrap(err, "%s", c.path);
  return proto_cfg_end(&c);
}

static int read_adhesion_solver(blk_model *m, proto_cfg *sec) {
  proto_cfg c;
  int r = proto_cfg_child(sec, "adhesion", PROTO_OPTIONAL, &c);
  if (r < 0) return -1;
  if (r == 0 && (proto_cfg_bool(&c, "enabled", PROTO_OPTIONAL, &m->adhesion) ||
                 proto_cfg_num(&c, "release_force", PROTO_OPTIONAL, 1e-12, 1e9,
                               &m->release_force) ||
                 proto_cfg_end(&c)))
    return -1;
  r = proto_cfg_child(sec, "solver", PROTO_OPTIONAL, &c);
  if (r < 0) return -1;
  if (r == 1) return 0;
  /* the order of blk_method and blk_history_kind */
  static const char *const methods[] = {"newton", "line_search", "dual_newton",
                                        "constrained_cg", "auto", NULL};
  static const char *const hist[] = {"fft", "direct", "separable", "auto", NULL};
  int method = (int)m->solver.method, h = (int)m->solver.history;
  int64_t max_iter = m->solver.max_iter, cg_max_iter = m->solver.cg_max_iter;
  if (proto_cfg_enum(&c, "method", PROTO_OPTIONAL, methods, &method) ||
      proto_cfg_int(&c, "max_iter", PROTO_OPTIONAL, 1, 100000, &max_iter) ||
      proto_cfg_int(&c, "cg_max_iter", PROTO_OPTIONAL, 1, 10000000, &cg_max_iter) ||
      proto_cfg_bool(&c, "tangent", PROTO_OPTIONAL, &m->solver.tangent) ||
      proto_cfg_num(&c, "tol", PROTO_OPTIONAL, 1e-30, 1.0, &m->solver.tol) ||
      proto_cfg_bool(&c, "quasi_static", PROTO_OPTIONAL, &m->solver.quasi_static) ||
      proto_cfg_enum(&c, "history", PROTO_OPTIONAL, hist, &h) ||
      proto_cfg_num(&c, "tail_tol", PROTO_OPTIONAL, 0.0, 1.0, &m->solver.tail_tol) ||
      proto_cfg_bool(&c, "reuse_jacobian", PROTO_OPTIONAL, &m->solver.reuse_jacobian) ||
      proto_cfg_num(&c, "max_force", PROTO_OPTIONAL, 1e-12, 1e300, &m->solver.max_force) ||
      proto_cfg_end(&c))
    return -1;
  m->solver.method = (blk_method)method;
  m->solver.history = (blk_history_kind)h;
  m->solver.max_iter = (int)max_iter;
  m->solver.cg_max_iter = (int)cg_max_iter;
  return 0;
}

int blk_model_from_config(blk_model *m, const cJSON *section, const char *key_path,
                          proto_err *err) {
  proto_cfg sec;
  memset(m, 0, sizeof *m);
  if (proto_cfg_open(&sec, section, key_path, err)) return -1;
  char exec[256];
  if (proto_cfg_str(&sec, "exec", PROTO_OPTIONAL, exec, sizeof exec)) return -1;
  if (read_grid(m, &sec, err) || read_springs(m, &sec, err) || read_road(m, &sec, err) ||
      read_green(m, &sec, err) || read_adhesion_solver(m, &sec) || proto_cfg_end(&sec))
    return -1;
  if (blk_model_check(m, err)) return proto_wrap(err, "%s", key_path);
  return 0;
}
