/* Flat punch on a bonded incompressible film: half-space limit 2E*a as
 * a/h -> 0, thin-film law (3π/8) G a⁴/h³ as a/h -> ∞; roughness springs from
 * a paraboloid against the closed form; monotone C¹ Hermite and the
 * monotone 10th-order polynomial. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "cosim_test.h"
#include "green/green.h"

int main(void) {
  proto_err err;
  double phi, phi2;
  /* half-space limit */
  CHECK(grn_punch_solve(1e-3, 0.5, 0, &phi, &err) == 0, "%s", err.msg);
  CHECK_REL("a/h = 1e-3: K/(2E*a)", phi, 1.0, 2e-3);
  /* Nyström convergence at a moderate ratio */
  CHECK(grn_punch_solve(3.0, 0.5, 150, &phi, &err) == 0, "%s", err.msg);
  CHECK(grn_punch_solve(3.0, 0.5, 300, &phi2, &err) == 0, "%s", err.msg);
  CHECK_REL("a/h = 3: n = 150 vs 300", phi, phi2, 2e-3);
  /* thin film: ratio to (3π/64) λ³ (= (3π/8) G a⁴ δ / h³ over 2E*a δ with
   * E* = 4G) tends to 1 like 1 + c/λ */
  double lam[3] = {10, 20, 40}, r[3];
  for (int i = 0; i < 3; i++) {
    CHECK(grn_punch_solve(lam[i], 0.5, 0, &phi, &err) == 0, "%s", err.msg);
    r[i] = phi / (3 * M_PI / 64 * pow(lam[i], 3));
    printf("a/h = %4.0f: K/(2E*a) = %.5g, / thin-film law = %.4f\n", lam[i], phi, r[i]);
  }
  CHECK(r[0] > r[1] && r[1] > r[2] && r[2] > 1, "monotone approach to the thin-film law");
  CHECK_REL("thin-film limit (Richardson, a/h = 20, 40)",
            (lam[2] * r[2] - lam[1] * r[1]) / (lam[2] - lam[1]), 1.0, 0.02);
  /* compressible thin layer is Winkler-like, not ∝ λ³: phi/λ bounded */
  /* table interpolation */
  grn_punch_table t;
  CHECK(grn_punch_table_build(&t, 0.5, 1e-3, 20, 16, &err) == 0, "%s", err.msg);
  CHECK(grn_punch_solve(0.5, 0.5, 0, &phi, &err) == 0, "%s", err.msg);
  CHECK_REL("table interpolation at a/h = 0.5", grn_punch_phi(&t, 0.5), phi, 5e-3);
  CHECK(grn_punch_phi(&t, 100) > grn_punch_phi(&t, 20), "continuation beyond the table");

  /* roughness spring of a paraboloid z = −r²/(2R) in a thick film: patch
   * radius sqrt(2Rd), F = ∫ 2E* sqrt(2Rs) ds = (4/3) E* sqrt(2R) d^{3/2} */
  const int n = 201;
  const double ds = 5e-6, R = 0.5e-3;
  double *z = malloc(n * n * sizeof *z);
  for (int j = 0; j < n; j++)
    for (int i = 0; i < n; i++) {
      double x = (i - n / 2) * ds, y = (j - n / 2) * ds;
      z[j * n + i] = -(x * x + y * y) / (2 * R);
    }
  grn_spring_opts o;
  grn_spring_opts_default(&o);
  o.film_h = 1.0; /* a/h ~ 1e-4: half-space */
  o.d_max_frac = 0.4;
  const int nd = 65;
  double d[65], F[65], k[65], m[65];
  CHECK(grn_spring_raw(z, n, n, n, ds, ds, &t, &o, nd, d, F, k, &err) == 0, "%s", err.msg);
  double Es = o.E / (1 - o.nu * o.nu);
  CHECK_REL("paraboloid spring F(d_max)",
            F[nd - 1], 4.0 / 3 * Es * sqrt(2 * R) * pow(d[nd - 1], 1.5), 0.02);
  CHECK_REL("paraboloid spring k(d_max)", k[nd - 1], 2 * Es * sqrt(2 * R * d[nd - 1]), 0.02);
  /* thin film (thesis rule h = z_max - z_min - d) is stiffer */
  o.film_h = 0;
  double F2[65], k2[65];
  CHECK(grn_spring_raw(z, n, n, n, ds, ds, &t, &o, nd, d, F2, k2, &err) == 0, "%s", err.msg);
  CHECK(F2[nd - 1] > F[nd - 1], "film rule stiffer than the half-space");
  /* Hermite: monotone, C¹, interpolating; polynomial with dF/dd >= 0 */
  const int K = 9;
  double dk[9], Fk[9];
  for (int i = 0; i < K; i++) { dk[i] = d[i * 8]; Fk[i] = F2[i * 8]; }
  grn_pchip_slopes(K, dk, Fk, m);
  double prev = -1, eh = 0, c[11], ep = 0;
  int mono = 1, c1 = 1;
  for (int i = 0; i < nd; i++) {
    double s, v = grn_pchip_eval(K, dk, Fk, m, d[i], &s);
    if (v < prev - 1e-12 * Fk[K - 1] || s < 0) mono = 0;
    prev = v;
    eh = fmax(eh, fabs(v - F2[i]) / F2[nd - 1]);
  }
  for (int i = 1; i < K - 1; i++) { /* slopes from both sides of each knot */
    double sl, sr, e = 1e-9 * (dk[1] - dk[0]);
    grn_pchip_eval(K, dk, Fk, m, dk[i] - e, &sl);
    grn_pchip_eval(K, dk, Fk, m, dk[i] + e, &sr);
    if (fabs(sl - sr) > 1e-5 * fabs(m[i]) + 1e-9) c1 = 0;
  }
  CHECK(mono, "Hermite interpolant monotone");
  CHECK(c1, "Hermite interpolant C1 at the knots");
  CHECK(grn_polyfit_monotone(nd, d, F2, c, &err) == 0, "%s", err.msg);
  int pos = 1;
  for (int i = 0; i <= 1000; i++) {
    double s;
    grn_poly_eval(c, d[nd - 1] * i / 1000.0, &s);
    if (s < -1e-9 * k2[nd - 1]) pos = 0;
  }
  for (int i = 0; i < nd; i++) ep = fmax(ep, fabs(grn_poly_eval(c, d[i], NULL) - F2[i]) / F2[nd - 1]);
  printf("paraboloid, film rule: Hermite (9 knots) error %.2e, 10th-order poly error %.2e of F(d_max)\n", eh, ep);
  CHECK(pos, "polynomial dF/dd >= 0 on [0, d_max]");
  CHECK(eh < 0.02 && ep < 0.05, "fit errors");
  /* a perfectly flat element: finite, increasing curve (no 0/0) */
  {
    double flat[100] = {0}, fd[9], fF[9], fk[9];
    CHECK(grn_spring_raw(flat, 10, 10, 10, ds, ds, &t, &o, 9, fd, fF, fk, &err) == 0, "%s", err.msg);
    grn_pchip_limit(9, fd, fF, fk);
    CHECK(fd[8] > fd[0] && isfinite(fF[8]) && isfinite(fk[8]) && fF[8] > 0, "flat element");
  }
  /* adhesion: mirrored branch, release, re-attach on compression */
  {
    double sd[3] = {0, 1e-5, 2e-5}, sF[3] = {0, 0.4, 1.2}, sk[3];
    grn_pchip_slopes(3, sd, sF, sk);
    grn_springs sp = {0};
    sp.K = 3; sp.d = sd; sp.F = sF; sp.k = sk; sp.release_force = 0.6;
    int att = 0;
    double kk;
    CHECK(grn_spring_eval(&sp, 0, -1e-5, &att, &kk) == 0 && !att, "no tension before contact");
    CHECK_REL("compression branch", grn_spring_eval(&sp, 0, 1e-5, &att, &kk), 0.4, 1e-12);
    CHECK(att == 1, "attached after compression");
    CHECK_REL("mirrored tension", grn_spring_eval(&sp, 0, -1e-5, &att, &kk), -0.4, 1e-12);
    CHECK(att == 1 && kk > 0, "still attached below the release force");
    CHECK(grn_spring_eval(&sp, 0, -1.6e-5, &att, &kk) == 0 && att == 0, "released above 0.6 N");
    CHECK(grn_spring_eval(&sp, 0, -0.5e-5, &att, &kk) == 0 && att == 0, "stays released");
    CHECK_REL("linear beyond the last knot",
              grn_spring_eval(&sp, 0, 3e-5, &att, &kk), 1.2 + sk[2] * 1e-5, 1e-12);
    /* the signed law contact_block uses: scaled, mirrored only while held */
    const grn_spring_table tab = {3, sd, sF, sk};
    double Fs, ks, Fu, ku;
    grn_spring_force(&tab, 2.0, 1e-5, 0, &Fs, &ks);
    CHECK_REL("scaled compression", Fs, 0.8, 1e-12);
    grn_spring_force(&tab, 2.0, -1e-5, 1, &Fs, &ks);
    grn_spring_force(&tab, 2.0, -1e-5, 0, &Fu, &ku);
    CHECK(Fs == -0.8 && ks > 0 && Fu == 0 && ku == 0, "mirrored only while held");
    CHECK(grn_spring_released(-0.61, GRN_RELEASE_FORCE_DEFAULT) &&
          !grn_spring_released(-0.59, GRN_RELEASE_FORCE_DEFAULT), "release at 0.6 N");
  }
  /* the knot search on uneven knots equals bisection (every interval) */
  {
    const double kx[5] = {-1.0, -0.5, 0.1, 2.0, 7.0};
    int ok = 1;
    for (int i = 0; i < 4; i++)
      for (int j = 0; j < 4; j++) {
        const double t = kx[i] + 0.25 * j * (kx[i + 1] - kx[i]);
        ok &= grn_pchip_interval(5, kx, t) == i;
      }
    CHECK(ok, "grn_pchip_interval finds x[lo] <= t < x[lo+1]");
  }
  grn_punch_table_free(&t);
  free(z);
  return cosim_test_done("test_green_springs");
}
