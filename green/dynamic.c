/* dynamic.c — impulse responses of a viscoelastic layer on a rigid base by the
 * wavenumber–frequency method (seed 002 ch. 3.3; Larsson & Kropp 2002): per frequency
 * the layer compliance H(|q|, ω) times the element shape S(q) is transformed
 * to every element offset (FFT on the zero-padded box, the long-range
 * half-space part in closed form), then each offset's spectrum goes to time
 * by the causal "two times the real part" cosine transform (FFTW DCT-I),
 * sampled as zero-order-hold increments and as point values. */
#include <complex.h>
#include <fftw3.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "green/green.h"
#include "green/green_internal.h"

void grn_dyn_opts_default(grn_dyn_opts *o) {
  memset(o, 0, sizeof *o);
  o->Q = 256;          /* seed 002 ch. 3.3 */
  o->rate = 51200;     /* seed 002 appendix B */
  o->oversample = 4;   /* spectrum up to 2 x the sampling rate */
  o->period_factor = 4;/* transform period 8 x the Green's function length */
}

int grn_causal_response(int nf, double df, const double *spec_re,
                        const double *spec_im, double dt, int Q, double *zoh,
                        double *point, proto_err *err) {
  const int K = nf - 1;
  (void)spec_im;
  const double s_real = 2.0 * K * df * dt; /* fine steps per sample */
  const int s = (int)lround(s_real);
  if (K < 2 || s < 1 || fabs(s_real - s) > 1e-6 * s_real)
    return proto_fail(err, "spectrum grid (nf = %d, df = %g Hz) does not fit "
                           "dt = %g s: 2 (nf-1) df dt = %g must be an integer",
                      nf, df, dt, s_real);
  if ((long)Q * s > K)
    return proto_fail(err, "Q = %d samples exceed half the transform period "
                           "(%d fine steps of %d)", Q, K, s);
  double *x = fftw_alloc_real(nf), *y = fftw_alloc_real(nf);
  if (!x || !y) {
    fftw_free(x);
    fftw_free(y);
    return proto_fail(err, "out of memory (nf = %d)", nf);
  }
  /* Y_n = X_0 + (-1)^n X_K + 2 Σ X_k cos(π k n / K): the trapezoid rule of
   * g(t) = (2/π) ∫ Re ĝ(ω) cos ωt dω with t_n = n/(2 K df) */
  fftw_plan p = fftw_plan_r2r_1d(nf, x, y, FFTW_REDFT00, FFTW_ESTIMATE);
  const double scale = 2.0 * df;
  if (point) {
    memcpy(x, spec_re, nf * sizeof *x);
    fftw_execute(p);
    for (int k = 0; k < Q; k++)
      point[k] = scale * y[(size_t)k * s];
  }
  if (zoh && K > 1) {
    /* ZOH from the step response S(t) = (2/π) ∫ Re ĝ(ω) sin(ωt)/ω dω: its
     * integrand decays one power of ω faster than g's, so the increments
     * converge fast where a ZOH filter on g would feel the spectrum's
     * truncation. Trapezoid rule, DST-I over k = 1..K-1:
     * S(t_n) = 2 df [X_0 t_n + Y_{n-1}], Y = DST-I of X_k/ω_k. Only Re ĝ
     * is needed (causality); spec_im is accepted for callers that check. */
    fftw_plan ps = fftw_plan_r2r_1d(K - 1, x, y, FFTW_RODFT00, FFTW_ESTIMATE);
    for (int k = 1; k < K; k++)
      x[k - 1] = spec_re[k] / (2 * M_PI * k * df);
    fftw_execute(ps);
    fftw_destroy_plan(ps);
    const double dtf = 1.0 / (2.0 * K * df);
    double prev = 0.0; /* S(0) */
    for (int k = 0; k < Q; k++) {
      int n = (k + 1) * s;
      double step = scale * (spec_re[0] * n * dtf + (n < K ? y[n - 1] : 0.0));
      zoh[k] = (step - prev) / dt;
      prev = step;
    }
  }
  fftw_destroy_plan(p);
  fftw_free(x);
  fftw_free(y);
  return 0;
}

/* Fills spec (2 kernels: Re, Im; [Py][nqx] each) with the folded remainder
 * S(q) [H(q,ω) − 2(1 − e^{−qc})/(E*(ω) q)] at one frequency. */
static void fill_remainder(const grn_box *b, const grn_grid *g, double h,
                           double rho, double nu, double omega,
                           double complex E, fftw_complex *spec, size_t stride) {
  const double complex mu = E / (2 * (1 + nu)), lam = 2 * mu * nu / (1 - 2 * nu);
  const double complex E_star = E / (1 - nu * nu);
  /* H depends on |q| and S is even: fill j <= Py/2, mirror to -j, and on a
   * square box with square elements take (i, j) from (j, i) */
  const int square = b->Px == b->Py && g->dx == g->dy && b->mx == b->my;
  for (int j = 0; j <= b->Py / 2; j++)
    for (int i = 0; i < b->nqx; i++) {
      double complex sum = 0;
      if (square && i < j) {
        sum = spec[(size_t)i * b->nqx + j] + I * spec[stride + (size_t)i * b->nqx + j];
      } else {
        for (int gy = -b->my; gy <= b->my; gy++)
          for (int gx = -b->mx; gx <= b->mx; gx++) {
            double qx = grn_box_qx(b, g, i, gx), qy = grn_box_qy(b, g, j, gy);
            double q = hypot(qx, qy);
            double complex H = omega > 0 ? grn_layer_dynamic_c(q, omega, h, rho, mu, lam)
                                         : grn_layer_compliance(q, h, 1.0, nu) / E;
            double split = q > 0 ? 2.0 * -expm1(-q * b->c) / q : 2 * b->c;
            sum += grn_element_shape(g, qx, qy) * (H - split / E_star);
          }
      }
      int jm = (b->Py - j) % b->Py;
      spec[(size_t)j * b->nqx + i] = creal(sum);
      spec[(size_t)jm * b->nqx + i] = creal(sum);
      spec[stride + (size_t)j * b->nqx + i] = cimag(sum);
      spec[stride + (size_t)jm * b->nqx + i] = cimag(sum);
    }
}

int grn_dynamic(const grn_grid *g, const grn_material *mat, double h,
                const grn_dyn_opts *o, double *g_zoh, double *g_point,
                double *stat, proto_err *err) {
  if (grn_material_check(mat, err))
    return -1;
  if (!(h > 0) || !isfinite(h))
    return proto_fail(err, "thickness = %g: must be > 0", h);
  if (mat->nu >= 0.5)
    return proto_fail(err, "nu = %g: the dynamic layer needs nu < 0.5", mat->nu);
  if (o->Q < 1 || !(o->rate > 0) || o->oversample < 1 || o->period_factor < 1)
    return proto_fail(err, "Q = %d, rate = %g, oversample = %d, period_factor = %d: "
                           "all must be positive", o->Q, o->rate, o->oversample,
                      o->period_factor);
  const int nx = g->nx, ny = g->ny, wx = 2 * nx - 1, nk = wx * (2 * ny - 1);
  const int K = o->oversample * o->Q * o->period_factor, nf = K + 1;
  const double df = o->oversample * o->rate / (2.0 * K), dt = 1.0 / o->rate;
  grn_box b;
  grn_box_init(&b, g, h, o->pad);
  const size_t box_c = (size_t)b.Py * b.nqx, box_r = (size_t)b.Py * b.Px;
  /* spectra per offset in the quarter di, dj >= 0 (the layer is isotropic
   * and the element symmetric), stored [offset][frequency] */
  const size_t nq4 = (size_t)nx * ny;
  double *re = malloc(nq4 * nf * sizeof *re), *im = malloc(nq4 * nf * sizeof *im);
  double *love = malloc(nk * sizeof *love), *kern = malloc(2 * nk * sizeof *kern);
  double *outz = malloc(o->Q * sizeof *outz), *outp = malloc(o->Q * sizeof *outp);
  fftw_complex *spec = fftw_alloc_complex(2 * box_c);
  double *work = fftw_alloc_real(2 * box_r);
  int rc = -1;
  if (!re || !im || !love || !kern || !spec || !work || !outz || !outp) {
    proto_fail(err, "out of memory: %zu offsets x %d frequencies", nq4, nf);
    goto done;
  }
  /* closed-form part for E = 1: (Love − smoothed Love) scales as 1/E(ω) */
  for (int dj = -(ny - 1); dj < ny; dj++)
    for (int di = -(nx - 1); di < nx; di++) {
      double x = di * g->dx, y = dj * g->dy, a = 0.5 * g->dx, bb = 0.5 * g->dy;
      love[(dj + ny - 1) * wx + di + nx - 1] =
          grn_love_compliance(x, y, a, bb, 1.0, mat->nu) -
          grn_love_smoothed(x, y, a, bb, b.c, 1.0, mat->nu);
    }
  for (int k = 0; k < nf; k++) {
    double f = k * df, Ef, eta;
    grn_material_at(mat, f, &Ef, &eta);
    /* DC: the relaxed modulus without loss (a causal material has none) */
    double complex E = k == 0 ? Ef : Ef * (1 + I * eta);
    fill_remainder(&b, g, h, mat->rho, mat->nu, 2 * M_PI * f, E, spec, box_c);
    for (int m = 0; m < nk; m++) {
      double complex c = love[m] / E;
      kern[m] = creal(c);
      kern[nk + m] = cimag(c);
    }
    if (grn_box_to_kernel(&b, g, spec, work, kern, 2, (int)box_c, (int)box_r)) {
      proto_fail(err, "FFTW plan failed (box %dx%d)", b.Px, b.Py);
      goto done;
    }
    for (int dj = 0; dj < ny; dj++)
      for (int di = 0; di < nx; di++) {
        int m = (dj + ny - 1) * wx + di + nx - 1;
        re[((size_t)dj * nx + di) * nf + k] = kern[m];
        im[((size_t)dj * nx + di) * nf + k] = kern[nk + m];
      }
    if (o->progress && (k % 64 == 0 || k == nf - 1))
      o->progress(o->progress_user, (k + 1.0) / nf, "frequencies");
  }
  /* time domain per quarter offset, mirrored to all four quadrants */
  for (int dj = 0; dj < ny; dj++)
    for (int di = 0; di < nx; di++) {
      size_t q4 = (size_t)dj * nx + di;
      if (grn_causal_response(nf, df, re + q4 * nf, im + q4 * nf, dt, o->Q,
                              outz, outp, err))
        goto done;
      for (int sy = -1; sy <= 1; sy += 2)
        for (int sx = -1; sx <= 1; sx += 2) {
          int m = (sy * dj + ny - 1) * wx + sx * di + nx - 1;
          for (int t = 0; t < o->Q; t++) {
            if (g_zoh) g_zoh[(size_t)t * nk + m] = outz[t];
            if (g_point) g_point[(size_t)t * nk + m] = outp[t];
          }
          if (stat) stat[m] = re[q4 * nf]; /* ω = 0: static, E(0) */
        }
    }
  rc = 0;
done:
  free(re);
  free(im);
  free(love);
  free(kern);
  free(outz);
  free(outp);
  fftw_free(spec);
  fftw_free(work);
  return rc;
}
