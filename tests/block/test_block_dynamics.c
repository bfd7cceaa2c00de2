/* Dynamic model checks (issue 5):
 *  - quasi-static equals dynamic for very slow loading within 1 %;
 *  - the layer displacement equals the convolution of the forces with g
 *    (eq. 4–5, plain double sum) to round-off;
 *  - FFT and direct history agree to 1e-10 relative. */
#include <math.h>
#include <string.h>

#include "blk_test.h"

static proto_err err;

/* Runs a linear ramp 0 → d_max over n_steps; forces per step into F_tot,
 * element forces into F_hist (may be NULL). */
static void run(blk_model *m, int n_steps, double d_max, double *F_tot, double *F_hist,
                blk_state *out) {
  OK(blk_state_create(m, out, &err));
  for (int n = 1; n <= n_steps; n++) {
    OK(blk_step(m, out, d_max * n / n_steps, &err));
    CHECK(out->converged, "step %d not converged (residual %g)", n, out->residual);
    F_tot[n - 1] = out->total_force;
    if (F_hist) memcpy(F_hist + (size_t)(n - 1) * m->M, out->force, m->M * sizeof(double));
  }
}

static double max_abs(const double *a, int n) {
  double x = 0;
  for (int i = 0; i < n; i++) x = fmax(x, fabs(a[i]));
  return x;
}

int main(void) {
  blk_model m;
  OK(blk_test_scene(&m, 10, 256, 0, &err));
  /* 1. very slow loading: 0 → 0.1 mm in 2048 steps (40 ms ≫ the 0.5 ms mode) */
  enum { NS = 2048 };
  static double F_dyn[NS], F_qs[NS];
  blk_state s;
  run(&m, NS, 1e-4, F_dyn, NULL, &s);
  blk_state_free(&s);
  m.solver.quasi_static = 1;
  run(&m, NS, 1e-4, F_qs, NULL, &s);
  blk_state_free(&s);
  m.solver.quasi_static = 0;
  double worst = 0;
  for (int n = 0; n < NS; n++) worst = fmax(worst, fabs(F_dyn[n] - F_qs[n]));
  const double Fmax = max_abs(F_qs, NS);
  printf("slow loading: max |F_dyn - F_qs| = %.4e N of max F %.4e N (%.3f %%)\n", worst,
         Fmax, 100 * worst / Fmax);
  CHECK(Fmax > 1.0, "scene too soft: max F %g N", Fmax);
  CHECK(worst < 0.01 * Fmax, "dynamic differs from quasi-static by %.3f %%",
        100 * worst / Fmax);

  /* 2. faster loading (dynamics matter), FFT history without tail truncation:
   *    d_el against the plain convolution of the recorded forces */
  enum { NF = 300 };
  static double Ft_fft[NF], Ft_dir[NF], Fh_fft[NF * 100], Fh_dir[NF * 100];
  double ref[100];
  m.solver.tail_tol = 0;
  run(&m, NF, 1e-4, Ft_fft, Fh_fft, &s);
  blk_layer_displacement_ref(&m, Fh_fft, NF, ref);
  double dmax = 0, dref = max_abs(ref, m.M);
  for (int e = 0; e < m.M; e++) dmax = fmax(dmax, fabs(s.d_el[e] - ref[e]));
  printf("d_el vs plain convolution: max diff %.3e m of %.3e m (rel %.2e)\n", dmax, dref,
         dmax / dref);
  CHECK(dmax <= 1e-12 * dref, "d_el differs from the convolution by %.3e rel", dmax / dref);
  double del_fft[100];
  memcpy(del_fft, s.d_el, sizeof del_fft);
  blk_state_free(&s);

  /* 3. the same run with the direct history sum: FFT vs direct */
  m.solver.history = BLK_HIST_DIRECT;
  run(&m, NF, 1e-4, Ft_dir, Fh_dir, &s);
  double fd = 0, dd = 0;
  for (int n = 0; n < NF * m.M; n++) fd = fmax(fd, fabs(Fh_fft[n] - Fh_dir[n]));
  for (int e = 0; e < m.M; e++) dd = fmax(dd, fabs(del_fft[e] - s.d_el[e]));
  const double fref = max_abs(Fh_dir, NF * m.M);
  printf("FFT vs direct: element forces rel %.2e, d_el rel %.2e\n", fd / fref, dd / dref);
  CHECK(fd <= 1e-10 * fref, "FFT/direct force mismatch %.2e rel", fd / fref);
  CHECK(dd <= 1e-10 * dref, "FFT/direct d_el mismatch %.2e rel", dd / dref);
  blk_state_free(&s);

  /* 4. chord steps (solver.reuse_jacobian) reach the same solution */
  static double Ft_chord[NF];
  m.solver.history = BLK_HIST_FFT;
  m.solver.method = BLK_NR_PLAIN;
  run(&m, NF, 1e-4, Ft_dir, NULL, &s);
  blk_state_free(&s);
  m.solver.reuse_jacobian = 1;
  run(&m, NF, 1e-4, Ft_chord, NULL, &s);
  double cd = 0;
  for (int n = 0; n < NF; n++) cd = fmax(cd, fabs(Ft_chord[n] - Ft_dir[n]));
  printf("chord vs full Newton: max force difference %.2e N of %.2e N\n", cd,
         max_abs(Ft_dir, NF));
  CHECK(cd <= 1e-8 * max_abs(Ft_dir, NF), "chord steps differ by %.2e N", cd);
  blk_state_free(&s);
  blk_model_free(&m);
  return cosim_test_done("test_block_dynamics");
}
