/* liggghts_dem checkpoints (lgd_save, lgd_options.resume). A scene runs N
 * coupling steps, is checkpointed, and runs N more; a second sim started from
 * the checkpoint runs the same N. Both are compared with a sim that ran 2N
 * steps straight: positions, velocities, spins, nodal forces, wall forces and
 * the series (the measured differences are printed, and whether bitwise).
 *  1. "bed": grains pressed on each other and on a plane wall, sliding (the
 *     tangential history of pairs and walls), the coupled surface moving
 *     below them: checkpointed and resumed runs equal the straight one to
 *     1e-12 (bitwise at 1 and 2 ranks); with 2 ranks, rank 0 alone also
 *     resumes the 2-rank checkpoint (another rank count) and runs on (its
 *     positions checked to 1e-12; its velocities do not agree, see README).
 *  2. "surface": grains sliding on the coupled surface: the checkpointed run
 *     equals the straight one bitwise; the resumed one runs on but is NOT
 *     exact (grain–mesh contacts, README "Checkpoints"): only its clock is
 *     checked and its difference printed, one rank only (LIGGGHTS 3.8's read_restart crashes on this file at 2 ranks). */
#include "lgd_test.h"

#include <stdlib.h>
#include <unistd.h>

#define STEPS 40              /* N: coupling steps before and after the checkpoint */
#define COUPLING_DT 3e-6      /* s: three DEM steps of 1e-6 s each */
#define RESTART_TOL 1e-12     /* relative to the largest value of each quantity */

#define MAT "\"materials\":[{\"density\":2600,\"E\":5e6,\"nu\":0.3,\"restitution\":0.5,\"friction\":0.6}]"
#define WALL "\"walls\":[{\"type\":\"plane\",\"point\":[-0.012,0,0],\"normal\":[1,0,0]}],"
/* four grains 0.1 mm above the surface pressed on each other, one on top,
 * one against the plane wall x = -0.012 */
static const char BED[] = "{" MAT ",\"gravity\":[0,0,-9.81],\"dt\":1e-6," WALL
    "\"particles\":["
    "{\"x\":[-0.003,-0.003,0.0031],\"v\":[0.05,0.01,0],\"r\":0.003},"
    "{\"x\":[0.003,-0.003,0.0031],\"v\":[-0.03,0.02,0],\"r\":0.003},"
    "{\"x\":[-0.003,0.003,0.0031],\"v\":[0.02,-0.04,0],\"r\":0.003},"
    "{\"x\":[0.003,0.003,0.0031],\"v\":[0,0,-0.01],\"r\":0.003},"
    "{\"x\":[0,0,0.0072],\"v\":[0.03,0,-0.05],\"r\":0.003},"
    "{\"x\":[-0.008999,0.008,0.003],\"v\":[-0.02,0.05,0],\"r\":0.003}]}";
/* two grains pressed onto the surface (overlap 2 µm) and on each other, one
 * resting on both, one against the wall and on the surface */
static const char SURFACE[] = "{" MAT ",\"gravity\":[0,0,-9.81],\"dt\":1e-6," WALL
    "\"particles\":["
    "{\"x\":[-0.0063,-0.00206,0.002998],\"v\":[0.05,0.01,0],\"r\":0.003},"
    "{\"x\":[-0.00206,-0.0063,0.002998],\"v\":[-0.03,0.02,0],\"r\":0.003},"
    "{\"x\":[-0.00418,-0.00418,0.008192],\"v\":[0.03,0,-0.05],\"r\":0.003},"
    "{\"x\":[-0.008999,0.008,0.003],\"v\":[-0.02,0.05,0],\"r\":0.003}]}";

enum { N = 4, NN = (N + 1) * (N + 1), NT = 2 * N * N, NG = 4 };
static const double L = 0.02;

typedef struct run {
  dem_model m;
  int ng;
  lgd_sim *sim;
  double x0[3 * NN], x[3 * NN], v[3 * NN];
  int32_t tri[3 * NT];
} run;

/* The surface slides in x and rises slowly: x(t) = x0 + u t. */
static void surface_at(const run *r, double t, double *x, double *v) {
  const double u[3] = {0.04, -0.01, 0.005};
  for (int a = 0; a < NN; a++)
    for (int k = 0; k < 3; k++) {
      v[3 * a + k] = u[k];
      x[3 * a + k] = r->x0[3 * a + k] + u[k] * t;
    }
}

static void run_open(run *r, const char *scene, MPI_Comm comm, const lgd_resume *from) {
  proto_err err = {{0}};
  memset(r, 0, sizeof *r);
  model_from_json(scene, &r->m);
  r->ng = r->m.n_grains;
  lgd_grid(N, L, 0, 0, r->x0, r->tri);
  if (dem_model_set_surface(&r->m, NN, r->x0, NT, r->tri, &err)) die("surface", &err);
  lgd_options o = {.resume = from};
  if (lgd_open(&r->sim, comm, &r->m, COUPLING_DT, &o, &err)) die(from ? "resume" : "open", &err);
}

static void run_steps(run *r, int64_t k0, int n) {
  proto_err err = {{0}};
  for (int k = 0; k < n; k++) {
    surface_at(r, (double)(k0 + k) * COUPLING_DT, r->x, r->v);
    if (lgd_step(r->sim, COUPLING_DT, r->x, r->v, &err)) die("lgd_step", &err);
  }
}

/* What is compared: grains (x, v, ω), nodal forces, wall forces, series. */
typedef struct result {
  double g[9 * NG], nodal[3 * NN], wall[3], series[DEM_N_SERIES];
} result;

static void result_of(run *r, result *o) {
  proto_err err = {{0}};
  if (lgd_gather(r->sim, o->g, o->g + 3 * NG, o->g + 6 * NG, &err)) die("gather", &err);
  const lgd_out *out = lgd_result(r->sim);
  memcpy(o->nodal, out->nodal_force, sizeof o->nodal);
  memcpy(o->wall, out->wall_force, sizeof o->wall);
  memcpy(o->series, out->series, sizeof o->series);
}

static double rel_diff(const double *a, const double *b, int n) {
  double d = 0, mx = 0;
  for (int i = 0; i < n; i++) {
    d = fmax(d, fabs(a[i] - b[i]));
    mx = fmax(mx, fabs(b[i]));
  }
  return mx > 0 ? d / mx : d;
}

/* Largest relative difference over everything compared; prints them. */
static double compare(const char *scene, const char *what, const result *a, const result *ref) {
  const double dx = rel_diff(a->g, ref->g, 3 * NG), dv = rel_diff(a->g + 3 * NG, ref->g + 3 * NG, 3 * NG);
  const double dw = rel_diff(a->g + 6 * NG, ref->g + 6 * NG, 3 * NG);
  const double dn = rel_diff(a->nodal, ref->nodal, 3 * NN), dwall = rel_diff(a->wall, ref->wall, 3);
  const double ds = rel_diff(a->series, ref->series, DEM_N_SERIES);
  const int bitwise = !memcmp(a, ref, sizeof *a);
  if (g_rank == 0)
    printf("%s, %s: relative differences x %.3g v %.3g omega %.3g nodal %.3g wall %.3g series %.3g (%s)\n", scene,
           what, dx, dv, dw, dn, dwall, ds, bitwise ? "bitwise equal" : "not bitwise");
  return fmax(fmax(fmax(dx, dv), fmax(dw, dn)), fmax(dwall, ds));
}

static void run_close(run *r) {
  lgd_close(r->sim);
  dem_model_free(&r->m);
}

/* exact: the resumed runs must equal the straight one to RESTART_TOL; else
 * only the checkpointed one, and the resumed positions to SURFACE_TOL. */
static void scene(const char *name, const char *json, int exact, const char *path) {
  int nproc;
  MPI_Comm_size(MPI_COMM_WORLD, &nproc);
  proto_err err = {{0}};
  static run straight, a, b;
  static result ref, ra, rb;
  memset(&ref, 0, sizeof ref); memset(&ra, 0, sizeof ra); memset(&rb, 0, sizeof rb);
  run_open(&straight, json, MPI_COMM_WORLD, NULL);
  run_steps(&straight, 0, 2 * STEPS);
  result_of(&straight, &ref);
  CHECK(g_rank != 0 || ref.series[DEM_SERIES_CONTACTS] >= 5, "%s: the grains touch (%g contacts)", name,
        ref.series[DEM_SERIES_CONTACTS]);
  CHECK(g_rank != 0 || fabs(ref.wall[0]) > 0, "%s: a grain presses on the plane wall", name);

  run_open(&a, json, MPI_COMM_WORLD, NULL);
  run_steps(&a, 0, STEPS);
  lgd_resume ck;
  if (lgd_save(a.sim, path, &ck, &err)) die("lgd_save", &err);
  static double sx[3 * NN], sv[3 * NN]; /* the surface is the sim's own: it moves on */
  memcpy(sx, ck.surface_x, sizeof sx);
  memcpy(sv, ck.surface_v, sizeof sv);
  ck.surface_x = sx, ck.surface_v = sv;
  run_steps(&a, STEPS, STEPS);
  result_of(&a, &ra);
  CHECK_SMALL("checkpointed run against the straight one",
              compare(name, "checkpointed run against the straight one", &ra, &ref), RESTART_TOL);

  if (exact || nproc == 1) {
    run_open(&b, json, MPI_COMM_WORLD, &ck);
    run_steps(&b, STEPS, STEPS);
    result_of(&b, &rb);
    const double d = compare(name, "resumed run against the straight one", &rb, &ref);
    if (exact) CHECK_SMALL("resumed run against the straight one", d, RESTART_TOL);
    /* not exact yet with grains on the surface (README "Checkpoints"): the
     * difference is printed by compare(), no tolerance is claimed for it */
    CHECK(rb.series[DEM_SERIES_T] == ref.series[DEM_SERIES_T], "%s: resumed clock %.17g, straight %.17g", name,
          rb.series[DEM_SERIES_T], ref.series[DEM_SERIES_T]);
  }
  if (exact && nproc > 1) { /* the 2-rank checkpoint on 1 rank */
    MPI_Comm one;
    MPI_Comm_split(MPI_COMM_WORLD, g_rank == 0 ? 0 : MPI_UNDEFINED, 0, &one);
    if (g_rank == 0) {
      static run c;
      static result rc;
      run_open(&c, json, one, &ck);
      run_steps(&c, STEPS, STEPS);
      result_of(&c, &rc);
      /* positions agree bitwise; the gathered velocities and spins do not
       * (unexplained, README "Checkpoints"): positions only */
      compare(name, "the 2-rank checkpoint resumed on 1 rank", &rc, &ref);
      CHECK_SMALL("the 2-rank checkpoint resumed on 1 rank: positions", rel_diff(rc.g, ref.g, 3 * NG), RESTART_TOL);
      run_close(&c);
      MPI_Comm_free(&one);
    }
  }
  if (exact || nproc == 1) run_close(&b);
  run_close(&straight);
  run_close(&a);
}

int main(int argc, char **argv) {
  lgd_test_init(&argc, &argv);
  char dir[] = "/tmp/test_lgd_restart-XXXXXX", path[64] = "";
  if (g_rank == 0 && !mkdtemp(dir)) { fprintf(stderr, "mkdtemp failed\n"); MPI_Abort(MPI_COMM_WORLD, 2); }
  snprintf(path, sizeof path, "%s/ckpt.restart", dir);
  scene("bed", BED, 1, path);
  scene("surface", SURFACE, 0, path);
  if (g_rank == 0) { unlink(path); rmdir(dir); }
  return lgd_test_finish("test_lgd_restart");
}
