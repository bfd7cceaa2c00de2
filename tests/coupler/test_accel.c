/* The implicit scheme's accelerators on affine fixed-point problems
 * x = H(x) = A x + b (Degroote et al. 2009; Walker & Ni 2011): IQN-ILS is
 * equivalent to GMRES there, so from the first relaxation step it reaches
 * the fixed point within m + 1 further evaluations for m unknowns, and a
 * next step with the same A (reused columns) at once; with two fields of
 * very different scale (per-field weights) too. Constant relaxation and
 * Aitken converge only when H is a contraction; a diverging map stays
 * diverging for them. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "coupler/runner.h"
#include "cosim_test.h"

#define M 6

static double A[M][M], b[M], scale[M];

static void H(const double *x, double *y) {
  for (int i = 0; i < M; i++) {
    y[i] = b[i];
    for (int j = 0; j < M; j++) y[i] += A[i][j] * x[j] * scale[i] / scale[j];
  }
}

/* Iterations to converge (tolerance tol), or max + 1. */
static int solve(cpl_accel *a, double *x, int max) {
  double y[M], res[2];
  const double *base[2] = {NULL, NULL};
  cpl_accel_begin(a);
  int it;
  for (it = 1; it <= max; it++) {
    H(x, y);
    if (cpl_accel_next(a, x, y, base, res)) break;
  }
  cpl_accel_end(a);
  return it;
}

static cpl_accel *make(cpl_accel_kind kind, double relax, int64_t split) {
  cpl_implicit opt = {.tolerance = 1e-10, .max_iterations = 200, .acceleration = kind,
                      .relaxation = relax, .reuse = 8, .max_columns = 40, .filter = 1e-8};
  int64_t len[2] = {split, M - split};
  proto_err err;
  cpl_accel *a = cpl_accel_create(&opt, split ? 2 : 1, split ? len : (int64_t[]){M}, &err);
  if (!a) fprintf(stderr, "%s\n", err.msg);
  return a;
}

int main(void) {
  /* a map that diverges under plain iteration: spectral radius > 1 */
  unsigned s = 12345;
  for (int i = 0; i < M; i++) {
    scale[i] = 1;
    b[i] = (double)(i + 1);
    for (int j = 0; j < M; j++) {
      s = s * 1103515245u + 12345u;
      A[i][j] = ((double)(s >> 8) / (1u << 24) - 0.5) * 1.2;
    }
    A[i][i] -= 1.5; /* eigenvalues around -1.5: plain iteration diverges */
  }
  double x[M] = {0};
  cpl_accel *iqn = make(CPL_ACCEL_IQN_ILS, 0.1, 0);
  int n1 = solve(iqn, x, 200);
  printf("IQN-ILS: first step %d evaluations (m = %d)\n", n1, M);
  CHECK(n1 <= M + 2);
  /* the fixed point: x = A x + b */
  double y[M];
  H(x, y);
  for (int i = 0; i < M; i++) CHECK(fabs(y[i] - x[i]) < 1e-8 * (1 + fabs(x[i])));
  /* a next step with another b: the reused columns know A */
  for (int i = 0; i < M; i++) b[i] = -2.0 * i;
  int n2 = solve(iqn, x, 200);
  printf("IQN-ILS: second step %d evaluations\n", n2);
  CHECK(n2 <= 3);
  cpl_accel_free(iqn);

  /* two fields of scale 1e-3 and 1e3 (positions, forces): the weights keep
   * the least squares balanced */
  for (int i = 0; i < M; i++) {
    scale[i] = i < M / 2 ? 1e-3 : 1e3;
    b[i] = (double)(i + 1) * scale[i];
  }
  double z[M] = {0};
  cpl_accel *two = make(CPL_ACCEL_IQN_ILS, 0.1, M / 2);
  int n3 = solve(two, z, 200);
  printf("IQN-ILS, two fields 1e-3 / 1e3: %d evaluations\n", n3);
  CHECK(n3 <= M + 2);
  cpl_accel_free(two);

  /* constant relaxation and Aitken on the diverging map: no convergence in
   * 200 (the acceleration is what makes the implicit scheme work here) */
  for (int i = 0; i < M; i++) scale[i] = 1, b[i] = (double)(i + 1);
  double w[M] = {0};
  cpl_accel *con = make(CPL_ACCEL_CONSTANT, 1.0, 0);
  int n4 = solve(con, w, 200);
  printf("constant relaxation 1: %d evaluations (201 = did not converge)\n", n4);
  CHECK(n4 > 200);
  cpl_accel_free(con);

  /* a scalar contraction y = 0.5 - 0.8 x: Aitken is the secant method,
   * exact at the third evaluation; constant omega = 1 needs many */
  memset(A, 0, sizeof A);
  for (int i = 0; i < M; i++) A[i][i] = -0.8, b[i] = 0.5;
  double u[M] = {0}, v[M] = {0};
  cpl_accel *ait = make(CPL_ACCEL_AITKEN, 0.5, 0);
  int n5 = solve(ait, u, 200);
  cpl_accel *c1 = make(CPL_ACCEL_CONSTANT, 1.0, 0);
  int n6 = solve(c1, v, 200);
  printf("contraction -0.8: Aitken %d, constant %d evaluations\n", n5, n6);
  CHECK(n5 == 3);
  CHECK(n6 > 50);
  for (int i = 0; i < M; i++) CHECK(fabs(u[i] - 0.5 / 1.8) < 1e-9);
  cpl_accel_free(ait);
  cpl_accel_free(c1);
  return cosim_test_done("test_accel");
}
