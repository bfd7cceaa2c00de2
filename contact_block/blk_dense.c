/* blk_dense.c — the dense per-step solvers for small grids: the thesis'
 * Newton–Raphson over the elements in contact (seed 002 eq. 6–8, the active
 * set changing during the iteration; optional line search and chord steps)
 * and the projected Newton on the convex dual (README "Solvers"). The
 * matrices are built from the offset kernel (C[i][p] = kern[i − p]); no
 * allocation here after blk_state_create. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "contact_block/blk_internal.h"
#include "contact_block/blk_internal.h"

/* ------------------------------------------------------ dense algebra */

/* Dot product with four partial sums (the compiler may not reassociate a
 * single floating-point sum; this gives it independent chains). */
static inline double dot(const double *a, const double *b, int n) {
  double s0 = 0, s1 = 0, s2 = 0, s3 = 0;
  int k = 0;
  for (; k + 4 <= n; k += 4) {
    s0 += a[k] * b[k];
    s1 += a[k + 1] * b[k + 1];
    s2 += a[k + 2] * b[k + 2];
    s3 += a[k + 3] * b[k + 3];
  }
  for (; k < n; k++) s0 += a[k] * b[k];
  return (s0 + s1) + (s2 + s3);
}

/* In-place Cholesky of the leading n×n of A (row stride ld, lower triangle
 * used), row-oriented: row i needs only rows < i. 0 or -1 (not SPD). */
BLK_HOT static int cholesky(double *A, int n, int ld) {
  for (int i = 0; i < n; i++) {
    double *Ai = A + (size_t)i * ld;
    for (int j = 0; j < i; j++) {
      const double *Aj = A + (size_t)j * ld;
      Ai[j] = (Ai[j] - dot(Ai, Aj, j)) / Aj[j];
    }
    const double s = Ai[i] - dot(Ai, Ai, i);
    if (!(s > 0)) return -1;
    Ai[i] = sqrt(s);
  }
  return 0;
}

BLK_HOT static void cholesky_solve(const double *L, int n, int ld, double *x) {
  for (int i = 0; i < n; i++) {
    const double *Li = L + (size_t)i * ld;
    x[i] = (x[i] - dot(Li, x, i)) / Li[i];
  }
  for (int i = n - 1; i >= 0; i--) {
    x[i] /= L[(size_t)i * ld + i];
    const double xi = x[i];
    const double *Li = L + (size_t)i * ld;
    for (int k = 0; k < i; k++) x[k] -= Li[k] * xi; /* column i of Lᵀ = row i of L */
  }
}

/* LU with partial pivoting and solve (fallback for a non-symmetric or
 * indefinite g(0)); -1 if singular. */
BLK_HOT static int lu_solve(double *A, int n, int ld, int *piv, double *x) {
  for (int j = 0; j < n; j++) {
    int p = j;
    for (int i = j + 1; i < n; i++)
      if (fabs(A[(size_t)i * ld + j]) > fabs(A[(size_t)p * ld + j])) p = i;
    if (A[(size_t)p * ld + j] == 0.0) return -1;
    piv[j] = p;
    if (p != j)
      for (int k = 0; k < n; k++) {
        double t = A[(size_t)j * ld + k];
        A[(size_t)j * ld + k] = A[(size_t)p * ld + k];
        A[(size_t)p * ld + k] = t;
      }
    for (int i = j + 1; i < n; i++) {
      double f = A[(size_t)i * ld + j] / A[(size_t)j * ld + j];
      A[(size_t)i * ld + j] = f;
      for (int k = j + 1; k < n; k++) A[(size_t)i * ld + k] -= f * A[(size_t)j * ld + k];
    }
  }
  for (int j = 0; j < n; j++) {
    double t = x[j];
    x[j] = x[piv[j]];
    x[piv[j]] = t;
    for (int i = j + 1; i < n; i++) x[i] -= A[(size_t)i * ld + j] * x[j];
  }
  for (int i = n - 1; i >= 0; i--) {
    double s = x[i];
    for (int k = i + 1; k < n; k++) s -= A[(size_t)i * ld + k] * x[k];
    x[i] = s / A[(size_t)i * ld + i];
  }
  return 0;
}

/* y −= Σ_a f[a] · (column idx[a] of C), a ascending, columns read from the
 * offset kernel: row j of column p is a contiguous run of nx kernel values
 * (fits L1, unlike C). Same products in the same order as the dense columns
 * (C[i][p] = kern[…] exactly). */
static inline void columns_sub_nx(const double *kern, int nx, int ny, int nox, int n,
                                  const int *idx, const double *f, double *restrict y) {
  for (int a = 0; a < n; a++) {
    const int p = idx[a], pi = p % nx, pj = p / nx;
    const double fa = f[a];
    for (int j = 0; j < ny; j++) {
      const double *restrict kr = kern + (size_t)(j - pj + ny - 1) * nox + (nx - 1 - pi);
      double *restrict yj = y + (size_t)j * nx;
      for (int i = 0; i < nx; i++) yj[i] -= kr[i] * fa;
    }
  }
}

/* The short rows vectorise far better with nx known at compile time:
 * specialised for common block widths (the thesis' 20), generic otherwise. */
BLK_HOT static void columns_sub(const blk_model *m, const double *kern, int n, const int *idx,
                                const double *f, double *y) {
  switch (m->nx) {
  case 10: columns_sub_nx(kern, 10, m->ny, m->nox, n, idx, f, y); break;
  case 16: columns_sub_nx(kern, 16, m->ny, m->nox, n, idx, f, y); break;
  case 20: columns_sub_nx(kern, 20, m->ny, m->nox, n, idx, f, y); break;
  case 32: columns_sub_nx(kern, 32, m->ny, m->nox, n, idx, f, y); break;
  case 40: columns_sub_nx(kern, 40, m->ny, m->nox, n, idx, f, y); break;
  default: columns_sub_nx(kern, m->nx, m->ny, m->nox, n, idx, f, y);
  }
}

/* --------------------------------------------------------------- state */

/* C[i][p] from the offset kernel (translation invariance). */
static inline double c_entry(const blk_model *m, const double *kern, int i, int p) {
  return kern[(size_t)(i / m->nx - p / m->nx + m->ny - 1) * m->nox +
              (i % m->nx - p % m->nx + m->nx - 1)];
}

/* --------------------------------------------------------------- solve */

/* r = b − C F − d (eq. 6 with eq. 4); returns ½|r|², max|r| in *rmax. */
static double residual(const blk_model *m, blk_work *w, const double *d, const double *F,
                       double *r, double *rmax) {
  const int M = m->M;
  memcpy(w->CF, w->b, (size_t)M * sizeof(double));
  int n = 0; /* the loaded elements */
  for (int p = 0; p < M; p++)
    if (F[p] != 0.0) {
      w->col_idx[n] = p;
      w->col_f[n++] = F[p];
    }
  columns_sub(m, w->kern, n, w->col_idx, w->col_f, w->CF);
  double phi = 0, mx = 0;
  for (int i = 0; i < M; i++) {
    r[i] = w->CF[i] - d[i];
    phi += r[i] * r[i];
    if (fabs(r[i]) > mx) mx = fabs(r[i]);
  }
  *rmax = mx;
  return 0.5 * phi;
}

/* Newton direction: (I + C K) Δ = r, K = diag(k) (eq. 8). Only elements with
 * k > 0 couple; the others get Δ_i = r_i − (C K Δ)_i. Symmetric C: the SPD
 * form (I + K½ C K½) y = K½ r, y = K½ Δ, by Cholesky. */
static int newton_direction(const blk_model *m, blk_work *w, const double *k,
                            int may_reuse, int *factored) {
  const int M = m->M;
  int P = 0;
  for (int e = 0; e < M; e++)
    if (k[e] > 0) w->act[P++] = e;
  /* chord step: the stored factor of (I + K½ C K½) with the old K, if the
   * contact set is the same */
  const int reuse = may_reuse && w->fact_valid == BLK_FACT_PRIMAL && P == w->fact_P &&
                    memcmp(w->act, w->fact_act, (size_t)P * sizeof(int)) == 0;
  const double *keff = k; /* stiffness the direction is built with */
  int ok = -1;
  if (reuse) {
    for (int a = 0; a < P; a++) w->y[a] = w->fact_sk[a] * w->r[w->act[a]];
    cholesky_solve(w->A, P, P, w->y);
    for (int a = 0; a < P; a++) {
      w->y[a] /= w->fact_sk[a];
      w->sk[w->act[a]] = w->fact_sk[a] * w->fact_sk[a];
    }
    keff = w->sk; /* indexed by element here */
    ok = 0;
  } else if (w->symmetric) {
    for (int a = 0; a < P; a++) w->fact_sk[a] = sqrt(k[w->act[a]]);
    for (int a = 0; a < P; a++) {
      const int i = w->act[a];
      double *Aa = w->A + (size_t)a * P;
      for (int c = 0; c <= a; c++)
        Aa[c] = w->fact_sk[a] * c_entry(m, w->kern, i, w->act[c]) * w->fact_sk[c];
      Aa[a] += 1.0;
      w->y[a] = w->fact_sk[a] * w->r[i];
    }
    ok = cholesky(w->A, P, P);
    (*factored)++;
    w->fact_valid = ok == 0 ? BLK_FACT_PRIMAL : 0;
    if (ok == 0) {
      w->fact_P = P;
      memcpy(w->fact_act, w->act, (size_t)P * sizeof(int));
      cholesky_solve(w->A, P, P, w->y);
      for (int a = 0; a < P; a++) w->y[a] /= w->fact_sk[a];
    }
  }
  if (ok != 0) {
    w->fact_valid = 0;
    for (int a = 0; a < P; a++) {
      const int i = w->act[a];
      double *Aa = w->A + (size_t)a * P;
      for (int c = 0; c < P; c++) Aa[c] = c_entry(m, w->kern, i, w->act[c]) * k[w->act[c]];
      Aa[a] += 1.0;
      w->y[a] = w->r[i];
    }
    if (lu_solve(w->A, P, P, w->piv, w->y)) return -1;
  }
  /* Δ = r − C K Δ_A for every element (the active ones reproduce y) */
  for (int i = 0; i < M; i++) w->delta[i] = w->r[i];
  for (int a = 0; a < P; a++) w->col_f[a] = keff[w->act[a]] * w->y[a];
  columns_sub(m, w->kern, P, w->act, w->col_f, w->delta);
  for (int a = 0; a < P; a++) w->delta[w->act[a]] = w->y[a];
  return 0;
}

/* Newton iteration from s->d_rs. Returns iterations used; *conv, *rmax. */
static int newton(const blk_model *m, blk_state *s, int *conv, double *rmax,
                  int *cuts, int *factored) {
  blk_work *w = s->work;
  const int M = m->M;
  double *d = s->d_rs, *F = s->force, *k = w->k_try;
  blk_spring_law(m, w->held, d, F, k);
  double phi = residual(m, w, d, F, w->r, rmax);
  int it = 0, refactor = 0;
  *conv = 0;
  for (;;) {
    if (*rmax < m->solver.tol) {
      *conv = 1;
      break;
    }
    if (it == m->solver.max_iter || !isfinite(*rmax)) break;
    const int before = *factored;
    const double r_before = *rmax;
    const int may_reuse = m->solver.reuse_jacobian && m->solver.method == BLK_NR_PLAIN;
    if (newton_direction(m, w, k, may_reuse && !refactor, factored)) break;
    it++;
    if (m->solver.method == BLK_NR_PLAIN) {
      for (int e = 0; e < M; e++) d[e] += w->delta[e];
      blk_spring_law(m, w->held, d, F, k);
      phi = residual(m, w, d, F, w->r, rmax);
      /* a chord step that did not cut the residual 4×: refactor next time */
      refactor = *factored == before && !(*rmax < 0.25 * r_before);
      continue;
    }
    /* Armijo backtracking on ½|r|²; along the Newton direction its slope is −2φ */
    double lambda = 1.0, phi_try = 0, rmax_try = 0;
    for (int cut = 0; cut < BLK_PRIMAL_CUTS; cut++) {
      for (int e = 0; e < M; e++) w->d_try[e] = d[e] + lambda * w->delta[e];
      blk_spring_law(m, w->held, w->d_try, w->F_try, k);
      phi_try = residual(m, w, w->d_try, w->F_try, w->y, &rmax_try);
      if (phi_try <= (1.0 - 2 * BLK_ARMIJO * lambda) * phi) break;
      lambda *= 0.5;
      (*cuts)++;
    }
    memcpy(d, w->d_try, (size_t)M * sizeof(double));
    memcpy(F, w->F_try, (size_t)M * sizeof(double));
    memcpy(w->r, w->y, (size_t)M * sizeof(double));
    phi = phi_try;
    *rmax = rmax_try;
  }
  return it;
}


/* ---------------------------------------------------- robust: dual Newton */

/* Dual objective J(F) = ½FᵀCF − bᵀF + Σ Ψ(F) and its gradient
 * ∇J = CF − b + d(F) = −f (eq. 6: the residual in m), blk_dual_element for
 * the spring terms. d_of_F holds the previous d(F) (warm start) on entry.
 * Also returns 1/k at d(F) in w->sk and C F in w->CF. */
static double dual_eval(const blk_model *m, blk_work *w, const double *F, double *grad,
                        double *d_of_F) {
  blk_fft_apply(&w->fft, &w->C_hat, F, w->CF);
  double J = 0;
  for (int e = 0; e < m->M; e++) {
    double de;
    const double psi = blk_dual_element(m, w, e, F[e], d_of_F[e], &de, &w->sk[e]);
    d_of_F[e] = de;
    grad[e] = w->CF[e] - w->b[e] + de;
    J += F[e] * (0.5 * w->CF[e] - w->b[e]) + psi;
  }
  return J;
}

/* Projected Newton (Bertsekas 1982) on J with the bound F ≥ 0 for elements
 * without an adhesive bond. J is strictly convex (C SPD, springs monotone),
 * so Armijo backtracking along the projection arc converges from any start. */
int blk_dense_dual(const blk_model *m, blk_state *s, int *conv, double *rmax, int *cuts,
                   int *factored) {
  blk_work *w = s->work;
  const int M = m->M;
  double *F = s->force, *grad = w->r, *dF = w->delta, *Ft = w->F_try, *gt = w->y,
         *dd = w->d_try;
  for (int e = 0; e < M; e++) {
    if (!(m->adhesion && w->held[e]) && F[e] < 0) F[e] = 0;
    dd[e] = s->d_rs[e];
  }
  w->dense_overflow = 0;
  w->fact_valid = 0; /* w->A holds the dual's factor from here */
  double J = dual_eval(m, w, F, grad, dd);
  int it = 0;
  *conv = 0;
  for (;;) {
    /* optimality in m: |f| < tol where F ≠ 0 or bonded, no penetration (f ≤ tol) where F = 0 */
    double viol = 0;
    int P = 0;
    for (int e = 0; e < M; e++) {
      const int bound = !(m->adhesion && w->held[e]) && F[e] <= 0;
      double v = bound ? fmax(-grad[e], 0.0) : fabs(grad[e]);
      if (v > viol) viol = v;
      if (!(bound && grad[e] > 0)) w->act[P++] = e; /* free set */
    }
    *rmax = viol;
    if (viol < m->solver.tol) {
      *conv = 1;
      break;
    }
    if (it == m->solver.max_iter || !isfinite(J)) break;
    if (P > w->A_cap) { /* auto: too many for the matrix, the caller goes matrix-free */
      w->dense_overflow = 1;
      return it;
    }
    it++;
    /* (C_AA + diag(1/k_A)) ΔF_A = −∇J_A, ΔF = 0 on the binding set */
    for (int a = 0; a < P; a++) {
      const int i = w->act[a];
      double *Aa = w->A + (size_t)a * P;
      for (int c = 0; c <= a; c++) Aa[c] = c_entry(m, w->kern, i, w->act[c]);
      Aa[a] += w->sk[i];
      gt[a] = -grad[i];
    }
    (*factored)++;
    w->fact_valid = 0;
    if (cholesky(w->A, P, P)) break; /* C not SPD: the dual is not convex */
    w->fact_valid = BLK_FACT_DUAL; /* kept for the tangent's preconditioner */
    w->fact_P = P;
    memcpy(w->fact_act, w->act, (size_t)P * sizeof(int));
    cholesky_solve(w->A, P, P, gt);
    for (int e = 0; e < M; e++) dF[e] = 0;
    for (int a = 0; a < P; a++) dF[w->act[a]] = gt[a];
    double lambda = 1.0, Jt = J;
    for (int cut = 0; cut < BLK_MAX_CUTS; cut++) {
      double slope = 0;
      for (int e = 0; e < M; e++) {
        double v = F[e] + lambda * dF[e];
        if (!(m->adhesion && w->held[e]) && v < 0) v = 0;
        Ft[e] = v;
        slope += grad[e] * (v - F[e]);
      }
      Jt = dual_eval(m, w, Ft, gt, dd);
      /* near the solution the decrease of J drops below its round-off
       * (|slope| ~ k f² ≪ eps |J|): take the Newton step as it is */
      if (Jt <= J + BLK_ARMIJO * slope || slope >= 0 ||
          -slope < BLK_DECREASE_ROUNDOFF * fabs(J))
        break;
      lambda *= 0.5;
      (*cuts)++;
    }
    memcpy(F, Ft, (size_t)M * sizeof(double));
    memcpy(grad, gt, (size_t)M * sizeof(double));
    J = Jt;
  }
  /* back to the thesis' variables: compression d(F) in contact, the geometric
   * overlap b − CF (≤ 0: a gap) elsewhere; w->CF = C F */
  dual_eval(m, w, F, grad, dd);
  for (int e = 0; e < M; e++) s->d_rs[e] = F[e] != 0.0 ? dd[e] : w->b[e] - w->CF[e];
  return it;
}

int blk_dense_newton(const blk_model *m, blk_state *s, int *conv, double *rmax,
                     int *cuts, int *factored) {
  const int it = newton(m, s, conv, rmax, cuts, factored);
  blk_work *w = s->work; /* residual() left b − C F */
  for (int e = 0; e < m->M; e++) w->CF[e] = w->b[e] - w->CF[e];
  return it;
}

/* ------------------------------------------------------------ tangent */

/* dF/dd_road = 1ᵀ(C_AA + D_A)⁻¹1 over the loaded set A (blk_cg_tangent),
 * by CG preconditioned with the last factor of the Newton matrix when that
 * was built on the same set: primal form sᵀ(I + S C S)⁻¹s with S = diag √k
 * (factor of I + S_f C S_f), dual form with the factor of C_AA + D_A. The
 * factor is from the last iterate, so a couple of iterations suffice.
 * Returns -1 (nothing done) when no factor fits. */
int blk_dense_tangent(const blk_model *m, blk_state *s, double tol, double *K,
                      int *products) {
  blk_work *w = s->work;
  const int M = m->M, primal = w->fact_valid == BLK_FACT_PRIMAL;
  if (!w->fact_valid) return -1;
  int P = 0;
  for (int e = 0; e < M; e++) {
    const int in = s->force[e] > 0 || (m->adhesion && w->held[e] && s->force[e] != 0);
    if (!in) continue;
    if (P >= w->fact_P || w->fact_act[P] != e) return -1;
    double Fe, ke;
    blk_spring_eval(m, e, fabs(s->d_rs[e]), &Fe, &ke);
    if (!m->rigid && !(ke > 0)) return -1;
    w->sk[P] = m->rigid ? 0.0 : primal ? sqrt(ke) : 1.0 / ke; /* √k, or 1/k (dual) */
    P++;
  }
  if (P != w->fact_P) return -1;
  /* vectors over A: x (w->y), r (w->r), z (w->delta), p (w->d_try), q (w->F_try) */
  double *x = w->y, *r = w->r, *z = w->delta, *p = w->d_try, *q = w->F_try;
  double rz = 0, rhs = 0;
  for (int a = 0; a < P; a++) {
    x[a] = 0;
    r[a] = primal ? w->sk[a] : 1.0;
    z[a] = r[a];
    rhs = fmax(rhs, fabs(r[a]));
  }
  cholesky_solve(w->A, P, P, z);
  for (int a = 0; a < P; a++) {
    p[a] = z[a];
    rz += r[a] * z[a];
  }
  for (int it = 0; it < m->solver.cg_max_iter; it++) {
    memset(w->t, 0, (size_t)M * sizeof(double));
    for (int a = 0; a < P; a++) w->t[w->fact_act[a]] = primal ? w->sk[a] * p[a] : p[a];
    blk_fft_apply(&w->fft, &w->C_hat, w->t, w->qc);
    (*products)++;
    double pq = 0;
    for (int a = 0; a < P; a++) {
      const double c = w->qc[w->fact_act[a]];
      q[a] = primal ? p[a] + w->sk[a] * c : c + w->sk[a] * p[a];
      pq += p[a] * q[a];
    }
    if (!(pq > 0)) break;
    const double alpha = rz / pq;
    double rmax = 0;
    for (int a = 0; a < P; a++) {
      x[a] += alpha * p[a];
      r[a] -= alpha * q[a];
      rmax = fmax(rmax, fabs(r[a]));
      z[a] = r[a];
    }
    if (rmax <= tol * rhs) break;
    cholesky_solve(w->A, P, P, z);
    double rz_new = 0;
    for (int a = 0; a < P; a++) rz_new += r[a] * z[a];
    const double beta = rz_new / rz;
    rz = rz_new;
    for (int a = 0; a < P; a++) p[a] = z[a] + beta * p[a];
  }
  double T = 0;
  for (int a = 0; a < P; a++) T += primal ? w->sk[a] * x[a] : x[a];
  *K = T;
  return 0;
}
