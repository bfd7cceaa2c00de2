/* fem_stub — a rigid tread surface that speaks the fem role (PROTOCOL.md):
 * the surface never deforms; it moves with the rim frame. Its series records
 * the force it receives, so a test can check what the other side sent.
 * Config: {"exec": "fem_stub", "surface": {"plane": {"size": [lx, ly],
 *          "n": [nx, ny], "z": z0}} | {"wheel": {"radius": r, "width": w,
 *          "n": [n_arc, n_width]}} | {"nodes": [[x,y,z]...],
 *          "triangles": [[i,j,k]...]}}. A plane or explicit nodes follow the
 * rim frame, x = R X0 + c, v = v_rim + omega x (x - c). A wheel is the lower
 * half of a rigid cylinder about the axle (y): a body of revolution, so its
 * surface is the same in every rim angle and the stub keeps its nodes at the
 * bottom (x = X0 + c) while they carry the rolling wheel's material velocity
 * v = v_rim + omega x (x - c): the rigid wheel of terramechanics (Wong &
 * Reece 1967), seen where it meets the soil. Without "surface" (standing
 * in for fem_server, whose other keys are named in the log and ignored) it
 * is the default wheel: the outer surface of the 165/65 R13 tread band,
 * seed 000 §5. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "stubs/stub.h"

/* Default surface: the outer surface of the tread band of fem_server's
 * "tread" generator (165/65 R13, seed 000 §5: radius 0.272 m, width
 * 0.165 m). A flat patch that turns with the rim tips its leading edge into
 * the bed as the wheel rolls, 0.1 m x sin(omega t) (configs/default.json:
 * 11.5 mm 0.064 s into the travel, where it crushed a grain to an overlap of
 * half its radius; 47 mm by the scene's end). 96 cells over the half
 * circumference: 8.9 mm chords (grains 3.3-7.8 mm in radius), sag
 * c^2 / (8 r) = 36 um; 8 cells across the width. */
static const double WHEEL_RADIUS = 0.272, WHEEL_WIDTH = 0.165, WHEEL_N[2] = {96, 8};
/* How far R may turn the axle e_y away from itself before the wheel's
 * symmetry (x = X0 + c) no longer holds: round-off of a rotation matrix. */
#define AXLE_TOL 1e-12

enum { COL_T, COL_FX, COL_FY, COL_FZ, COL_N, NCOL };
static const char *const columns[NCOL] = {"t", "force_x", "force_y", "force_z",
                                          "n_nodes"};

typedef struct fem_stub {
  int64_t n_nodes, n_tris;
  double *x0, *x, *v;
  double *f_dense; /* a sparse nodal_force expanded (PROTOCOL.md "Sparse exchange") */
  int32_t *tri;
  int wheel; /* 1: body of revolution about the axle, nodes kept at the bottom */
  double series[NCOL];
} fem_stub;

/* Node (i, j) of an nx x ny grid of cells: a plane at height z, or the
 * lower half of a cylinder about y (i sweeps the angle from -x to +x). */
typedef struct grid_shape {
  int wheel;
  double size[2], z; /* plane: lx, ly, height; wheel: radius, width */
} grid_shape;

static void grid_node(const grid_shape *g, int i, int j, int nx, int ny, double *p) {
  const double u = (double)i / nx - 0.5, y = g->size[1] * ((double)j / ny - 0.5);
  if (g->wheel) {
    const double phi = M_PI * u; /* angle from the bottom, in [-pi/2, pi/2] */
    p[0] = g->size[0] * sin(phi);
    p[1] = y;
    p[2] = -g->size[0] * cos(phi);
  } else {
    p[0] = g->size[0] * u;
    p[1] = y;
    p[2] = g->z;
  }
}

static int grid_mesh(fem_stub *s, const grid_shape *g, const double *n, proto_cfg *c) {
  int nx = (int)n[0], ny = (int)n[1];
  if (nx < 1 || ny < 1 || nx > 4096 || ny > 4096 || n[0] != nx || n[1] != ny)
    return proto_fail(c->err, "%s.n: expected two integers in [1, 4096]", c->path);
  if (g->size[0] <= 0 || g->size[1] <= 0)
    return proto_fail(c->err, "%s.%s: must be positive", c->path,
                      g->wheel ? "radius and width" : "size");
  s->wheel = g->wheel;
  s->n_nodes = (int64_t)(nx + 1) * (ny + 1);
  s->n_tris = 2 * (int64_t)nx * ny;
  s->x0 = malloc(sizeof(double) * 3 * (size_t)s->n_nodes);
  s->tri = malloc(sizeof(int32_t) * 3 * (size_t)s->n_tris);
  if (!s->x0 || !s->tri) return proto_fail(c->err, "out of memory");
  for (int j = 0; j <= ny; j++)
    for (int i = 0; i <= nx; i++) grid_node(g, i, j, nx, ny, &s->x0[3 * (j * (nx + 1) + i)]);
  int32_t *t = s->tri;
  for (int j = 0; j < ny; j++)
    for (int i = 0; i < nx; i++) {
      int32_t a = j * (nx + 1) + i, b = a + 1, d = a + nx + 1, e = d + 1;
      /* normals point away from the rim (-z at the bottom): the tread's
       * outer surface faces the soil */
      int32_t tt[6] = {a, d, b, b, d, e};
      memcpy(t, tt, sizeof tt);
      t += 6;
    }
  return 0;
}

static int plane(fem_stub *s, proto_cfg *c) {
  grid_shape g = {0, {1, 1}, 0};
  double n[2] = {4, 4};
  if (proto_cfg_vec(c, "size", PROTO_REQUIRED, g.size, 2, 2, NULL) < 0 ||
      proto_cfg_vec(c, "n", PROTO_REQUIRED, n, 2, 2, NULL) < 0 ||
      proto_cfg_num(c, "z", PROTO_OPTIONAL, -1e6, 1e6, &g.z) < 0 ||
      proto_cfg_end(c) < 0)
    return -1;
  return grid_mesh(s, &g, n, c);
}

static int wheel(fem_stub *s, proto_cfg *c) {
  grid_shape g = {1, {WHEEL_RADIUS, WHEEL_WIDTH}, 0};
  double n[2] = {WHEEL_N[0], WHEEL_N[1]};
  if (proto_cfg_num(c, "radius", PROTO_OPTIONAL, 1e-6, 1e3, &g.size[0]) < 0 ||
      proto_cfg_num(c, "width", PROTO_OPTIONAL, 1e-6, 1e3, &g.size[1]) < 0 ||
      proto_cfg_vec(c, "n", PROTO_OPTIONAL, n, 2, 2, NULL) < 0 || proto_cfg_end(c) < 0)
    return -1;
  return grid_mesh(s, &g, n, c);
}

static int explicit_mesh(fem_stub *s, proto_cfg *c) {
  const cJSON *nodes = proto_cfg_raw(c, "nodes", PROTO_REQUIRED);
  const cJSON *tris = proto_cfg_raw(c, "triangles", PROTO_REQUIRED);
  if (!nodes || !tris || proto_cfg_end(c) < 0) return -1;
  char path[320];
  s->n_nodes = cJSON_IsArray(nodes) ? cJSON_GetArraySize(nodes) : 0;
  s->n_tris = cJSON_IsArray(tris) ? cJSON_GetArraySize(tris) : 0;
  if (s->n_nodes < 3 || s->n_tris < 1)
    return proto_fail(c->err, "%s: needs at least 3 nodes and 1 triangle", c->path);
  s->x0 = malloc(sizeof(double) * 3 * (size_t)s->n_nodes);
  s->tri = malloc(sizeof(int32_t) * 3 * (size_t)s->n_tris);
  if (!s->x0 || !s->tri) return proto_fail(c->err, "out of memory");
  /* walk the lists (cJSON_GetArrayItem(list, i) would be quadratic) */
  const cJSON *p = nodes->child;
  for (int64_t i = 0; i < s->n_nodes; i++, p = p->next) {
    for (int a = 0; a < 3; a++) {
      const cJSON *v = cJSON_IsArray(p) && cJSON_GetArraySize(p) == 3
                           ? cJSON_GetArrayItem(p, a) : NULL;
      if (!cJSON_IsNumber(v) || !isfinite(v->valuedouble)) {
        proto_cfg_subpath(c, "nodes", (int)i, path, sizeof path);
        return proto_fail(c->err, "%s: expected [x, y, z]", path);
      }
      s->x0[3 * i + a] = v->valuedouble;
    }
  }
  p = tris->child;
  for (int64_t i = 0; i < s->n_tris; i++, p = p->next) {
    for (int a = 0; a < 3; a++) {
      const cJSON *v = cJSON_IsArray(p) && cJSON_GetArraySize(p) == 3
                           ? cJSON_GetArrayItem(p, a) : NULL;
      if (!cJSON_IsNumber(v) || !(v->valuedouble >= 0) ||
          v->valuedouble >= (double)s->n_nodes || v->valuedouble != floor(v->valuedouble)) {
        proto_cfg_subpath(c, "triangles", (int)i, path, sizeof path);
        return proto_fail(c->err, "%s: expected three node indices in [0, %lld)",
                          path, (long long)s->n_nodes);
      }
      s->tri[3 * i + a] = (int32_t)v->valueint;
    }
  }
  return 0;
}

/* "surface": one of "plane", "wheel" or explicit "nodes" + "triangles". */
static int surface(fem_stub *s, proto_cfg *surf) {
  proto_cfg sub;
  int rc = proto_cfg_child(surf, "plane", PROTO_OPTIONAL, &sub);
  if (rc == 0) rc = plane(s, &sub);
  else if (rc > 0 && (rc = proto_cfg_child(surf, "wheel", PROTO_OPTIONAL, &sub)) == 0)
    rc = wheel(s, &sub);
  else if (rc > 0) rc = explicit_mesh(s, surf);
  return rc < 0 ? -1 : proto_cfg_end(surf);
}

static int configure(void *user, const proto_run_info *info,
                     const cJSON *section, proto_err *err) {
  fem_stub *s = user;
  proto_cfg c, surf;
  char exec[256];
  if (proto_cfg_open(&c, section, info->key_path, err) < 0 ||
      proto_cfg_str(&c, "exec", PROTO_OPTIONAL, exec, sizeof exec) < 0)
    return -1;
  int rc = proto_cfg_child(&c, "surface", PROTO_OPTIONAL, &surf);
  if (rc < 0) return -1;
  if (rc > 0) { /* standing in for a solver: the default wheel */
    const grid_shape g = {1, {WHEEL_RADIUS, WHEEL_WIDTH}, 0};
    rc = grid_mesh(s, &g, WHEEL_N, &c);
  } else {
    rc = surface(s, &surf);
  }
  if (rc < 0 || stub_cfg_end(&c, "fem_stub") < 0) return -1;
  s->x = calloc((size_t)s->n_nodes * 3, sizeof(double));
  s->v = calloc((size_t)s->n_nodes * 3, sizeof(double));
  s->f_dense = calloc((size_t)s->n_nodes * 3 + 1, sizeof(double));
  return s->x && s->v && s->f_dense ? 0 : proto_fail(err, "out of memory");
}

static int init(void *user, const proto_msg *welcome, proto_msg *ready,
                proto_err *err) {
  (void)welcome;
  fem_stub *s = user;
  if (proto_msg_add_f8(ready, PROTO_A_SURFACE_X0, s->n_nodes, 3, s->x0) < 0 ||
      proto_msg_add_i4(ready, PROTO_A_SURFACE_TRI, s->n_tris, 3, s->tri) < 0 ||
      proto_ready_series(ready, PROTO_A_SERIES, NCOL, columns) < 0)
    return proto_fail(err, "cannot build the ready message");
  cJSON_AddBoolToObject(proto_msg_header(ready), PROTO_H_SPARSE, 1); /* takes a sparse force */
  return 0;
}

static int step(void *user, proto_peer *peer, const proto_step_info *info,
                const proto_msg *req, proto_msg *reply, proto_err *err) {
  (void)peer;
  fem_stub *s = user;
  /* checked against the role table by the participant loop */
  const double *f = proto_msg_dense(req, PROTO_A_NODAL_FORCE, s->n_nodes, 3, s->f_dense);
  const double *R = proto_msg_data(req, PROTO_A_RIM_R);
  const double *c = proto_msg_data(req, PROTO_A_RIM_C);
  const double *w = proto_msg_data(req, PROTO_A_RIM_OMEGA);
  const double *vr = proto_msg_data(req, PROTO_A_RIM_V);
  static const double identity[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  /* the wheel is the same surface in every frame that turns about y */
  if (s->wheel && fabs(R[1]) + fabs(R[4] - 1) + fabs(R[7]) > AXLE_TOL)
    return proto_fail(err, "%s: the wheel surface needs a rim that turns about its axle y "
                      "(R e_y = e_y), got R e_y = (%g, %g, %g)", PROTO_A_RIM_R, R[1], R[4], R[7]);
  const double *Q = s->wheel ? identity : R;
  double F[3] = {0, 0, 0};
  for (int64_t i = 0; i < s->n_nodes; i++) {
    const double *X = &s->x0[3 * i];
    double *x = &s->x[3 * i], *v = &s->v[3 * i], r[3];
    for (int a = 0; a < 3; a++) {
      r[a] = Q[3 * a] * X[0] + Q[3 * a + 1] * X[1] + Q[3 * a + 2] * X[2];
      x[a] = c[a] + r[a];
      F[a] += f[3 * i + a];
    }
    v[0] = vr[0] + w[1] * r[2] - w[2] * r[1];
    v[1] = vr[1] + w[2] * r[0] - w[0] * r[2];
    v[2] = vr[2] + w[0] * r[1] - w[1] * r[0];
  }
  double row[NCOL] = {info->t_end, F[0], F[1], F[2], (double)s->n_nodes};
  memcpy(s->series, row, sizeof row);
  if (proto_msg_add_f8(reply, PROTO_A_X, s->n_nodes, 3, s->x) < 0 ||
      proto_msg_add_f8(reply, PROTO_A_V, s->n_nodes, 3, s->v) < 0 ||
      proto_msg_add_f8(reply, PROTO_A_SERIES, NCOL, 0, s->series) < 0)
    return proto_fail(err, "reply full");
  return 0;
}

static void finish(void *user) {
  fem_stub *s = user;
  free(s->x0);
  free(s->x);
  free(s->v);
  free(s->f_dense);
  free(s->tri);
  memset(s, 0, sizeof *s);
}

int main(int argc, char **argv) {
  fem_stub s = {0};
  const proto_participant_ops ops = {.role = PROTO_ROLE_FEM,
                                     .configure = configure,
                                     .init = init,
                                     .step = step,
                                     .finish = finish,
                                     .state_save = stub_state_none_save,
                                     .state_load = stub_state_none_load};
  return proto_participant_main(argc, argv, &ops, &s);
}
