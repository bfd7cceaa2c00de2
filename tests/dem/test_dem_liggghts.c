/* One grain (r = 3.5 mm, E = 5e6, ν = 0.3, e = 0.5, μ = 0.6) hitting a plane at
 * vz = −0.7 m/s, normally and with vx = 0.2 m/s, dt = 1e-6 s: the trajectory
 * equals LIGGGHTS 3.8.0 (Debian) `model hertz tangential history` step by step.
 * Reference values from bench/dem/impact.liggghts (log printed with %.15g). */
#include "dem_test.h"

static void run(double vt, long steps, long peak_step, double *peak_f, double *vx, double *vz,
                double *wy) {
  char json[1024];
  snprintf(json, sizeof json,
           "{\"materials\":[{\"density\":2600,\"E\":5e6,\"nu\":0.3,\"restitution\":0.5,\"friction\":0.6}],"
           "\"gravity\":[0,0,0],\"dt\":1e-6,"
           "\"walls\":[{\"type\":\"plane\",\"point\":[0,0,0],\"normal\":[0,0,1]}],"
           "\"particles\":[{\"x\":[0,0,0.0035001],\"v\":[%g,0,-0.7],\"r\":0.0035}]}", vt);
  dem_model m;
  dem_state s;
  proto_err err;
  scene(json, &m, &s);
  for (long k = 1; k <= steps; k++) {
    if (dem_step(&m, &s, &err)) { fprintf(stderr, "%s\n", err.msg); exit(1); }
    if (k == peak_step) *peak_f = s.force[2];
  }
  *vx = s.v[0]; *vz = s.v[2]; *wy = s.omega[1];
  dem_state_free(&s);
  dem_model_free(&m);
}

int main(void) {
  double f, vx, vz, wy;
  run(0.0, 1400, 421, &f, &vx, &vz, &wy);
  check_rel("normal impact: F_z at step 421 (peak)", f, 0.770309709966501, 1e-9);
  check_rel("normal impact: rebound vz", vz, 0.349947667907081, 1e-9);
  run(0.2, 1400, 299, &f, &vx, &vz, &wy);
  check_rel("oblique impact: F_z at step 299", f, 0.710395362246951, 1e-9);
  check_rel("oblique impact: final vx", vx, 0.143481381020693, 1e-9);
  check_rel("oblique impact: final omega_y", wy, 39.7941075459724, 1e-9);
  check_rel("oblique impact: rebound vz", vz, 0.349947667907081, 1e-9);
  return finish("test_dem_liggghts");
}
