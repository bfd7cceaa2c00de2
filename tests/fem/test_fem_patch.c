/* Patch test (docs/fem-verification.md §1): a linear displacement field u = a + H x is
 * reproduced exactly by TET4 and TET10 on an irregular mesh, both with all
 * boundary nodes prescribed (variant A) and with the consistent boundary
 * tractions sigma.n and only rigid-body DOFs fixed (variant B). Rigid-body
 * motions give zero internal force. */
#include "fem_test.h"

#include <string.h>

static const double A[3] = {1e-3, -2e-3, 0.5e-3};
static const double H[3][3] = {{1e-3, 2e-4, -3e-4}, {-1e-4, -5e-4, 4e-4}, {2.5e-4, 1e-4, 7e-4}};

static void exact(const double *x, double *u) {
  for (int i = 0; i < 3; i++) u[i] = A[i] + H[i][0] * x[0] + H[i][1] * x[1] + H[i][2] * x[2];
}

static void build(fem_model *md, int tet10, proto_err *err_) {
  proto_err err;
  fem_mesh m;
  const double L[3] = {1.0, 0.8, 0.6};
  const int n[3] = {3, 3, 3};
  OK(fem_gen_box(&m, L, n, 0.25, &err));
  if (tet10) OK(fem_mesh_to_tet10(&m, NULL, NULL, &err));
  fem_material mat = {20e6, 0.3, 1100, 0};
  OK(fem_model_init(md, &m, &mat, &err));
  (void)err_;
}

static double max_err_u(const fem_model *md, const double *u) {
  double e = 0, s = 0;
  for (int32_t i = 0; i < md->mesh.n_nodes; i++) {
    double ue[3];
    exact(md->mesh.x + 3 * i, ue);
    for (int d = 0; d < 3; d++) {
      e = fmax(e, fabs(u[3 * i + d] - ue[d]));
      s = fmax(s, fabs(ue[d]));
    }
  }
  return e / s;
}

static double stress_err(const fem_model *md, const double *u, double S[3][3]) {
  double *sig = malloc(sizeof *sig * 6 * md->mesh.n_elems);
  proto_err err;
  fem_work w;
  OK(fem_work_init(md, &w, &err));
  fem_element_strain_stress(md, &w, u, NULL, sig);
  fem_work_free(&w);
  static const int vi[6] = {0, 1, 2, 1, 0, 0}, vj[6] = {0, 1, 2, 2, 2, 1};
  double e = 0, s = 0;
  for (int32_t k = 0; k < md->mesh.n_elems; k++)
    for (int c = 0; c < 6; c++) {
      e = fmax(e, fabs(sig[6 * k + c] - S[vi[c]][vj[c]]));
      s = fmax(s, fabs(S[vi[c]][vj[c]]));
    }
  free(sig);
  return e / s;
}

static void exact_stress(const fem_model *md, double S[3][3]) {
  double tr = H[0][0] + H[1][1] + H[2][2];
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++)
      S[i][j] = md->mu * (H[i][j] + H[j][i]) + (i == j ? md->lambda * tr : 0);
}

static void variant_a(int tet10) {
  proto_err err;
  fem_model md;
  build(&md, tet10, &err);
  static const char *faces[] = {"xmin", "xmax", "ymin", "ymax", "zmin", "zmax"};
  for (int g = 0; g < 6; g++) {
    int32_t *nodes, nn;
    OK(fem_group_nodes(&md.mesh, fem_mesh_group(&md.mesh, faces[g], &err), &nodes, &nn, &err));
    for (int32_t i = 0; i < nn; i++) {
      double ue[3];
      exact(md.mesh.x + 3 * nodes[i], ue);
      fem_model_fix_node(&md, nodes[i], 7, ue);
    }
    free(nodes);
  }
  OK(fem_model_assemble(&md, &err));
  double *b = calloc(md.n_dof, sizeof *b), *u = calloc(md.n_dof, sizeof *u);
  double S[3][3];
  exact_stress(&md, S);
  fem_factor *fac = NULL;
  for (int solver = 0; solver < 2; solver++) {
    fem_solve_stats st;
    OK(fem_static_solve(&md, &fac, solver ? FEM_PCG : FEM_CHOLMOD, 1e-14, b, u, &st, &err));
    double eu = max_err_u(&md, u), es = stress_err(&md, u, S);
    printf("patch A %s %s: %d free DOF, max rel error u %.2e, stress %.2e, residual %.1e\n",
           tet10 ? "TET10" : "TET4", solver ? "PCG" : "CHOLMOD", md.n_eq, eu, es, st.residual);
    CHECK(eu < 1e-10, "patch A displacement error %.3e", eu);
    CHECK(es < 1e-9, "patch A stress error %.3e", es);
  }
  free(b);
  free(u);
  fem_factor_free(&fac);
  fem_model_free(&md);
}

static void variant_b(int tet10) {
  proto_err err;
  fem_model md;
  build(&md, tet10, &err);
  double S[3][3];
  exact_stress(&md, S);
  static const char *faces[] = {"xmin", "xmax", "ymin", "ymax", "zmin", "zmax"};
  double *b = calloc(md.n_dof, sizeof *b), *u = calloc(md.n_dof, sizeof *u);
  for (int g = 0; g < 6; g++) {
    double n[3] = {0, 0, 0}, t[3];
    n[g / 2] = g % 2 ? 1 : -1;
    for (int i = 0; i < 3; i++) t[i] = S[i][0] * n[0] + S[i][1] * n[1] + S[i][2] * n[2];
    OK(fem_load_traction(&md, faces[g], t, b, &err));
  }
  /* remove rigid motion: 6 DOFs at three corners, to the exact values */
  int32_t c0 = fem_test_node_at(&md.mesh, 0, 0, 0), c1 = fem_test_node_at(&md.mesh, 1, 0, 0);
  int32_t c2 = fem_test_node_at(&md.mesh, 0, 0.8, 0);
  double ue[3];
  exact(md.mesh.x + 3 * c0, ue);
  fem_model_fix_node(&md, c0, 7, ue);
  exact(md.mesh.x + 3 * c1, ue);
  fem_model_fix_node(&md, c1, 6, ue);
  exact(md.mesh.x + 3 * c2, ue);
  fem_model_fix_node(&md, c2, 4, ue);
  OK(fem_model_assemble(&md, &err));
  fem_factor *fac = NULL;
  OK(fem_static_solve(&md, &fac, FEM_CHOLMOD, 0, b, u, NULL, &err));
  fem_factor_free(&fac);
  double eu = max_err_u(&md, u), es = stress_err(&md, u, S);
  printf("patch B %s (tractions): max rel error u %.2e, stress %.2e\n", tet10 ? "TET10" : "TET4", eu, es);
  CHECK(eu < 1e-9, "patch B displacement error %.3e", eu);
  CHECK(es < 1e-8, "patch B stress error %.3e", es);
  /* explicit variant: start on the patch field with the tractions: no motion */
  fem_state st;
  OK(fem_state_init(&md, &st, &err));
  OK(fem_stable_dt(&md, &st, 200, &err));
  fem_state_reset(&md, &st, u);
  memcpy(st.b, b, sizeof *b * md.n_dof);
  OK(fem_explicit_advance(&md, &st, 20 * st.dt_crit, 0.9, 0, &err));
  double vmax = 0, umax = 0;
  for (int32_t i = 0; i < md.n_dof; i++) {
    vmax = fmax(vmax, fabs(st.v[i]));
    umax = fmax(umax, fabs(st.u[i] - u[i]));
  }
  double vscale = 1e-3 * fem_wave_speed_p(&md.mat);
  printf("patch B %s explicit, %lld sub-steps: max |v| %.2e m/s (scale %.2e), max |du| %.2e m\n",
         tet10 ? "TET10" : "TET4", (long long)st.n_sub, vmax, vscale, umax);
  CHECK(vmax < 1e-10 * vscale, "explicit patch moved: |v| %.3e", vmax);
  fem_state_free(&st);
  free(b);
  free(u);
  fem_model_free(&md);
}

static void rigid_body(int tet10) {
  proto_err err;
  fem_model md;
  build(&md, tet10, &err);
  double *u = calloc(md.n_dof, sizeof *u), *f = calloc(md.n_dof, sizeof *f);
  const double w[3] = {0.3, -0.2, 0.5}, c[3] = {1e-3, 2e-3, -1e-3};
  for (int32_t i = 0; i < md.mesh.n_nodes; i++) { /* translation + small rotation w x x */
    const double *x = md.mesh.x + 3 * i;
    u[3 * i] = c[0] + w[1] * x[2] - w[2] * x[1];
    u[3 * i + 1] = c[1] + w[2] * x[0] - w[0] * x[2];
    u[3 * i + 2] = c[2] + w[0] * x[1] - w[1] * x[0];
  }
  fem_work wk;
  OK(fem_work_init(&md, &wk, &err));
  fem_internal_force(&md, &wk, u, f);
  fem_work_free(&wk);
  double fmax_ = 0;
  for (int32_t i = 0; i < md.n_dof; i++) fmax_ = fmax(fmax_, fabs(f[i]));
  double scale = md.mat.E * 0.3 * 0.3 * 0.5; /* E h^2 |u| */
  printf("rigid body %s: max |K u_rigid| / (E h^2 |u|) = %.2e\n", tet10 ? "TET10" : "TET4", fmax_ / scale);
  CHECK(fmax_ / scale < 1e-12, "rigid motion strains the %s mesh: %.3e", tet10 ? "TET10" : "TET4",
        fmax_ / scale);
  free(u);
  free(f);
  fem_model_free(&md);
}

int main(void) {
  for (int t = 0; t < 2; t++) {
    variant_a(t);
    variant_b(t);
    rigid_body(t);
  }
  return cosim_test_done("test_fem_patch");
}
