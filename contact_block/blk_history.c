/* blk_history.c — the history term d_el_old (seed 002 eq. 5): the response
 * at the next step to all past forces. The layer is translation-invariant,
 * so g depends on the element offset only: the spatial sum is a 2-D linear
 * convolution, done with FFTs on a zero-padded 2nx × 2ny grid (Hockney), and
 * the time sum runs per spatial frequency over a ring of past force spectra:
 * the latest lags directly, older ones block-wise with FFTs in time (levels
 * of a non-uniformly partitioned convolution). A separable g (g_time ⊗
 * g_space, the synthetic layer) needs far less: the time sums per element
 * over a ring of past forces, then one spatial FFT product (large grids).
 * The direct double sum is kept as the reference (solver.history = "direct"). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "contact_block/blk_internal.h"

/* Samples kept: up to the last one with max|g_k| above tail_tol·max|g|. */
static int truncated_length(const blk_model *m) {
  const size_t no = (size_t)m->nox * m->noy;
  double gmax = 0;
  if (m->g_time) { /* separable: |g(k; o)| = |T_k| |S(o)| */
    for (int k = 0; k < m->Q; k++) gmax = fmax(gmax, fabs(m->g_time[k]));
    int Qh = 1;
    for (int k = 0; k < m->Q; k++)
      if (fabs(m->g_time[k]) > m->solver.tail_tol * gmax) Qh = k + 1;
    return Qh;
  }
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
  memset(pad, 0, (size_t)h->Nx * h->Ny * sizeof(double));
  /* periodic: circular on nx × ny, the offsets 0..n−1 (K(Δ) = K(Δ − n)) */
  const int lo_j = m->periodic ? 0 : -(m->ny - 1), lo_i = m->periodic ? 0 : -(m->nx - 1);
  for (int dj = lo_j; dj <= m->ny - 1; dj++)
    for (int di = lo_i; di <= m->nx - 1; di++) {
      int pj = (dj + h->Ny) % h->Ny, pi = (di + h->Nx) % h->Nx;
      pad[pj * h->Nx + pi] =
          blk_green_at(m, k, (size_t)(dj + m->ny - 1) * m->nox + (di + m->nx - 1));
    }
}


/* One level of the partitioned time convolution: block B, segments s = 1..S
 * covering the lags s·B+1 .. s·B+B (capped at k_end), convolved once per
 * block of B steps with FFTs of length 2B (uniformly partitioned
 * overlap-save). Everything is time-major, [2B][nq]: a window is a copy of
 * 2B rows of the force-spectrum ring, FFTW transforms the nq bins as a
 * strided batch, and the product sum runs over contiguous bin rows. With a
 * real ĝ (even kernel) a segment is real in time, its spectrum Hermitian, and
 * only the bins 0..B are kept (hl = B+1). */
static int level_init(blk_history *h, blk_level *lv, int B, int k_end, proto_err *err) {
  const int nq = h->nq, L = 2 * B;
  lv->B = B;
  lv->S = (k_end - B + B - 1) / B;
  lv->hl = h->ghat_re ? B + 1 : L;
  const size_t seg = (size_t)nq * L;
  lv->seg_hat = fftw_malloc((size_t)lv->S * nq * lv->hl * sizeof(fftw_complex));
  lv->fdl = fftw_malloc((size_t)lv->S * seg * sizeof(fftw_complex));
  lv->win = fftw_malloc(seg * sizeof(fftw_complex));
  if (!lv->seg_hat || !lv->fdl || !lv->win) return proto_fail(err, "out of memory");
  const int n[1] = {L};
  lv->tfwd = fftw_plan_many_dft(1, n, nq, lv->win, NULL, nq, 1, lv->win, NULL, nq, 1,
                                FFTW_FORWARD, BLK_FFTW_BLOCK);
  lv->tinv = fftw_plan_many_dft(1, n, nq, lv->win, NULL, nq, 1, lv->win, NULL, nq, 1,
                                FFTW_BACKWARD, BLK_FFTW_BLOCK);
  if (!lv->tfwd || !lv->tinv) return proto_fail(err, "history: FFTW planning failed");
  /* segment s (1..S): h_s[i] = ĝ_{sB+1+i}, i < B, zero-padded to 2B; the
   * 1/(2B) of the inverse transform is folded in here. Stored [hl][S][nq]. */
  for (int s = 1; s <= lv->S; s++) {
    memset(lv->win, 0, seg * sizeof(fftw_complex));
    for (int i = 0; i < B && s * B + 1 + i <= k_end; i++) {
      const fftw_complex *g = h->ghat + (size_t)(s * B + 1 + i) * nq;
      for (int q = 0; q < nq; q++) {
        lv->win[(size_t)i * nq + q][0] = g[q][0] / L;
        lv->win[(size_t)i * nq + q][1] = g[q][1] / L;
      }
    }
    fftw_execute(lv->tfwd);
    for (int w = 0; w < lv->hl; w++)
      memcpy(lv->seg_hat + ((size_t)w * lv->S + (s - 1)) * nq, lv->win + (size_t)w * nq,
             (size_t)nq * sizeof(fftw_complex));
  }
  return 0;
}

/* Levels (non-uniform partition, Gardner 1995): lags 1..B0 summed directly,
 * then levels of blocks growing 4×, each covering lags B+1 .. 4B (3
 * segments), the last one the rest up to Qh−1, opened while more than 3
 * blocks of the next size are left (measured: opening levels earlier, for
 * fewer segments, was slower). Each lag costs the head
 * a product per step; a segment costs about two per step, whatever its
 * length (plus the level's FFTs and window copy, about as much). */
static int partition_init(blk_history *h, proto_err *err) {
  int B = 8;
  if (h->Qh - 1 <= 3 * B) return 0;
  h->head = B;
  while (h->n_lev < BLK_MAX_LEVELS) {
    const int last = h->n_lev == BLK_MAX_LEVELS - 1 || h->Qh - 1 <= 3 * (4 * B);
    if (level_init(h, &h->lev[h->n_lev], B, last ? h->Qh - 1 : 4 * B, err)) return -1;
    h->n_lev++;
    if (last) break;
    B *= 4;
  }
  return 0;
}

/* acc[q] += H[q]·W[q] over a row of nq bins (conj: H̄[q]·W[q]). */
BLK_HOT static void row_mac(const double *restrict H, const double *restrict W,
                            double *restrict acc, int nq, int conj) {
  if (conj) {
    for (int i = 0; i < 2 * nq; i += 2) {
      acc[i] += H[i] * W[i] + H[i + 1] * W[i + 1];
      acc[i + 1] += H[i] * W[i + 1] - H[i + 1] * W[i];
    }
    return;
  }
  for (int i = 0; i < 2 * nq; i += 2) {
    acc[i] += H[i] * W[i] - H[i + 1] * W[i + 1];
    acc[i + 1] += H[i] * W[i + 1] + H[i + 1] * W[i];
  }
}

/* At a block start (pushed = J·B): the lags > B of the outputs J·B .. J·B+B−1
 * only need inputs up to J·B − 2, all known. Window W_{J−1} = x[(J−2)B−1 ..
 * JB−2] enters the delay line; win = IFFT(Σ_s Ĥ_s Ŵ_{J−s}), whose last B rows
 * are this level's part of the next B outputs. */
static void level_block(blk_history *h, blk_level *lv) {
  const int B = lv->B, L = 2 * B, nq = h->nq, S = lv->S, hl = lv->hl;
  const int64_t J = h->pushed / B;
  const size_t seg = (size_t)nq * L, row = (size_t)nq * sizeof(fftw_complex);
  fftw_complex *W = lv->fdl + (size_t)((J - 1) % S) * seg;
  const int64_t t0 = (J - 2) * B - 1;
  for (int t = 0; t < L; t++) {
    const int64_t x = t0 + t;
    if (x < 0 || x >= h->pushed) memset(W + (size_t)t * nq, 0, row);
    else memcpy(W + (size_t)t * nq, h->F_hat + (size_t)(x % h->Qh) * nq, row);
  }
  fftw_execute_dft(lv->tfwd, W, W);
  for (int w = 0; w < L; w++) { /* frequency by frequency: acc row stays in L1 */
    double *acc = (double *)(lv->win + (size_t)w * nq);
    memset(acc, 0, row);
    /* Hermitian segments: H(L−ω) = conj H(ω) */
    const int wh = w < hl ? w : L - w, conj = w >= hl;
    for (int s = 1; s <= S && J - s >= 0; s++)
      row_mac((const double *)(lv->seg_hat + ((size_t)wh * S + (s - 1)) * nq),
              (const double *)(lv->fdl + (size_t)((J - s) % S) * seg + (size_t)w * nq),
              acc, nq, conj);
  }
  fftw_execute(lv->tinv);
}

/* auto, separable g: the partitioned `fft` history costs O(M log Qh) per
 * step against the separable ring's O(M Qh), and was as fast or faster at
 * every size measured (32²-128², Qh 256-2048: bench/results/block.md
 * "History against the memory length"; 64², Qh 2048: 1.3 against 3.0 ms per
 * step), but it keeps about BLK_HIST_FFT_BYTES_PER_LAG bytes per element per
 * lag against the ring's 8 (the force ring, the top level's delay line and
 * segment spectra). So auto takes `fft` while that stays under
 * BLK_HIST_FFT_MAX_BYTES (1 GiB: four lug processes of 64² at Qh 2048 keep
 * 1 GB on a 24 GiB machine; 512² at Qh 256 would need 2.1 GB) and the
 * separable ring beyond it. */
#define BLK_HIST_FFT_BYTES_PER_LAG 32.0       /* bytes / (element lag), measured 31 */
#define BLK_HIST_FFT_MAX_BYTES (1024.0 * 1024 * 1024) /* bytes */

static void *track(blk_history *h, size_t n, size_t size) {
  void *p = calloc(n ? n : 1, size);
  if (p) h->bytes += n * size;
  return p;
}

/* direct and separable: the ring of past force fields; separable also the
 * time sums y and the spectrum of Δt g_space (d_old = Δt S * y). */
static int ring_init(const blk_model *m, blk_work *w, blk_history *h, proto_err *err) {
  h->F_ring = track(h, (size_t)h->Qh * m->M, sizeof(double));
  h->nnz = track(h, (size_t)h->Qh, sizeof(int));
  if (!h->F_ring || !h->nnz) return proto_fail(err, "out of memory (history ring %d x %d)",
                                               h->Qh, m->M);
  if (h->kind == BLK_HIST_DIRECT) return 0;
  h->y = track(h, (size_t)m->M, sizeof(double));
  if (!h->y) return proto_fail(err, "out of memory");
  if (blk_fft_kernel(&w->fft, m, m->g_space, h->dt, &h->S_hat, err)) return -1;
  h->bytes += blk_kspec_bytes(&w->fft, &h->S_hat);
  return 0;
}

/* fft: the bins of the time convolution — the spatial frequencies of a
 * zero-padded (or periodic) box; for a separable g the elements themselves,
 * two real fields packed per complex bin (T_k is real, so real and imaginary
 * parts stay apart), and one product with Δt·S at the end — and the spectra
 * rings. */
static int bins_alloc(const blk_model *m, blk_history *h, proto_err *err) {
  h->packed = m->g_time != NULL;
  h->Nx = m->periodic ? m->nx : 2 * m->nx;
  h->Ny = m->periodic ? m->ny : 2 * m->ny;
  h->nq = h->packed ? (m->M + 1) / 2 : h->Ny * (h->Nx / 2 + 1);
  if (!h->packed) h->pad = fftw_malloc((size_t)h->Nx * h->Ny * sizeof(double));
  h->ghat = fftw_malloc((size_t)h->Qh * h->nq * sizeof(fftw_complex));
  h->F_hat = fftw_malloc((size_t)h->Qh * h->nq * sizeof(fftw_complex));
  h->acc = fftw_malloc((size_t)h->nq * sizeof(fftw_complex));
  h->nnz = calloc((size_t)h->Qh, sizeof(int));
  if ((!h->pad && !h->packed) || !h->ghat || !h->F_hat || !h->acc || !h->nnz)
    return proto_fail(err, "out of memory");
  h->bytes += (h->packed ? 0 : (size_t)h->Nx * h->Ny * sizeof(double)) +
              (size_t)(h->Qh + 1) * h->nq * sizeof(fftw_complex) + h->Qh * sizeof(int);
  return 0;
}

/* ĝ_k per bin: packed, Δt T_k in every bin (then Δt·S by one product);
 * else the spectra of g_k scaled by Δt / (Nx Ny) (FFTW's unnormalised
 * inverse), with the step's plans. */
static int kernel_spectra(const blk_model *m, blk_work *w, blk_history *h, proto_err *err) {
  if (h->packed) {
    h->y = track(h, (size_t)2 * h->nq, sizeof(double));
    if (!h->y) return proto_fail(err, "out of memory");
    for (int k = 0; k < h->Qh; k++)
      for (int q = 0; q < h->nq; q++) {
        h->ghat[(size_t)k * h->nq + q][0] = h->dt * m->g_time[k];
        h->ghat[(size_t)k * h->nq + q][1] = 0;
      }
    if (blk_fft_kernel(&w->fft, m, m->g_space, 1.0, &h->S_hat, err)) return -1;
    h->bytes += blk_kspec_bytes(&w->fft, &h->S_hat);
    return 0;
  }
  const unsigned flags = BLK_FFTW_STEP(m->M);
  h->fwd = fftw_plan_dft_r2c_2d(h->Ny, h->Nx, h->pad, h->acc, flags);
  h->inv = fftw_plan_dft_c2r_2d(h->Ny, h->Nx, h->acc, h->pad, flags);
  if (!h->fwd || !h->inv) return proto_fail(err, "history: FFTW planning failed");
  const double scale = h->dt / ((double)h->Nx * h->Ny);
  for (int k = 0; k < h->Qh; k++) {
    place_kernel(m, h, k, h->pad);
    fftw_execute_dft_r2c(h->fwd, h->pad, h->ghat + (size_t)k * h->nq);
    for (int q = 0; q < h->nq; q++) {
      h->ghat[(size_t)k * h->nq + q][0] *= scale;
      h->ghat[(size_t)k * h->nq + q][1] *= scale;
    }
  }
  return 0;
}

/* A real ĝ (even kernel): the lags summed directly keep each real ĝ twice
 * (Re, Im) in ghat_re2; the full spectra were only needed to build the
 * segments and this, they are freed. */
static int keep_real_head(blk_history *h, proto_err *err) {
  const int nk = h->n_lev ? h->head + 1 : h->Qh;
  h->ghat_re2 = malloc((size_t)nk * 2 * h->nq * sizeof(double));
  if (!h->ghat_re2) return proto_fail(err, "out of memory");
  h->bytes += (size_t)nk * 2 * h->nq * sizeof(double);
  for (size_t i = 0; i < (size_t)nk * h->nq; i++)
    h->ghat_re2[2 * i] = h->ghat_re2[2 * i + 1] = h->ghat_re[i];
  free(h->ghat_re);
  fftw_free(h->ghat);
  h->ghat_re = NULL;
  h->ghat = NULL;
  h->bytes -= (size_t)h->Qh * h->nq * sizeof(fftw_complex);
  return 0;
}

int blk_history_init(const blk_model *m, blk_work *w, blk_history *h, proto_err *err) {
  memset(h, 0, sizeof *h);
  if (m->solver.quasi_static || (!m->g && !m->g_time)) return 0;
  h->kind = m->solver.history;
  h->Qh = truncated_length(m);
  if (h->kind == BLK_HIST_AUTO)
    h->kind = m->g_time && BLK_HIST_FFT_BYTES_PER_LAG * m->M * h->Qh > BLK_HIST_FFT_MAX_BYTES
                  ? BLK_HIST_SEPARABLE
                  : BLK_HIST_FFT;
  if (h->kind == BLK_HIST_SEPARABLE && !m->g_time)
    return proto_fail(err, "solver.history = separable needs a separable Green's function "
                      "(the synthetic layer); this one (%s) is stored in full", m->green_model);
  h->dt = 1.0 / m->rate;
  if (h->Qh < 2) return 0; /* instantaneous response only: no history */
  if (h->kind == BLK_HIST_DIRECT || h->kind == BLK_HIST_SEPARABLE)
    return ring_init(m, w, h, err);
  if (bins_alloc(m, h, err) || kernel_spectra(m, w, h, err)) return -1;
  /* an even kernel (g(Δ) = g(−Δ)) has a real spectrum: keep only Re */
  if (blk_spectrum_is_real(h->ghat, (size_t)h->Qh * h->nq)) {
    h->ghat_re = malloc((size_t)h->Qh * h->nq * sizeof(double));
    if (!h->ghat_re) return proto_fail(err, "out of memory");
    for (size_t i = 0; i < (size_t)h->Qh * h->nq; i++) h->ghat_re[i] = h->ghat[i][0];
  }
  if (partition_init(h, err)) return -1;
  if (h->ghat_re && keep_real_head(h, err)) return -1;
  for (int l = 0; l < h->n_lev; l++) {
    const blk_level *lv = &h->lev[l];
    h->bytes += (size_t)(lv->S * lv->hl + (lv->S + 1) * 2 * lv->B) * h->nq *
                sizeof(fftw_complex);
  }
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
  for (int l = 0; l < BLK_MAX_LEVELS; l++) {
    blk_level *lv = &h->lev[l];
    if (lv->tfwd) fftw_destroy_plan(lv->tfwd);
    if (lv->tinv) fftw_destroy_plan(lv->tinv);
    fftw_free(lv->seg_hat);
    fftw_free(lv->fdl);
    fftw_free(lv->win);
  }
  free(h->ghat_re);
  free(h->ghat_re2);
  free(h->F_ring);
  free(h->nnz);
  free(h->y);
  blk_kspec_free(&h->S_hat);
  memset(h, 0, sizeof *h);
}

void blk_history_reset(const blk_model *m, blk_history *h) {
  h->pushed = 0;
  if (h->F_ring) memset(h->F_ring, 0, (size_t)h->Qh * m->M * sizeof(double));
  if (h->F_hat) memset(h->F_hat, 0, (size_t)h->Qh * h->nq * sizeof(fftw_complex));
  if (h->nnz) memset(h->nnz, 0, (size_t)h->Qh * sizeof(int));
  for (int l = 0; l < h->n_lev; l++) {
    const blk_level *lv = &h->lev[l];
    memset(lv->fdl, 0, (size_t)lv->S * h->nq * 2 * lv->B * sizeof(fftw_complex));
    memset(lv->win, 0, (size_t)2 * lv->B * h->nq * sizeof(fftw_complex));
  }
}

/* The force field of the step just solved into the real-space ring. */
static void ring_push(const blk_model *m, blk_history *h, const double *F) {
  const int slot = (int)(h->pushed % h->Qh);
  double *row = h->F_ring + (size_t)slot * m->M;
  int nnz = 0;
  for (int e = 0; e < m->M; e++) {
    row[e] = F[e];
    nnz += F[e] != 0.0;
  }
  h->nnz[slot] = nnz;
  h->pushed++;
}

static void push_direct(const blk_model *m, blk_history *h, const double *F,
                        double *d_old) {
  const int Qh = h->Qh, M = m->M, nx = m->nx;
  ring_push(m, h, F);
  memset(d_old, 0, (size_t)M * sizeof(double));
  /* next step n+1 = pushed: d_old = Δt Σ_{k≥1} Σ_p g(k; m−p) F_p(n+1−k) */
  for (int k = 1; k < Qh && k <= h->pushed; k++) {
    const int s = (int)((h->pushed - k) % Qh);
    if (!h->nnz[s]) continue;
    const double *Fk = h->F_ring + (size_t)s * M;
    for (int p = 0; p < M; p++) {
      if (Fk[p] == 0.0) continue;
      const int pi = p % nx, pj = p / nx;
      const double f = Fk[p] * h->dt;
      for (int e = 0; e < M; e++) {
        const int ei = e % nx, ej = e / nx;
        d_old[e] +=
            f * blk_green_at(m, k, (size_t)(ej - pj + m->ny - 1) * m->nox + (ei - pi + nx - 1));
      }
    }
  }
}

BLK_HOT static void push_fft(const blk_model *m, blk_work *w, blk_history *h, const double *F,
                             double *d_old) {
  const int Qh = h->Qh, nq = h->nq, nx = m->nx, ny = m->ny;
  const int slot = (int)(h->pushed % Qh);
  fftw_complex *Fs = h->F_hat + (size_t)slot * nq;
  int nnz = 0;
  for (int e = 0; e < m->M; e++) nnz += F[e] != 0.0;
  h->nnz[slot] = nnz;
  if (h->packed) { /* elements p and p + nq as one complex bin */
    for (int q = 0; q < nq; q++) {
      Fs[q][0] = F[q];
      Fs[q][1] = q + nq < m->M ? F[q + nq] : 0.0;
    }
  } else if (nnz) {
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
  int head = Qh; /* lags summed directly: all, or 1..B0 with the partitioned rest */
  memset(acc, 0, (size_t)nq * sizeof(fftw_complex));
  for (int l = 0; l < h->n_lev; l++) {
    blk_level *lv = &h->lev[l];
    if (h->pushed % lv->B == 0) level_block(h, lv);
    const double *t = (const double *)(lv->win + (size_t)(lv->B + h->pushed % lv->B) * nq);
    for (int q = 0; q < 2 * nq; q++) acc[q] += t[q];
  }
  if (h->n_lev) {
    head = h->head + 1;
    any = h->pushed > h->head;
  }
  for (int k = 1; k < head && k <= h->pushed; k++) {
    const int s = (int)((h->pushed - k) % Qh);
    if (!h->nnz[s]) continue;
    any = 1;
    const double *a = (const double *)(h->F_hat + (size_t)s * nq);
    if (h->ghat_re2) { /* real ĝ stored twice per bin: a plain streaming loop */
      const double *g = h->ghat_re2 + (size_t)k * 2 * nq;
      for (int q = 0; q < 2 * nq; q++) acc[q] += g[q] * a[q];
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
  if (h->packed) { /* the time sums per element, then Δt-weighted S * y */
    for (int q = 0; q < nq; q++) {
      h->y[q] = acc[2 * q];
      if (q + nq < m->M) h->y[q + nq] = acc[2 * q + 1];
    }
    blk_fft_apply(&w->fft, &h->S_hat, h->y, d_old);
    return;
  }
  fftw_execute_dft_c2r(h->inv, h->acc, h->pad);
  for (int j = 0; j < ny; j++)
    for (int i = 0; i < nx; i++) d_old[j * nx + i] = h->pad[j * h->Nx + i];
}

/* Separable g: y_p = Σ_{k≥1} T_k F_p(n+1−k) over the ring (rows with no load
 * skipped), then d_old = Δt S * y by one FFT product. */
BLK_HOT static void push_separable(const blk_model *m, blk_work *w, blk_history *h,
                                   const double *F, double *d_old) {
  const int Qh = h->Qh, M = m->M;
  ring_push(m, h, F);
  double *restrict y = h->y;
  memset(y, 0, (size_t)M * sizeof(double));
  int any = 0;
  for (int k = 1; k < Qh && k <= h->pushed; k++) {
    const int s = (int)((h->pushed - k) % Qh);
    if (!h->nnz[s]) continue;
    any = 1;
    const double T = m->g_time[k], *restrict Fk = h->F_ring + (size_t)s * M;
    for (int p = 0; p < M; p++) y[p] += T * Fk[p];
  }
  if (!any) {
    memset(d_old, 0, (size_t)M * sizeof(double));
    return;
  }
  blk_fft_apply(&w->fft, &h->S_hat, y, d_old);
}

void blk_history_push(const blk_model *m, blk_work *w, blk_history *h, const double *F,
                      double *d_old) {
  if (h->Qh < 2) {
    memset(d_old, 0, (size_t)m->M * sizeof(double));
    return;
  }
  switch (h->kind) {
  case BLK_HIST_SEPARABLE: push_separable(m, w, h, F, d_old); break;
  case BLK_HIST_DIRECT: push_direct(m, h, F, d_old); break;
  default: push_fft(m, w, h, F, d_old);
  }
}
