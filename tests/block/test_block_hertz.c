/* Hertz: a rigid paraboloid road z = −r²/(2R) pressed into the Love
 * half-space (quasi-static), against the analytic solution (Johnson 1985
 * §4.2):
 *   F = 4/3 E* √R δ^{3/2},  a = √(Rδ),  p(r) = p0 √(1 − r²/a²),
 *   p0 = 2 E* √(δ/R) / π,  dF/dδ = 2 E* a.
 *  1. dense solver, stiff linear springs, 40 × 40: F within 2 % once the
 *     contact spans ≥ 8 elements, contact area within 10 % (issue 5);
 *  2. matrix-free solver, no springs (rigid), n × n (argument, default 64;
 *     256 in the slow test): F within 0.1 %, the pressure within 0.5 % of
 *     Hertz at every element inside 0.8 a, the tangent stiffness within 1 %
 *     of 2 E* a;
 *  3. rectangular elements (dx = 1.5 dy), matrix-free: the same bounds; and
 *     the dense solver on a smaller rectangular grid agrees to 1e-10. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "blk_test.h"
#include "contact_block/blk.h"

static proto_err err;

static const double R = 0.1, E = 10e6, nu = 0.3;
#define E_STAR (E / (1 - nu * nu))

static void sweep_dense(void) {
  const int n = 40;
  const double dx = 0.5e-3;
  blk_model m;
  OK(blk_model_init(&m, n, n, dx, dx, &err));
  OK(blk_road_paraboloid(&m, R, &err));
  OK(blk_green_halfspace(&m, E, nu, &err));
  /* "no roughness springs": a spring far stiffer than the layer element
   * (self-stiffness E* dx / 1.12 ≈ 5e3 N/m here) leaves d_rs ~ 1e-8 of d_el */
  const double k = 1e6 * E_STAR * dx;
  OK(blk_springs_linear(&m, &k, 0, &err));
  m.solver.quasi_static = 1;
  m.solver.method = BLK_NR_DUAL;
  m.solver.max_iter = 50;
  m.solver.tol = 1e-18;
  blk_state s;
  OK(blk_state_create(&m, &s, &err));
  double worst = 0;
  /* contact radius a = √(Rδ) from 4 to ~13 elements (grid half-width 20) */
  for (int i = 1; i <= 8; i++) {
    const double a = (4.0 + 9.0 * (i - 1) / 7.0) * dx, delta = a * a / R;
    OK(blk_step(&m, &s, delta, &err));
    CHECK(s.converged, "delta %g: not converged (residual %g)", delta, s.residual);
    const double F_hertz = 4.0 / 3.0 * E_STAR * sqrt(R) * pow(delta, 1.5);
    const double rel = s.total_force / F_hertz - 1.0;
    printf("dense: a/dx %5.2f  F %.6e N  Hertz %.6e N  rel %+.4f  contacts %d\n", a / dx,
           s.total_force, F_hertz, rel, s.n_contact);
    if (i >= 4 && fabs(rel) > worst) worst = fabs(rel); /* fine: a >= 8 elements */
    if (i >= 4) {
      CHECK(fabs(rel) < 0.02, "Hertz error %.4f at a/dx = %.1f", rel, a / dx);
      const double area = s.n_contact * dx * dx, area_hertz = M_PI * R * delta;
      CHECK(fabs(area / area_hertz - 1) < 0.10, "contact area %g vs Hertz %g", area,
            area_hertz);
    }
  }
  printf("dense: max |rel error| for a >= 8 elements: %.4f\n", worst);
  blk_state_free(&s);
  blk_model_free(&m);
}

/* One quasi-static step to δ with contact radius a = 0.7 × the grid's
 * smaller half-width; checks against Hertz if `check` (grids with a ≥ 20
 * elements); element forces into F (M). */
static void hertz(int nx, int ny, double dx, double dy, blk_method method, double *F,
                  int check, const char *label) {
  blk_model m;
  OK(blk_model_init(&m, nx, ny, dx, dy, &err));
  OK(blk_road_paraboloid(&m, R, &err));
  OK(blk_green_halfspace(&m, E, nu, &err));
  OK(blk_springs_rigid(&m, &err));
  const double a = 0.7 * 0.5 * fmin(nx * dx, ny * dy), delta = a * a / R;
  m.solver.quasi_static = 1;
  m.solver.method = method;
  m.solver.max_iter = 50;
  m.solver.tol = 1e-12 * delta; /* m: a little above the round-off of C·F */
  blk_state s;
  OK(blk_state_create(&m, &s, &err));
  OK(blk_step(&m, &s, delta, &err));
  CHECK(s.converged, "%s: not converged (residual %g m)", label, s.residual);
  const double F_h = 4.0 / 3.0 * E_STAR * sqrt(R) * pow(delta, 1.5);
  const double p0 = 2 * E_STAR / M_PI * sqrt(delta / R), xc = 0.5 * nx * dx, yc = 0.5 * ny * dy;
  double ep = 0;
  int inside = 0;
  for (int j = 0; j < ny; j++)
    for (int i = 0; i < nx; i++) {
      const double r = hypot((i + 0.5) * dx - xc, (j + 0.5) * dy - yc);
      if (r >= 0.8 * a) continue;
      const double pH = p0 * sqrt(1 - r * r / (a * a)), p = s.force[j * nx + i] / (dx * dy);
      ep = fmax(ep, fabs(p - pH) / pH);
      inside++;
    }
  const double eF = s.total_force / F_h - 1, eK = s.stiffness / (2 * E_STAR * a) - 1;
  printf("%s: %d x %d, dx %g, dy %g, a = %.1f dx: F %.8e N (Hertz %.8e, rel %+.2e), "
         "pressure inside 0.8a (%d elements) max rel %.2e, dF/dd %.6e (2E*a: rel %+.2e), "
         "%d products\n", label, nx, ny, dx, dy, a / dx, s.total_force, F_h, eF, inside, ep,
         s.stiffness, eK, s.products);
  if (check) {
    CHECK(fabs(eF) < 1e-3, "%s: force off Hertz by %.2e", label, eF);
    CHECK(inside > 100 && ep < 5e-3, "%s: pressure off Hertz by %.2e (%d elements)", label,
          ep, inside);
    CHECK(fabs(eK) < 1e-2, "%s: tangent off 2E*a by %.2e", label, eK);
  }
  if (F) memcpy(F, s.force, (size_t)m.M * sizeof(double));
  blk_state_free(&s);
  blk_model_free(&m);
}

int main(int argc, char **argv) {
  const int n = argc > 1 ? atoi(argv[1]) : 64;
  if (n < 16 || n > 4096) {
    fprintf(stderr, "usage: test_block_hertz [n >= 16]\n");
    return 2;
  }
  if (n <= 64) sweep_dense();
  hertz(n, n, 1e-4, 1e-4, BLK_CG, NULL, 1, "matrix-free");
  /* rectangular elements: dx = 1.5 dy, the grid about square in metres */
  hertz(n, n * 3 / 2, 1.5e-4, 1e-4, BLK_CG, NULL, 1, "rectangular");
  if (n <= 64) { /* dense and matrix-free on the same rectangular grid */
    enum { RX = 20, RY = 30 };
    static double Fd[RX * RY], Fc[RX * RY];
    hertz(RX, RY, 1.5e-4, 1e-4, BLK_NR_DUAL, Fd, 0, "rectangular dense");
    hertz(RX, RY, 1.5e-4, 1e-4, BLK_CG, Fc, 0, "rectangular matrix-free");
    double d = 0, fmax_ = 0;
    for (int e = 0; e < RX * RY; e++) {
      d = fmax(d, fabs(Fd[e] - Fc[e]));
      fmax_ = fmax(fmax_, fabs(Fd[e]));
    }
    printf("rectangular: dense vs matrix-free element forces: max diff %.2e rel\n", d / fmax_);
    CHECK(d <= 1e-10 * fmax_, "dense and matrix-free differ by %.2e rel", d / fmax_);
  }
  return cosim_test_done("test_block_hertz");
}
