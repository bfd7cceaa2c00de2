/* fem_explicit.c — central differences (seed 000 eq. 30, 32) in leapfrog
 * form with lumped mass and optional mass-proportional damping C = alpha M:
 *
 *   v_{n+1/2} = [(1 - alpha dt/2) v_{n-1/2} + dt M^-1 (b - K u_n)] / (1 + alpha dt/2)
 *   u_{n+1}   = u_n + dt v_{n+1/2}
 *
 * which for alpha = 0 is exactly eq. 32. The discrete energy
 *   E_n = 1/2 v_{n+1/2}.M v_{n+1/2} + 1/2 u_{n+1}.K u_n
 * changes only by the work 1/2 dt b.(v_{n+1/2} + v_{n-1/2}) (and damping),
 * to round-off: an exact invariant of eq. 32, used to detect instability.
 *
 * In a moving frame (st->frame, fem_frame.c) each node a also feels
 *   f_a = -m_a [acc + alpha x r_a + Omega x (Omega x r_a)] - 2 m_a Omega x w_a.
 * The position-dependent part is evaluated at u_n, like K u_n, and counted as
 * external work: the identity above holds for any force evaluated at u_n, so
 * the energy check stays exact. The road's penalty (fem_road.c), when there is
 * one, is such a force too: evaluated at u_n after K u_n, added to b. The
 * frame's u-dependent piece m Omega x (Omega x u)
 * is a negative stiffness of size m Omega^2: it lowers omega_max^2 by at most
 * Omega^2 (rim ~2 rad/s against omega_max ~1e5 rad/s), so dt_crit stands.
 * The Coriolis term depends on the velocity; it is taken at the midpoint
 * w = (v_{n+1/2} + v_{n-1/2})/2, like the damping, which gives per node
 *   (c+ I + dt [Omega]x) v_{n+1/2} = (c- I - dt [Omega]x) v_{n-1/2} + dt F/m,
 *   c+- = 1 +- alpha dt/2,
 * solved in closed form (3x3). For alpha = 0 this maps v_{n-1/2} by the
 * Cayley transform of a skew matrix, an orthogonal matrix: the Coriolis force
 * rotates the relative velocity and does exactly no work, as in the continuum
 * (w . Omega x w = 0), so it neither enters the energy balance nor changes
 * the stability limit (a skew term under the midpoint rule is neutral for any
 * dt). Taken explicitly at v_{n-1/2} it would scale |v| by sqrt(1 + 4 Omega^2
 * dt^2) per step: a slow spurious energy gain. */
#include "fem_server/fem.h"
#include "fem_server/fem_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

int fem_state_init(const fem_model *md, fem_state *st, proto_err *err) {
  memset(st, 0, sizeof *st);
  size_t n = (size_t)md->n_dof;
  st->u = calloc(n, sizeof *st->u);
  st->v = calloc(n, sizeof *st->v);
  st->v_half = calloc(n, sizeof *st->v_half);
  st->fint = calloc(n, sizeof *st->fint);
  st->b = calloc(n, sizeof *st->b);
  if (!st->u || !st->v || !st->v_half || !st->fint || !st->b)
    return proto_fail(err, "out of memory (state with %zu DOFs)", n);
  return fem_work_init(md, &st->work, err);
}

void fem_state_free(fem_state *st) {
  if (!st) return;
  free(st->u);
  free(st->v);
  free(st->v_half);
  free(st->fint);
  free(st->b);
  fem_work_free(&st->work);
  fem_road_free(&st->road);
  memset(st, 0, sizeof *st);
}

void fem_state_reset(const fem_model *md, fem_state *st, const double *u) {
  size_t n = (size_t)md->n_dof;
  for (size_t i = 0; i < n; i++) st->u[i] = md->fixed[i] ? md->u_fixed[i] : (u ? u[i] : 0);
  memset(st->v, 0, sizeof *st->v * n);
  memset(st->v_half, 0, sizeof *st->v_half * n);
  fem_internal_force(md, &st->work, st->u, st->fint);
  double se = 0;
  for (size_t i = 0; i < n; i++) se += 0.5 * st->u[i] * st->fint[i];
  st->strain = se;
  st->kinetic = 0;
  st->energy0 = st->energy = se; /* u_{-1} = u_0 when v = 0 */
  st->work_ext = st->work_abs = 0;
  st->t = 0;
  st->n_sub = 0;
}

int fem_stable_dt(const fem_model *md, fem_state *st, int max_iter, proto_err *err) {
  if (!st->work.elem_force) return proto_fail(err, "stable time step: fem_state_init first");
  size_t n = (size_t)md->n_dof;
  double *x = malloc(sizeof *x * n), *y = malloc(sizeof *y * n);
  if (!x || !y) {
    free(x);
    free(y);
    return proto_fail(err, "out of memory (power iteration)");
  }
  uint64_t s = 0x9e3779b97f4a7c15ULL; /* deterministic start vector */
  for (size_t i = 0; i < n; i++) {
    s = s * 6364136223846793005ULL + 1442695040888963407ULL;
    x[i] = md->fixed[i] ? 0 : (double)(s >> 11) / 9007199254740992.0 - 0.5;
  }
  double lam = 0, lam_old = 0;
  int it;
  for (it = 1; it <= max_iter; it++) {
    fem_internal_force(md, &st->work, x, y); /* the state's scratch: u, fint untouched */
    double xKx = 0, xMx = 0, nrm = 0;
    for (size_t i = 0; i < n; i++) {
      if (md->fixed[i]) continue;
      double m = md->mass[i / 3];
      xKx += x[i] * y[i];
      xMx += m * x[i] * x[i];
    }
    lam = xKx / xMx; /* Rayleigh quotient of M^-1 K */
    for (size_t i = 0; i < n; i++) {
      x[i] = md->fixed[i] ? 0 : y[i] / md->mass[i / 3];
      nrm += x[i] * x[i];
    }
    nrm = sqrt(nrm);
    if (!(nrm > 0) || !isfinite(nrm)) break;
    for (size_t i = 0; i < n; i++) x[i] /= nrm;
    if (it > 30 && fabs(lam - lam_old) < 1e-7 * lam) break;
    lam_old = lam;
  }
  free(x);
  free(y);
  if (!(lam > 0) || !isfinite(lam))
    return proto_fail(err, "stable time step: power iteration gave lambda_max = %g", lam);
  st->omega_max = sqrt(lam);
  st->dt_crit = 2.0 / st->omega_max;
  return 0;
}

static int unstable(const fem_model *md, const fem_state *st, double dt, int64_t k,
                    int64_t n, proto_err *err) {
  for (int32_t i = 0; i < md->n_dof; i++)
    if (!isfinite(st->u[i]))
      return proto_fail(err, "explicit run diverged at t = %.6g s (sub-step %lld of %lld): "
                        "non-finite displacement at node %d; dt_sub = %.4g s, stable limit "
                        "dt_crit = 2/omega_max = %.4g s", st->t, (long long)k, (long long)n,
                        i / 3, dt, st->dt_crit);
  return proto_fail(err, "explicit run unstable at t = %.6g s (sub-step %lld of %lld): discrete "
                    "energy %.4g J exceeds 10x (initial %.4g J + work %.4g J); dt_sub = %.4g s "
                    "vs stable limit dt_crit = 2/omega_max = %.4g s", st->t, (long long)k,
                    (long long)n, st->energy, st->energy0, st->work_abs, dt, st->dt_crit);
}

/* Solves A v = r for a node whose fixed components have v = 0: their rows
 * of A are replaced by identity rows (the free block of c I + [k]x is
 * positive definite, so the system is regular). Cramer's rule. */
static void solve_node(double A[3][3], double r[3], const uint8_t *fixed, double v[3]) {
  for (int d = 0; d < 3; d++)
    if (fixed[d]) {
      for (int e = 0; e < 3; e++) A[d][e] = d == e;
      r[d] = 0;
    }
  double det = A[0][0] * (A[1][1] * A[2][2] - A[1][2] * A[2][1]) -
               A[0][1] * (A[1][0] * A[2][2] - A[1][2] * A[2][0]) +
               A[0][2] * (A[1][0] * A[2][1] - A[1][1] * A[2][0]);
  for (int c = 0; c < 3; c++) {
    double M[3][3];
    memcpy(M, A, sizeof M);
    for (int d = 0; d < 3; d++) M[d][c] = r[d];
    v[c] = (M[0][0] * (M[1][1] * M[2][2] - M[1][2] * M[2][1]) -
            M[0][1] * (M[1][0] * M[2][2] - M[1][2] * M[2][0]) +
            M[0][2] * (M[1][0] * M[2][1] - M[1][1] * M[2][0])) / det;
  }
}

/* One leapfrog step of node a in a rotating frame (see the file comment).
 * Returns the kinetic energy of the new half-step velocity; adds u_{n+1}.K u_n
 * and the work to *uKu and *dw. */
static double node_step_rotating(const fem_model *md, fem_state *st, int32_t a, double dt,
                                 double alpha, double *uKu, double *dw) {
  const size_t i0 = 3 * (size_t)a;
  const double m = md->mass[a];
  const fem_frame *fr = &st->frame;
  double r[3], acc[3], F[3], rhs[3], k[3], kxw[3], w_new[3];
  for (int d = 0; d < 3; d++) r[d] = md->mesh.x[i0 + d] + st->u[i0 + d];
  fem_frame_point_acc(fr, r, acc);
  for (int d = 0; d < 3; d++) {
    F[d] = st->b[i0 + d] - m * acc[d]; /* external + frame, at u_n */
    if (st->road.n) F[d] += st->road.force[i0 + d];
    k[d] = dt * fr->omega[d];
  }
  const double *w_old = st->v_half + i0;
  fem_cross(k, w_old, kxw);
  const double cp = 1 + 0.5 * alpha * dt, cm = 1 - 0.5 * alpha * dt;
  for (int d = 0; d < 3; d++) rhs[d] = cm * w_old[d] - kxw[d] + dt * (F[d] - st->fint[i0 + d]) / m;
  double A[3][3] = {{cp, -k[2], k[1]}, {k[2], cp, -k[0]}, {-k[1], k[0], cp}}; /* cp I + [k]x */
  solve_node(A, rhs, md->fixed + i0, w_new);
  double kin = 0;
  for (int d = 0; d < 3; d++) {
    const size_t i = i0 + d;
    if (md->fixed[i]) {
      *uKu += md->u_fixed[i] * st->fint[i];
      continue;
    }
    *dw += 0.5 * dt * F[d] * (w_new[d] + w_old[d]);
    st->v_half[i] = w_new[d];
    st->u[i] += dt * w_new[d];
    kin += 0.5 * m * w_new[d] * w_new[d];
    *uKu += st->u[i] * st->fint[i]; /* u_{n+1} . K u_n */
  }
  return kin;
}

/* One leapfrog step of the nodes of chunk c (FEM_SUM_CHUNK nodes), their
 * kinetic energy, u_{n+1}.K u_n and work into sums[0..2]. */
static void chunk_step(const fem_model *md, fem_state *st, int32_t c, double dt, double c1,
                       double c2, const fem_road *road, double sums[3]) {
  const int32_t a1 = fem_chunk_end(c, md->mesh.n_nodes);
  const double *acc = st->frame.acc; /* a translating frame: uniform -m acc */
  double kin = 0, uKu = 0, dw = 0;
  if (fem_frame_rotating(&st->frame))
    for (int32_t a = c * FEM_SUM_CHUNK; a < a1; a++) kin += node_step_rotating(md, st, a, dt, md->mat.damping, &uKu, &dw);
  else
    for (int32_t i = 3 * c * FEM_SUM_CHUNK; i < 3 * a1; i++) {
      if (md->fixed[i]) {
        uKu += md->u_fixed[i] * st->fint[i];
        continue;
      }
      double m = md->mass[i / 3];
      double f = st->b[i] - m * acc[i % 3];
      if (road) f += road->force[i];
      double w_old = st->v_half[i];
      double w = c1 * w_old + c2 * (f - st->fint[i]) / m;
      st->v_half[i] = w;
      st->u[i] += dt * w;
      kin += 0.5 * m * w * w;
      uKu += st->u[i] * st->fint[i]; /* u_{n+1} . K u_n */
      dw += 0.5 * dt * f * (w + w_old);
    }
  sums[0] = kin;
  sums[1] = uKu;
  sums[2] = dw;
}

/* The span's end for the nodes of chunk c: v_n = v_{n-1/2} + dt/2 a_n, their
 * kinetic and strain energy into sums[0..1] (sums[2] = 0). */
static void chunk_close(const fem_model *md, fem_state *st, int32_t c, double dt, const fem_road *road,
                        double sums[3]) {
  const int32_t a1 = fem_chunk_end(c, md->mesh.n_nodes);
  const double alpha = md->mat.damping;
  double kin = 0, se = 0;
  for (int32_t a = c * FEM_SUM_CHUNK; a < a1; a++) {
    const size_t i0 = 3 * (size_t)a;
    const double m = md->mass[a];
    double r[3], fa[3], cor[3];
    for (int d = 0; d < 3; d++) r[d] = md->mesh.x[i0 + d] + st->u[i0 + d];
    fem_frame_point_acc(&st->frame, r, fa);
    fem_cross(st->frame.omega, st->v_half + i0, cor);
    for (int d = 0; d < 3; d++) {
      const size_t i = i0 + d;
      se += 0.5 * st->u[i] * st->fint[i];
      if (md->fixed[i]) {
        st->v[i] = 0;
        continue;
      }
      const double f_ext = road ? st->b[i] + road->force[i] : st->b[i];
      double acc_i = (f_ext - st->fint[i]) / m - fa[d] - 2 * cor[d] - alpha * st->v_half[i];
      st->v[i] = st->v_half[i] + 0.5 * dt * acc_i;
      kin += 0.5 * m * st->v[i] * st->v[i];
    }
  }
  sums[0] = kin;
  sums[1] = se;
  sums[2] = 0;
}

/* The chunks' partial sums (three per chunk) added in chunk order. */
static void chunk_sums(const double *cs, int32_t nchunk, double sum[3]) {
  sum[0] = sum[1] = sum[2] = 0;
  for (int32_t c = 0; c < nchunk; c++)
    for (int k = 0; k < 3; k++) sum[k] += cs[3 * c + k];
}

int fem_explicit_advance(const fem_model *md, fem_state *st, double span, double safety,
                         double dt_sub, proto_err *err) {
  if (!(span > 0)) return proto_fail(err, "explicit advance: span %g must be > 0", span);
  if (!(st->dt_crit > 0) && !(dt_sub > 0))
    return proto_fail(err, "explicit advance: stable step not computed (fem_stable_dt)");
  double target = dt_sub > 0 ? dt_sub : safety * st->dt_crit;
  int64_t n = (int64_t)ceil(span / target - 1e-9);
  if (n < 1) n = 1;
  const double dt = span / n, alpha = md->mat.damping;
  const double c1 = (1 - 0.5 * alpha * dt) / (1 + 0.5 * alpha * dt), c2 = dt / (1 + 0.5 * alpha * dt);
  const int32_t nn = md->mesh.n_nodes;
  const double t0 = st->t;
  fem_road *road = st->road.n ? &st->road : NULL; /* its force at u_n, like K u_n */
  if (road) fem_road_force(md, road, st->u);
  st->dt_sub = dt;
  /* one team per sub-step for the node update and K u_{n+1} (the element
   * kernel's threshold: the node update alone is too short to pay a fork);
   * the energies are summed per chunk of nodes, then over the chunks in
   * order: the same sums for any number of threads */
  const int team = md->mesh.n_elems > FEM_OMP_MIN_ELEMS;
  const int32_t nchunk = fem_sum_chunks(nn);
  double *cs = st->work.chunk_sum;
  for (int64_t k = 1; k <= n; k++) {
#pragma omp parallel if (team)
    {
#pragma omp for schedule(static)
      for (int32_t c = 0; c < nchunk; c++) chunk_step(md, st, c, dt, c1, c2, road, cs + 3 * c);
      fem_internal_force_team(md, &st->work, st->u, st->fint); /* after the loop's barrier: u_{n+1} whole */
    }
    double sum[3];
    chunk_sums(cs, nchunk, sum);
    const double kin = sum[0], uKu = sum[1], dw = sum[2];
    st->energy = kin + 0.5 * uKu;
    st->work_ext += dw;
    st->work_abs += fabs(dw);
    st->t = t0 + span * (double)k / (double)n;
    st->n_sub++;
    if (road) fem_road_force(md, road, st->u);
    if (!isfinite(st->energy) || fabs(st->energy) > 10 * (fabs(st->energy0) + st->work_abs))
      return unstable(md, st, dt, k, n, err);
  }
  /* velocity and energies at the end of the span: v_n = v_{n-1/2} + dt/2 a_n */
#pragma omp parallel for schedule(static) if (team)
  for (int32_t c = 0; c < nchunk; c++) chunk_close(md, st, c, dt, road, cs + 3 * c);
  double sum[3];
  chunk_sums(cs, nchunk, sum);
  const double kin = sum[0], se = sum[1];
  st->kinetic = kin;
  st->strain = se;
  return 0;
}
