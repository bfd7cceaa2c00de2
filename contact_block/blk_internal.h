/* blk_internal.h — workspace shared by the block library's files (not public). */
#ifndef COSIM_BLK_INTERNAL_H
#define COSIM_BLK_INTERNAL_H

#include <fftw3.h>

#include "contact_block/blk.h"
#include "green/green.h"

/* FFTW planning, once in blk_state_create (never in the step loop). The
 * per-step transforms are measured from BLK_FFTW_MEASURE_MIN elements on
 * (512 × 512: a product takes 0.56 ms measured, 0.69 ms estimated, for
 * 0.6 s of planning); below, measuring the row/column plans costs more than
 * a run saves (20 × 20: 0.15 s of planning to save 2.6 µs a product). The
 * batched time transforms of the partitioned history run once per block,
 * measuring them costs more than it saves. */
enum { BLK_FFTW_MEASURE_MIN = 64 * 64 };
#define BLK_FFTW_STEP(M) ((M) >= BLK_FFTW_MEASURE_MIN ? FFTW_MEASURE : FFTW_ESTIMATE)
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

/* ---------------------------------------------------------- FFT products
 * y = K * x over the grid for an offset kernel K [noy][nox] (blk_fft.c):
 * linear convolution on a zero-padded box of Nx × Ny ≥ (2nx−1) × (2ny−1)
 * (Hockney), or circular on nx × ny for a periodic grid. The 2-D transforms
 * are split into row and column passes so that the rows that are all zero
 * (input) or not needed (output) are skipped: half the row work. */
typedef struct blk_fft {
  int nx, ny, Nx, Ny, nqx, periodic;
  double *box;        /* [Ny][Nx] */
  fftw_complex *spec; /* [Ny][nqx] */
  fftw_plan rows_fwd, cols_fwd, cols_inv, rows_inv;
} blk_fft;

/* Spectrum of a kernel on the box, normalised (1/(Nx Ny) folded in): real
 * for an even kernel (re), else complex (c). [Ny][nqx]. */
typedef struct blk_kspec {
  double *re;
  fftw_complex *c;
} blk_kspec;

int blk_fft_init(blk_fft *f, const blk_model *m, proto_err *err);
void blk_fft_free(blk_fft *f);
size_t blk_fft_bytes(const blk_fft *f);
/* Spectrum of scale · kern, kern [noy][nox] in the model's offset layout. */
int blk_fft_kernel(blk_fft *f, const blk_model *m, const double *kern, double scale,
                   blk_kspec *ks, proto_err *err);
/* An even kernel (g(Δ) = g(−Δ), reciprocity) has a real spectrum: true when
 * every |Im| is below BLK_REAL_SPECTRUM_TOL of the largest |Re| (the
 * round-off of the transform of the closed forms). */
#define BLK_REAL_SPECTRUM_TOL 1e-13
int blk_spectrum_is_real(const fftw_complex *spec, size_t n);
void blk_kspec_free(blk_kspec *ks);
size_t blk_kspec_bytes(const blk_fft *f, const blk_kspec *ks);
/* y[M] = K * x[M]; x and y may alias. */
void blk_fft_apply(blk_fft *f, const blk_kspec *ks, const double *x, double *y);

/* ------------------------------------------------------------- history */

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
  blk_history_kind kind; /* resolved (never AUTO) */
  int Qh;            /* samples used after tail truncation (0: quasi-static) */
  int64_t pushed;    /* force fields pushed so far */
  double dt;
  size_t bytes;
  /* direct sum: ring of past force fields [Qh][M] and their nonzero counts;
   * separable: the same ring, time sums y = Σ_{k≥1} T_k F(n−k) per element,
   * then d_old = Δt S * y by one FFT product */
  double *F_ring;
  int *nnz;
  double *y;          /* [M] separable time sums */
  blk_kspec S_hat;    /* separable: spectrum of Δt g_space */
  /* FFT: zero-padded Ny × Nx grid, spectra of g_k and of past forces; or,
   * packed (separable g), the elements two per complex bin */
  int packed;
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
  size_t bytes;       /* allocated by blk_state_create (blk_state_bytes) */
  blk_method method;  /* resolved (never BLK_AUTO) */
  /* compliance of this step's forces per element offset (translation
   * invariance): C[i][p] = kern[(j_i−j_p+ny−1)·nox + (i_i−i_p+nx−1)] */
  double *kern;
  double c_self;      /* its diagonal */
  int symmetric;      /* kern even: C symmetric */
  blk_fft fft;        /* products C·x (matrix-free, tangent, dense dual) */
  blk_kspec C_hat;
  /* shared per-step vectors [M] */
  double *b, *CF;     /* b = d_road + z − z_free − d_el_old; CF = C F at the end */
  int *held;          /* adhesive law per element for this sweep */
  /* dense (blk_dense.c) */
  int *col_idx;       /* [M] columns of C in a product, and their factors */
  double *col_f;
  double *r, *delta, *d_try, *F_try, *k_try, *sk, *y;
  int *act;           /* indices with k > 0 / the free set */
  double *A;          /* [A_cap][A_cap] Newton matrix (dense methods only) */
  int A_cap;          /* rows of A: M, or BLK_AUTO_DENSE_CAP for auto */
  int dense_overflow; /* the last dense solve found more free elements than A_cap */
  int auto_dense;     /* auto: the dense dual may be used (springs, symmetric C) */
  int *piv;
  /* the last Cholesky factor of the Newton matrix, kept for chord steps
   * (solver.reuse_jacobian) and the tangent: its kind (BLK_FACT_*), active
   * set and √k (primal) */
  int fact_valid, fact_P;
  int *fact_act;
  double *fact_sk;
  /* matrix-free (blk_cg.c) */
  double *g, *Dk, *dF, *wC, *rho, *z, *t, *q, *qc, *Fn, *dn, *un, *prec, *psi;
  blk_history hist;
};

/* blk_spring.c: spring law of this sweep (compression branch; with adhesion
 * the mirrored tensile branch for held elements, seed 002 ch. 5.1). */
void blk_spring_law(const blk_model *m, const int *held, const double *d, double *F,
                    double *k);
/* d(F) warm-started from d0 (≥ 0), for F ≥ 0. */
double blk_spring_inverse_from(const blk_model *m, int e, double F, double d0);
/* Spring terms of the dual at force F of element e (the convex dual of the
 * per-step problem, README "Solvers"): the signed compression d(F)
 * (mirrored for F < 0), 1/k at d (capped), returns Ψ(F) = |F| d − W(d).
 * Rigid springs: all zero. d_guess: warm start. */
double blk_dual_element(const blk_model *m, const blk_work *w, int e, double F,
                        double d_guess, double *d, double *inv_k);
/* The knot energies spr_W of every table (after the tables are set). */
void blk_springs_energies(blk_model *m);

/* 1/k used at the contact onset of a spring with k(0) = 0: far softer than
 * the layer (× its self-compliance), so the element barely moves a Newton
 * step (1 m/N if the step has no instantaneous compliance). */
#define BLK_INV_K_CAP 1e8
static inline double blk_inverse_stiffness(const blk_work *w, double k) {
  return k > 0 ? 1.0 / k : w->c_self > 0 ? BLK_INV_K_CAP * w->c_self : 1.0;
}

/* Armijo constant of the backtracking line searches (sufficient decrease
 * c·λ·slope, the usual 1e-4), and the relative decrease of
 * J below which it is round-off of J: the step is taken as it is. */
#define BLK_ARMIJO 1e-4
#define BLK_DECREASE_ROUNDOFF 1e-13
/* Backtracking halvings of the dual line searches (2^-40: no decrease left)
 * and of the primal Newton's on ½|r|² (2^-30). */
enum { BLK_MAX_CUTS = 40, BLK_PRIMAL_CUTS = 30 };

/* blk_dense.c — dense solvers; on return w->CF = C F at the final forces.
 * Return the iterations used; *conv, *rmax (max |f|, m), *cuts, *factored. */
int blk_dense_newton(const blk_model *m, blk_state *s, int *conv, double *rmax,
                     int *cuts, int *factored);
int blk_dense_dual(const blk_model *m, blk_state *s, int *conv, double *rmax, int *cuts,
                   int *factored);
enum { BLK_FACT_NONE = 0, BLK_FACT_PRIMAL = 1, BLK_FACT_DUAL = 2 };
/* The tangent preconditioned by the kept factor; -1 if none fits. */
int blk_dense_tangent(const blk_model *m, blk_state *s, double tol, double *K,
                      int *products);
/* blk_cg.c — matrix-free dual solver (same contract) and the tangent
 * stiffness 1ᵀ(C_AA + diag(1/k_A))⁻¹1 over the loaded elements. */
int blk_cg_solve(const blk_model *m, blk_state *s, int *conv, double *rmax, int *products);
double blk_cg_tangent(const blk_model *m, blk_state *s, int *products);
/* relative residual of the tangent's linear solve: 1ᵀx is stationary at the
 * solution (an energy), its error quadratic in the residual — 1e-6 gives the
 * tangent to about 1e-12 (measured: the same 10 digits as 1e-8). */
#define BLK_TANGENT_TOL 1e-6

int blk_history_init(const blk_model *m, blk_work *w, blk_history *h, proto_err *err);
void blk_history_free(blk_history *h);
void blk_history_reset(const blk_model *m, blk_history *h);
/* Pushes the force field of the step just solved and returns, in d_old, the
 * history term (eq. 5) of the next step. */
void blk_history_push(const blk_model *m, blk_work *w, blk_history *h, const double *F,
                      double *d_old);

#endif
