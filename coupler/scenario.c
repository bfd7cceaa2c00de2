/* scenario.c — what the coupler prescribes.
 * tire_travel (seed 000 §5, docs/architecture.md): the rim sinks at constant speed until
 * the vertical load reaches the target, then rotates with omega about +y and
 * travels along +x with v = omega R (1 - s). Its height during travel:
 * frozen (rig "kinematic", the paper's) or a degree of freedom carrying the
 * load (rig "load", a single-wheel tester: coupler/README.md). Rig "dbp"
 * (Project Chrono's angular-velocity drawbar-pull rig): the height as in
 * "load", and the carriage free along +x, (grains' x force, travel clock) ->
 * carriage speed against a hold-then-ramp resistive force; the slip follows
 * (cpl_rim_slip) and cpl_dbp_row keeps its running averages.
 * indentation (seed 002 app. C.3, fig. 40, fig. 49): road displacement
 * histories towards the tread block. */
#include "coupler.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

static void rotation_y(double angle, double *R) {
  double c = cos(angle), s = sin(angle);
  const double r[9] = {c, 0, s, 0, 1, 0, -s, 0, c};
  memcpy(R, r, sizeof r);
}

void cpl_rim_init(cpl_rim *rim, const cpl_scenario *s) {
  memset(rim, 0, sizeof *rim);
  memcpy(rim->c, s->rim_center, sizeof rim->c);
  memcpy(rim->c0, s->rim_center, sizeof rim->c0);
  rotation_y(0, rim->R);
  rim->z_touch = rim->z_fit = NAN;
  if (cpl_scenario_rolls(s->kind)) rim->v[2] = -s->sinkage_velocity;
}

void cpl_rim_place(cpl_rim *rim, const double *x0, int64_t n, double z) {
  double lowest = INFINITY;
  for (int64_t i = 0; i < n; i++) lowest = fmin(lowest, x0[3 * i + 2]);
  rim->c[2] = rim->c0[2] = z - (n ? lowest : 0);
}

/* Sinkage phase of the load rig: the first touch, and the least-squares
 * sums of the load over the height once the load has reached W/2. */
static void rig_observe(cpl_rim *rim, const cpl_scenario *s, double load) {
  const double z = rim->c[2];
  if (isnan(rim->z_touch) && load > 0) rim->z_touch = z;
  if (isnan(rim->z_fit) && load >= 0.5 * s->sinkage_force) rim->z_fit = z;
  if (isnan(rim->z_fit)) return;
  const double dz = z - rim->z_fit;
  const double add[5] = {1, dz, load, dz * dz, dz * load};
  for (int i = 0; i < 5; i++) rim->fit[i] += add[i];
}

/* The soil's stiffness k = -dF/dz (N/m): the slope of the fit; if the fit
 * has too few points or no slope (the load jumped), the secant from the
 * first touch; 0 if neither is known. */
static double rig_stiffness(const cpl_rim *rim, const cpl_scenario *s) {
  const double *f = rim->fit;
  const double det = f[0] * f[3] - f[1] * f[1];
  if (f[0] >= 2 && det > 0) {
    double k = -(f[0] * f[4] - f[1] * f[2]) / det;
    if (k > 0) return k;
  }
  const double depth = rim->z_touch - rim->c[2];
  return depth > 0 ? s->sinkage_force / depth : 0;
}

/* The switch from sinkage to travel: the load rig's parameters, checked
 * against the soil's stiffness measured while sinking. */
static int rig_start(cpl_rim *rim, const cpl_scenario *s, double dt, proto_err *err) {
  rim->stiffness = rig_stiffness(rim, s);
  rim->mass = s->rig_mass;
  rim->damping = s->rig_damping;
  rim->travel_time = 0;
  rim->resistive_force = 0;
  if (s->rig == CPL_RIG_KINEMATIC) return 0;
  const double omega_dt = sqrt(rim->stiffness / rim->mass) * dt;
  if (s->rig == CPL_RIG_DBP)
    fprintf(stderr, "cosim: dbp rig: carriage %.10g kg, resistive force %.10g N held for "
            "%.10g s, then rising at %.10g N/s; running averages over %.10g s\n",
            s->carriage_mass, s->dbp_force_start, s->dbp_hold, s->dbp_force_rate,
            s->dbp_window);
  fprintf(stderr, "cosim: load rig: soil stiffness k = %.10g N/m (from the sinkage phase), "
          "mass %.10g kg, damping %.10g N s/m (%.3g of critical), omega dt = %.3g\n",
          rim->stiffness, rim->mass, rim->damping,
          rim->stiffness > 0 ? rim->damping / (2 * sqrt(rim->stiffness * rim->mass)) : 0,
          omega_dt);
  if (!(rim->stiffness > 0))
    fprintf(stderr, "cosim: warning: the load rig's stability cannot be checked: the "
            "sinkage phase showed no stiffness (the load reached sinkage_force = %g N at "
            "once)\n", s->sinkage_force);
  if (omega_dt > CPL_RIG_MAX_OMEGA_DT)
    return proto_fail(err, "scenario.rig_mass: %g kg on the soil's stiffness k = %.4g N/m "
                      "oscillates at omega = %.4g rad/s, omega dt = %.3g > %g at dt = %g s "
                      "(semi-implicit Euler: unstable at 2); give a larger rig_mass or a "
                      "smaller time.dt", rim->mass, rim->stiffness,
                      sqrt(rim->stiffness / rim->mass), omega_dt, CPL_RIG_MAX_OMEGA_DT, dt);
  return 0;
}

/* The integral of F_res from 0 to tau (N s): dbp_force_start tau, plus the
 * ramp's dbp_force_rate (tau - dbp_hold)^2 / 2 once tau passes the hold. */
static double resistance_integral(const cpl_scenario *s, double tau) {
  const double ramp = fmax(tau - s->dbp_hold, 0);
  return s->dbp_force_start * tau + 0.5 * s->dbp_force_rate * ramp * ramp;
}

double cpl_dbp_resistance(const cpl_scenario *s, double a, double b) {
  if (!(b > a)) return s->dbp_force_start + s->dbp_force_rate * fmax(a - s->dbp_hold, 0);
  /* for a step inside the hold or the ramp the mean is the midpoint value
   * (exact for a linear law); the difference of integrals also covers the
   * step across the kink */
  return (resistance_integral(s, b) - resistance_integral(s, a)) / (b - a);
}

double cpl_rim_slip(const cpl_rim *rim, const cpl_scenario *s) {
  const double rolling = rim->w[1] * s->radius; /* omega R, m/s */
  return rolling != 0 ? 1 - rim->v[0] / rolling : 0;
}

/* The dbp carriage over one step (the travel clock from tau to tau + dt):
 * m (v_k - v_{k-1}) = dt F_x - int F_res dt, the soil's impulse of the
 * step (F_x: impulse / dt of the exchange) and the resistance's exact one,
 * so the carriage's momentum balances the impulses to round-off whatever
 * dt; x then moves with v_k (semi-implicit Euler, as the load rig). */
static void carriage_advance(cpl_rim *rim, const cpl_scenario *s, double dt, double fx) {
  const double a = rim->travel_time, b = a + dt;
  rim->resistive_force = cpl_dbp_resistance(s, a, b);
  rim->v[0] += dt * (fx - rim->resistive_force) / s->carriage_mass;
  rim->travel_time = b;
}

/* Kinematic spin-up over T = scenario.spin_up: the speeds rise as u(tau) = tau / T to 1
 * (tau the travel clock), and a step [a, b] moves the rim by the exact integral of the
 * ramped speed, U(b) - U(a) with U = tau^2 / (2T) in the ramp and tau - T/2 after:
 * the step's speeds are their means over the step, so x = V tau^2 / (2T) and the angle
 * omega tau^2 / (2T) during the ramp, to round-off, and not V tau. */
static double ramp_integral(double T, double tau) {
  return tau < T ? 0.5 * tau * tau / T : tau - 0.5 * T;
}

static void spin_up_speeds(cpl_rim *rim, const cpl_scenario *s, double dt) {
  const double a = rim->travel_time, b = a + dt;
  const double u = a >= s->spin_up ? 1
                   : (ramp_integral(s->spin_up, b) - ramp_integral(s->spin_up, a)) / dt;
  rim->v[0] = s->omega * s->radius * (1 - s->slip) * u;
  rim->w[1] = s->omega * u;
  rim->travel_time = b;
}

int cpl_rim_advance(cpl_rim *rim, const cpl_scenario *s, double dt, const double force[3],
                    proto_err *err) {
  if (!cpl_scenario_rolls(s->kind)) return 0;
  const double vertical_load = force[2];
  if (!rim->travelling) rig_observe(rim, s, vertical_load);
  const int deep = s->sinkage_depth > 0 && rim->c0[2] - rim->c[2] >= s->sinkage_depth;
  if (!rim->travelling && (vertical_load >= s->sinkage_force || deep)) {
    rim->travelling = 1;
    rim->v[2] = 0; /* kinematic: frozen; load and dbp rigs: released at rest */
    rim->v[0] = s->omega * s->radius * (1 - s->slip); /* dbp: the carriage's start */
    rim->w[1] = s->omega;
    if (rig_start(rim, s, dt, err) < 0) return -1;
    if (s->spin_up > 0) spin_up_speeds(rim, s, dt);
  } else if (rim->travelling && s->spin_up > 0) {
    spin_up_speeds(rim, s, dt); /* kinematic only (scene.c) */
  } else if (rim->travelling && s->rig != CPL_RIG_KINEMATIC) {
    /* m z'' = F - W - c z': semi-implicit Euler, damping implicit */
    const double m = rim->mass, c = rim->damping;
    rim->v[2] = (rim->v[2] + dt * (vertical_load - s->sinkage_force) / m) / (1 + dt * c / m);
    if (s->rig == CPL_RIG_DBP) carriage_advance(rim, s, dt, force[0]);
  }
  for (int i = 0; i < 3; i++) rim->c[i] += rim->v[i] * dt;
  rim->angle += rim->w[1] * dt;
  rotation_y(rim->angle, rim->R);
  return 0;
}

double cpl_road_displacement(const cpl_scenario *s, double t) {
  double x = s->ramp_time > 0 ? t / s->ramp_time : 0;
  switch (s->profile) {
  case CPL_PROFILE_LINEAR:
    return s->depth * fmin(x, 1.0);
  case CPL_PROFILE_QUADRATIC:
    return s->depth * fmin(x * x, 1.0);
  case CPL_PROFILE_LOAD_HOLD_UNLOAD: {
    /* linear up over ramp_time, hold, linear down over ramp_time, then the
     * road keeps retracting at the same rate (to separate adhered points) */
    double t_hold_end = s->ramp_time + s->hold_time;
    if (t <= s->ramp_time) return s->depth * x;
    if (t <= t_hold_end) return s->depth;
    return s->depth * (1.0 - (t - t_hold_end) / s->ramp_time);
  }
  case CPL_PROFILE_SINUSOIDAL:
    return s->depth + s->amplitude * sin(2 * M_PI * s->frequency * t);
  case CPL_PROFILE_FORCE:
    return NAN;
  }
  return NAN;
}

/* (road body at t_{k-1}, contact force of the last step) -> (road at t_k) */
double cpl_road_explicit(cpl_road *road, const cpl_scenario *s, double dt) {
  double a = (s->road_force - road->force_last) / s->road_mass;
  road->v += a * dt;
  road->d += road->v * dt;
  return road->d;
}

/* (road body at t_{k-1}, contact force of t_k) -> (road at t_k) */
double cpl_road_trapezoid(const cpl_road *road, const cpl_scenario *s, double dt,
                          double force, double *v, double *a) {
  *a = (s->road_force - force) / s->road_mass;
  *v = road->v + 0.5 * dt * (road->a + *a);
  return road->d + 0.5 * dt * (road->v + *v);
}

/* (nodal forces, node positions, rim) -> (traction row) */
void cpl_traction(const double *F, const double *X, int64_t n, const cpl_rim *rim, double t,
                  double row[CPL_N_TRACTION]) {
  double th = 0, tr = 0, fz = 0, torque = 0;
  for (int64_t i = 0; i < n; i++) {
    const double *f = &F[3 * i], *x = &X[3 * i];
    if (f[0] > 0) th += f[0];
    else tr += f[0];
    fz += f[2];
    /* y-component of (x - c) × f */
    torque += (x[2] - rim->c[2]) * f[0] - (x[0] - rim->c[0]) * f[2];
  }
  double sinkage = rim->c0[2] - rim->c[2];
  double vals[CPL_N_TRACTION] = {t, th, tr, th - fabs(tr), fz, sinkage, torque};
  memcpy(row, vals, sizeof vals);
}

/* ------------------------------------------------------- the dbp series */

const char *const cpl_dbp_columns[CPL_N_DBP] = {
    "t", "phase", "carriage_speed", "resistive_force", "slip", "T_H_avg", "T_R_avg",
    "T_P_avg", "vertical_load_avg", "resistive_force_avg", "slip_avg"};

/* The step's values into the current bin; a full bin (avg_n[0] steps)
 * goes into the ring. The mean is over the current bin and the newest
 * complete bins, CPL_DBP_BINS bins' worth at most: from (B - 1) m + 1 to
 * B m steps once the ring is full, all steps since the travel start before. */
static void running_means(cpl_rim *rim, const double val[CPL_DBP_NAVG], double mean[CPL_DBP_NAVG]) {
  int64_t *n = rim->avg_n; /* steps per bin, steps in the current bin, bins, head */
  for (int q = 0; q < CPL_DBP_NAVG; q++) rim->avg_part[q] += val[q];
  if (++n[1] == n[0]) {
    memcpy(rim->avg_bins[n[3]], rim->avg_part, sizeof rim->avg_part);
    memset(rim->avg_part, 0, sizeof rim->avg_part);
    n[1] = 0;
    n[3] = (n[3] + 1) % CPL_DBP_BINS;
    if (n[2] < CPL_DBP_BINS) n[2]++;
  }
  const int64_t nb = n[2] < CPL_DBP_BINS - (n[1] > 0) ? n[2] : CPL_DBP_BINS - (n[1] > 0);
  double sum[CPL_DBP_NAVG];
  memcpy(sum, rim->avg_part, sizeof sum);
  for (int64_t j = 1; j <= nb; j++) {
    const double *bin = rim->avg_bins[(n[3] - j + CPL_DBP_BINS) % CPL_DBP_BINS];
    for (int q = 0; q < CPL_DBP_NAVG; q++) sum[q] += bin[q];
  }
  const double steps = (double)(nb * n[0] + n[1]);
  for (int q = 0; q < CPL_DBP_NAVG; q++) mean[q] = sum[q] / steps;
}

/* (rim after the step, the step's traction row) -> (dbp row; running sums) */
void cpl_dbp_row(cpl_rim *rim, const cpl_scenario *s, double dt,
                 const double traction[CPL_N_TRACTION], double row[CPL_N_DBP]) {
  memset(row, 0, sizeof(double) * CPL_N_DBP);
  row[CPL_DBP_T] = traction[CPL_TR_T];
  row[CPL_DBP_SPEED] = rim->v[0];
  if (!rim->travelling) return;
  row[CPL_DBP_PHASE] = rim->travel_time > s->dbp_hold ? 2 : 1;
  row[CPL_DBP_FORCE] = rim->resistive_force;
  row[CPL_DBP_SLIP] = cpl_rim_slip(rim, s);
  if (rim->avg_n[0] == 0) { /* steps per bin: the window in CPL_DBP_BINS bins */
    const double m = round(s->dbp_window / (dt * CPL_DBP_BINS));
    rim->avg_n[0] = m >= 1 ? (int64_t)m : 1;
  }
  const double val[CPL_DBP_NAVG] = {traction[CPL_TR_TH], traction[CPL_TR_TR],
                                    traction[CPL_TR_TP], traction[CPL_TR_LOAD],
                                    row[CPL_DBP_FORCE], row[CPL_DBP_SLIP]};
  running_means(rim, val, row + CPL_DBP_TH_AVG);
}
