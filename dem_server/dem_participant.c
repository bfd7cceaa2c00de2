/* dem_server — the DEM as a cosim participant (role "dem", proto/PROTOCOL.md).
 * Sub-steps inside one coupling step when its own dt is smaller; what it
 * returns then stands for the whole step (the role table): the nodal force
 * and the wall forces are the impulse over the step divided by dt, the mean
 * of the sub-steps' forces, so the tread receives exactly the impulse the
 * grains lost. The surface moves at the given velocity within the step
 * (dem_mesh_set_nodes, then dem_step moves it by v dt per sub-step).
 * Sparse exchange (dem_nodeset.c, PROTOCOL.md "Sparse exchange"): when the
 * request says sparse, the done carries the nodal force as (index, force)
 * for the nodes that carry one (dense beyond a third of the nodes) and the
 * box the grains can reach next (header reach; with sleep grown to what the
 * active region looks at, and reach_speed for the coupler to grow it by the
 * surface's speed: dem_sleep_reach); a request with x_index sets only those
 * nodes. With sleep the region's guard counts the jumps of the nodes near the
 * grains only (dem_sleep_jump_box), the same nodes dense or sparse.
 * A bed read from a file (particles.file) that holds a saved state continues
 * the run that saved it (dem_bed_continue, after the state is made and the
 * surface added); a generated bed settles in init (dem_bed_settle: with
 * particles.prepare first with the preparation's laws, then the scene's) and
 * with particles.save is written after settling, with its whole state. */
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
  int64_t logged[7]; /* log_counts at the last output's log line (sleep) */
  double series[DEM_N_SERIES];
  double *wall_row;    /* t, then Fx Fy Fz per wall (means over the step) */
  double *surface_force; /* [n*3] nodal force, mean over the step's sub-steps */
  int32_t *force_index;  /* [n] sparse exchange: nodes whose force row is sent */
  double *force_rows;    /* [n*3] their rows */
  uint8_t *node_seen, *tri_live; /* [n], [m]: nodes set this step, live triangles */
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
  const size_t n = (size_t)xa->shape[0];
  a->surface_force = calloc(3 * n, sizeof(double));
  a->force_index = malloc(sizeof(int32_t) * (n + 1));
  a->force_rows = malloc(sizeof(double) * 3 * (n + 1));
  a->node_seen = malloc(n + 1);
  a->tri_live = malloc((size_t)tri->shape[0] + 1);
  if (!a->surface_force || !a->force_index || !a->force_rows || !a->node_seen || !a->tri_live)
    return proto_fail(err, "out of memory");
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

/* The state of a bed file (particles.file): the saved one continues the run
 * that saved it; the log says which start this is. */
static int continue_bed(dem_app *a, proto_err *err) {
  const dem_model *m = &a->model;
  const dem_state *s = &a->state;
  dem_bed_info b;
  if (dem_bed_continue(m, &a->state, &b, err)) return proto_wrap(err, "%s.particles.file", m->key_path);
  const char *f = m->cfg.bed_file;
  if (b.continued)
    fprintf(stderr, "dem_server: bed %s: its saved state continues (contact springs, neighbour list, "
            "sleep, clock: t = %.6g s, step %lld)\n", f, s->t, (long long)s->step);
  else if (b.has_state)
    fprintf(stderr, "dem_server: bed %s: positions only (particles.state = \"positions\"): the saved "
            "state is not used, contacts start without tangential springs\n", f);
  else
    fprintf(stderr, "dem_server: bed %s has no saved state (an older or hand-made file): positions "
            "only, contacts start without tangential springs\n", f);
  const int same_g = b.gravity[0] == m->gravity[0] && b.gravity[1] == m->gravity[1] &&
                     b.gravity[2] == m->gravity[2];
  if (b.continued && (b.dt != s->dt || !same_g))
    fprintf(stderr, "dem_server: bed %s was saved with dt = %.6g s, gravity (%g, %g, %g); this run has "
            "dt = %.6g s, gravity (%g, %g, %g): it continues, but not bit for bit the run that saved "
            "it\n", f, b.dt, b.gravity[0], b.gravity[1], b.gravity[2], s->dt, m->gravity[0],
            m->gravity[1], m->gravity[2]);
  if (b.other_meshes)
    fprintf(stderr, "dem_server: bed %s was saved with other meshes (node and triangle counts, "
            "triangles or material; no grain touched one): the grains' state continues, the meshes "
            "start as this scene's, without contacts\n", f);
  if (b.friction[0])
    fprintf(stderr, "dem_server: bed %s was saved with other friction (pair %s): %s from the first step "
            "on, capped by this scene's friction\n", f, b.friction,
            b.continued ? "its springs continue" : "positions only");
  return 0;
}

/* ready's bed_top: with a coupled surface, the height its lowest node has
 * when the surface (as placed in the welcome), lowered straight down, first
 * touches a grain; without one, the 95th percentile of all grain tops
 * (dem_bed_ready_top). Absent if no grain lies there. */
static int report_bed_top(dem_app *a, cJSON *h, proto_err *err) {
  const dem_mesh *me = a->surface >= 0 ? &a->model.meshes[a->surface] : NULL;
  double top;
  int count;
  if (dem_bed_ready_top(a->state.x, a->state.radius, a->state.n, me ? me->x0 : NULL,
                        me ? me->n_nodes : 0, me ? me->tri : NULL, me ? me->n_tri : 0, &top, &count,
                        err) < 0)
    return -1;
  if (count > 0) cJSON_AddNumberToObject(h, PROTO_H_BED_TOP, top);
  cJSON_AddNumberToObject(h, PROTO_H_BED_TOP_GRAINS, count);
  return 0;
}

static int init(void *user, const proto_msg *welcome, proto_msg *ready, proto_err *err) {
  dem_app *a = user;
  const dem_model *m = &a->model;
  if (add_surface(a, welcome, err) || dem_state_init(m, &a->state, a->run_dt, err)) return -1;
  a->have_state = 1;
  a->logged[0] = -1;
  log_threads(a);
  if (m->cfg.bed_file[0] && a->restart_step == 0 && continue_bed(a, err)) return -1;
  /* a restart's state (dem_state_import into a fresh state, bitwise) takes
   * the place of the settled bed: no need to settle it first */
  if (m->cfg.settle_steps > 0 && a->restart_step > 0)
    fprintf(stderr, "dem_server: restart from step %lld: not settling (the checkpoint "
            "has the bed)\n", (long long)a->restart_step);
  else if (m->cfg.settle_steps > 0) {
    double t0 = proto_now();
    int64_t steps = 0;
    if (dem_bed_settle(m, &a->state, report, a->peer, &steps, err)) return -1;
    fprintf(stderr, "dem_server: bed of %d grains settled in %lld steps (%.1f s), KE %.3g J", m->n_grains,
            (long long)steps, proto_now() - t0, a->state.kinetic_energy);
    if (m->cfg.prep.on)
      fprintf(stderr, " (prepared: friction %g, rolling friction %g, then the scene's laws)",
              m->cfg.prep.friction, m->cfg.prep.rolling);
    if (m->cfg.substrate_steps > 0)
      fprintf(stderr, " (its substrate of %d grains settled alone first, in %lld steps of its own)",
              m->cfg.substrate_grains, (long long)m->cfg.substrate_steps);
    fprintf(stderr, "\n");
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

/* The surface of the request: dense, or the k nodes of x_index (v_index the
 * same) inside the reach box the header gives (*k = -1: dense). */
static int set_surface(dem_app *a, const proto_msg *req, double *reach, int64_t *k,
                       proto_err *err) {
  const dem_model *m = &a->model;
  const int32_t *xi, *vi;
  *k = proto_msg_sparse(req, PROTO_A_X, &xi);
  const int64_t kv = proto_msg_sparse(req, PROTO_A_V, &vi);
  double grains[6]; /* with sleep: the box the last done reported before the region's growth */
  if (m->sleep.on) {
    dem_reach_box(m, &a->state, a->run_dt, grains);
    dem_sleep_jump_box(&a->state, grains, a->run_dt);
  }
  if (*k < 0 && kv < 0) {
    a->state.mesh_live[a->surface] = NULL;
    dem_mesh_set_nodes(m, &a->state, a->surface, proto_msg_data(req, PROTO_A_X),
                       proto_msg_data(req, PROTO_A_V));
    return 0;
  }
  if (*k != kv || memcmp(xi, vi, sizeof(int32_t) * (size_t)(*k > 0 ? *k : 0)) != 0)
    return proto_fail(err, "step: %s and %s must list the same nodes", PROTO_A_X_INDEX,
                      PROTO_A_V_INDEX);
  const cJSON *b = cJSON_GetObjectItemCaseSensitive(req->header, PROTO_H_REACH);
  int ok = cJSON_IsArray(b) && cJSON_GetArraySize(b) == 6;
  for (int d = 0; ok && d < 6; d++) {
    const cJSON *e = cJSON_GetArrayItem(b, d);
    ok = cJSON_IsNumber(e) && isfinite(e->valuedouble);
    if (ok) reach[d] = e->valuedouble;
  }
  if (!ok)
    return proto_fail(err, "step: %s needs the header %s [lo x, y, z, hi x, y, z] it was "
                      "chosen by", PROTO_A_X_INDEX, PROTO_H_REACH);
  dem_mesh_set_nodes_sparse(m, &a->state, a->surface, *k, xi, proto_msg_data(req, PROTO_A_X),
                            proto_msg_data(req, PROTO_A_V), a->node_seen, a->tri_live);
  /* with sleep the grains are checked against their own box (inside the one
   * sent): the region's grains box then stays inside what dem_sleep_reach grew */
  if (m->sleep.on) memcpy(reach, grains, sizeof grains);
  return 0;
}

/* A grain left the box the coupler chose the surface by: this step's
 * contacts may miss triangles it did not send. */
static int escaped(const dem_state *s, int i, const double *b, int64_t k, proto_err *err) {
  const double *x = &s->x[3 * i];
  return proto_fail(err, "coupling step %lld: sparse exchange: grain %d (at %.6g, %.6g, %.6g m, "
                    "radius %.3g m) left the reach box [%.6g, %.6g, %.6g] - [%.6g, %.6g, %.6g] m "
                    "the surface was sent by; it moved farther within one step than the margin "
                    "allows (dem_nodeset.c): run with coupling.sparse false",
                    (long long)k, s->id[i], x[0], x[1], x[2], s->radius[i], b[0], b[1], b[2],
                    b[3], b[4], b[5]);
}

/* nodal_force into the reply: sparse (index, rows) when asked and at most a
 * third of the nodes carry a force, else dense; with sparse, the reach box
 * of the next step in the header. */
static int add_force(dem_app *a, proto_msg *reply, int sparse, int64_t *rows) {
  const dem_model *m = &a->model;
  const int64_t n = m->meshes[a->surface].n_nodes;
  const int64_t k = sparse ? proto_sparse_rows(a->surface_force, n, a->force_index, a->force_rows) : -1;
  if (sparse) {
    double box[6], per_speed;
    dem_reach_box(m, &a->state, a->run_dt, box);
    dem_sleep_reach(m, &a->state, box, &per_speed);
    cJSON_AddItemToObject(proto_msg_header(reply), PROTO_H_REACH, cJSON_CreateDoubleArray(box, 6));
    if (per_speed > 0) cJSON_AddNumberToObject(proto_msg_header(reply), PROTO_H_REACH_SPEED, per_speed);
  }
  *rows = k >= 0 && 3 * k <= n ? k : n;
  if (k >= 0 && 3 * k <= n)
    return proto_msg_add_i4(reply, PROTO_A_NODAL_FORCE_INDEX, k, 0, a->force_index) ||
           proto_msg_add_f8(reply, PROTO_A_NODAL_FORCE, k, 3, a->force_rows);
  return proto_msg_add_f8(reply, PROTO_A_NODAL_FORCE, n, 3, a->surface_force);
}

/* The active block's counters for the log (sleep): rebuilds, full, wake, the
 * grains waiting to fall asleep summed over the checks, the checks, and the
 * mesh lists built for the surface's moves and kept through moves clear of
 * the grains. */
static void log_counts(const dem_state *s, int64_t c[7]) {
  c[0] = s->rebuilds;
  dem_rebuild_kinds(s, &c[1], &c[2]);
  dem_sleep_waiting(s, &c[3], &c[4]);
  dem_mesh_list_counts(s, &c[5], &c[6]);
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
  const int sparse = cJSON_IsTrue(cJSON_GetObjectItemCaseSensitive(req->header, PROTO_H_SPARSE));
  double reach[6];
  int64_t k_x = -1;
  /* checked against the role table by the participant loop */
  if (a->surface >= 0 && set_surface(a, req, reach, &k_x, err) < 0) return -1;
  /* equal sub-steps s->dt = dt/nsub (dem_state_set_dt): the impulse/dt of a
   * force sampled once per sub-step is the mean of the samples */
  long long nsub = llround(dt / s->dt);
  if (nsub < 1) nsub = 1;
  if (a->logged[0] < 0) log_counts(s, a->logged); /* the run's first step: the bed's rebuilds are not its */
  for (long long k = 0; k < nsub; k++) {
    if (dem_step(m, s, err)) return proto_wrap(err, "coupling step %lld", (long long)info->k);
    const int out = k_x >= 0 ? dem_reach_escaped(s, reach) : -1;
    if (out >= 0) return escaped(s, out, reach, info->k, err);
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
  int64_t k_f = 0;
  if (a->surface >= 0 && add_force(a, reply, sparse, &k_f)) return proto_fail(err, "reply full");
  if (a->surface >= 0 && sparse && info->output)
    fprintf(stderr, "dem_server: t = %.6g s: sparse exchange: x, v of %lld of %d nodes, nodal "
            "force of %lld\n", t, (long long)(k_x >= 0 ? k_x : m->meshes[a->surface].n_nodes),
            m->meshes[a->surface].n_nodes, (long long)k_f);
  if (info->output && m->sleep.on) { /* the active block (dem_sleep.c); its rebuilds are its overhead */
    int64_t r[7];
    log_counts(s, r);
    const int64_t *l = a->logged, full = r[1] - l[1], wake = r[2] - l[2], checks = r[4] - l[4];
    fprintf(stderr, "dem_server: t = %.6g s: %lld of %d grains active (sleep), %.0f of them at rest outside the "
            "region (mean); list rebuilds since the last output: %lld partial, %lld full, %lld wake; "
            "mesh lists built for the surface's moves: %lld, kept through moves clear of the grains: "
            "%lld\n", t, (long long)(s->n - s->sleeping), s->n,
            checks > 0 ? (double)(r[3] - l[3]) / (double)checks : 0.0,
            (long long)(r[0] - l[0] - full - wake), (long long)full, (long long)wake, (long long)(r[5] - l[5]),
            (long long)(r[6] - l[6]));
    memcpy(a->logged, r, sizeof r);
  }
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
  free(a->wall_row); free(a->surface_force);
  free(a->force_index); free(a->force_rows); free(a->node_seen); free(a->tri_live); free(a->snap_x); free(a->snap_v); free(a->snap_w); free(a->snap_r);
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
