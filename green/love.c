/* love.c — Love (1929) influence coefficients of an elastic half-space for a
 * uniformly loaded rectangle (Love 1929; Johnson 1985 eq. 3.25). */
#include <math.h>

#include "green/green.h"

/* Antiderivative over X and Y of 1/sqrt(X² + Y² + c²). Written with asinh so
 * that no logarithm of a difference of near-equal numbers appears; the terms
 * dropped against the textbook x ln(y + r) form (−X ln|X|, ...) depend on one
 * variable only and cancel in the mixed corner difference. c = 0 is Love's
 * 1/r kernel (limit 0 on the axes). */
static double corner_term(double X, double Y, double c) {
  double t = 0.0;
  const double sx = sqrt(X * X + c * c), sy = sqrt(Y * Y + c * c);
  if (sx > 0.0)
    t += X * asinh(Y / sx);
  if (sy > 0.0)
    t += Y * asinh(X / sy);
  if (c > 0.0)
    t -= c * atan(X * Y / (c * sqrt(X * X + Y * Y + c * c)));
  return t;
}

static double rect_integral(double x, double y, double a, double b, double c) {
  return corner_term(x + a, y + b, c) - corner_term(x - a, y + b, c) -
         corner_term(x + a, y - b, c) + corner_term(x - a, y - b, c);
}

double grn_love_compliance(double x, double y, double a, double b, double E,
                           double nu) {
  return grn_love_smoothed(x, y, a, b, 0.0, E, nu);
}

double grn_love_smoothed(double x, double y, double a, double b, double c,
                         double E, double nu) {
  const double E_star = E / (1.0 - nu * nu);
  const double pressure = 1.0 / (4.0 * a * b); /* unit total force */
  /* Boussinesq: u = p/(π E*) ∫∫ dA'/r (Johnson eq. 3.25) */
  return pressure * rect_integral(x, y, a, b, c) / (M_PI * E_star);
}

void grn_static_love(const grn_grid *g, double E, double nu, double *C) {
  const int wx = 2 * g->nx - 1;
  for (int dj = -(g->ny - 1); dj <= g->ny - 1; dj++)
    for (int di = -(g->nx - 1); di <= g->nx - 1; di++)
      C[(dj + g->ny - 1) * wx + di + g->nx - 1] = grn_love_compliance(
          di * g->dx, dj * g->dy, 0.5 * g->dx, 0.5 * g->dy, E, nu);
}
