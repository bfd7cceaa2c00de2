/* Hertz: rigid paraboloid road on a Love half-space (quasi-static, no
 * roughness springs: springs 1e6× stiffer than the element self-stiffness).
 * Force–indentation must match F = 4/3 E* √R δ^{3/2} within 2 % (issue 5). */
#include <math.h>
#include <string.h>

#include "blk_test.h"
#include "contact_block/blk.h"

static proto_err err;

int main(void) {
  const int n = 40;
  const double dx = 0.5e-3, R = 0.1, E = 10e6, nu = 0.3, Es = E / (1 - nu * nu);
  blk_model m;
  OK(blk_model_init(&m, n, n, dx, dx, &err));
  OK(blk_road_paraboloid(&m, R, &err));
  OK(blk_green_halfspace(&m, E, nu, &err));
  /* "no roughness springs": a spring far stiffer than the layer element
   * (self-stiffness E* dx / 1.12 ≈ 5e3 N/m here) leaves d_rs ~ 1e-8 of d_el */
  const double k = 1e6 * Es * dx;
  OK(blk_springs_linear(&m, &k, 0, &err));
  m.solver.quasi_static = 1;
  m.solver.method = BLK_NR_DUAL;
  m.solver.max_iter = 50;
  m.solver.tol = 1e-16;
  blk_state s;
  OK(blk_state_create(&m, &s, &err));
  double worst = 0;
  /* contact radius a = √(Rδ) from 4 to ~13 elements (grid half-width 20) */
  for (int i = 1; i <= 8; i++) {
    const double a = (4.0 + 9.0 * (i - 1) / 7.0) * dx, delta = a * a / R;
    OK(blk_step(&m, &s, delta, &err));
    CHECK(s.converged, "delta %g: not converged (residual %g)", delta, s.residual);
    const double F_hertz = 4.0 / 3.0 * Es * sqrt(R) * pow(delta, 1.5);
    const double rel = s.total_force / F_hertz - 1.0;
    printf("a/dx %5.2f  delta %.4e m  F %.6e N  Hertz %.6e N  rel %+.4f  contacts %d  "
           "iterations %d\n", a / dx, delta, s.total_force, F_hertz, rel, s.n_contact,
           s.iterations);
    if (i >= 4 && fabs(rel) > worst) worst = fabs(rel); /* fine: a >= 8 elements */
    if (i >= 4) {
      CHECK(fabs(rel) < 0.02, "Hertz error %.4f at a/dx = %.1f", rel, a / dx);
      const double area = s.n_contact * dx * dx, area_hertz = M_PI * R * delta;
      CHECK(fabs(area / area_hertz - 1) < 0.10, "contact area %g vs Hertz %g", area,
            area_hertz);
    }
  }
  printf("max |rel error| for a >= 8 elements: %.4f\n", worst);
  blk_state_free(&s);
  blk_model_free(&m);
  return blk_test_failures ? 1 : 0;
}
