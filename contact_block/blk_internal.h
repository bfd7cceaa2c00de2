/* blk_internal.h — workspace shared by the block library's files (not public). */
#ifndef COSIM_BLK_INTERNAL_H
#define COSIM_BLK_INTERNAL_H

#include <fftw3.h>

#include "contact_block/blk.h"

/* FFTW planning, once in blk_state_create (never in the step loop): the
 * per-step 2-D transforms are measured (×4 case: step loop ~5-9 % faster for
 * ~0.1 s more set-up); the batched time transforms of the partitioned
 * history run once per block, measuring them costs more than it saves. */
#define BLK_FFTW_STEP FFTW_MEASURE
#define BLK_FFTW_BLOCK FFTW_ESTIMATE

/* The hot loops (history product sums, compliance columns, Cholesky) get an
 * AVX2 clone picked at load time (GCC function multiversioning); the build
 * stays portable. Without -ffp-contract (ISO C mode) no FMA is formed and
 * the loops are element-wise, so both clones give the same bits. */
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && \
    !defined(__SANITIZE_ADDRESS__)
#define BLK_HOT __attribute__((target_clones("avx2", "default")))
#else
#define BLK_HOT
#endif

/* One level of the partitioned time convolution (blk_history.c). */
enum { BLK_MAX_LEVELS = 6 };
typedef struct blk_level {
  int B, S, hl;           /* block, segments, stored bins per segment */
  fftw_complex *seg_hat;  /* [hl][S][nq] spectra of the g segments (hl = B+1
                             bins when ĝ is real: Hermitian in time, else 2B) */
  fftw_complex *fdl;      /* [S][2B][nq] frequency-domain delay line of windows */
  fftw_complex *win;      /* [2B][nq] product sum; after the inverse FFT its
                             rows B..2B−1 are this level's part of the next B
                             outputs */
  fftw_plan tfwd, tinv;
} blk_level;

typedef struct blk_history {
  int Qh;            /* samples used after tail truncation (0: quasi-static) */
  int64_t pushed;    /* force fields pushed so far */
  double dt;
  /* direct sum: ring of past force fields [Qh][M] and their nonzero counts */
  double *F_ring;
  int *nnz;
  /* FFT: zero-padded Ny × Nx grid, spectra of g_k and of past forces */
  int Nx, Ny, nq;
  double *pad;
  fftw_complex *ghat;   /* [Qh][nq] */
  double *ghat_re;      /* [Qh][nq] when g is even in the offset (reciprocity):
                           its spectrum is real, half the multiply-adds */
  double *ghat_re2;     /* [lags summed directly][nq][2]: ghat_re twice per bin */
  fftw_complex *F_hat;  /* [Qh][nq] ring */
  fftw_complex *acc;    /* [nq] */
  fftw_plan fwd, inv;
  /* non-uniformly partitioned overlap-save in time (per spatial bin): lags
   * 1..head summed directly, longer lags by levels of growing block size */
  int head, n_lev;
  blk_level lev[BLK_MAX_LEVELS];
} blk_history;

struct blk_work {
  double *C;    /* [M][M] compliance of this step's forces (Δt g(0) or static) */
  /* the same compliance per element offset (translation invariance):
   * C[i][p] = kern[(j_i−j_p+ny−1)·nox + (i_i−i_p+nx−1)], [noy][nox] (fits
   * L1, unlike C): the products C·F in the Newton iteration */
  double *kern;
  int *col_idx;   /* [M] columns of C in a product, and their factors */
  double *col_f;
  int symmetric;
  double *b, *r, *delta, *d_try, *F_try, *k_try, *CF, *sk;
  int *held;    /* adhesive law per element for this sweep */
  int *act;     /* indices with k > 0 */
  double *A;    /* [M][M] Newton matrix */
  double *y;
  int *piv;
  /* the last Cholesky factor of the Newton matrix, kept for chord steps
   * (solver.reuse_jacobian): its active set and √k */
  int fact_valid, fact_P;
  int *fact_act;
  double *fact_sk;
  blk_history hist;
};

int blk_history_init(const blk_model *m, blk_history *h, proto_err *err);
void blk_history_free(blk_history *h);
void blk_history_reset(const blk_model *m, blk_history *h);
/* Pushes the force field of the step just solved and returns, in d_old, the
 * history term (eq. 5) of the next step. */
void blk_history_push(const blk_model *m, blk_history *h, const double *F,
                      double *d_old);

#endif
