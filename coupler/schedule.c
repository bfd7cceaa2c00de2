/* schedule.c — a coupling step as data: the coupler-side fields, the
 * role table's rows bound to them (contract.c), and the list of exchanges a scheme
 * walks (PROTOCOL.md "Schedule"). A stage sends all its requests, then
 * collects all its replies: its processes compute at the same time.
 * Sparse exchange (PROTOCOL.md "Sparse exchange", coupling.sparse): a dem
 * that gave a reach box gets x, v only for the nodes of the triangles that
 * can meet it; a fem that takes it gets the nodal force only of the nodes
 * that carry one; a sparse reply is expanded to the dense field before it is
 * copied or summed, so every field holds the bits the dense exchange gives. */
#include "runner.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Doubles in one row of a per-process field: the row's literal dims. */
/* The length of one process's row of a per-process field (literal dims, or
 * the lug processes' cells c). */
static int64_t row_len(const cpl_runner *r, const proto_array_spec *s) {
  int64_t m = 1;
  for (int d = 0; d < s->ndim; d++) m *= s->dims[d] == PROTO_DIM_CELLS ? r->plan->lugs.cells : s->dims[d];
  return m;
}

/* Is the array due for this peer (the table's "when")? */
static int due(const cpl_peer *p, const proto_array_spec *s) {
  return s->when != PROTO_WHEN_SURFACE || p->dims.surface;
}

/* A request goes sparse only when it carries at most this fraction of the
 * surface's nodes: beyond it the gather (coupler) and scatter (participant)
 * cost about what the smaller message saves (PROTOCOL.md "Sparse exchange"). */
#define CPL_SPARSE_MAX_FRACTION (1.0 / 3.0)
/* The peers' sparse buffers for a surface of n nodes; fem: does it take a
 * sparse nodal_force (its ready, in its reply slot now)? */
static int sparse_init(cpl_runner *r, int64_t n, proto_err *err) {
  const size_t nn = (size_t)(n > 0 ? n : 1);
  for (int i = 0; i < r->n; i++) {
    cpl_sparse *sp = &r->peers[i].sp;
    sp->index = malloc(sizeof(int32_t) * nn);
    sp->rows[0] = malloc(sizeof(double) * 3 * nn);
    sp->rows[1] = malloc(sizeof(double) * 3 * nn);
    sp->dense = malloc(sizeof(double) * 3 * nn);
    sp->mark = malloc(nn);
    if (!sp->index || !sp->rows[0] || !sp->rows[1] || !sp->dense || !sp->mark)
      return proto_fail(err, "out of memory for the sparse exchange");
  }
  if (r->plan->fem >= 0)
    r->peers[r->plan->fem].sp.takes_force = cJSON_IsTrue(cJSON_GetObjectItemCaseSensitive(
        r->peers[r->plan->fem].reply.header, PROTO_H_SPARSE));
  return 0;
}

int cpl_fields_init(cpl_runner *r, int64_t n, proto_err *err) {
  if (sparse_init(r, n, err) < 0) return -1;
  const cpl_contract *c = &r->plan->contract;
  for (int f = 0; f < c->nfields; f++) {
    cpl_field *fd = &r->data.fields[f];
    fd->name = c->field[f].name;
    fd->len = 1;
    for (int d = 0; d < c->field[f].ndim; d++)
      fd->len *= c->field[f].dims[d] == PROTO_DIM_NODES   ? n
                 : c->field[f].dims[d] == PROTO_DIM_CELLS ? r->plan->lugs.cells
                                                          : c->field[f].dims[d];
    if (c->field[f].per_process) /* a row per process of its role */
      fd->len *= c->field_role[f] >= 0 ? r->plan->n_of_role[c->field_role[f]] : 0;
    size_t bytes = sizeof(double) * (size_t)(fd->len > 0 ? fd->len : 1);
    fd->cur = calloc(1, bytes);
    fd->out = calloc(1, bytes);
    if (!fd->cur || !fd->out) return proto_fail(err, "out of memory for the fields");
  }
  cpl_inputs_current(r);
  return 0;
}

void cpl_fields_free(cpl_runner *r) {
  for (int i = 0; i < r->n; i++) {
    cpl_sparse *sp = &r->peers[i].sp;
    free(sp->index); free(sp->rows[0]); free(sp->rows[1]); free(sp->dense); free(sp->mark);
    sp->index = NULL, sp->rows[0] = sp->rows[1] = sp->dense = NULL, sp->mark = NULL;
  }
  for (int f = 0; f < CPL_MAX_FIELDS; f++) {
    free(r->data.fields[f].cur);
    free(r->data.fields[f].out);
    r->data.fields[f].cur = r->data.fields[f].out = NULL;
  }
}

void cpl_inputs_current(cpl_runner *r) {
  for (int f = 0; f < r->plan->contract.nfields; f++) r->data.in[f] = r->data.fields[f].cur;
}

void cpl_field_commit(cpl_runner *r, int id) {
  cpl_field *f = &r->data.fields[id];
  double *t = f->cur;
  f->cur = f->out;
  f->out = t;
  if (r->data.in[id] == t) r->data.in[id] = f->cur; /* requests follow the current value */
}

/* ------------------------------------------------------------- building */

static void add(cpl_plan *p, int stage, int peer, cpl_action a) {
  if (p->nex < CPL_MAX_EXCHANGES) p->ex[p->nex++] = (cpl_exchange){stage, peer, a};
}

static void add_role(cpl_plan *p, const cpl_peer *peers, int n, int stage, int role) {
  for (int i = 0; i < n; i++)
    if ((int)peers[i].role == role) add(p, stage, i, CPL_ACT_NONE);
}

/* serial (Gauss–Seidel): the contract's order of the step (contract.c), a
 * role's processes in their order. parallel and implicit: the order's
 * actions first (with the last step's load), then every process of its
 * roles, in the order's order, all in one stage. */
void cpl_schedule_build(cpl_plan *p, const cpl_peer *peers, int n, cpl_scheme scheme) {
  const cpl_contract *c = &p->contract;
  p->nex = 0;
  for (int pass = 0; pass < 2; pass++)
    for (int s = 0; s < c->nstages; s++) {
      const cpl_stage_row *o = &c->stage[s];
      const int stage = scheme == CPL_SCHEME_SERIAL ? o->stage : 0;
      if (scheme == CPL_SCHEME_SERIAL ? pass : (pass == 0) != (o->role < 0)) continue;
      if (o->role < 0) add(p, stage, -1, o->action);
      else add_role(p, peers, n, stage, o->role);
    }
}

void cpl_sparse_print(const cpl_runner *r, FILE *f) {
  if (!r->scene->sparse || !r->plan->surf.n_nodes) return;
  fprintf(f, "sparse exchange (coupling.sparse; surface arrays, bytes as a share of dense):\n");
  for (int i = 0; i < r->n; i++) {
    const cpl_sparse *sp = &r->peers[i].sp;
    if (sp->out_dense <= 0 && sp->in_dense <= 0) continue;
    fprintf(f, "  %-12s to it %5.1f %% (%.4g MB), from it %5.1f %% (%.4g MB)\n",
            r->peers[i].proc->name, sp->out_dense > 0 ? 100 * sp->out_bytes / sp->out_dense : 0,
            sp->out_bytes / 1e6, sp->in_dense > 0 ? 100 * sp->in_bytes / sp->in_dense : 0,
            sp->in_bytes / 1e6);
  }
}

int cpl_last_stage(const cpl_runner *r) {
  return r->plan->nex ? r->plan->ex[r->plan->nex - 1].stage : 0;
}

void cpl_schedule_print(const cpl_runner *r, FILE *f) {
  static const char *const actions[] = {"", "rim frame <- vertical load (scenario)",
                                        "road displacement (scenario)",
                                        "lugs -> lug processes, their approach (scenario)",
                                        "lug forces + road penalty -> surface force (scenario)"};
  fprintf(f, "schedule (%s):\n", cpl_scheme_name(r->scene->scheme));
  for (int s = 0; s <= cpl_last_stage(r); s++) {
    int any = 0;
    for (int e = 0; e < r->plan->nex; e++) {
      const cpl_exchange *x = &r->plan->ex[e];
      if (x->stage != s) continue;
      if (x->peer < 0) {
        if ((x->action == CPL_ACT_RIM && !cpl_scenario_rolls(r->scene->scenario.kind)) ||
            (x->action == CPL_ACT_ROAD && !r->plan->n_of_role[PROTO_ROLE_BLOCK]) ||
            ((x->action == CPL_ACT_LUG || x->action == CPL_ACT_LUG_FORCE) &&
             !r->plan->n_of_role[PROTO_ROLE_LUG]))
          continue;
        fprintf(f, "  %d. coupler: %s\n", s + 1, actions[x->action]);
        continue;
      }
      const cpl_peer *p = &r->peers[x->peer];
      fprintf(f, "  %d.%s %s (%s) [%s]:", s + 1, any++ ? " +" : "", p->proc->name,
              proto_role_name(p->role), p->shm_on ? "shm" : "tcp/ipc");
      for (int pass = 0; pass < 2; pass++) {
        fprintf(f, "%s", pass ? " ->" : "");
        for (int b = 0; b < r->plan->contract.n; b++) {
          const cpl_binding *bd = &r->plan->contract.b[b];
          if (bd->role != p->role || bd->msg != (pass ? PROTO_MSG_DONE : PROTO_MSG_STEP) ||
              !due(p, bd->spec))
            continue;
          fprintf(f, " %s%s", bd->array, pass && bd->sum ? " (summed)" : "");
        }
      }
      fprintf(f, "\n");
    }
  }
  /* the transport of each process (PROTOCOL.md "Shared memory") and why not shm */
  for (int i = 0; i < r->n; i++)
    if (!r->peers[i].shm_on)
      fprintf(f, "  %s: arrays by tcp/ipc (%s)\n", r->peers[i].proc->name,
              r->peers[i].shm_why[0] ? r->peers[i].shm_why : "no shared memory");
  fprintf(f, "  affinity: %s\n", r->affinity.why); /* affinity.c */
}

/* ------------------------------------------------------------- exchanges */

/* ------------------------------------------------------ sparse exchange */

/* The nodes a dem gets this step (proto_reach_nodes: the contract of
 * x_index): those of every triangle that can meet the reach box the dem
 * gave, over the step. With reach_speed (a dem with sleep: its active
 * region's margin grows with the surface's speed) the box grows by that
 * times the largest node speed |v| of the step, and that node goes too (the
 * dem takes the speed from the nodes it gets: the same as dense). */
static int64_t reach_nodes(const cpl_runner *r, cpl_sparse *sp) {
  const double *v = r->data.in[CPL_F_SURF_V];
  const int64_t n = r->plan->surf.n_nodes;
  double box[6], v2 = 0;
  int64_t fast = -1;
  memcpy(box, sp->reach_use, sizeof box);
  for (int64_t a = 0; sp->speed_use > 0 && a < n; a++) {
    const double *u = &v[3 * a], q = u[0] * u[0] + u[1] * u[1] + u[2] * u[2]; /* as dem_dot */
    if (q > v2) v2 = q, fast = a;
  }
  const double grow = sp->speed_use * sqrt(v2);
  for (int d = 0; d < 3; d++) box[d] -= grow, box[3 + d] += grow;
  int64_t k = proto_reach_nodes(r->data.in[CPL_F_SURF_X], v, r->scene->dt, r->plan->surf.tri,
                                r->plan->surf.n_tris, n, box, sp->mark, sp->index);
  if (fast >= 0 && !sp->mark[fast]) { /* into its place: the index ascends */
    int64_t j = k++;
    for (; j > 0 && sp->index[j - 1] > fast; j--) sp->index[j] = sp->index[j - 1];
    sp->index[j] = (int32_t)fast;
    sp->mark[fast] = 1;
  }
  return k;
}


static void gather(const double *f, const int32_t *idx, int64_t k, double *rows) {
  for (int64_t j = 0; j < k; j++) memcpy(&rows[3 * j], &f[3 * (size_t)idx[j]], 3 * sizeof(double));
}

/* Rows of the sparse form of this request (k of n), or -1: dense. Sets
 * sp->rows for x/v (dem) or the force (fem). */
static int64_t sparse_rows(cpl_runner *r, cpl_peer *p) {
  const int64_t n = r->plan->surf.n_nodes;
  cpl_sparse *sp = &p->sp;
  int64_t k = -1;
  if (!r->scene->sparse || n == 0) return -1;
  if (p->role == PROTO_ROLE_DEM && sp->use_reach && p->dims.surface) {
    k = reach_nodes(r, sp);
    if ((double)k <= CPL_SPARSE_MAX_FRACTION * (double)n) {
      gather(r->data.in[CPL_F_SURF_X], sp->index, k, sp->rows[0]);
      gather(r->data.in[CPL_F_SURF_V], sp->index, k, sp->rows[1]);
    }
  } else if (p->role == PROTO_ROLE_FEM && sp->takes_force) {
    k = proto_sparse_rows(r->data.in[CPL_F_SURF_FORCE], n, sp->index, sp->rows[0]);
  }
  return (double)k <= CPL_SPARSE_MAX_FRACTION * (double)n ? k : -1;
}

/* (fields the scheme points requests at: data.in) -> (peer i's step request) */
void cpl_request_build(cpl_runner *r, int i, int64_t k, int iteration, int output,
                       proto_msg *m) {
  cpl_peer *p = &r->peers[i];
  proto_msg_reset(m, p->proc->name, proto_msg_type(PROTO_MSG_STEP), k,
                  (double)(k - 1) * r->scene->dt);
  cJSON *h = proto_msg_header(m);
  cJSON_AddNumberToObject(h, PROTO_H_DT, r->scene->dt);
  cJSON_AddBoolToObject(h, PROTO_H_OUTPUT, output);
  if (iteration > 0) cJSON_AddNumberToObject(h, PROTO_H_ITERATION, iteration);
  /* the dem's grains at the start of step k are those of its last done of
   * step k-1; the repeats of step k start there again */
  if (iteration == 0) {
    p->sp.use_reach = p->sp.has_reach;
    memcpy(p->sp.reach_use, p->sp.reach, sizeof p->sp.reach);
    p->sp.speed_use = p->sp.reach_speed;
  }
  const int64_t rows = sparse_rows(r, p);
  if (p->role == PROTO_ROLE_DEM && r->scene->sparse) cJSON_AddBoolToObject(h, PROTO_H_SPARSE, 1);
  if (p->role == PROTO_ROLE_DEM && rows >= 0)
    cJSON_AddItemToObject(h, PROTO_H_REACH, cJSON_CreateDoubleArray(p->sp.reach_use, 6));
  if (p->role == PROTO_ROLE_LUG && p->rank < CPL_MAX_PROCS && r->data.lug.reset[p->rank])
    cJSON_AddBoolToObject(h, PROTO_H_RESET, 1); /* it takes a new lug this step */
  if (p->role == PROTO_ROLE_LUG && p->rank < CPL_MAX_PROCS && r->data.lug.lug[p->rank] < 0)
    cJSON_AddBoolToObject(h, PROTO_H_IDLE, 1); /* no lug: its force is 0, its next lug resets it */
  for (int b = 0; b < r->plan->contract.n; b++) {
    const cpl_binding *bd = &r->plan->contract.b[b];
    const proto_array_spec *s = bd->spec;
    if (bd->role != p->role || bd->msg != PROTO_MSG_STEP || !due(p, s)) continue;
    int64_t shape[PROTO_MAX_NDIM];
    for (int d = 0; d < s->ndim; d++)
      shape[d] = s->dims[d] > 0 ? s->dims[d]
                 : s->dims[d] == PROTO_DIM_NODES ? p->dims.nodes
                 : s->dims[d] == PROTO_DIM_CELLS ? p->dims.cells : p->dims.tris;
    const void *data = r->data.in[bd->field];
    if (r->plan->contract.field[bd->field].per_process) /* its own row */
      data = r->data.in[bd->field] + (int64_t)p->rank * row_len(r, s);
    if (s->dims[0] == PROTO_DIM_NODES) {
      p->sp.out_dense += 24.0 * (double)p->dims.nodes;
      p->sp.out_bytes += bd->index && rows >= 0 ? 28.0 * (double)rows : 24.0 * (double)p->dims.nodes;
    }
    if (bd->index && rows >= 0) { /* its sparse form: k rows and their nodes */
      shape[0] = rows;
      data = p->sp.rows[bd->field == CPL_F_SURF_V ? 1 : 0];
      proto_msg_add(m, bd->index->name, PROTO_I4, 1, &rows, p->sp.index);
    }
    proto_msg_add(m, bd->array, s->dtype, s->ndim, shape, data);
  }
}

static int send_request(cpl_runner *r, int i, int64_t k, int iteration, int output) {
  proto_msg req = {0};
  cpl_request_build(r, i, k, iteration, output, &req);
  r->peers[i].t_sent = proto_now();
  int rc = cpl_send(r, i, &req);
  proto_msg_free(&req);
  return rc;
}

/* A dem's done header "reach": the box its grains can reach in its next
 * step, [lo x, y, z, hi x, y, z], finite, lo <= hi; absent: send it dense. */
static int take_reach(cpl_runner *r, cpl_peer *p) {
  const cJSON *b = cJSON_GetObjectItemCaseSensitive(p->reply.header, PROTO_H_REACH);
  p->sp.has_reach = 0;
  p->sp.reach_speed = 0;
  if (!b || p->role != PROTO_ROLE_DEM || !r->scene->sparse) return 0;
  const cJSON *sv = cJSON_GetObjectItemCaseSensitive(p->reply.header, PROTO_H_REACH_SPEED);
  if (sv && !(cJSON_IsNumber(sv) && isfinite(sv->valuedouble) && sv->valuedouble >= 0))
    return proto_fail(&r->err, "participant '%s': done header '%s': expected a finite number "
                      ">= 0 (s)", p->proc->name, PROTO_H_REACH_SPEED);
  if (sv) p->sp.reach_speed = sv->valuedouble;
  int ok = cJSON_IsArray(b) && cJSON_GetArraySize(b) == 6;
  for (int d = 0; ok && d < 6; d++) {
    const cJSON *e = cJSON_GetArrayItem(b, d);
    ok = cJSON_IsNumber(e) && isfinite(e->valuedouble);
    if (ok) p->sp.reach[d] = e->valuedouble;
  }
  for (int d = 0; ok && d < 3; d++) ok = p->sp.reach[d] <= p->sp.reach[3 + d];
  if (!ok)
    return proto_fail(&r->err, "participant '%s': done header '%s': expected [lo x, y, z, "
                      "hi x, y, z] of finite numbers with lo <= hi", p->proc->name,
                      PROTO_H_REACH);
  p->sp.has_reach = 1;
  return 0;
}

/* The reply of peer i: the right message, checked against the role table,
 * every bound value finite. */
static int check_reply(cpl_runner *r, int i, int64_t k, int iteration) {
  cpl_peer *p = &r->peers[i];
  const proto_msg *m = &p->reply;
  int64_t got_it = -1;
  r->failed_peer = i;
  if (proto_header_int(m, PROTO_H_ITERATION, 0, INT32_MAX, 0, &got_it, &r->err) < 0)
    return proto_wrap(&r->err, "participant '%s'", p->proc->name);
  if (strcmp(m->type, proto_msg_type(PROTO_MSG_DONE)) != 0 || m->step != k ||
      got_it != iteration)
    return proto_fail(&r->err, "participant '%s': expected 'done' for step %lld "
                      "(iteration %d), got '%s' for step %lld (iteration %d)",
                      p->proc->name, (long long)k, iteration, m->type,
                      (long long)m->step, (int)got_it);
  if (proto_role_check(p->role, PROTO_MSG_DONE, m, &p->dims, &r->err) < 0)
    return proto_wrap(&r->err, "participant '%s'", p->proc->name);
  for (int b = 0; b < r->plan->contract.n; b++) {
    const cpl_binding *bd = &r->plan->contract.b[b];
    if (bd->role != p->role || bd->msg != PROTO_MSG_DONE || !due(p, bd->spec)) continue;
    const proto_array *arr = proto_msg_find(m, bd->array);
    const int64_t j = proto_first_nonfinite(arr->data, (int64_t)(arr->nbytes / sizeof(double)));
    if (j >= 0)
      return proto_fail(&r->err, "participant '%s': %s[%lld] is not finite",
                        p->proc->name, bd->array, (long long)j);
  }
  if (take_reach(r, p) < 0) return -1;
  r->failed_peer = -1;
  return 0;
}

/* Copies or sums the reply of peer i into the fields' out buffers. */
static void take_outputs(cpl_runner *r, int i) {
  cpl_peer *p = &r->peers[i];
  for (int b = 0; b < r->plan->contract.n; b++) {
    const cpl_binding *bd = &r->plan->contract.b[b];
    if (bd->role != p->role || bd->msg != PROTO_MSG_DONE || !due(p, bd->spec)) continue;
    cpl_field *f = &r->data.fields[bd->field];
    const int32_t *idx;
    const int64_t rows = bd->index ? proto_msg_sparse(&p->reply, bd->array, &idx) : -1;
    if (bd->spec->dims[0] == PROTO_DIM_NODES) {
      p->sp.in_dense += 8.0 * (double)f->len;
      p->sp.in_bytes += rows >= 0 ? 28.0 * (double)rows : 8.0 * (double)f->len;
    }
    /* a sparse reply expanded: rows not listed are +0.0, as the dense reply's */
    const double *a = bd->index ? proto_msg_dense(&p->reply, bd->array, f->len / 3, 3, p->sp.dense)
                                : proto_msg_data(&p->reply, bd->array);
    if (r->plan->contract.field[bd->field].per_process) { /* into its own row */
      const int64_t m = row_len(r, bd->spec);
      memcpy(f->out + (int64_t)p->rank * m, a, sizeof(double) * (size_t)m);
      f->given++;
      continue;
    }
    if (!f->given++ || !bd->sum) memcpy(f->out, a, sizeof(double) * (size_t)f->len);
    else
      for (int64_t j = 0; j < f->len; j++) f->out[j] += a[j];
  }
}

static int in_stage(const cpl_runner *r, int stage, int peer) {
  for (int e = 0; e < r->plan->nex; e++)
    if (r->plan->ex[e].stage == stage && r->plan->ex[e].peer == peer) return 1;
  return 0;
}

static int run_stage(cpl_runner *r, int stage, int64_t k, int iteration, int output,
                     int commit, int actions) {
  int waiting = 0;
  for (int e = 0; e < r->plan->nex; e++) {
    const cpl_exchange *x = &r->plan->ex[e];
    if (x->stage != stage) continue;
    if (x->peer < 0) {
      if (actions && cpl_do_action(r, x->action, k) < 0) return -1;
      continue;
    }
    if (send_request(r, x->peer, k, iteration, output) < 0) return -1;
    waiting++;
  }
  int replied[CPL_MAX_PROCS] = {0};
  while (waiting > 0) {
    int from = -1;
    double t0 = proto_now();
    if (cpl_receive(r, -1, r->scene->step_timeout, "step_timeout", NULL, &from) < 0) {
      const int late = r->failed_peer < 0 && strstr(r->err.msg, "did not answer");
      for (int e = 0; e < r->plan->nex && late && r->failed_peer < 0; e++) /* name who is late */
        if (r->plan->ex[e].stage == stage && r->plan->ex[e].peer >= 0 && !replied[r->plan->ex[e].peer]) {
          r->failed_peer = r->plan->ex[e].peer;
          proto_fail(&r->err, "participant '%s' did not answer within %g s "
                     "(coupling.step_timeout)", r->peers[r->failed_peer].proc->name,
                     r->scene->step_timeout);
        }
      return -1;
    }
    double now = proto_now();
    r->t_blocked += now - t0;
    if (!in_stage(r, stage, from) || replied[from]) {
      r->failed_peer = from;
      return proto_fail(&r->err, "participant '%s' sent '%s' out of turn",
                        r->peers[from].proc->name, r->peers[from].reply.type);
    }
    replied[from] = 1;
    waiting--;
    if (check_reply(r, from, k, iteration) < 0) return -1;
    const cJSON *c = cJSON_GetObjectItemCaseSensitive(r->peers[from].reply.header,
                                                      PROTO_H_COMPUTE_S);
    const double compute = cJSON_IsNumber(c) ? c->valuedouble : 0;
    cpl_timing_reply(r, from, now, compute >= 0 && compute < 1e9 ? compute : 0);
  }
  cpl_stage_take(r, stage, commit);
  return 0;
}

/* (replies of a stage) -> (fields' out, summed in exchange order; committed) */
void cpl_stage_take(cpl_runner *r, int stage, int commit) {
  /* outputs in exchange order: sums do not depend on arrival order */
  const int nf = r->plan->contract.nfields;
  for (int f = 0; f < nf; f++) r->data.fields[f].given = 0;
  for (int e = 0; e < r->plan->nex; e++)
    if (r->plan->ex[e].stage == stage && r->plan->ex[e].peer >= 0) take_outputs(r, r->plan->ex[e].peer);
  if (commit)
    for (int f = 0; f < nf; f++)
      if (r->data.fields[f].given) cpl_field_commit(r, f);
}

/* (fields) -> (requests of each stage); (replies) -> (fields, summed, committed) */
int cpl_run_stages(cpl_runner *r, int first, int last, int64_t k, int iteration,
                   int output, int commit, int actions) {
  for (int s = first; s <= last; s++)
    if (run_stage(r, s, k, iteration, output, commit, actions) < 0) return -1;
  return 0;
}
