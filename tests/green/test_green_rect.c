/* Rectangular elements (dx ≠ dy) and the periodic half-space (issue 14):
 *  - the bonded layer's static coefficients of 1.5 × 0.5 mm elements equal
 *    those of three 0.5 mm squares side by side (superposition), and are even;
 *  - the periodic half-space kernel is even, has zero mean, and its
 *    near-field differences K(Δ) − K(Δ') equal Love's when the period is
 *    long (the images only add a smooth, nearly uniform field);
 *  - it is periodic in the offset layout: K(Δ) = K(Δ − n). */
#include <math.h>
#include <stdlib.h>

#include "cosim_test.h"
#include "green/green.h"

/* The bonded layer with 1.5 × 0.5 mm elements against the same layer with
 * 0.5 mm squares: a rectangle is three squares side by side, so its
 * coefficient at offset (Δi, Δj) is the mean over the three source squares of
 * the square coefficient at the target's middle square (superposition, exact).
 * Different element shapes, boxes and alias shells in layer.c: an
 * independent route. */
static double layer_rect_vs_squares(double h, double E, double nu, proto_err *err) {
  const grn_grid r = {4, 3, 1.5e-3, 0.5e-3}, q = {12, 3, 0.5e-3, 0.5e-3};
  const int rx = 2 * r.nx - 1, ry = 2 * r.ny - 1, qx = 2 * q.nx - 1, qy = 2 * q.ny - 1;
  double *R = malloc(sizeof(double) * rx * ry), *Q = malloc(sizeof(double) * qx * qy);
  if (grn_static_layer(&r, h, E, nu, 0, R, err) || grn_static_layer(&q, h, E, nu, 0, Q, err))
    return 1;
  double worst = 0;
  const double self = R[(r.ny - 1) * rx + r.nx - 1];
  for (int dj = -(r.ny - 1); dj < r.ny; dj++)
    for (int di = -(r.nx - 1); di < r.nx; di++) {
      double s = 0;
      for (int k = -1; k <= 1; k++) s += Q[(dj + q.ny - 1) * qx + 3 * di + k + q.nx - 1] / 3;
      worst = fmax(worst, fabs(R[(dj + r.ny - 1) * rx + di + r.nx - 1] - s) / self);
    }
  free(R);
  free(Q);
  return worst;
}

int main(void) {
  const double E = 10e6, nu = 0.3;
  proto_err err = {{0}};
  /* 1. rectangular layer elements against squares; the kernel's symmetry */
  const double wr = layer_rect_vs_squares(0.01, E, nu, &err);
  printf("layer h = 10 mm, 1.5 x 0.5 mm elements vs three 0.5 mm squares: worst %.2e of the "
         "self term\n", wr);
  CHECK(wr < 1e-4, "rectangular layer elements differ from squares by %.2e (%s)", wr, err.msg);
  const grn_grid g = {6, 4, 1.5e-3, 1e-3};
  const int wx = 2 * g.nx - 1, wy = 2 * g.ny - 1, nk = wx * wy;
  double *C = malloc(sizeof(double) * nk);
  CHECK(grn_static_layer(&g, 0.01, E, nu, 0, C, &err) == 0, "layer: %s", err.msg);
  /* symmetric in ±Δi and ±Δj separately */
  double asym = 0;
  for (int dj = 0; dj < wy; dj++)
    for (int di = 0; di < wx; di++)
      asym = fmax(asym, fabs(C[dj * wx + di] - C[dj * wx + (wx - 1 - di)]) +
                            fabs(C[dj * wx + di] - C[(wy - 1 - dj) * wx + di]));
  CHECK(asym < 1e-12 * C[(g.ny - 1) * wx + g.nx - 1], "layer kernel not even: %.2e", asym);
  free(C);
  /* 2. periodic half-space, long period, rectangular elements */
  const grn_grid p = {48, 32, 1.5e-3, 1e-3};
  const int px = 2 * p.nx - 1, py = 2 * p.ny - 1;
  double *K = malloc(sizeof(double) * px * py);
  CHECK(grn_static_love_periodic(&p, E, nu, K, &err) == 0, "periodic: %s", err.msg);
  double mean = 0, per = 0, even = 0;
  for (int j = 0; j < p.ny; j++)
    for (int i = 0; i < p.nx; i++) mean += K[(j + p.ny - 1) * px + i + p.nx - 1];
  mean /= p.nx * p.ny;
  for (int dj = -(p.ny - 1); dj < p.ny; dj++)
    for (int di = -(p.nx - 1); di < p.nx; di++) {
      const double k = K[(dj + p.ny - 1) * px + di + p.nx - 1];
      even = fmax(even, fabs(k - K[(-dj + p.ny - 1) * px - di + p.nx - 1]));
      if (di > 0) per = fmax(per, fabs(k - K[(dj + p.ny - 1) * px + di - p.nx + p.nx - 1]));
    }
  const double self = K[(p.ny - 1) * px + p.nx - 1];
  printf("periodic: mean %.2e, asymmetry %.2e, K(d) - K(d - n) %.2e (of the self term %.4e)\n",
         mean / self, even / self, per / self, self);
  CHECK(fabs(mean) < 1e-12 * self && even < 1e-12 * self && per < 1e-12 * self,
        "periodic kernel: mean %g, asymmetry %g, periodicity %g", mean, even, per);
  const int near[4][2] = {{0, 0}, {1, 0}, {0, 1}, {3, 2}};
  for (int k = 1; k < 4; k++) {
    const double dk = self - K[(near[k][1] + p.ny - 1) * px + near[k][0] + p.nx - 1];
    const double dl = grn_love_compliance(0, 0, 0.5 * p.dx, 0.5 * p.dy, E, nu) -
                      grn_love_compliance(near[k][0] * p.dx, near[k][1] * p.dy, 0.5 * p.dx,
                                          0.5 * p.dy, E, nu);
    char what[64];
    snprintf(what, sizeof what, "periodic K(0) - K(%d,%d) vs Love", near[k][0], near[k][1]);
    CHECK_REL(what, dk, dl, 2e-4);
  }
  free(K);
  return cosim_test_done("test_green_rect");
}
