/* scenario_step.c — the scenario's stage of a coupled step: the coupler's
 * actions of the schedule (runner.h cpl_action) that move the rim frame and the
 * road to t_k and write them into the fields the requests read. The physics
 * is in scenario.c (rim kinematics and rigs, road profiles and road body,
 * traction); this file only moves values between it and the fields. */
#include "runner.h"

#include <string.h>

double cpl_vertical_load(const cpl_runner *r) {
  const cpl_field *f = &r->data.fields[CPL_F_SURF_FORCE];
  double fz = 0;
  for (int64_t i = 2; i < f->len; i += 3) fz += f->cur[i];
  return fz;
}

/* The grains' force on the tread, the sum over its nodes (N): x drives
 * the dbp rig's carriage, z is the vertical load. */
static void tread_force(const cpl_runner *r, double force[3]) {
  const cpl_field *f = &r->data.fields[CPL_F_SURF_FORCE];
  force[0] = force[1] = 0;
  for (int64_t i = 0; i + 2 < f->len; i += 3) {
    force[0] += f->cur[i];
    force[1] += f->cur[i + 1];
  }
  force[2] = cpl_vertical_load(r);
}

static void rim_to_fields(cpl_runner *r) {
  memcpy(r->data.fields[CPL_F_RIM_R].cur, r->data.rim.R, sizeof r->data.rim.R);
  memcpy(r->data.fields[CPL_F_RIM_C].cur, r->data.rim.c, sizeof r->data.rim.c);
  memcpy(r->data.fields[CPL_F_RIM_OMEGA].cur, r->data.rim.w, sizeof r->data.rim.w);
  memcpy(r->data.fields[CPL_F_RIM_V].cur, r->data.rim.v, sizeof r->data.rim.v);
}

/* (rim frame at t = 0, surface x0) -> (surface x, rim fields): the world
 * positions the first step starts from. */
void cpl_fields_from_rim(cpl_runner *r) {
  const cpl_surface *s = &r->plan->surf;
  double *x = r->data.fields[CPL_F_SURF_X].cur;
  for (int64_t i = 0; i < s->n_nodes; i++)
    for (int a = 0; a < 3; a++) {
      double acc = r->data.rim.c[a];
      for (int b = 0; b < 3; b++) acc += r->data.rim.R[3 * a + b] * s->x0[3 * i + b];
      x[3 * i + a] = acc;
    }
  rim_to_fields(r);
}

/* Road displacement at t_k: prescribed, or the road body moved by the
 * external force against the last contact force (explicit central
 * difference: the force at d_{k-1} moves it to d_k). The implicit scheme
 * integrates the road body itself (implicit.c). */
static void road_action(cpl_runner *r, int64_t k) {
  const cpl_scenario *s = &r->scene->scenario;
  double *d = r->data.fields[CPL_F_ROAD_D].cur;
  if (s->kind != CPL_SCN_INDENTATION) {
    d[0] = 0;
    return;
  }
  if (s->profile != CPL_PROFILE_FORCE) {
    d[0] = cpl_road_displacement(s, (double)k * r->scene->dt);
    return;
  }
  d[0] = cpl_road_explicit(&r->data.road, s, r->scene->dt);
}

/* (scenario, rim/road state, the grains' force of the fields) -> (rim frame,
 * road displacement fields of t_k) */
int cpl_do_action(cpl_runner *r, cpl_action a, int64_t k) {
  if (a == CPL_ACT_RIM && r->plan->fem >= 0) {
    double force[3];
    tread_force(r, force);
    if (cpl_rim_advance(&r->data.rim, &r->scene->scenario, r->scene->dt, force, &r->err) < 0)
      return -1;
    rim_to_fields(r);
  } else if (a == CPL_ACT_ROAD && r->plan->n_of_role[PROTO_ROLE_BLOCK]) {
    road_action(r, k);
  }
  return 0;
}
