/* The dense and the matrix-free per-step solvers solve the same problem
 * (issue 14): on a 64 × 64 block (stiffening roughness springs, a curved
 * rough road, the synthetic layer) they agree to 1e-10 in every element
 * force at every step —
 *  1. quasi-static loading (dense dual Newton and the thesis' Newton vs
 *     constrained CG);
 *  2. adhesion: load, then unload into tension with the release force
 *     (elements adhere and let go on the same steps);
 *  3. dynamic loading (history term, separable synthetic layer);
 * and 4. the tangent stiffness dF/dd of the solver's Jacobian equals the
 * central difference of the force–indentation curve (an independent check:
 * two extra solves). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "blk_test.h"
#include "contact_block/blk.h"

static proto_err err;

enum { N = 64, M = N * N, STEPS = 12 };

static void scene(blk_model *m, int quasi_static, int adhesion, blk_method method) {
  const double dx = 0.5e-3, R = 0.1;
  OK(blk_model_init(m, N, N, dx, dx, &err));
  OK(blk_road_paraboloid(m, R, &err));
  uint64_t h = 12345; /* small roughness on the paraboloid (a hash, deterministic) */
  for (int e = 0; e < M; e++) {
    h = h * 6364136223846793005ull + 1442695040888963407ull;
    m->z_road[e] += 2e-6 * ((double)(h >> 11) / 9007199254740992.0 - 0.5);
  }
  OK(blk_springs_stiffening(m, 3e5, 1.5e-6, 0.5, 2, 5e-4, 33, &err));
  blk_synth sy = {.E = 25e6, .nu = 0.49, .rate = 51200, .Q = 64, .f_mode = 2000,
                  .zeta = 0.1, .beta = 0.0, .tau_fast = 2e-5, .point_sampling = 0};
  OK(blk_green_synthetic(m, &sy, &err));
  m->solver.quasi_static = quasi_static;
  m->adhesion = adhesion;
  m->release_force = 0.3;
  m->solver.method = method;
  m->solver.max_iter = 100;
  m->solver.tol = 1e-18;
}

/* Road history: load to 60 µm in 4 steps, then unload to −20 µm. */
static double road(int n, int unload) {
  if (!unload || n <= 4) return 6e-5 * fmin(n, 4) / 4.0;
  return 6e-5 - 8e-5 * (n - 4) / (STEPS - 4.0);
}

/* Runs STEPS steps, element forces per step into F [STEPS][M]. */
static void run(int quasi_static, int adhesion, blk_method method, double *F, int *contacts,
                double *stiff) {
  blk_model m;
  scene(&m, quasi_static, adhesion, method);
  blk_state s;
  OK(blk_state_create(&m, &s, &err));
  for (int n = 1; n <= STEPS; n++) {
    OK(blk_step(&m, &s, road(n, adhesion), &err));
    CHECK(s.converged, "method %d step %d: not converged (residual %g)", method, n,
          s.residual);
    memcpy(F + (size_t)(n - 1) * M, s.force, sizeof(double) * M);
    contacts[n - 1] = s.n_contact;
    stiff[n - 1] = s.stiffness;
  }
  blk_state_free(&s);
  blk_model_free(&m);
}

static void compare(const char *what, int quasi_static, int adhesion, blk_method dense) {
  static double Fd[STEPS * M], Fc[STEPS * M];
  int cd[STEPS], cc[STEPS];
  double kd[STEPS], kc[STEPS];
  run(quasi_static, adhesion, dense, Fd, cd, kd);
  run(quasi_static, adhesion, BLK_CG, Fc, cc, kc);
  double diff = 0, fmax_ = 0, fmin_ = 0, kdiff = 0;
  for (int i = 0; i < STEPS * M; i++) {
    diff = fmax(diff, fabs(Fd[i] - Fc[i]));
    fmax_ = fmax(fmax_, fabs(Fd[i]));
  }
  int same_contacts = 1;
  for (int n = 0; n < STEPS; n++) {
    same_contacts &= cd[n] == cc[n];
    double tot = 0;
    for (int e = 0; e < M; e++) tot += Fd[(size_t)n * M + e];
    fmin_ = fmin(fmin_, tot);
    if (kd[n] > 0) kdiff = fmax(kdiff, fabs(kc[n] / kd[n] - 1));
  }
  printf("%s: dense (method %d) vs matrix-free: element forces max diff %.2e rel (max "
         "element force %.3g N, most tensile total %.3g N, contacts at the peak %d), "
         "tangent rel diff %.1e\n", what, dense, diff / fmax_, fmax_, fmin_, cd[3], kdiff);
  CHECK(fmax_ > 0.1, "%s: no load", what);
  CHECK(diff <= 1e-10 * fmax_, "%s: solvers differ by %.2e rel", what, diff / fmax_);
  CHECK(same_contacts, "%s: contact counts differ", what);
  CHECK(kdiff <= 1e-6, "%s: tangent stiffness differs by %.2e", what, kdiff);
  if (adhesion) CHECK(fmin_ < -0.1, "%s: the block never pulled on the road (%g N)", what, fmin_);
}

/* Tangent stiffness against the central difference of F(δ) (quasi-static). */
static void tangent_fd(blk_method method) {
  blk_model m;
  scene(&m, 1, 0, method);
  blk_state s;
  OK(blk_state_create(&m, &s, &err));
  const double d0 = 5e-5, h = 1e-4 * d0;
  OK(blk_step(&m, &s, d0, &err));
  const double K = s.stiffness;
  OK(blk_step(&m, &s, d0 + h, &err));
  const double Fp = s.total_force;
  OK(blk_step(&m, &s, d0 - h, &err));
  const double Fm = s.total_force, Kfd = (Fp - Fm) / (2 * h);
  printf("method %d: tangent %.8e N/m, central difference %.8e N/m (rel %+.1e)\n", method,
         K, Kfd, K / Kfd - 1);
  CHECK(fabs(K / Kfd - 1) < 1e-4, "method %d: tangent %g vs finite difference %g", method,
        K, Kfd);
  blk_state_free(&s);
  blk_model_free(&m);
}

int main(void) {
  compare("quasi-static, springs", 1, 0, BLK_NR_DUAL);
  compare("quasi-static, springs (thesis' Newton)", 1, 0, BLK_NR_PLAIN);
  compare("quasi-static, springs, adhesion", 1, 1, BLK_NR_DUAL);
  compare("dynamic, springs", 0, 0, BLK_NR_DUAL);
  tangent_fd(BLK_CG);
  tangent_fd(BLK_NR_PLAIN);
  return cosim_test_done("test_block_solvers");
}
