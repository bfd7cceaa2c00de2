/* test_dem_interface.c — what crosses the tread–grain interface balances
 * (issue 10): at every DEM step the nodal forces the coupled surface gets
 * (mesh_force, what dem_server sends the FEM as nodal_force) sum to minus the
 * forces the grains get, and, with "surface_couple", their moment about the
 * rim centre is minus the moment the grains get (orbital (x_i - c) × F_i
 * plus spin torque), both to 1e-12 relative.
 *
 * The scene: a cluster of grains in contact with each other (pair forces
 * cancel in the sums up to rounding), no gravity, no walls, pressed and
 * sheared by a coupled surface that is a triangulated sector of a rim
 * (radius 0.1 m) sinking, travelling and turning about its axle (node
 * velocities v_c + ω × (x − c), set every step as the coupler does), with
 * friction and rolling friction; once with LIGGGHTS' limit_force. The
 * grains' forces are the step's (velocity Verlet: F at x_{n+1}), the surface
 * nodes where the step left them. */
#include "dem_test.h"

#include <string.h>

#define NA 24 /* nodes around (sector) */
#define NW 4  /* nodes across */
#define RIM 0.1
#define STEPS 1500

typedef struct rig {
  double c[3], v[3], w; /* centre, its velocity, spin about +y */
  double x0[NA * NW * 3];
} rig;

static void surface_nodes(const rig *g, double angle, double *x, double *v) {
  const double ca = cos(angle), sa = sin(angle);
  for (int q = 0; q < NA * NW; q++) {
    const double *p = &g->x0[3 * q];
    double r[3] = {ca * p[0] + sa * p[2], p[1], -sa * p[0] + ca * p[2]}; /* about +y */
    for (int d = 0; d < 3; d++) x[3 * q + d] = g->c[d] + r[d];
    /* ω × r with ω = (0, w, 0) */
    v[3 * q + 0] = g->v[0] + g->w * r[2];
    v[3 * q + 1] = g->v[1];
    v[3 * q + 2] = g->v[2] - g->w * r[0];
  }
}

static void cross(const double *a, const double *b, double *o) {
  o[0] = a[1] * b[2] - a[2] * b[1];
  o[1] = a[2] * b[0] - a[0] * b[2];
  o[2] = a[0] * b[1] - a[1] * b[0];
}

static double norm(const double *a) { return sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]); }

static void run(int limit_force, double rolling, int couple) {
  /* 4 x 3 x 2 grains of r = 5 mm touching (centres 2r apart), top at z = 0 */
  char json[8192];
  int len = snprintf(json, sizeof json,
                     "{\"materials\":[{\"density\":2600,\"E\":5e6,\"nu\":0.3,\"restitution\":0.5,"
                     "\"friction\":0.6,\"rolling_friction\":%g},"
                     "{\"density\":1100,\"E\":20e6,\"nu\":0.45,\"restitution\":0.5,"
                     "\"friction\":0.8,\"rolling_friction\":%g}],"
                     "\"pairs\":[{\"materials\":[0,1],\"friction\":0.3}],"
                     "\"limit_force\":%s,\"surface_couple\":%s,\"surface_material\":1,\"gravity\":[0,0,0],"
                     "\"dt\":1e-5,\"particles\":[",
                     rolling, rolling, limit_force ? "true" : "false", couple ? "true" : "false");
  const double r = 0.005;
  int n = 0;
  for (int i = 0; i < 4; i++)
    for (int j = 0; j < 3; j++)
      for (int k = 0; k < 2; k++)
        len += snprintf(json + len, sizeof json - len,
                        "%s{\"x\":[%.6f,%.6f,%.6f],\"r\":%g,\"material\":0}", n++ ? "," : "",
                        -0.015 + 2 * r * i, -0.01 + 2 * r * j, -r - 2 * r * k, r * (1 - 0.04 * k));
  snprintf(json + len, sizeof json - len, "]}");
  dem_model m;
  dem_state s;
  proto_err err = {{0}};
  cJSON *j = cJSON_Parse(json);
  if (!j || dem_model_from_json(&m, j, "processes.dem", &err)) {
    fprintf(stderr, "setup: %s\n", err.msg);
    exit(2);
  }
  cJSON_Delete(j);
  /* the rim sector: angles -40..40 deg below the axle, width 0.04 m */
  rig g = {{0.0, 0.0, RIM + 0.0005}, {0.3, 0.0, -0.2}, 4.0, {0}};
  for (int a = 0; a < NA; a++)
    for (int b = 0; b < NW; b++) {
      double th = (-40.0 + 80.0 * a / (NA - 1)) * M_PI / 180;
      double *p = &g.x0[3 * (a * NW + b)];
      p[0] = RIM * sin(th);
      p[1] = -0.02 + 0.04 * b / (NW - 1);
      p[2] = -RIM * cos(th);
    }
  int32_t tri[(NA - 1) * (NW - 1) * 6];
  int nt = 0;
  for (int a = 0; a + 1 < NA; a++)
    for (int b = 0; b + 1 < NW; b++) {
      int p = a * NW + b, q = p + NW;
      int32_t t[6] = {p, q, p + 1, q, q + 1, p + 1}; /* outward (down) */
      memcpy(&tri[3 * nt], t, sizeof t);
      nt += 2;
    }
  double x[NA * NW * 3], v[NA * NW * 3];
  surface_nodes(&g, 0, x, v);
  if (dem_model_set_surface(&m, NA * NW, x, nt, tri, &err) || dem_state_init(&m, &s, 0, &err)) {
    fprintf(stderr, "setup: %s\n", err.msg);
    exit(2);
  }
  double worst_f = 0, worst_t = 0, f_peak = 0, t_peak = 0;
  int touching = 0;
  for (int k = 0; k < STEPS; k++) {
    const double t = s.t;
    if (k == STEPS / 2) g.v[2] = 0.2; /* back out: contacts open */
    surface_nodes(&g, g.w * t, x, v);
    dem_mesh_set_nodes(&m, &s, 0, x, v);
    if (dem_step(&m, &s, &err)) {
      fprintf(stderr, "step %d: %s\n", k, err.msg);
      exit(2);
    }
    for (int d = 0; d < 3; d++) g.c[d] += g.v[d] * s.dt;
    /* sums: grains (orbital about c + spin), surface nodes */
    double Fg[3] = {0}, Tg[3] = {0}, Fm[3] = {0}, Tm[3] = {0}, mag = 0, tmag = 0;
    for (int i = 0; i < s.n; i++) {
      const double *F = &s.force[3 * i];
      double rel[3], tq[3];
      for (int d = 0; d < 3; d++) rel[d] = s.x[3 * i + d] - g.c[d];
      cross(rel, F, tq);
      for (int d = 0; d < 3; d++) {
        Fg[d] += F[d];
        Tg[d] += tq[d] + s.torque[3 * i + d];
      }
      mag += norm(F);
      tmag += norm(tq) + norm(&s.torque[3 * i]);
    }
    const double *xn = s.mesh_x[0], *fn = s.mesh_force[0];
    for (int q = 0; q < NA * NW; q++) {
      double rel[3], tq[3];
      for (int d = 0; d < 3; d++) rel[d] = xn[3 * q + d] - g.c[d];
      cross(rel, &fn[3 * q], tq);
      for (int d = 0; d < 3; d++) {
        Fm[d] += fn[3 * q + d];
        Tm[d] += tq[d];
      }
    }
    const double nf = norm(Fm), ntq = norm(Tm);
    if (nf == 0) continue;
    touching++;
    double df[3], dt[3];
    for (int d = 0; d < 3; d++) {
      df[d] = Fg[d] + Fm[d];
      dt[d] = Tg[d] + Tm[d];
    }
    /* relative to the interface's force and moment; the pair forces in the
     * grains' sums only add rounding of their own size (mag, tmag) */
    double ef = norm(df) / fmax(nf, 1e-300), et = norm(dt) / fmax(ntq, 1e-300);
    (void)mag;
    (void)tmag;
    if (ef > worst_f) worst_f = ef;
    if (et > worst_t) worst_t = et;
    if (nf > f_peak) f_peak = nf;
    if (ntq > t_peak) t_peak = ntq;
  }
  printf("surface_couple %d, limit_force %d, rolling %g: %d steps with surface contact, max |F| %.3g N, max |T| "
         "%.3g N m; max |sum F_nodes + sum F_grains| / |sum F_nodes| = %.3g, torque about the "
         "rim centre %.3g\n",
         couple, limit_force, rolling, touching, f_peak, t_peak, worst_f, worst_t);
  CHECK(touching > 200, "the surface touched the grains in %d steps", touching);
  CHECK(worst_f <= 1e-12, "force balance %.3g > 1e-12", worst_f);
  /* without the couple (eq. 42 alone, as LIGGGHTS) the moment misses
   * (δ/2) n × F_t per contact and the rolling torque */
  if (couple) CHECK(worst_t <= 1e-12, "torque balance %.3g > 1e-12", worst_t);
  else CHECK(worst_t > 1e-6, "without surface_couple the moment is not exact (%.3g)", worst_t);
  dem_state_free(&s);
  dem_model_free(&m);
}

int main(void) {
  run(0, 0.0, 1);
  run(1, 0.0, 1);
  run(0, 0.05, 1);
  run(0, 0.0, 0);
  run(0, 0.05, 0);
  return cosim_test_done("test_dem_interface");
}
