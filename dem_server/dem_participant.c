/* dem_server — the DEM as a cosim participant (role "dem", proto/PROTOCOL.md).
 * Sub-steps inside one coupling step when its own dt is smaller; what it
 * returns then stands for the whole step (the role table): the nodal force
 * and the wall forces are the impulse over the step divided by dt, the mean
 * of the sub-steps' forces, so the tread receives exactly the impulse the
 * grains lost. The surface moves at the given velocity within the step
 * (dem_mesh_set_nodes, then dem_step moves it by v dt per sub-step). */
#include "dem_server/dem.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct dem_app {
  char name[PROTO_NAME_LEN];
  dem_model model;
  dem_state state;
  int have_model, have_state;
  double run_dt;
  proto_peer *peer;     /* for init progress (settling) */
  int64_t restart_step; /* > 0: a restart, whose state replaces the settled bed */
  int surface;         /* mesh index of the coupled FEM surface, -1 if none */
  int threads_logged;  /* thread count last written to the log */
  double series[DEM_N_SERIES];
  double *wall_row;    /* t, then Fx Fy Fz per wall (means over the step) */
  double *surface_force; /* [n*3] nodal force, mean over the step's sub-steps */
  double *snap_x, *snap_v, *snap_w, *snap_r;
} dem_app;



static int configure(void *user, const proto_run_info *info, const cJSON *section, proto_err *err) {
  dem_app *a = user;
  if (a->have_model) dem_model_free(&a->model);
  a->have_model = 1; /* also a half-read model: finish() frees it */
  if (dem_model_from_json(&a->model, section, info->key_path, err)) return -1;
  a->run_dt = info->dt;
  a->peer = info->peer;
  a->restart_step = info->restart_step;
  snprintf(a->name, sizeof a->name, "%s", info->name ? info->name : "dem");
  /* the initial configuration too (overlaps, grains outside): also for --check-config */
  dem_state probe;
  if (dem_state_init(&a->model, &probe, info->dt, err)) return -1;
  dem_state_free(&probe);
  return 0;
}

static int add_surface(dem_app *a, const proto_msg *welcome, proto_err *err) {
  a->surface = -1;
  /* checked against the role table by the participant loop */
  const proto_array *xa = proto_msg_find(welcome, PROTO_A_SURFACE_X0);
  const proto_array *tri = proto_msg_find(welcome, PROTO_A_SURFACE_TRI);
  if (!xa) return 0;
  a->surface = a->model.n_meshes;
  a->surface_force = calloc(3 * (size_t)xa->shape[0], sizeof(double));
  if (!a->surface_force) return proto_fail(err, "out of memory");
  return dem_model_set_surface(&a->model, (int)xa->shape[0], xa->data, (int)tri->shape[0],
                               (const int32_t *)tri->data, err);
}

/* The thread count and why (it may change with the machine's load). */
static void log_threads(dem_app *a) {
  if (a->state.threads == a->threads_logged) return;
  fprintf(stderr, "dem_server: t = %.6g s: %s\n", a->state.t, a->state.threads_why);
  a->threads_logged = a->state.threads;
}

/* The DEM library's progress, as this participant's heartbeats say it. */
static void report(void *ctx, double fraction, const char *what) {
  proto_peer_progress(ctx, fraction, what);
}

/* ready's bed_top: the settled bed's top under the coupled surface's x-y
 * footprint (its bounding box as placed in the welcome), or under all
 * grains without a surface; absent if no grain lies there. */
static int report_bed_top(dem_app *a, cJSON *h, proto_err *err) {
  double lo[2] = {-INFINITY, -INFINITY}, hi[2] = {INFINITY, INFINITY}, top;
  if (a->surface >= 0) {
    const dem_mesh *me = &a->model.meshes[a->surface];
    for (int k = 0; k < 2; k++) lo[k] = INFINITY, hi[k] = -INFINITY;
    for (int i = 0; i < me->n_nodes; i++)
      for (int k = 0; k < 2; k++) {
        lo[k] = fmin(lo[k], me->x0[3 * i + k]);
        hi[k] = fmax(hi[k], me->x0[3 * i + k]);
      }
  }
  int count;
  if (dem_bed_top(&a->state, lo, hi, DEM_BED_TOP_PERCENTILE, &top, &count, err) < 0) return -1;
  if (count > 0) cJSON_AddNumberToObject(h, PROTO_H_BED_TOP, top);
  cJSON_AddNumberToObject(h, PROTO_H_BED_TOP_GRAINS, count);
  return 0;
}

static int init(void *user, const proto_msg *welcome, proto_msg *ready, proto_err *err) {
  dem_app *a = user;
  const dem_model *m = &a->model;
  if (add_surface(a, welcome, err) || dem_state_init(m, &a->state, a->run_dt, err)) return -1;
  a->have_state = 1;
  log_threads(a);
  /* a restart's state (dem_state_import into a fresh state, bitwise) takes
   * the place of the settled bed: no need to settle it first */
  if (m->cfg.settle_steps > 0 && a->restart_step > 0)
    fprintf(stderr, "dem_server: restart from step %lld: not settling (the checkpoint "
            "has the bed)\n", (long long)a->restart_step);
  else if (m->cfg.settle_steps > 0) {
    double t0 = proto_now();
    if (dem_settle(m, &a->state, m->cfg.settle_ke, (int64_t)m->cfg.settle_steps, report,
                   a->peer, err))
      return -1;
    fprintf(stderr, "dem_server: bed of %d grains settled in %lld steps (%.1f s), KE %.3g J\n",
            m->n_grains, (long long)a->state.step, proto_now() - t0, a->state.kinetic_energy);
    a->state.t = 0;
    a->state.step = 0;
  }
  if (m->cfg.save_bed[0] && a->restart_step == 0 &&
      dem_bed_save(m, &a->state, m->cfg.save_bed, err))
    return proto_wrap(err, "%s.particles.save", m->key_path);
  size_t n = (size_t)m->n_grains;
  a->wall_row = calloc(1 + 3 * (size_t)m->n_walls, sizeof(double));
  a->snap_x = malloc(3 * n * sizeof(double));
  a->snap_v = malloc(3 * n * sizeof(double));
  a->snap_w = malloc(3 * n * sizeof(double));
  a->snap_r = malloc(n * sizeof(double));
  if (!a->wall_row || !a->snap_x || !a->snap_v || !a->snap_w || !a->snap_r)
    return proto_fail(err, "out of memory");
  dem_gather(&a->state, a->state.radius, 1, a->snap_r);
  if (dem_ready_declare(m, ready, err)) return -1;
  cJSON *h = proto_msg_header(ready);
  if (report_bed_top(a, h, err) < 0) return -1;
  cJSON_AddNumberToObject(h, "dem_dt", a->state.dt);
  cJSON_AddNumberToObject(h, "rayleigh_time", m->rayleigh_time);
  cJSON_AddNumberToObject(h, "grains", m->n_grains);
  fprintf(stderr, "dem_server: %d grains, %d walls, dt = %.4g s = %.3g Rayleigh times\n",
          m->n_grains, m->n_walls, a->state.dt, a->state.dt / m->rayleigh_time);
  return 0;
}

/* The per-step summary on the bus, with its column names, for live monitors
 * that have no results.h5 at hand ("<name>.summary"; the coupler republishes
 * the same row as "<name>.series"). */
static void publish_summary(dem_app *a, proto_peer *peer, int64_t step, double t) {
  proto_msg m = {0};
  char topic[PROTO_NAME_LEN + 8];
  snprintf(topic, sizeof topic, "%s.summary", a->name);
  proto_msg_reset(&m, topic, "summary", step, t);
  cJSON_AddItemToObject(proto_msg_header(&m), "columns",
                        cJSON_CreateStringArray(DEM_SERIES, DEM_N_SERIES));
  proto_msg_add_f8(&m, PROTO_A_SERIES, DEM_N_SERIES, 0, a->series);
  proto_peer_publish(peer, &m);
  proto_msg_free(&m);
}

/* The mean over the step's sub-steps, in place: the impulse/dt of the role
 * table. One sub-step: the sub-step's force itself, bit for bit. */
static void accumulate(double *sum, const double *f, size_t n, long long k) {
  if (k == 0) memcpy(sum, f, n * sizeof(double));
  else
    for (size_t i = 0; i < n; i++) sum[i] += f[i];
}

static void to_mean(double *sum, size_t n, long long nsub) {
  if (nsub == 1) return;
  for (size_t i = 0; i < n; i++) sum[i] /= (double)nsub;
}

static int step(void *user, proto_peer *peer, const proto_step_info *info, const proto_msg *req,
                proto_msg *reply, proto_err *err) {
  dem_app *a = user;
  const dem_model *m = &a->model;
  dem_state *s = &a->state;
  const double dt = info->dt;
  if (fabs(dt - a->run_dt) > 1e-12 * dt) { /* coupling step changed: re-split it */
    if (dem_state_set_dt(m, s, dt, err)) return -1;
    a->run_dt = dt;
  }
  const size_t nn3 = a->surface >= 0 ? 3 * (size_t)m->meshes[a->surface].n_nodes : 0;
  const size_t nw3 = 3 * (size_t)m->n_walls;
  if (a->surface >= 0) /* checked against the role table by the participant loop */
    dem_mesh_set_nodes(m, s, a->surface, proto_msg_data(req, PROTO_A_X),
                       proto_msg_data(req, PROTO_A_V));
  /* equal sub-steps s->dt = dt/nsub (dem_state_set_dt): the impulse/dt of a
   * force sampled once per sub-step is the mean of the samples */
  long long nsub = llround(dt / s->dt);
  if (nsub < 1) nsub = 1;
  for (long long k = 0; k < nsub; k++) {
    if (dem_step(m, s, err)) return proto_wrap(err, "coupling step %lld", (long long)info->k);
    if (nn3) accumulate(a->surface_force, s->mesh_force[a->surface], nn3, k);
    accumulate(a->wall_row + 1, s->wall_force, nw3, k);
  }
  to_mean(a->surface_force, nn3, nsub);
  to_mean(a->wall_row + 1, nw3, nsub);
  log_threads(a);
  const double t = info->t_end;
  a->series[DEM_SERIES_T] = t;
  a->series[DEM_SERIES_KINETIC] = s->kinetic_energy;
  a->series[DEM_SERIES_CONTACTS] = (double)s->contacts;
  a->series[DEM_SERIES_MAX_OVERLAP] = s->max_overlap_ratio;
  a->series[DEM_SERIES_ELASTIC] = s->elastic_energy;
  a->series[DEM_SERIES_COORDINATION] = dem_coordination(m, s);
  publish_summary(a, peer, info->k, t);
  a->wall_row[0] = t;
  if (proto_msg_add_f8(reply, PROTO_A_SERIES, DEM_N_SERIES, 0, a->series) ||
      proto_msg_add_prefixed(reply, PROTO_P_SERIES, DEM_WALL_FORCES, PROTO_F8, 1 + (int64_t)nw3, 0,
                             a->wall_row))
    return proto_fail(err, "reply full");
  if (a->surface >= 0 &&
      proto_msg_add_f8(reply, PROTO_A_NODAL_FORCE, m->meshes[a->surface].n_nodes, 3, a->surface_force))
    return proto_fail(err, "reply full");
  if (info->output) {
    dem_gather(s, s->x, 3, a->snap_x);
    dem_gather(s, s->v, 3, a->snap_v);
    dem_gather(s, s->omega, 3, a->snap_w);
    const int n = s->n;
    const double *snap[DEM_N_SNAP] = {a->snap_x, a->snap_v, a->snap_w, a->snap_r};
    for (int k = 0; k < DEM_N_SNAP; k++)
      if (proto_msg_add_prefixed(reply, PROTO_P_SNAP, DEM_SNAP[k], PROTO_F8, n, k == DEM_SNAP_R ? 0 : 3, snap[k]))
        return proto_fail(err, "reply full");
  }
  return 0;
}

/* The whole changing state (rollback of the implicit scheme, checkpoints):
 * dem_state_export/import. surface_force and wall_row are rebuilt by every
 * step, the model does not change. */
static int state_save(void *user, proto_msg *state, proto_err *err) {
  dem_app *a = user;
  return dem_state_export(&a->model, &a->state, state, err);
}

static int state_load(void *user, const proto_msg *state, proto_err *err) {
  dem_app *a = user;
  return dem_state_import(&a->model, &a->state, state, err);
}

static void finish(void *user) {
  dem_app *a = user;
  if (a->have_state) dem_state_free(&a->state);
  if (a->have_model) dem_model_free(&a->model);
  free(a->wall_row); free(a->surface_force); free(a->snap_x); free(a->snap_v); free(a->snap_w); free(a->snap_r);
  memset(a, 0, sizeof *a);
}

int main(int argc, char **argv) {
  dem_openmp_env(argv); /* short barrier spin: the machine may be shared */
  static dem_app app;
  const proto_participant_ops ops = {.role = PROTO_ROLE_DEM, .configure = configure, .init = init,
                                     .step = step, .finish = finish, .state_save = state_save,
                                     .state_load = state_load};
  return proto_participant_main(argc, argv, &ops, &app);
}
