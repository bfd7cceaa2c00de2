/* bench_lgd_diff — what liggghts_dem does differently from dem_server, each
 * effect measured on a small scene run in both engines side by side (the twin
 * of tests/liggghts/lgd_test.h): LIGGGHTS' rules for mesh contacts (features
 * of nearly coplanar faces, a face contact plus the neighbour's edge near a
 * convex edge, contact history per triangle), the cost of re-deciding edge and
 * corner activity, and what returning the last sub-step's nodal force instead
 * of the step average would cost. Prints a markdown table (rank 0).
 *   mpirun -np 1 build/bin/bench_lgd_diff > table.md */
#include "../../tests/liggghts/lgd_test.h"

#include <time.h>

#define MAT "\"materials\":[{\"density\":2600,\"E\":5e6,\"nu\":0.3,\"restitution\":0.5,\"friction\":0.6}]"
enum { N = 4, NN = (N + 1) * (N + 1), NT = 2 * N * N };
static const double L = 0.02, R = 0.004;

static void row(const char *what, const char *scene, const char *effect) {
  if (g_rank == 0) printf("| %s | %s | %s |\n", what, scene, effect);
}

static void still(double t, int nn, const double *x0, double *x, double *v, void *ctx) {
  (void)t; (void)ctx;
  memcpy(x, x0, sizeof(double) * 3 * (size_t)nn);
  memset(v, 0, sizeof(double) * 3 * (size_t)nn);
}

/* The centre node rises at 0.04 m/s from t = 0. */
static void apex_rising(double t, int nn, const double *x0, double *x, double *v, void *ctx) {
  const double dt = *(const double *)ctx, rise = 0.04;
  for (int a = 0; a < nn; a++)
    for (int k = 0; k < 3; k++) {
      const int c = k == 2 && fabs(x0[3 * a]) < 1e-12 && fabs(x0[3 * a + 1]) < 1e-12;
      x[3 * a + k] = x0[3 * a + k] + (c ? rise * t : 0);
      v[3 * a + k] = c ? rise : 0;
    }
  (void)dt;
}

/* 1. A grain resting exactly on a node of a flat plate whose node starts to
 * rise: until the bend passes LIGGGHTS' coplanarity angle the corner stays
 * inactive by LIGGGHTS' own rule. Largest |x_lgd − x_dem| / r. */
static double subthreshold(double tolerance) {
  static double x0[3 * NN];
  static int32_t tri[3 * NT];
  lgd_grid(N, L, 0, 0, x0, tri);
  char json[400];
  snprintf(json, sizeof json, "{" MAT ",\"gravity\":[0,0,-9.81],\"dt\":2e-5,\"max_overlap_ratio\":1,"
           "\"particles\":[{\"x\":[0,0,%.17g],\"r\":%.17g}]}", R - 9.4e-6, R); /* near its rest overlap */
  twin w;
  double dt = 6e-5;
  twin_open_tol(&w, json, NN, x0, NT, tri, dt, 0, tolerance);
  double d = 0;
  for (int k = 0; k < 500; k++) { /* 30 ms: the bend passes 0.26° at 1.1 ms */
    twin_step(&w, apex_rising, &dt);
    if (k % 5 == 0) d = fmax(d, twin_position_diff(&w));
  }
  twin_close(&w);
  return d / R;
}

/* 2. A grain dropped onto a roof (slope angle 5°) at a distance s from its
 * ridge: near a convex edge LIGGGHTS adds the neighbour triangle's edge contact
 * to the face contact; dem_server keeps one. Peak force and rebound ratios. */
static void near_edge(double s, int side, double *peak_ratio, double *rebound_ratio) {
  static double x0[3 * NN];
  static int32_t tri[3 * NT];
  const double slope = tan(5 * M_PI / 180), r = 0.003;
  lgd_grid(N, L, 0, slope, x0, tri);
  const double x = side * s, n[3] = {side * slope, 0, 1}, nl = sqrt(1 + slope * slope);
  const double gap = 1e-4, zs = -slope * fabs(x); /* surface under the grain */
  double c[3] = {x + n[0] / nl * (r + gap), 0.0031, zs + n[2] / nl * (r + gap)};
  char json[400];
  snprintf(json, sizeof json, "{" MAT ",\"gravity\":[0,0,0],\"dt\":1e-6,\"particles\":[{\"x\":[%.17g,%.17g,%.17g],"
           "\"v\":[%.17g,0,%.17g],\"r\":%.17g}]}", c[0], c[1], c[2], -0.5 * n[0] / nl, -0.5 * n[2] / nl, r);
  twin w;
  twin_open(&w, json, NN, x0, NT, tri, 1e-6, 0);
  double peak_l = 0, peak_d = 0;
  for (int k = 0; k < 1500; k++) {
    twin_step(&w, still, NULL);
    if (g_rank == 0) {
      peak_l = fmax(peak_l, fabs(lgd_result(w.sim)->wall_force[2]));
      peak_d = fmax(peak_d, fabs(w.dem_wall[2]));
    }
  }
  double lv[3];
  proto_err err = {{0}};
  if (lgd_gather(w.sim, NULL, lv, NULL, &err)) die("gather", &err);
  *peak_ratio = peak_l / peak_d;
  *rebound_ratio = sqrt(lv[0] * lv[0] + lv[2] * lv[2]) /
                   sqrt(w.sd.v[0] * w.sd.v[0] + w.sd.v[2] * w.sd.v[2]);
  twin_close(&w);
}

/* 3./4. A grain sliding and rolling across the ridge of a roof (slope angle
 * `deg`, 0 = flat): contact history per triangle in LIGGGHTS, carried across
 * edges by dem_server. Relative difference of the final velocity and spin. */
static void across(double deg, double *dv, double *dw) {
  static double x0[3 * NN];
  static int32_t tri[3 * NT];
  const double slope = tan(deg * M_PI / 180), r = 0.003;
  lgd_grid(N, L, 0, slope, x0, tri);
  char json[400];
  snprintf(json, sizeof json, "{" MAT ",\"gravity\":[0,0,-9.81],\"dt\":1e-5,\"particles\":[{\"x\":[-0.006,0.0031,%.17g],"
           "\"v\":[0.3,0,0],\"r\":%.17g}]}", -slope * 0.006 + r / cos(atan(slope)) - 1e-5, r);
  twin w;
  twin_open(&w, json, NN, x0, NT, tri, 1e-5, 0);
  for (int k = 0; k < 4000; k++) twin_step(&w, still, NULL); /* 40 ms: over the ridge */
  double lv[3], lw[3];
  proto_err err = {{0}};
  if (lgd_gather(w.sim, NULL, lv, lw, &err)) die("gather", &err);
  const double *v = w.sd.v, *o = w.sd.omega;
  *dv = sqrt(pow(lv[0] - v[0], 2) + pow(lv[1] - v[1], 2) + pow(lv[2] - v[2], 2)) / sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
  *dw = sqrt(pow(lw[0] - o[0], 2) + pow(lw[1] - o[1], 2) + pow(lw[2] - o[2], 2)) / sqrt(o[0] * o[0] + o[1] * o[1] + o[2] * o[2]);
  twin_close(&w);
}

/* 5. Rolling friction: LIGGGHTS' `cdt` takes the elastic normal force kn·δ
 * and drops the torque's component along the normal; dem_server uses |F_n|
 * with damping and keeps it. A grain rolling and spinning on a plane. */
static void rolling(double *dv, double *dw) {
  twin w;
  twin_open(&w, "{\"materials\":[{\"density\":2600,\"E\":5e6,\"nu\":0.3,\"restitution\":0.5,\"friction\":0.6,"
                "\"rolling_friction\":0.2}],\"gravity\":[0,0,-9.81],\"dt\":1e-6,"
                "\"walls\":[{\"type\":\"plane\",\"point\":[0,0,0],\"normal\":[0,0,1]}],\"particles\":["
                "{\"x\":[0,0,0.0035001],\"v\":[0.3,-0.1,-0.5],\"omega\":[5,-20,30],\"r\":0.0035}]}",
            0, NULL, 0, NULL, 1e-5, 0);
  for (int k = 0; k < 2000; k++) twin_step(&w, NULL, NULL); /* 20 ms */
  double lv[3], lw[3];
  proto_err err = {{0}};
  if (lgd_gather(w.sim, NULL, lv, lw, &err)) die("gather", &err);
  const double *v = w.sd.v, *o = w.sd.omega;
  *dv = sqrt(pow(lv[0] - v[0], 2) + pow(lv[1] - v[1], 2) + pow(lv[2] - v[2], 2)) / sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
  *dw = sqrt(pow(lw[0] - o[0], 2) + pow(lw[1] - o[1], 2) + pow(lw[2] - o[2], 2)) / sqrt(o[0] * o[0] + o[1] * o[1] + o[2] * o[2]);
  twin_close(&w);
}

/* 6. Cost of the activity rule on a tread-sized surface (µs per triangle). */
static double activity_cost(int n) {
  const int nn = (n + 1) * (n + 1), nt = 2 * n * n;
  double *x = malloc(sizeof(double) * 3 * (size_t)nn);
  int32_t *tri = malloc(sizeof(int32_t) * 3 * (size_t)nt);
  uint8_t *e = malloc(3 * (size_t)nt), *c = malloc(3 * (size_t)nt);
  lgd_grid(n, 0.3, 0, 0, x, tri);
  for (int a = 0; a < nn; a++) x[3 * a + 2] = 1e-3 * sin(40 * x[3 * a]) * cos(30 * x[3 * a + 1]);
  lgd_topo t;
  proto_err err = {{0}};
  if (lgd_topo_build(&t, nn, nt, tri, &err)) die("topology", &err);
  const int reps = 20;
  const double t0 = MPI_Wtime();
  for (int k = 0; k < reps; k++) lgd_topo_activity(&t, x, e, c);
  const double us = (MPI_Wtime() - t0) / reps / nt * 1e6;
  lgd_topo_free(&t);
  free(x); free(tri); free(e); free(c);
  return us;
}

/* 7. Sub-steps: a grain hits the plate with 5 DEM steps per coupling step.
 * The impulse the surface gets, Σ F Δt, from the step average (what both
 * return under the role table) against the last sub-step's force (what
 * dem_server returned before), relative to the grain's momentum change. */
static void substeps(double *err_avg, double *err_last) {
  static double x0[3 * NN];
  static int32_t tri[3 * NT];
  lgd_grid(N, L, 0, 0, x0, tri);
  const double r = 0.003, v0 = -0.7;
  char json[400];
  snprintf(json, sizeof json, "{" MAT ",\"gravity\":[0,0,0],\"dt\":2e-6,\"particles\":[{\"x\":[0.0013,0.0021,%.17g],"
           "\"v\":[0,0,%.17g],\"r\":%.17g}]}", r + 1e-5, v0, r);
  twin w;
  twin_open(&w, json, NN, x0, NT, tri, 1e-5, 0);
  double imp_avg = 0, imp_last = 0;
  for (int k = 0; k < 300; k++) {
    twin_step(&w, still, NULL);
    double fz = 0;
    for (int a = 0; a < NN; a++) fz += w.sd.mesh_force[w.surface][3 * a + 2];
    imp_last += fz * 1e-5;
    if (g_rank == 0) imp_avg += lgd_result(w.sim)->wall_force[2] * 1e-5;
  }
  const double mass = 2600 * 4.0 / 3.0 * M_PI * r * r * r, dp = mass * (w.sd.v[2] - v0);
  /* the grain's momentum change is minus the surface's impulse */
  *err_avg = fabs(imp_avg + dp) / fabs(dp);
  *err_last = fabs(imp_last + dp) / fabs(dp);
  twin_close(&w);
}

int main(int argc, char **argv) {
  lgd_test_init(&argc, &argv);
  char a[160], b[160];
  row("difference", "scene", "effect measured (liggghts_dem against dem_server)");
  row("---", "---", "---");
  const double d_def = subthreshold(1e-8), d_auto = subthreshold(0);
  snprintf(a, sizeof a, "largest position difference %.2g r with LIGGGHTS' default precision 1e-8 m; "
           "%.2g r with the face tolerance r_max·θc", d_def, d_auto);
  row("bends below LIGGGHTS' coplanarity angle θc = 0.26° keep their edges/corners inactive (LIGGGHTS' rule, re-decided each step)",
      "grain resting on a plate node that starts to rise at 0.04 m/s", a);
  for (int side = -1; side <= 1; side += 2)
    for (int k = 0; k < 3; k++) {
      const double s = (k == 0 ? 0.2e-3 : k == 1 ? 0.5e-3 : 1.0e-3);
      double pr, rr;
      near_edge(s, side, &pr, &rr);
      snprintf(a, sizeof a, "grain (r 3 mm, 0.5 m/s) onto the %s-id face of a 5° roof, %.1f mm from the ridge",
               side < 0 ? "lower" : "higher", s * 1e3);
      snprintf(b, sizeof b, "peak force ×%.3f, rebound speed ×%.3f", pr, rr);
      row(k == 0 && side < 0 ? "near a convex edge LIGGGHTS adds the neighbour's edge contact to a face contact" : "",
          a, b);
    }
  for (int k = 0; k < 2; k++) {
    double dv, dw;
    across(k ? 3.0 : 0.0, &dv, &dw);
    snprintf(a, sizeof a, "grain rolling/sliding at 0.3 m/s across a %s", k ? "3° ridge" : "flat triangulated floor");
    snprintf(b, sizeof b, "final velocity differs by %.2g, spin by %.2g (relative)", dv, dw);
    row(k ? "" : "tangential history per (grain, triangle); LIGGGHTS copies it only between coplanar faces", a, b);
  }
  {
    double dv, dw;
    rolling(&dv, &dw);
    snprintf(a, sizeof a, "after 20 ms velocity differs by %.2g, spin by %.2g (relative)", dv, dw);
    row("rolling friction `cdt`: LIGGGHTS scales it with the elastic force k_n·δ and drops its normal (torsion) part; dem_server uses the full normal force and keeps it",
        "grain (μ_r 0.2) rolling and spinning on a plane", a);
  }
  snprintf(a, sizeof a, "%.3f µs per triangle per DEM step (24 200 triangles: %.2f ms)", activity_cost(110),
           activity_cost(110) * 24200e-3);
  row("edge/corner activity re-decided every DEM step", "110 × 110 grid, bumpy", a);
  double ea, el;
  substeps(&ea, &el);
  snprintf(a, sizeof a, "impulse error %.2g with the step average, %.2g with the last sub-step's force", ea, el);
  row("nodal forces are the step average (impulse / Δt)", "grain hitting the plate, 5 DEM steps per coupling step", a);
  return lgd_test_finish("bench_lgd_diff");
}
