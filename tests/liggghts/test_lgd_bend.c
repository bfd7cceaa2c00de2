/* The edge/corner activation trap (docs/liggghts.md §2): LIGGGHTS
 * decides once, on a mesh's initial shape, which triangle edges and corners
 * take part in contact, so on a tread that starts flat every interior edge and
 * corner stays inactive. A flat plate bends while a grain falls onto it and
 * then rides on it:
 *   - tent: the node under the grain rises 2 mm (the grain lands on a corner);
 *   - ridge: the row of nodes under the grain rises 2 mm (it lands on an edge).
 * With the activity re-decided on the current shape (liggghts_dem) the grain
 * lands and rides up exactly as in dem_server (position history and nodal
 * forces to 1e-6); with LIGGGHTS' own frozen activity the plate goes through
 * it. Run with 1 and 2 MPI ranks.
 * (The grain lands once the bend is past LIGGGHTS' coplanarity angle, 0.26°:
 * below it LIGGGHTS' own rule keeps the feature inactive by design — see
 * lgd_script.c face_tolerance and the README for that residual.) */
#include "lgd_test.h"

enum { N = 4, NN = (N + 1) * (N + 1) };
static const double L = 0.02, R = 0.004, RISE = 0.002, T1 = 0.05, DROP = 0.001;
static double g_x0[3 * NN];
static int32_t g_tri[3 * 2 * N * N];

static void plate(void) { lgd_grid(N, L, 0, 0, g_x0, g_tri); }

typedef struct bend { int ridge; double dt; } bend;

static double lift(double t) { return RISE * fmin(t / T1, 1.0); }

/* The centre node (tent) or the centre column x = 0 (ridge) rises. */
static void bending(double t, int nn, const double *x0, double *x, double *v, void *ctx) {
  const bend *b = ctx;
  for (int a = 0; a < nn; a++) {
    const double *p = &x0[3 * a];
    const int moves = fabs(p[0]) < 1e-12 && (b->ridge || fabs(p[1]) < 1e-12);
    for (int k = 0; k < 3; k++) {
      x[3 * a + k] = p[k] + (k == 2 && moves ? lift(t) : 0);
      v[3 * a + k] = k == 2 && moves ? (lift(t + b->dt) - lift(t)) / b->dt : 0;
    }
  }
}

typedef struct result {
  double z_dem, z_lgd; /* grain height at the end */
  double dx;           /* largest |x_lgd − x_dem| on the way */
  double df;           /* nodal forces: largest |diff| / largest |F| */
} result;

static void run(int ridge, int frozen, result *r) {
  char json[512];
  /* on the ridge the grain sits between two rising nodes, on the edge;
   * max_overlap_ratio 1: a grain that falls through is measured, not stopped */
  snprintf(json, sizeof json,
           "{\"materials\":[{\"density\":2600,\"E\":5e6,\"nu\":0.3,\"restitution\":0.5,\"friction\":0.6}],"
           "\"gravity\":[0,0,-9.81],\"dt\":2e-5,\"max_overlap_ratio\":1,"
           "\"particles\":[{\"x\":[0,%.17g,%.17g],\"r\":%.17g}]}",
           ridge ? L / N : 0.0, R + DROP, R);
  bend b = {ridge, 6e-5};
  twin w;
  twin_open(&w, json, NN, g_x0, 2 * N * N, g_tri, b.dt, frozen);
  r->dx = 0;
  const int steps = (int)(0.08 / b.dt); /* lands at ~12 ms, rides up to 50 ms, rests */
  for (int k = 1; k <= steps; k++) {
    twin_step(&w, bending, &b);
    if (k % 10 == 0 || k == steps) r->dx = fmax(r->dx, twin_position_diff(&w));
  }
  double lx[3];
  proto_err err = {{0}};
  if (lgd_gather(w.sim, lx, NULL, NULL, &err)) die("gather", &err);
  r->z_dem = w.sd.x[2];
  r->z_lgd = lx[2];
  r->df = w.nodal_diff / w.nodal_max;
  twin_close(&w);
}

int main(int argc, char **argv) {
  lgd_test_init(&argc, &argv);
  plate();
  for (int ridge = 0; ridge <= 1; ridge++) {
    const char *name = ridge ? "ridge (edge contact)" : "tent (corner contact)";
    char what[128];
    result r;
    run(ridge, 0, &r);
    if (g_rank == 0) printf("%s: grain z at the end %.9g m (dem_server %.9g m; rest height about %.6g m)\n",
                            name, r.z_lgd, r.z_dem, R + RISE);
    CHECK(fabs(r.z_dem - (R + RISE)) < 0.1 * R, "%s: dem_server's grain rides up to %g (expected about %g)",
          name, r.z_dem, R + RISE);
    snprintf(what, sizeof what, "%s: positions, max |lgd - dem_server| / r", name);
    CHECK_SMALL(what, r.dx / R, 1e-6);
    snprintf(what, sizeof what, "%s: nodal forces, max |diff| / max |F|", name);
    CHECK_SMALL(what, r.df, 1e-6);
    run(ridge, 1, &r);
    if (g_rank == 0)
      printf("%s, LIGGGHTS' frozen activity: grain z at the end %.6g m (the plate top is at %.6g m)\n", name,
             r.z_lgd, RISE);
    CHECK(fabs(r.z_lgd - r.z_dem) > R, "%s: with LIGGGHTS' frozen activity the plate should go through the "
          "grain (z = %g, riding would be %g)", name, r.z_lgd, r.z_dem);
  }
  return lgd_test_finish("test_lgd_bend");
}
