/* scenario_step.c — the scenario's stage of a coupled step: the coupler's
 * actions of the schedule (runner.h cpl_action) that move the rim frame and the
 * road to t_k and write them into the fields the requests read. The physics
 * is in scenario.c (rim kinematics and rigs, road profiles and road body,
 * traction); this file only moves values between it and the fields. */
#include "runner.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
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

/* tire_road, before the lug processes: (surface x of t_{k-1}, lug.force) ->
 * (who serves which lug, lug.d, lug.origin, lug.base) */
static int lug_action(cpl_runner *r) {
  const cpl_scenario *s = &r->scene->scenario;
  const cpl_lugs *L = &r->plan->lugs;
  const double *x = r->data.fields[CPL_F_SURF_X].cur;
  cpl_lug_slots *S = &r->data.lug;
  for (int j = 0; j < L->n; j++) r->data.lug_d[j] = cpl_lug_approach(L, j, x, s->road_z);
  /* a shaped face meets the road with its deepest node, a flat one everywhere at once */
  for (int j = 0; j < L->n && !s->lug_flat; j++)
    r->data.lug_reach[j] = cpl_lug_reach(L, j, x, s->road_z);
  if (cpl_lug_assign(S, L->n, s->lug_flat ? r->data.lug_d : r->data.lug_reach, s->lug_engage,
                     r->data.fields[CPL_F_LUG_FORCE].cur, &r->err) < 0)
    return -1;
  double *d = r->data.fields[CPL_F_LUG_D].cur, *o = r->data.fields[CPL_F_LUG_ORIGIN].cur;
  double *base = r->data.fields[CPL_F_LUG_BASE].cur; /* 0 for a flat face, and while idle */
  for (int p = 0; p < S->n; p++) {
    d[p] = S->lug[p] >= 0 ? r->data.lug_d[S->lug[p]] : CPL_LUG_IDLE_D;
    if (S->lug[p] >= 0 && !s->lug_flat) cpl_lug_base(L, S->lug[p], x, &base[(size_t)p * (size_t)L->cells]);
    o[2 * p] = o[2 * p + 1] = 0;
    if (S->lug[p] >= 0) cpl_lug_centre(L, S->lug[p], x, &o[2 * p]);
    S->ahead[p] = S->lug[p] >= 0 ? o[2 * p] - r->data.rim.c[0] : 0; /* both of t_{k-1} */
  }
  return 0;
}

/* tire_road, after the lug processes: (lug.cell_force, or lug.force and
 * lug.cop for flat faces; surface x) -> (surface.force: each block's force on
 * its lug's nodes, the road's penalty on the others) */
static void lug_force_action(cpl_runner *r) {
  const cpl_scenario *s = &r->scene->scenario;
  const cpl_lugs *L = &r->plan->lugs;
  cpl_field *f = &r->data.fields[CPL_F_SURF_FORCE];
  const double *x = r->data.fields[CPL_F_SURF_X].cur;
  const double *F = r->data.fields[CPL_F_LUG_FORCE].cur, *cop = r->data.fields[CPL_F_LUG_COP].cur;
  const double *cell = r->data.fields[CPL_F_LUG_CELL_FORCE].cur;
  memset(f->cur, 0, sizeof(double) * (size_t)f->len);
  for (int p = 0; p < r->data.lug.n; p++) {
    const int j = r->data.lug.lug[p];
    if (j < 0) continue;
    if (s->lug_flat) cpl_lug_spread(L, j, x, F[p], &cop[2 * p], f->cur);
    else cpl_lug_spread_cells(L, j, &cell[(size_t)p * (size_t)L->cells], f->cur);
  }
  r->data.lug_penalty = cpl_road_penalty(L, x, r->plan->surf.n_nodes, s->road_z, s->road_penalty,
                                         f->cur);
}

/* (scenario, rim/road state, the grains' force of the fields) -> (rim frame,
 * road displacement fields of t_k) */
int cpl_do_action(cpl_runner *r, cpl_action a, int64_t k) {
  const int lugs = r->plan->n_of_role[PROTO_ROLE_LUG] > 0;
  if (a == CPL_ACT_LUG && lugs) return lug_action(r);
  if (a == CPL_ACT_LUG_FORCE && lugs) {
    lug_force_action(r);
    return 0;
  }
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

/* (the lug processes' ready: cell_xy) -> (their grid on every lug face) */
static int lug_grid(cpl_runner *r) {
  cpl_plan *p = r->draft;
  const double *xy = NULL;
  const char *first = NULL;
  int64_t c = -1;
  for (int i = 0; i < r->n; i++) {
    const cpl_peer *q = &r->peers[i];
    if (q->role != PROTO_ROLE_LUG) continue;
    const double *a = proto_msg_data(&q->reply, PROTO_A_CELL_XY);
    if (!xy) {
      xy = a, c = q->dims.cells, first = q->proc->name;
      continue;
    }
    if (q->dims.cells != c || memcmp(a, xy, sizeof(double) * 2 * (size_t)c) != 0)
      return proto_fail(&r->err, "scenario tire_road: lug processes '%s' and '%s' have "
                        "different block grids (%lld and %lld cells, or other cell centres): "
                        "every lug process needs the same grid (the coupler lays one grid on "
                        "every lug face)", first, q->proc->name, (long long)c,
                        (long long)q->dims.cells);
  }
  if (!xy || c < 1 || c > INT32_MAX / 3)
    return proto_fail(&r->err, "scenario tire_road: the lug processes declared no cells");
  if (cpl_lugs_map(&p->lugs, p->surf.x0, p->surf.tri, p->surf.n_tris, xy, (int)c, &r->err) < 0)
    return -1;
  if (!r->opts->quiet)
    printf("tire_road: blocks of %lld cells, lug faces %s (at least %.1f %% of a block's "
           "cells lie on its face, at most %.1f %% of a face's area beyond the grid)\n",
           (long long)c, r->scene->scenario.lug_flat ? "flat" : "shaped",
           100 * p->lugs.covered, 100 * p->lugs.beyond);
  if (p->lugs.beyond > CPL_LUG_BEYOND_WARN && !r->scene->scenario.lug_flat)
    fprintf(stderr, "cosim: warning: %.1f %% of a lug face's area lies beyond the lug "
            "processes' block grid: no cell meets the road there (make the grid cover the "
            "face: nx dx along the circumference, ny dy along the axle)\n", 100 * p->lugs.beyond);
  return 0;
}

int cpl_lugs_setup(cpl_runner *r) {
  cpl_plan *p = r->draft;
  const int np = p->n_of_role[PROTO_ROLE_LUG];
  if (!np) return 0;
  if (cpl_lugs_find(p->surf.x0, p->surf.n_nodes, p->surf.tri, p->surf.n_tris,
                    r->scene->scenario.lug_tolerance, &p->lugs, &r->err) < 0)
    return -1;
  r->data.lug.n = np;
  for (int s = 0; s < np; s++) r->data.lug.lug[s] = -1;
  if (lug_grid(r) < 0) return -1;
  double amin = INFINITY, amax = 0;
  for (int j = 0; j < p->lugs.n; j++)
    amin = fmin(amin, p->lugs.area[j]), amax = fmax(amax, p->lugs.area[j]);
  if (!r->opts->quiet)
    printf("tire_road: %d lug faces on the outer radius %.6g m (areas %.4g-%.4g mm2), served by "
           "%d lug processes\n", p->lugs.n, p->lugs.outer_radius, amin * 1e6, amax * 1e6, np);
  r->data.lug_d = calloc((size_t)p->lugs.n, sizeof(double));
  r->data.lug_reach = calloc((size_t)p->lugs.n, sizeof(double));
  /* /coupler/lugs: t, handovers, penalty, then per process lug, d, force, cop_x, cop_y,
   * x (ahead of the rim centre), y of its face (record.c) */
  enum { PER = CPL_LUG_COLS, HEAD = 3, W = 32 };
  p->n_lug_cols = HEAD + PER * np;
  p->lug_cols = malloc(sizeof(char *) * (size_t)p->n_lug_cols);
  p->lug_col_text = malloc((size_t)W * (size_t)p->n_lug_cols);
  if (!r->data.lug_d || !r->data.lug_reach || !p->lug_cols || !p->lug_col_text)
    return proto_fail(&r->err, "out of memory (lugs)");
  static const char *const head[HEAD] = {"t", "handovers", "road_penalty"};
  static const char *const per[PER] = {"lug", "d", "force", "cop_x", "cop_y", "x", "y"};
  for (int c = 0; c < p->n_lug_cols; c++) {
    char *t = p->lug_col_text + (size_t)W * (size_t)c;
    if (c < HEAD) snprintf(t, W, "%s", head[c]);
    else snprintf(t, W, "%s%d", per[(c - HEAD) % PER], (c - HEAD) / PER);
    p->lug_cols[c] = t;
  }
  return 0;
}

void cpl_lugs_teardown(cpl_plan *p, cpl_data *d) {
  cpl_lugs_free(&p->lugs);
  free(p->lug_cols);
  free(p->lug_col_text);
  p->lug_cols = NULL;
  p->lug_col_text = NULL;
  free(d->lug_d);
  free(d->lug_reach);
  d->lug_d = d->lug_reach = NULL;
}
