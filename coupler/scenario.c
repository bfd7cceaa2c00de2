/* scenario.c — what the coupler prescribes.
 * tire_travel (seed 000 §5, docs/architecture.md): the rim sinks at constant speed until
 * the vertical load reaches the target, then rotates with omega about +y and
 * travels along +x with v = omega R (1 - s). Its height during travel:
 * frozen (rig "kinematic", the paper's) or a degree of freedom carrying the
 * load (rig "load", a single-wheel tester: coupler/README.md).
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
  if (s->kind == CPL_SCN_TIRE_TRAVEL) rim->v[2] = -s->sinkage_velocity;
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
  if (s->rig != CPL_RIG_LOAD) return 0;
  const double omega_dt = sqrt(rim->stiffness / rim->mass) * dt;
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

int cpl_rim_advance(cpl_rim *rim, const cpl_scenario *s, double dt, double vertical_load,
                    proto_err *err) {
  if (s->kind != CPL_SCN_TIRE_TRAVEL) return 0;
  if (!rim->travelling) rig_observe(rim, s, vertical_load);
  if (!rim->travelling && vertical_load >= s->sinkage_force) {
    rim->travelling = 1;
    rim->v[2] = 0; /* kinematic: frozen; load rig: released at rest */
    rim->v[0] = s->omega * s->radius * (1 - s->slip);
    rim->w[1] = s->omega;
    if (rig_start(rim, s, dt, err) < 0) return -1;
  } else if (rim->travelling && s->rig == CPL_RIG_LOAD) {
    /* m z'' = F - W - c z': semi-implicit Euler, damping implicit */
    const double m = rim->mass, c = rim->damping;
    rim->v[2] = (rim->v[2] + dt * (vertical_load - s->sinkage_force) / m) / (1 + dt * c / m);
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
