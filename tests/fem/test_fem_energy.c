/* Undamped free vibration of a cantilever released from its static
 * deflection: the discrete energy of eq. 32 (1/2 v+.M v+ + 1/2 u+.K u) is
 * conserved to 1e-6 over 10 periods with dt = 0.9 dt_crit, the run is
 * stable for 5000 steps at 0.97 dt_crit (the power-iteration limit is not optimistic), and
 * with dt 10 % above the limit the instability is detected with a message
 * naming the limit. Mass-proportional damping dissipates. */
#include "fem_test.h"

#include <string.h>

static fem_model md;
static double *u0;

/* The built model is const: the damped case is a model of its own. */
static void setup(int tet10, double damping) {
  proto_err err;
  fem_mesh m;
  const double size[3] = {10, 1, 1};
  const int n[3] = {tet10 ? 10 : 20, tet10 ? 1 : 2, tet10 ? 1 : 2};
  OK(fem_gen_box(&m, size, n, 0.1, &err));
  if (tet10) OK(fem_mesh_to_tet10(&m, NULL, NULL, &err));
  fem_material mat = {20e6, 0.3, 1100, damping};
  OK(fem_model_init(&md, &m, &mat, &err));
  OK(fem_model_fix_group(&md, "xmin", 7, &err));
  OK(fem_model_assemble(&md, &err));
  double *b = calloc(md.n_dof, sizeof *b);
  u0 = calloc(md.n_dof, sizeof *u0);
  const double t[3] = {0, 0, -1000};
  OK(fem_load_traction(&md, "xmax", t, b, &err));
  fem_factor *fac = NULL;
  OK(fem_static_solve(&md, &fac, FEM_CHOLMOD, 0, b, u0, NULL, &err));
  fem_factor_free(&fac);
  free(b);
}

/* First bending period of the clamped 10 x 1 x 1 beam, Euler-Bernoulli. */
static double first_period(void) {
  const double EI = md.mat.E / 12, mA = md.mat.density;
  return 2 * M_PI / (1.8751 * 1.8751 * sqrt(EI / (mA * 1e4)));
}

static void conservation(const char *name) {
  proto_err err;
  fem_state st;
  OK(fem_state_init(&md, &st, &err));
  OK(fem_stable_dt(&md, &st, 2000, &err));
  fem_state_reset(&md, &st, u0);
  const double period = first_period();
  double drift = 0, naive_lo = INFINITY, naive_hi = 0;
  const int n_periods = 10, per = 40;
  for (int k = 0; k < n_periods * per; k++) {
    OK(fem_explicit_advance(&md, &st, period / per, 0.9, 0, &err));
    drift = fmax(drift, fabs(st.energy - st.energy0) / st.energy0);
    double naive = st.kinetic + st.strain;
    naive_lo = fmin(naive_lo, naive);
    naive_hi = fmax(naive_hi, naive);
  }
  printf("%s: dt_crit %.4e s, period %.3f s, %d periods, %lld sub-steps of %.4e s: discrete energy "
         "drift %.2e; 1/2 v.Mv + 1/2 u.Ku varies by %.2e\n", name, st.dt_crit, period, n_periods,
         (long long)st.n_sub, st.dt_sub, drift, (naive_hi - naive_lo) / st.energy0);
  CHECK(drift < 1e-6, "%s: energy drift %.3e above 1e-6", name, drift);
  CHECK((naive_hi - naive_lo) / st.energy0 < 0.05, "%s: naive energy varies by %.3e", name,
        (naive_hi - naive_lo) / st.energy0);

  /* just below the computed limit: still stable */
  fem_state_reset(&md, &st, u0);
  int rc = fem_explicit_advance(&md, &st, 5000 * 0.97 * st.dt_crit, 0.97, 0, &err);
  CHECK(rc == 0, "%s: unstable at 0.97 dt_crit: %s", name, err.msg);

  /* 10 % above the limit: detected, message names the limit */
  fem_state_reset(&md, &st, u0);
  err.msg[0] = 0;
  rc = fem_explicit_advance(&md, &st, 2000 * st.dt_crit, 1, 1.1 * st.dt_crit, &err);
  char want[64];
  snprintf(want, sizeof want, "dt_crit = 2/omega_max = %.4g s", st.dt_crit);
  printf("%s at 1.1 dt_crit: rc %d after %lld sub-steps: %s\n", name, rc, (long long)st.n_sub, err.msg);
  CHECK(rc != 0, "%s: instability not detected", name);
  CHECK(strstr(err.msg, want) != NULL, "%s: message does not name the limit", name);
  CHECK(st.n_sub < 1000, "%s: detection took %lld steps", name, (long long)st.n_sub);

  fem_state_free(&st);
}

/* Mass-proportional damping (alpha = 2/s, the model of setup(.., 2.0)) dissipates. */
static void dissipation(const char *name) {
  proto_err err;
  fem_state st;
  OK(fem_state_init(&md, &st, &err));
  OK(fem_stable_dt(&md, &st, 2000, &err));
  const double period = first_period();
  fem_state_reset(&md, &st, u0);
  OK(fem_explicit_advance(&md, &st, 2 * period, 0.9, 0, &err));
  printf("%s damped (alpha = 2/s): energy after 2 periods %.3e of %.3e\n", name, st.energy, st.energy0);
  CHECK(st.energy < 0.2 * st.energy0, "%s: damping does not dissipate", name);
  fem_state_free(&st);
}

int main(void) {
  const char *names[2] = {"TET4", "TET10"};
  for (int tet10 = 0; tet10 < 2; tet10++) {
    setup(tet10, 0);
    conservation(names[tet10]);
    fem_model_free(&md);
    free(u0);
    setup(tet10, 2.0);
    dissipation(names[tet10]);
    fem_model_free(&md);
    free(u0);
  }
  return cosim_test_done("test_fem_energy");
}
