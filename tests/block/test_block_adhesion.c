/* Adhesion (seed 002 ch. 5.1, issue 5): load–hold–unload with mirrored
 * springs and a release force. The force goes negative while unloading and
 * returns to exactly zero once every point has released; release forces
 * 0.3 / 0.6 / 0.9 N give an increasing adherence force. */
#include <math.h>

#include "blk_test.h"

static proto_err err;

/* d_road of the load–hold–unload history (fig. 40): 0 → 50 µm in 200 steps,
 * hold 100 steps, then down to −200 µm in 300 steps and hold 100 */
static double history(int n) {
  if (n <= 200) return 5e-5 * n / 200.0;
  if (n <= 300) return 5e-5;
  if (n <= 600) return 5e-5 - 2.5e-4 * (n - 300) / 300.0;
  return -2e-4;
}

/* Returns the adherence force (−min F after the peak); checks the end state. */
static double run(blk_model *m, double release, const char *label) {
  m->adhesion = 1;
  m->release_force = release;
  blk_state s;
  OK(blk_state_create(m, &s, &err));
  double Fmin = 0, Fpeak = 0;
  int went_negative_unloading = 0;
  for (int n = 1; n <= 700; n++) {
    OK(blk_step(m, &s, history(n), &err));
    CHECK(s.converged, "%s step %d not converged (residual %g)", label, n, s.residual);
    if (s.total_force > Fpeak) Fpeak = s.total_force;
    if (n > 300 && s.total_force < Fmin) Fmin = s.total_force;
    if (n > 300 && s.total_force < 0) went_negative_unloading = 1;
  }
  printf("%s: release %.1f N: peak %.3f N, adherence force %.4f N, end force %g N, "
         "contacts %d\n", label, release, Fpeak, -Fmin, s.total_force, s.n_contact);
  CHECK(went_negative_unloading, "%s: force never negative while unloading", label);
  CHECK(s.total_force == 0.0, "%s: force after full release is %g, not exactly 0", label,
        s.total_force);
  CHECK(s.n_contact == 0, "%s: %d points still in contact", label, s.n_contact);
  blk_state_free(&s);
  return -Fmin;
}

int main(void) {
  blk_model m;
  OK(blk_test_scene(&m, 10, 256, 0, &err));
  /* dynamic (ZOH synthetic layer) with the default release force */
  double dyn = run(&m, 0.6, "dynamic");
  CHECK(dyn > 0, "no adherence force");
  /* the release-force sweep (fig. 43), quasi-static */
  m.solver.quasi_static = 1;
  double a3 = run(&m, 0.3, "quasi-static"), a6 = run(&m, 0.6, "quasi-static"),
         a9 = run(&m, 0.9, "quasi-static");
  CHECK(a3 < a6 && a6 < a9, "adherence not increasing: %g %g %g", a3, a6, a9);
  /* without adhesion the force never goes negative */
  m.adhesion = 0;
  blk_state s;
  OK(blk_state_create(&m, &s, &err));
  double Fmin = 0;
  for (int n = 1; n <= 700; n++) {
    OK(blk_step(&m, &s, history(n), &err));
    Fmin = fmin(Fmin, s.total_force);
  }
  CHECK(Fmin == 0.0, "force %g < 0 without adhesion", Fmin);
  blk_state_free(&s);
  blk_model_free(&m);
  return cosim_test_done("test_block_adhesion");
}
