/* Cantilever under an end shear load (docs/fem-verification.md §2): L = 10, b = h = 1,
 * root clamped, tip traction P/(bh). Tip deflection against Timoshenko
 * delta_T = P L^3/(3EI) + P L/(k G A), k = 10(1+nu)/(12+11nu). TET4 converges
 * (observed order from three meshes), TET10 is within 1 % on a moderate mesh. */
#include "fem_test.h"

static const double L = 10, B = 1, Hh = 1, P = 1000, E = 20e6, NU = 0.3;

static double tip_deflection(int nx, int tet10, int *ndof) {
  proto_err err;
  fem_mesh m;
  const double size[3] = {L, B, Hh};
  const int n[3] = {nx, nx / 10 > 0 ? nx / 10 : 1, nx / 10 > 0 ? nx / 10 : 1};
  OK(fem_gen_box(&m, size, n, 0, &err));
  if (tet10) OK(fem_mesh_to_tet10(&m, NULL, NULL, &err));
  fem_material mat = {E, NU, 1000, 0};
  fem_model md;
  OK(fem_model_init(&md, &m, &mat, &err));
  OK(fem_model_fix_group(&md, "xmin", 7, &err));
  OK(fem_model_assemble(&md, &err));
  double *b = calloc(md.n_dof, sizeof *b), *u = calloc(md.n_dof, sizeof *u);
  const double t[3] = {0, 0, -P / (B * Hh)};
  OK(fem_load_traction(&md, "xmax", t, b, &err));
  fem_factor *fac = NULL;
  OK(fem_static_solve(&md, &fac, FEM_CHOLMOD, 0, b, u, NULL, &err));
  double fz = 0;
  for (int32_t i = 0; i < md.n_dof; i += 3) fz += b[i + 2];
  CHECK(fabs(fz + P) < 1e-9 * P, "tip load sums to %g, not %g", fz, -P);
  /* mean deflection of the tip face nodes */
  int32_t *nodes, nn;
  OK(fem_group_nodes(&md.mesh, fem_mesh_group(&md.mesh, "xmax", &err), &nodes, &nn, &err));
  double s = 0;
  for (int32_t i = 0; i < nn; i++) s += -u[3 * nodes[i] + 2];
  *ndof = md.n_eq;
  free(nodes);
  free(b);
  free(u);
  fem_factor_free(&fac);
  fem_model_free(&md);
  return s / nn;
}

int main(void) {
  double I = B * Hh * Hh * Hh / 12, G = E / (2 * (1 + NU)), k = 10 * (1 + NU) / (12 + 11 * NU);
  double d_eb = P * L * L * L / (3 * E * I), d_t = d_eb + P * L / (k * G * B * Hh);
  printf("reference: Euler-Bernoulli %.6f m, Timoshenko %.6f m (nu = %.2f)\n", d_eb, d_t, NU);
  const int nx4[4] = {10, 20, 40, 80};
  double d4[4], d10[3];
  for (int i = 0; i < 4; i++) {
    int nd;
    d4[i] = tip_deflection(nx4[i], 0, &nd);
    printf("TET4  %2dx%dx%d  %6d DOF  delta/delta_T = %.4f\n", nx4[i], nx4[i] / 10, nx4[i] / 10, nd, d4[i] / d_t);
  }
  for (int i = 0; i < 3; i++) {
    int nd;
    d10[i] = tip_deflection(nx4[i], 1, &nd);
    printf("TET10 %2dx%dx%d  %6d DOF  delta/delta_T = %.4f\n", nx4[i], nx4[i] / 10, nx4[i] / 10, nd, d10[i] / d_t);
  }
  /* The converged 3-D answer (clamped root, distributed tip shear) is not
   * exactly Timoshenko's: take it from the TET10 sequence by Richardson. */
  double p10 = log2((d10[1] - d10[0]) / (d10[2] - d10[1]));
  double d_ref = d10[2] + (d10[2] - d10[1]) / (pow(2, p10) - 1);
  printf("TET10 observed order %.2f, extrapolated 3-D answer %.4f delta_T\n", p10, d_ref / d_t);
  double ratio[3];
  for (int i = 0; i < 3; i++) {
    ratio[i] = (d_ref - d4[i]) / (d_ref - d4[i + 1]);
    printf("TET4 error ratio %dx -> %dx: %.2f (O(h^2) -> 4)\n", nx4[i], nx4[i + 1], ratio[i]);
  }
  for (int i = 1; i < 4; i++) CHECK(d4[i] > d4[i - 1], "TET4 not converging monotonically");
  CHECK(ratio[2] > 3.0 && ratio[2] < 5, "TET4 error ratio %.2f: not approaching 4 (h^2)", ratio[2]);
  CHECK(ratio[2] > ratio[1] && ratio[1] > ratio[0], "TET4 error ratios not approaching the asymptote");
  CHECK(p10 > 1.9, "TET10 observed order %.2f below 2", p10);
  CHECK(fabs(d_ref / d_t - 1) < 0.01, "3-D answer %.4f not within 1 %% of Timoshenko", d_ref / d_t);
  CHECK(fabs(d10[2] / d_t - 1) < 0.01, "TET10 40x4x4 off Timoshenko by %.2f %%", 100 * (d10[2] / d_t - 1));
  CHECK(fabs(d10[1] / d_ref - 1) < 0.005, "TET10 20x2x2 off the 3-D answer by %.2f %%", 100 * (d10[1] / d_ref - 1));
  CHECK(d4[0] / d_t < 0.7, "TET4 coarse mesh should show shear locking (%.3f)", d4[0] / d_t);
  return cosim_test_done("test_fem_cantilever");
}
