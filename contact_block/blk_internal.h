/* blk_internal.h — workspace shared by the block library's files (not public). */
#ifndef COSIM_BLK_INTERNAL_H
#define COSIM_BLK_INTERNAL_H

#include <fftw3.h>

#include "contact_block/blk.h"

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
  fftw_complex *F_hat;  /* [Qh][nq] ring */
  fftw_complex *acc;    /* [nq] */
  fftw_plan fwd, inv;
  /* uniformly partitioned overlap-save in time (per spatial bin): lags
   * 1..B summed directly ("head"), lags > B in S segments of B samples,
   * convolved once per block of B steps with FFTs of length 2B */
  int B, S;
  fftw_complex *seg_hat;  /* [S][nq][2B] spectra of the g segments */
  fftw_complex *fdl;      /* [S][nq][2B] frequency-domain delay line of windows */
  fftw_complex *win;      /* [nq][2B] work */
  fftw_complex *tail;     /* [B][nq] tail part of the next B outputs */
  fftw_plan tfwd, tinv;
} blk_history;

struct blk_work {
  double *C;    /* [M][M] compliance of this step's forces (Δt g(0) or static) */
  double *Ct;   /* its transpose (= C when symmetric): column p contiguous */
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
