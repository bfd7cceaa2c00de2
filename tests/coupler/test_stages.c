/* The coupler's stages without a run (no sockets, no processes): the
 * schedule of each scheme on a stub set of peers; the exchange's
 * bookkeeping (the sub-stepped impulse / dt of two dem processes summed
 * exactly, the fem's surface copied); the load rig, the road body and the
 * traction on numbers worked out by hand from their formulas (README
 * "Scenario keys"; seed 000 §5); liveness on a fake clock. */
#include <math.h>
#include <string.h>

#include "coupler/runner.h"
#include "cosim_test.h"

enum { DEM0, DEM1, FEM, BLOCK, NPEERS };
#define NODES 2

static cpl_scene scene;
static cpl_process procs[NPEERS];
static cpl_runner r;

static void stub_plan(cpl_scheme scheme) {
  static const char *const names[NPEERS] = {"dem0", "dem1", "fem", "block"};
  static const proto_role roles[NPEERS] = {PROTO_ROLE_DEM, PROTO_ROLE_DEM, PROTO_ROLE_FEM,
                                           PROTO_ROLE_BLOCK};
  proto_err err = {0};
  int nrows;
  const proto_array_spec *t = proto_role_table(&nrows);
  scene.scheme = scheme;
  scene.dt = 1.0 / 1024; /* a power of two: the impulses below are exact */
  r.scene = &scene;
  r.n = NPEERS;
  r.plan.fem = FEM;
  for (int i = 0; i < NPEERS; i++) {
    snprintf(procs[i].name, sizeof procs[i].name, "%s", names[i]);
    r.peers[i].proc = &procs[i];
    r.peers[i].role = roles[i];
    proto_dims_init(&r.peers[i].dims);
    r.peers[i].dims.surface = roles[i] != PROTO_ROLE_BLOCK;
    r.peers[i].dims.nodes = NODES;
    r.plan.n_of_role[roles[i]]++;
  }
  OK(cpl_contract_build(&r.plan.contract, t, nrows, &err));
  OK(cpl_fields_init(&r, NODES, &err));
  cpl_schedule_build(&r);
}

static void schedules(void) {
  stub_plan(CPL_SCHEME_SERIAL);
  /* 1. the dems; 2. rim action, fem; 3. road action, block */
  const cpl_exchange serial[] = {{0, DEM0, CPL_ACT_NONE}, {0, DEM1, CPL_ACT_NONE},
                                 {1, -1, CPL_ACT_RIM},   {1, FEM, CPL_ACT_NONE},
                                 {2, -1, CPL_ACT_ROAD},  {2, BLOCK, CPL_ACT_NONE}};
  CHECK(r.plan.nex == 6, "serial: 6 exchanges, got %d", r.plan.nex);
  for (int e = 0; e < 6 && e < r.plan.nex; e++)
    CHECK(r.plan.ex[e].stage == serial[e].stage && r.plan.ex[e].peer == serial[e].peer &&
          r.plan.ex[e].action == serial[e].action, "serial exchange %d", e);
  CHECK(cpl_last_stage(&r) == 2, "serial: three stages");
  cpl_fields_free(&r);
  memset(&r, 0, sizeof r);
  stub_plan(CPL_SCHEME_PARALLEL);
  /* one stage: both actions first (the last step's load), then every process
   * in role order (dem, fem, block) */
  const cpl_exchange parallel[] = {{0, -1, CPL_ACT_RIM},   {0, -1, CPL_ACT_ROAD},
                                   {0, DEM0, CPL_ACT_NONE}, {0, DEM1, CPL_ACT_NONE},
                                   {0, FEM, CPL_ACT_NONE},  {0, BLOCK, CPL_ACT_NONE}};
  CHECK(r.plan.nex == 6 && cpl_last_stage(&r) == 0, "parallel: 6 exchanges in one stage");
  for (int e = 0; e < 6 && e < r.plan.nex; e++)
    CHECK(r.plan.ex[e].stage == parallel[e].stage && r.plan.ex[e].peer == parallel[e].peer &&
          r.plan.ex[e].action == parallel[e].action, "parallel exchange %d", e);
  cpl_fields_free(&r);
  memset(&r, 0, sizeof r);
}

/* Impulse / dt of a process that took 4 sub-steps of dt/4 with nodal forces
 * f[j] (the same on every component): (1/dt) sum_j (dt/4) f_j. */
static double mean_force(const double f[4]) {
  double impulse = 0;
  for (int j = 0; j < 4; j++) impulse += scene.dt / 4 * f[j];
  return impulse / scene.dt;
}

static void exchange_bookkeeping(void) {
  stub_plan(CPL_SCHEME_SERIAL);
  static const double f0[4] = {1, 2, 3, 6}, f1[4] = {-0.5, 0.25, 0.75, -2.5};
  const double F0 = mean_force(f0), F1 = mean_force(f1); /* 3 and -0.5 */
  CHECK(F0 == 3 && F1 == -0.5, "the impulses / dt: %g %g", F0, F1);
  double a0[3 * NODES], a1[3 * NODES], x[3 * NODES], v[3 * NODES], road_f = 7;
  for (int j = 0; j < 3 * NODES; j++) {
    a0[j] = F0 * (j + 1);
    a1[j] = F1 * (j + 1);
    x[j] = 0.125 * j;
    v[j] = -0.25 * j;
  }
  const int64_t n3[2] = {NODES, 3}, one[1] = {1};
  proto_msg *m = &r.peers[DEM0].reply;
  proto_msg_reset(m, "dem0", "done", 1, scene.dt);
  proto_msg_add(m, PROTO_A_NODAL_FORCE, PROTO_F8, 2, n3, a0);
  m = &r.peers[DEM1].reply;
  proto_msg_reset(m, "dem1", "done", 1, scene.dt);
  proto_msg_add(m, PROTO_A_NODAL_FORCE, PROTO_F8, 2, n3, a1);
  cpl_stage_take(&r, 0, 1);
  const double *F = r.fields[CPL_F_SURF_FORCE].cur;
  int exact = 1;
  for (int j = 0; j < 3 * NODES; j++) exact &= F[j] == F0 * (j + 1) + F1 * (j + 1);
  CHECK(exact, "surface.force = the two dems' impulse / dt summed, exactly");
  CHECK(r.in[CPL_F_SURF_FORCE] == F, "the fem's request reads the committed sum");
  CHECK(r.fields[CPL_F_SURF_FORCE].given == 2, "both dems gave it");

  m = &r.peers[FEM].reply;
  proto_msg_reset(m, "fem", "done", 1, scene.dt);
  proto_msg_add(m, PROTO_A_X, PROTO_F8, 2, n3, x);
  proto_msg_add(m, PROTO_A_V, PROTO_F8, 2, n3, v);
  cpl_stage_take(&r, 1, 1);
  CHECK(memcmp(r.fields[CPL_F_SURF_X].cur, x, sizeof x) == 0 &&
        memcmp(r.fields[CPL_F_SURF_V].cur, v, sizeof v) == 0, "the fem's surface copied");
  CHECK(r.fields[CPL_F_SURF_FORCE].cur == F, "stage 2 left the forces alone");

  m = &r.peers[BLOCK].reply;
  proto_msg_reset(m, "block", "done", 1, scene.dt);
  proto_msg_add(m, PROTO_A_FORCE, PROTO_F8, 1, one, &road_f);
  cpl_stage_take(&r, 2, 0); /* not committed: the value waits in out */
  CHECK(r.fields[CPL_F_ROAD_FORCE].out[0] == 7 && r.fields[CPL_F_ROAD_FORCE].cur[0] == 0,
        "an uncommitted reply stays in out");
  for (int i = 0; i < NPEERS; i++) proto_msg_free(&r.peers[i].reply);
  cpl_fields_free(&r);
  memset(&r, 0, sizeof r);
}

/* Load rig (README "Scenario keys"): dt = 1e-3 s, sinking at 0.01 m/s; the
 * loads 0, 40 (= W/2: the fit starts), 80 (= W: travel) give two fit points
 * dz = 0 and dz = -1e-5 m at F = 40, 80 N, so k = 40 / 1e-5 = 4e6 N/m. Then
 * with F = 88 N: v_z = dt (F - W)/m / (1 + dt c/m) = 1e-3 / 1.00125. */
static void load_rig(void) {
  cpl_scenario s = {0};
  s.kind = CPL_SCN_TIRE_TRAVEL;
  s.rim_center[2] = 1;
  s.sinkage_velocity = 0.01;
  s.sinkage_force = 80;
  s.omega = 2;
  s.radius = 0.5;
  s.slip = 0.1;
  s.rig = CPL_RIG_LOAD;
  s.rig_mass = 8;
  s.rig_damping = 10;
  const double dt = 1e-3;
  cpl_rim rim;
  proto_err err = {0};
  cpl_rim_init(&rim, &s);
  OK(cpl_rim_advance(&rim, &s, dt, 0, &err));
  CHECK_REL("sinking", rim.c[2], 1 - 1e-5, 1e-14);
  OK(cpl_rim_advance(&rim, &s, dt, 40, &err));
  OK(cpl_rim_advance(&rim, &s, dt, 80, &err));
  CHECK(rim.travelling, "travel starts at the load");
  CHECK_REL("soil stiffness k", rim.stiffness, 4e6, 1e-9);
  CHECK_REL("travel speed omega R (1 - s)", rim.v[0], 2 * 0.5 * 0.9, 1e-15);
  CHECK_REL("rim height frozen at release", rim.c[2], 1 - 2e-5, 1e-14);
  CHECK_REL("x after one travel step", rim.c[0], 0.9e-3, 1e-14);
  OK(cpl_rim_advance(&rim, &s, dt, 88, &err));
  const double vz = 1e-3 / 1.00125;
  CHECK_REL("rig velocity", rim.v[2], vz, 1e-14);
  CHECK_REL("rig height", rim.c[2], 1 - 2e-5 + vz * dt, 1e-14);
  CHECK_REL("angle 2 omega dt", rim.angle, 2 * 2 * dt, 1e-14);
  /* m = 0.1 kg: omega dt = sqrt(4e6 / 0.1) 1e-3 = 6.3 > 1: refused */
  s.rig_mass = 0.1;
  cpl_rim_init(&rim, &s);
  OK(cpl_rim_advance(&rim, &s, dt, 0, &err));
  OK(cpl_rim_advance(&rim, &s, dt, 40, &err));
  FAILS_WITH(cpl_rim_advance(&rim, &s, dt, 80, &err), "scenario.rig_mass");
}

/* Road body: road_force 10 N, road_mass 2 kg, dt 0.5 s. Explicit with the
 * last force 4 N: a = 3, v = 1.5, d = 0.75; then with 10 N: a = 0, v = 1.5,
 * d = 1.5. Trapezoid from d = 1, v = 2, a = 1 with the force 6 N of t_k:
 * a = 2, v = 2 + 0.25 (1 + 2) = 2.75, d = 1 + 0.25 (2 + 2.75) = 2.1875. */
static void road_body(void) {
  cpl_scenario s = {0};
  s.kind = CPL_SCN_INDENTATION;
  s.profile = CPL_PROFILE_FORCE;
  s.road_force = 10;
  s.road_mass = 2;
  cpl_road road = {0, 0, 0, 4};
  CHECK(cpl_road_explicit(&road, &s, 0.5) == 0.75 && road.v == 1.5, "explicit step 1");
  road.force_last = 10;
  CHECK(cpl_road_explicit(&road, &s, 0.5) == 1.5 && road.v == 1.5, "explicit step 2");
  const cpl_road r0 = {1, 2, 1, 0};
  double v, a;
  CHECK(cpl_road_trapezoid(&r0, &s, 0.5, 6, &v, &a) == 2.1875 && v == 2.75 && a == 2,
        "trapezoid: d %g v %g a %g", cpl_road_trapezoid(&r0, &s, 0.5, 6, &v, &a), v, a);
}

/* Traction: forces (3, 0, 5) at (1, 0, 0) and (-1, 0, 2) at (0, 0, -1), rim
 * centre (0, 0, 0.5), start height 0.6: T_H = 3, T_R = -1, T_P = 2, load 7,
 * sinkage 0.1, torque (z - c_z) f_x - (x - c_x) f_z summed:
 * (-0.5)(3) - (1)(5) + (-1.5)(-1) - 0 = -5. */
static void traction(void) {
  const double F[6] = {3, 0, 5, -1, 0, 2}, X[6] = {1, 0, 0, 0, 0, -1};
  cpl_rim rim = {0};
  rim.c[2] = 0.5;
  rim.c0[2] = 0.6;
  double row[CPL_N_TRACTION];
  cpl_traction(F, X, 2, &rim, 0.25, row);
  CHECK(row[CPL_TR_T] == 0.25 && row[CPL_TR_TH] == 3 && row[CPL_TR_TR] == -1 &&
        row[CPL_TR_TP] == 2 && row[CPL_TR_LOAD] == 7 && row[CPL_TR_TORQUE] == -5,
        "traction row");
  CHECK_REL("sinkage", row[CPL_TR_SINK], 0.1, 1e-14);
}

/* Liveness on a fake wall clock: a look credits at most 0.25 s to the watch
 * clock, so a 30 s pause of the coupler itself counts 0.25 s; a dem that
 * promised heartbeats and is then silent for more than heartbeat_timeout
 * (10 s) of watch time is named. */
static void liveness(void) {
  proto_err err = {0};
  stub_plan(CPL_SCHEME_SERIAL);
  scene.heartbeat_timeout = 10;
  snprintf(procs[DEM1].exec, sizeof procs[DEM1].exec, "dem_server");
  for (int i = 0; i < NPEERS; i++) r.peers[i].connected = 1;
  r.peers[DEM1].hb_s = 1;
  double wall = 100;
  r.watch_wall = wall;
  CHECK(cpl_watch_at(&r, wall += 0.125) == 0.125, "a short gap counts whole");
  r.peers[DEM1].heard = r.watch;
  const double w0 = r.watch;
  CHECK(cpl_watch_at(&r, wall += 30) == w0 + 0.25, "the coupler's own pause counts 0.25 s");
  OK(cpl_check_silence(&r, r.watch));
  double now = r.watch;
  while (now - r.peers[DEM1].heard <= 10) now = cpl_watch_at(&r, wall += 0.125);
  r.err.msg[0] = 0;
  CHECK(cpl_check_silence(&r, now) < 0 && r.failed_peer == DEM1, "the silent dem is named");
  CHECK(strstr(r.err.msg, "participant 'dem1'") && strstr(r.err.msg, "heartbeat_timeout"),
        "message: %s", r.err.msg);
  cpl_fields_free(&r);
  memset(&r, 0, sizeof r);
}

int main(void) {
  liveness();
  schedules();
  exchange_bookkeeping();
  load_rig();
  road_body();
  traction();
  return cosim_test_done("test_stages");
}
