/* layer.c — elastic layer bonded to a rigid base: static surface stiffness
 * (the bonded-layer k(q) of ContactMechanics' PeriodicFFTElasticHalfSpace),
 * dynamic compliance from the 4x4 potential system (the wavenumber–frequency
 * method of Larsson & Kropp 2002),
 * and static influence coefficients by FFT (zero-padded periodic box). */
#include <complex.h>
#include <fftw3.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "green/green.h"
#include "green/green_internal.h"

/* sinh(x) − x without cancellation for small x */
static double sinh_minus_x(double x) {
  if (fabs(x) < 0.1) {
    double x2 = x * x;
    return x * x2 / 6.0 * (1.0 + x2 / 20.0 * (1.0 + x2 / 42.0 * (1.0 + x2 / 72.0)));
  }
  return sinh(x) - x;
}

/* k(q) / (E* q / 2): the layer's stiffening over the half-space (>= 1). */
double grn_layer_factor(double tau, double nu) {
  if (tau >= 20.0) /* correction ~ tau² e^{-2 tau} below round-off */
    return 1.0;
  const double num = (3 - 4 * nu) * cosh(2 * tau) + 2 * tau * tau + 5 - 12 * nu +
                     8 * nu * nu;
  /* (3−4ν) sinh 2τ − 2τ rewritten so that ν = 0.5 keeps its τ³ accuracy */
  const double den = (3 - 4 * nu) * sinh_minus_x(2 * tau) + (4 - 8 * nu) * tau;
  return num / den;
}

double grn_layer_stiffness(double q, double h, double E, double nu) {
  if (q <= 0.0)
    return nu < 0.5 ? E * (1 - nu) / ((1 + nu) * (1 - 2 * nu) * h) : INFINITY;
  return E / (1 - nu * nu) * q / 2 * grn_layer_factor(q * h, nu);
}

/* 1/k(q), finite at q = 0 (0 for an incompressible layer) */
double grn_layer_compliance(double q, double h, double E, double nu) {
  if (q <= 0.0)
    return nu < 0.5 ? (1 + nu) * (1 - 2 * nu) * h / (E * (1 - nu)) : 0.0;
  return 1.0 / grn_layer_stiffness(q, h, E, nu);
}

/* Gaussian elimination with partial pivoting, 4x4 complex, one rhs. */
static int solve4(double complex A[4][4], double complex b[4]) {
  for (int c = 0; c < 4; c++) {
    int p = c;
    for (int r = c + 1; r < 4; r++)
      if (cabs(A[r][c]) > cabs(A[p][c]))
        p = r;
    if (cabs(A[p][c]) == 0.0)
      return -1;
    if (p != c) {
      for (int k = 0; k < 4; k++) {
        double complex t = A[c][k];
        A[c][k] = A[p][k];
        A[p][k] = t;
      }
      double complex t = b[c];
      b[c] = b[p];
      b[p] = t;
    }
    for (int r = c + 1; r < 4; r++) {
      double complex f = A[r][c] / A[c][c];
      for (int k = c; k < 4; k++)
        A[r][k] -= f * A[c][k];
      b[r] -= f * b[c];
    }
  }
  for (int c = 3; c >= 0; c--) {
    for (int k = c + 1; k < 4; k++)
      b[c] -= A[c][k] * b[k];
    b[c] /= A[c][c];
  }
  return 0;
}

double complex grn_layer_dynamic_c(double q, double omega, double h, double rho,
                                   double complex mu, double complex lam) {
  const double complex ks2 = rho * omega * omega / mu;
  const double complex kp2 = rho * omega * omega / (lam + 2 * mu);
  if (cabs(ks2) < 1e-6 * q * q) {
    /* quasi-static: the potential system degenerates as alpha -> beta; the
     * static formula with the complex modulus is exact to O(k_s²/q²) */
    const double complex E = mu * (3 * lam + 2 * mu) / (lam + mu);
    const double nu = creal(lam / (2 * (lam + mu)));
    return grn_layer_compliance(q, h, 1.0, nu) / E;
  }
  double complex al = csqrt(q * q - kp2), be = csqrt(q * q - ks2);
  if (creal(al) < 0) al = -al;
  if (creal(be) < 0) be = -be;
  const double complex K2 = 2 * q * q - ks2, Ea = cexp(-al * h), Eb = cexp(-be * h);
  const double complex iq = I * q;
  /* rows: sigma_zz(0) = -p, sigma_xz(0) = 0, u_x(h) = 0, u_z(h) = 0 */
  double complex A[4][4] = {
      {K2, K2 * Ea, -2 * iq * be, 2 * iq * be * Eb},
      {-2 * iq * al, 2 * iq * al * Ea, -K2, -K2 * Eb},
      {iq * Ea, iq, be * Eb, -be},
      {-al * Ea, al, iq * Eb, iq}};
  double complex b[4] = {-1.0 / mu, 0, 0, 0};
  if (solve4(A, b))
    return NAN;
  return -al * b[0] + al * Ea * b[1] + iq * b[2] + iq * Eb * b[3];
}

int grn_layer_dynamic(double q, double omega, double h, double rho, double mu_re,
                      double mu_im, double lambda_re, double lambda_im,
                      double *H_re, double *H_im) {
  double complex H = grn_layer_dynamic_c(q, omega, h, rho, mu_re + I * mu_im,
                                         lambda_re + I * lambda_im);
  *H_re = creal(H);
  *H_im = cimag(H);
  return isfinite(creal(H)) ? 0 : -1;
}

/* ---------------------------------------------------------------- FFT box */

int grn_fft_size(int n) {
  for (;; n++) {
    int m = n;
    while (m % 2 == 0) m /= 2;
    while (m % 3 == 0) m /= 3;
    while (m % 5 == 0) m /= 5;
    if (m == 1)
      return n;
  }
}

int grn_box_init(grn_box *b, const grn_grid *g, double h, int pad) {
  const double dmax = fmax(g->dx, g->dy);
  /* smoothing length of the split-off Boussinesq part; <= 2h so that for a
   * thin layer its c²/r³ tail (periodic images) stays negligible */
  b->c = fmin(4.0 * dmax, 2.0 * h);
  const double reach = 6.0 * fmax(h, b->c); /* layer response decays over ~h */
  int px = pad > 0 ? pad : (int)ceil(reach / g->dx);
  int py = pad > 0 ? pad : (int)ceil(reach / g->dy);
  b->Px = grn_fft_size(2 * g->nx - 1 + 2 * px);
  b->Py = grn_fft_size(2 * g->ny - 1 + 2 * py);
  /* alias shells so the remainder is resolved to q·min(c, 2h) >= 12
   * (e^-12 = 6e-6 of the half-space term) */
  const double lc = fmin(b->c, 2 * h);
  b->mx = (int)ceil(fmax(0.0, (12.0 * g->dx / (M_PI * lc) - 1) / 2));
  b->my = (int)ceil(fmax(0.0, (12.0 * g->dy / (M_PI * lc) - 1) / 2));
  b->nqx = b->Px / 2 + 1;
  return 0;
}

double grn_box_qx(const grn_box *b, const grn_grid *g, int i, int gx) {
  return 2 * M_PI * i / (b->Px * g->dx) + 2 * M_PI * gx / g->dx;
}
double grn_box_qy(const grn_box *b, const grn_grid *g, int j, int gy) {
  int jj = j <= b->Py / 2 ? j : j - b->Py;
  return 2 * M_PI * jj / (b->Py * g->dy) + 2 * M_PI * gy / g->dy;
}

static double sinc(double x) { return fabs(x) < 1e-8 ? 1.0 - x * x / 6 : sin(x) / x; }

double grn_element_shape(const grn_grid *g, double qx, double qy) {
  return sinc(0.5 * qx * g->dx) * sinc(0.5 * qy * g->dy);
}

/* Inverse transform of spec [Py][Px/2+1] to the kernel layout
 * [2ny-1][2nx-1], scaled by 1/(Lx Ly), added into C. */
int grn_box_to_kernel(const grn_box *b, const grn_grid *g, fftw_complex *spec,
                      double *work, double *C, int n_kernels, int spec_stride,
                      int out_stride) {
  int n[2] = {b->Py, b->Px};
  fftw_plan p = fftw_plan_many_dft_c2r(2, n, n_kernels, spec, NULL, 1,
                                       spec_stride, work, NULL, 1, out_stride,
                                       FFTW_ESTIMATE);
  if (!p)
    return -1;
  fftw_execute(p);
  fftw_destroy_plan(p);
  const double scale = 1.0 / (b->Px * g->dx * b->Py * g->dy);
  const int wx = 2 * g->nx - 1;
  for (int k = 0; k < n_kernels; k++)
    for (int dj = -(g->ny - 1); dj < g->ny; dj++)
      for (int di = -(g->nx - 1); di < g->nx; di++) {
        int jj = (dj + b->Py) % b->Py, ii = (di + b->Px) % b->Px;
        C[(size_t)k * (2 * g->ny - 1) * wx + (dj + g->ny - 1) * wx + di + g->nx - 1] +=
            scale * work[(size_t)k * out_stride + (size_t)jj * b->Px + ii];
      }
  return 0;
}

/* Smoothed half-space compliance split off in wavenumber space. */
double grn_split_compliance(double q, double c, double E_star) {
  if (q <= 0.0)
    return 2 * c / E_star;
  return 2.0 / (E_star * q) * -expm1(-q * c);
}

int grn_static_layer(const grn_grid *g, double h, double E, double nu, int pad,
                     double *C, proto_err *err) {
  if (!(h > 0) || !isfinite(h))
    return proto_fail(err, "thickness = %g: must be > 0", h);
  if (!(E > 0) || !(nu >= 0 && nu <= 0.5))
    return proto_fail(err, "E = %g, nu = %g: need E > 0, 0 <= nu <= 0.5", E, nu);
  grn_box b;
  grn_box_init(&b, g, h, pad);
  const double E_star = E / (1 - nu * nu);
  fftw_complex *spec = fftw_alloc_complex((size_t)b.Py * b.nqx);
  double *work = fftw_alloc_real((size_t)b.Py * b.Px);
  if (!spec || !work) {
    fftw_free(spec);
    fftw_free(work);
    return proto_fail(err, "out of memory for a %dx%d box", b.Px, b.Py);
  }
  /* remainder R(q) = S(q) [1/k(q) − 2(1 − e^{−qc})/(E* q)], folded over
   * the alias shells: smooth at q = 0 and decaying like e^{−q min(c, 2h)} */
  for (int j = 0; j < b.Py; j++)
    for (int i = 0; i < b.nqx; i++) {
      double sum = 0;
      for (int gy = -b.my; gy <= b.my; gy++)
        for (int gx = -b.mx; gx <= b.mx; gx++) {
          double qx = grn_box_qx(&b, g, i, gx), qy = grn_box_qy(&b, g, j, gy);
          double q = hypot(qx, qy);
          sum += grn_element_shape(g, qx, qy) *
                 (grn_layer_compliance(q, h, E, nu) -
                  grn_split_compliance(q, b.c, E_star));
        }
      spec[(size_t)j * b.nqx + i] = sum;
    }
  const int wx = 2 * g->nx - 1;
  for (int dj = -(g->ny - 1); dj < g->ny; dj++)
    for (int di = -(g->nx - 1); di < g->nx; di++) {
      double x = di * g->dx, y = dj * g->dy, a = 0.5 * g->dx, bb = 0.5 * g->dy;
      C[(dj + g->ny - 1) * wx + di + g->nx - 1] =
          grn_love_compliance(x, y, a, bb, E, nu) -
          grn_love_smoothed(x, y, a, bb, b.c, E, nu);
    }
  int rc = grn_box_to_kernel(&b, g, spec, work, C, 1, 0, 0);
  fftw_free(spec);
  fftw_free(work);
  return rc ? proto_fail(err, "FFTW plan failed") : 0;
}
