/* Friction against rigid-body mechanics: a non-rotating grain on an incline
 * sticks below tan θ = μ and slides above with a = g (sin θ − μ cos θ); a free
 * sphere rolls without slip (a = 5/7 g sin θ, v = ω r) below tan θ = 7/2 μ and
 * slides above with a = g (sin θ − μ cos θ), ω̇ = 5 μ g cos θ / (2 r); a sphere
 * thrown flat without spin ends rolling with v = 5/7 v0 = ω r. The incline is
 * the plane z = 0 with gravity tilted by θ. As in LIGGGHTS the contact point
 * sits in the middle of the overlap, so the lever arm is r_c = r − δ/2 (δ the
 * static Hertz overlap): rolling means v = ω r_c, a = g sin θ / (1 + I/(m r_c²)). */
#include "dem_test.h"

static const double R = 5e-3, RHO = 2600, E = 1e7, NU = 0.3, MU = 0.4, G = 9.81;

/* lever arm r − δ/2 under the static normal load m g cos θ */
static double lever(double theta) {
  const double mass = RHO * 4.0 / 3.0 * M_PI * R * R * R, estar = E / (2 * (1 - NU * NU));
  return R - 0.5 * pow(3 * mass * G * cos(theta) / (4 * estar * sqrt(R)), 2.0 / 3.0);
}

static void setup(double theta, int fix, double v0, dem_model *m, dem_state *s) {
  const double mass = RHO * 4.0 / 3.0 * M_PI * R * R * R, estar = E / (2 * (1 - NU * NU));
  const double ds = pow(3 * mass * G * cos(theta) / (4 * estar * sqrt(R)), 2.0 / 3.0);
  char json[1024];
  snprintf(json, sizeof json,
           "{\"materials\":[{\"density\":%g,\"E\":%g,\"nu\":%g,\"restitution\":0.5,\"friction\":%g}],"
           "\"gravity\":[%.17g,0,%.17g],\"dt_fraction\":0.05,"
           "\"walls\":[{\"type\":\"plane\",\"point\":[0,0,0],\"normal\":[0,0,1]}],"
           "\"particles\":[{\"x\":[0,0,%.17g],\"v\":[%g,0,0],\"r\":%g,\"fix_rotation\":%s}]}",
           RHO, E, NU, MU, G * sin(theta), -G * cos(theta), R - ds, v0, R, fix ? "true" : "false");
  scene(json, m, s);
}

static void advance(const dem_model *m, dem_state *s, double t) {
  proto_err err;
  if (dem_advance(m, s, t - s->t, &err)) { fprintf(stderr, "%s\n", err.msg); exit(1); }
}

int main(void) {
  dem_model m;
  dem_state s;
  /* 1. non-rotating grain, tan θ = 0.8 μ: sticks (only the elastic tangential spring gives) */
  setup(atan(0.8 * MU), 1, 0, &m, &s);
  advance(&m, &s, 0.1);
  double x1 = s.x[0];
  advance(&m, &s, 0.3);
  printf("stick: x(0.1) = %.3g m, x(0.3) = %.3g m, v = %.3g m/s\n", x1, s.x[0], s.v[0]);
  CHECK(fabs(s.x[0] - x1) < 1e-12 && fabs(s.v[0]) < 1e-9,
        "grain below the friction angle creeps: %g -> %g", x1, s.x[0]);
  dem_state_free(&s); dem_model_free(&m);
  {
    /* tan θ = 0.4 μ: even the first overshoot (2 m g sin θ) stays below μ N, so the
     * tangential spring alone holds m g sin θ: x = m g sin θ / k_t, k_t = 8 G* sqrt(R δ) */
    const double th0 = atan(0.4 * MU), mass = RHO * 4.0 / 3.0 * M_PI * R * R * R;
    setup(th0, 1, 0, &m, &s);
    advance(&m, &s, 0.3);
    const double Gs = 1.0 / (2 * (2 - NU) * 2 * (1 + NU) / E), delta = R - s.x[2];
    CHECK_REL("sticking grain: elastic tangential displacement",
              s.x[0], mass * G * sin(th0) / (8 * Gs * sqrt(R * delta)), 1e-6);
  }
  dem_state_free(&s); dem_model_free(&m);

  /* 2. non-rotating grain, tan θ = 1.25 μ: slides with a = g (sin θ − μ cos θ) */
  double th = atan(1.25 * MU);
  setup(th, 1, 0, &m, &s);
  advance(&m, &s, 0.05);
  double v1 = s.v[0], t1 = s.t;
  advance(&m, &s, 0.15);
  CHECK_REL("sliding block acceleration",
            (s.v[0] - v1) / (s.t - t1), G * (sin(th) - MU * cos(th)), 1e-5);
  dem_state_free(&s); dem_model_free(&m);

  /* 3. free sphere, tan θ = 2 μ < 7/2 μ: rolls, a = 5/7 g sin θ, v = ω r */
  th = atan(2 * MU);
  setup(th, 0, 0, &m, &s);
  advance(&m, &s, 0.05);
  v1 = s.v[0]; t1 = s.t;
  advance(&m, &s, 0.15);
  double rc = lever(th);
  CHECK_REL("rolling sphere acceleration",
            (s.v[0] - v1) / (s.t - t1), G * sin(th) / (1 + 0.4 * R * R / (rc * rc)), 1e-5);
  CHECK_REL("rolling sphere v = omega r_c", s.omega[1] * rc, s.v[0], 1e-5);
  dem_state_free(&s); dem_model_free(&m);

  /* 4. free sphere, tan θ = 5 μ > 7/2 μ: slides and spins up */
  th = atan(5 * MU);
  setup(th, 0, 0, &m, &s);
  advance(&m, &s, 0.05);
  v1 = s.v[0];
  double w1 = s.omega[1];
  t1 = s.t;
  advance(&m, &s, 0.15);
  CHECK_REL("sliding sphere acceleration",
            (s.v[0] - v1) / (s.t - t1), G * (sin(th) - MU * cos(th)), 1e-5);
  CHECK_REL("sliding sphere angular acceleration",
            (s.omega[1] - w1) / (s.t - t1), MU * G * cos(th) * lever(th) / (0.4 * R * R), 1e-5);
  dem_state_free(&s); dem_model_free(&m);

  /* 5. flat plane, thrown at v0 without spin: ends rolling at 5/7 v0 */
  setup(0, 0, 1.0, &m, &s);
  advance(&m, &s, 0.3); /* sliding phase lasts 2 v0 / (7 μ g) = 0.073 s */
  rc = lever(0);
  CHECK_REL("sphere thrown flat: final v = v0/(1 + 2/5 r^2/r_c^2)",
            s.v[0], 1.0 / (1 + 0.4 * R * R / (rc * rc)), 1e-5);
  CHECK_REL("sphere thrown flat: v = omega r_c", s.omega[1] * rc, s.v[0], 1e-5);
  dem_state_free(&s); dem_model_free(&m);
  return cosim_test_done("test_dem_friction");
}
