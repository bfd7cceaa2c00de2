/* Hertz theory checks (seed 000 eq. 22–23; Kloss et al. 2012): a sphere hitting a
 * plane and two spheres colliding head-on, without damping: contact duration,
 * peak force and peak overlap against the analytic Hertz impact; with damping
 * the restitution coefficient; a sphere resting on a plane reaches the static
 * Hertz overlap. */
#include "dem_test.h"
#include <string.h>

static const double R = 5e-3, RHO = 2600, E = 1e8, NU = 0.3;

typedef struct impact { double tc, dmax, fmax, e; } impact;

/* Hertz impact of reduced mass ms, radius rs, modulus es at speed v. */
static impact hertz_theory(double ms, double rs, double es, double v) {
  impact t;
  t.dmax = pow(15.0 * ms * v * v / (16.0 * es * sqrt(rs)), 0.4);
  t.fmax = 4.0 / 3.0 * es * sqrt(rs) * pow(t.dmax, 1.5);
  /* t_c = 2 δmax/v ∫0^1 dx/sqrt(1 − x^{5/2}) = 2 δmax/v · (2/5) B(2/5, 1/2) */
  double I = 0.4 * tgamma(0.4) * tgamma(0.5) / tgamma(0.9);
  t.tc = 2.0 * t.dmax / v * I;
  t.e = 1;
  return t;
}

static impact run(int pair, double v, double e, double dt) {
  char json[2048];
  const double gap = 1e-7;
  if (pair)
    snprintf(json, sizeof json,
             "{\"exec\":\"dem_server\",\"materials\":[{\"density\":%g,\"E\":%g,\"nu\":%g,\"restitution\":%g,\"friction\":0.5}],"
             "\"gravity\":[0,0,0],\"dt\":%.17g,\"particles\":["
             "{\"x\":[0,0,%.17g],\"v\":[0,0,%.17g],\"r\":%g},{\"x\":[0,0,%.17g],\"v\":[0,0,%.17g],\"r\":%g}]}",
             RHO, E, NU, e, dt, R + gap / 2, -v / 2, R, -R - gap / 2, v / 2, R);
  else
    snprintf(json, sizeof json,
             "{\"materials\":[{\"density\":%g,\"E\":%g,\"nu\":%g,\"restitution\":%g,\"friction\":0.5}],"
             "\"gravity\":[0,0,0],\"dt\":%.17g,\"walls\":[{\"type\":\"plane\",\"point\":[0,0,0],\"normal\":[0,0,1]}],"
             "\"particles\":[{\"x\":[0,0,%.17g],\"v\":[0,0,%.17g],\"r\":%g}]}",
             RHO, E, NU, e, dt, R + gap, -v, R);
  dem_model m;
  dem_state s;
  scene(json, &m, &s);
  impact out = {0, 0, 0, 0};
  int in_contact = 0, steps = 0;
  proto_err err;
  for (int k = 0; k < 10000000; k++) {
    if (dem_step(&m, &s, &err)) { fprintf(stderr, "%s\n", err.msg); exit(1); }
    int g = s.id[0] == 0 ? 0 : 1; /* slot of grain 0 */
    double delta = pair ? 2 * R - fabs(s.x[2] - s.x[5]) : R - s.x[2];
    if (delta > 0) {
      in_contact = 1;
      steps++;
      if (delta > out.dmax) out.dmax = delta;
      if (fabs(s.force[3 * g + 2]) > out.fmax) out.fmax = fabs(s.force[3 * g + 2]);
    } else if (in_contact) {
      out.e = pair ? fabs(s.v[2] - s.v[5]) / v : fabs(s.v[2]) / v;
      break;
    }
  }
  out.tc = steps * dt;
  dem_state_free(&s);
  dem_model_free(&m);
  return out;
}

int main(void) {
  const double mass = RHO * 4.0 / 3.0 * M_PI * R * R * R;
  const double estar = E / (2 * (1 - NU * NU)); /* same material on both sides */
  const double speeds[] = {0.1, 1.0, 3.0};
  char what[128];
  for (int pair = 0; pair < 2; pair++)
    for (int k = 0; k < 3; k++) {
      double v = speeds[k];
      impact th = pair ? hertz_theory(mass / 2, R / 2, estar, v) : hertz_theory(mass, R, estar, v);
      impact got = run(pair, v, 1.0, th.tc / 3333.3);
      const char *kind = pair ? "pair" : "wall";
      snprintf(what, sizeof what, "%s v=%g contact duration", kind, v);
      CHECK_REL(what, got.tc, th.tc, 0.01);
      snprintf(what, sizeof what, "%s v=%g peak overlap", kind, v);
      CHECK_REL(what, got.dmax, th.dmax, 0.01);
      snprintf(what, sizeof what, "%s v=%g peak force", kind, v);
      CHECK_REL(what, got.fmax, th.fmax, 0.01);
      snprintf(what, sizeof what, "%s v=%g restitution (undamped)", kind, v);
      CHECK_REL(what, got.e, 1.0, 0.01);
      const double es[] = {0.5, 0.9};
      for (int q = 0; q < 2; q++) {
        impact d = run(pair, v, es[q], th.tc / 3333.3);
        snprintf(what, sizeof what, "%s v=%g restitution e=%g", kind, v, es[q]);
        CHECK_REL(what, d.e, es[q], 0.02);
      }
    }
  /* static overlap on a plane under gravity: 4/3 E* sqrt(r) δ^{3/2} = m g */
  {
    char json[1024];
    double g = 9.81;
    double ds = pow(3 * mass * g / (4 * estar * sqrt(R)), 2.0 / 3.0);
    snprintf(json, sizeof json,
             "{\"materials\":[{\"density\":%g,\"E\":%g,\"nu\":%g,\"restitution\":0.5,\"friction\":0.5}],"
             "\"gravity\":[0,0,%g],\"dt\":1e-6,\"walls\":[{\"type\":\"plane\",\"point\":[0,0,0],\"normal\":[0,0,1]}],"
             "\"particles\":[{\"x\":[0,0,%.17g],\"r\":%g}]}", RHO, E, NU, -g, R, R);
    dem_model m;
    dem_state s;
    proto_err err;
    scene(json, &m, &s);
    if (dem_advance(&m, &s, 0.1, &err)) { fprintf(stderr, "%s\n", err.msg); return 1; }
    CHECK_REL("static overlap on a plane", R - s.x[2], ds, 1e-6);
    CHECK(fabs(s.v[2]) < 1e-9, "resting grain still moves: v = %g", s.v[2]);
    dem_state_free(&s);
    dem_model_free(&m);
  }
  return cosim_test_done("test_dem_hertz");
}
