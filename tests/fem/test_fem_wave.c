/* Dilatational wave in a laterally constrained column (1-D strain,
 * docs/fem-verification.md §4): a step pressure at x = 0 sends a front at
 * c_p = sqrt((lambda + 2 mu)/rho). The time the particle velocity at two
 * stations crosses half its plateau gives the speed; within 2 % of c_p. */
#include "fem_test.h"

#include <string.h>

static double station_v(const fem_state *st, const int32_t *nodes, int n) {
  double s = 0;
  for (int i = 0; i < n; i++) s += st->v[3 * nodes[i]];
  return s / n;
}

static int run(int tet10) {
  proto_err err;
  fem_mesh m;
  const double size[3] = {1.0, 0.01, 0.01};
  const int n[3] = {tet10 ? 100 : 200, 1, 1};
  OK(fem_gen_box(&m, size, n, 0, &err));
  if (tet10) OK(fem_mesh_to_tet10(&m, NULL, NULL, &err));
  fem_material mat = {20e6, 0.45, 1100, 0};
  fem_model md;
  OK(fem_model_init(&md, &m, &mat, &err));
  OK(fem_model_fix_group(&md, "ymin", 2, &err));
  OK(fem_model_fix_group(&md, "ymax", 2, &err));
  OK(fem_model_fix_group(&md, "zmin", 4, &err));
  OK(fem_model_fix_group(&md, "zmax", 4, &err));
  OK(fem_model_fix_group(&md, "xmax", 1, &err));
  OK(fem_model_assemble(&md, &err));
  fem_state st;
  OK(fem_state_init(&md, &st, &err));
  OK(fem_stable_dt(&md, &st, 500, &err));
  fem_state_reset(&md, &st, NULL);
  const double p = 1e4, cp = fem_wave_speed_p(&mat), vplat = p / (mat.density * cp);
  OK(fem_load_pressure(&md, "xmin", p, st.b, &err));
  const double xs[2] = {0.25, 0.75};
  int32_t sn[2][16];
  int ns[2] = {0, 0};
  for (int32_t i = 0; i < md.mesh.n_nodes; i++)
    for (int k = 0; k < 2; k++)
      if (fabs(md.mesh.x[3 * i] - xs[k]) < 1e-9 && ns[k] < 16) sn[k][ns[k]++] = i;
  double t_cross[2] = {-1, -1}, v_prev[2] = {0, 0}, t_prev = 0;
  const double dt = 0.9 * st.dt_crit, t_end = 1.1 * xs[1] / cp;
  while (st.t < t_end) {
    OK(fem_explicit_advance(&md, &st, dt, 0.9, 0, &err));
    for (int k = 0; k < 2; k++) {
      double v = station_v(&st, sn[k], ns[k]);
      if (t_cross[k] < 0 && v >= 0.5 * vplat) /* linear interpolation of the crossing */
        t_cross[k] = t_prev + (st.t - t_prev) * (0.5 * vplat - v_prev[k]) / (v - v_prev[k]);
      v_prev[k] = v;
    }
    t_prev = st.t;
  }
  double c = (xs[1] - xs[0]) / (t_cross[1] - t_cross[0]);
  printf("%s: h = %.1f mm, dt_crit = %.3e s (h/c_p = %.3e), %lld steps; front speed %.2f m/s, "
         "c_p = %.2f m/s, error %+.3f %%\n", tet10 ? "TET10" : "TET4", 1e3 * size[0] / n[0], st.dt_crit,
         size[0] / n[0] / cp, (long long)st.n_sub, c, cp, 100 * (c / cp - 1));
  CHECK(t_cross[0] > 0 && t_cross[1] > 0, "front did not reach the stations");
  CHECK(fabs(c / cp - 1) < 0.02, "%s front speed %.2f vs c_p %.2f", tet10 ? "TET10" : "TET4", c, cp);
  fem_state_free(&st);
  fem_model_free(&md);
  return 0;
}

int main(void) {
  run(0);
  run(1);
  return cosim_test_done("test_fem_wave");
}
