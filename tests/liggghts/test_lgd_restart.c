/* liggghts_dem checkpoints (lgd_save, lgd_options.resume). A scene runs N
 * coupling steps, is checkpointed, and runs N more; a second sim started from
 * the checkpoint runs the same N. Both are compared with a sim that ran 2N
 * steps straight: positions, velocities, spins, nodal forces, wall forces and
 * the series (the measured differences are printed, and whether bitwise).
 * Two scenes: "bed", grains pressed on each other and on a plane wall,
 * sliding (the tangential history of pairs and walls), the coupled surface
 * moving below them; "surface", grains sliding on the coupled surface and on
 * each other (grain-mesh contact histories too).
 *  - on the same rank count (1, and 2 with mpirun -np 2) the checkpointed and
 *    the resumed run equal the straight one bitwise (asserted: LIGGGHTS
 *    allows it);
 *  - with 2 ranks, the 2-rank checkpoint resumed by rank 0 alone, and a
 *    1-rank checkpoint resumed on 2 ranks, run on and equal the straight run
 *    of the rank count that wrote the checkpoint to RESTART_TOL (another rank
 *    count sums the forces of a grain in another order: not bitwise). */
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

enum { N = 4, NN = (N + 1) * (N + 1), NT = 2 * N * N, NG_MAX = 6, NW = 2 };
/* NG_MAX: grains of the largest scene; NW: walls (the plane, the coupled surface) */
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
  int ng;
  double g[9 * NG_MAX], nodal[3 * NN], wall[3 * NW], series[DEM_N_SERIES];
} result;

static void result_of(run *r, result *o) {
  proto_err err = {{0}};
  o->ng = r->ng;
  if (o->ng > NG_MAX) { fprintf(stderr, "%d grains, more than NG_MAX\n", o->ng); MPI_Abort(MPI_COMM_WORLD, 2); }
  if (lgd_gather(r->sim, o->g, o->g + 3 * o->ng, o->g + 6 * o->ng, &err)) die("gather", &err);
  const lgd_out *out = lgd_result(r->sim);
  memcpy(o->nodal, out->nodal_force, sizeof o->nodal);
  if (r->m.n_walls != NW) { fprintf(stderr, "%d walls, not NW\n", r->m.n_walls); MPI_Abort(MPI_COMM_WORLD, 2); }
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
  const int n3 = 3 * ref->ng;
  const double dx = rel_diff(a->g, ref->g, n3), dv = rel_diff(a->g + n3, ref->g + n3, n3);
  const double dw = rel_diff(a->g + 2 * n3, ref->g + 2 * n3, n3);
  const double dn = rel_diff(a->nodal, ref->nodal, 3 * NN), dwall = rel_diff(a->wall, ref->wall, 3 * NW);
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

/* Every rank gets rank 0's clock and surface of a checkpoint written by rank
 * 0 alone (lgd_step and resume take them on every rank; the participant
 * broadcasts them likewise). */
static void share_checkpoint(lgd_resume *ck, double *sx, double *sv) {
  double clock[2] = {ck->t, ck->coupling_dt};
  MPI_Bcast(clock, 2, MPI_DOUBLE, 0, MPI_COMM_WORLD);
  ck->t = clock[0], ck->coupling_dt = clock[1];
  MPI_Bcast(sx, 3 * NN, MPI_DOUBLE, 0, MPI_COMM_WORLD);
  MPI_Bcast(sv, 3 * NN, MPI_DOUBLE, 0, MPI_COMM_WORLD);
  ck->surface_x = sx, ck->surface_v = sv;
}

/* N steps, a checkpoint into path (the surface copied into sx, sv: the sim's
 * own moves on), N more steps; the result after 2N into res. */
static void run_checkpointed(run *r, const char *json, MPI_Comm comm, const char *path, lgd_resume *ck,
                             double *sx, double *sv, result *res) {
  proto_err err = {{0}};
  run_open(r, json, comm, NULL);
  run_steps(r, 0, STEPS);
  if (lgd_save(r->sim, path, ck, &err)) die("lgd_save", &err);
  memcpy(sx, ck->surface_x, sizeof(double) * 3 * NN);
  memcpy(sv, ck->surface_v, sizeof(double) * 3 * NN);
  ck->surface_x = sx, ck->surface_v = sv;
  run_steps(r, STEPS, STEPS);
  result_of(r, res);
}

/* Resumes ck on comm, runs N steps and compares with ref: bitwise when the
 * rank count is the one that wrote ck, else to RESTART_TOL. */
static void resume_and_compare(const char *name, const char *what, const char *json, MPI_Comm comm,
                               const lgd_resume *ck, const result *ref, int bitwise) {
  static run b;
  static result rb;
  memset(&rb, 0, sizeof rb);
  run_open(&b, json, comm, ck);
  run_steps(&b, STEPS, STEPS);
  result_of(&b, &rb);
  const double d = compare(name, what, &rb, ref);
  CHECK_SMALL(what, d, RESTART_TOL);
  if (bitwise) CHECK(!memcmp(&rb, ref, sizeof rb), "%s: %s is not bitwise equal to the straight run", name, what);
  CHECK(rb.series[DEM_SERIES_T] == ref->series[DEM_SERIES_T], "%s: resumed clock %.17g, straight %.17g", name,
        rb.series[DEM_SERIES_T], ref->series[DEM_SERIES_T]);
  run_close(&b);
}

static void scene(const char *name, const char *json, const char *path) {
  int nproc;
  MPI_Comm_size(MPI_COMM_WORLD, &nproc);
  static run straight, a;
  static result ref, ra;
  static double sx[3 * NN], sv[3 * NN];
  memset(&ref, 0, sizeof ref); memset(&ra, 0, sizeof ra);
  run_open(&straight, json, MPI_COMM_WORLD, NULL);
  run_steps(&straight, 0, 2 * STEPS);
  result_of(&straight, &ref);
  run_close(&straight);
  CHECK(g_rank != 0 || ref.series[DEM_SERIES_CONTACTS] >= 5, "%s: the grains touch (%g contacts)", name,
        ref.series[DEM_SERIES_CONTACTS]);
  CHECK(g_rank != 0 || fabs(ref.wall[0]) > 0, "%s: a grain presses on the plane wall", name);

  lgd_resume ck;
  run_checkpointed(&a, json, MPI_COMM_WORLD, path, &ck, sx, sv, &ra);
  compare(name, "checkpointed run against the straight one", &ra, &ref);
  CHECK(!memcmp(&ra, &ref, sizeof ra), "%s: the checkpointed run is not bitwise equal to the straight one", name);
  resume_and_compare(name, "resumed run against the straight one", json, MPI_COMM_WORLD, &ck, &ref, 1);
  if (nproc == 1) {
    run_close(&a);
    return;
  }
  MPI_Comm one; /* rank 0 alone */
  MPI_Comm_split(MPI_COMM_WORLD, g_rank == 0 ? 0 : MPI_UNDEFINED, 0, &one);
  if (g_rank == 0)
    resume_and_compare(name, "the 2-rank checkpoint resumed on 1 rank", json, one, &ck, &ref, 0);
  run_close(&a); /* ck pointed into it */

  /* a 1-rank checkpoint resumed on 2 ranks, against a 1-rank straight run */
  static run straight1, a1;
  static result ref1, ra1;
  memset(&ref1, 0, sizeof ref1); memset(&ra1, 0, sizeof ra1);
  lgd_resume ck1 = {0};
  if (g_rank == 0) {
    run_open(&straight1, json, one, NULL);
    run_steps(&straight1, 0, 2 * STEPS);
    result_of(&straight1, &ref1);
    run_close(&straight1);
    run_checkpointed(&a1, json, one, path, &ck1, sx, sv, &ra1);
    CHECK(!memcmp(&ra1, &ref1, sizeof ra1), "%s: the 1-rank checkpointed run is not bitwise equal", name);
  }
  share_checkpoint(&ck1, sx, sv);
  resume_and_compare(name, "the 1-rank checkpoint resumed on 2 ranks", json, MPI_COMM_WORLD, &ck1, &ref1, 0);
  if (g_rank == 0) {
    run_close(&a1);
    MPI_Comm_free(&one);
  }
}

int main(int argc, char **argv) {
  lgd_test_init(&argc, &argv);
  char dir[] = "/tmp/test_lgd_restart-XXXXXX", path[64] = "";
  if (g_rank == 0 && !mkdtemp(dir)) { fprintf(stderr, "mkdtemp failed\n"); MPI_Abort(MPI_COMM_WORLD, 2); }
  snprintf(path, sizeof path, "%s/ckpt.restart", dir);
  scene("bed", BED, path);
  scene("surface", SURFACE, path);
  if (g_rank == 0) { unlink(path); rmdir(dir); }
  return lgd_test_finish("test_lgd_restart");
}
