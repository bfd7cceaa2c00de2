/* fem_solve.c — static solve K u = b over the free DOFs: CHOLMOD (supernodal
 * Cholesky, factor kept for reuse) or Jacobi-preconditioned CG. Dirichlet
 * DOFs are eliminated: K_ff u_f = b_f - K_fc u_c. What the solver keeps
 * between solves (factorisation, scratch) is its own fem_factor, owned by
 * the caller: the model stays const. */
#define _GNU_SOURCE /* RTLD_DEFAULT */
#include "fem_server/fem.h"

#include <dlfcn.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <suitesparse/cholmod.h>

struct fem_factor {
  /* the assembly this workspace belongs to (fem_static_solve checks it) */
  const int32_t *colptr, *rowind;
  const double *kval;
  int32_t n_eq, n_dof, nnz;
  cholmod_common c;
  cholmod_factor *L;
  cholmod_dense *X, *Y, *E; /* cholmod_solve2 workspaces, reused */
  cholmod_dense *B;
  double *rhs;              /* [n_eq] */
  double *full;             /* [n_dof] scratch */
  double *kuc;              /* [n_dof] K u_c */
  double *pcg;              /* [6*n_eq] PCG work: x r z p q 1/diag */
  fem_work work;            /* force kernel scratch for K u_c */
};

void fem_factor_free(fem_factor **pf) {
  fem_factor *f = *pf;
  if (!f) return;
  cholmod_free_factor(&f->L, &f->c);
  cholmod_free_dense(&f->X, &f->c);
  cholmod_free_dense(&f->Y, &f->c);
  cholmod_free_dense(&f->E, &f->c);
  cholmod_free_dense(&f->B, &f->c);
  cholmod_finish(&f->c);
  free(f->rhs);
  free(f->full);
  free(f->kuc);
  free(f->pcg);
  fem_work_free(&f->work);
  free(f);
  *pf = NULL;
}

const char *fem_blas_name(void) {
  static char name[64] = "unknown";
  FILE *fp = fopen("/proc/self/maps", "r");
  if (!fp) return name;
  char line[512];
  while (fgets(line, sizeof line, fp)) {
    if (strstr(line, "openblas")) { snprintf(name, sizeof name, "openblas"); break; }
    if (strstr(line, "libblas.so")) snprintf(name, sizeof name, "reference (libblas.so)");
    if (strstr(line, "mkl")) snprintf(name, sizeof name, "mkl");
  }
  fclose(fp);
  return name;
}

/* y = K x for the upper-stored symmetric CSC matrix (free DOFs). */
static void csc_symv(const fem_model *md, const double *x, double *y) {
  memset(y, 0, sizeof *y * (size_t)md->n_eq);
  for (int32_t j = 0; j < md->n_eq; j++) {
    double xj = x[j], s = 0;
    for (int32_t p = md->colptr[j]; p < md->colptr[j + 1]; p++) {
      int32_t i = md->rowind[p];
      double k = md->kval[p];
      y[i] += k * xj;
      if (i != j) s += k * x[i];
    }
    y[j] += s;
  }
}

static double norm2(const double *x, int32_t n) {
  double s = 0;
  for (int32_t i = 0; i < n; i++) s += x[i] * x[i];
  return sqrt(s);
}

/* rhs = b_f - (K u_c)_f, using the factor's scratch. */
static void reduced_rhs(const fem_model *md, fem_factor *f, const double *b) {
  int any = 0;
  for (int32_t i = 0; i < md->n_dof; i++) {
    f->full[i] = md->fixed[i] ? md->u_fixed[i] : 0;
    any |= f->full[i] != 0;
  }
  if (any) fem_internal_force(md, &f->work, f->full, f->kuc);
  for (int32_t i = 0; i < md->n_dof; i++)
    if (md->eq[i] >= 0) f->rhs[md->eq[i]] = b[i] - (any ? f->kuc[i] : 0);
}

static void scatter_solution(const fem_model *md, const double *xf, double *u) {
  for (int32_t i = 0; i < md->n_dof; i++) u[i] = md->eq[i] >= 0 ? xf[md->eq[i]] : md->u_fixed[i];
}

static fem_factor *factor_new(const fem_model *md, proto_err *err) {
  fem_factor *f = calloc(1, sizeof *f);
  if (!f) {
    proto_fail(err, "out of memory");
    return NULL;
  }
  f->colptr = md->colptr;
  f->rowind = md->rowind;
  f->kval = md->kval;
  f->n_eq = md->n_eq;
  f->n_dof = md->n_dof;
  f->nnz = md->colptr[md->n_eq];
  cholmod_start(&f->c);
  f->c.print = 0;
  f->rhs = malloc(sizeof *f->rhs * (size_t)md->n_eq);
  f->full = malloc(sizeof *f->full * (size_t)md->n_dof);
  f->kuc = malloc(sizeof *f->kuc * (size_t)md->n_dof);
  if (!f->rhs || !f->full || !f->kuc || fem_work_init(md, &f->work, err)) {
    fem_factor_free(&f);
    proto_fail(err, "out of memory (solver scratch)");
  }
  return f;
}

/* A cholmod_sparse view of the model's CSC arrays (no copy). cholmod_sparse
 * has no const members; analyze and factorize only read A. */
static cholmod_sparse csc_view(const fem_model *md) {
  cholmod_sparse A;
  memset(&A, 0, sizeof A);
  A.nrow = A.ncol = (size_t)md->n_eq;
  A.nzmax = (size_t)md->colptr[md->n_eq];
  A.p = (void *)md->colptr;
  A.i = (void *)md->rowind;
  A.x = (void *)md->kval;
  A.stype = 1; /* upper triangle stored */
  A.itype = CHOLMOD_INT;
  A.xtype = CHOLMOD_REAL;
  A.dtype = CHOLMOD_DOUBLE;
  A.sorted = 1;
  A.packed = 1;
  return A;
}

/* OpenBLAS splits the supernodal factorization's dense blocks by its thread
 * count, and the factor's last bits (so the tread's u0 and every step after)
 * followed the machine's cores: the paper scene's load at t = 0.15 s was
 * 57.19 N with one thread, 56.32 N with two (bench/results/tire_soil.md
 * "Hand-offs on one core"). CHOLMOD's BLAS runs on one thread, so a run gives
 * the same bits on every machine; the count is put back after. Looked up at
 * run time: another BLAS has no such call (reference BLAS has one thread). */
static int blas_threads(int n) {
  static int looked; /* once: a quasi-static tread solves every step */
  static int (*get)(void);
  static void (*set)(int);
  if (!looked) {
    get = (int (*)(void))dlsym(RTLD_DEFAULT, "openblas_get_num_threads");
    set = (void (*)(int))dlsym(RTLD_DEFAULT, "openblas_set_num_threads");
    looked = 1;
  }
  if (!get || !set || n < 1) return -1;
  const int before = get();
  set(n);
  return before;
}

static int cholmod_path_blas(const fem_model *md, fem_factor *f, fem_solve_stats *st,
                             proto_err *err) {
  cholmod_sparse A = csc_view(md);
  if (!f->L) {
    double t0 = proto_now();
    f->L = cholmod_analyze(&A, &f->c); /* AMD, METIS if AMD's fill is bad */
    double t1 = proto_now();
    if (!f->L || f->c.status < CHOLMOD_OK)
      return proto_fail(err, "CHOLMOD analyze failed (status %d)", f->c.status);
    cholmod_factorize(&A, f->L, &f->c);
    double t2 = proto_now();
    if (f->c.status == CHOLMOD_NOT_POSDEF)
      return proto_fail(err, "stiffness matrix not positive definite at column %zu: "
                        "is the body constrained against rigid motion (fixed group)?",
                        (size_t)f->L->minor);
    if (f->c.status < CHOLMOD_OK)
      return proto_fail(err, "CHOLMOD factorize failed (status %d)", f->c.status);
    /* a singular K (rigid motion left free) often factors with round-off
     * pivots instead of failing: check the condition estimate */
    double rcond = cholmod_rcond(f->L, &f->c);
    if (!(rcond > 1e-13)) {
      cholmod_free_factor(&f->L, &f->c);
      return proto_fail(err, "stiffness matrix is singular or not positive definite "
                        "(reciprocal condition estimate %.2g): is the body constrained "
                        "against rigid motion (fixed group)?", rcond);
    }
    if (st) {
      st->t_analyze = t1 - t0;
      st->t_factor = t2 - t1;
    }
    f->B = cholmod_zeros((size_t)md->n_eq, 1, CHOLMOD_REAL, &f->c);
    if (!f->B) return proto_fail(err, "out of memory (CHOLMOD rhs)");
  }
  memcpy(f->B->x, f->rhs, sizeof *f->rhs * (size_t)md->n_eq);
  double t3 = proto_now();
  if (!cholmod_solve2(CHOLMOD_A, f->L, f->B, NULL, &f->X, NULL, &f->Y, &f->E, &f->c))
    return proto_fail(err, "CHOLMOD solve failed (status %d)", f->c.status);
  if (st) {
    st->t_solve = proto_now() - t3;
    st->nnz_factor = f->c.lnz;
    st->memory_peak = (double)f->c.memory_usage;
  }
  return 0;
}

/* CHOLMOD's BLAS on one thread (blas_threads). */
static int cholmod_path(const fem_model *md, fem_factor *f, fem_solve_stats *st, proto_err *err) {
  const int before = blas_threads(1);
  const int rc = cholmod_path_blas(md, f, st, err);
  if (before > 0) blas_threads(before);
  return rc;
}

/* Jacobi-PCG on the CSC matrix from x = 0; work = 5*n_eq doubles. */
static int pcg_path(const fem_model *md, const double *rhs, double *x, double *work, double rtol,
                    fem_solve_stats *st, proto_err *err) {
  int32_t n = md->n_eq;
  double *r = work, *z = r + n, *p = z + n, *q = p + n, *dinv = q + n;
  for (int32_t j = 0; j < n; j++) dinv[j] = 1.0 / md->kval[md->colptr[j + 1] - 1]; /* diagonal is last */
  double bn = norm2(rhs, n), rz = 0;
  for (int32_t i = 0; i < n; i++) {
    x[i] = 0;
    r[i] = rhs[i];
    z[i] = dinv[i] * r[i];
    p[i] = z[i];
    rz += r[i] * z[i];
  }
  int it = 0, maxit = 20 * n + 100;
  double rn = bn;
  while (rn > rtol * bn && bn > 0) {
    if (++it > maxit)
      return proto_fail(err, "PCG did not converge in %d iterations (residual %.3g)", maxit, rn / bn);
    csc_symv(md, p, q);
    double pq = 0;
    for (int32_t i = 0; i < n; i++) pq += p[i] * q[i];
    if (!(pq > 0))
      return proto_fail(err, "PCG breakdown (p.Kp = %g): stiffness not positive definite "
                        "(is the body constrained against rigid motion?)", pq);
    double alpha = rz / pq, rz_new = 0;
    rn = 0;
    for (int32_t i = 0; i < n; i++) {
      x[i] += alpha * p[i];
      r[i] -= alpha * q[i];
      z[i] = dinv[i] * r[i];
      rz_new += r[i] * z[i];
      rn += r[i] * r[i];
    }
    rn = sqrt(rn);
    double beta = rz_new / rz;
    rz = rz_new;
    for (int32_t i = 0; i < n; i++) p[i] = z[i] + beta * p[i];
  }
  if (st) {
    st->iterations = it;
    st->memory_peak = 6.0 * sizeof(double) * n;
  }
  return 0;
}

int fem_static_solve(const fem_model *md, fem_factor **factor, fem_solver_kind kind, double rtol,
                     const double *b, double *u, fem_solve_stats *stats, proto_err *err) {
  if (!md->colptr) return proto_fail(err, "static solve before fem_model_assemble");
  if (stats) memset(stats, 0, sizeof *stats);
  if (!*factor && !(*factor = factor_new(md, err))) return -1;
  fem_factor *f = *factor;
  if (f->colptr != md->colptr || f->rowind != md->rowind || f->kval != md->kval ||
      f->n_eq != md->n_eq || f->n_dof != md->n_dof || f->nnz != md->colptr[md->n_eq])
    return proto_fail(err, "static solve: the solver workspace belongs to another model or an "
                      "earlier assembly (fem_factor_free it after fem_model_assemble)");
  reduced_rhs(md, f, b);
  double t0 = proto_now();
  const double *xf;
  if (kind == FEM_CHOLMOD) {
    if (cholmod_path(md, f, stats, err)) return -1;
    xf = f->X->x;
  } else {
    if (!f->pcg && !(f->pcg = malloc(sizeof *f->pcg * 6 * (size_t)md->n_eq)))
      return proto_fail(err, "out of memory (PCG work)");
    double *x = f->pcg + 5 * (size_t)md->n_eq;
    if (pcg_path(md, f->rhs, x, f->pcg, rtol > 0 ? rtol : 1e-10, stats, err)) return -1;
    if (stats) stats->t_solve = proto_now() - t0;
    xf = x;
  }
  scatter_solution(md, xf, u);
  if (stats) { /* residual over the free DOFs */
    double *uf = malloc(sizeof *uf * (size_t)md->n_eq), *ku = malloc(sizeof *ku * (size_t)md->n_eq);
    if (uf && ku) {
      for (int32_t i = 0; i < md->n_dof; i++)
        if (md->eq[i] >= 0) uf[md->eq[i]] = u[i];
      csc_symv(md, uf, ku);
      for (int32_t i = 0; i < md->n_eq; i++) ku[i] = f->rhs[i] - ku[i];
      double bn = norm2(f->rhs, md->n_eq);
      stats->residual = bn > 0 ? norm2(ku, md->n_eq) / bn : norm2(ku, md->n_eq);
    }
    free(uf);
    free(ku);
  }
  for (int32_t i = 0; i < md->n_dof; i++)
    if (!isfinite(u[i])) return proto_fail(err, "static solve produced a non-finite value at DOF %d", i);
  return 0;
}
