/* timing.c — where the time of a coupled step goes: compute / waiting /
 * transfer per process (MUSCLE3's event taxonomy, Veen & Hoekstra 2020;
 * Chrono's "sim time vs total time", Serban et al. 2018). Per step and
 * process:
 *   compute   seconds the process spent in its step (its own report in
 *             `done`, incl. state save/restore),
 *   transfer  request sent → reply received, minus compute: both sides'
 *             encode/decode and the sockets,
 *   waiting   the rest of the step's wall time: idle while others compute
 *             or the coupler works;
 * and the coupler's own mapping (requests, fields, actions, acceleration)
 * and output (HDF5, bus). One row per step in /coupler/timing (columns in
 * the "columns" attribute) and on the bus ("coupler.timing"); the totals as
 * a table when the run ends. */
#include "runner.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { TM_T, TM_WALL, TM_MAP, TM_OUTPUT, N_TM };
static const char *const fixed_cols[N_TM] = {"t", "wall", "coupler.mapping",
                                             "coupler.output"};
enum { TP_COMPUTE, TP_TRANSFER, TP_WAIT, N_TP };
static const char *const proc_cols[N_TP] = {"compute", "transfer", "waiting"};

#define N_COLS (N_TM + N_TP * CPL_MAX_PROCS)

struct cpl_timing {
  int ncols;
  char names[N_COLS][2 * PROTO_NAME_LEN];
  const char *cols[N_COLS];
  double row[N_COLS];
  double total[N_COLS]; /* sums over the steps (t column unused) */
  int64_t steps;
};

static int col(int proc, int what) { return N_TM + N_TP * proc + what; }

cpl_timing *cpl_timing_create(const cpl_runner *r) {
  cpl_timing *t = calloc(1, sizeof *t);
  if (!t) return NULL;
  t->ncols = N_TM + N_TP * r->n;
  for (int c = 0; c < N_TM; c++) snprintf(t->names[c], sizeof t->names[c], "%s", fixed_cols[c]);
  for (int i = 0; i < r->n; i++)
    for (int w = 0; w < N_TP; w++)
      snprintf(t->names[col(i, w)], sizeof t->names[0], "%s.%s", r->peers[i].proc->name,
               proc_cols[w]);
  for (int c = 0; c < t->ncols; c++) t->cols[c] = t->names[c];
  return t;
}

void cpl_timing_free(cpl_timing *t) { free(t); }

void cpl_timing_reply(cpl_runner *r, int i, double now, double compute) {
  cpl_peer *p = &r->peers[i];
  p->busy += now - p->t_sent;
  p->compute += compute;
}

/* (per-process times of step k) -> (/coupler/timing row, bus) */
int cpl_timing_step(cpl_runner *r, int64_t k, double wall, double output_s) {
  cpl_timing *t = r->timing;
  double *row = t->row;
  row[TM_T] = (double)k * r->scene->dt;
  row[TM_WALL] = wall;
  row[TM_OUTPUT] = output_s;
  row[TM_MAP] = wall - r->t_blocked - output_s;
  for (int i = 0; i < r->n; i++) {
    cpl_peer *p = &r->peers[i];
    double transfer = p->busy - p->compute;
    row[col(i, TP_COMPUTE)] = p->compute;
    row[col(i, TP_TRANSFER)] = transfer > 0 ? transfer : 0;
    row[col(i, TP_WAIT)] = wall - p->busy;
    p->busy = p->compute = 0;
  }
  for (int c = 1; c < t->ncols; c++) t->total[c] += row[c];
  t->steps++;
  if (cpl_output_coupler_row(r->out, "timing", t->ncols, t->cols, row, &r->err) < 0)
    return -1;
  void *pub = cpl_bus_pub(r->bus);
  if (pub) {
    proto_msg m = {0};
    proto_msg_reset(&m, "coupler.timing", "timing", k, row[TM_T]);
    cJSON_AddItemToObject(proto_msg_header(&m), "columns",
                          cJSON_CreateStringArray(t->cols, t->ncols));
    proto_msg_add_f8(&m, PROTO_A_SERIES, t->ncols, 0, row);
    proto_publish(pub, &m);
    proto_msg_free(&m);
  }
  return 0;
}

static void line(FILE *f, const char *what, double total, double loop, int64_t steps) {
  fprintf(f, "  %-28s | %10.3f | %6.1f | %12.4f\n", what, total,
          loop > 0 ? 100 * total / loop : 0, steps ? 1e3 * total / (double)steps : 0);
}

/* Like LAMMPS' "Loop time" breakdown: per process, its compute, transfer
 * and waiting time (the three add up to the loop time); the coupler's. */
void cpl_timing_print(const cpl_runner *r, FILE *f) {
  const cpl_timing *t = r->timing;
  if (!t || !t->steps) return;
  const double loop = t->total[TM_WALL];
  fprintf(f, "Loop time %.3f s for %lld steps (%.4f ms/step), scheme %s\n", loop,
          (long long)t->steps, 1e3 * loop / (double)t->steps,
          cpl_scheme_name(r->scene->scheme));
  fprintf(f, "  %-28s | %10s | %6s | %12s\n", "section", "total (s)", "% loop",
          "per step (ms)");
  for (int i = 0; i < r->n; i++)
    for (int w = 0; w < N_TP; w++) line(f, t->names[col(i, w)], t->total[col(i, w)], loop, t->steps);
  line(f, fixed_cols[TM_MAP], t->total[TM_MAP], loop, t->steps);
  line(f, fixed_cols[TM_OUTPUT], t->total[TM_OUTPUT], loop, t->steps);
  for (int i = 0; i < r->n; i++) { /* the doorbell (PROTOCOL.md "Shared memory") */
    const uint64_t sent = r->peers[i].shm_sent, posted = r->peers[i].shm_posted;
    if (!r->peers[i].shm_on) continue;
    fprintf(f, "  shm %s: %llu of %llu messages to it posted in the segment (the rest "
            "on the socket)\n", r->peers[i].proc->name, (unsigned long long)posted,
            (unsigned long long)sent);
  }
}
