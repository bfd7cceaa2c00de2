/* implicit.c — the implicit scheme's step (PROTOCOL.md "Schemes";
 * docs/coupling-schemes.md; Degroote et al. 2009): the parallel stage
 * repeated on an interface vector until it stops changing, accelerated
 * (accel.c: IQN-ILS, Aitken or constant), the processes rolled back between
 * repeats; the impulse defect of the last iterate carried into the next
 * step so that the impulses balance exactly over the run. */
#include "runner.h"

#include <stdlib.h>
#include <string.h>

/* The interface vector of the implicit scheme: what one process gives and
 * another takes within the same step. [surface positions at t_k | surface
 * forces | road force (force-driven road only)]. The DEM takes the
 * positions through the secant velocity (d - x_{k-1})/dt, so its surface
 * moves exactly from the tread's x_{k-1} to its x_k within the step. */
static int road_coupled(const cpl_runner *r) {
  const cpl_scenario *s = &r->scene->scenario;
  return r->plan->n_of_role[PROTO_ROLE_BLOCK] && s->kind == CPL_SCN_INDENTATION &&
         s->profile == CPL_PROFILE_FORCE;
}

static int64_t if_len(const cpl_runner *r, int f) {
  int surface = r->plan->fem >= 0 && r->plan->n_of_role[PROTO_ROLE_DEM];
  return f == CPL_IF_ROAD ? road_coupled(r) : surface ? 3 * r->plan->surf.n_nodes : 0;
}

int cpl_implicit_init(cpl_runner *r) {
  int64_t len[CPL_N_IF], total = 0;
  for (int f = 0; f < CPL_N_IF; f++) total += len[f] = if_len(r, f);
  size_t n3 = sizeof(double) * (size_t)(3 * r->plan->surf.n_nodes + 1);
  r->data.xi = calloc((size_t)total + 1, sizeof(double));
  r->data.xt = calloc((size_t)total + 1, sizeof(double));
  r->data.x_start = calloc(1, n3);
  r->data.v_dem = calloc(1, n3);
  r->data.f_fem = calloc(1, n3);
  r->data.carry = calloc(1, n3);
  if (!r->data.xi || !r->data.xt || !r->data.x_start || !r->data.v_dem || !r->data.f_fem || !r->data.carry)
    return proto_fail(&r->err, "out of memory (implicit scheme)");
  r->accel = cpl_accel_create(&r->scene->implicit, CPL_N_IF, len, &r->err);
  return r->accel ? 0 : -1;
}

/* Road body at t_k by the trapezoidal rule with the force of t_k
 * (scenario.c): the implicit counterpart of the explicit road action. */
static double road_trapezoid(const cpl_runner *r, double force, double *v, double *a) {
  return cpl_road_trapezoid(&r->data.road, &r->scene->scenario, r->scene->dt, force, v, a);
}

/* Sets the requests' inputs from the iterate xi. */
static void implicit_inputs(cpl_runner *r) {
  const int64_t nx = if_len(r, CPL_IF_X), nf = if_len(r, CPL_IF_F);
  const double *d = r->data.xi, *f = r->data.xi + nx, dt = r->scene->dt;
  for (int64_t j = 0; j < nx; j++) r->data.v_dem[j] = (d[j] - r->data.x_start[j]) / dt;
  for (int64_t j = 0; j < nf; j++) r->data.f_fem[j] = f[j] + r->data.carry[j];
  r->data.in[CPL_F_SURF_X] = r->data.x_start;
  r->data.in[CPL_F_SURF_V] = nx ? r->data.v_dem : r->data.fields[CPL_F_SURF_V].cur;
  r->data.in[CPL_F_SURF_FORCE] = nf ? r->data.f_fem : r->data.fields[CPL_F_SURF_FORCE].cur;
  if (road_coupled(r)) {
    double v, a;
    r->data.road_iter = r->data.xi[nx + nf];
    r->data.fields[CPL_F_ROAD_D].cur[0] = road_trapezoid(r, r->data.road_iter, &v, &a);
  }
}

/* H(xi): what the processes returned, as an interface vector. */
static void implicit_outputs(cpl_runner *r) {
  const int64_t nx = if_len(r, CPL_IF_X), nf = if_len(r, CPL_IF_F);
  memcpy(r->data.xt, r->data.fields[CPL_F_SURF_X].out, sizeof(double) * (size_t)nx);
  memcpy(r->data.xt + nx, r->data.fields[CPL_F_SURF_FORCE].out, sizeof(double) * (size_t)nf);
  if (road_coupled(r)) r->data.xt[nx + nf] = r->data.fields[CPL_F_ROAD_FORCE].out[0];
}

/* After the last iteration: the processes' last outputs become the fields.
 * The tread received f_iter + carry while the grains felt f_out: the
 * difference (at most the tolerance) is carried into the next step's force,
 * so the impulses balance exactly over the run (one defect in flight). */
static void implicit_commit(cpl_runner *r) {
  const int64_t nf = if_len(r, CPL_IF_F);
  const double *f_out = r->data.fields[CPL_F_SURF_FORCE].out;
  /* defect so far = old defect + f_out - f_fem, with f_fem = iterate + old */
  for (int64_t j = 0; j < nf; j++) r->data.carry[j] += f_out[j] - r->data.f_fem[j];
  for (int f = 0; f < r->plan->contract.nfields; f++)
    if (f != CPL_F_ROAD_D && r->data.fields[f].given) cpl_field_commit(r, f);
  if (road_coupled(r)) {
    double v, a;
    r->data.road.d = road_trapezoid(r, r->data.road_iter, &v, &a);
    r->data.road.v = v;
    r->data.road.a = a;
  }
  cpl_inputs_current(r);
}

/* (fields at t_{k-1}) -> (fields at t_k, iterated until the interface settles) */
int cpl_implicit_step(cpl_runner *r, int64_t k, int output) {
  const int64_t nx = if_len(r, CPL_IF_X), nf = if_len(r, CPL_IF_F);
  const cpl_field *X = &r->data.fields[CPL_F_SURF_X], *V = &r->data.fields[CPL_F_SURF_V];
  const double dt = r->scene->dt;
  /* actions once, at the start (with the last step's load) */
  for (int e = 0; e < r->plan->nex; e++)
    if (r->plan->ex[e].peer < 0 && !(road_coupled(r) && r->plan->ex[e].action == CPL_ACT_ROAD) &&
        cpl_do_action(r, r->plan->ex[e].action, k) < 0)
      return -1;
  /* start: x_{k-1}; guess d_k = x_{k-1} + dt v, forces of the last step */
  memcpy(r->data.x_start, X->cur, sizeof(double) * (size_t)nx);
  for (int64_t j = 0; j < nx; j++) r->data.xi[j] = X->cur[j] + dt * V->cur[j];
  memcpy(r->data.xi + nx, r->data.fields[CPL_F_SURF_FORCE].cur, sizeof(double) * (size_t)nf);
  if (road_coupled(r)) r->data.xi[nx + nf] = r->data.road.force_last;
  const double *base[CPL_N_IF] = {r->data.x_start, NULL, NULL};
  cpl_accel_begin(r->accel);
  r->data.converged = 0;
  int it;
  for (it = 0; it < r->scene->implicit.max_iterations; it++) {
    implicit_inputs(r);
    if (cpl_run_stages(r, 0, cpl_last_stage(r), k, it, output, 0, 0) < 0) return -1;
    implicit_outputs(r);
    r->data.converged = cpl_accel_next(r->accel, r->data.xi, r->data.xt, base, r->data.residual);
    if (r->data.converged) break;
  }
  r->data.iterations = it < r->scene->implicit.max_iterations ? it + 1 : it;
  if (!r->data.converged) r->data.steps_unconverged++; /* the last outputs are kept */
  cpl_accel_end(r->accel);
  implicit_commit(r);
  return 0;
}

