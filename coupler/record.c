/* record.c — the record stage: after each step, each process's series and
 * snapshots into results.h5 and onto the monitor bus, the coupler's own
 * series (wall time, the implicit scheme's iterations and residuals), the
 * traction and the dbp rig's rows (scenario.c computes them), and the run's
 * progress on the terminal and the bus. */
#include "runner.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

/* The traction row of step k (scenario.c) from the current fields. */
static void traction(const cpl_runner *r, double t, double *row) {
  cpl_traction(r->data.fields[CPL_F_SURF_FORCE].cur, r->data.fields[CPL_F_SURF_X].cur, r->plan->surf.n_nodes,
               &r->data.rim, t, row);
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

/* tire_road's /coupler/lugs row: t, lugs taken so far, the road's penalty
 * force, then per lug process the lug it serves (-1: none), its approach,
 * force, centre of pressure, and where its face is: x ahead of the rim's
 * centre (the place in the footprint) and y (world). */
static int lug_row(cpl_runner *r, int64_t k, double t) {
  double row[3 + CPL_LUG_COLS * CPL_MAX_PROCS];
  const cpl_lug_slots *S = &r->data.lug;
  const double *d = r->data.fields[CPL_F_LUG_D].cur, *F = r->data.fields[CPL_F_LUG_FORCE].cur;
  const double *cop = r->data.fields[CPL_F_LUG_COP].cur;
  const double *o = r->data.fields[CPL_F_LUG_ORIGIN].cur;
  row[0] = t, row[1] = (double)S->handovers, row[2] = r->data.lug_penalty;
  for (int p = 0; p < S->n; p++) {
    double *q = &row[3 + CPL_LUG_COLS * p];
    const int on = S->lug[p] >= 0;
    q[0] = S->lug[p], q[1] = d[p], q[2] = F[p], q[3] = cop[2 * p], q[4] = cop[2 * p + 1];
    q[5] = S->ahead[p], q[6] = on ? o[2 * p + 1] : 0;
  }
  const int n = r->plan->n_lug_cols;
  if (cpl_output_coupler_row(r->out, "lugs", n, r->plan->lug_cols, row, &r->err) < 0) return -1;
  publish(r, "coupler.lugs", "series", k, t, n, row, r->plan->lug_cols);
  return 0;
}

/* (fields, replies of step k, rim) -> (results.h5 rows and snapshots, bus) */
int cpl_record(cpl_runner *r, int64_t k, int output) {
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
  double crow[N_CS] = {t, proto_now() - r->wall_start, r->data.iterations, r->data.converged,
                       r->data.residual[CPL_IF_X], r->data.residual[CPL_IF_F], r->data.residual[CPL_IF_ROAD]};
  if (cpl_output_coupler_row(r->out, PROTO_A_SERIES, N_CS, coupler_cols, crow, &r->err) < 0)
    return -1;
  publish(r, "coupler.series", "series", k, t, N_CS, crow, coupler_cols);
  if (cpl_scenario_rolls(r->scene->scenario.kind)) {
    double row[CPL_N_TRACTION];
    traction(r, t, row);
    if (cpl_output_coupler_row(r->out, "traction", CPL_N_TRACTION, traction_cols, row,
                               &r->err) < 0)
      return -1;
    publish(r, "coupler.traction", "series", k, t, CPL_N_TRACTION, row, traction_cols);
    if (r->plan->n_of_role[PROTO_ROLE_LUG] && lug_row(r, k, t) < 0) return -1;
    if (r->scene->scenario.rig == CPL_RIG_DBP) { /* /coupler/dbp (scenario.c cpl_dbp_row) */
      double drow[CPL_N_DBP];
      cpl_dbp_row(&r->data.rim, &r->scene->scenario, r->scene->dt, row, drow);
      if (cpl_output_coupler_row(r->out, "dbp", CPL_N_DBP, cpl_dbp_columns, drow, &r->err) < 0)
        return -1;
      publish(r, "coupler.dbp", "series", k, t, CPL_N_DBP, drow, cpl_dbp_columns);
    }
  }
  /* at output steps everything so far goes to the disk: a run that fails
   * later keeps it */
  return output ? cpl_output_flush(r->out, &r->err) : 0;
}


/* (step k, steps per second) -> (the terminal's progress line, coupler.progress) */
void cpl_progress(cpl_runner *r, int64_t k, double rate, int final) {
  show_progress(r, k, rate, final);
  publish_progress(r, k, rate);
}
