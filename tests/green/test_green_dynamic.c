/* Dynamic layer Green's functions: the 1-D column (q = 0) against the exact
 * bouncing wave (period 4h/c_p), and the time sums against the static
 * influence coefficients (within 1 %). */
#include <complex.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cosim_test.h"
#include "green/green.h"

static void one_dimensional(void) {
  /* compressible column so that 4h/c_p spans many samples */
  const double E = 25e6, nu = 0.3, rho = 1300, h = 0.01, eta = 0.004;
  const double mu = E / (2 * (1 + nu)), lam = 2 * mu * nu / (1 - 2 * nu);
  const double M = lam + 2 * mu, cp = sqrt(M / rho), T = 4 * h / cp;
  const double rate = 64 / T; /* 64 samples per period */
  const int Q = 256, over = 4, pf = 8, K = over * Q * pf, nf = K + 1;
  const double df = over * rate / (2.0 * K);
  double *re = malloc(nf * sizeof *re), *im = malloc(nf * sizeof *im);
  double *zoh = malloc(Q * sizeof *zoh), *pt = malloc(Q * sizeof *pt);
  for (int k = 0; k < nf; k++) {
    double w = 2 * M_PI * k * df, Hr, Hi;
    if (k == 0) {
      Hr = h / M;
      Hi = 0;
    } else {
      double complex m = mu * (1 + I * eta), l = lam * (1 + I * eta);
      grn_layer_dynamic(0.0, w, h, rho, creal(m), cimag(m), creal(l), cimag(l), &Hr, &Hi);
    }
    re[k] = Hr;
    im[k] = Hi;
  }
  proto_err err;
  CHECK(grn_causal_response(nf, df, re, im, 1 / rate, Q, zoh, pt, &err) == 0, "%s", err.msg);
  /* step response S(t_{k+1}) = dt Σ zoh: undamped it is a triangle wave
   * 0 -> 2h/M at T/2 -> 0 at T (the 1-D column, q = 0: a P wave
   * reflected between the free top and the rigid base, T = 2h/c_P) */
  double S = 0, worst = 0, smax = 0;
  int kmax = 0;
  for (int k = 0; k < 64; k++) {
    S += zoh[k] / rate;
    double t = (k + 1) / rate, ph = fmod(t, T) / T;
    double tri = 2 * h / M * (ph < 0.5 ? 2 * ph : 2 - 2 * ph);
    worst = fmax(worst, fabs(S - tri));
    if (S > smax) { smax = S; kmax = k; }
  }
  printf("1-D column: c_p = %.1f m/s, 4h/c_p = %.3e s; step-response peak at "
         "%.3e s (expect %.3e), worst |S - triangle| = %.3f of 2h/M\n",
         cp, T, (kmax + 1) / rate, T / 2, worst / (2 * h / M));
  CHECK(fabs((kmax + 1) / rate - T / 2) <= 1.01 / rate, "peak time");
  CHECK(worst < 0.05 * 2 * h / M, "triangle wave within 5%%: %.3f", worst / (2 * h / M));
  /* the first impulse-response samples: +1/(ρ c_p) before the first echo */
  CHECK_REL("g = 1/(rho c_p) before the echo", zoh[8], 1 / (rho * cp), 0.08);
  /* period from the zero crossings of the impulse response (sign changes) */
  int first = -1, second = -1;
  for (int k = 1; k < Q; k++)
    if (zoh[k - 1] > 0 && zoh[k] <= 0) { if (first < 0) first = k; else if (second < 0) second = k; }
  CHECK_REL("bounce period 4h/c_p", (second - first) / rate, T, 0.02);
  free(re); free(im); free(zoh); free(pt);
}

static void time_sums(void) {
  /* tread-like layer (appendix B modulus and density) with a loss factor
   * rising from 0 at DC (a causal material has no loss at DC; a constant
   * hysteretic eta puts a step of eta² into Re ĝ at ω = 0) to 0.15 */
  grn_material mat;
  grn_material_default(&mat);
  mat.n = 3;
  const double f[3] = {0, 2000, 1e5}, eta[3] = {0, 0.15, 0.15};
  for (int i = 0; i < 3; i++) { mat.f[i] = f[i]; mat.E[i] = 25e6; mat.eta[i] = eta[i]; }
  const double h = 0.01;
  grn_grid g = {4, 4, 1e-3, 1e-3};
  grn_dyn_opts o;
  grn_dyn_opts_default(&o);
  o.Q = 256;
  o.oversample = 2;
  o.period_factor = 2;
  o.pad = 24;
  const int nk = (2 * g.nx - 1) * (2 * g.ny - 1), c0 = (g.ny - 1) * (2 * g.nx - 1) + g.nx - 1;
  double *gz = malloc((size_t)o.Q * nk * sizeof *gz), *gp = malloc((size_t)o.Q * nk * sizeof *gp);
  double *st = malloc(nk * sizeof *st), *ref = malloc(nk * sizeof *ref);
  proto_err err;
  CHECK(grn_dynamic(&g, &mat, h, &o, gz, gp, st, &err) == 0, "%s", err.msg);
  CHECK(grn_static_layer(&g, h, mat.E[0], mat.nu, o.pad, ref, &err) == 0, "%s", err.msg);
  CHECK_REL("dynamic DC = static layer (self)", st[c0], ref[c0], 1e-9);
  double worst = 0, worst_p = 0;
  for (int m = 0; m < nk; m++) {
    double sz = 0, sp = 0;
    for (int k = 0; k < o.Q; k++) { sz += gz[(size_t)k * nk + m] / o.rate; sp += gp[(size_t)k * nk + m] / o.rate; }
    worst = fmax(worst, fabs(sz - st[m]) / st[c0]);
    worst_p = fmax(worst_p, fabs(sp - st[m]) / st[c0]);
  }
  printf("time sum vs static: zoh worst %.2e, point worst %.2e (of the self coefficient)\n",
         worst, worst_p);
  printf("self g_zoh[0..5] = %.4g %.4g %.4g %.4g %.4g %.4g m/(N s)\n", gz[c0],
         gz[nk + c0], gz[2 * nk + c0], gz[3 * nk + c0], gz[4 * nk + c0], gz[5 * nk + c0]);
  printf("self g_pt [0..5] = %.4g %.4g %.4g %.4g %.4g %.4g m/(N s)\n", gp[c0],
         gp[nk + c0], gp[2 * nk + c0], gp[3 * nk + c0], gp[4 * nk + c0], gp[5 * nk + c0]);
  CHECK(worst < 0.01, "zoh time sum within 1%%: %.3e", worst);
  /* reciprocity / symmetry of the offsets */
  CHECK(gz[c0 + 1] == gz[c0 - 1], "symmetry");
  /* bad input: loss-factor table out of order */
  mat.f[2] = 5;
  CHECK(grn_dynamic(&g, &mat, h, &o, gz, NULL, NULL, &err) == -1 && strstr(err.msg, "f[2]"),
        "out-of-order table error: %s", err.msg);
  printf("error message: %s\n", err.msg);
  grn_material_default(&mat);
  CHECK(grn_dynamic(&g, &mat, 0.0, &o, gz, NULL, NULL, &err) == -1 && strstr(err.msg, "thickness"),
        "thickness error: %s", err.msg);
  printf("error message: %s\n", err.msg);
  free(gz); free(gp); free(st); free(ref);
}

int main(void) {
  one_dimensional();
  time_sums();
  return cosim_test_done("test_green_dynamic");
}
