/* The thesis' instability and its cures on the default scene
 * (configs/tread_block.json, 20 × 20, 51.2 kHz, 0 → 0.2 mm in 6.7 ms):
 *  - point-sampled g + plain Newton leaves the quasi-static force band
 *    between 0.04 and 0.09 mm (the thesis: 0.05–0.06 mm);
 *  - ZOH-sampled g, and point samples at ×2, stay within 3 % of the
 *    quasi-static force up to 0.2 mm with every step converged;
 *  - the robust dual Newton converges at every step while the forces are
 *    physical: with point samples it fails only after the blow-up;
 *  - the thesis' second cure (ch. 4.2.2: the 80 stiffest springs, by force
 *    at 9 µm, exchanged for the next 80) on a road whose springs scatter as
 *    the thesis found them (a huge, heavy-tailed spread: log-normal σ 2.5):
 *    the point-sampled run at the base rate fails without it (0.04–0.07 mm)
 *    and stays within 3 % of its quasi-static force to 0.2 mm with it. */
#include <math.h>
#include <string.h>

#include "blk_test.h"
#include "contact_block/blk.h"

static proto_err err;
enum { NMAX = 2 * 343 + 1 };

typedef struct result {
  int n;
  double runaway_at; /* indentation of a step stopped by solver.max_force, or -1 */
  double d[NMAX], F[NMAX];
  int conv[NMAX];
} result;

static void run(const char *const *sets, int nsets, result *r) {
  cJSON *root = proto_json_load(SCENE_FILE, &err);
  if (!root) {
    fprintf(stderr, "%s\n", err.msg);
    exit(1);
  }
  for (int i = 0; i < nsets; i++) OK(proto_json_set(root, sets[i], &err));
  const cJSON *sec = cJSON_GetObjectItem(cJSON_GetObjectItem(root, "processes"), "block");
  blk_model m;
  OK(blk_model_from_config(&m, sec, "processes.block", &err));
  blk_state s;
  OK(blk_state_create(&m, &s, &err));
  const double dt = 1.0 / (m.rate > 0 ? m.rate : 51200.0), T = 6.7e-3;
  const int n_steps = (int)lround(T / dt);
  r->runaway_at = -1;
  r->n = 0;
  for (int n = 1; n <= n_steps; n++) {
    const double d = 2e-4 * fmin(n * dt / T, 1.0);
    if (blk_step(&m, &s, d, &err)) {
      CHECK(strstr(err.msg, "runaway") != NULL, "step error: %s", err.msg);
      r->runaway_at = d;
      printf("  stopped: %s\n", err.msg);
      break;
    }
    r->n = n;
    r->d[n - 1] = d;
    r->F[n - 1] = s.total_force;
    r->conv[n - 1] = s.converged;
  }
  blk_state_free(&s);
  blk_model_free(&m);
  cJSON_Delete(root);
}

/* Quasi-static force at indentation d (linear interpolation). */
static double qs_at(const result *q, double d) {
  for (int i = 1; i < q->n; i++)
    if (q->d[i] >= d)
      return q->F[i - 1] + (q->F[i] - q->F[i - 1]) * (d - q->d[i - 1]) / (q->d[i] - q->d[i - 1]);
  return q->F[q->n - 1];
}

/* First indentation where |F − F_qs| > 3 % of F_qs(0.2 mm) + 1 N; -1: never. */
static double leaves_band(const result *r, const result *q) {
  const double tol = 0.03 * q->F[q->n - 1] + 1.0;
  for (int i = 0; i < r->n; i++)
    if (!(fabs(r->F[i] - qs_at(q, r->d[i])) <= tol)) return r->d[i];
  return r->runaway_at;
}

static int all_converged(const result *r, double up_to) {
  for (int i = 0; i < r->n; i++)
    if (r->d[i] < up_to && !r->conv[i]) return 0;
  return 1;
}

int main(void) {
  static result qs, point, zoh, point2, dual;
  const char *q[] = {"processes.block.solver.quasi_static=true",
                     "processes.block.green.sampling=zoh"};
  run(q, 2, &qs);
  const char *p[] = {"processes.block.green.sampling=point"};
  run(p, 1, &point);
  const char *z[] = {"processes.block.green.sampling=zoh"};
  run(z, 1, &zoh);
  const char *p2[] = {"processes.block.green.sampling=point", "processes.block.green.refine=2"};
  run(p2, 2, &point2);
  const char *pd[] = {"processes.block.green.sampling=point",
                      "processes.block.solver.method=\"dual_newton\""};
  run(pd, 2, &dual);
  const double fail = leaves_band(&point, &qs);
  printf("quasi-static F(0.2 mm) = %.2f N\n", qs.F[qs.n - 1]);
  printf("point x1, plain Newton: leaves the band at %.4f mm\n", fail * 1e3);
  CHECK(fail > 0.04e-3 && fail < 0.09e-3, "failure at %g mm, expected 0.04-0.09", fail * 1e3);
  double z_at = leaves_band(&zoh, &qs), p2_at = leaves_band(&point2, &qs);
  printf("ZOH x1: %s; point x2: %s\n", z_at < 0 ? "stable" : "UNSTABLE",
         p2_at < 0 ? "stable" : "UNSTABLE");
  CHECK(z_at < 0, "ZOH x1 leaves the band at %g mm", z_at * 1e3);
  CHECK(p2_at < 0, "point x2 leaves the band at %g mm", p2_at * 1e3);
  CHECK(all_converged(&zoh, 1), "ZOH x1: a step did not converge");
  CHECK(all_converged(&point2, 1), "point x2: a step did not converge");
  const double dual_fail = leaves_band(&dual, &qs);
  printf("point x1, dual Newton: leaves the band at %.4f mm\n", dual_fail * 1e3);
  CHECK(dual_fail > 0, "dual Newton with point samples did not blow up");
  CHECK(all_converged(&dual, dual_fail), "dual Newton: a step before the blow-up did not converge");

  /* cure 2 on the heavy-tailed springs */
  static result sq, sp, sc, scq;
#define SPREAD "processes.block.springs.spread=0", "processes.block.springs.k0=3e4", \
               "processes.block.springs.lognormal=2.5"
#define CURE2 "processes.block.springs.soften={\"count\": 80, \"at\": 9e-6}"
  const char *s_q[] = {SPREAD, "processes.block.solver.quasi_static=true"};
  run(s_q, 4, &sq);
  const char *s_p[] = {SPREAD, "processes.block.green.sampling=point"};
  run(s_p, 4, &sp);
  const char *s_c[] = {SPREAD, "processes.block.green.sampling=point", CURE2};
  run(s_c, 5, &sc);
  const char *s_cq[] = {SPREAD, "processes.block.solver.quasi_static=true", CURE2};
  run(s_cq, 5, &scq);
  const double s_fail = leaves_band(&sp, &sq), c_fail = leaves_band(&sc, &scq);
  printf("log-normal springs: quasi-static F(0.2 mm) = %.2f N (softened: %.2f N)\n",
         sq.F[sq.n - 1], scq.F[scq.n - 1]);
  printf("point x1 without cure 2: leaves the band at %.4f mm; with cure 2: %s\n",
         s_fail * 1e3, c_fail < 0 ? "stable to 0.2 mm" : "UNSTABLE");
  CHECK(s_fail > 0.04e-3 && s_fail < 0.07e-3, "without cure 2: failure at %g mm, expected "
        "0.04-0.07", s_fail * 1e3);
  CHECK(c_fail < 0, "cure 2: leaves the band at %g mm", c_fail * 1e3);
  CHECK(sc.n == sq.n && all_converged(&sc, 1), "cure 2: a step did not converge or the run "
        "stopped (%d of %d steps)", sc.n, sq.n);
  return cosim_test_done("test_block_stability");
}
