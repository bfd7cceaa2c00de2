/* schedule.c — a coupling step as data: the coupler-side fields, the
 * role table's rows bound to them (contract.c), and the list of exchanges a scheme
 * walks (PROTOCOL.md "Schedule"). A stage sends all its requests, then
 * collects all its replies: its processes compute at the same time. */
#include "runner.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Is the array due for this peer (the table's "when")? */
static int due(const cpl_peer *p, const proto_array_spec *s) {
  return s->when != PROTO_WHEN_SURFACE || p->dims.surface;
}

int cpl_fields_init(cpl_runner *r, int64_t n, proto_err *err) {
  const int64_t len[CPL_N_FIELDS] = {3 * n, 3 * n, 3 * n, 9, 3, 3, 3, 1, 1};
  for (int f = 0; f < CPL_N_FIELDS; f++) {
    cpl_field *fd = &r->fields[f];
    fd->name = cpl_field_name((cpl_field_id)f);
    fd->len = len[f];
    size_t bytes = sizeof(double) * (size_t)(len[f] > 0 ? len[f] : 1);
    fd->cur = calloc(1, bytes);
    fd->out = calloc(1, bytes);
    if (!fd->cur || !fd->out) return proto_fail(err, "out of memory for the fields");
  }
  cpl_inputs_current(r);
  return 0;
}

void cpl_fields_free(cpl_runner *r) {
  for (int f = 0; f < CPL_N_FIELDS; f++) {
    free(r->fields[f].cur);
    free(r->fields[f].out);
    r->fields[f].cur = r->fields[f].out = NULL;
  }
}

void cpl_inputs_current(cpl_runner *r) {
  for (int f = 0; f < CPL_N_FIELDS; f++) r->in[f] = r->fields[f].cur;
}

void cpl_field_commit(cpl_runner *r, cpl_field_id id) {
  cpl_field *f = &r->fields[id];
  double *t = f->cur;
  f->cur = f->out;
  f->out = t;
  if (r->in[id] == t) r->in[id] = f->cur; /* requests follow the current value */
}

/* ------------------------------------------------------------- building */

static void add(cpl_runner *r, int stage, int peer, cpl_action a) {
  if (r->plan.nex < CPL_MAX_EXCHANGES)
    r->plan.ex[r->plan.nex++] = (cpl_exchange){stage, peer, a};
}

static void add_role(cpl_runner *r, int stage, proto_role role) {
  for (int i = 0; i < r->n; i++)
    if (r->peers[i].role == role) add(r, stage, i, CPL_ACT_NONE);
}

/* serial (Gauss–Seidel, the paper's staggered scheme): the grains on the
 * surface of t_{k-1}; the rim moved with their load; the tread with their
 * forces; the blocks on the road of t_k. parallel and implicit: actions
 * first (with the last step's load), then every process at once. */
void cpl_schedule_build(cpl_runner *r) {
  r->plan.nex = 0;
  if (r->scene->scheme == CPL_SCHEME_SERIAL) {
    add_role(r, 0, PROTO_ROLE_DEM);
    add(r, 1, -1, CPL_ACT_RIM);
    add_role(r, 1, PROTO_ROLE_FEM);
    add(r, 2, -1, CPL_ACT_ROAD);
    add_role(r, 2, PROTO_ROLE_BLOCK);
    return;
  }
  add(r, 0, -1, CPL_ACT_RIM);
  add(r, 0, -1, CPL_ACT_ROAD);
  for (int role = 0; role < PROTO_N_ROLES; role++) add_role(r, 0, (proto_role)role);
}

int cpl_last_stage(const cpl_runner *r) {
  return r->plan.nex ? r->plan.ex[r->plan.nex - 1].stage : 0;
}

void cpl_schedule_print(const cpl_runner *r, FILE *f) {
  static const char *const actions[] = {"", "rim frame <- vertical load (scenario)",
                                        "road displacement (scenario)"};
  fprintf(f, "schedule (%s):\n", cpl_scheme_name(r->scene->scheme));
  for (int s = 0; s <= cpl_last_stage(r); s++) {
    int any = 0;
    for (int e = 0; e < r->plan.nex; e++) {
      const cpl_exchange *x = &r->plan.ex[e];
      if (x->stage != s) continue;
      if (x->peer < 0) {
        if ((x->action == CPL_ACT_RIM && r->scene->scenario.kind != CPL_SCN_TIRE_TRAVEL) ||
            (x->action == CPL_ACT_ROAD && !r->plan.n_of_role[PROTO_ROLE_BLOCK]))
          continue;
        fprintf(f, "  %d. coupler: %s\n", s + 1, actions[x->action]);
        continue;
      }
      const cpl_peer *p = &r->peers[x->peer];
      fprintf(f, "  %d.%s %s (%s):", s + 1, any++ ? " +" : "", p->proc->name,
              proto_role_name(p->role));
      for (int pass = 0; pass < 2; pass++) {
        fprintf(f, "%s", pass ? " ->" : "");
        for (int b = 0; b < r->plan.contract.n; b++) {
          const cpl_binding *bd = &r->plan.contract.b[b];
          if (bd->role != p->role || bd->msg != (pass ? PROTO_MSG_DONE : PROTO_MSG_STEP) ||
              !due(p, bd->spec))
            continue;
          fprintf(f, " %s%s", bd->array, pass && bd->sum ? " (summed)" : "");
        }
      }
      fprintf(f, "\n");
    }
  }
}

/* ------------------------------------------------------------- exchanges */

static int send_request(cpl_runner *r, int i, int64_t k, int iteration, int output) {
  cpl_peer *p = &r->peers[i];
  proto_msg req = {0};
  proto_msg_reset(&req, p->proc->name, proto_msg_type(PROTO_MSG_STEP), k,
                  (double)(k - 1) * r->scene->dt);
  cJSON *h = proto_msg_header(&req);
  cJSON_AddNumberToObject(h, PROTO_H_DT, r->scene->dt);
  cJSON_AddBoolToObject(h, PROTO_H_OUTPUT, output);
  if (iteration > 0) cJSON_AddNumberToObject(h, PROTO_H_ITERATION, iteration);
  for (int b = 0; b < r->plan.contract.n; b++) {
    const cpl_binding *bd = &r->plan.contract.b[b];
    const proto_array_spec *s = bd->spec;
    if (bd->role != p->role || bd->msg != PROTO_MSG_STEP || !due(p, s)) continue;
    int64_t shape[PROTO_MAX_NDIM];
    for (int d = 0; d < s->ndim; d++)
      shape[d] = s->dims[d] > 0 ? s->dims[d]
                 : s->dims[d] == PROTO_DIM_NODES ? p->dims.nodes : p->dims.tris;
    proto_msg_add(&req, bd->array, s->dtype, s->ndim, shape, r->in[bd->field]);
  }
  p->t_sent = proto_now();
  int rc = cpl_send(r, i, &req);
  proto_msg_free(&req);
  return rc;
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
  for (int b = 0; b < r->plan.contract.n; b++) {
    const cpl_binding *bd = &r->plan.contract.b[b];
    if (bd->role != p->role || bd->msg != PROTO_MSG_DONE || !due(p, bd->spec)) continue;
    const double *a = proto_msg_data(m, bd->array);
    for (int64_t j = 0; j < r->fields[bd->field].len; j++)
      if (!isfinite(a[j]))
        return proto_fail(&r->err, "participant '%s': %s[%lld] is not finite",
                          p->proc->name, bd->array, (long long)j);
  }
  r->failed_peer = -1;
  return 0;
}

/* Copies or sums the reply of peer i into the fields' out buffers. */
static void take_outputs(cpl_runner *r, int i) {
  cpl_peer *p = &r->peers[i];
  for (int b = 0; b < r->plan.contract.n; b++) {
    const cpl_binding *bd = &r->plan.contract.b[b];
    if (bd->role != p->role || bd->msg != PROTO_MSG_DONE || !due(p, bd->spec)) continue;
    cpl_field *f = &r->fields[bd->field];
    const double *a = proto_msg_data(&p->reply, bd->array);
    if (!f->given++ || !bd->sum) memcpy(f->out, a, sizeof(double) * (size_t)f->len);
    else
      for (int64_t j = 0; j < f->len; j++) f->out[j] += a[j];
  }
}

static int in_stage(const cpl_runner *r, int stage, int peer) {
  for (int e = 0; e < r->plan.nex; e++)
    if (r->plan.ex[e].stage == stage && r->plan.ex[e].peer == peer) return 1;
  return 0;
}

static int run_stage(cpl_runner *r, int stage, int64_t k, int iteration, int output,
                     int commit, int actions) {
  int waiting = 0;
  for (int e = 0; e < r->plan.nex; e++) {
    const cpl_exchange *x = &r->plan.ex[e];
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
      for (int e = 0; e < r->plan.nex && late && r->failed_peer < 0; e++) /* name who is late */
        if (r->plan.ex[e].stage == stage && r->plan.ex[e].peer >= 0 && !replied[r->plan.ex[e].peer]) {
          r->failed_peer = r->plan.ex[e].peer;
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
  for (int f = 0; f < CPL_N_FIELDS; f++) r->fields[f].given = 0;
  for (int e = 0; e < r->plan.nex; e++)
    if (r->plan.ex[e].stage == stage && r->plan.ex[e].peer >= 0) take_outputs(r, r->plan.ex[e].peer);
  if (commit)
    for (int f = 0; f < CPL_N_FIELDS; f++)
      if (r->fields[f].given) cpl_field_commit(r, (cpl_field_id)f);
}

/* (fields) -> (requests of each stage); (replies) -> (fields, summed, committed) */
int cpl_run_stages(cpl_runner *r, int first, int last, int64_t k, int iteration,
                   int output, int commit, int actions) {
  for (int s = first; s <= last; s++)
    if (run_stage(r, s, k, iteration, output, commit, actions) < 0) return -1;
  return 0;
}
