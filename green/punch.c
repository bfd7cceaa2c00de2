/* punch.c — rigid frictionless flat punch (radius a) on an elastic layer of
 * thickness h bonded to a rigid base, for any a/h, exact within linear
 * elasticity up to quadrature error.
 *
 * Derivation (Hankel transforms, Abel representation; cf. Lebedev & Ufliand
 * 1958): write the pressure transform as P(ξ) = ∫_0^a g(t) cos(ξt) dt and the
 * layer compliance as 1/k(ξ) = 2 (1 − N(ξh)) / (E* ξ), N = 1 − 1/R with R the
 * stiffening factor of the bonded layer (grn_layer_factor, layer.c). u(r) = δ on r < a gives,
 * with g = (E* δ / π) φ(a x),
 *   φ(x) − (λ/π) ∫_0^1 φ(y) [k(λ(x−y)) + k(λ(x+y))] dy = 1,   λ = a/h,
 *   k(v) = ∫_0^∞ N(τ) cos(τ v) dτ,
 * and F = 2 E* a δ ∫_0^1 φ(x) dx. Half-space: N = 0, φ = 1, F = 2E*aδ.
 * Solved by Nyström (trapezoid) on n points. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "green/green.h"
#include "green/green_internal.h"

/* k(v) on v_m = m * dv, m = 0..nv-1, by Simpson's rule over τ in [0, 30]. */
static void kernel_table(double nu, double dv, int nv, double *kv) {
  const double tau_max = 30.0;
  double dtau = 0.004;
  if (dv * (nv - 1) * dtau > 0.2) /* keep >= 30 points per oscillation */
    dtau = 0.2 / (dv * (nv - 1));
  int nt = (int)ceil(tau_max / dtau);
  if (nt % 2) nt++;
  dtau = tau_max / nt;
  double *Nt = malloc((nt + 1) * sizeof *Nt);
  for (int i = 0; i <= nt; i++) {
    double tau = i * dtau;
    Nt[i] = tau == 0 ? 1.0 : 1.0 - 1.0 / grn_layer_factor(tau, nu);
  }
  for (int m = 0; m < nv; m++) {
    double v = m * dv, s = 0;
    for (int i = 0; i <= nt; i++) {
      double w = (i == 0 || i == nt) ? 1 : (i % 2 ? 4 : 2);
      s += w * Nt[i] * cos(i * dtau * v);
    }
    kv[m] = s * dtau / 3;
  }
  free(Nt);
}

/* Dense LU with partial pivoting, in place; solves A x = b (b overwritten). */
static int dense_solve(int n, double *A, double *b) {
  for (int c = 0; c < n; c++) {
    int p = c;
    for (int r = c + 1; r < n; r++)
      if (fabs(A[(size_t)r * n + c]) > fabs(A[(size_t)p * n + c]))
        p = r;
    if (A[(size_t)p * n + c] == 0.0)
      return -1;
    if (p != c) {
      for (int k = 0; k < n; k++) {
        double t = A[(size_t)c * n + k];
        A[(size_t)c * n + k] = A[(size_t)p * n + k];
        A[(size_t)p * n + k] = t;
      }
      double t = b[c];
      b[c] = b[p];
      b[p] = t;
    }
    const double *rc = A + (size_t)c * n;
    for (int r = c + 1; r < n; r++) {
      double *rr = A + (size_t)r * n, f = rr[c] / rc[c];
      if (f == 0.0) continue;
      for (int k = c; k < n; k++)
        rr[k] -= f * rc[k];
      b[r] -= f * b[c];
    }
  }
  for (int c = n - 1; c >= 0; c--) {
    for (int k = c + 1; k < n; k++)
      b[c] -= A[(size_t)c * n + k] * b[k];
    b[c] /= A[(size_t)c * n + c];
  }
  return 0;
}

int grn_punch_solve(double lam, double nu, int npts, double *phi,
                    proto_err *err) {
  if (!(lam > 0) || !isfinite(lam))
    return proto_fail(err, "punch: a/h = %g must be > 0", lam);
  if (!(nu >= 0 && nu <= 0.5))
    return proto_fail(err, "punch: nu = %g must be in [0, 0.5]", nu);
  const int n = npts > 1 ? npts : 1 + (int)fmin(1500, fmax(100, 24 * lam));
  const double dx = 1.0 / (n - 1);
  double *kv = malloc((size_t)(2 * n) * sizeof *kv);
  double *A = malloc((size_t)n * n * sizeof *A), *b = malloc(n * sizeof *b);
  if (!kv || !A || !b) {
    free(kv); free(A); free(b);
    return proto_fail(err, "punch: out of memory (n = %d)", n);
  }
  /* x_i − y_j and x_i + y_j are multiples of dx: tabulate k(λ m dx) */
  kernel_table(nu, lam * dx, 2 * n, kv);
  for (int i = 0; i < n; i++) {
    for (int j = 0; j < n; j++) {
      double w = (j == 0 || j == n - 1) ? 0.5 * dx : dx;
      A[(size_t)i * n + j] = (i == j) - lam / M_PI * w * (kv[abs(i - j)] + kv[i + j]);
    }
    b[i] = 1.0;
  }
  int rc = dense_solve(n, A, b);
  double s = 0;
  for (int j = 0; j < n; j++)
    s += ((j == 0 || j == n - 1) ? 0.5 * dx : dx) * b[j];
  free(kv); free(A); free(b);
  if (rc)
    return proto_fail(err, "punch: singular Nyström matrix at a/h = %g", lam);
  *phi = s;
  return 0;
}

int grn_punch_table_build(grn_punch_table *t, double nu, double lam_min,
                          double lam_max, int n, proto_err *err) {
  memset(t, 0, sizeof *t);
  if (n < 2 || !(lam_min > 0) || !(lam_max > lam_min))
    return proto_fail(err, "punch table: need n >= 2 and 0 < lam_min < lam_max");
  t->lam = malloc(n * sizeof *t->lam);
  t->phi = malloc(n * sizeof *t->phi);
  t->loglam = malloc(n * sizeof *t->loglam);
  t->logphi1 = malloc(n * sizeof *t->logphi1);
  t->slope = malloc(n * sizeof *t->slope);
  if (!t->lam || !t->phi || !t->loglam || !t->logphi1 || !t->slope) {
    grn_punch_table_free(t);
    return proto_fail(err, "punch table: out of memory");
  }
  t->n = n;
  t->nu = nu;
  for (int i = 0; i < n; i++) {
    t->lam[i] = lam_min * pow(lam_max / lam_min, (double)i / (n - 1));
    if (grn_punch_solve(t->lam[i], nu, 0, &t->phi[i], err)) {
      grn_punch_table_free(t);
      return -1;
    }
    t->loglam[i] = log(t->lam[i]);
    t->logphi1[i] = log(fmax(t->phi[i] - 1, 1e-300));
  }
  grn_pchip_slopes(n, t->loglam, t->logphi1, t->slope);
  return 0;
}

void grn_punch_table_free(grn_punch_table *t) {
  free(t->lam);
  free(t->phi);
  free(t->loglam);
  free(t->logphi1);
  free(t->slope);
  t->lam = t->phi = t->loglam = t->logphi1 = t->slope = NULL;
  t->n = 0;
}

double grn_punch_phi(const grn_punch_table *t, double lam) {
  const int n = t->n;
  if (lam <= t->lam[0]) /* φ − 1 ∝ λ as λ -> 0 */
    return 1.0 + (t->phi[0] - 1.0) * lam / t->lam[0];
  if (lam >= t->lam[n - 1]) {
    const double r = lam / t->lam[n - 1];
    if (t->nu < 0.4999) /* compressible thin layer: Winkler, F ∝ a² -> φ ∝ λ */
      return t->phi[n - 1] * r;
    /* incompressible film: φ = (3π/64) λ³ (1 + c/λ) (Yang 1998: the
     * thin-film limit F = (3π/8) G a⁴ δ / h³, with E* = 4G), the λ² term
     * matched to the last table entry */
    const double A = 3 * M_PI / 64, l3 = pow(t->lam[n - 1], 3);
    return A * l3 * r * r * r + (t->phi[n - 1] - A * l3) * r * r;
  }
  /* log(φ − 1) is smooth in log λ (slope 1 at small λ, 3 at large) */
  return 1.0 + exp(grn_pchip_eval(n, t->loglam, t->logphi1, t->slope, log(lam), NULL));
}
