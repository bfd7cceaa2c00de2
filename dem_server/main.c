/* dem_server — the DEM as a cosim participant (role "dem", proto/PROTOCOL.md).
 * Sub-steps inside one coupling step when its own dt is smaller. */
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
  int surface;         /* mesh index of the coupled FEM surface, -1 if none */
  int threads_logged;  /* thread count last written to the log */
  double series[6];
  double *wall_row;    /* t, then Fx Fy Fz per wall */
  double *snap_x, *snap_v, *snap_w, *snap_r;
} dem_app;

static const char *const SERIES[] = {"t", "kinetic_energy", "contacts", "max_overlap_ratio",
                                     "elastic_energy", "coordination"};

static int configure(void *user, const proto_run_info *info, const cJSON *section, proto_err *err) {
  dem_app *a = user;
  if (a->have_model) dem_model_free(&a->model);
  a->have_model = 0;
  if (dem_model_from_json(&a->model, section, info->key_path, err)) return -1;
  a->have_model = 1;
  a->run_dt = info->dt;
  snprintf(a->name, sizeof a->name, "%s", info->name ? info->name : "dem");
  /* the initial configuration too (overlaps, grains outside): also for --check-config */
  dem_state probe;
  if (dem_state_init(&a->model, &probe, err)) return -1;
  dem_state_free(&probe);
  if (info->dt > 0 && dem_model_set_dt(&a->model, info->dt, err)) return -1;
  return 0;
}

static int add_surface(dem_app *a, const proto_msg *welcome, proto_err *err) {
  a->surface = -1;
  if (!proto_msg_find(welcome, "surface_x0")) return 0;
  const double *x0 = proto_msg_get_f8(welcome, "surface_x0", -1, 3, err);
  const int64_t tshape[2] = {-1, 3};
  const proto_array *tri = proto_msg_get(welcome, "surface_tri", PROTO_I4, 2, tshape, err);
  if (!x0 || !tri) return -1;
  const proto_array *xa = proto_msg_find(welcome, "surface_x0");
  a->surface = a->model.n_meshes;
  return dem_model_set_surface(&a->model, (int)xa->shape[0], x0, (int)tri->shape[0],
                               (const int32_t *)tri->data, err);
}

/* The thread count and why (it may change with the machine's load). */
static void log_threads(dem_app *a) {
  if (a->state.threads == a->threads_logged) return;
  fprintf(stderr, "dem_server: t = %.6g s: %s\n", a->state.t, a->state.threads_why);
  a->threads_logged = a->state.threads;
}

static int init(void *user, const proto_msg *welcome, proto_msg *ready, proto_err *err) {
  dem_app *a = user;
  dem_model *m = &a->model;
  if (add_surface(a, welcome, err) || dem_state_init(m, &a->state, err)) return -1;
  a->have_state = 1;
  log_threads(a);
  if (m->cfg.settle_steps > 0) {
    double t0 = proto_now();
    if (dem_settle(m, &a->state, m->cfg.settle_ke, (int64_t)m->cfg.settle_steps, err)) return -1;
    fprintf(stderr, "dem_server: bed of %d grains settled in %lld steps (%.1f s), KE %.3g J\n",
            m->n_grains, (long long)a->state.step, proto_now() - t0, a->state.kinetic_energy);
    a->state.t = 0;
    a->state.step = 0;
  }
  if (m->cfg.save_bed[0] && dem_bed_save(m, &a->state, m->cfg.save_bed, err))
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
  const char *attrs[] = {"v", "omega", "r"};
  if (proto_ready_series(ready, "series", 6, SERIES) < 0 ||
      proto_ready_snapshot(ready, "points", "x", NULL, 3, attrs) < 0)
    return proto_fail(err, "out of memory");
  cJSON *h = proto_msg_header(ready);
  cJSON *series = cJSON_GetObjectItemCaseSensitive(h, "series");
  cJSON *wf = cJSON_AddArrayToObject(series, "wall_forces");
  cJSON_AddItemToArray(wf, cJSON_CreateString("t"));
  for (int w = 0; w < m->n_walls; w++)
    for (int k = 0; k < 3; k++) {
      char name[32];
      snprintf(name, sizeof name, "wall%d_F%c", w, "xyz"[k]);
      cJSON_AddItemToArray(wf, cJSON_CreateString(name));
    }
  cJSON_AddNumberToObject(h, "dem_dt", m->dt);
  cJSON_AddNumberToObject(h, "rayleigh_time", m->rayleigh_time);
  cJSON_AddNumberToObject(h, "grains", m->n_grains);
  fprintf(stderr, "dem_server: %d grains, %d walls, dt = %.4g s = %.3g Rayleigh times\n",
          m->n_grains, m->n_walls, m->dt, m->dt / m->rayleigh_time);
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
  cJSON_AddItemToObject(proto_msg_header(&m), "columns", cJSON_CreateStringArray(SERIES, 6));
  proto_msg_add_f8(&m, "series", 6, 0, a->series);
  proto_peer_publish(peer, &m);
  proto_msg_free(&m);
}

static int step(void *user, proto_peer *peer, const proto_msg *req, proto_msg *reply, proto_err *err) {
  dem_app *a = user;
  dem_model *m = &a->model;
  dem_state *s = &a->state;
  const cJSON *hdt = req->header ? cJSON_GetObjectItemCaseSensitive(req->header, "dt") : NULL;
  const double dt = cJSON_IsNumber(hdt) ? hdt->valuedouble : a->run_dt;
  if (!(dt > 0)) return proto_fail(err, "step %lld: no coupling dt", (long long)req->step);
  if (fabs(dt - a->run_dt) > 1e-12 * dt) { /* coupling step changed: re-split it */
    if (dem_model_set_dt(m, dt, err)) return -1;
    a->run_dt = dt;
  }
  if (a->surface >= 0) {
    const int nn = m->meshes[a->surface].n_nodes;
    const double *x = proto_msg_get_f8(req, "x", nn, 3, err);
    const double *v = x ? proto_msg_get_f8(req, "v", nn, 3, err) : NULL;
    if (!x || !v) return -1;
    dem_mesh_set_nodes(m, s, a->surface, x, v);
  }
  long long nsub = llround(dt / m->dt);
  if (nsub < 1) nsub = 1;
  for (long long k = 0; k < nsub; k++)
    if (dem_step(m, s, err)) return proto_wrap(err, "coupling step %lld", (long long)req->step);
  log_threads(a);
  const double t = req->t + dt;
  double row[6] = {t, s->kinetic_energy, (double)s->contacts, s->max_overlap_ratio,
                   s->elastic_energy, dem_coordination(m, s)};
  memcpy(a->series, row, sizeof row);
  publish_summary(a, peer, req->step, t);
  a->wall_row[0] = t;
  memcpy(a->wall_row + 1, s->wall_force, sizeof(double) * 3 * (size_t)m->n_walls);
  if (proto_msg_add_f8(reply, "series", 6, 0, a->series) ||
      proto_msg_add_f8(reply, "series.wall_forces", 1 + 3 * m->n_walls, 0, a->wall_row))
    return proto_fail(err, "reply full");
  if (a->surface >= 0 &&
      proto_msg_add_f8(reply, "nodal_force", m->meshes[a->surface].n_nodes, 3, s->mesh_force[a->surface]))
    return proto_fail(err, "reply full");
  const cJSON *out = req->header ? cJSON_GetObjectItemCaseSensitive(req->header, "output") : NULL;
  if (cJSON_IsTrue(out)) {
    dem_gather(s, s->x, 3, a->snap_x);
    dem_gather(s, s->v, 3, a->snap_v);
    dem_gather(s, s->omega, 3, a->snap_w);
    int n = s->n;
    if (proto_msg_add_f8(reply, "snap.x", n, 3, a->snap_x) || proto_msg_add_f8(reply, "snap.v", n, 3, a->snap_v) ||
        proto_msg_add_f8(reply, "snap.omega", n, 3, a->snap_w) || proto_msg_add_f8(reply, "snap.r", n, 0, a->snap_r))
      return proto_fail(err, "reply full");
  }
  return 0;
}

static void finish(void *user) {
  dem_app *a = user;
  if (a->have_state) dem_state_free(&a->state);
  if (a->have_model) dem_model_free(&a->model);
  free(a->wall_row); free(a->snap_x); free(a->snap_v); free(a->snap_w); free(a->snap_r);
  memset(a, 0, sizeof *a);
}

int main(int argc, char **argv) {
  dem_openmp_env(argv); /* short barrier spin: the machine may be shared */
  static dem_app app;
  const proto_participant_ops ops = {"dem", configure, init, step, finish};
  return proto_participant_main(argc, argv, &ops, &app);
}
