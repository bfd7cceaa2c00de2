/* The periodic option (grid.periodic): a rigid road h0 cos(2πx/λ), uniform
 * in y, repeating over the block, pressed into the periodic half-space —
 * Westergaard's problem (Westergaard 1939; Johnson 1985 §13.2):
 *   p* = π E* h0 / λ,  p̄ = p* sin²(πa/λ),
 *   p(x) = 2 p̄ cos(πx/λ) / sin²(πa/λ) · √(sin²(πa/λ) − sin²(πx/λ)),  |x| < a.
 * From the computed mean pressure p̄ the analytic contact half-width a and
 * pressure follow; the computed pressure must match within 1 % of p(0)
 * inside 0.9 a, and the contact width within one element. The matrix-free
 * (circular FFT) and dense solvers agree to 1e-10 on a smaller periodic grid,
 * and the matrix-free solver runs the same on dx ≠ dy. */
#include <math.h>
#include <string.h>

#include "blk_test.h"
#include "contact_block/blk.h"

static proto_err err;

static const double E = 10e6, nu = 0.3, h0 = 1e-5, lambda = 6.4e-3;

/* Element forces into F; returns the computed mean pressure. */
static double westergaard(int nx, int ny, double dy, blk_method method, double approach,
                          double *F, int check, const char *label) {
  const double dx = lambda / nx, Es = E / (1 - nu * nu);
  blk_model m;
  OK(blk_model_init(&m, nx, ny, dx, dy, &err));
  m.periodic = 1;
  for (int j = 0; j < ny; j++)
    for (int i = 0; i < nx; i++) /* crest at x = 0: element i centred at (i + ½ − nx/2) dx */
      m.z_road[j * nx + i] = h0 * cos(2 * M_PI * (i + 0.5 - 0.5 * nx) * dx / lambda) - h0;
  OK(blk_green_halfspace(&m, E, nu, &err));
  OK(blk_springs_rigid(&m, &err));
  m.solver.quasi_static = 1;
  m.solver.method = method;
  m.solver.max_iter = 50;
  m.solver.tol = 1e-17;
  blk_state s;
  OK(blk_state_create(&m, &s, &err));
  OK(blk_step(&m, &s, approach * h0, &err));
  CHECK(s.converged, "%s: not converged (residual %g)", label, s.residual);
  const double pbar = s.total_force / (nx * dx * ny * dy), pstar = M_PI * Es * h0 / lambda;
  const double s2 = pbar / pstar, a = lambda / M_PI * asin(sqrt(s2));
  double worst = 0;
  int in_contact = 0;
  for (int i = 0; i < nx; i++) in_contact += s.force[i] > 0; /* row j = 0 */
  const double p_0 = 2 * pbar / s2 * sqrt(s2);
  for (int j = 0; j < ny; j++)
    for (int i = 0; i < nx; i++) {
      const double x = (i + 0.5 - 0.5 * nx) * dx;
      if (fabs(x) >= 0.9 * a) continue;
      const double c = sin(M_PI * x / lambda);
      const double p = 2 * pbar * cos(M_PI * x / lambda) / s2 * sqrt(s2 - c * c);
      worst = fmax(worst, fabs(s.force[j * nx + i] / (dx * dy) - p) / p_0);
    }
  printf("%s: %d x %d: mean pressure %.5g Pa = %.4f p*, contact width %d elements (2a = "
         "%.2f elements), pressure inside 0.9 a: max |p - p_W| = %.2e p(0)\n", label, nx, ny,
         pbar, s2, in_contact, 2 * a / dx, worst);
  if (check) {
    CHECK(s2 > 0.05 && s2 < 0.95, "%s: contact not partial (p/p* = %g)", label, s2);
    CHECK(fabs(in_contact - 2 * a / dx) <= 1.0, "%s: contact width %d vs 2a = %.2f elements",
          label, in_contact, 2 * a / dx);
    CHECK(worst < 0.01, "%s: pressure off Westergaard by %.2e of p(0)", label, worst);
  }
  if (F) memcpy(F, s.force, sizeof(double) * m.M);
  blk_state_free(&s);
  blk_model_free(&m);
  return pbar;
}

/* Beyond full contact the periodic rigid problem has no equilibrium: a
 * clear error, not a runaway. */
static void beyond_full_contact(void) {
  blk_model m;
  OK(blk_model_init(&m, 16, 2, 1e-4, 1e-4, &err));
  m.periodic = 1;
  for (int i = 0; i < m.M; i++) m.z_road[i] = h0 * cos(2 * M_PI * (i % 16) / 16.0) - h0;
  OK(blk_green_halfspace(&m, E, nu, &err));
  OK(blk_springs_rigid(&m, &err));
  m.solver.quasi_static = 1;
  blk_state s;
  OK(blk_state_create(&m, &s, &err));
  err.msg[0] = 0;
  CHECK(blk_step(&m, &s, 1.5 * h0, &err) == -1 && strstr(err.msg, "no equilibrium"),
        "beyond full contact: '%s'", err.msg);
  printf("beyond full contact: %s\n", err.msg);
  blk_state_free(&s);
  blk_model_free(&m);
}

int main(void) {
  beyond_full_contact();
  westergaard(128, 8, lambda / 128, BLK_CG, 0.4, NULL, 1, "matrix-free");
  westergaard(128, 12, lambda / 192, BLK_CG, 0.4, NULL, 1, "matrix-free, dy = dx/1.5");
  enum { NX = 32, NY = 4 };
  static double Fd[NX * NY], Fc[NX * NY];
  westergaard(NX, NY, lambda / NX, BLK_NR_DUAL, 0.4, Fd, 0, "dense");
  westergaard(NX, NY, lambda / NX, BLK_CG, 0.4, Fc, 0, "matrix-free");
  double d = 0, fm = 0;
  for (int e = 0; e < NX * NY; e++) {
    d = fmax(d, fabs(Fd[e] - Fc[e]));
    fm = fmax(fm, fabs(Fd[e]));
  }
  printf("periodic %d x %d: dense vs matrix-free element forces max diff %.2e rel\n", NX, NY,
         d / fm);
  CHECK(fm > 0 && d <= 1e-10 * fm, "periodic dense/matrix-free differ by %.2e rel", d / fm);
  return cosim_test_done("test_block_periodic");
}
