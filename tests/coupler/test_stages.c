/* The coupler's stages without a run (no sockets, no processes): the
 * schedule of each scheme on a stub set of peers; the exchange's
 * bookkeeping (the sub-stepped impulse / dt of two dem processes summed
 * exactly, the fem's surface copied); the load rig, the dbp rig (carriage,
 * resistance, running means), the road body and the
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
static cpl_plan plan; /* the stub plan: written here, read by the stages through r.plan */

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
  memset(&plan, 0, sizeof plan);
  r.plan = &plan;
  plan.fem = FEM;
  for (int i = 0; i < NPEERS; i++) {
    snprintf(procs[i].name, sizeof procs[i].name, "%s", names[i]);
    r.peers[i].proc = &procs[i];
    r.peers[i].role = roles[i];
    proto_dims_init(&r.peers[i].dims);
    r.peers[i].dims.surface = roles[i] != PROTO_ROLE_BLOCK;
    r.peers[i].dims.nodes = NODES;
    plan.n_of_role[roles[i]]++;
  }
  OK(cpl_contract_build(&plan.contract, t, nrows, &err));
  OK(cpl_fields_init(&r, NODES, &err));
  cpl_schedule_build(&plan, r.peers, r.n, scheme);
}

static void schedules(void) {
  stub_plan(CPL_SCHEME_SERIAL);
  /* 1. the dems (the lug action first: a no-op without lug processes); 2. the
   * lug-force and rim actions, fem; 3. road action, block */
  const cpl_exchange serial[] = {{0, -1, CPL_ACT_LUG},       {0, DEM0, CPL_ACT_NONE},
                                 {0, DEM1, CPL_ACT_NONE},    {1, -1, CPL_ACT_LUG_FORCE},
                                 {1, -1, CPL_ACT_RIM},       {1, FEM, CPL_ACT_NONE},
                                 {2, -1, CPL_ACT_ROAD},      {2, BLOCK, CPL_ACT_NONE}};
  CHECK(r.plan->nex == 8, "serial: 8 exchanges, got %d", r.plan->nex);
  for (int e = 0; e < 8 && e < r.plan->nex; e++)
    CHECK(r.plan->ex[e].stage == serial[e].stage && r.plan->ex[e].peer == serial[e].peer &&
          r.plan->ex[e].action == serial[e].action, "serial exchange %d", e);
  CHECK(cpl_last_stage(&r) == 2, "serial: three stages");
  cpl_fields_free(&r);
  memset(&r, 0, sizeof r);
  stub_plan(CPL_SCHEME_PARALLEL);
  /* one stage: the actions first (the last step's values), then every
   * process in the order's order (dem, fem, block) */
  const cpl_exchange parallel[] = {{0, -1, CPL_ACT_LUG},   {0, -1, CPL_ACT_LUG_FORCE},
                                   {0, -1, CPL_ACT_RIM},   {0, -1, CPL_ACT_ROAD},
                                   {0, DEM0, CPL_ACT_NONE}, {0, DEM1, CPL_ACT_NONE},
                                   {0, FEM, CPL_ACT_NONE},  {0, BLOCK, CPL_ACT_NONE}};
  CHECK(r.plan->nex == 8 && cpl_last_stage(&r) == 0, "parallel: 8 exchanges in one stage");
  for (int e = 0; e < 8 && e < r.plan->nex; e++)
    CHECK(r.plan->ex[e].stage == parallel[e].stage && r.plan->ex[e].peer == parallel[e].peer &&
          r.plan->ex[e].action == parallel[e].action, "parallel exchange %d", e);
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
  const double *F = r.data.fields[CPL_F_SURF_FORCE].cur;
  int exact = 1;
  for (int j = 0; j < 3 * NODES; j++) exact &= F[j] == F0 * (j + 1) + F1 * (j + 1);
  CHECK(exact, "surface.force = the two dems' impulse / dt summed, exactly");
  CHECK(r.data.in[CPL_F_SURF_FORCE] == F, "the fem's request reads the committed sum");
  CHECK(r.data.fields[CPL_F_SURF_FORCE].given == 2, "both dems gave it");

  m = &r.peers[FEM].reply;
  proto_msg_reset(m, "fem", "done", 1, scene.dt);
  proto_msg_add(m, PROTO_A_X, PROTO_F8, 2, n3, x);
  proto_msg_add(m, PROTO_A_V, PROTO_F8, 2, n3, v);
  cpl_stage_take(&r, 1, 1);
  CHECK(memcmp(r.data.fields[CPL_F_SURF_X].cur, x, sizeof x) == 0 &&
        memcmp(r.data.fields[CPL_F_SURF_V].cur, v, sizeof v) == 0, "the fem's surface copied");
  CHECK(r.data.fields[CPL_F_SURF_FORCE].cur == F, "stage 2 left the forces alone");

  m = &r.peers[BLOCK].reply;
  proto_msg_reset(m, "block", "done", 1, scene.dt);
  proto_msg_add(m, PROTO_A_FORCE, PROTO_F8, 1, one, &road_f);
  cpl_stage_take(&r, 2, 0); /* not committed: the value waits in out */
  CHECK(r.data.fields[CPL_F_ROAD_FORCE].out[0] == 7 && r.data.fields[CPL_F_ROAD_FORCE].cur[0] == 0,
        "an uncommitted reply stays in out");
  for (int i = 0; i < NPEERS; i++) proto_msg_free(&r.peers[i].reply);
  cpl_fields_free(&r);
  memset(&r, 0, sizeof r);
}

/* The rim advanced with a vertical load alone (N). */
static int advance_z(cpl_rim *rim, const cpl_scenario *s, double dt, double fz, proto_err *err) {
  const double force[3] = {0, 0, fz};
  return cpl_rim_advance(rim, s, dt, force, err);
}

/* The rigs' rolling rim: from z = 1 m, sinking at 0.01 m/s until 80 N, then
 * omega = 2 rad/s on R = 0.5 m at slip 0.1 (v = 0.9 m/s). */
static cpl_scenario rolling_scene(cpl_scenario_kind kind) {
  cpl_scenario s = {0};
  s.kind = kind;
  s.rim_center[2] = 1;
  s.sinkage_velocity = 0.01;
  s.sinkage_force = 80;
  s.omega = 2;
  s.radius = 0.5;
  s.slip = 0.1;
  return s;
}

/* Load rig (README "Scenario keys"): dt = 1e-3 s, sinking at 0.01 m/s; the
 * loads 0, 40 (= W/2: the fit starts), 80 (= W: travel) give two fit points
 * dz = 0 and dz = -1e-5 m at F = 40, 80 N, so k = 40 / 1e-5 = 4e6 N/m. Then
 * with F = 88 N: v_z = dt (F - W)/m / (1 + dt c/m) = 1e-3 / 1.00125. */
static void load_rig(void) {
  cpl_scenario s = rolling_scene(CPL_SCN_TIRE_TRAVEL);
  s.rig = CPL_RIG_LOAD;
  s.rig_mass = 8;
  s.rig_damping = 10;
  const double dt = 1e-3;
  cpl_rim rim;
  proto_err err = {0};
  cpl_rim_init(&rim, &s);
  OK(advance_z(&rim, &s, dt, 0, &err));
  CHECK_REL("sinking", rim.c[2], 1 - 1e-5, 1e-14);
  OK(advance_z(&rim, &s, dt, 40, &err));
  OK(advance_z(&rim, &s, dt, 80, &err));
  CHECK(rim.travelling, "travel starts at the load");
  CHECK_REL("soil stiffness k", rim.stiffness, 4e6, 1e-9);
  CHECK_REL("travel speed omega R (1 - s)", rim.v[0], 2 * 0.5 * 0.9, 1e-15);
  CHECK_REL("rim height frozen at release", rim.c[2], 1 - 2e-5, 1e-14);
  CHECK_REL("x after one travel step", rim.c[0], 0.9e-3, 1e-14);
  OK(advance_z(&rim, &s, dt, 88, &err));
  const double vz = 1e-3 / 1.00125;
  CHECK_REL("rig velocity", rim.v[2], vz, 1e-14);
  CHECK_REL("rig height", rim.c[2], 1 - 2e-5 + vz * dt, 1e-14);
  CHECK_REL("angle 2 omega dt", rim.angle, 2 * 2 * dt, 1e-14);
  /* m = 0.1 kg: omega dt = sqrt(4e6 / 0.1) 1e-3 = 6.3 > 1: refused */
  s.rig_mass = 0.1;
  cpl_rim_init(&rim, &s);
  OK(advance_z(&rim, &s, dt, 0, &err));
  OK(advance_z(&rim, &s, dt, 40, &err));
  FAILS_WITH(advance_z(&rim, &s, dt, 80, &err), "scenario.rig_mass");
}

/* sinkage_depth (README "Scenario keys"): with no load the rim sinks at 0.01 m/s,
 * dt = 1e-3 s, and stops at the first step that starts 3e-5 m down (the sum of
 * three steps' 1e-5 m, bit for bit); without the key it keeps sinking. */
static double rim_sunk(const cpl_rim *rim) { return rim->c0[2] - rim->c[2]; }

static void sinkage_depth(void) {
  cpl_scenario s = {0};
  s.kind = CPL_SCN_TIRE_ROAD;
  s.rim_center[2] = 1;
  s.sinkage_velocity = 0.01;
  s.sinkage_force = 80;
  const double dt = 1e-3;
  cpl_rim rim, free_rim;
  proto_err err = {0};
  cpl_rim_init(&free_rim, &s);
  for (int k = 0; k < 3; k++) OK(advance_z(&free_rim, &s, dt, 0, &err));
  s.sinkage_depth = rim_sunk(&free_rim);
  cpl_rim_init(&rim, &s);
  for (int k = 0; k < 6; k++) OK(advance_z(&rim, &s, dt, 0, &err));
  CHECK(rim.travelling, "the rim stops at sinkage_depth without a load");
  CHECK(rim.c[2] == free_rim.c[2], "at the same height, bit for bit (%.17g, %.17g)", rim.c[2],
        free_rim.c[2]);
  s.sinkage_depth = 0;
  cpl_rim_init(&rim, &s);
  for (int k = 0; k < 6; k++) OK(advance_z(&rim, &s, dt, 0, &err));
  CHECK(!rim.travelling && rim.c[2] < free_rim.c[2], "sinkage_depth 0: the load alone stops it");
}

/* spin_up (README "Scenario keys"): the kinematic rig's omega = 2 rad/s and
 * v = omega R (1 - s) = 0.9 m/s rise linearly over T = 10.5 ms (not a multiple of
 * dt = 1 ms) once the load is reached. x and the angle are the integrals of the
 * ramped speeds: V tau^2 / (2T) in the ramp, V (tau - T/2) after (tau = n dt the
 * travel clock); spin_up 0 is the instant start, bit for bit the sum of V dt. */
static void spin_up(void) {
  cpl_scenario s = rolling_scene(CPL_SCN_TIRE_ROAD);
  const double dt = 1e-3, T = 10.5e-3, V = 0.9;
  proto_err err = {0};
  cpl_rim rim;
  s.spin_up = T;
  cpl_rim_init(&rim, &s);
  double err_x = 0, err_a = 0;
  for (int n = 1; n <= 20; n++) {
    OK(advance_z(&rim, &s, dt, 80, &err));
    const double tau = n * dt, U = tau < T ? 0.5 * tau * tau / T : tau - 0.5 * T;
    err_x = fmax(err_x, fabs(rim.c[0] - V * U) / (V * U));
    err_a = fmax(err_a, fabs(rim.angle - 2 * U) / (2 * U));
    if (n == 5) CHECK_REL("speed mid-ramp: the mean over [4, 5] ms", rim.v[0], V * 4.5e-3 / T, 1e-14);
    if (n == 11) CHECK_REL("omega across the ramp's end", rim.w[1],
                           2 * (U - 0.5 * 1e-4 / T) / dt, 1e-12);
  }
  CHECK(rim.travelling && rim.c[2] == 1, "travel from the first step, height frozen");
  CHECK(err_x < 1e-13, "x = V tau^2 / (2T) in the ramp, V (tau - T/2) after (rel. %.3g)", err_x);
  CHECK(err_a < 1e-13, "angle = omega tau^2 / (2T), omega (tau - T/2) (rel. %.3g)", err_a);
  CHECK(rim.v[0] == V * 1.0 && rim.w[1] == 2, "full speed after the ramp, exactly");
  s.spin_up = 0;
  cpl_rim_init(&rim, &s);
  double x = 0, a = 0;
  for (int n = 1; n <= 20; n++) {
    OK(advance_z(&rim, &s, dt, 80, &err));
    x += 2 * 0.5 * (1 - 0.1) * dt;
    a += 2 * dt;
  }
  CHECK(rim.c[0] == x && rim.angle == a, "spin_up 0: the instant start, bit for bit");
}

/* ----------------------------------------------------------- the dbp rig */

/* A dbp scene: omega R = 1 m/s, W = 80 N carried from the first step,
 * carriage 8 kg starting at slip 0.1; resistance F0 = -5 N (a push) held
 * for 0.25 s, then rising at 40 N/s. dt = 1/1024 s: the hold ends between
 * steps 256 and 257 (0.25 = 256/1024 exactly: on a step), so the kink is
 * moved to 0.2505 s to fall inside a step. */
static cpl_scenario dbp_scene(void) {
  cpl_scenario s = rolling_scene(CPL_SCN_TIRE_TRAVEL);
  s.rig = CPL_RIG_DBP;
  s.rig_mass = 8;
  s.carriage_mass = 8;
  s.dbp_hold = 0.2505;
  s.dbp_force_start = -5;
  s.dbp_force_rate = 40;
  s.dbp_window = 2.0 * CPL_DBP_BINS / 1024; /* 2 steps per bin */
  return s;
}

/* Round-off of a sum of ~1000 terms of size ~1 (double, 2.2e-16 each):
 * well below 1e-12 relative. */
#define DBP_ROUNDOFF 1e-12

/* The resistance law: means over steps inside the hold, inside the ramp
 * and across the kink, from the integral worked by hand. */
static void dbp_resistance(void) {
  const cpl_scenario s = dbp_scene();
  CHECK_REL("hold", cpl_dbp_resistance(&s, 0.1, 0.2), -5, 1e-15);
  /* ramp [0.3, 0.4]: the midpoint 0.35: -5 + 40 (0.35 - 0.2505) = -1.02 */
  CHECK_REL("ramp", cpl_dbp_resistance(&s, 0.3, 0.4), -1.02, 1e-13);
  /* across the kink [0.25, 0.26]: -5 + 40 (0.26 - 0.2505)^2 / 2 / 0.01 = -4.8195 */
  CHECK_REL("kink", cpl_dbp_resistance(&s, 0.25, 0.26), -4.8195, 1e-13);
}

/* The stub soil's horizontal force of step k (N): a constant 3 N (the
 * analytic part) or, with wobble, 3 N + 2 sin(0.37 k) (any history: the
 * impulse balance must hold whatever the force). */
static double stub_fx(int64_t k, int wobble) { return 3 + (wobble ? 2 * sin(0.37 * (double)k) : 0); }

/* Constant F_x = 3 N: the carriage from v0 = omega R (1 - s) = 0.9 m/s is
 * v(tau) = v0 + (F_x tau - int_0^tau F_res) / m exactly (the midpoint rule
 * is exact for a piecewise linear F_res integrated piece by piece), so the
 * discrete speed equals it to round-off at every step; the slip is
 * 1 - v / (omega R); the load carried at W keeps the height. With the
 * wobbling force: m (v_N - v_0) = sum dt F_x - int_0^T F_res to round-off,
 * and sum dt F_res (the rows' mean forces) = int_0^T F_res. */
static void dbp_carriage(void) {
  const cpl_scenario s = dbp_scene();
  const double dt = 1.0 / 1024, m = s.carriage_mass, v0 = 0.9;
  proto_err err = {0};
  for (int wobble = 0; wobble < 2; wobble++) {
    cpl_rim rim;
    cpl_rim_init(&rim, &s);
    OK(advance_z(&rim, &s, dt, 80, &err)); /* the load at once: travel */
    CHECK(rim.travelling && rim.v[0] == v0, "travel from the first step at v0 (%g)", rim.v[0]);
    const double z0 = rim.c[2];
    double impulse = 0, resisted = 0, worst = 0, worst_slip = 0;
    const int64_t n = 600; /* 0.586 s: hold and 0.33 s of ramp */
    for (int64_t k = 1; k <= n; k++) {
      const double force[3] = {stub_fx(k, wobble), 0, 80};
      OK(cpl_rim_advance(&rim, &s, dt, force, &err));
      impulse += dt * force[0];
      resisted += dt * rim.resistive_force;
      if (wobble) continue;
      const double tau = (double)k * dt, ramp = fmax(tau - s.dbp_hold, 0);
      const double v = v0 + (3 * tau - (-5 * tau + 0.5 * 40 * ramp * ramp)) / m;
      worst = fmax(worst, fabs(rim.v[0] / v - 1));
      worst_slip = fmax(worst_slip, fabs(cpl_rim_slip(&rim, &s) - (1 - v / 1.0)));
    }
    const double T = (double)n * dt, ramp = T - s.dbp_hold;
    const double exact = -5 * T + 0.5 * 40 * ramp * ramp;
    if (!wobble) {
      CHECK(worst < DBP_ROUNDOFF, "carriage speed = analytic to round-off (worst %.3g)", worst);
      CHECK(worst_slip < DBP_ROUNDOFF, "slip = 1 - v / (omega R) (worst %.3g)", worst_slip);
    }
    CHECK_REL("resistance's impulse = int F_res", resisted, exact, DBP_ROUNDOFF);
    CHECK_REL("impulse balance m (v_N - v_0)", m * (rim.v[0] - v0), impulse - exact,
              DBP_ROUNDOFF);
    CHECK(rim.c[2] == z0 && rim.v[2] == 0, "the load carried: height kept");
    CHECK_REL("travel clock", rim.travel_time, T, 1e-15);
  }
}

/* Running means: T_H of step j = j (j = 0 at the travel start), 2 steps a
 * bin, 32 bins. After the rows 0..99 (100 steps, 50 bins: the ring full,
 * no partial bin) the mean is over the last 64 steps, 36..99: 67.5; after
 * 0..100 (a partial bin of 1) over 31 bins + 1 = 63 steps, 38..100: 69. The
 * phase: 1 in the hold, 2 in the ramp. */
static void dbp_means(void) {
  const cpl_scenario s = dbp_scene();
  const double dt = 1.0 / 1024;
  proto_err err = {0};
  cpl_rim rim;
  cpl_rim_init(&rim, &s);
  double tr[CPL_N_TRACTION] = {0}, row[CPL_N_DBP];
  cpl_dbp_row(&rim, &s, dt, tr, row);
  CHECK(row[CPL_DBP_PHASE] == 0 && row[CPL_DBP_TH_AVG] == 0, "sinkage: phase 0, no means");
  OK(advance_z(&rim, &s, dt, 80, &err));
  for (int j = 0; j <= 100; j++) {
    if (j) OK(advance_z(&rim, &s, dt, 80, &err));
    tr[CPL_TR_TH] = j;
    tr[CPL_TR_TP] = 2.0 * j;
    cpl_dbp_row(&rim, &s, dt, tr, row);
    if (j == 99) {
      CHECK(row[CPL_DBP_TH_AVG] == 67.5, "mean over 64 steps: %.17g", row[CPL_DBP_TH_AVG]);
      CHECK(row[CPL_DBP_TP_AVG] == 135, "T_P mean: %.17g", row[CPL_DBP_TP_AVG]);
    }
    if (j == 3) CHECK(row[CPL_DBP_TH_AVG] == 1.5, "before the ring fills: all steps");
  }
  CHECK(row[CPL_DBP_TH_AVG] == 69, "mean over 63 steps: %.17g", row[CPL_DBP_TH_AVG]);
  CHECK(row[CPL_DBP_PHASE] == 1 && row[CPL_DBP_SLIP] == 1 - row[CPL_DBP_SPEED],
        "hold at step 100 (tau = %g), slip from the speed", rim.travel_time);
  while (rim.travel_time <= s.dbp_hold) OK(advance_z(&rim, &s, dt, 80, &err));
  cpl_dbp_row(&rim, &s, dt, tr, row);
  CHECK(row[CPL_DBP_PHASE] == 2, "ramp after the hold");
}

/* A known force-slip law recovered: the stub soil pulls with
 * F_x(s) = 60 (1 - exp(-s / 0.1)) - 10 N (a Janosi-Hanamoto-like rise from
 * a running resistance of 10 N), and the resistance rises slowly (4 N/s
 * from -8 N after 0.5 s). Quasi-steady, F_res = F_x(s) - m a with
 * m a = -m omega R ds/dt and ds/dt = rate / F_x'(s): the curve of the
 * resistive force over the slip lags the law by m omega R rate / F_x'(s)
 * (1.07 N at s = 0.3 where F_x' = 30 N; less below). Checked: over the
 * ramp, |F_res - F_x(s)| is within 1.5 times that lag (the start of the
 * ramp's transient decays as exp(-t F_x' / (m omega R)), fast against the
 * ramp), and the slip covers 0.05..0.3. */
static double stub_law(double slip) { return 60 * (1 - exp(-slip / 0.1)) - 10; }

static void dbp_law(void) {
  cpl_scenario s = dbp_scene();
  s.dbp_hold = 0.5;
  s.dbp_force_start = -8;
  s.dbp_force_rate = 4;
  s.slip = 0;
  const double dt = 1.0 / 1024;
  proto_err err = {0};
  cpl_rim rim;
  cpl_rim_init(&rim, &s);
  OK(advance_z(&rim, &s, dt, 80, &err));
  double lo = 1, hi = 0, worst = 0;
  for (int64_t k = 1; k <= 20 * 1024; k++) {
    const double slip = cpl_rim_slip(&rim, &s);
    const double force[3] = {stub_law(slip), 0, 80};
    OK(cpl_rim_advance(&rim, &s, dt, force, &err));
    if (rim.travel_time < s.dbp_hold + 1) continue; /* the hold's approach settled */
    const double now = cpl_rim_slip(&rim, &s);
    if (now > 0.3) break;
    const double slope = 600 * exp(-now / 0.1); /* F_x'(s), N */
    const double lag = s.carriage_mass * 1.0 * s.dbp_force_rate / slope;
    worst = fmax(worst, fabs(rim.resistive_force - stub_law(now)) / lag);
    lo = fmin(lo, now);
    hi = fmax(hi, now);
  }
  printf("dbp law: slip %.3g..%.3g, |F_res - F_x(s)| at most %.3g quasi-steady lags\n", lo, hi,
         worst);
  CHECK(lo < 0.05 && hi > 0.29, "the ramp sweeps the slip %.3g..%.3g", lo, hi);
  CHECK(worst < 1.5, "F_res(s) on the law within 1.5 quasi-steady lags (worst %.3g)", worst);
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
  sinkage_depth();
  spin_up();
  dbp_resistance();
  dbp_carriage();
  dbp_means();
  dbp_law();
  road_body();
  traction();
  return cosim_test_done("test_stages");
}
