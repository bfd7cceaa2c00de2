/* One grain (r = 3.5 mm, E = 5e6, ν = 0.3, e = 0.5, μ = 0.6) hitting a plane at
 * vz = −0.7 m/s, normally and with vx = 0.2 m/s, dt = 1e-6 s: the trajectory
 * equals LIGGGHTS 3.8.0 (Debian) `model hertz tangential history` step by step.
 * Reference values from bench/dem/impact.liggghts (log printed with %.15g).
 * Material pairs: the same grain hitting a plane of another material (E 2e7,
 * ν 0.45) whose pair with the grain has its own friction 0.3 and restitution
 * 0.7 (the config's "pairs"; LIGGGHTS' peratomtypepair tables), with and
 * without "limit_force" (LIGGGHTS `limitForce on`: F_n never attractive):
 * bench/dem/impact_pair.liggghts with vt 0.2, mu12 0.3, e12 0.7, limit off/on. */
#include "dem_test.h"

/* Steps the one-grain scene `json` 1400 steps; F_z at peak_step and the
 * final velocities. */
static void impact(const char *json, long peak_step, double *peak_f, double *vx, double *vz, double *wy) {
  dem_model m;
  dem_state s;
  proto_err err;
  scene(json, &m, &s);
  for (long k = 1; k <= 1400; k++) {
    if (dem_step(&m, &s, &err)) { fprintf(stderr, "%s\n", err.msg); exit(1); }
    if (k == peak_step) *peak_f = s.force[2];
  }
  *vx = s.v[0]; *vz = s.v[2]; *wy = s.omega[1];
  dem_state_free(&s);
  dem_model_free(&m);
}

static void run(double vt, long peak_step, double *peak_f, double *vx, double *vz, double *wy) {
  char json[1024];
  snprintf(json, sizeof json,
           "{\"materials\":[{\"density\":2600,\"E\":5e6,\"nu\":0.3,\"restitution\":0.5,\"friction\":0.6}],"
           "\"gravity\":[0,0,0],\"dt\":1e-6,"
           "\"walls\":[{\"type\":\"plane\",\"point\":[0,0,0],\"normal\":[0,0,1]}],"
           "\"particles\":[{\"x\":[0,0,0.0035001],\"v\":[%g,0,-0.7],\"r\":0.0035}]}", vt);
  impact(json, peak_step, peak_f, vx, vz, wy);
}

static void run_pair(int limit, long peak_step, double *peak_f, double *vx, double *vz, double *wy) {
  char json[1024];
  snprintf(json, sizeof json,
           "{\"materials\":[{\"density\":2600,\"E\":5e6,\"nu\":0.3,\"restitution\":0.5,\"friction\":0.6},"
           "{\"density\":1000,\"E\":2e7,\"nu\":0.45,\"restitution\":0.5,\"friction\":0.6}],"
           "\"pairs\":[{\"materials\":[1,0],\"friction\":0.3,\"restitution\":0.7}],\"limit_force\":%s,"
           "\"gravity\":[0,0,0],\"dt\":1e-6,"
           "\"walls\":[{\"type\":\"plane\",\"point\":[0,0,0],\"normal\":[0,0,1],\"material\":1}],"
           "\"particles\":[{\"x\":[0,0,0.0035001],\"v\":[0.2,0,-0.7],\"r\":0.0035}]}", limit ? "true" : "false");
  impact(json, peak_step, peak_f, vx, vz, wy);
}

/* Two grains colliding head on: with limit_force the normal force on grain 0
 * (along −x) is never attractive; without it, damping pulls at the end. */
static double min_pair_force(int limit) {
  char json[1024];
  snprintf(json, sizeof json,
           "{\"materials\":[{\"density\":2600,\"E\":5e6,\"nu\":0.3,\"restitution\":0.3,\"friction\":0.6}],"
           "\"limit_force\":%s,\"gravity\":[0,0,0],\"dt\":1e-6,"
           "\"particles\":[{\"x\":[0,0,0],\"v\":[0.7,0,0],\"r\":0.0035},"
           "{\"x\":[0.0070001,0,0],\"v\":[-0.7,0,0],\"r\":0.0035}]}", limit ? "true" : "false");
  dem_model m;
  dem_state s;
  proto_err err;
  scene(json, &m, &s);
  double lo = 0;
  for (long k = 1; k <= 2000; k++) {
    if (dem_step(&m, &s, &err)) { fprintf(stderr, "%s\n", err.msg); exit(1); }
    const int i = s.id[0] == 0 ? 0 : 1;
    lo = fmin(lo, -s.force[3 * i]); /* repulsion pushes grain 0 towards −x */
  }
  dem_state_free(&s);
  dem_model_free(&m);
  return lo;
}

int main(void) {
  double f, vx, vz, wy;
  run(0.0, 421, &f, &vx, &vz, &wy);
  CHECK_REL("normal impact: F_z at step 421 (peak)", f, 0.770309709966501, 1e-9);
  CHECK_REL("normal impact: rebound vz", vz, 0.349947667907081, 1e-9);
  run(0.2, 299, &f, &vx, &vz, &wy);
  CHECK_REL("oblique impact: F_z at step 299", f, 0.710395362246951, 1e-9);
  CHECK_REL("oblique impact: final vx", vx, 0.143481381020693, 1e-9);
  CHECK_REL("oblique impact: final omega_y", wy, 39.7941075459724, 1e-9);
  CHECK_REL("oblique impact: rebound vz", vz, 0.349947667907081, 1e-9);
  run_pair(0, 299, &f, &vx, &vz, &wy);
  CHECK_REL("pair friction 0.3, e 0.7: F_z at step 299", f, 0.934294476843845, 1e-9);
  CHECK_REL("pair friction 0.3, e 0.7: final vx", vx, 0.152128025423608, 1e-9);
  CHECK_REL("pair friction 0.3, e 0.7: final omega_y", wy, 33.694688332888, 1e-9);
  CHECK_REL("pair friction 0.3, e 0.7: rebound vz", vz, 0.489998664737585, 1e-9);
  run_pair(1, 299, &f, &vx, &vz, &wy);
  CHECK_REL("... with limit_force: F_z at step 299", f, 0.934294476843845, 1e-9);
  CHECK_REL("... with limit_force: final vx", vx, 0.154763226379975, 1e-9);
  CHECK_REL("... with limit_force: final omega_y", wy, 31.8199920611984, 1e-9);
  CHECK_REL("... with limit_force: rebound vz", vz, 0.502736886283737, 1e-9);
  const double with = min_pair_force(1), without = min_pair_force(0);
  printf("grain pair, e = 0.3: least normal force %.3g N with limit_force, %.3g N without\n", with, without);
  CHECK(with == 0 && without < -1e-3, "limit_force: least normal force %g (clamped) / %g (not)", with, without);
  return cosim_test_done("test_dem_liggghts");
}
