/* One-grain impacts: liggghts_dem's engine (LIGGGHTS 3.8 over MPI) against
 * dem_server's (cosim_dem, itself checked against LIGGGHTS' plane walls in
 * tests/dem/test_dem_liggghts.c), coupling step by coupling step with three
 * DEM sub-steps each, forces averaged over the sub-steps in both:
 *   1. a grain hitting a plane wall obliquely: wall force history;
 *   2. grains hitting the coupled surface — a roof whose ridge bends while it
 *      moves — on a face, on the ridge edge and at a boundary corner: the
 *      nodal forces of every node (seed 000 eq. 42) and the wall force;
 *   3. a grain that does not rotate (its own LIGGGHTS type, `fix nve`) and a
 *      spinning one, obliquely on a plane. (Rolling friction is left out:
 *      dem_server's differs from LIGGGHTS' `cdt`, bench_lgd_diff measures it.)
 * Run with 1 and 2 MPI ranks (ctest). Tolerance 1e-6 of the largest value. */
#include "lgd_test.h"

#define MAT "\"materials\":[{\"density\":2600,\"E\":5e6,\"nu\":0.3,\"restitution\":0.5,\"friction\":0.6}]"

static void plane_impact(void) {
  twin w;
  twin_open(&w, "{" MAT ",\"gravity\":[0,0,0],\"dt\":1e-6,"
                "\"walls\":[{\"type\":\"plane\",\"point\":[0,0,0],\"normal\":[0,0,1]}],"
                "\"particles\":[{\"x\":[0,0,0.0035001],\"v\":[0.2,0.05,-0.7],\"r\":0.0035}]}",
            0, NULL, 0, NULL, 3e-6, 0);
  for (int k = 0; k < 467; k++) twin_step(&w, NULL, NULL); /* 1.4 ms: contact and rebound */
  CHECK_SMALL("plane: wall force history, max |diff| / max |F|", w.wall_diff / w.wall_max, 1e-6);
  CHECK_SMALL("plane: final grain position |diff| / r", twin_position_diff(&w) / 0.0035, 1e-6);
  CHECK(w.wall_max > 0.5, "plane: the grain hit the wall (max force %g N)", w.wall_max);
  twin_close(&w);
}

/* A roof over [-L, L]², ridge along y at x = 0: z = H − S|x|; n × n cells. */
enum { N = 4 };
static const double L = 0.02, H = -0.001, S = 0.3;
static double g_x0[3 * (N + 1) * (N + 1)];
static int32_t g_tri[3 * 2 * N * N];

static void roof(void) { lgd_grid(N, L, H, S, g_x0, g_tri); }

/* Moves at u while the slopes steepen (v_z ∝ −x²): the ridge bends. */
static void moving_roof(double t, int nn, const double *x0, double *x, double *v, void *ctx) {
  (void)ctx;
  for (int a = 0; a < nn; a++) {
    const double *p = &x0[3 * a], xx = p[0] * p[0] / (L * L);
    const double u[3] = {0.05, -0.02, 0.03 - 0.4 * xx};
    for (int k = 0; k < 3; k++) {
      v[3 * a + k] = u[k];
      x[3 * a + k] = p[k] + u[k] * t;
    }
  }
}

static void surface_impact(void) {
  roof();
  /* a face (x = 9 mm), the ridge (x = 0), a boundary corner (outside, diagonal) */
  const char *json = "{" MAT ",\"gravity\":[0,0,-9.81],\"dt\":1e-6,\"particles\":["
      "{\"x\":[0.009,0.004,0.0],\"v\":[0.1,0,-0.6],\"r\":0.003},"
      "{\"x\":[0.0003,-0.006,0.0035],\"v\":[0,0.05,-0.7],\"r\":0.004},"
      "{\"x\":[0.0225,0.0225,-0.0055],\"v\":[-0.4,-0.4,-0.3],\"r\":0.003}]}";
  twin w;
  twin_open(&w, json, (N + 1) * (N + 1), g_x0, 2 * N * N, g_tri, 3e-6, 0);
  for (int k = 0; k < 1200; k++) twin_step(&w, moving_roof, NULL);
  CHECK_SMALL("surface: nodal forces, max |diff| / max |F_node|", w.nodal_diff / w.nodal_max, 1e-6);
  CHECK_SMALL("surface: wall force, max |diff| / max |F|", w.wall_diff / w.wall_max, 1e-6);
  CHECK_SMALL("surface: final grain positions |diff| / r", twin_position_diff(&w) / 0.003, 1e-6);
  CHECK(w.nodal_max > 0.05, "surface: the grains hit it (max nodal force %g N)", w.nodal_max);
  twin_close(&w);
}

static void fixed_rotation(void) {
  twin w;
  twin_open(&w, "{\"materials\":[{\"density\":2600,\"E\":5e6,\"nu\":0.3,\"restitution\":0.5,\"friction\":0.6}],\"gravity\":[0,0,-9.81],\"dt\":1e-6,"
                "\"walls\":[{\"type\":\"plane\",\"point\":[0,0,0],\"normal\":[0,0,1]}],\"particles\":["
                "{\"x\":[0,0,0.0035001],\"v\":[0.3,0.05,-0.5],\"r\":0.0035,\"fix_rotation\":true},"
                "{\"x\":[0.02,0,0.0035001],\"v\":[0.3,-0.1,-0.5],\"omega\":[5,-20,3],\"r\":0.0035}]}",
            0, NULL, 0, NULL, 3e-6, 0);
  for (int k = 0; k < 1000; k++) twin_step(&w, NULL, NULL); /* 3 ms: impact, then rolling and sliding */
  CHECK_SMALL("fixed rotation: wall force history", w.wall_diff / w.wall_max, 1e-6);
  CHECK_SMALL("fixed rotation: final positions |diff| / r", twin_position_diff(&w) / 0.0035, 1e-6);
  double lw[6];
  proto_err err = {{0}};
  if (lgd_gather(w.sim, NULL, NULL, lw, &err)) die("gather", &err);
  double dw = 0, wmax = 0;
  for (int i = 0; i < 2; i++)
    for (int k = 0; k < 3; k++) {
      dw = fmax(dw, fabs(lw[3 * w.sd.id[i] + k] - w.sd.omega[3 * i + k]));
      wmax = fmax(wmax, fabs(w.sd.omega[3 * i + k]));
    }
  CHECK_SMALL("fixed rotation: final spins |diff| / max", dw / wmax, 1e-6);
  CHECK(g_rank != 0 || (lw[0] == 0 && lw[1] == 0 && lw[2] == 0), "the grain with fix_rotation does not rotate");
  twin_close(&w);
}

int main(int argc, char **argv) {
  lgd_test_init(&argc, &argv);
  plane_impact();
  surface_impact();
  fixed_rotation();
  return lgd_test_finish("test_lgd_impact");
}
