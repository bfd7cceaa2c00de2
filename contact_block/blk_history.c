/* blk_history.c — the history term d_el_old (seed 002 eq. 5): the response
 * at the next step to all past forces. The layer is translation-invariant,
 * so g depends on the element offset only: the spatial sum is a 2-D linear
 * convolution, done with FFTs on a zero-padded 2nx × 2ny grid (Hockney), and
 * the time sum is a product sum over a ring of past force spectra. The
 * direct double sum is kept as the reference (solver.history = "direct"). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "contact_block/blk_internal.h"

/* Samples kept: up to the last one with max|g_k| above tail_tol·max|g|. */
static int truncated_length(const blk_model *m) {
  const size_t no = (size_t)m->nox * m->noy;
  double gmax = 0;
  for (size_t i = 0; i < (size_t)m->Q * no; i++)
    if (fabs(m->g[i]) > gmax) gmax = fabs(m->g[i]);
  int Qh = 1;
  for (int k = 0; k < m->Q; k++)
    for (size_t o = 0; o < no; o++)
      if (fabs(m->g[(size_t)k * no + o]) > m->solver.tail_tol * gmax) {
        Qh = k + 1;
        break;
      }
  return Qh;
}

/* Kernel of sample k on the padded grid: K[(Δj mod Ny)][(Δi mod Nx)]. */
static void place_kernel(const blk_model *m, const blk_history *h, int k, double *pad) {
  const size_t no = (size_t)m->nox * m->noy;
  memset(pad, 0, (size_t)h->Nx * h->Ny * sizeof(double));
  for (int dj = -(m->ny - 1); dj <= m->ny - 1; dj++)
    for (int di = -(m->nx - 1); di <= m->nx - 1; di++) {
      int pj = (dj + h->Ny) % h->Ny, pi = (di + h->Nx) % h->Nx;
      pad[pj * h->Nx + pi] =
          m->g[(size_t)k * no + (size_t)(dj + m->ny - 1) * m->nox + (di + m->nx - 1)];
    }
}


/* Sets up the partitioned time convolution when g is long enough (Qh > 3B). */
static int partition_init(blk_history *h, proto_err *err) {
  const int B = h->Qh < 512 ? 32 : 64; /* ≈ 2√Q balances head and tail work */
  if (h->Qh <= 3 * B) return 0;
  const int nq = h->nq, L = 2 * B;
  h->B = B;
  h->S = (h->Qh - 1 - B + B - 1) / B; /* segments covering lags B+1 .. Qh−1 */
  const size_t seg = (size_t)nq * L;
  h->seg_hat = fftw_malloc((size_t)h->S * seg * sizeof(fftw_complex));
  h->fdl = fftw_malloc((size_t)h->S * seg * sizeof(fftw_complex));
  h->win = fftw_malloc(seg * sizeof(fftw_complex));
  h->tail = fftw_malloc((size_t)B * nq * sizeof(fftw_complex));
  if (!h->seg_hat || !h->fdl || !h->win || !h->tail) return proto_fail(err, "out of memory");
  const int n[1] = {L};
  h->tfwd = fftw_plan_many_dft(1, n, nq, h->win, NULL, 1, L, h->win, NULL, 1, L,
                               FFTW_FORWARD, FFTW_ESTIMATE);
  h->tinv = fftw_plan_many_dft(1, n, nq, h->win, NULL, 1, L, h->win, NULL, 1, L,
                               FFTW_BACKWARD, FFTW_ESTIMATE);
  if (!h->tfwd || !h->tinv) return proto_fail(err, "history: FFTW planning failed");
  /* segment s (1..S): h_s[i] = ĝ_{sB+1+i}(q), i < B, zero-padded to 2B;
   * the 1/(2B) of the inverse transform is folded in here */
  for (int s = 1; s <= h->S; s++) {
    memset(h->win, 0, seg * sizeof(fftw_complex));
    for (int q = 0; q < nq; q++)
      for (int i = 0; i < B; i++) {
        const int k = s * B + 1 + i;
        if (k >= h->Qh) break;
        h->win[(size_t)q * L + i][0] = h->ghat[(size_t)k * nq + q][0] / L;
        h->win[(size_t)q * L + i][1] = h->ghat[(size_t)k * nq + q][1] / L;
      }
    fftw_execute(h->tfwd);
    memcpy(h->seg_hat + (size_t)(s - 1) * seg, h->win, seg * sizeof(fftw_complex));
  }
  return 0;
}

/* At a block start (pushed = J·B): the lags > B of the outputs J·B .. J·B+B−1
 * only need inputs up to J·B − 2, all known. Window W_{J−1} = x[(J−2)B−1 ..
 * JB−2] enters the delay line; tail = IFFT(Σ_s Ĥ_s Ŵ_{J−s}), last B samples. */
static void partition_block(blk_history *h) {
  const int B = h->B, L = 2 * B, nq = h->nq, S = h->S;
  const int64_t J = h->pushed / B;
  const size_t seg = (size_t)nq * L;
  fftw_complex *W = h->fdl + (size_t)((J - 1) % S) * seg;
  const int64_t t0 = (J - 2) * B - 1;
  for (int t = 0; t < L; t++) {
    const int64_t x = t0 + t;
    if (x < 0 || x >= h->pushed) {
      for (int q = 0; q < nq; q++) W[(size_t)q * L + t][0] = W[(size_t)q * L + t][1] = 0;
      continue;
    }
    const fftw_complex *src = h->F_hat + (size_t)(x % h->Qh) * nq;
    for (int q = 0; q < nq; q++) {
      W[(size_t)q * L + t][0] = src[q][0];
      W[(size_t)q * L + t][1] = src[q][1];
    }
  }
  fftw_execute_dft(h->tfwd, W, W);
  double *acc = (double *)h->win;
  memset(acc, 0, seg * sizeof(fftw_complex));
  for (int s = 1; s <= S && J - s >= 0; s++) {
    const double *Hs = (const double *)(h->seg_hat + (size_t)(s - 1) * seg);
    const double *Ws = (const double *)(h->fdl + (size_t)((J - s) % S) * seg);
    for (size_t i = 0; i < 2 * seg; i += 2) {
      acc[i] += Hs[i] * Ws[i] - Hs[i + 1] * Ws[i + 1];
      acc[i + 1] += Hs[i] * Ws[i + 1] + Hs[i + 1] * Ws[i];
    }
  }
  fftw_execute(h->tinv);
  for (int j = 0; j < B; j++)
    for (int q = 0; q < nq; q++) {
      h->tail[(size_t)j * nq + q][0] = h->win[(size_t)q * L + B + j][0];
      h->tail[(size_t)j * nq + q][1] = h->win[(size_t)q * L + B + j][1];
    }
}

int blk_history_init(const blk_model *m, blk_history *h, proto_err *err) {
  memset(h, 0, sizeof *h);
  if (m->solver.quasi_static || !m->g) return 0;
  h->Qh = truncated_length(m);
  h->dt = 1.0 / m->rate;
  if (h->Qh < 2) return 0; /* instantaneous response only: no history */
  if (m->solver.history == BLK_HIST_DIRECT) {
    h->F_ring = calloc((size_t)h->Qh * m->M, sizeof(double));
    h->nnz = calloc((size_t)h->Qh, sizeof(int));
    if (!h->F_ring || !h->nnz) return proto_fail(err, "out of memory");
    return 0;
  }
  h->Nx = 2 * m->nx;
  h->Ny = 2 * m->ny;
  h->nq = h->Ny * (h->Nx / 2 + 1);
  h->pad = fftw_malloc((size_t)h->Nx * h->Ny * sizeof(double));
  h->ghat = fftw_malloc((size_t)h->Qh * h->nq * sizeof(fftw_complex));
  h->F_hat = fftw_malloc((size_t)h->Qh * h->nq * sizeof(fftw_complex));
  h->acc = fftw_malloc((size_t)h->nq * sizeof(fftw_complex));
  h->nnz = calloc((size_t)h->Qh, sizeof(int));
  if (!h->pad || !h->ghat || !h->F_hat || !h->acc || !h->nnz)
    return proto_fail(err, "out of memory");
  h->fwd = fftw_plan_dft_r2c_2d(h->Ny, h->Nx, h->pad, h->acc, FFTW_ESTIMATE);
  h->inv = fftw_plan_dft_c2r_2d(h->Ny, h->Nx, h->acc, h->pad, FFTW_ESTIMATE);
  if (!h->fwd || !h->inv) return proto_fail(err, "history: FFTW planning failed");
  /* spectra of g_k, scaled by Δt / (Nx Ny) (FFTW's unnormalised inverse) */
  const double scale = h->dt / ((double)h->Nx * h->Ny);
  for (int k = 0; k < h->Qh; k++) {
    place_kernel(m, h, k, h->pad);
    fftw_execute_dft_r2c(h->fwd, h->pad, h->ghat + (size_t)k * h->nq);
    for (int q = 0; q < h->nq; q++) {
      h->ghat[(size_t)k * h->nq + q][0] *= scale;
      h->ghat[(size_t)k * h->nq + q][1] *= scale;
    }
  }
  /* an even kernel (g(Δ) = g(−Δ)) has a real spectrum: keep only Re */
  double im = 0, mag = 0;
  for (size_t i = 0; i < (size_t)h->Qh * h->nq; i++) {
    im = fmax(im, fabs(h->ghat[i][1]));
    mag = fmax(mag, fabs(h->ghat[i][0]));
  }
  if (im <= 1e-13 * mag) {
    h->ghat_re = malloc((size_t)h->Qh * h->nq * sizeof(double));
    if (!h->ghat_re) return proto_fail(err, "out of memory");
    for (size_t i = 0; i < (size_t)h->Qh * h->nq; i++) h->ghat_re[i] = h->ghat[i][0];
  }
  if (partition_init(h, err)) return -1;
  blk_history_reset(m, h);
  return 0;
}

void blk_history_free(blk_history *h) {
  if (h->fwd) fftw_destroy_plan(h->fwd);
  if (h->inv) fftw_destroy_plan(h->inv);
  fftw_free(h->pad);
  fftw_free(h->ghat);
  fftw_free(h->F_hat);
  fftw_free(h->acc);
  if (h->tfwd) fftw_destroy_plan(h->tfwd);
  if (h->tinv) fftw_destroy_plan(h->tinv);
  fftw_free(h->seg_hat);
  fftw_free(h->fdl);
  fftw_free(h->win);
  fftw_free(h->tail);
  free(h->ghat_re);
  free(h->F_ring);
  free(h->nnz);
  memset(h, 0, sizeof *h);
}

void blk_history_reset(const blk_model *m, blk_history *h) {
  h->pushed = 0;
  if (h->F_ring) memset(h->F_ring, 0, (size_t)h->Qh * m->M * sizeof(double));
  if (h->F_hat) memset(h->F_hat, 0, (size_t)h->Qh * h->nq * sizeof(fftw_complex));
  if (h->nnz) memset(h->nnz, 0, (size_t)h->Qh * sizeof(int));
  if (h->fdl) memset(h->fdl, 0, (size_t)h->S * h->nq * 2 * h->B * sizeof(fftw_complex));
  if (h->tail) memset(h->tail, 0, (size_t)h->B * h->nq * sizeof(fftw_complex));
}

static void push_direct(const blk_model *m, blk_history *h, const double *F,
                        double *d_old) {
  const int Qh = h->Qh, M = m->M, nx = m->nx;
  const size_t no = (size_t)m->nox * m->noy;
  const int slot = (int)(h->pushed % Qh);
  double *row = h->F_ring + (size_t)slot * M;
  int nnz = 0;
  for (int e = 0; e < M; e++) {
    row[e] = F[e];
    nnz += F[e] != 0.0;
  }
  h->nnz[slot] = nnz;
  h->pushed++;
  memset(d_old, 0, (size_t)M * sizeof(double));
  /* next step n+1 = pushed: d_old = Δt Σ_{k≥1} Σ_p g(k; m−p) F_p(n+1−k) */
  for (int k = 1; k < Qh && k <= h->pushed; k++) {
    const int s = (int)((h->pushed - k) % Qh);
    if (!h->nnz[s]) continue;
    const double *Fk = h->F_ring + (size_t)s * M;
    const double *gk = m->g + (size_t)k * no;
    for (int p = 0; p < M; p++) {
      if (Fk[p] == 0.0) continue;
      const int pi = p % nx, pj = p / nx;
      const double f = Fk[p] * h->dt;
      for (int e = 0; e < M; e++) {
        const int ei = e % nx, ej = e / nx;
        d_old[e] += f * gk[(size_t)(ej - pj + m->ny - 1) * m->nox + (ei - pi + nx - 1)];
      }
    }
  }
}

static void push_fft(const blk_model *m, blk_history *h, const double *F, double *d_old) {
  const int Qh = h->Qh, nq = h->nq, nx = m->nx, ny = m->ny;
  const int slot = (int)(h->pushed % Qh);
  fftw_complex *Fs = h->F_hat + (size_t)slot * nq;
  int nnz = 0;
  for (int e = 0; e < m->M; e++) nnz += F[e] != 0.0;
  h->nnz[slot] = nnz;
  if (nnz) {
    memset(h->pad, 0, (size_t)h->Nx * h->Ny * sizeof(double));
    for (int j = 0; j < ny; j++)
      for (int i = 0; i < nx; i++) h->pad[j * h->Nx + i] = F[j * nx + i];
    fftw_execute_dft_r2c(h->fwd, h->pad, Fs);
  } else {
    memset(Fs, 0, (size_t)nq * sizeof(fftw_complex));
  }
  h->pushed++;
  double *acc = (double *)h->acc;
  int any = 0;
  int head = Qh; /* lags summed directly: all, or 1..B with the partitioned tail */
  if (h->B) {
    if (h->pushed % h->B == 0) partition_block(h);
    memcpy(acc, h->tail + (size_t)(h->pushed % h->B) * nq, (size_t)nq * sizeof(fftw_complex));
    head = h->B + 1;
    any = h->pushed > h->B;
  } else {
    memset(acc, 0, (size_t)nq * sizeof(fftw_complex));
  }
  for (int k = 1; k < head && k <= h->pushed; k++) {
    const int s = (int)((h->pushed - k) % Qh);
    if (!h->nnz[s]) continue;
    any = 1;
    const double *a = (const double *)(h->F_hat + (size_t)s * nq);
    if (h->ghat_re) {
      const double *g = h->ghat_re + (size_t)k * nq;
      for (int q = 0; q < nq; q++) {
        acc[2 * q] += g[q] * a[2 * q];
        acc[2 * q + 1] += g[q] * a[2 * q + 1];
      }
      continue;
    }
    const double *g = (const double *)(h->ghat + (size_t)k * nq);
    for (int q = 0; q < 2 * nq; q += 2) {
      acc[q] += g[q] * a[q] - g[q + 1] * a[q + 1];
      acc[q + 1] += g[q] * a[q + 1] + g[q + 1] * a[q];
    }
  }
  if (!any) {
    memset(d_old, 0, (size_t)m->M * sizeof(double));
    return;
  }
  fftw_execute_dft_c2r(h->inv, h->acc, h->pad);
  for (int j = 0; j < ny; j++)
    for (int i = 0; i < nx; i++) d_old[j * nx + i] = h->pad[j * h->Nx + i];
}

void blk_history_push(const blk_model *m, blk_history *h, const double *F,
                      double *d_old) {
  if (h->Qh < 2) {
    memset(d_old, 0, (size_t)m->M * sizeof(double));
    return;
  }
  if (h->F_ring) push_direct(m, h, F, d_old);
  else push_fft(m, h, F, d_old);
}

void blk_layer_displacement_ref(const blk_model *m, const double *F_hist,
                                int64_t n_rows, double *d_el) {
  const int M = m->M, nx = m->nx;
  const size_t no = (size_t)m->nox * m->noy;
  memset(d_el, 0, (size_t)M * sizeof(double));
  const int dynamic = m->g && !m->solver.quasi_static;
  const int Q = dynamic ? m->Q : 1;
  const double dt = dynamic ? 1.0 / m->rate : 1.0;
  for (int k = 0; k < Q && k < n_rows; k++) {
    const double *Fk = F_hist + (size_t)(n_rows - 1 - k) * M;
    const double *gk = dynamic ? m->g + (size_t)k * no : m->g_static;
    for (int e = 0; e < M; e++) {
      const int ei = e % nx, ej = e / nx;
      double s = 0;
      for (int p = 0; p < M; p++)
        s += gk[(size_t)(ej - p / nx + m->ny - 1) * m->nox + (ei - p % nx + nx - 1)] * Fk[p];
      d_el[e] += s * dt;
    }
  }
}
