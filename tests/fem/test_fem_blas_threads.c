/* The static solve gives the same bits whatever number of threads the BLAS
 * was set to before it (fem_solve.c blas_threads): the paper's tread (refine
 * 1, 17 280 equations, rim fixed, 0.14 MPa inside) solved by CHOLMOD after
 * openblas_set_num_threads(1) and after (2), fresh factorisations both. With
 * OpenBLAS threads splitting the supernodal blocks by their count, the two
 * differed in the last bits (bench/results/tire_soil.md "Hand-offs on one
 * core"); the count the caller set is put back. Without OpenBLAS (another
 * BLAS has no such call) there is nothing to compare: the test says so. */
#define _GNU_SOURCE /* RTLD_DEFAULT */
#include "fem_test.h"

#include <dlfcn.h>
#include <stdlib.h>
#include <string.h>

static int solve(const fem_model *md, const double *b, double *u) {
  proto_err err = {{0}};
  fem_factor *f = NULL;
  const int rc = fem_static_solve(md, &f, FEM_CHOLMOD, 1e-10, b, u, NULL, &err);
  if (rc) fprintf(stderr, "solve: %s\n", err.msg);
  fem_factor_free(&f);
  return rc;
}

int main(void) {
  int (*get)(void) = (int (*)(void))dlsym(RTLD_DEFAULT, "openblas_get_num_threads");
  void (*set)(int) = (void (*)(int))dlsym(RTLD_DEFAULT, "openblas_set_num_threads");
  printf("BLAS: %s\n", fem_blas_name());
  if (!get || !set) {
    printf("no openblas_set_num_threads: one thread always, nothing to compare\n");
    return cosim_test_done("fem_blas_threads");
  }
  proto_err err;
  fem_tread_params p;
  fem_tread_defaults(&p);
  fem_mesh m;
  OK(fem_gen_tread(&m, &p, &err));
  fem_material mat = {20e6, 0.45, 1100, 0};
  fem_model md;
  OK(fem_model_init(&md, &m, &mat, &err));
  OK(fem_model_fix_group(&md, "rim", 7, &err));
  OK(fem_model_assemble(&md, &err));
  const size_t nd = (size_t)md.n_dof;
  double *b = calloc(nd, sizeof *b), *u1 = calloc(nd, sizeof *u1), *u2 = calloc(nd, sizeof *u2);
  CHECK(b && u1 && u2, "memory");
  OK(fem_load_pressure(&md, "inner", 1.4e5, b, &err));
  set(1);
  CHECK(solve(&md, b, u1) == 0, "solved after openblas_set_num_threads(1)");
  set(2);
  CHECK(solve(&md, b, u2) == 0, "solved after openblas_set_num_threads(2)");
  CHECK(get() == 2, "the caller's thread count is put back (%d, set 2)", get());
  size_t differ = 0;
  double umax = 0;
  for (size_t i = 0; i < nd; i++) {
    differ += memcmp(&u1[i], &u2[i], sizeof(double)) != 0;
    umax = fabs(u1[i]) > umax ? fabs(u1[i]) : umax;
  }
  printf("%d equations, largest |u| %.4g m, %zu of %zu DOFs differ\n", (int)md.n_eq, umax, differ, nd);
  CHECK(umax > 1e-6, "the pressure moves the tread (%.3g m)", umax);
  CHECK(differ == 0, "the same bits with 1 and 2 BLAS threads (%zu of %zu DOFs differ)", differ, nd);
  free(b);
  free(u1);
  free(u2);
  fem_model_free(&md);
  return cosim_test_done("fem_blas_threads");
}
