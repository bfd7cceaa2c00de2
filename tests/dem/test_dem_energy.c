/* Elastic (e = 1), frictionless grains in a closed box, no gravity: the total
 * energy (kinetic + Hertz elastic) is conserved to 1e-6 relative over 1e5
 * steps (velocity Verlet is symplectic; Hertz forces are C¹ at contact).
 * With "orientation" on, a free grain spinning at ω turns by |ω|t about ω
 * (the quaternion against the exact rotation); off, q stays the identity. */
#include "dem_test.h"
#include <string.h>

static void test_orientation(int on) {
  const double w[3] = {30, -40, 120}, T = 0.05; /* |ω| = 130 rad/s */
  char json[512];
  snprintf(json, sizeof json,
           "{\"materials\":[{\"density\":2600,\"E\":1e7,\"nu\":0.3,\"restitution\":0.5,\"friction\":0.5}],"
           "\"gravity\":[0,0,0],\"orientation\":%s,\"dt\":1e-5,"
           "\"particles\":[{\"x\":[0,0,0],\"omega\":[%g,%g,%g],\"r\":0.005}]}",
           on ? "true" : "false", w[0], w[1], w[2]);
  dem_model m;
  dem_state s;
  proto_err err;
  scene(json, &m, &s);
  if (dem_advance(&m, &s, T, &err)) { fprintf(stderr, "%s\n", err.msg); exit(1); }
  const double wm = sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]), h = 0.5 * wm * s.t;
  const double want[4] = {cos(h), sin(h) * w[0] / wm, sin(h) * w[1] / wm, sin(h) * w[2] / wm};
  double e = 0;
  for (int k = 0; k < 4; k++) e = fmax(e, fabs(s.q[k] - (on ? want[k] : k == 0)));
  printf("orientation %s: %.0f rad turned, max |q - exact| = %.3g\n", on ? "on" : "off", 2 * h, e);
  CHECK(e < 1e-9, "quaternion off the exact rotation by %.3g (orientation %s)", e, on ? "on" : "off");
  dem_state_free(&s);
  dem_model_free(&m);
}

int main(int argc, char **argv) {
  test_orientation(1);
  test_orientation(0);
  const int steps = argc > 1 ? atoi(argv[1]) : 100000;
  const double frac = argc > 2 ? atof(argv[2]) : 0.002; /* fluctuation ~ dt^2: 6.5e-5 at 0.02 T_R */
  char json[8192];
  int len = snprintf(json, sizeof json,
      "{\"materials\":[{\"density\":2600,\"E\":1e7,\"nu\":0.3,\"restitution\":1,\"friction\":0}],"
      "\"gravity\":[0,0,0],\"dt_fraction\":%g,"
      "\"walls\":[{\"type\":\"box\",\"lo\":[0,0,0],\"hi\":[0.03,0.03,0.03]}],\"particles\":[", frac);
  uint64_t st = 12345;
  int n = 0;
  for (int i = 0; i < 2; i++)
    for (int j = 0; j < 2; j++)
      for (int k = 0; k < 2; k++) {
        double v[3];
        for (int a = 0; a < 3; a++) {
          st = st * 6364136223846793005ull + 1442695040888963407ull;
          v[a] = ((double)(st >> 11) / 9007199254740992.0 - 0.5) * 1.0;
        }
        len += snprintf(json + len, sizeof json - len,
                        "%s{\"x\":[%g,%g,%g],\"v\":[%.17g,%.17g,%.17g],\"omega\":[%d,0,0],\"r\":%g}",
                        n++ ? "," : "", 0.008 + 0.014 * i, 0.008 + 0.014 * j, 0.008 + 0.014 * k,
                        v[0], v[1], v[2], 10 * i, 0.004 + 0.001 * k);
      }
  snprintf(json + len, sizeof json - len, "]}");
  dem_model m;
  dem_state s;
  proto_err err;
  scene(json, &m, &s);
  const double e0 = s.kinetic_energy + s.elastic_energy;
  double worst = 0, worst_free = 0;
  int64_t contact_steps = 0;
  for (int k = 0; k < steps; k++) {
    if (dem_step(&m, &s, &err)) { fprintf(stderr, "%s\n", err.msg); return 1; }
    double e = s.kinetic_energy + s.elastic_energy;
    double d = fabs(e - e0) / e0;
    if (d > worst) worst = d;
    contact_steps += s.contacts > 0;
    if (s.contacts == 0 && d > worst_free) worst_free = d; /* no contact: no shadow-energy term */
  }
  printf("dt = %.3g s = %.3g T_R; %d steps, %lld steps with contacts, %lld rebuilds\n", s.dt,
         s.dt / m.rayleigh_time, steps, (long long)contact_steps, (long long)s.rebuilds);
  CHECK(contact_steps > steps / 20, "too few contacts to test anything (%lld)", (long long)contact_steps);
  printf("max |E(t) - E(0)| / E(0) = %.3g at any step, %.3g at contact-free steps\n", worst, worst_free);
  CHECK(worst <= 1e-6, "energy drift %.3g > 1e-6", worst);
  dem_state_free(&s);
  dem_model_free(&m);
  return cosim_test_done("test_dem_energy");
}
