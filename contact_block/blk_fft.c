/* blk_fft.c — products of an element-offset kernel with a field over the
 * grid by FFT: the layer's influence C·F (translation invariance: C[i][p]
 * depends on i − p only). Non-periodic: linear convolution on a box of
 * Nx ≥ 2nx − 1 by Ny ≥ 2ny − 1 (zero padding, Hockney 1969), so no image of
 * the grid leaks in; periodic grid: circular convolution on nx × ny.
 *
 * The 2-D transform is done as rows then columns: on input only the ny rows
 * holding the field are transformed (the others are zero), on output only
 * the ny rows of the grid are transformed back — half of the row work of a
 * plain 2-D transform on the padded box. Plans are made once here. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "contact_block/blk_internal.h"
#include "green/green.h"

int blk_fft_init(blk_fft *f, const blk_model *m, proto_err *err) {
  memset(f, 0, sizeof *f);
  f->nx = m->nx;
  f->ny = m->ny;
  f->periodic = m->periodic;
  f->Nx = m->periodic ? m->nx : grn_fft_size(2 * m->nx - 1);
  f->Ny = m->periodic ? m->ny : grn_fft_size(2 * m->ny - 1);
  f->nqx = f->Nx / 2 + 1;
  f->box = fftw_alloc_real((size_t)f->Nx * f->Ny);
  f->spec = fftw_alloc_complex((size_t)f->Ny * f->nqx);
  if (!f->box || !f->spec) return proto_fail(err, "FFT box %d x %d: out of memory", f->Nx, f->Ny);
  const unsigned flags = BLK_FFTW_STEP(m->M);
  const int nX[1] = {f->Nx}, nY[1] = {f->Ny};
  f->rows_fwd = fftw_plan_many_dft_r2c(1, nX, f->ny, f->box, NULL, 1, f->Nx, f->spec, NULL,
                                       1, f->nqx, flags);
  f->cols_fwd = fftw_plan_many_dft(1, nY, f->nqx, f->spec, NULL, f->nqx, 1, f->spec, NULL,
                                   f->nqx, 1, FFTW_FORWARD, flags);
  f->cols_inv = fftw_plan_many_dft(1, nY, f->nqx, f->spec, NULL, f->nqx, 1, f->spec, NULL,
                                   f->nqx, 1, FFTW_BACKWARD, flags);
  f->rows_inv = fftw_plan_many_dft_c2r(1, nX, f->ny, f->spec, NULL, 1, f->nqx, f->box, NULL,
                                       1, f->Nx, flags);
  if (!f->rows_fwd || !f->cols_fwd || !f->cols_inv || !f->rows_inv)
    return proto_fail(err, "FFTW planning failed (box %d x %d)", f->Nx, f->Ny);
  return 0;
}

void blk_fft_free(blk_fft *f) {
  if (f->rows_fwd) fftw_destroy_plan(f->rows_fwd);
  if (f->cols_fwd) fftw_destroy_plan(f->cols_fwd);
  if (f->cols_inv) fftw_destroy_plan(f->cols_inv);
  if (f->rows_inv) fftw_destroy_plan(f->rows_inv);
  fftw_free(f->box);
  fftw_free(f->spec);
  memset(f, 0, sizeof *f);
}

size_t blk_fft_bytes(const blk_fft *f) {
  return (size_t)f->Nx * f->Ny * sizeof(double) +
         (size_t)f->Ny * f->nqx * sizeof(fftw_complex);
}

size_t blk_kspec_bytes(const blk_fft *f, const blk_kspec *ks) {
  const size_t n = (size_t)f->Ny * f->nqx;
  return ks->re ? n * sizeof(double) : ks->c ? n * sizeof(fftw_complex) : 0;
}

void blk_kspec_free(blk_kspec *ks) {
  fftw_free(ks->re);
  fftw_free(ks->c);
  ks->re = NULL;
  ks->c = NULL;
}

int blk_fft_kernel(blk_fft *f, const blk_model *m, const double *kern, double scale,
                   blk_kspec *ks, proto_err *err) {
  memset(ks, 0, sizeof *ks);
  const size_t n = (size_t)f->Ny * f->nqx;
  memset(f->box, 0, (size_t)f->Nx * f->Ny * sizeof(double));
  /* K[(Δj mod Ny)][(Δi mod Nx)]; periodic: the offsets 0..n−1 (a periodic
   * kernel has K(Δ) = K(Δ − n), blk_model_check) */
  const int lo_j = f->periodic ? 0 : -(m->ny - 1), lo_i = f->periodic ? 0 : -(m->nx - 1);
  for (int dj = lo_j; dj <= m->ny - 1; dj++)
    for (int di = lo_i; di <= m->nx - 1; di++)
      f->box[(size_t)((dj + f->Ny) % f->Ny) * f->Nx + (di + f->Nx) % f->Nx] =
          kern[(size_t)(dj + m->ny - 1) * m->nox + (di + m->nx - 1)];
  fftw_plan p = fftw_plan_dft_r2c_2d(f->Ny, f->Nx, f->box, f->spec, FFTW_ESTIMATE);
  if (!p) return proto_fail(err, "FFTW planning failed (kernel %d x %d)", f->Nx, f->Ny);
  fftw_execute(p);
  fftw_destroy_plan(p);
  const double s = scale / ((double)f->Nx * f->Ny);
  if (blk_spectrum_is_real(f->spec, n)) { /* even kernel (reciprocity) */
    ks->re = fftw_alloc_real(n);
    if (!ks->re) return proto_fail(err, "out of memory");
    for (size_t q = 0; q < n; q++) ks->re[q] = s * f->spec[q][0];
  } else {
    ks->c = fftw_alloc_complex(n);
    if (!ks->c) return proto_fail(err, "out of memory");
    for (size_t q = 0; q < n; q++) {
      ks->c[q][0] = s * f->spec[q][0];
      ks->c[q][1] = s * f->spec[q][1];
    }
  }
  return 0;
}

int blk_spectrum_is_real(const fftw_complex *spec, size_t n) {
  double im = 0, mag = 0;
  for (size_t q = 0; q < n; q++) {
    im = fmax(im, fabs(spec[q][1]));
    mag = fmax(mag, fabs(spec[q][0]));
  }
  return im <= BLK_REAL_SPECTRUM_TOL * mag;
}

BLK_HOT static void mul_real(fftw_complex *restrict spec, const double *restrict re,
                             size_t n) {
  double *a = (double *)spec;
  for (size_t q = 0; q < n; q++) {
    a[2 * q] *= re[q];
    a[2 * q + 1] *= re[q];
  }
}

static void mul_complex(fftw_complex *restrict spec, const fftw_complex *restrict c,
                        size_t n) {
  for (size_t q = 0; q < n; q++) {
    const double a = spec[q][0], b = spec[q][1];
    spec[q][0] = a * c[q][0] - b * c[q][1];
    spec[q][1] = a * c[q][1] + b * c[q][0];
  }
}

void blk_fft_apply(blk_fft *f, const blk_kspec *ks, const double *x, double *y) {
  const int nx = f->nx, ny = f->ny, Nx = f->Nx;
  for (int j = 0; j < ny; j++) {
    double *row = f->box + (size_t)j * Nx;
    memcpy(row, x + (size_t)j * nx, (size_t)nx * sizeof(double));
    if (Nx > nx) memset(row + nx, 0, (size_t)(Nx - nx) * sizeof(double));
  }
  fftw_execute(f->rows_fwd);
  if (f->Ny > ny) /* the rows of the padding transform to zero */
    memset(f->spec + (size_t)ny * f->nqx, 0,
           (size_t)(f->Ny - ny) * f->nqx * sizeof(fftw_complex));
  fftw_execute(f->cols_fwd);
  const size_t n = (size_t)f->Ny * f->nqx;
  if (ks->re) mul_real(f->spec, ks->re, n);
  else mul_complex(f->spec, ks->c, n);
  fftw_execute(f->cols_inv);
  fftw_execute(f->rows_inv);
  for (int j = 0; j < ny; j++) memcpy(y + (size_t)j * nx, f->box + (size_t)j * Nx,
                                      (size_t)nx * sizeof(double));
}
