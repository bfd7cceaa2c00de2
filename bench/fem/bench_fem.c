/* bench_fem — one FEM benchmark case per invocation, one JSON line out.
 *
 *   bench_fem static  SOLVER REFINE      tread static solve (rim fixed, 2 bar
 *                                        inflation + gravity): time, memory
 *   bench_fem explicit ELEMENT REFINE N  N internal-force evaluations and N
 *                                        full explicit sub-steps on the tread
 *   bench_fem lame    ELEMENT NU NR      Lame cylinder: error and run time
 *
 * Separate processes keep the peak RSS of each case honest. */
#include "fem_server/fem.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <time.h>

#ifdef _OPENMP
#include <omp.h>
#endif

static double peak_rss_mb(void) {
  struct rusage ru;
  getrusage(RUSAGE_SELF, &ru);
  return ru.ru_maxrss / 1024.0;
}

static double cpu_now(void) { /* process CPU time: robust on a shared machine */
  struct timespec ts;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

static int threads(void) {
#ifdef _OPENMP
  return omp_get_max_threads();
#else
  return 1;
#endif
}

static int die(const proto_err *err) {
  fprintf(stderr, "bench_fem: %s\n", err->msg);
  return 1;
}

static int tread_model(fem_model *md, double refine, int tet10, int anp, proto_err *err) {
  fem_tread_params p;
  fem_tread_defaults(&p);
  p.refine = refine;
  fem_mesh m;
  if (fem_gen_tread(&m, &p, err)) return -1;
  if (tet10) {
    double radii[3] = {p.outer_diameter / 2 - p.groove_depth - p.wall, p.outer_diameter / 2 - p.groove_depth,
                       p.outer_diameter / 2};
    if (fem_mesh_to_tet10(&m, fem_snap_tread, radii, err)) return -1;
  }
  fem_material mat = {20e6, 0.45, 1100, 0};
  if (fem_model_init(md, &m, &mat, err) || fem_model_fix_group(md, "rim", 7, err)) return -1;
  return anp ? fem_model_set_anp(md, err) : 0;
}

static int bench_static(const char *solver, double refine) {
  proto_err err;
  fem_model md;
  double t0 = proto_now();
  if (tread_model(&md, refine, 0, 0, &err)) return die(&err);
  if (fem_model_assemble(&md, &err)) return die(&err);
  double t_asm = proto_now() - t0;
  double *b = calloc(md.n_dof, sizeof *b), *u = calloc(md.n_dof, sizeof *u);
  const double g[3] = {0, 0, -9.81};
  if (fem_load_pressure(&md, "inner", 2e5, b, &err)) return die(&err);
  fem_load_gravity(&md, g, b);
  fem_solve_stats st;
  int pcg = strcmp(solver, "pcg") == 0;
  fem_factor *fac = NULL;
  double t1 = proto_now();
  if (fem_static_solve(&md, &fac, pcg ? FEM_PCG : FEM_CHOLMOD, 1e-10, b, u, &st, &err)) return die(&err);
  double t_total = proto_now() - t1;
  fem_factor_free(&fac);
  double umax = 0;
  for (int32_t i = 0; i < md.n_dof; i++) umax = fmax(umax, fabs(u[i]));
  printf("{\"case\":\"static\",\"solver\":\"%s\",\"refine\":%g,\"elements\":%d,\"dof\":%d,\"nnz_K\":%d,"
         "\"t_assemble\":%.4f,\"t_analyze\":%.4f,\"t_factor\":%.4f,\"t_solve\":%.4f,\"t_total\":%.4f,"
         "\"iterations\":%d,\"residual\":%.3g,\"nnz_L\":%.4g,\"solver_peak_mb\":%.2f,\"peak_rss_mb\":%.1f,"
         "\"u_max\":%.6e,\"threads\":%d,\"blas\":\"%s\"}\n",
         solver, refine, md.mesh.n_elems, md.n_eq, md.colptr[md.n_eq], t_asm, st.t_analyze, st.t_factor,
         st.t_solve, t_total, st.iterations, st.residual, st.nnz_factor, st.memory_peak / 1048576.0,
         peak_rss_mb(), umax, threads(), fem_blas_name());
  free(b);
  free(u);
  fem_model_free(&md);
  return 0;
}

static int bench_explicit(const char *element, double refine, int n) {
  proto_err err;
  fem_model md;
  int tet10 = strcmp(element, "tet10") == 0, anp = strcmp(element, "tet4_anp") == 0;
  if (tread_model(&md, refine, tet10, anp, &err)) return die(&err);
  if (fem_model_assemble(&md, &err)) return die(&err);
  fem_state st;
  if (fem_state_init(&md, &st, &err) || fem_stable_dt(&md, &st, 300, &err)) return die(&err);
  fem_state_reset(&md, &st, NULL);
  if (fem_load_pressure(&md, "inner", 2e5, st.b, &err)) return die(&err);
  double *u = calloc(md.n_dof, sizeof *u), *f = calloc(md.n_dof, sizeof *f);
  for (int32_t i = 0; i < md.n_dof; i++) u[i] = 1e-4 * sin(0.37 * i);
  fem_internal_force(&md, &st.work, u, f); /* warm-up */
  /* minimum over 5 blocks: the least disturbed timing on a shared machine */
  double t_force = 1e30, c_force = 1e30, t_step = 1e30, c_step = 1e30;
  double dt = 0.9 * st.dt_crit;
  for (int rep = 0; rep < 5; rep++) {
    double t0 = proto_now(), c0 = cpu_now();
    for (int k = 0; k < n; k++) fem_internal_force(&md, &st.work, u, f);
    t_force = fmin(t_force, (proto_now() - t0) / n);
    c_force = fmin(c_force, (cpu_now() - c0) / n);
    t0 = proto_now();
    c0 = cpu_now();
    if (fem_explicit_advance(&md, &st, n * dt, 0.9, dt, &err)) return die(&err);
    t_step = fmin(t_step, (proto_now() - t0) / n);
    c_step = fmin(c_step, (cpu_now() - c0) / n);
  }
  int nt = threads();
  printf("{\"case\":\"explicit\",\"element\":\"%s\",\"refine\":%g,\"elements\":%d,\"nodes\":%d,"
         "\"threads\":%d,\"dt_crit\":%.4e,\"wall_force\":%.4e,\"wall_substep\":%.4e,"
         "\"cpu_force\":%.4e,\"cpu_substep\":%.4e,\"cpu_ns_per_element_force\":%.2f,"
         "\"element_updates_per_cpu_s\":%.4g,\"element_updates_per_cpu_s_full_step\":%.4g,"
         "\"element_updates_per_wall_s_per_thread\":%.4g}\n",
         element, refine, md.mesh.n_elems, md.mesh.n_nodes, nt, st.dt_crit, t_force, t_step, c_force,
         c_step, 1e9 * c_force / md.mesh.n_elems, md.mesh.n_elems / c_force, md.mesh.n_elems / c_step,
         md.mesh.n_elems / t_force / nt);
  free(u);
  free(f);
  fem_state_free(&st);
  fem_model_free(&md);
  return 0;
}

static int bench_lame(const char *element, double nu, int nr) {
  proto_err err;
  const double a = 0.1, b = 0.2, p = 0.2e6, E = 20e6;
  int tet10 = strcmp(element, "tet10") == 0;
  double t0 = proto_now();
  fem_mesh m;
  const int n[3] = {nr, 2 * nr, 1};
  double radii[2] = {a, b};
  if (fem_gen_cylinder(&m, a, b, 0.25 * a, M_PI / 2, n, &err)) return die(&err);
  if (tet10 && fem_mesh_to_tet10(&m, fem_snap_cylinder, radii, &err)) return die(&err);
  fem_material mat = {E, nu, 1100, 0};
  fem_model md;
  if (fem_model_init(&md, &m, &mat, &err) ||
      (strcmp(element, "tet4_anp") == 0 && fem_model_set_anp(&md, &err)) ||
      fem_model_fix_group(&md, "theta0", 2, &err) ||
      fem_model_fix_group(&md, "theta1", 1, &err) || fem_model_fix_group(&md, "zmin", 4, &err) ||
      fem_model_fix_group(&md, "zmax", 4, &err) || fem_model_assemble(&md, &err))
    return die(&err);
  double *f = calloc(md.n_dof, sizeof *f), *u = calloc(md.n_dof, sizeof *u);
  fem_factor *fac = NULL;
  if (fem_load_pressure(&md, "inner", p, f, &err) ||
      fem_static_solve(&md, &fac, FEM_CHOLMOD, 0, f, u, NULL, &err))
    return die(&err);
  fem_factor_free(&fac);
  double t = proto_now() - t0;
  /* L2-type error of u_r over all nodes (nodal RMS, relative) and at r = a */
  double se = 0, sr = 0, ea = 0;
  int na = 0;
  for (int32_t i = 0; i < md.mesh.n_nodes; i++) {
    const double *x = md.mesh.x + 3 * i;
    double r = hypot(x[0], x[1]);
    double ur = (u[3 * i] * x[0] + u[3 * i + 1] * x[1]) / r;
    double ex = (1 + nu) * p * a * a / (E * (b * b - a * a)) * ((1 - 2 * nu) * r + b * b / r);
    se += (ur - ex) * (ur - ex);
    sr += ex * ex;
    if (fabs(r - a) < 1e-9) {
      ea += ur / ex - 1;
      na++;
    }
  }
  printf("{\"case\":\"lame\",\"element\":\"%s\",\"nu\":%g,\"nr\":%d,\"dof\":%d,\"time\":%.5f,"
         "\"err_rms\":%.4e,\"err_ur_a\":%.4e}\n", element, nu, nr, md.n_eq, t, sqrt(se / sr), ea / na);
  free(f);
  free(u);
  fem_model_free(&md);
  return 0;
}

int main(int argc, char **argv) {
  if (argc >= 4 && strcmp(argv[1], "static") == 0) return bench_static(argv[2], atof(argv[3]));
  if (argc >= 5 && strcmp(argv[1], "explicit") == 0) return bench_explicit(argv[2], atof(argv[3]), atoi(argv[4]));
  if (argc >= 5 && strcmp(argv[1], "lame") == 0) return bench_lame(argv[2], atof(argv[3]), atoi(argv[4]));
  fprintf(stderr, "usage: bench_fem static cholmod|pcg REFINE | explicit tet4|tet10|tet4_anp REFINE N | "
                  "lame tet4|tet10|tet4_anp NU NR\n");
  return 2;
}
