/* schedule.c — a coupling step as data: the coupler-side fields, the
 * bindings of role-table arrays to them, and the list of exchanges a scheme
 * walks (PROTOCOL.md "Schedule"). A stage sends all its requests, then
 * collects all its replies: its processes compute at the same time. */
#include "run.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Which role-table array reads or fills which field. */
static const cpl_binding bindings[] = {
    {PROTO_ROLE_DEM, PROTO_MSG_STEP, PROTO_A_X, CPL_F_SURF_X, 0},
    {PROTO_ROLE_DEM, PROTO_MSG_STEP, PROTO_A_V, CPL_F_SURF_V, 0},
    {PROTO_ROLE_DEM, PROTO_MSG_DONE, PROTO_A_NODAL_FORCE, CPL_F_SURF_FORCE, 1},
    {PROTO_ROLE_FEM, PROTO_MSG_STEP, PROTO_A_NODAL_FORCE, CPL_F_SURF_FORCE, 0},
    {PROTO_ROLE_FEM, PROTO_MSG_STEP, PROTO_A_RIM_R, CPL_F_RIM_R, 0},
    {PROTO_ROLE_FEM, PROTO_MSG_STEP, PROTO_A_RIM_C, CPL_F_RIM_C, 0},
    {PROTO_ROLE_FEM, PROTO_MSG_STEP, PROTO_A_RIM_OMEGA, CPL_F_RIM_OMEGA, 0},
    {PROTO_ROLE_FEM, PROTO_MSG_STEP, PROTO_A_RIM_V, CPL_F_RIM_V, 0},
    {PROTO_ROLE_FEM, PROTO_MSG_DONE, PROTO_A_X, CPL_F_SURF_X, 0},
    {PROTO_ROLE_FEM, PROTO_MSG_DONE, PROTO_A_V, CPL_F_SURF_V, 0},
    {PROTO_ROLE_BLOCK, PROTO_MSG_STEP, PROTO_A_D_ROAD, CPL_F_ROAD_D, 0},
    {PROTO_ROLE_BLOCK, PROTO_MSG_DONE, PROTO_A_FORCE, CPL_F_ROAD_FORCE, 1},
};
#define N_BINDINGS ((int)(sizeof bindings / sizeof bindings[0]))

static const char *const field_names[CPL_N_FIELDS] = {
    "surface.x", "surface.v", "surface.force", "rim.R", "rim.c", "rim.omega",
    "rim.v", "road.d", "road.force"};

/* The role-table entry of a binding. */
static const proto_array_spec *spec_of(const cpl_binding *b) {
  int n;
  const proto_array_spec *t = proto_role_table(&n);
  for (int i = 0; i < n; i++)
    if (t[i].role == b->role && t[i].msg == b->msg && strcmp(t[i].name, b->array) == 0)
      return &t[i];
  return NULL;
}

/* Is the array due for this peer (the table's "when")? */
static int due(const cpl_peer *p, const proto_array_spec *s) {
  return s && (s->when != PROTO_WHEN_SURFACE || p->dims.surface);
}

int cpl_fields_init(cpl_runner *r, int64_t n, proto_err *err) {
  const int64_t len[CPL_N_FIELDS] = {3 * n, 3 * n, 3 * n, 9, 3, 3, 3, 1, 1};
  for (int f = 0; f < CPL_N_FIELDS; f++) {
    cpl_field *fd = &r->fields[f];
    fd->name = field_names[f];
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
  if (r->nex < CPL_MAX_EXCHANGES)
    r->ex[r->nex++] = (cpl_exchange){stage, peer, a};
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
  r->nex = 0;
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
  return r->nex ? r->ex[r->nex - 1].stage : 0;
}

void cpl_schedule_print(const cpl_runner *r, FILE *f) {
  static const char *const actions[] = {"", "rim frame <- vertical load (scenario)",
                                        "road displacement (scenario)"};
  fprintf(f, "schedule (%s):\n", cpl_scheme_name(r->scene->scheme));
  for (int s = 0; s <= cpl_last_stage(r); s++) {
    int any = 0;
    for (int e = 0; e < r->nex; e++) {
      const cpl_exchange *x = &r->ex[e];
      if (x->stage != s) continue;
      if (x->peer < 0) {
        if ((x->action == CPL_ACT_RIM && r->scene->scenario.kind != CPL_SCN_TIRE_TRAVEL) ||
            (x->action == CPL_ACT_ROAD && !r->n_of_role[PROTO_ROLE_BLOCK]))
          continue;
        fprintf(f, "  %d. coupler: %s\n", s + 1, actions[x->action]);
        continue;
      }
      const cpl_peer *p = &r->peers[x->peer];
      fprintf(f, "  %d.%s %s (%s):", s + 1, any++ ? " +" : "", p->proc->name,
              proto_role_name(p->role));
      for (int pass = 0; pass < 2; pass++) {
        fprintf(f, "%s", pass ? " ->" : "");
        for (int b = 0; b < N_BINDINGS; b++) {
          const cpl_binding *bd = &bindings[b];
          if (bd->role != p->role || bd->msg != (pass ? PROTO_MSG_DONE : PROTO_MSG_STEP) ||
              !due(p, spec_of(bd)))
            continue;
          fprintf(f, " %s%s", bd->array, pass && bd->sum ? " (summed)" : "");
        }
      }
      fprintf(f, "\n");
    }
  }
}

/* -------------------------------------------------------------- actions */

double cpl_vertical_load(const cpl_runner *r) {
  const cpl_field *f = &r->fields[CPL_F_SURF_FORCE];
  double fz = 0;
  for (int64_t i = 2; i < f->len; i += 3) fz += f->cur[i];
  return fz;
}

static void rim_to_fields(cpl_runner *r) {
  memcpy(r->fields[CPL_F_RIM_R].cur, r->rim.R, sizeof r->rim.R);
  memcpy(r->fields[CPL_F_RIM_C].cur, r->rim.c, sizeof r->rim.c);
  memcpy(r->fields[CPL_F_RIM_OMEGA].cur, r->rim.w, sizeof r->rim.w);
  memcpy(r->fields[CPL_F_RIM_V].cur, r->rim.v, sizeof r->rim.v);
}

/* Road displacement at t_k: prescribed, or the road body moved by the
 * external force against the last contact force (explicit central
 * difference: the force at d_{k-1} moves it to d_k). The implicit scheme
 * integrates the road body itself (loop.c). */
static void road_action(cpl_runner *r, int64_t k) {
  const cpl_scenario *s = &r->scene->scenario;
  double *d = r->fields[CPL_F_ROAD_D].cur;
  if (s->kind != CPL_SCN_INDENTATION) {
    d[0] = 0;
    return;
  }
  if (s->profile != CPL_PROFILE_FORCE) {
    d[0] = cpl_road_displacement(s, (double)k * r->scene->dt);
    return;
  }
  double a = (s->road_force - r->road.force_last) / s->road_mass;
  r->road.v += a * r->scene->dt;
  r->road.d += r->road.v * r->scene->dt;
  d[0] = r->road.d;
}

int cpl_do_action(cpl_runner *r, cpl_action a, int64_t k) {
  if (a == CPL_ACT_RIM && r->fem >= 0) {
    if (cpl_rim_advance(&r->rim, &r->scene->scenario, r->scene->dt, cpl_vertical_load(r),
                        &r->err) < 0)
      return -1;
    rim_to_fields(r);
  } else if (a == CPL_ACT_ROAD && r->n_of_role[PROTO_ROLE_BLOCK]) {
    road_action(r, k);
  }
  return 0;
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
  for (int b = 0; b < N_BINDINGS; b++) {
    const cpl_binding *bd = &bindings[b];
    const proto_array_spec *s = spec_of(bd);
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
  for (int b = 0; b < N_BINDINGS; b++) {
    const cpl_binding *bd = &bindings[b];
    if (bd->role != p->role || bd->msg != PROTO_MSG_DONE || !due(p, spec_of(bd))) continue;
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
  for (int b = 0; b < N_BINDINGS; b++) {
    const cpl_binding *bd = &bindings[b];
    if (bd->role != p->role || bd->msg != PROTO_MSG_DONE || !due(p, spec_of(bd))) continue;
    cpl_field *f = &r->fields[bd->field];
    const double *a = proto_msg_data(&p->reply, bd->array);
    if (!f->given++ || !bd->sum) memcpy(f->out, a, sizeof(double) * (size_t)f->len);
    else
      for (int64_t j = 0; j < f->len; j++) f->out[j] += a[j];
  }
}

static int in_stage(const cpl_runner *r, int stage, int peer) {
  for (int e = 0; e < r->nex; e++)
    if (r->ex[e].stage == stage && r->ex[e].peer == peer) return 1;
  return 0;
}

static int run_stage(cpl_runner *r, int stage, int64_t k, int iteration, int output,
                     int commit, int actions) {
  int waiting = 0;
  for (int e = 0; e < r->nex; e++) {
    const cpl_exchange *x = &r->ex[e];
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
      for (int e = 0; e < r->nex && late && r->failed_peer < 0; e++) /* name who is late */
        if (r->ex[e].stage == stage && r->ex[e].peer >= 0 && !replied[r->ex[e].peer]) {
          r->failed_peer = r->ex[e].peer;
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
  /* outputs in exchange order: sums do not depend on arrival order */
  for (int f = 0; f < CPL_N_FIELDS; f++) r->fields[f].given = 0;
  for (int e = 0; e < r->nex; e++)
    if (r->ex[e].stage == stage && r->ex[e].peer >= 0) take_outputs(r, r->ex[e].peer);
  if (commit)
    for (int f = 0; f < CPL_N_FIELDS; f++)
      if (r->fields[f].given) cpl_field_commit(r, (cpl_field_id)f);
  return 0;
}

int cpl_run_stages(cpl_runner *r, int first, int last, int64_t k, int iteration,
                   int output, int commit, int actions) {
  for (int s = first; s <= last; s++)
    if (run_stage(r, s, k, iteration, output, commit, actions) < 0) return -1;
  return 0;
}
