/* Bonded layer: kernel limits, the 4x4 dynamic system against the static
 * formula / half-space / 1-D column, and the static influence coefficients
 * between the half-space (thick) and Winkler (thin) limits. */
#include <complex.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cosim_test.h"
#include "green/green.h"

int main(void) {
  const double E = 3e6, nu = 0.45, h = 0.01, rho = 1100;
  const double Es = E / (1 - nu * nu);
  /* kernel: half-space at qh >> 1, incompressible thin film 3G/(q²h³) */
  CHECK_REL("k(qh=30) = E*q/2", grn_layer_stiffness(3000, h, E, nu), Es * 3000 / 2, 1e-9);
  {
    double G = E / 3, q = 0.01 / h; /* nu = 0.5 exactly */
    CHECK_REL("k(qh=0.01, nu=.5) = 3G/(q²h³)",
              grn_layer_stiffness(q, h, E, 0.5), 3 * G / (q * q * h * h * h), 2e-4);
  }
  CHECK_REL("k(0) = M/h", grn_layer_stiffness(1e-4, h, E, nu),
            E * (1 - nu) / ((1 + nu) * (1 - 2 * nu) * h), 1e-6);
  /* dynamic system: static limit, half-space, 1-D column */
  const double mu = E / (2 * (1 + nu)), lam = 2 * mu * nu / (1 - 2 * nu);
  double Hr, Hi, worst = 0;
  for (double qh = 0.3; qh < 25; qh *= 2.2) {
    double q = qh / h;
    grn_layer_dynamic(q, 2 * M_PI * 2, h, rho, mu, 0, lam, 0, &Hr, &Hi);
    worst = fmax(worst, fabs(Hr * grn_layer_stiffness(q, h, E, nu) - 1));
  }
  printf("dynamic at 2 Hz vs static kernel: worst rel %.2e\n", worst);
  CHECK(worst < 1e-5, "low-frequency limit %.3e", worst);
  {
    double q = 300, w = 2 * M_PI * 300; /* half-space: Rayleigh function */
    double complex ks2 = rho * w * w / mu, kp2 = rho * w * w / (lam + 2 * mu);
    double complex a = csqrt(q * q - kp2), b = csqrt(q * q - ks2);
    double complex R = (2 * q * q - ks2) * (2 * q * q - ks2) - 4 * q * q * a * b;
    double complex Hhs = -a * ks2 / (mu * R);
    grn_layer_dynamic(q, w, 1.0, rho, mu, 0, lam, 0, &Hr, &Hi);
    CHECK_REL("thick layer = Rayleigh half-space", Hr, creal(Hhs), 1e-9);
  }
  {
    double w = 2 * M_PI * 500, M = lam + 2 * mu, kp = w / sqrt(M / rho);
    grn_layer_dynamic(0.0, w, h, rho, mu, 0, lam, 0, &Hr, &Hi);
    CHECK_REL("q = 0: tan(k_p h)/(M k_p)", Hr, tan(kp * h) / (M * kp), 1e-10);
  }
  /* static influence coefficients */
  grn_grid g = {4, 4, 1e-3, 1e-3};
  int nk = (2 * g.nx - 1) * (2 * g.ny - 1), c0 = (g.ny - 1) * (2 * g.nx - 1) + g.nx - 1;
  double *CL = malloc(nk * sizeof *CL), *C = malloc(nk * sizeof *C);
  proto_err err;
  grn_static_love(&g, E, nu, CL);
  double prev = 1;
  for (double hh = 0.01; hh <= 0.081; hh *= 2) {
    CHECK(grn_static_layer(&g, hh, E, nu, 0, C, &err) == 0, "%s", err.msg);
    double dself = fabs(C[c0] - CL[c0]) / CL[c0];
    /* relative shape: differences C(0) - C(r) remove the layer's constant */
    double dshape = fabs((C[c0] - C[c0 + 3]) - (CL[c0] - CL[c0 + 3])) / (CL[c0] - CL[c0 + 3]);
    printf("h = %5.3f m: self %.6e vs Love %.6e (rel %.2e), shape rel %.2e\n", hh,
           C[c0], CL[c0], dself, dshape);
    CHECK(dself < prev, "self deviation must shrink with h");
    CHECK(C[c0] < CL[c0], "a bonded layer is stiffer than the half-space");
    prev = dself;
    if (hh > 0.07) {
      CHECK(dself < 0.01, "thick layer self coefficient within 1%% of Love: %.3e", dself);
      CHECK(dshape < 1e-3, "thick layer shape within 0.1%% of Love: %.3e", dshape);
    }
  }
  /* thin compressible layer: Winkler, u = p h / M locally */
  {
    double ht = 2e-5, M = E * (1 - nu) / ((1 + nu) * (1 - 2 * nu));
    CHECK(grn_static_layer(&g, ht, E, nu, 0, C, &err) == 0, "%s", err.msg);
    CHECK_REL("thin layer self = h/(M A)", C[c0], ht / (M * g.dx * g.dy), 2e-3);
    CHECK(fabs(C[c0 + 1]) < 1e-3 * C[c0], "thin layer neighbour %.3e", C[c0 + 1] / C[c0]);
    /* symmetry */
    CHECK(fabs(C[c0 + 1] - C[c0 - 1]) <= 1e-12 * C[c0], "symmetry");
  }
  /* errors */
  CHECK(grn_static_layer(&g, -1e-3, E, nu, 0, C, &err) == -1 &&
            strstr(err.msg, "thickness"), "non-positive thickness error: %s", err.msg);
  printf("error message: %s\n", err.msg);
  free(CL);
  free(C);
  return cosim_test_done("test_green_layer");
}
