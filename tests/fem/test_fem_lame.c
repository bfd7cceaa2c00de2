/* Thick-walled cylinder under internal pressure (Lame, plane strain,
 * docs/fem-verification.md §3): quarter model a = 0.1, b = 0.2, p = 0.2 MPa, symmetry
 * planes and u_z = 0 on both faces. Radial displacement at r = a and r = b.
 * TET10 within 1 % at nu = 0.45; TET4 converges as h^2 and its error at
 * nu = 0.45 is larger than at nu = 0.3 (volumetric locking). */
#include "fem_test.h"

static const double A = 0.1, Bo = 0.2, P = 0.2e6, E = 20e6;

static double lame_ur(double r, double nu) {
  return (1 + nu) * P * A * A / (E * (Bo * Bo - A * A)) * ((1 - 2 * nu) * r + Bo * Bo / r);
}

/* mean radial displacement at radius R over the group's nodes, rel. error */
static double group_err(fem_model *md, const double *u, const char *g, double R, double nu) {
  proto_err err;
  int32_t *nodes, nn;
  OK(fem_group_nodes(&md->mesh, fem_mesh_group(&md->mesh, g, &err), &nodes, &nn, &err));
  double e = 0;
  for (int32_t i = 0; i < nn; i++) {
    const double *x = md->mesh.x + 3 * nodes[i];
    double r = hypot(x[0], x[1]);
    double ur = (u[3 * nodes[i]] * x[0] + u[3 * nodes[i] + 1] * x[1]) / r;
    e += ur / lame_ur(R, nu);
  }
  free(nodes);
  return e / nn - 1;
}

static double run(int nr, int tet10, double nu, double *err_b) {
  proto_err err;
  fem_mesh m;
  const int n[3] = {nr, 2 * nr, 1};
  double radii[2] = {A, Bo};
  OK(fem_gen_cylinder(&m, A, Bo, 0.25 * A, M_PI / 2, n, &err));
  if (tet10) OK(fem_mesh_to_tet10(&m, fem_snap_cylinder, radii, &err));
  fem_material mat = {E, nu, 1100, 0};
  fem_model md;
  OK(fem_model_init(&md, &m, &mat, &err));
  OK(fem_model_fix_group(&md, "theta0", 2, &err)); /* y = 0 plane: u_y = 0 */
  OK(fem_model_fix_group(&md, "theta1", 1, &err)); /* x = 0 plane: u_x = 0 */
  OK(fem_model_fix_group(&md, "zmin", 4, &err));
  OK(fem_model_fix_group(&md, "zmax", 4, &err));
  OK(fem_model_assemble(&md, &err));
  double *b = calloc(md.n_dof, sizeof *b), *u = calloc(md.n_dof, sizeof *u);
  OK(fem_load_pressure(&md, "inner", P, b, &err));
  fem_factor *fac = NULL;
  OK(fem_static_solve(&md, &fac, FEM_CHOLMOD, 0, b, u, NULL, &err));
  double ea = group_err(&md, u, "inner", A, nu);
  *err_b = group_err(&md, u, "outer", Bo, nu);
  free(b);
  free(u);
  fem_factor_free(&fac);
  fem_model_free(&md);
  return ea;
}

int main(void) {
  double e4[2][4], eb;
  const double nus[2] = {0.3, 0.45};
  printf("u_r(a) relative error (mesh r x theta x z):\n");
  for (int k = 0; k < 2; k++)
    for (int i = 0; i < 4; i++) {
      int nr = 2 << i;
      e4[k][i] = run(nr, 0, nus[k], &eb);
      printf("TET4  nu=%.2f %2dx%2dx1  u_r(a) %+.4f%%  u_r(b) %+.4f%%\n", nus[k], nr, 2 * nr, 100 * e4[k][i], 100 * eb);
    }
  for (int i = 0; i < 3; i++) {
    double r4 = e4[0][i] / e4[0][i + 1];
    printf("TET4 nu=0.30 error ratio per halving: %.2f (h^2 -> 4)\n", r4);
  }
  CHECK(e4[0][2] / e4[0][3] > 3.0, "TET4 not converging as h^2 (ratio %.2f)", e4[0][2] / e4[0][3]);
  for (int i = 0; i < 4; i++)
    CHECK(fabs(e4[1][i]) > 1.5 * fabs(e4[0][i]), "locking not visible: |err(0.45)| %.3g vs |err(0.3)| %.3g",
          e4[1][i], e4[0][i]);
  printf("TET4 locking factor err(0.45)/err(0.30): %.2f %.2f %.2f %.2f\n", e4[1][0] / e4[0][0],
         e4[1][1] / e4[0][1], e4[1][2] / e4[0][2], e4[1][3] / e4[0][3]);
  for (int i = 0; i < 2; i++) {
    int nr = 2 << i;
    double ea = run(nr, 1, 0.45, &eb);
    printf("TET10 nu=0.45 %2dx%2dx1  u_r(a) %+.4f%%  u_r(b) %+.4f%%\n", nr, 2 * nr, 100 * ea, 100 * eb);
    if (i == 1) {
      CHECK(fabs(ea) < 0.01, "TET10 u_r(a) error %.3f %% above 1 %%", 100 * ea);
      CHECK(fabs(eb) < 0.01, "TET10 u_r(b) error %.3f %% above 1 %%", 100 * eb);
    }
  }
  return cosim_test_done("test_fem_lame");
}
