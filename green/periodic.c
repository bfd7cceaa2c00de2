/* periodic.c — influence coefficients of a periodic elastic half-space
 * (element-averaged load, centre-point displacement, as love.c), for a road
 * that repeats over the block (nx·dx × ny·dy).
 *
 * The image sum of Love's kernel diverges (1/r), so the uniform mode is
 * fixed by convention: zero mean displacement per period (Stanley & Kato
 * 1997; the convention of ContactMechanics' periodic half-space). The sum is
 * split Ewald-like (as layer.c splits the half-space part off): 1/r = [1/r − 1/√(r²+c²)] +
 * 1/√(r²+c²); the short-range bracket (∝ c²/r³) is summed over the nearest
 * images in real space with love.c's closed forms, the smooth long-range
 * part in wavenumber space, 2 e^{−qc}/(E* q) × element shape, its aliases
 * decaying like e^{−2πc/dx}. */
#include <fftw3.h>
#include <math.h>
#include <stdlib.h>

#include "green/green.h"

/* Smoothing length (elements): e^{−2π·2} = 3.5e-6 per alias shell. */
#define GRN_PERIODIC_SMOOTH 2.0
/* Alias shells of the long-range part: e^{−2π·2·4} ≈ 1e-22. */
enum { GRN_PERIODIC_ALIAS = 4 };
/* Real-space images reach at least this many elements beyond the period:
 * the far images' c²/r³ remainder is nearly uniform over the period and
 * removed with the mean. */
enum { GRN_PERIODIC_REACH = 32, GRN_PERIODIC_MAX_IMAGES = 64 };

static double sinc(double x) { return fabs(x) < 1e-8 ? 1.0 - x * x / 6 : sin(x) / x; }

int grn_static_love_periodic(const grn_grid *g, double E, double nu, double *C,
                             proto_err *err) {
  if (!(E > 0) || !(nu >= 0 && nu < 0.5))
    return proto_fail(err, "periodic half-space: need E > 0 and 0 <= nu < 0.5");
  const int nx = g->nx, ny = g->ny, nqx = nx / 2 + 1;
  const double E_star = E / (1 - nu * nu), c = GRN_PERIODIC_SMOOTH * fmax(g->dx, g->dy);
  const double Lx = nx * g->dx, Ly = ny * g->dy;
  double *K = fftw_alloc_real((size_t)nx * ny);
  fftw_complex *spec = fftw_alloc_complex((size_t)ny * nqx);
  if (!K || !spec) {
    fftw_free(K);
    fftw_free(spec);
    return proto_fail(err, "periodic half-space: out of memory (%d x %d)", nx, ny);
  }
  /* long-range part per wavenumber, aliases folded, the q = 0 term left out */
  for (int j = 0; j < ny; j++)
    for (int i = 0; i < nqx; i++) {
      const int jj = j <= ny / 2 ? j : j - ny;
      double sum = 0;
      for (int gy = -GRN_PERIODIC_ALIAS; gy <= GRN_PERIODIC_ALIAS; gy++)
        for (int gx = -GRN_PERIODIC_ALIAS; gx <= GRN_PERIODIC_ALIAS; gx++) {
          const double qx = 2 * M_PI * i / Lx + 2 * M_PI * gx / g->dx;
          const double qy = 2 * M_PI * jj / Ly + 2 * M_PI * gy / g->dy;
          const double q = hypot(qx, qy);
          if (q == 0) continue;
          sum += 2 * exp(-q * c) / (E_star * q) * sinc(0.5 * qx * g->dx) *
                 sinc(0.5 * qy * g->dy);
        }
      spec[(size_t)j * nqx + i][0] = sum / (g->dx * g->dy * nx * ny);
      spec[(size_t)j * nqx + i][1] = 0;
    }
  fftw_plan p = fftw_plan_dft_c2r_2d(ny, nx, spec, K, FFTW_ESTIMATE);
  if (!p) {
    fftw_free(K);
    fftw_free(spec);
    return proto_fail(err, "periodic half-space: FFTW plan failed");
  }
  fftw_execute(p);
  fftw_destroy_plan(p);
  /* short-range part over the images, then the mean removed */
  const int Rx = (int)fmin(GRN_PERIODIC_MAX_IMAGES, ceil((double)GRN_PERIODIC_REACH / nx));
  const int Ry = (int)fmin(GRN_PERIODIC_MAX_IMAGES, ceil((double)GRN_PERIODIC_REACH / ny));
  for (int j = 0; j < ny; j++)
    for (int i = 0; i < nx; i++) {
      /* images about the nearest representative of the offset */
      const int ic = i <= nx / 2 ? i : i - nx, jc = j <= ny / 2 ? j : j - ny;
      double s = 0;
      for (int my = -Ry; my <= Ry; my++)
        for (int mx = -Rx; mx <= Rx; mx++) {
          const double x = (ic + mx * nx) * g->dx, y = (jc + my * ny) * g->dy;
          s += grn_love_compliance(x, y, 0.5 * g->dx, 0.5 * g->dy, E, nu) -
               grn_love_smoothed(x, y, 0.5 * g->dx, 0.5 * g->dy, c, E, nu);
        }
      K[(size_t)j * nx + i] += s;
    }
  /* exactly even in each axis (the truncated image sum of the half-period
   * offsets is not), then the mean removed */
  double mean = 0;
  for (int j = 0; j <= ny / 2; j++)
    for (int i = 0; i <= nx / 2; i++) {
      const int i2 = (nx - i) % nx, j2 = (ny - j) % ny;
      double *a = &K[(size_t)j * nx + i], *b = &K[(size_t)j * nx + i2],
             *c2 = &K[(size_t)j2 * nx + i], *d = &K[(size_t)j2 * nx + i2];
      const double v = 0.25 * (*a + *b + *c2 + *d);
      *a = *b = *c2 = *d = v;
    }
  for (size_t q = 0; q < (size_t)nx * ny; q++) mean += K[q];
  mean /= (double)nx * ny;
  /* offset layout [2ny−1][2nx−1]: K(Δ) = K(Δ mod n), so K(Δ) = K(Δ − n) */
  const int wx = 2 * nx - 1;
  for (int dj = -(ny - 1); dj <= ny - 1; dj++)
    for (int di = -(nx - 1); di <= nx - 1; di++)
      C[(size_t)(dj + ny - 1) * wx + di + nx - 1] =
          K[(size_t)((dj + ny) % ny) * nx + (di + nx) % nx] - mean;
  fftw_free(K);
  fftw_free(spec);
  return 0;
}
