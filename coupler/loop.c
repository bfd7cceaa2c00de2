/* loop.c — the coupling schemes over the schedule (PROTOCOL.md "Schemes";
 * docs/coupling-schemes.md; Gatzhammer 2014; Degroote et al. 2009):
 *   serial    the stages in order, each committed before the next (the
 *             grains' forces of step k reach the tread in step k);
 *   parallel  one stage, every process at once on the last committed fields
 *             (the tread gets the grains' forces one step late: Jacobi);
 *   implicit  the parallel stage repeated until the interface fields stop
 *             changing, accelerated (IQN-ILS, Aitken or constant), the
 *             processes rolled back between repeats.
 * Then the rows of the step: each process's series and snapshots, traction,
 * the coupler's series and timing. */
#include "runner.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ---------------------------------------------------------- implicit */

/* The interface vector of the implicit scheme: what one process gives and
 * another takes within the same step. [surface positions at t_k | surface
 * forces | road force (force-driven road only)]. The DEM takes the
 * positions through the secant velocity (d - x_{k-1})/dt, so its surface
 * moves exactly from the tread's x_{k-1} to its x_k within the step. */
enum { IF_X, IF_F, IF_ROAD, N_IF };

static int road_coupled(const cpl_runner *r) {
  const cpl_scenario *s = &r->scene->scenario;
  return r->plan.n_of_role[PROTO_ROLE_BLOCK] && s->kind == CPL_SCN_INDENTATION &&
         s->profile == CPL_PROFILE_FORCE;
}

static int64_t if_len(const cpl_runner *r, int f) {
  int surface = r->plan.fem >= 0 && r->plan.n_of_role[PROTO_ROLE_DEM];
  return f == IF_ROAD ? road_coupled(r) : surface ? 3 * r->plan.surf.n_nodes : 0;
}

static int implicit_init(cpl_runner *r) {
  int64_t len[N_IF], total = 0;
  for (int f = 0; f < N_IF; f++) total += len[f] = if_len(r, f);
  size_t n3 = sizeof(double) * (size_t)(3 * r->plan.surf.n_nodes + 1);
  r->xi = calloc((size_t)total + 1, sizeof(double));
  r->xt = calloc((size_t)total + 1, sizeof(double));
  r->x_start = calloc(1, n3);
  r->v_dem = calloc(1, n3);
  r->f_fem = calloc(1, n3);
  r->carry = calloc(1, n3);
  if (!r->xi || !r->xt || !r->x_start || !r->v_dem || !r->f_fem || !r->carry)
    return proto_fail(&r->err, "out of memory (implicit scheme)");
  r->accel = cpl_accel_create(&r->scene->implicit, N_IF, len, &r->err);
  return r->accel ? 0 : -1;
}

/* Road body at t_k by the trapezoidal rule with the force of t_k
 * (scenario.c): the implicit counterpart of the explicit road action. */
static double road_trapezoid(const cpl_runner *r, double force, double *v, double *a) {
  return cpl_road_trapezoid(&r->road, &r->scene->scenario, r->scene->dt, force, v, a);
}

/* Sets the requests' inputs from the iterate xi. */
static void implicit_inputs(cpl_runner *r) {
  const int64_t nx = if_len(r, IF_X), nf = if_len(r, IF_F);
  const double *d = r->xi, *f = r->xi + nx, dt = r->scene->dt;
  for (int64_t j = 0; j < nx; j++) r->v_dem[j] = (d[j] - r->x_start[j]) / dt;
  for (int64_t j = 0; j < nf; j++) r->f_fem[j] = f[j] + r->carry[j];
  r->in[CPL_F_SURF_X] = r->x_start;
  r->in[CPL_F_SURF_V] = nx ? r->v_dem : r->fields[CPL_F_SURF_V].cur;
  r->in[CPL_F_SURF_FORCE] = nf ? r->f_fem : r->fields[CPL_F_SURF_FORCE].cur;
  if (road_coupled(r)) {
    double v, a;
    r->road_iter = r->xi[nx + nf];
    r->fields[CPL_F_ROAD_D].cur[0] = road_trapezoid(r, r->road_iter, &v, &a);
  }
}

/* H(xi): what the processes returned, as an interface vector. */
static void implicit_outputs(cpl_runner *r) {
  const int64_t nx = if_len(r, IF_X), nf = if_len(r, IF_F);
  memcpy(r->xt, r->fields[CPL_F_SURF_X].out, sizeof(double) * (size_t)nx);
  memcpy(r->xt + nx, r->fields[CPL_F_SURF_FORCE].out, sizeof(double) * (size_t)nf);
  if (road_coupled(r)) r->xt[nx + nf] = r->fields[CPL_F_ROAD_FORCE].out[0];
}

/* After the last iteration: the processes' last outputs become the fields.
 * The tread received f_iter + carry while the grains felt f_out: the
 * difference (at most the tolerance) is carried into the next step's force,
 * so the impulses balance exactly over the run (one defect in flight). */
static void implicit_commit(cpl_runner *r) {
  const int64_t nf = if_len(r, IF_F);
  const double *f_out = r->fields[CPL_F_SURF_FORCE].out;
  /* defect so far = old defect + f_out - f_fem, with f_fem = iterate + old */
  for (int64_t j = 0; j < nf; j++) r->carry[j] += f_out[j] - r->f_fem[j];
  for (int f = 0; f < CPL_N_FIELDS; f++)
    if (f != CPL_F_ROAD_D && r->fields[f].given) cpl_field_commit(r, (cpl_field_id)f);
  if (road_coupled(r)) {
    double v, a;
    r->road.d = road_trapezoid(r, r->road_iter, &v, &a);
    r->road.v = v;
    r->road.a = a;
  }
  cpl_inputs_current(r);
}

static int implicit_step(cpl_runner *r, int64_t k, int output) {
  const int64_t nx = if_len(r, IF_X), nf = if_len(r, IF_F);
  const cpl_field *X = &r->fields[CPL_F_SURF_X], *V = &r->fields[CPL_F_SURF_V];
  const double dt = r->scene->dt;
  /* actions once, at the start (with the last step's load) */
  for (int e = 0; e < r->plan.nex; e++)
    if (r->plan.ex[e].peer < 0 && !(road_coupled(r) && r->plan.ex[e].action == CPL_ACT_ROAD) &&
        cpl_do_action(r, r->plan.ex[e].action, k) < 0)
      return -1;
  /* start: x_{k-1}; guess d_k = x_{k-1} + dt v, forces of the last step */
  memcpy(r->x_start, X->cur, sizeof(double) * (size_t)nx);
  for (int64_t j = 0; j < nx; j++) r->xi[j] = X->cur[j] + dt * V->cur[j];
  memcpy(r->xi + nx, r->fields[CPL_F_SURF_FORCE].cur, sizeof(double) * (size_t)nf);
  if (road_coupled(r)) r->xi[nx + nf] = r->road.force_last;
  const double *base[N_IF] = {r->x_start, NULL, NULL};
  cpl_accel_begin(r->accel);
  r->converged = 0;
  int it;
  for (it = 0; it < r->scene->implicit.max_iterations; it++) {
    implicit_inputs(r);
    if (cpl_run_stages(r, 0, cpl_last_stage(r), k, it, output, 0, 0) < 0) return -1;
    implicit_outputs(r);
    r->converged = cpl_accel_next(r->accel, r->xi, r->xt, base, r->residual);
    if (r->converged) break;
  }
  r->iterations = it < r->scene->implicit.max_iterations ? it + 1 : it;
  if (!r->converged) r->steps_unconverged++; /* the last outputs are kept */
  cpl_accel_end(r->accel);
  implicit_commit(r);
  return 0;
}

/* ---------------------------------------------------------- recording */

/* The traction row of step k (scenario.c) from the current fields. */
static void traction(const cpl_runner *r, double t, double *row) {
  cpl_traction(r->fields[CPL_F_SURF_FORCE].cur, r->fields[CPL_F_SURF_X].cur, r->plan.surf.n_nodes,
               &r->rim, t, row);
}

static const char *const traction_cols[CPL_N_TRACTION] = {
    "t", "T_H", "T_R", "T_P", "vertical_load", "sinkage", "torque"};

/* A row of the coupler's own series on the bus, its column names in the
 * header (as coupler.timing) so that a monitor can name what it plots. */
static void publish(cpl_runner *r, const char *topic, const char *type, int64_t k,
                    double t, int n, const double *row, const char *const *cols) {
  void *pub = cpl_bus_pub(r->bus);
  if (!pub) return;
  proto_msg m = {0};
  proto_msg_reset(&m, topic, type, k, t);
  proto_msg_add_f8(&m, PROTO_A_SERIES, n, 0, row);
  cJSON_AddItemToObject(proto_msg_header(&m), "columns", cJSON_CreateStringArray(cols, n));
  proto_publish(pub, &m);
  proto_msg_free(&m);
}

static int publish_reply(cpl_runner *r, int i, int output) {
  void *pub = cpl_bus_pub(r->bus);
  if (!pub) return 0;
  const proto_msg *d = &r->peers[i].reply;
  proto_msg m = {0};
  /* snapshots only when a monitor subscribes to them (bus.c): else no copy */
  for (int pass = 0; pass < 1 + (output && cpl_bus_snapshots_wanted(r->bus)); pass++) {
    const char *prefix = pass == 0 ? PROTO_A_SERIES : PROTO_P_SNAP;
    const char *what = pass == 0 ? "series" : "snapshot";
    char topic[PROTO_NAME_LEN];
    snprintf(topic, sizeof topic, "%s.%s", r->peers[i].proc->name, what);
    proto_msg_reset(&m, topic, what, d->step, d->t);
    for (int a = 0; a < d->narrays; a++)
      if (strncmp(d->arrays[a].name, prefix, strlen(prefix)) == 0)
        proto_msg_add(&m, d->arrays[a].name, d->arrays[a].dtype,
                      d->arrays[a].ndim, d->arrays[a].shape, d->arrays[a].data);
    if (m.narrays) proto_publish(pub, &m);
  }
  proto_msg_free(&m);
  return 0;
}

static void publish_progress(cpl_runner *r, int64_t k, double rate) {
  void *pub = cpl_bus_pub(r->bus);
  if (!pub) return;
  proto_msg m = {0};
  double t = (double)k * r->scene->dt;
  proto_msg_reset(&m, "coupler.progress", "progress", k, t);
  cJSON *h = proto_msg_header(&m);
  cJSON_AddNumberToObject(h, "n_steps", (double)r->scene->n_steps);
  cJSON_AddNumberToObject(h, "steps_per_s", rate);
  cJSON_AddNumberToObject(h, "eta_s",
                          rate > 0 ? (double)(r->scene->n_steps - k) / rate : -1);
  proto_publish(pub, &m);
  proto_msg_free(&m);
}

/* One status line on a terminal; else (a batch run's log) a line per tenth
 * of the run, so a long run shows where it is and when it will end. */
static void show_progress(cpl_runner *r, int64_t k, double rate, int final) {
  if (r->opts->quiet) return;
  const int64_t n = r->scene->n_steps;
  double eta = rate > 0 ? (double)(n - k) / rate : 0;
  if (r->opts->progress) {
    fprintf(stderr, "\r  step %lld/%lld  t = %.4g s  %.0f steps/s  ETA %.0f s   %s",
            (long long)k, (long long)n, (double)k * r->scene->dt, rate, eta, final ? "\n" : "");
    fflush(stderr);
    return;
  }
  int tenth = n > 0 ? (int)(10 * k / n) : 10;
  if (tenth <= r->progress_shown) return;
  r->progress_shown = tenth;
  printf("cosim: step %lld/%lld (%.0f %%), t = %.4g s, %.0f steps/s, ETA %.0f s\n", (long long)k,
         (long long)n, 100.0 * (double)k / (double)n, (double)k * r->scene->dt, rate, eta);
  fflush(stdout);
}

/* The coupler's own series: wall time and, for the implicit scheme, the
 * iterations of the step, whether it converged and the relative residual
 * of each interface field at exit. */
enum { CS_T, CS_WALL, CS_ITER, CS_CONV, CS_RES_X, CS_RES_F, CS_RES_ROAD, N_CS };
static const char *const coupler_cols[N_CS] = {
    "t", "wall_s", "iterations", "converged", "residual_x", "residual_force",
    "residual_road"};

/* (fields, replies of step k, rim) -> (results.h5 rows and snapshots, bus) */
static int record(cpl_runner *r, int64_t k, int output) {
  for (int i = 0; i < r->n; i++) {
    if (cpl_output_done(r->out, r->peers[i].proc->name, &r->peers[i].reply,
                        output, &r->err) < 0) {
      /* a write error is the disk's, not the participant's */
      if (!cpl_output_io_failed(r->out)) r->failed_peer = i;
      return proto_wrap(&r->err, "output of '%s'", r->peers[i].proc->name);
    }
    publish_reply(r, i, output);
  }
  double t = (double)k * r->scene->dt;
  double crow[N_CS] = {t, proto_now() - r->wall_start, r->iterations, r->converged,
                       r->residual[IF_X], r->residual[IF_F], r->residual[IF_ROAD]};
  if (cpl_output_coupler_row(r->out, PROTO_A_SERIES, N_CS, coupler_cols, crow, &r->err) < 0)
    return -1;
  publish(r, "coupler.series", "series", k, t, N_CS, crow, coupler_cols);
  if (r->scene->scenario.kind == CPL_SCN_TIRE_TRAVEL) {
    double row[CPL_N_TRACTION];
    traction(r, t, row);
    if (cpl_output_coupler_row(r->out, "traction", CPL_N_TRACTION, traction_cols, row,
                               &r->err) < 0)
      return -1;
    publish(r, "coupler.traction", "series", k, t, CPL_N_TRACTION, row, traction_cols);
    if (r->scene->scenario.rig == CPL_RIG_DBP) { /* /coupler/dbp (scenario.c cpl_dbp_row) */
      double drow[CPL_N_DBP];
      cpl_dbp_row(&r->rim, &r->scene->scenario, r->scene->dt, row, drow);
      if (cpl_output_coupler_row(r->out, "dbp", CPL_N_DBP, cpl_dbp_columns, drow, &r->err) < 0)
        return -1;
      publish(r, "coupler.dbp", "series", k, t, CPL_N_DBP, drow, cpl_dbp_columns);
    }
  }
  /* at output steps everything so far goes to the disk: a run that fails
   * later keeps it */
  return output ? cpl_output_flush(r->out, &r->err) : 0;
}

/* ---------------------------------------------------------- the loop */

static int one_step(cpl_runner *r, int64_t k, int output) {
  switch (r->scene->scheme) {
  case CPL_SCHEME_IMPLICIT:
    return implicit_step(r, k, output);
  case CPL_SCHEME_SERIAL:
  case CPL_SCHEME_PARALLEL:
    r->iterations = r->converged = 1;
    return cpl_run_stages(r, 0, cpl_last_stage(r), k, 0, output, 1, 1);
  }
  return -1;
}

int cpl_scheme_init(cpl_runner *r) {
  return r->scene->scheme == CPL_SCHEME_IMPLICIT ? implicit_init(r) : 0;
}

/* The orchestrator: per step the scheme's exchange and scenario stages
 * (schedule.c, scenario_step.c), then record, timing and checkpoint. */
int cpl_step_loop(cpl_runner *r) {
  const cpl_scene *s = r->scene;
  cpl_inputs_current(r);
  double last_shown = proto_now(), start = proto_now();
  for (int64_t k = r->k0 + 1; k <= s->n_steps; k++) {
    int output = (k % s->output_every == 0) || k == s->n_steps;
    double t_step = proto_now();
    r->t_blocked = 0;
    int rc = one_step(r, k, output);
    if (rc == 0) r->road.force_last = r->fields[CPL_F_ROAD_FORCE].cur[0];
    double t_rec = proto_now();
    if (rc == 0) rc = record(r, k, output);
    double now = proto_now();
    if (rc == 0) rc = cpl_timing_step(r, k, now - t_step, now - t_rec);
    if (rc == 0 && s->checkpoint_every && k % s->checkpoint_every == 0)
      rc = cpl_checkpoint_write(r, k);
    if (rc < 0) {
      proto_err ignore;
      if (!cpl_output_io_failed(r->out)) cpl_output_flush(r->out, &ignore);
      return proto_wrap(&r->err, "step %lld (t = %g s)", (long long)k,
                        (double)(k - 1) * s->dt);
    }
    if (now - last_shown > 0.5 || k == s->n_steps) {
      double rate = (double)(k - r->k0) / fmax(now - start, 1e-9);
      show_progress(r, k, rate, k == s->n_steps);
      publish_progress(r, k, rate);
      last_shown = now;
    }
  }
  if (r->steps_unconverged)
    fprintf(stderr, "cosim: warning: %lld of %lld steps did not reach "
            "coupling.implicit.tolerance %g within max_iterations %lld "
            "(see /coupler/series)\n", (long long)r->steps_unconverged,
            (long long)s->n_steps, s->implicit.tolerance,
            (long long)s->implicit.max_iterations);
  return 0;
}
