/* A new role added through the contract alone (CONTRIBUTING.md "Adding a
 * role"): a toy thermal process that takes the tread's surface positions
 * of t_k and returns a temperature per surface node. What is touched: the
 * role table (its two rows; here a copy of the shipped table), one field
 * (surface.temperature, [n]) and one row of the step's order (stage 3,
 * after the tread). The schedule, the request, the reply and its commit are
 * the shipped coupler's code, unchanged; a role with rows but no place in
 * the order, or a row naming a field nobody declared, stops the start-up. */
#include <string.h>

#include "coupler/runner.h"
#include "cosim_test.h"

enum { THERMAL = PROTO_N_ROLES }; /* the newcomer: the first role id free */
enum { DEM, FEM, TH, NPEERS };
#define NODES 3
#define MAX_ROWS 48

static proto_array_spec rows[MAX_ROWS];
static int nrows;
static cpl_stage_row order[CPL_MAX_STAGE_ROWS];
static int norder;
static const cpl_field_spec temperature = {"surface.temperature", 1, {PROTO_DIM_NODES}, 0};

/* The shipped table and order, and the newcomer's two rows and its stage. */
static void newcomer_contract(void) {
  const proto_array_spec *t = proto_role_table(&nrows);
  CHECK(nrows + 2 <= MAX_ROWS, "table of %d rows", nrows);
  memcpy(rows, t, sizeof(proto_array_spec) * (size_t)nrows);
  rows[nrows++] = (proto_array_spec){(proto_role)THERMAL, PROTO_MSG_STEP, PROTO_A_X, PROTO_F8, 2,
                                     {PROTO_DIM_NODES, 3}, "m", PROTO_WHEN_SURFACE,
                                     "tread surface positions at t_k", "surface.x", 0};
  rows[nrows++] = (proto_array_spec){(proto_role)THERMAL, PROTO_MSG_DONE, "temperature", PROTO_F8, 1,
                                     {PROTO_DIM_NODES}, "K", PROTO_WHEN_SURFACE,
                                     "temperature of each surface node", "surface.temperature",
                                     0};
  const cpl_stage_row *o = cpl_contract_stages(&norder);
  memcpy(order, o, sizeof(cpl_stage_row) * (size_t)norder);
  order[norder++] = (cpl_stage_row){3, THERMAL, CPL_ACT_NONE};
}

static void refused_when_incomplete(void) {
  static cpl_contract c;
  proto_err err = {0};
  newcomer_contract();
  FAILS_WITH(cpl_contract_build_with(&c, rows, nrows, NULL, 0, order, norder, &err),
             "unknown coupler field 'surface.temperature'");
  FAILS_WITH(cpl_contract_build_with(&c, rows, nrows, &temperature, 1, order, norder - 1, &err),
             "has no place in the step's order");
  order[norder - 1].stage = 5;
  FAILS_WITH(cpl_contract_build_with(&c, rows, nrows, &temperature, 1, order, norder, &err),
             "stages 0, 1, ... in order");
  FAILS_WITH(cpl_contract_build(&c, rows, nrows, &err), "unknown coupler field");
}

static cpl_scene scene;
static cpl_process procs[NPEERS];
static cpl_runner r;
static cpl_plan plan;

static void stub_run(cpl_scheme scheme) {
  static const char *const names[NPEERS] = {"dem", "fem", "thermal"};
  static const int roles[NPEERS] = {PROTO_ROLE_DEM, PROTO_ROLE_FEM, THERMAL};
  proto_err err = {0};
  memset(&r, 0, sizeof r);
  memset(&plan, 0, sizeof plan);
  newcomer_contract();
  OK(cpl_contract_build_with(&plan.contract, rows, nrows, &temperature, 1, order, norder, &err));
  scene.scheme = scheme;
  scene.dt = 1e-3;
  r.scene = &scene;
  r.plan = &plan;
  r.n = NPEERS;
  plan.fem = FEM;
  for (int i = 0; i < NPEERS; i++) {
    snprintf(procs[i].name, sizeof procs[i].name, "%s", names[i]);
    r.peers[i].proc = &procs[i];
    r.peers[i].role = (proto_role)roles[i];
    proto_dims_init(&r.peers[i].dims);
    r.peers[i].dims.surface = 1;
    r.peers[i].dims.nodes = NODES;
    plan.n_of_role[roles[i]]++;
  }
  OK(cpl_fields_init(&r, NODES, &err));
  cpl_schedule_build(&plan, r.peers, r.n, scheme);
}

static void scheduled(void) {
  stub_run(CPL_SCHEME_SERIAL);
  const cpl_exchange serial[] = {{0, -1, CPL_ACT_LUG}, {0, DEM, CPL_ACT_NONE},
                                 {1, -1, CPL_ACT_LUG_FORCE}, {1, -1, CPL_ACT_RIM},
                                 {1, FEM, CPL_ACT_NONE}, {2, -1, CPL_ACT_ROAD},
                                 {3, TH, CPL_ACT_NONE}};
  CHECK(plan.nex == 7 && cpl_last_stage(&r) == 3, "serial: 7 exchanges in 4 stages (%d)",
        plan.nex);
  for (int e = 0; e < 7 && e < plan.nex; e++)
    CHECK(plan.ex[e].stage == serial[e].stage && plan.ex[e].peer == serial[e].peer &&
          plan.ex[e].action == serial[e].action, "serial exchange %d", e);
  cpl_fields_free(&r);
  stub_run(CPL_SCHEME_PARALLEL);
  CHECK(plan.nex == 7 && plan.ex[6].peer == TH && cpl_last_stage(&r) == 0,
        "parallel: the thermal process in the one stage, last");
  cpl_fields_free(&r);
}

/* Its request carries the surface positions; its reply lands in its field
 * and is what the next request of any role reading it would send. */
static void exchanged(void) {
  stub_run(CPL_SCHEME_SERIAL);
  const int T = CPL_N_FIELDS; /* the first further field */
  CHECK(r.data.fields[T].len == NODES && strcmp(r.data.fields[T].name, temperature.name) == 0,
        "surface.temperature: [n] = %lld doubles", (long long)r.data.fields[T].len);
  double *x = r.data.fields[CPL_F_SURF_X].cur;
  for (int j = 0; j < 3 * NODES; j++) x[j] = 0.5 * j - 1;
  proto_msg req = {0};
  cpl_request_build(&r, TH, 7, 0, 0, &req);
  const proto_array *ax = proto_msg_find(&req, PROTO_A_X);
  CHECK(req.narrays == 1 && ax && ax->shape[0] == NODES && ax->shape[1] == 3 &&
        memcmp(ax->data, x, sizeof(double) * 3 * NODES) == 0,
        "the thermal request: x of the surface, nothing else (%d arrays)", req.narrays);
  CHECK(req.step == 7, "for step 7");
  cpl_request_build(&r, FEM, 7, 0, 0, &req);
  CHECK(!proto_msg_find(&req, "temperature"), "the fem's request is the shipped one");
  proto_msg_free(&req);

  const double temp[NODES] = {293.15, 300.5, 311.25};
  const int64_t n1[1] = {NODES};
  proto_msg *m = &r.peers[TH].reply;
  proto_msg_reset(m, "thermal", "done", 7, 7e-3);
  proto_msg_add(m, "temperature", PROTO_F8, 1, n1, temp);
  cpl_stage_take(&r, 3, 1);
  CHECK(memcmp(r.data.fields[T].cur, temp, sizeof temp) == 0 && r.data.fields[T].given == 1,
        "its reply committed into surface.temperature");
  CHECK(r.data.in[T] == r.data.fields[T].cur, "requests read the committed value");
  CHECK(r.data.fields[CPL_F_SURF_X].cur == x, "stage 3 left the surface alone");
  proto_msg_free(m);
  cpl_fields_free(&r);
}

int main(void) {
  refused_when_incomplete();
  scheduled();
  exchanged();
  return cosim_test_done("test_new_role");
}
