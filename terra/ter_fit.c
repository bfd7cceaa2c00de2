/* ter_fit.c — soil parameters from the virtual tests (Bekker 1969 plate
 * sinkage; Mohr–Coulomb and Janosi & Hanamoto 1961 from the shear box). */
#include "terra/terra.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define TER_K_MIN 1e-6   /* search range of the shear modulus K, m */
#define TER_K_MAX 10.0
#define TER_K_GRID 240   /* log-spaced scan before the golden section */
#define TER_MAX_PLATES 8

int ter_fit_line(int n, const double *x, const double *y, double *a, double *b, double *se_a,
                 double *se_b, proto_err *err) {
  if (n < 2) return proto_fail(err, "line fit: %d points, need 2", n);
  double mx = 0, my = 0;
  for (int i = 0; i < n; i++) {
    mx += x[i];
    my += y[i];
  }
  mx /= n;
  my /= n;
  double sxx = 0, sxy = 0;
  for (int i = 0; i < n; i++) {
    sxx += (x[i] - mx) * (x[i] - mx);
    sxy += (x[i] - mx) * (y[i] - my);
  }
  if (!(sxx > 0)) return proto_fail(err, "line fit: all %d points have the same x = %g", n, mx);
  *b = sxy / sxx;
  *a = my - *b * mx;
  double sse = 0;
  for (int i = 0; i < n; i++) sse += (y[i] - *a - *b * x[i]) * (y[i] - *a - *b * x[i]);
  double s2 = n > 2 ? sse / (n - 2) : 0;
  if (se_b) *se_b = sqrt(s2 / sxx);
  if (se_a) *se_a = sqrt(s2 * (1.0 / n + mx * mx / sxx));
  return 0;
}

/* (ln z, ln p) of a plate's points in the fit range; returns the count. */
static int log_points(const ter_series *t, int cz, int cp, double z_lo, double z_hi, double *lx,
                      double *ly) {
  int m = 0;
  for (int r = 0; r < t->n; r++) {
    double z = t->row[(size_t)r * t->ncol + cz], p = t->row[(size_t)r * t->ncol + cp];
    if (z >= z_lo && z <= z_hi && z > 0 && p > 0) {
      lx[m] = log(z);
      ly[m] = log(p);
      m++;
    }
  }
  return m;
}

int ter_fit_plates(int n_plates, const double *b, const ter_series *const *plates,
                   const char *zcol, const char *pcol, double z_lo, double z_hi,
                   ter_plate_fit *out, proto_err *err) {
  memset(out, 0, sizeof *out);
  if (n_plates < 2 || n_plates > TER_MAX_PLATES)
    return proto_fail(err, "Bekker fit: %d plates (need 2..%d widths)", n_plates, TER_MAX_PLATES);
  int total = 0;
  for (int i = 0; i < n_plates; i++) total += plates[i]->n;
  double *lx = malloc(sizeof *lx * (total + 1)), *ly = malloc(sizeof *ly * (total + 1));
  if (!lx || !ly) {
    free(lx);
    free(ly);
    return proto_fail(err, "out of memory");
  }
  int start[TER_MAX_PLATES + 1], rc = 0;
  start[0] = 0;
  out->n_plates = n_plates;
  for (int i = 0; i < n_plates && !rc; i++) {
    const ter_series *t = plates[i];
    int cz = ter_series_col(t, zcol), cp = ter_series_col(t, pcol);
    if (cz < 0 || cp < 0) {
      rc = proto_fail(err, "plate %d: no columns '%s' and '%s'", i, zcol, pcol);
      break;
    }
    for (int k = 0; k < i; k++)
      if (fabs(b[k] - b[i]) < 1e-9) rc = proto_fail(err, "plates %d and %d have the same width %g m", k, i, b[i]);
    int m = log_points(t, cz, cp, z_lo, z_hi, lx + start[i], ly + start[i]);
    out->b[i] = b[i];
    out->points[i] = m;
    start[i + 1] = start[i] + m;
    double a_own = 0, n_own = 0;
    if (!rc && ter_fit_line(m, lx + start[i], ly + start[i], &a_own, &n_own, NULL, NULL, err))
      rc = proto_wrap(err, "plate %d (b = %g m), z in [%g, %g] m", i, b[i], z_lo, z_hi);
    out->n_own[i] = n_own;
    out->k_own[i] = exp(a_own);
  }
  if (!rc) { /* pooled within-plate regression: one n, one intercept per plate */
    double sxy = 0, sxx = 0, mx[TER_MAX_PLATES], my[TER_MAX_PLATES];
    for (int i = 0; i < n_plates; i++) {
      mx[i] = my[i] = 0;
      int m = start[i + 1] - start[i];
      for (int k = start[i]; k < start[i + 1]; k++) {
        mx[i] += lx[k] / m;
        my[i] += ly[k] / m;
      }
      for (int k = start[i]; k < start[i + 1]; k++) {
        sxx += (lx[k] - mx[i]) * (lx[k] - mx[i]);
        sxy += (lx[k] - mx[i]) * (ly[k] - my[i]);
      }
    }
    out->n = sxy / sxx;
    double sse = 0, inv_b[TER_MAX_PLATES];
    for (int i = 0; i < n_plates; i++) {
      out->k_eq[i] = exp(my[i] - out->n * mx[i]);
      inv_b[i] = 1 / b[i];
      for (int k = start[i]; k < start[i + 1]; k++) {
        double e = ly[k] - (my[i] - out->n * mx[i]) - out->n * lx[k];
        sse += e * e;
      }
    }
    out->rms_log = sqrt(sse / start[n_plates]);
    /* k_eq = k_phi + k_c / b */
    rc = ter_fit_line(n_plates, inv_b, out->k_eq, &out->k_phi, &out->k_c, NULL, NULL, err);
  }
  free(lx);
  free(ly);
  return rc;
}

/* Least-squares tau_f at fixed K and the residual sum of squares. */
static double janosi_sse(int n, const double *j, const double *tau, double j_hi, double K,
                         double *tau_f) {
  double sgg = 0, sgt = 0;
  for (int i = 0; i < n; i++) {
    if (!(j[i] > 0 && j[i] <= j_hi)) continue;
    double g = 1 - exp(-j[i] / K);
    sgg += g * g;
    sgt += g * tau[i];
  }
  *tau_f = sgg > 0 ? sgt / sgg : 0;
  double sse = 0;
  for (int i = 0; i < n; i++) {
    if (!(j[i] > 0 && j[i] <= j_hi)) continue;
    double e = tau[i] - *tau_f * (1 - exp(-j[i] / K));
    sse += e * e;
  }
  return sse;
}

int ter_fit_janosi(int n, const double *j, const double *tau, double j_hi, double *tau_f,
                   double *K, double *rms, proto_err *err) {
  int m = 0;
  for (int i = 0; i < n; i++) m += j[i] > 0 && j[i] <= j_hi;
  if (m < 3) return proto_fail(err, "Janosi fit: %d points with 0 < j <= %g m, need 3", m, j_hi);
  /* scan ln K, then golden section around the best grid point */
  const double l0 = log(TER_K_MIN), l1 = log(TER_K_MAX), h = (l1 - l0) / (TER_K_GRID - 1);
  int best = 0;
  double tf, sbest = INFINITY;
  for (int g = 0; g < TER_K_GRID; g++) {
    double sse = janosi_sse(n, j, tau, j_hi, exp(l0 + g * h), &tf);
    if (sse < sbest) {
      sbest = sse;
      best = g;
    }
  }
  double a = l0 + (best > 0 ? best - 1 : 0) * h, b = l0 + (best < TER_K_GRID - 1 ? best + 1 : best) * h;
  const double gr = 0.5 * (sqrt(5.0) - 1);
  double c = b - gr * (b - a), d = a + gr * (b - a);
  double fc = janosi_sse(n, j, tau, j_hi, exp(c), &tf), fd = janosi_sse(n, j, tau, j_hi, exp(d), &tf);
  for (int it = 0; it < 100 && b - a > 1e-12; it++) {
    if (fc < fd) {
      b = d; d = c; fd = fc;
      c = b - gr * (b - a);
      fc = janosi_sse(n, j, tau, j_hi, exp(c), &tf);
    } else {
      a = c; c = d; fc = fd;
      d = a + gr * (b - a);
      fd = janosi_sse(n, j, tau, j_hi, exp(d), &tf);
    }
  }
  *K = exp(0.5 * (a + b));
  double sse = janosi_sse(n, j, tau, j_hi, *K, tau_f);
  if (rms) *rms = sqrt(sse / m);
  if (best == 0 || best == TER_K_GRID - 1)
    return proto_fail(err, "Janosi fit: K at the end of the search range [%g, %g] m (no shear "
                      "curve to fit?)", TER_K_MIN, TER_K_MAX);
  return 0;
}
