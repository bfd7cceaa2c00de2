/* Love's coefficients: closed form vs Johnson's log form (round-off), vs the
 * values of Love's closed form (Love 1929; Johnson 1985 eq. 3.25, as
 * ContactMechanics computes them) and vs fine-grid numerical integration. */
#include <math.h>
#include <stdio.h>

#include "cosim_test.h"
#include "green/green.h"

/* Johnson (1985) eq. 3.25 as printed (logs), for the round-off comparison. */
static double love_log_form(double x, double y, double a, double b, double Es) {
  double xp = x + a, xm = x - a, yp = y + b, ym = y - b;
  double r_pp = hypot(xp, yp), r_pm = hypot(xp, ym), r_mp = hypot(xm, yp),
         r_mm = hypot(xm, ym);
  double s = xp * log((yp + r_pp) / (ym + r_pm)) +
             yp * log((xp + r_pp) / (xm + r_mp)) +
             xm * log((ym + r_mm) / (yp + r_mp)) +
             ym * log((xm + r_mm) / (xp + r_pm));
  return s / (4 * a * b) / (M_PI * Es);
}

/* ∫∫ 1/r over the rectangle seen from (x,y): polar rays from the field point
 * for the self element (exact radial integral), else Gauss–Legendre product
 * rule on a fine sub-grid. */
static double numeric(double x, double y, double a, double b, double Es) {
  double sum = 0;
  if (fabs(x) < a && fabs(y) < b) {
    /* ∫ dθ R(θ), R = distance to the boundary; split at the 4 corners */
    double cx[4] = {a - x, -a - x, -a - x, a - x}, cy[4] = {b - y, b - y, -b - y, -b - y};
    for (int c = 0; c < 4; c++) {
      double t0 = atan2(cy[c], cx[c]), t1 = atan2(cy[(c + 1) % 4], cx[(c + 1) % 4]);
      if (t1 < t0) t1 += 2 * M_PI;
      int n = 20000;
      for (int k = 0; k < n; k++) {
        double t = t0 + (k + 0.5) * (t1 - t0) / n, ct = cos(t), st = sin(t);
        double R = 1e300;
        if (ct > 1e-15) R = fmin(R, (a - x) / ct);
        if (ct < -1e-15) R = fmin(R, (-a - x) / ct);
        if (st > 1e-15) R = fmin(R, (b - y) / st);
        if (st < -1e-15) R = fmin(R, (-b - y) / st);
        sum += R * (t1 - t0) / n;
      }
    }
  } else {
    const double gx[4] = {-0.8611363115940526, -0.3399810435848563,
                          0.3399810435848563, 0.8611363115940526};
    const double gw[4] = {0.3478548451374538, 0.6521451548625461,
                          0.6521451548625461, 0.3478548451374538};
    int n = 200;
    double hx = 2 * a / n, hy = 2 * b / n;
    for (int i = 0; i < n; i++)
      for (int j = 0; j < n; j++)
        for (int p = 0; p < 4; p++)
          for (int q = 0; q < 4; q++) {
            double xs = -a + (i + 0.5 + 0.5 * gx[p]) * hx;
            double ys = -b + (j + 0.5 + 0.5 * gx[q]) * hy;
            sum += gw[p] * gw[q] * 0.25 * hx * hy / hypot(x - xs, y - ys);
          }
  }
  return sum / (4 * a * b) / (M_PI * Es);
}

int main(void) {
  const double E = 6e6, nu = 0.5, Es = E / (1 - nu * nu), D = 1e-3;
  const double a = D / 2;
  /* Love's values in units of 1/(E* Δ) (Johnson 1985 eq. 3.25, checked) */
  const double pos[4][2] = {{0, 0}, {1, 0}, {1, 1}, {5, 0}};
  const double ref[4] = {1.1222, 0.3304, 0.2307, 0.06377};
  for (int k = 0; k < 4; k++) {
    double c = grn_love_compliance(pos[k][0] * D, pos[k][1] * D, a, a, E, nu);
    char what[64];
    snprintf(what, sizeof what, "published (%g,%g)", pos[k][0], pos[k][1]);
    CHECK_REL(what, c * Es * D, ref[k], 5e-4);
  }
  /* round-off agreement with the log form away from its singular lines */
  const double fx[5][2] = {{0.3, 0.2}, {1.7, 0.4}, {2, 3}, {-4.2, 7.1}, {12, -9}};
  double worst = 0;
  for (int k = 0; k < 5; k++) {
    double c1 = grn_love_compliance(fx[k][0] * D, fx[k][1] * D, a, 0.7 * a, E, nu);
    double c2 = love_log_form(fx[k][0] * D, fx[k][1] * D, a, 0.7 * a, Es);
    worst = fmax(worst, fabs(c1 - c2) / c2);
  }
  printf("closed form vs log form: worst rel %.2e\n", worst);
  CHECK(worst < 1e-12, "round-off agreement %.3e", worst);
  /* numerical integration: self, neighbours, far, rectangle */
  const double nq[6][2] = {{0, 0}, {1, 0}, {1, 1}, {0.2, 0.1}, {3, 2}, {8, 0}};
  for (int k = 0; k < 6; k++) {
    double c1 = grn_love_compliance(nq[k][0] * D, nq[k][1] * D, a, 0.6 * a, E, nu);
    double c2 = numeric(nq[k][0] * D, nq[k][1] * D, a, 0.6 * a, Es);
    char what[64];
    snprintf(what, sizeof what, "fine grid (%g,%g)", nq[k][0], nq[k][1]);
    CHECK_REL(what, c1, c2, 1e-6);
  }
  /* reciprocity / symmetry and far-field Boussinesq 1/(π E* r) */
  double cf = grn_love_compliance(40 * D, 30 * D, a, a, E, nu);
  CHECK_REL("far field Boussinesq", cf, 1 / (M_PI * Es * 50 * D), 1e-4);
  CHECK(grn_love_compliance(2 * D, 1 * D, a, a, E, nu) ==
            grn_love_compliance(-2 * D, -1 * D, a, a, E, nu), "symmetry");
  return cosim_test_done("test_green_love");
}
