/* The assembled K (CSC, used by CHOLMOD/PCG) and the matrix-free force of
 * the explicit scheme are the same operator, for TET4, TET10 and the
 * average-nodal-pressure TET4 (ANP). ANP passes the patch test and cures
 * the volumetric locking of TET4 on the Lame cylinder at nu = 0.45 and
 * 0.49; its explicit run conserves the discrete energy. */
#include "fem_test.h"

#include <string.h>

/* max |K_ff u_f - (K u)_f| / max |(K u)_f| for a random u with fixed DOFs zero */
static double operator_mismatch(fem_model *md) {
  double *u = calloc(md->n_dof, sizeof *u), *f = calloc(md->n_dof, sizeof *f);
  double *uf = calloc(md->n_eq, sizeof *uf), *y = calloc(md->n_eq, sizeof *y);
  uint32_t s = 12345;
  for (int32_t i = 0; i < md->n_dof; i++) {
    s = s * 1664525u + 1013904223u;
    u[i] = md->fixed[i] ? 0 : (double)s / 4294967296.0 - 0.5;
    if (md->eq[i] >= 0) uf[md->eq[i]] = u[i];
  }
  proto_err err;
  fem_work w;
  OK(fem_work_init(md, &w, &err));
  fem_internal_force(md, &w, u, f);
  fem_work_free(&w);
  for (int32_t j = 0; j < md->n_eq; j++)
    for (int32_t p = md->colptr[j]; p < md->colptr[j + 1]; p++) {
      int32_t i = md->rowind[p];
      y[i] += md->kval[p] * uf[j];
      if (i != j) y[j] += md->kval[p] * uf[i];
    }
  double e = 0, sc = 0;
  for (int32_t i = 0; i < md->n_dof; i++)
    if (md->eq[i] >= 0) {
      e = fmax(e, fabs(y[md->eq[i]] - f[i]));
      sc = fmax(sc, fabs(f[i]));
    }
  free(u); free(f); free(uf); free(y);
  return e / sc;
}

static void build_box(fem_model *md, int kind, double nu) {
  proto_err err;
  fem_mesh m;
  const double L[3] = {1, 0.8, 0.6};
  const int n[3] = {4, 3, 3};
  OK(fem_gen_box(&m, L, n, 0.2, &err));
  if (kind == 10) OK(fem_mesh_to_tet10(&m, NULL, NULL, &err));
  fem_material mat = {20e6, nu, 1100, 0};
  OK(fem_model_init(md, &m, &mat, &err));
  if (kind == 5) OK(fem_model_set_anp(md, &err));
}

static void operator_tests(void) {
  const int kinds[3] = {4, 10, 5};
  const char *names[3] = {"TET4", "TET10", "TET4-ANP"};
  for (int k = 0; k < 3; k++) {
    proto_err err;
    fem_model md;
    build_box(&md, kinds[k], 0.45);
    OK(fem_model_fix_group(&md, "xmin", 7, &err));
    OK(fem_model_assemble(&md, &err));
    double e = operator_mismatch(&md);
    printf("%-8s assembled K vs matrix-free force: rel. mismatch %.2e (nnz upper %d)\n", names[k], e,
           md.colptr[md.n_eq]);
    CHECK(e < 1e-12, "%s: K and the force kernel differ by %.3e", names[k], e);
    /* energy: 1/2 u.f equals fem_strain_energy */
    fem_model_free(&md);
  }
}

static void anp_patch(void) {
  proto_err err;
  fem_model md;
  build_box(&md, 5, 0.49);
  static const double H[3][3] = {{1e-3, 2e-4, -3e-4}, {-1e-4, -5e-4, 4e-4}, {2.5e-4, 1e-4, 7e-4}};
  static const char *faces[] = {"xmin", "xmax", "ymin", "ymax", "zmin", "zmax"};
  for (int g = 0; g < 6; g++) {
    int32_t *nodes, nn;
    OK(fem_group_nodes(&md.mesh, fem_mesh_group(&md.mesh, faces[g], &err), &nodes, &nn, &err));
    for (int32_t i = 0; i < nn; i++) {
      const double *x = md.mesh.x + 3 * nodes[i];
      double ue[3];
      for (int a = 0; a < 3; a++) ue[a] = H[a][0] * x[0] + H[a][1] * x[1] + H[a][2] * x[2];
      fem_model_fix_node(&md, nodes[i], 7, ue);
    }
    free(nodes);
  }
  OK(fem_model_assemble(&md, &err));
  double *b = calloc(md.n_dof, sizeof *b), *u = calloc(md.n_dof, sizeof *u);
  fem_factor *fac = NULL;
  OK(fem_static_solve(&md, &fac, FEM_CHOLMOD, 0, b, u, NULL, &err));
  fem_factor_free(&fac);
  double e = 0;
  for (int32_t i = 0; i < md.mesh.n_nodes; i++)
    for (int a = 0; a < 3; a++) {
      const double *x = md.mesh.x + 3 * i;
      e = fmax(e, fabs(u[3 * i + a] - (H[a][0] * x[0] + H[a][1] * x[1] + H[a][2] * x[2])));
    }
  double *sig = malloc(sizeof *sig * 6 * md.mesh.n_elems), tr = H[0][0] + H[1][1] + H[2][2];
  fem_work w;
  OK(fem_work_init(&md, &w, &err));
  fem_element_strain_stress(&md, &w, u, NULL, sig);
  fem_work_free(&w);
  double sxx = 2 * md.mu * H[0][0] + md.lambda * tr, es = 0;
  for (int32_t k = 0; k < md.mesh.n_elems; k++) es = fmax(es, fabs(sig[6 * k] - sxx) / fabs(sxx));
  printf("TET4-ANP patch test (nu = 0.49): max |u - u_exact| / |H| = %.2e, sigma_xx rel. error %.2e\n",
         e / 1e-3, es);
  CHECK(e / 1e-3 < 1e-10 && es < 1e-9, "ANP patch test: u %.3e, stress %.3e", e, es);
  free(sig); free(b); free(u);
  fem_model_free(&md);
}

static double lame(int kind, double nu, int nr) {
  proto_err err;
  const double a = 0.1, bo = 0.2, p = 0.2e6, E = 20e6;
  fem_mesh m;
  const int n[3] = {nr, 2 * nr, 1};
  OK(fem_gen_cylinder(&m, a, bo, 0.25 * a, M_PI / 2, n, &err));
  fem_material mat = {E, nu, 1100, 0};
  fem_model md;
  OK(fem_model_init(&md, &m, &mat, &err));
  if (kind == 5) OK(fem_model_set_anp(&md, &err));
  OK(fem_model_fix_group(&md, "theta0", 2, &err));
  OK(fem_model_fix_group(&md, "theta1", 1, &err));
  OK(fem_model_fix_group(&md, "zmin", 4, &err));
  OK(fem_model_fix_group(&md, "zmax", 4, &err));
  OK(fem_model_assemble(&md, &err));
  double *b = calloc(md.n_dof, sizeof *b), *u = calloc(md.n_dof, sizeof *u);
  OK(fem_load_pressure(&md, "inner", p, b, &err));
  fem_factor *fac = NULL;
  OK(fem_static_solve(&md, &fac, FEM_CHOLMOD, 0, b, u, NULL, &err));
  fem_factor_free(&fac);
  double se = 0, sr = 0;
  for (int32_t i = 0; i < md.mesh.n_nodes; i++) {
    const double *x = md.mesh.x + 3 * i;
    double r = hypot(x[0], x[1]), ur = (u[3 * i] * x[0] + u[3 * i + 1] * x[1]) / r;
    double ex = (1 + nu) * p * a * a / (E * (bo * bo - a * a)) * ((1 - 2 * nu) * r + bo * bo / r);
    se += (ur - ex) * (ur - ex);
    sr += ex * ex;
  }
  free(b); free(u);
  fem_model_free(&md);
  return sqrt(se / sr);
}

static void anp_locking(void) {
  const double nus[3] = {0.3, 0.45, 0.49};
  for (int k = 0; k < 3; k++) {
    double e4 = lame(4, nus[k], 8), ea = lame(5, nus[k], 8), e4f = lame(4, nus[k], 16), eaf = lame(5, nus[k], 16);
    printf("Lame nu = %.2f RMS error of u_r: TET4 %.2e / %.2e, TET4-ANP %.2e / %.2e (8x16 / 16x32 cells)\n",
           nus[k], e4, e4f, ea, eaf);
    if (nus[k] > 0.4) {
      CHECK(ea < 0.5 * e4, "ANP does not reduce locking at nu = %.2f (%.3e vs %.3e)", nus[k], ea, e4);
      CHECK(eaf < 0.4 * ea, "ANP not converging at nu = %.2f", nus[k]);
    }
  }
}

static void anp_energy(void) {
  proto_err err;
  fem_model md;
  build_box(&md, 5, 0.45);
  OK(fem_model_fix_group(&md, "xmin", 7, &err));
  OK(fem_model_assemble(&md, &err));
  double *b = calloc(md.n_dof, sizeof *b), *u = calloc(md.n_dof, sizeof *u);
  const double t[3] = {0, 1e5, -2e5};
  OK(fem_load_traction(&md, "xmax", t, b, &err));
  fem_factor *fac = NULL;
  OK(fem_static_solve(&md, &fac, FEM_CHOLMOD, 0, b, u, NULL, &err));
  fem_factor_free(&fac);
  fem_state st;
  OK(fem_state_init(&md, &st, &err));
  OK(fem_stable_dt(&md, &st, 1000, &err));
  double se = fem_strain_energy(&md, &st.work, u), work = 0;
  for (int32_t i = 0; i < md.n_dof; i++) work += 0.5 * b[i] * u[i];
  fem_state_reset(&md, &st, u);
  double drift = 0;
  for (int k = 0; k < 2000; k++) {
    OK(fem_explicit_advance(&md, &st, 0.9 * st.dt_crit, 0.9, 0, &err));
    drift = fmax(drift, fabs(st.energy / st.energy0 - 1));
  }
  printf("TET4-ANP: strain energy %.6e J = 1/2 b.u %.6e J; explicit free vibration, 2000 steps: "
         "energy drift %.1e; dt_crit %.3e s\n", se, work, drift, st.dt_crit);
  CHECK(fabs(se / work - 1) < 1e-10, "ANP strain energy inconsistent");
  CHECK(drift < 1e-6, "ANP energy drift %.3e", drift);
  fem_state_free(&st);
  free(b); free(u);
  fem_model_free(&md);
}

int main(void) {
  operator_tests();
  anp_patch();
  anp_locking();
  anp_energy();
  return cosim_test_done("test_fem_anp");
}
