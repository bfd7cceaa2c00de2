/* The rigid-wheel model (terra/ter_wheel.c) against
 *  - the regression values of docs/terramechanics.md §1 (dry sand, r = 0.3 m, b = 0.15 m,
 *    W = 1 kN, K = 25 mm, c1 = 0.43, c2 = 0.32): z = 65.8 / 72.6 mm at
 *    s = 0 / 0.4, DP = -107.8, -21.0, +28.2, +67.2 N at s = 0, 0.1, 0.2, 0.4,
 *    F_t = 205 N and R = 313 N at s = 0, Bekker z0 = 52.1 mm, R_c = 362 N;
 *  - a brute-force midpoint rule with 800 points (another quadrature);
 *  - closed forms that do not use the routine: with no shear (phi = c = 0)
 *    and theta_m = 0 the rim stresses are plate pressure under the rim, so
 *    R = b (k_c/b + k_phi) z^(n+1)/(n+1) exactly at any sinkage, and for
 *    small sinkage W = b k_eq sqrt(2 r) z^(n+1/2) Int_0^1 (1 - t^2)^n dt,
 *    Int = sqrt(pi) Gamma(n+1) / (2 Gamma(n+3/2)) (= 2/3 at n = 1, where
 *    Bekker's z0 is exact);
 *  - bad input (slip, load, immobilised wheel). */
#include "cosim_test.h"
#include "terra/terra.h"

static ter_soil dry_sand(void) {
  ter_soil p;
  ter_soil_defaults(&p);
  p.n = 1.1;
  p.k_c = 0.99e3;
  p.k_phi = 1528.4e3;
  p.c = 1.04e3;
  p.phi = 28 * M_PI / 180;
  p.K = 0.025;
  return p;
}

static void regression(void) {
  proto_err err;
  ter_soil p = dry_sand();
  ter_wheel w = {0.3, 0.15};
  const double slip[4] = {0, 0.1, 0.2, 0.4}, dp_ref[4] = {-107.8, -21.0, 28.2, 67.2};
  ter_forces f[4];
  for (int i = 0; i < 4; i++) {
    OK(ter_solve(&w, &p, 1000, slip[i], &f[i], &err));
    printf("s = %.1f: z = %.2f mm, W = %.6g N, F_t = %.2f N, R = %.2f N, DP = %.2f N, T = %.2f N m, "
           "eff %.3f\n", slip[i], 1e3 * f[i].z, f[i].W, f[i].Ft, f[i].R, f[i].DP, f[i].T, f[i].eff);
    CHECK(fabs(f[i].W - 1000) < 1e-6, "load not met: %.9g", f[i].W);
    CHECK(fabs(f[i].DP - dp_ref[i]) < 0.06, "DP(%.1f) = %.3f N, reference %.1f N", slip[i], f[i].DP, dp_ref[i]);
    /* brute-force midpoint rule at the same sinkage */
    ter_forces m;
    ter_wheel_forces(&w, &p, f[i].z, slip[i], 800, &m);
    double e = fmax(fmax(fabs(m.W - f[i].W), fabs(m.Ft - f[i].Ft)), fmax(fabs(m.R - f[i].R), fabs(m.T / w.r - f[i].T / w.r)));
    CHECK(e < 1e-5 * f[i].W, "Gauss-Legendre and 800-point midpoint differ by %.3e N", e);
  }
  CHECK(fabs(1e3 * f[0].z - 65.8) < 0.05 && fabs(1e3 * f[3].z - 72.6) < 0.05, "sinkage %.3f / %.3f mm",
        1e3 * f[0].z, 1e3 * f[3].z);
  CHECK(fabs(f[0].Ft - 205) < 0.5 && fabs(f[0].R - 313) < 0.5, "F_t %.2f, R %.2f at s = 0", f[0].Ft, f[0].R);
  CHECK(f[0].Ft > 0, "the driven-wheel model gives thrust at zero slip (docs/terramechanics.md §4)");
  double z0 = ter_bekker_z0(&w, &p, 1000), Rc = ter_compaction_resistance(&w, &p, f[0].z);
  printf("Bekker z0 = %.2f mm, R_c(z) = %.1f N\n", 1e3 * z0, Rc);
  CHECK(fabs(1e3 * z0 - 52.1) < 0.05 && fabs(Rc - 362) < 0.5, "z0 %.3f mm, R_c %.2f N", 1e3 * z0, Rc);
  /* self-propelled point: DP = 0 near s = 0.14 */
  double lo = 0.1, hi = 0.2;
  for (int it = 0; it < 40; it++) {
    ter_forces g;
    OK(ter_solve(&w, &p, 1000, 0.5 * (lo + hi), &g, &err));
    if (g.DP < 0) lo = 0.5 * (lo + hi);
    else hi = 0.5 * (lo + hi);
  }
  printf("DP = 0 at s = %.4f\n", lo);
  CHECK(fabs(lo - 0.14) < 0.005, "zero crossing at %.4f", lo);
}

static void closed_forms(void) {
  proto_err err;
  ter_wheel w = {0.3, 0.15};
  const double ns[3] = {0.7, 1.0, 1.3};
  for (int k = 0; k < 3; k++) {
    ter_soil p = dry_sand();
    p.n = ns[k];
    p.c = 0;
    p.phi = 0;
    p.c1 = p.c2 = 0;
    const double keq = p.k_c / w.b + p.k_phi;
    const double In = sqrt(M_PI) * tgamma(p.n + 1) / (2 * tgamma(p.n + 1.5));
    /* compaction resistance, exact at any sinkage */
    for (double z = 0.005; z < 0.2; z *= 2.5) {
      ter_forces g, m;
      ter_wheel_forces(&w, &p, z, 0.2, 0, &g);
      ter_wheel_forces(&w, &p, z, 0.2, 800, &m);
      double Rc = ter_compaction_resistance(&w, &p, z);
      CHECK(fabs(g.R / Rc - 1) < 1e-4 && fabs(m.R / Rc - 1) < 1e-4,
            "n %.1f z %.3f: R %.6g (GL) %.6g (midpoint) vs R_c %.6g", p.n, z, g.R, m.R, Rc);
      CHECK(g.Ft == 0 && g.T == 0, "shear without friction or cohesion");
    }
    /* small sinkage: the load of a shallow rim, error O(z/r) */
    double prev = 1;
    for (double W = 100; W >= 0.01; W /= 10) {
      ter_forces g;
      OK(ter_solve(&w, &p, W, 0, &g, &err));
      double z_small = pow(W / (w.b * keq * sqrt(2 * w.r) * In), 1 / (p.n + 0.5));
      double e = fabs(g.z / z_small - 1);
      if (W == 0.01) {
        printf("n = %.1f: W = %g N, z = %.4g mm, small-sinkage limit %.4g mm (rel. %.1e), Bekker z0 "
               "%.4g mm\n", p.n, W, 1e3 * g.z, 1e3 * z_small, e, 1e3 * ter_bekker_z0(&w, &p, W));
        CHECK(e < 1e-3, "n %.1f: small-sinkage limit off by %.2e", p.n, e);
        if (p.n == 1.0)
          CHECK(fabs(ter_bekker_z0(&w, &p, W) / g.z - 1) < 1e-3, "Bekker z0 at n = 1 should be the limit");
      }
      CHECK(e < prev, "n %.1f: small-sinkage error does not shrink with the load (%.2e -> %.2e)", p.n, prev, e);
      prev = e;
    }
  }
}

static void monotone_and_errors(void) {
  proto_err err;
  ter_soil p = dry_sand();
  ter_wheel w = {0.272, 0.165};
  for (double s = 0; s < 0.95; s += 0.15) {
    double last = 0;
    for (int i = 1; i <= 200; i++) {
      ter_forces g;
      ter_wheel_forces(&w, &p, 0.9 * w.r * i / 200, s, 0, &g);
      CHECK(g.W > last, "W(z) not increasing at s %.2f, z %.4f", s, g.z);
      last = g.W;
    }
  }
  ter_forces f;
  FAILS_WITH(ter_solve(&w, &p, 500, -0.1, &f, &err), "0 <= s < 1");
  FAILS_WITH(ter_solve(&w, &p, -5, 0.1, &f, &err), "load");
  FAILS_WITH(ter_solve(&w, &p, 1e9, 0.1, &f, &err), "immobilised");
  ter_soil bad = p;
  bad.K = 0;
  FAILS_WITH(ter_solve(&w, &bad, 500, 0.1, &f, &err), "soil.K");
  /* JSON round trip and a typo */
  cJSON *o = cJSON_CreateObject();
  CHECK(ter_soil_write(o, &p) == 0, "write");
  ter_soil q;
  OK(ter_soil_read(o, "params", &q, &err));
  CHECK(fabs(q.phi - p.phi) < 1e-15 && q.k_phi == p.k_phi && q.K == p.K, "JSON round trip");
  cJSON_AddNumberToObject(o, "kphi", 1);
  FAILS_WITH(ter_soil_read(o, "params", &q, &err), "params.kphi");
  cJSON_Delete(o);
}

int main(void) {
  regression();
  closed_forms();
  monotone_and_errors();
  return cosim_test_done("test_ter_wheel");
}
