/* scenario.c — what the coupler prescribes.
 * tire_travel (seed 000 §5, DESIGN.md): the rim sinks at constant speed until
 * the vertical load reaches the target, then rotates with omega about +y and
 * travels along +x with v = omega R (1 - s).
 * indentation (seed 002 app. C.3, fig. 40, fig. 49): road displacement
 * histories towards the tread block. */
#include "coupler.h"

#include <math.h>
#include <string.h>

static void rotation_y(double angle, double *R) {
  double c = cos(angle), s = sin(angle);
  const double r[9] = {c, 0, s, 0, 1, 0, -s, 0, c};
  memcpy(R, r, sizeof r);
}

void cpl_rim_init(cpl_rim *rim, const cpl_scenario *s) {
  memset(rim, 0, sizeof *rim);
  memcpy(rim->c, s->rim_center, sizeof rim->c);
  rotation_y(0, rim->R);
  if (s->kind == CPL_SCN_TIRE_TRAVEL) rim->v[2] = -s->sinkage_velocity;
}

void cpl_rim_advance(cpl_rim *rim, const cpl_scenario *s, double dt,
                     double vertical_load) {
  if (s->kind != CPL_SCN_TIRE_TRAVEL) return;
  if (!rim->travelling && vertical_load >= s->sinkage_force) {
    rim->travelling = 1;
    rim->v[2] = 0;
    rim->v[0] = s->omega * s->radius * (1 - s->slip);
    rim->w[1] = s->omega;
  }
  for (int i = 0; i < 3; i++) rim->c[i] += rim->v[i] * dt;
  rim->angle += rim->w[1] * dt;
  rotation_y(rim->angle, rim->R);
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
