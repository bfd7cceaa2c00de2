/* blk_cg.c — the matrix-free per-step solver for large grids.
 *
 * The step is the minimum of the convex dual (contact_block/README.md)
 *   J(F) = ½ FᵀCF − bᵀF + Σ Ψ_e(F_e),  F_e ≥ 0 unless adhesively bonded,
 * Ψ' = the inverse spring law (rigid springs: Ψ = 0, the Signorini problem of
 * Polonsky & Keer, Wear 231 (1999) 206). Newton on J: each step minimises
 * the quadratic model ½ΔᵀHΔ + ∇Jᵀ Δ, H = C + diag(1/k), over F + Δ ≥ 0 by
 * Polonsky–Keer's constrained conjugate gradients (CG on the loaded set,
 * projection of negative forces, re-activation of penetrating elements with
 * a reset of the conjugate direction), here Jacobi-preconditioned (the
 * springs' 1/k varies between elements) and with the bonded elements
 * unconstrained; then Armijo backtracking on J (F + λΔ stays feasible). For
 * rigid springs the model is exact and one Newton step is the whole solve.
 * Products C·x by FFT (blk_fft.c): one per CG iteration, one more when the
 * loaded set changed. Also the tangent stiffness dF/dd_road. */
#include <math.h>
#include <string.h>

#include "contact_block/blk_internal.h"

/* inexact Newton: each quadratic model solved to this fraction of the
 * current violation (but at least to the tolerance) */
#define BLK_CG_FORCING 0.1
/* CG iterations without halving the violation: stagnation, stop */
enum { BLK_CG_STALL = 200 };

static inline int bounded(const blk_model *m, const blk_work *w, int e) {
  return !(m->adhesion && w->held[e]);
}

/* The quadratic model's gradient ρ = g + CΔ + DΔ exactly (one product). */
static void qp_exact(const blk_model *m, blk_work *w, int *products) {
  blk_fft_apply(&w->fft, &w->C_hat, w->dF, w->wC);
  (*products)++;
  for (int e = 0; e < m->M; e++) w->rho[e] = w->g[e] + w->wC[e] + w->Dk[e] * w->dF[e];
}

/* min ½ΔᵀHΔ + gᵀΔ over F + Δ ≥ 0 (bounded elements) by Polonsky–Keer CG.
 * Leaves Δ in w->dF and CΔ in w->wC. Returns the violation reached. */
static double qp_solve(const blk_model *m, blk_work *w, const double *F, double tol_in,
                       int *products) {
  const int M = m->M;
  double *dF = w->dF, *rho = w->rho, *z = w->z, *t = w->t;
  for (int e = 0; e < M; e++) {
    dF[e] = w->wC[e] = 0;
    rho[e] = w->g[e];
    w->prec[e] = 1.0 / (w->c_self + w->Dk[e]);
    t[e] = 0;
  }
  int exact = 1, conj = 0, it = 0, since_best = 0;
  double G_old = 1, tau = 0, viol = 0, best = INFINITY;
  for (;;) {
    /* loaded (free) set: bonded, or F + Δ > 0 */
    double G = 0;
    int nfree = 0;
    viol = 0;
    for (int e = 0; e < M; e++) {
      const int fr = !bounded(m, w, e) || F[e] + dF[e] > 0;
      const double v = fr ? fabs(rho[e]) : fmax(-rho[e], 0.0);
      if (v > viol) viol = v;
      z[e] = fr ? rho[e] * w->prec[e] : 0.0;
      G += rho[e] * z[e];
      nfree += fr;
    }
    if (viol <= tol_in) {
      if (exact) break;
      qp_exact(m, w, products); /* confirm on the exact gradient */
      exact = 1;
      continue;
    }
    if (it == m->solver.cg_max_iter) break;
    /* stagnation (the tolerance below the round-off of the products) */
    if (viol < 0.5 * best) {
      best = viol;
      since_best = 0;
    } else if (++since_best > BLK_CG_STALL) {
      break;
    }
    it++;
    if (!nfree) { /* nothing loaded (cold start): a Jacobi step on the penetrating */
      for (int e = 0; e < M; e++)
        if (rho[e] < 0) dF[e] = -F[e] - rho[e] * w->prec[e];
      qp_exact(m, w, products);
      exact = 1;
      conj = 0;
      continue;
    }
    const double beta = conj ? G / G_old : 0.0;
    double num = 0;
    for (int e = 0; e < M; e++) { /* t vanishes off the free set */
      const int fr = !bounded(m, w, e) || F[e] + dF[e] > 0;
      t[e] = fr ? z[e] + beta * t[e] : 0.0;
      num += rho[e] * t[e];
    }
    if (!(num > 0)) { /* not a descent direction (after a projection): restart */
      num = G;
      for (int e = 0; e < M; e++) t[e] = z[e];
    }
    blk_fft_apply(&w->fft, &w->C_hat, t, w->qc);
    (*products)++;
    double den = 0;
    for (int e = 0; e < M; e++) {
      w->q[e] = w->qc[e] + w->Dk[e] * t[e];
      den += t[e] * w->q[e];
    }
    if (!(den > 0)) break; /* H not positive definite on this direction */
    tau = num / den;
    for (int e = 0; e < M; e++) {
      dF[e] -= tau * t[e];
      rho[e] -= tau * w->q[e];
      w->wC[e] -= tau * w->qc[e];
    }
    exact = 0;
    /* projection of negative forces, re-activation of penetrating elements */
    int changed = 0, react = 0;
    for (int e = 0; e < M; e++) {
      if (!bounded(m, w, e)) continue;
      if (F[e] + dF[e] < 0) {
        dF[e] = -F[e];
        changed = 1;
      }
      if (!(F[e] + dF[e] > 0) && rho[e] < 0) {
        dF[e] = -F[e] - tau * rho[e] * w->prec[e];
        react = 1;
      }
    }
    if (changed || react) {
      qp_exact(m, w, products);
      exact = 1;
    }
    conj = !react;
    G_old = G;
  }
  if (!exact) qp_exact(m, w, products);
  return viol;
}

/* J at F with d(F) warm-started from d_io (updated), Dk = 1/k, Ψ per
 * element into psi, u = C F given; g = u − b + d(F) into g (may be NULL). */
static double dual_value(const blk_model *m, blk_work *w, const double *F, const double *u,
                         double *d_io, double *Dk, double *psi, double *g) {
  double J = 0;
  for (int e = 0; e < m->M; e++) {
    double de;
    psi[e] = blk_dual_element(m, w, e, F[e], d_io[e], &de, &Dk[e]);
    d_io[e] = de;
    if (g) g[e] = u[e] - w->b[e] + de;
    J += F[e] * (0.5 * u[e] - w->b[e]) + psi[e];
  }
  return J;
}

/* J and g at the F just accepted by the line search, with the exact u = C F:
 * d(F), 1/k and Ψ are the trial's (they depend on F alone), so the spring
 * inverses are not solved again. */
static double dual_value_at_trial(const blk_model *m, blk_work *w, const double *F,
                                  const double *u, const double *d, const double *psi,
                                  double *g) {
  double J = 0;
  for (int e = 0; e < m->M; e++) {
    g[e] = u[e] - w->b[e] + d[e];
    J += F[e] * (0.5 * u[e] - w->b[e]) + psi[e];
  }
  return J;
}

/* KKT violation in m: |g| where loaded or bonded, penetration where F = 0. */
static double kkt(const blk_model *m, const blk_work *w, const double *F) {
  double viol = 0;
  for (int e = 0; e < m->M; e++) {
    const double v = bounded(m, w, e) && !(F[e] > 0) ? fmax(-w->g[e], 0.0) : fabs(w->g[e]);
    if (v > viol) viol = v;
  }
  return viol;
}

int blk_cg_solve(const blk_model *m, blk_state *s, int *conv, double *rmax, int *products) {
  blk_work *w = s->work;
  const int M = m->M;
  double *F = s->force, *d = s->d_rs, *u = w->CF;
  w->fact_valid = 0; /* a dense factor (auto) is stale from here */
  for (int e = 0; e < M; e++)
    if (bounded(m, w, e) && F[e] < 0) F[e] = 0;
  blk_fft_apply(&w->fft, &w->C_hat, F, u);
  (*products)++;
  double J = dual_value(m, w, F, u, d, w->Dk, w->psi, w->g);
  const int quadratic = m->rigid; /* Ψ = 0: the model is exact */
  int it = 0;
  double eta = BLK_CG_FORCING, viol_prev = 0;
  *conv = 0;
  for (;;) {
    const double viol = kkt(m, w, F);
    *rmax = viol;
    if (viol < m->solver.tol) {
      *conv = 1;
      break;
    }
    if (it == m->solver.max_iter || !isfinite(J)) break;
    it++;
    /* forcing term shrinking with the observed convergence: superlinear */
    if (viol_prev > 0) eta = fmin(BLK_CG_FORCING, viol / viol_prev);
    viol_prev = viol;
    const double tol_in = quadratic ? 0.5 * m->solver.tol : fmax(0.5 * m->solver.tol, eta * viol);
    qp_solve(m, w, F, tol_in, products);
    double slope = 0;
    for (int e = 0; e < M; e++) slope += w->g[e] * w->dF[e];
    double lambda = 1.0, Jn = J;
    for (int cut = 0; cut < BLK_MAX_CUTS; cut++) {
      for (int e = 0; e < M; e++) {
        double v = F[e] + lambda * w->dF[e];
        if (bounded(m, w, e) && v < 0) v = 0; /* round-off of a convex combination */
        w->Fn[e] = v;
        w->dn[e] = d[e];
        w->un[e] = u[e] + lambda * w->wC[e];
      }
      Jn = dual_value(m, w, w->Fn, w->un, w->dn, w->Dk, w->psi, NULL);
      /* near the solution the decrease of J drops below its round-off */
      if (Jn <= J + BLK_ARMIJO * lambda * slope || !(slope < 0) ||
          -lambda * slope < BLK_DECREASE_ROUNDOFF * fabs(J))
        break;
      lambda *= 0.5;
    }
    memcpy(F, w->Fn, (size_t)M * sizeof(double));
    memcpy(d, w->dn, (size_t)M * sizeof(double));
    blk_fft_apply(&w->fft, &w->C_hat, F, u); /* exact C F: no drift */
    (*products)++;
    J = dual_value_at_trial(m, w, F, u, d, w->psi, w->g);
  }
  /* the thesis' variables: compression where loaded, else the geometric
   * overlap b − C F (≤ 0: a gap); w->CF = C F */
  for (int e = 0; e < M; e++)
    if (F[e] == 0.0) d[e] = w->b[e] - u[e];
  return it;
}

/* dF_total/dd_road = 1ᵀ x, (C_AA + diag(1/k_A)) x = 1_A over the loaded and
 * bonded elements A (seed 002 eq. 8 with the past fixed): preconditioned CG.
 * Uses the matrix-free vectors; after the step's solve. */
double blk_cg_tangent(const blk_model *m, blk_state *s, int *products) {
  blk_work *w = s->work;
  double Kd;
  if (w->A && blk_dense_tangent(m, s, BLK_TANGENT_TOL, &Kd, products) == 0)
    return Kd;
  const int M = m->M;
  double *x = w->dF, *r = w->rho, *z = w->z, *p = w->t, *q = w->q, *D = w->Dk;
  int nA = 0;
  double rz = 0;
  for (int e = 0; e < M; e++) {
    const int in = s->force[e] > 0 || (m->adhesion && w->held[e] && s->force[e] != 0);
    double Fe = 0, ke = 0;
    if (in && !m->rigid) blk_spring_eval(m, e, fabs(s->d_rs[e]), &Fe, &ke);
    D[e] = !in ? -1.0 : m->rigid ? 0.0 : blk_inverse_stiffness(w, ke);
    x[e] = 0;
    r[e] = in ? 1.0 : 0.0;
    w->prec[e] = in ? 1.0 / (w->c_self + D[e]) : 0.0;
    z[e] = r[e] * w->prec[e];
    p[e] = z[e];
    rz += r[e] * z[e];
    nA += in;
  }
  if (!nA) return 0.0;
  for (int it = 0; it < m->solver.cg_max_iter; it++) {
    blk_fft_apply(&w->fft, &w->C_hat, p, q);
    (*products)++;
    double pq = 0;
    for (int e = 0; e < M; e++) {
      q[e] = D[e] < 0 ? 0.0 : q[e] + D[e] * p[e];
      pq += p[e] * q[e];
    }
    if (!(pq > 0)) break;
    const double alpha = rz / pq;
    double rmax = 0, rz_new = 0;
    for (int e = 0; e < M; e++) {
      x[e] += alpha * p[e];
      r[e] -= alpha * q[e];
      rmax = fmax(rmax, fabs(r[e]));
      z[e] = r[e] * w->prec[e];
      rz_new += r[e] * z[e];
    }
    if (rmax <= BLK_TANGENT_TOL) break;
    const double beta = rz_new / rz;
    rz = rz_new;
    for (int e = 0; e < M; e++) p[e] = z[e] + beta * p[e];
  }
  double K = 0;
  for (int e = 0; e < M; e++) K += x[e];
  return K;
}
