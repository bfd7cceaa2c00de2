/* The soil-parameter fits (terra/ter_fit.c) and the test records
 * (terra/ter_io.c) on synthetic data with known parameters:
 *  - three plates p = (k_c/b + k_phi) z^n with 2 % multiplicative noise:
 *    n, k_c, k_phi recovered; a plate of another n shows in its own n;
 *  - tau(j) = tau_f (1 - exp(-j/K)) with noise: tau_f and K recovered;
 *  - a line fit with its standard errors;
 *  - CSV round trip, malformed records named by file and line. */
#include "cosim_test.h"
#include "terra/terra.h"

#include <unistd.h>

/* deterministic noise in [-1, 1] */
static double noise(uint64_t *s) {
  *s = *s * 6364136223846793005ULL + 1442695040888963407ULL;
  return (double)(*s >> 11) / 4503599627370496.0 - 1.0;
}

static void plates(void) {
  proto_err err;
  const double n = 0.85, k_c = -2.0e4, k_phi = 9.0e5, b[3] = {0.06, 0.11, 0.165};
  static const char *const cols[] = {"z", "p"};
  ter_series t[3];
  const ter_series *tp[3];
  uint64_t seed = 7;
  for (int i = 0; i < 3; i++) {
    OK(ter_series_init(&t[i], 2, cols, &err));
    for (int k = 1; k <= 80; k++) {
      double z = 0.5e-3 * k, p = (k_c / b[i] + k_phi) * pow(z, n) * (1 + 0.02 * noise(&seed));
      OK(ter_series_add(&t[i], (double[2]){z, p}, &err));
    }
    tp[i] = &t[i];
  }
  ter_plate_fit f;
  OK(ter_fit_plates(3, b, tp, "z", "p", 0.005, 0.04, &f, &err));
  printf("plates: n %.4f (true %.2f), k_c %.4g (%.3g), k_phi %.5g (%.3g), rms ln p %.3g\n", f.n, n,
         f.k_c, k_c, f.k_phi, k_phi, f.rms_log);
  CHECK(fabs(f.n - n) < 0.01, "n %.4f", f.n);
  CHECK(fabs(f.k_phi / k_phi - 1) < 0.05 && fabs(f.k_c / k_c - 1) < 0.3, "k_c %.4g k_phi %.4g", f.k_c, f.k_phi);
  for (int i = 0; i < 3; i++) {
    double keq = k_c / b[i] + k_phi;
    CHECK(fabs(f.k_eq[i] / keq - 1) < 0.03 && fabs(f.n_own[i] - n) < 0.02, "plate %d: k_eq %.4g (%.4g), n %.3f",
          i, f.k_eq[i], keq, f.n_own[i]);
    CHECK(f.points[i] == 71, "plate %d: %d points in the range", i, f.points[i]);
  }
  /* a plate that does not follow the same n is seen in its own exponent */
  for (int k = 0; k < t[2].n; k++) t[2].row[2 * k + 1] = 5e5 * pow(t[2].row[2 * k], 1.3);
  OK(ter_fit_plates(3, b, tp, "z", "p", 0.005, 0.04, &f, &err));
  CHECK(fabs(f.n_own[2] - 1.3) < 1e-9 && f.rms_log > 0.05, "own n %.4f, rms %.3g", f.n_own[2], f.rms_log);
  FAILS_WITH(ter_fit_plates(3, b, tp, "z", "pressure", 0.005, 0.04, &f, &err), "pressure");
  FAILS_WITH(ter_fit_plates(1, b, tp, "z", "p", 0.005, 0.04, &f, &err), "plates");
  FAILS_WITH(ter_fit_plates(3, b, tp, "z", "p", 1, 2, &f, &err), "points");
  const double same[3] = {0.1, 0.1, 0.2};
  FAILS_WITH(ter_fit_plates(3, same, tp, "z", "p", 0.005, 0.04, &f, &err), "same width");
  for (int i = 0; i < 3; i++) ter_series_free(&t[i]);
}

static void shear(void) {
  proto_err err;
  const double tau_f = 3.2e3, K = 4e-3;
  double j[120], tau[120], tf, Kf, rms;
  uint64_t seed = 3;
  for (int k = 0; k < 120; k++) {
    j[k] = 0.25e-3 * (k + 0.5);
    tau[k] = tau_f * (1 - exp(-j[k] / K)) + 40 * noise(&seed);
  }
  OK(ter_fit_janosi(120, j, tau, INFINITY, &tf, &Kf, &rms, &err));
  printf("Janosi: tau_f %.1f (%.0f), K %.3f mm (%.1f), rms %.1f Pa\n", tf, tau_f, 1e3 * Kf, 1e3 * K, rms);
  CHECK(fabs(tf / tau_f - 1) < 0.01 && fabs(Kf / K - 1) < 0.03 && rms < 40, "tau_f %.1f K %.4g", tf, Kf);
  /* the tangent at the origin reaches tau_f at j = K: the early branch alone gives the same K */
  OK(ter_fit_janosi(120, j, tau, 3 * K, &tf, &Kf, &rms, &err));
  CHECK(fabs(Kf / K - 1) < 0.1, "K from j <= 3K: %.4g", Kf);
  FAILS_WITH(ter_fit_janosi(120, j, tau, 1e-5, &tf, &Kf, &rms, &err), "points");
  double flat[120];
  for (int k = 0; k < 120; k++) flat[k] = 0;
  FAILS_WITH(ter_fit_janosi(120, j, flat, INFINITY, &tf, &Kf, &rms, &err), "search range");
}

static void line(void) {
  proto_err err;
  const double x[5] = {2.5e3, 5e3, 10e3, 20e3, 40e3};
  double y[5], a, b, sa, sb;
  for (int i = 0; i < 5; i++) y[i] = 150 + 0.5 * x[i] + (i % 2 ? 30 : -30);
  OK(ter_fit_line(5, x, y, &a, &b, &sa, &sb, &err));
  CHECK(fabs(b - 0.5) < 0.01 && fabs(a - 150) < 60 && sa > 0 && sb > 0, "a %.3g b %.4g", a, b);
  const double same[2] = {1, 1};
  FAILS_WITH(ter_fit_line(2, same, y, &a, &b, NULL, NULL, &err), "same x");
}

static void records(void) {
  proto_err err;
  char path[64];
  snprintf(path, sizeof path, "/tmp/test_ter_fit_%d.csv", (int)getpid());
  static const char *const cols[] = {"j", "tau"};
  ter_series t, r;
  OK(ter_series_init(&t, 2, cols, &err));
  ter_series_meta(&t, "sigma_n_Pa", "%g", 5e3);
  for (int k = 0; k < 10; k++) OK(ter_series_add(&t, (double[2]){0.1 * k, sin(k) / 3}, &err));
  OK(ter_series_write(&t, path, &err));
  OK(ter_series_read(&r, path, &err));
  double sig = 0;
  OK(ter_series_meta_num(&r, "sigma_n_Pa", &sig, &err));
  CHECK(r.n == 10 && r.ncol == 2 && ter_series_col(&r, "tau") == 1 && sig == 5e3, "round trip");
  double maxe = 0;
  for (int k = 0; k < 20; k++) maxe = fmax(maxe, fabs(r.row[k] - t.row[k]));
  CHECK(maxe < 1e-9, "values differ by %.3g", maxe);
  FAILS_WITH(ter_series_meta_num(&r, "width_m", &sig, &err), "width_m");
  ter_series_free(&r);
  FILE *f = fopen(path, "w");
  fputs("# test: shear\nj,tau\n0.1,2\n0.2,x\n", f);
  fclose(f);
  FAILS_WITH(ter_series_read(&r, path, &err), ":4: column 'tau'");
  f = fopen(path, "w");
  fputs("j,tau\n0.1,2,3\n", f);
  fclose(f);
  FAILS_WITH(ter_series_read(&r, path, &err), "3 values");
  unlink(path);
  FAILS_WITH(ter_series_read(&r, path, &err), "cannot open");
  ter_series_free(&t);
}

int main(void) {
  plates();
  shear();
  line();
  records();
  return cosim_test_done("test_ter_fit");
}
