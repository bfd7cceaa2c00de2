/* A saved bed continues the run that saved it, bit for bit (issue 21).
 * Run A: a bed generated in a box, ploughed by a rigid plate (mesh wall) and
 * pressed by a coupled "foot" (the tread's stand-in: a mesh whose nodes are
 * set every coupling step), N steps, dem_bed_save, then M steps more. Run B:
 * the same scene with particles.file = that bed (dem_bed_load,
 * dem_state_init, dem_bed_continue), M steps, with 1 and 2 threads: every
 * array of the state export (positions, velocities, spins, quaternions,
 * forces, the neighbour list with its springs, plane and mesh springs, the
 * mesh nodes, sleep flags, the clock and counters) equal bit for bit. The same
 * with "sleep" on, the plate standing still and no foot (part of the bed
 * asleep when saved). At the save the bed has grain-grain contacts with
 * non-zero tangential springs and mesh contacts.
 * A bed continued with other friction is bit for bit the saving run with
 * its friction switched at the save, and names the pairs whose friction differs.
 * An old bed (x and r only) loads, positions only; a bed of another scene
 * (other restitution, walls, no foot) is refused naming what differs, or
 * loaded as positions only when particles.state says so (a bed saved with
 * sleep off continues with sleep on: its grains were all awake); a file
 * whose x was edited after the save is refused. */
#include "dem_test.h"
#include "dem_server/dem_internal.h"
#include <string.h>
#include <unistd.h>

#define MATERIALS "\"materials\":[{\"density\":2600,\"E\":5e6,\"nu\":0.3,\"restitution\":%s,\"friction\":%s}]"
#define WALLS                                                                                              \
  "\"walls\":[{\"type\":\"box\",\"lo\":[0,0,0],\"hi\":[0.1414213562,0.1414213562,%s],\"open_top\":true},"  \
  "{\"type\":\"mesh\",\"nodes\":[[0,0.01,0.015],[0,0.13,0.015],[0,0.13,0.12],[0,0.01,0.12]],"             \
  "\"triangles\":[[0,1,2],[0,2,3]],\"velocity\":[%s,0,0]}]"

/* The coupled foot: a 4 x 4 grid of squares, 6 cm wide, coming down. */
#define FOOT_N 4
#define FOOT_NODES ((FOOT_N + 1) * (FOOT_N + 1))
static const double FOOT_Z0 = 0.07, FOOT_VZ = -0.15, FOOT_VX = 0.1;
static const int COUPLING = 10; /* DEM steps per coupling step */

static void foot(double t, double *x, double *v) {
  for (int j = 0; j <= FOOT_N; j++)
    for (int i = 0; i <= FOOT_N; i++) {
      double *p = &x[3 * (j * (FOOT_N + 1) + i)], *u = &v[3 * (j * (FOOT_N + 1) + i)];
      p[0] = 0.04 + 0.015 * i + FOOT_VX * t;
      p[1] = 0.04 + 0.015 * j;
      p[2] = FOOT_Z0 + FOOT_VZ * t + 0.002 * ((i + j) % 2);
      u[0] = FOOT_VX; u[1] = 0; u[2] = FOOT_VZ;
    }
}

/* A scene's variations: the run's own and the mismatched ones. */
typedef struct variant {
  int threads, foot;
  const char *friction, *box_top, *sleep, *particles;
  const char *plate_v; /* NULL: 0.4 m/s */
} variant;
static const char *restitution = "0.5"; /* of every scene made; "other restitution" changes it */

/* Model (+ the foot as the coupled surface) + state; rc and message. */
static int make(const variant *v, dem_model *m, dem_state *s, proto_err *err) {
  char json[4096];
  snprintf(json, sizeof json, "{" MATERIALS ",\"threads\":%d,\"dt\":5e-5,\"sleep\":%s," WALLS ",\"particles\":%s}",
           restitution, v->friction, v->threads, v->sleep, v->box_top, v->plate_v ? v->plate_v : "0.4", v->particles);
  cJSON *j = cJSON_Parse(json);
  if (!j) { fprintf(stderr, "bad test JSON: %s\n", json); exit(2); }
  int32_t tri[6 * FOOT_N * FOOT_N];
  for (int b = 0; b < FOOT_N; b++)
    for (int a = 0; a < FOOT_N; a++) {
      int32_t *t = &tri[6 * (b * FOOT_N + a)], n0 = b * (FOOT_N + 1) + a;
      t[0] = n0; t[1] = n0 + 1; t[2] = n0 + FOOT_N + 2;
      t[3] = n0; t[4] = n0 + FOOT_N + 2; t[5] = n0 + FOOT_N + 1;
    }
  double x[3 * FOOT_NODES], u[3 * FOOT_NODES];
  foot(0, x, u);
  int rc = dem_model_from_json(m, j, "processes.dem", err);
  cJSON_Delete(j);
  if (rc) return -1;
  if ((v->foot && dem_model_set_surface(m, FOOT_NODES, x, 2 * FOOT_N * FOOT_N, tri, err)) ||
      dem_state_init(m, s, 0, err)) {
    dem_model_free(m);
    return -1;
  }
  return 0;
}

/* Steps k0..k1−1; the foot's nodes set at each coupling step. */
static void run(const dem_model *m, dem_state *s, int foot_on, int k0, int k1) {
  proto_err err;
  double x[3 * FOOT_NODES], v[3 * FOOT_NODES];
  for (int k = k0; k < k1; k++) {
    if (foot_on && k % COUPLING == 0) {
      foot(k * s->dt, x, v);
      dem_mesh_set_nodes(m, s, m->n_meshes - 1, x, v);
    }
    if (dem_step(m, s, &err)) { fprintf(stderr, "step %d: %s\n", k, err.msg); exit(1); }
  }
}

/* Grain pairs with a non-zero tangential spring, mesh contact slots in use. */
static void springs(const dem_state *s, int *pairs, int *mesh) {
  const struct dem_work *w = s->work;
  *pairs = *mesh = 0;
  for (int k = 0; k < w->nl_start[s->n]; k++) {
    const double *sh = &w->nl_shear[3 * k];
    *pairs += sh[0] != 0 || sh[1] != 0 || sh[2] != 0;
  }
  for (size_t k = 0; k < (size_t)s->n * DEM_MESH_SLOTS; k++) *mesh += w->mc_key[k] != 0;
}

static char bed_particles[700];

static const char *bed(const char *path, const char *state) {
  snprintf(bed_particles, sizeof bed_particles, "{\"file\":\"%s\"%s%s%s}", path, state ? ",\"state\":\"" : "",
           state ? state : "", state ? "\"" : "");
  return bed_particles;
}

/* A + B for one scene: saved after N steps, M more. With the foot (moving)
 * and the plate ploughing, or (foot_on 0) the plate standing still: a bed
 * with nothing moving near it, whose grains fall asleep. */
static void continues(const char *sleep, int foot_on, int N, int M, const char *path) {
  const variant gen = {1, foot_on, "0.6", "1", sleep, "{\"generate\":\"bed\",\"scale\":0.02,\"seed\":7}",
                       foot_on ? NULL : "0"};
  dem_model ma;
  dem_state a;
  proto_err err = {{0}};
  CHECK(make(&gen, &ma, &a, &err) == 0, "scene: %s", err.msg);
  run(&ma, &a, foot_on, 0, N);
  int pairs, mesh;
  springs(&a, &pairs, &mesh);
  printf("sleep %s: %d grains; saved after %d steps: %lld contacts, %d grain pairs with a tangential spring, "
         "%d mesh contacts, %lld asleep\n", sleep, ma.n_grains, N, (long long)a.contacts, pairs, mesh,
         (long long)a.sleeping);
  CHECK(pairs > 50 && mesh > 5, "the saved bed has too few springs to test (%d pairs, %d mesh)", pairs, mesh);
  if (strcmp(sleep, "false")) CHECK(a.sleeping > 20, "sleep on: only %lld grains asleep when saved", (long long)a.sleeping);
  CHECK(dem_bed_save(&ma, &a, path, &err) == 0, "save: %s", err.msg);
  run(&ma, &a, foot_on, N, N + M);
  for (int threads = 1; threads <= 2; threads++) {
    const variant load = {threads, foot_on, "0.6", "1", sleep, bed(path, NULL), gen.plate_v};
    dem_model mb;
    dem_state b;
    dem_bed_info info;
    CHECK(make(&load, &mb, &b, &err) == 0, "load: %s", err.msg);
    CHECK(dem_bed_continue(&mb, &b, &info, &err) == 0 && info.continued && info.has_state,
          "continue: %s", err.msg);
    CHECK(info.dt == b.dt && info.gravity[2] == mb.gravity[2], "the bed records dt and gravity");
    CHECK(b.step == N, "continued at step %lld, expected %d", (long long)b.step, N);
    run(&mb, &b, foot_on, N, N + M);
    char what[64];
    const int same = dem_test_same_state(&ma, &a, &mb, &b, what, sizeof what);
    printf("  %d thread(s): %d steps from the bed == the saving run: %s (%s)\n", threads, M, same ? "yes" : "NO", what);
    CHECK(same, "sleep %s, %d threads: state differs after continuing from the bed at '%s'", sleep, threads, what);
    dem_state_free(&b);
    dem_model_free(&mb);
  }
  dem_state_free(&a);
  dem_model_free(&ma);
}

static void expect(const variant *v, int want_rc, const char *want, int want_continued, const char *what) {
  dem_model m;
  dem_state s;
  proto_err err = {{0}};
  dem_bed_info info = {0};
  int rc = make(v, &m, &s, &err);
  if (!rc) {
    rc = dem_bed_continue(&m, &s, &info, &err);
    dem_state_free(&s);
    dem_model_free(&m);
  }
  printf("%-34s -> %s\n", what, rc ? err.msg : info.continued ? "(continued)" : "(positions only)");
  CHECK((rc != 0) == want_rc, "%s: %s", what, rc ? err.msg : "accepted");
  CHECK(!want || strstr(err.msg, want), "%s: message lacks '%s': %s", what, want, err.msg);
  CHECK(rc || info.continued == want_continued, "%s: continued %d, expected %d", what, info.continued,
        want_continued);
}

/* Friction is not in the fingerprint: a bed continued with other friction is
 * bit for bit the saving run with its friction switched at the save (the
 * springs continue, capped by the new limit from the next step), and the
 * bed says which pairs' friction differs. The switch must change the run
 * (the test bites): the saving run unswitched differs. */
static void friction_switch(const char *path, int N, int M) {
  const variant gen = {1, 1, "0.6", "1", "false", "{\"generate\":\"bed\",\"scale\":0.02,\"seed\":7}", NULL};
  const variant low = {1, 1, "0.5", "1", "false", bed(path, NULL), NULL};
  const variant keep = {1, 1, "0.6", "1", "false", bed(path, NULL), NULL};
  dem_model ma, mb, m0;
  dem_state a, a0, b;
  proto_err err = {{0}};
  CHECK(make(&gen, &ma, &a, &err) == 0, "scene: %s", err.msg);
  run(&ma, &a, 1, 0, N);
  CHECK(dem_bed_save(&ma, &a, path, &err) == 0, "save: %s", err.msg);
  CHECK(make(&low, &mb, &b, &err) == 0, "scene with friction 0.5: %s", err.msg);
  dem_bed_info info;
  CHECK(dem_bed_continue(&mb, &b, &info, &err) == 0 && info.continued, "continue with friction 0.5: %s", err.msg);
  printf("friction 0.6 -> 0.5: the bed says '%s'\n", info.friction);
  CHECK(strstr(info.friction, "0-0: friction 0.6 -> 0.5") != NULL, "the bed names the pair: '%s'", info.friction);
  /* a0: the saving run going on unswitched, from the same saved state */
  CHECK(make(&keep, &m0, &a0, &err) == 0 && dem_bed_continue(&m0, &a0, &info, &err) == 0 && !info.friction[0],
        "unswitched: %s", err.msg);
  run(&m0, &a0, 1, N, N + M);
  for (int i = 0; i < ma.n_materials; i++) {
    ma.mat[i].friction = mb.mat[i].friction;
    for (int j = 0; j < ma.n_materials; j++) ma.law[i][j].mu = mb.law[i][j].mu;
  }
  run(&ma, &a, 1, N, N + M);
  run(&mb, &b, 1, N, N + M);
  char what[64];
  const int same = dem_test_same_state(&ma, &a, &mb, &b, what, sizeof what);
  printf("  switched at the save == continued from the bed with friction 0.5: %s (%s)\n", same ? "yes" : "NO", what);
  CHECK(same, "the bed continued with other friction differs from the switched run at '%s'", what);
  CHECK(!dem_test_same_state(&m0, &a0, &mb, &b, what, sizeof what), "the switch changes nothing (the test does not bite)");
  dem_state_free(&a0);
  dem_model_free(&m0);
  dem_state_free(&b);
  dem_model_free(&mb);
  dem_state_free(&a);
  dem_model_free(&ma);
}

int main(void) {
  char path[] = "/tmp/test_dem_bed_continue_XXXXXX";
  close(mkstemp(path));
  /* sleep thresholds under which part of the bed falls asleep within N steps (68 of 436 grains) */
  /* a bed still settling, put to sleep by its speed alone (displacement 1: a radius) to have asleep grains to save */
  continues("{\"velocity\":0.06,\"time\":0.01,\"distance\":0.005,\"displacement\":1}", 0, 3000, 1000, path);
  { /* other thresholds: they decide only what falls asleep from now on, so the saved state continues */
    const variant t = {1, 0, "0.6", "1", "{\"velocity\":0.03,\"time\":0.02,\"overlap\":0.05}", bed(path, NULL), NULL};
    expect(&t, 0, NULL, 1, "other sleep thresholds");
  }
  friction_switch(path, 1500, 1000);
  continues("false", 1, 1500, 1000, path); /* the file now holds this bed */

  /* mismatches: refused, naming the part; or positions only when asked */
  variant v = {1, 1, "0.6", "1", "false", bed(path, NULL), NULL};
  expect(&v, 0, NULL, 1, "the same scene");
  restitution = "0.4";
  expect(&v, 1, "materials (", 0, "other restitution");
  v.particles = bed(path, "positions");
  expect(&v, 0, NULL, 0, "other restitution, state positions");
  restitution = "0.5";
  v = (variant){1, 1, "0.5", "1", "false", bed(path, NULL), NULL};
  expect(&v, 0, NULL, 1, "other friction"); /* friction_switch: bit for bit the switched run */
  v = (variant){1, 1, "0.6", "2", "false", bed(path, NULL), NULL};
  expect(&v, 1, "walls (", 0, "a taller box");
  v = (variant){1, 0, "0.6", "1", "false", bed(path, NULL), NULL};
  expect(&v, 1, "meshes (", 0, "no foot");
  v = (variant){1, 1, "0.6", "1", "true", bed(path, NULL), NULL};
  /* a bed saved all awake continues with sleep on (its grains all awake; the
   * other way is refused: tests/dem/test_dem_state_io.c) */
  expect(&v, 0, NULL, 1, "sleep on, the bed saved with sleep off");
  CHECK(strstr(bed(path, "sideways"), "sideways"), "builder");
  v = (variant){1, 1, "0.6", "1", "false", bed(path, "sideways"), NULL};
  expect(&v, 1, "particles.state", 0, "particles.state sideways");

  /* an old bed: x and r only (what the first beds held) */
  {
    const variant gen = {1, 1, "0.6", "1", "false", "{\"generate\":\"bed\",\"scale\":0.02,\"seed\":7}", NULL};
    dem_model m;
    dem_state s;
    proto_err err = {{0}};
    CHECK(make(&gen, &m, &s, &err) == 0, "scene: %s", err.msg);
    const int64_t n = m.n_grains;
    double *x = malloc(sizeof(double) * 3 * (size_t)n);
    dem_gather(&s, s.x, 3, x);
    proto_h5 *f = proto_h5_create(path, &err);
    proto_array ax = {.name = "x", .dtype = PROTO_F8, .ndim = 2, .shape = {n, 3}, .data = x,
                      .nbytes = sizeof(double) * 3 * (size_t)n};
    proto_array ar = {.name = "r", .dtype = PROTO_F8, .ndim = 1, .shape = {n}, .data = m.radius,
                      .nbytes = sizeof(double) * (size_t)n};
    CHECK(f && proto_h5_write_array(f, "/", &ax, &err) == 0 && proto_h5_write_array(f, "/", &ar, &err) == 0 &&
              proto_h5_close(f, &err) == 0, "writing an old bed: %s", err.msg);
    free(x);
    dem_state_free(&s);
    dem_model_free(&m);
    v = (variant){1, 1, "0.6", "1", "false", bed(path, NULL), NULL};
    expect(&v, 0, NULL, 0, "an old bed (x, r)");
  }

  /* a saved bed whose x was edited (one grain moved up 1 mm, into free space) */
  {
    const variant gen = {1, 1, "0.6", "1", "false", "{\"generate\":\"bed\",\"scale\":0.02,\"seed\":7}", NULL};
    dem_model m;
    dem_state s;
    proto_err err = {{0}};
    CHECK(make(&gen, &m, &s, &err) == 0, "scene: %s", err.msg);
    CHECK(dem_bed_save(&m, &s, path, &err) == 0, "save: %s", err.msg);
    const int64_t n = m.n_grains;
    double *x = malloc(sizeof(double) * 3 * (size_t)n);
    dem_gather(&s, s.x, 3, x);
    int top = 0;
    for (int g = 0; g < n; g++) top = x[3 * g + 2] > x[3 * top + 2] ? g : top;
    x[3 * top + 2] += 1e-3;
    proto_h5 *f = proto_h5_open(path, 1, &err);
    proto_array ax = {.name = "x", .dtype = PROTO_F8, .ndim = 2, .shape = {n, 3}, .data = x,
                      .nbytes = sizeof(double) * 3 * (size_t)n};
    CHECK(f && proto_h5_write_array(f, "/", &ax, &err) == 0 && proto_h5_close(f, &err) == 0, "edit: %s", err.msg);
    free(x);
    dem_state_free(&s);
    dem_model_free(&m);
    v = (variant){1, 1, "0.6", "1", "false", bed(path, NULL), NULL};
    expect(&v, 1, "the file was edited", 0, "x edited after the save");
  }
  unlink(path);
  return cosim_test_done("test_dem_bed_continue");
}
