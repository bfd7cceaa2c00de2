/* pchip.c — monotone piecewise cubic Hermite interpolation (Fritsch & Carlson
 * 1980): the slopes, their limiter, the knot search and the cubic piece.
 * Used by the punch table (punch.c) and by the roughness-spring law
 * (spring_law.c), which contact_block evaluates in its time loop. */
#include <math.h>
#include <stdlib.h>

#include "green/green.h"

void grn_pchip_slopes(int n, const double *x, const double *y, double *m) {
  /* Fritsch & Carlson (1980): secants, harmonic-type interior slopes, then
   * the alpha² + beta² <= 9 limiter keeps each cubic monotone */
  if (n < 2) { if (n == 1) m[0] = 0; return; }
  double *del = malloc((n - 1) * sizeof *del);
  if (!del) { /* no secant table: the limiter alone on zero slopes is monotone */
    for (int i = 0; i < n; i++) m[i] = 0;
    return;
  }
  for (int i = 0; i < n - 1; i++)
    del[i] = (y[i + 1] - y[i]) / (x[i + 1] - x[i]);
  m[0] = del[0];
  m[n - 1] = del[n - 2];
  for (int i = 1; i < n - 1; i++)
    m[i] = del[i - 1] * del[i] <= 0 ? 0 : 0.5 * (del[i - 1] + del[i]);
  grn_pchip_limit(n, x, y, m);
  free(del);
}

void grn_pchip_limit(int n, const double *x, const double *y, double *m) {
  /* Fritsch–Carlson step 2: clamp slopes so every cubic piece is monotone */
  for (int i = 0; i < n - 1; i++) {
    double del = (y[i + 1] - y[i]) / (x[i + 1] - x[i]);
    if (del == 0) { m[i] = m[i + 1] = 0; continue; }
    if (m[i] / del < 0) m[i] = 0;
    if (m[i + 1] / del < 0) m[i + 1] = 0;
    double a = m[i] / del, b = m[i + 1] / del, s = a * a + b * b;
    if (s > 9) {
      double t = 3 / sqrt(s);
      m[i] = t * a * del;
      m[i + 1] = t * b * del;
    }
  }
}

int grn_pchip_interval(int n, const double *x, double t) {
  /* guess for equally spaced knots (the synthetic spring tables: one step),
   * checked and moved by one, else bisection */
  const double r = (t - x[0]) / (x[n - 1] - x[0]); /* NaN: r > 0 fails */
  int lo = r > 0 ? (r < 1 ? (int)(r * (n - 1)) : n - 2) : 0;
  if (lo > n - 2) lo = n - 2;
  if (lo + 1 < n - 1 && x[lo + 1] <= t) lo++;
  else if (lo > 0 && x[lo] > t) lo--;
  if (x[lo] <= t && t < x[lo + 1]) return lo;
  int hi = n - 1;
  lo = 0;
  while (hi - lo > 1) {
    int mid = (lo + hi) / 2;
    if (x[mid] <= t) lo = mid; else hi = mid;
  }
  return lo;
}

double grn_pchip_piece(const double *x, const double *y, const double *m, int lo,
                       double t, double *dydt) {
  /* cubic Hermite basis on [x_lo, x_hi] (FORMATS.md) and its derivative */
  const int hi = lo + 1;
  const double h = x[hi] - x[lo], s = (t - x[lo]) / h, s2 = s * s, s3 = s2 * s;
  const double h00 = 2 * s3 - 3 * s2 + 1, h10 = s3 - 2 * s2 + s,
               h01 = -2 * s3 + 3 * s2, h11 = s3 - s2;
  if (dydt) {
    const double d00 = (6 * s2 - 6 * s) / h, d10 = 3 * s2 - 4 * s + 1,
                 d01 = (-6 * s2 + 6 * s) / h, d11 = 3 * s2 - 2 * s;
    *dydt = d00 * y[lo] + d10 * m[lo] + d01 * y[hi] + d11 * m[hi];
  }
  return h00 * y[lo] + h10 * h * m[lo] + h01 * y[hi] + h11 * h * m[hi];
}

double grn_pchip_eval(int n, const double *x, const double *y, const double *m,
                      double t, double *dydt) {
  if (t >= x[n - 1]) { /* linear beyond the last knot (FORMATS.md) */
    if (dydt) *dydt = m[n - 1];
    return y[n - 1] + m[n - 1] * (t - x[n - 1]);
  }
  if (t <= x[0]) {
    if (dydt) *dydt = m[0];
    return y[0] + m[0] * (t - x[0]);
  }
  return grn_pchip_piece(x, y, m, grn_pchip_interval(n, x, t), t, dydt);
}
