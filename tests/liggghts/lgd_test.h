/* lgd_test.h — helpers for the liggghts_dem tests: MPI set-up, a model from
 * JSON, checks (tests/common/cosim_test.h) decided on rank 0, and a "twin"
 * that runs one scene in liggghts_dem's engine (LIGGGHTS over MPI) and in
 * dem_server's (cosim_dem) side by side, the coupled surface driven by the
 * same motion. */
#ifndef COSIM_LGD_TEST_H
#define COSIM_LGD_TEST_H

#include <math.h>
#include <string.h>

#include "cosim_test.h"
#include "liggghts_dem/lgd.h"

static int g_rank;

static inline void lgd_test_init(int *argc, char ***argv) {
  MPI_Init(argc, argv);
  MPI_Comm_rank(MPI_COMM_WORLD, &g_rank);
  cosim_test_mute = g_rank != 0; /* the results are on rank 0 */
}

/* Checks are decided on rank 0 (where the results are); every rank exits alike. */
static inline int lgd_test_finish(const char *name) {
  MPI_Bcast(&cosim_test_failures, 1, MPI_INT, 0, MPI_COMM_WORLD);
  const int rc = g_rank == 0 ? cosim_test_done(name) : cosim_test_failures != 0;
  MPI_Finalize();
  return rc;
}

static inline void die(const char *what, const proto_err *err) {
  fprintf(stderr, "rank %d: %s: %s\n", g_rank, what, err->msg);
  MPI_Abort(MPI_COMM_WORLD, 2);
}

static inline void model_from_json(const char *json, dem_model *m) {
  proto_err err = {{0}};
  cJSON *j = cJSON_Parse(json);
  if (!j) { fprintf(stderr, "bad test JSON: %s\n", json); MPI_Abort(MPI_COMM_WORLD, 2); }
  if (dem_model_from_json(m, j, "processes.dem", &err)) die("model", &err);
  cJSON_Delete(j);
}

/* An n × n grid of squares over [-L, L]² (each split along the same
 * diagonal), heights z = h(x) with slope s·|x| folded at x = 0 (s = 0: flat
 * at z0). x0 [3(n+1)²], tri [6n²]. */
static inline void lgd_grid(int n, double L, double z0, double s, double *x0, int32_t *tri) {
  for (int j = 0; j <= n; j++)
    for (int i = 0; i <= n; i++) {
      double *p = &x0[3 * (j * (n + 1) + i)];
      p[0] = -L + 2 * L * i / n;
      p[1] = -L + 2 * L * j / n;
      p[2] = z0 - s * fabs(p[0]);
    }
  for (int j = 0; j < n; j++)
    for (int i = 0; i < n; i++) {
      const int32_t a = j * (n + 1) + i, b = a + 1, c = a + n + 1, d = c + 1;
      const int32_t tt[6] = {a, b, d, a, d, c};
      memcpy(&tri[6 * (j * n + i)], tt, sizeof tt);
    }
}

/* The coupled surface's motion: positions at time t and velocities over the
 * step that starts there (x(t + dt) = x(t) + v dt exactly, as both engines
 * move a surface within a step). */
typedef void (*twin_motion)(double t, int n_nodes, const double *x0, double *x, double *v, void *ctx);

typedef struct twin {
  dem_model ml, md; /* one model per engine */
  dem_state sd;
  lgd_sim *sim;
  int surface, nn;
  double coupling_dt, t;
  double *x, *v, *dem_nodal, *dem_wall, *lx;
  /* running maxima over the steps: |lgd − dem| and |dem| */
  double nodal_diff, nodal_max, wall_diff, wall_max;
  double last_nodal_diff, last_nodal_max; /* the same, last step only */
} twin;

/* tolerance: LIGGGHTS' face tolerance (0 = liggghts_dem's choice). */
static inline void twin_open_tol(twin *w, const char *json, int nn, const double *x0, int nt,
                                 const int32_t *tri, double coupling_dt, int frozen, double tolerance) {
  proto_err err = {{0}};
  memset(w, 0, sizeof *w);
  model_from_json(json, &w->ml);
  model_from_json(json, &w->md);
  w->surface = -1;
  if (nn > 0) {
    w->surface = w->ml.n_meshes;
    if (dem_model_set_surface(&w->ml, nn, x0, nt, tri, &err) ||
        dem_model_set_surface(&w->md, nn, x0, nt, tri, &err))
      die("surface", &err);
  }
  if (dem_state_init(&w->md, &w->sd, coupling_dt, &err)) die("dem_server state", &err);
  lgd_options o = {.frozen_activity = frozen, .face_tolerance = tolerance};
  if (lgd_open(&w->sim, MPI_COMM_WORLD, &w->ml, coupling_dt, &o, &err)) die("liggghts", &err);
  w->nn = nn;
  w->coupling_dt = coupling_dt;
  const size_t n3 = 3 * (size_t)(nn > 0 ? nn : 1);
  w->x = calloc(n3, sizeof(double));
  w->v = calloc(n3, sizeof(double));
  w->dem_nodal = calloc(n3, sizeof(double));
  w->dem_wall = calloc(3 * (size_t)w->md.n_walls + 3, sizeof(double));
  w->lx = calloc(3 * (size_t)w->md.n_grains, sizeof(double));
}

static inline void twin_open(twin *w, const char *json, int nn, const double *x0, int nt,
                             const int32_t *tri, double coupling_dt, int frozen) {
  twin_open_tol(w, json, nn, x0, nt, tri, coupling_dt, frozen, 0);
}

/* One coupling step in both engines; dem_server's forces are averaged over
 * its sub-steps (impulse / Δt), as liggghts_dem returns them. */
static inline void twin_step(twin *w, twin_motion motion, void *ctx) {
  proto_err err = {{0}};
  const dem_mesh *me = w->surface >= 0 ? &w->md.meshes[w->surface] : NULL;
  if (me) {
    motion(w->t, w->nn, me->x0, w->x, w->v, ctx);
    dem_mesh_set_nodes(&w->md, &w->sd, w->surface, w->x, w->v);
  }
  const long long nsub = llround(w->coupling_dt / w->sd.dt);
  memset(w->dem_nodal, 0, sizeof(double) * 3 * (size_t)w->nn);
  memset(w->dem_wall, 0, sizeof(double) * 3 * (size_t)w->md.n_walls);
  for (long long k = 0; k < nsub; k++) {
    if (dem_step(&w->md, &w->sd, &err)) die("dem_step", &err);
    for (int a = 0; a < 3 * w->nn; a++) w->dem_nodal[a] += w->sd.mesh_force[w->surface][a] / nsub;
    for (int a = 0; a < 3 * w->md.n_walls; a++) w->dem_wall[a] += w->sd.wall_force[a] / nsub;
  }
  if (lgd_step(w->sim, w->coupling_dt, w->x, w->v, &err)) die("lgd_step", &err);
  w->t += w->coupling_dt;
  const lgd_out *o = lgd_result(w->sim);
  w->last_nodal_diff = w->last_nodal_max = 0;
  for (int a = 0; a < 3 * w->nn && g_rank == 0; a++) {
    w->last_nodal_diff = fmax(w->last_nodal_diff, fabs(o->nodal_force[a] - w->dem_nodal[a]));
    w->last_nodal_max = fmax(w->last_nodal_max, fabs(w->dem_nodal[a]));
  }
  w->nodal_diff = fmax(w->nodal_diff, w->last_nodal_diff);
  w->nodal_max = fmax(w->nodal_max, w->last_nodal_max);
  for (int a = 0; a < 3 * w->md.n_walls && g_rank == 0; a++) {
    w->wall_diff = fmax(w->wall_diff, fabs(o->wall_force[a] - w->dem_wall[a]));
    w->wall_max = fmax(w->wall_max, fabs(w->dem_wall[a]));
  }
}

/* Largest |x_lgd − x_dem| over the grains (rank 0; gathers). */
static inline double twin_position_diff(twin *w) {
  proto_err err = {{0}};
  if (lgd_gather(w->sim, w->lx, NULL, NULL, &err)) die("gather", &err);
  double d = 0;
  for (int i = 0; i < w->sd.n && g_rank == 0; i++)
    for (int k = 0; k < 3; k++)
      d = fmax(d, fabs(w->lx[3 * w->sd.id[i] + k] - w->sd.x[3 * i + k]));
  return d;
}

static inline void twin_close(twin *w) {
  lgd_close(w->sim);
  dem_state_free(&w->sd);
  dem_model_free(&w->ml);
  dem_model_free(&w->md);
  free(w->x); free(w->v); free(w->dem_nodal); free(w->dem_wall); free(w->lx);
}

#endif
