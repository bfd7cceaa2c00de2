/* The active block ("sleep", dem_sleep.c) at its boundary: a pulse travels
 * into asleep grains. A simple cubic lattice of grains exactly at rest in zero
 * gravity, neighbours GAP apart (within the list's skin, not touching); the
 * first layer is launched along +x. With "sleep" on, the grains ahead fall
 * asleep while the pulse is still far (at rest for `time`: they are left out
 * of every per-step loop), and wake when an awake grain listed with them moves
 * faster than the sleep velocity, before it touches them. So the run must be
 * the all-awake run to round-off within the region the pulse reached (same
 * positions and velocities of every grain, the same momentum and energy: the
 * boundary leaks neither), the grains it did not reach exactly where they
 * started, and bitwise the same for 1 and 2 threads and across an export and
 * import half way (the "state.active" block).
 * And a mesh far from every grain (dem_mesh.c: one comparison per step, no
 * node scan) still meets the grains in time: a plate coming from 0.2 m away,
 * rigid or a coupled surface set every 10 steps, touches a grain at rest
 * exactly at the steps its plane is within the grain's radius (then pushes it on). */
#include "dem_test.h"
#include "dem_server/dem_internal.h"
#include <string.h>

#define R 0.005
#define GAP 1e-4 /* m between neighbours: < skin (they are listed), > 0 (no force at rest) */
#define NX 16
#define NY 8
#define NZ 8
#define N (NX * NY * NZ)
#define V0 0.05 /* m/s, the first layer's launch speed */
#define STEPS 3000
#define DT 5e-5
/* Round-off: the two runs sum each grain's contact forces in another order
 * (other slots, other chunks), 1e-16 relative per sum; over STEPS steps of
 * collisions that grows to ~1e-14 m. 1e-11 m (2e-9 of a radius) and 1e-9 m/s
 * (2e-8 of V0) are far below any physical difference (a grain held one step
 * as a fixed one would be off by ~V0 DT = 2.5e-6 m). */
#define TOL_X 1e-11
#define TOL_V 1e-9

static char *lattice(int sleep, int threads) {
  static char json[400000];
  int len = snprintf(json, sizeof json,
                     "{\"materials\":[{\"density\":2600,\"E\":5e6,\"nu\":0.3,\"restitution\":0.5,\"friction\":0.5}],"
                     "\"gravity\":[0,0,0],\"dt\":%g,\"skin\":0.001,\"threads\":%d,\"sleep\":%s,\"particles\":[",
                     DT, threads, sleep ? "{\"velocity\":1e-6,\"time\":0.002}" : "false");
  for (int a = 0; a < NX; a++)
    for (int b = 0; b < NY; b++)
      for (int c = 0; c < NZ; c++)
        len += snprintf(json + len, sizeof json - (size_t)len, "%s{\"x\":[%.17g,%.17g,%.17g],\"v\":[%g,0,0],\"r\":%g}",
                        a + b + c ? "," : "", (2 * R + GAP) * a, (2 * R + GAP) * b, (2 * R + GAP) * c, a ? 0.0 : V0, R);
  snprintf(json + len, sizeof json - (size_t)len, "]}");
  return json;
}

static void steps(const dem_model *m, dem_state *s, int n, int64_t *least_awake) {
  proto_err err;
  for (int k = 0; k < n; k++) {
    if (dem_step(m, s, &err)) { fprintf(stderr, "%s\n", err.msg); exit(1); }
    if (least_awake && s->n - s->sleeping < *least_awake) *least_awake = s->n - s->sleeping;
  }
}

/* x, v by grain id; momentum; asleep by id */
static void by_id(const dem_state *s, double *x, double *v, double *p, uint8_t *asleep) {
  dem_gather(s, s->x, 3, x);
  dem_gather(s, s->v, 3, v);
  p[0] = p[1] = p[2] = 0;
  for (int i = 0; i < s->n; i++)
    for (int k = 0; k < 3; k++) p[k] += s->v[3 * i + k] / s->inv_mass[i];
  for (int i = 0; i < s->n; i++) asleep[s->id[i]] = s->work->asleep ? s->work->asleep[i] : 0;
}

/* The plate x = const (0.1 x 0.1 m) from x = X0 at V along +x; a grain at the origin. */
#define X0 -0.2
#define VP 1.0
static int far_plate(int coupled) {
  char json[1024];
  snprintf(json, sizeof json,
           "{\"materials\":[{\"density\":2600,\"E\":5e6,\"nu\":0.3,\"restitution\":0.5,\"friction\":0.5}],"
           "\"gravity\":[0,0,0],\"dt\":%g,\"threads\":1,\"walls\":[%s],"
           "\"particles\":[{\"x\":[0,0,0],\"r\":%g}]}", DT,
           coupled ? "" : "{\"type\":\"mesh\",\"nodes\":[[-0.2,-0.05,-0.05],[-0.2,0.05,-0.05],[-0.2,0.05,0.05],"
                          "[-0.2,-0.05,0.05]],\"triangles\":[[0,1,2],[0,2,3]],\"velocity\":[1,0,0]}", R);
  dem_model m;
  dem_state s;
  proto_err err;
  cJSON *j = cJSON_Parse(json);
  const double y[4] = {-0.05, 0.05, 0.05, -0.05}, z[4] = {-0.05, -0.05, 0.05, 0.05};
  double x[12], v[12];
  for (int a = 0; a < 4; a++) {
    x[3 * a] = X0; x[3 * a + 1] = y[a]; x[3 * a + 2] = z[a];
    v[3 * a] = VP; v[3 * a + 1] = v[3 * a + 2] = 0;
  }
  const int32_t tri[6] = {0, 1, 2, 0, 2, 3};
  if (!j || dem_model_from_json(&m, j, "processes.dem", &err) ||
      (coupled && dem_model_set_surface(&m, 4, x, 2, tri, &err)) || dem_state_init(&m, &s, 0, &err)) {
    fprintf(stderr, "setup: %s\n", err.msg);
    exit(2);
  }
  cJSON_Delete(j);
  int wrong = 0, touched = 0;
  for (int k = 0; k < 4400; k++) {
    if (coupled && k % 10 == 0) { /* the surface as the FEM would send it */
      for (int a = 0; a < 4; a++) x[3 * a] = X0 + VP * k * DT;
      dem_mesh_set_nodes(&m, &s, 0, x, v);
    }
    if (dem_step(&m, &s, &err)) { fprintf(stderr, "%s\n", err.msg); exit(1); }
    const double d = s.x[0] - s.mesh_x[0][0]; /* the grain's centre from the plane */
    const int touch = d * d < R * R;
    wrong += touch != (s.contacts > 0);
    touched += touch;
  }
  printf("plate from %g m (%s): %d steps touching, %d steps with the contact wrong%s\n", X0,
         coupled ? "coupled surface" : "rigid mesh", touched, wrong, "");
  dem_state_free(&s);
  dem_model_free(&m);
  return touched > 0 && wrong == 0;
}

/* ---- the springs of asleep–asleep contacts are kept (issue 21) ----
 * A bed settles under gravity in an open box with friction until every grain
 * is asleep; its contacts hold non-zero tangential springs. A full rebuild
 * (forced), an export and import, and a region passing over the bed (a
 * coupled plate that touches no grain: the asleep grains under it wake, wake
 * rebuilds, then a partial rebuild forced) must leave the spring of every
 * contact not evaluated since the bed fell asleep the same bits. A pair
 * counts as not evaluated while neither grain was awake in a force sweep. */
#define SPRINGS_MAX 40000
typedef struct spring {
  int a, b; /* grain ids, a < b */
  double sh[3]; /* the spring on a */
} spring;

static int spring_cmp(const void *p, const void *q) {
  const spring *x = p, *y = q;
  return x->a != y->a ? (x->a > y->a) - (x->a < y->a) : (x->b > y->b) - (x->b < y->b);
}

/* Every listed pair with its spring, by ids (the sign as seen from the smaller id), sorted. */
static int springs_by_id(const dem_state *s, spring *out) {
  const struct dem_work *w = s->work;
  int c = 0;
  for (int i = 0; i < s->n; i++)
    for (int k = w->nl_start[i]; k < w->nl_start[i + 1] && c < SPRINGS_MAX; k++) {
      const int j = w->nl_j[k], flip = s->id[i] > s->id[j];
      spring *p = &out[c++];
      p->a = flip ? s->id[j] : s->id[i];
      p->b = flip ? s->id[i] : s->id[j];
      for (int d = 0; d < 3; d++) p->sh[d] = flip ? -w->nl_shear[3 * k + d] : w->nl_shear[3 * k + d];
    }
  qsort(out, (size_t)c, sizeof *out, spring_cmp);
  return c;
}

/* Springs of ref (non-zero, neither grain evaluated) missing from s or not the same bits. */
static int springs_lost(const spring *ref, int nref, const dem_state *s, const uint8_t *evaluated, int *kept) {
  static spring now[SPRINGS_MAX];
  const int n = springs_by_id(s, now);
  int bad = 0;
  *kept = 0;
  for (int q = 0; q < nref; q++) {
    const spring *r = &ref[q];
    if ((r->sh[0] == 0 && r->sh[1] == 0 && r->sh[2] == 0) || evaluated[r->a] || evaluated[r->b]) continue;
    const spring *f = bsearch(r, now, (size_t)n, sizeof *now, spring_cmp);
    const int same = f && !memcmp(f->sh, r->sh, sizeof r->sh);
    bad += !same;
    *kept += same;
  }
  return bad;
}

#define PLATE_GAP 0.004 /* m above the bed's top: > r_max + skin, the plate touches no grain */
#define PLATE_V 0.5     /* m/s along +x */
static void plate_nodes(double x0, double z, double *x, double *v) {
  const double px[4] = {0, 0.1, 0.1, 0}, py[4] = {0.02, 0.02, 0.12, 0.12};
  for (int a = 0; a < 4; a++) {
    x[3 * a] = x0 + px[a]; x[3 * a + 1] = py[a]; x[3 * a + 2] = z;
    v[3 * a] = PLATE_V; v[3 * a + 1] = v[3 * a + 2] = 0;
  }
}

/* (the bed falls asleep by its speed alone, displacement 1: a radius; its
 * last rattlers never come to rest within 1e-3 of their radius) */
static void bed_scene(dem_model *m, dem_state *s) {
  const char *json =
      "{\"materials\":[{\"density\":2600,\"E\":5e6,\"nu\":0.3,\"restitution\":0.5,\"friction\":0.6}],\"threads\":1,"
      "\"dt\":5e-5,\"sleep\":{\"velocity\":0.05,\"time\":0.005,\"distance\":0.005,\"displacement\":1},"
      "\"walls\":[{\"type\":\"box\",\"lo\":[0,0,0],\"hi\":[0.1414213562,0.1414213562,1],\"open_top\":true}],"
      "\"particles\":{\"generate\":\"bed\",\"scale\":0.02,\"seed\":7}}";
  proto_err err = {{0}};
  cJSON *j = cJSON_Parse(json);
  double x[12], v[12];
  plate_nodes(-1.0, 1.0, x, v); /* parked far away, still: no region */
  memset(v, 0, sizeof v);
  const int32_t tri[6] = {0, 1, 2, 0, 2, 3};
  if (!j || dem_model_from_json(m, j, "processes.dem", &err) || dem_model_set_surface(m, 4, x, 2, tri, &err) ||
      dem_state_init(m, s, 0, &err)) {
    fprintf(stderr, "setup: %s\n", err.msg);
    exit(2);
  }
  cJSON_Delete(j);
}

static void asleep_springs(void) {
  static spring ref[SPRINGS_MAX];
  static uint8_t evaluated[4096];
  dem_model m, m2;
  dem_state s, s2;
  proto_err err = {{0}};
  bed_scene(&m, &s);
  struct dem_work *w = s.work;
  int steps_run = 0;
  for (; steps_run < 40000 && s.sleeping < s.n; steps_run++)
    if (dem_step(&m, &s, &err)) { fprintf(stderr, "%s\n", err.msg); exit(1); }
  const int nref = springs_by_id(&s, ref);
  int nonzero = 0, kept;
  for (int q = 0; q < nref; q++) nonzero += ref[q].sh[0] != 0 || ref[q].sh[1] != 0 || ref[q].sh[2] != 0;
  printf("bed of %d grains: all asleep after %d steps: %lld asleep, %d listed pairs, %d with a tangential spring\n",
         s.n, steps_run, (long long)s.sleeping, nref, nonzero);
  CHECK(s.sleeping == s.n && s.n > 400, "the bed did not fall asleep (%lld of %d)", (long long)s.sleeping, s.n);
  CHECK(nonzero > 200, "too few springs to test (%d)", nonzero);
  CHECK(s.n <= (int)sizeof evaluated && nref < SPRINGS_MAX, "test arrays too small");

  const int64_t full0 = w->full_rebuilds;
  w->compact = DEM_COMPACT_SLEEP; /* a full rebuild, as after a batch fell asleep */
  CHECK(dem_neigh_rebuild(&m, &s, &err) == 0, "rebuild: %s", err.msg);
  int lost = springs_lost(ref, nref, &s, evaluated, &kept);
  printf("  full rebuild (all asleep): %d of %d springs kept, %d lost or changed\n", kept, nonzero, lost);
  CHECK(w->full_rebuilds == full0 + 1 && lost == 0 && kept == nonzero, "a full rebuild lost %d springs", lost);

  proto_msg msg = {0};
  proto_msg_reset(&msg, "state", "state", 0, 0);
  CHECK(dem_state_export(&m, &s, &msg, &err) == 0, "export: %s", err.msg);
  bed_scene(&m2, &s2);
  CHECK(dem_state_import(&m2, &s2, &msg, &err) == 0, "import: %s", err.msg);
  proto_msg_free(&msg);
  lost = springs_lost(ref, nref, &s2, evaluated, &kept);
  printf("  export + import: %d kept, %d lost or changed\n", kept, lost);
  CHECK(lost == 0 && kept == nonzero, "export/import lost %d springs", lost);

  /* the region passes: the plate over the bed's top, set every step as the tread would be */
  double ztop = 0, x[12], v[12];
  for (int i = 0; i < s2.n; i++) ztop = fmax(ztop, s2.x[3 * i + 2] + s2.radius[i]);
  struct dem_work *w2 = s2.work;
  const int64_t wake0 = w2->wake_rebuilds, reb0 = s2.rebuilds;
  int woke_steps = 0, partials = 0, worst = 0;
  for (int k = 0; k < 4000; k++) {
    for (int i = 0; i < w2->n_active; i++) evaluated[s2.id[i]] = 1; /* in this step's force sweep */
    plate_nodes(-0.15 + PLATE_V * k * s2.dt, ztop + PLATE_GAP, x, v);
    dem_mesh_set_nodes(&m2, &s2, 0, x, v);
    const int64_t before = s2.sleeping;
    if (dem_step(&m2, &s2, &err)) { fprintf(stderr, "%s\n", err.msg); exit(1); }
    if (s2.sleeping >= before) continue;
    woke_steps++; /* grains woke at the end of this step: their springs not evaluated yet */
    lost = springs_lost(ref, nref, &s2, evaluated, &kept);
    worst = lost > worst ? lost : worst;
    if (w2->n_active < s2.n && w2->grid_ok) { /* and a partial rebuild at once */
      const int64_t full = w2->full_rebuilds, wake = w2->wake_rebuilds, reb = s2.rebuilds;
      CHECK(dem_neigh_rebuild(&m2, &s2, &err) == 0, "rebuild: %s", err.msg);
      partials += s2.rebuilds == reb + 1 && w2->full_rebuilds == full && w2->wake_rebuilds == wake;
      lost = springs_lost(ref, nref, &s2, evaluated, &kept);
      worst = lost > worst ? lost : worst;
    }
  }
  int awake_ever = 0;
  for (int i = 0; i < s2.n; i++) awake_ever += evaluated[s2.id[i]];
  lost = springs_lost(ref, nref, &s2, evaluated, &kept);
  printf("  region passing: %d grains woke (%d steps with wakes, %lld wake and %d partial rebuilds forced of %lld); "
         "at most %d springs lost at a wake; at the end %d kept untouched, %d lost\n", awake_ever, woke_steps,
         (long long)(w2->wake_rebuilds - wake0), partials, (long long)(s2.rebuilds - reb0), worst, kept, lost);
  CHECK(awake_ever > 50 && woke_steps > 0 && w2->wake_rebuilds > wake0 && partials > 0,
        "the case tests nothing: %d grains woke, %d partial rebuilds", awake_ever, partials);
  CHECK(worst == 0 && lost == 0, "springs of contacts not evaluated changed at a wake or a rebuild (%d)", worst);
  CHECK(kept > 50, "too few springs left untouched at the end (%d)", kept);
  dem_state_free(&s);
  dem_model_free(&m);
  dem_state_free(&s2);
  dem_model_free(&m2);
}

/* ---- a mesh that starts moving or jumps between two region updates ----
 * A 6 x 6 x 3 lattice at rest in zero gravity falls asleep beside a coupled
 * plate (x = const, set every step as the FEM would) that stands still, so
 * no region is set; at a step between two region updates (K % 5 == 1) the
 * plate starts moving at 1 m/s toward the grains, from GAP2 away (variant 0)
 * or jumping there from 0.1 m away (variant 1); or (variant 2) it moves at
 * 1 cm/s 0.1 m away and jumps there (a move beyond the margin the region got
 * from its slow speed). The asleep grains have no
 * mesh candidates: unless the region follows at once, the plate passes into
 * them unseen for up to 4 steps. With sleep the contacts must start at the
 * step they start all awake, and the run match the all-awake one to
 * round-off (TOL_X, TOL_V as above). */
#define MS_NX 3
#define MS_NY 6
#define MS_NZ 6
#define MS_N (MS_NX * MS_NY * MS_NZ)
#define GAP2 1e-4  /* m between the plate and the first layer's surface: touched after 2 steps at VP */
#define MS_K 101   /* the step the plate starts, K % DEM_REGION_STEPS == 1 */
#define MS_STEPS 300

static void ms_plate(double xp, double vx, double *x, double *v) {
  const double y[4] = {-0.01, 0.07, 0.07, -0.01}, z[4] = {-0.01, -0.01, 0.07, 0.07};
  for (int a = 0; a < 4; a++) {
    x[3 * a] = xp; x[3 * a + 1] = y[a]; x[3 * a + 2] = z[a];
    v[3 * a] = vx; v[3 * a + 1] = v[3 * a + 2] = 0;
  }
}

/* first step with a contact; x, v by id at the end */
#define VSLOW 0.01 /* m/s, variant 2's speed before the jump */
static int64_t mesh_starts_run(int sleep, int jump, double *x_out, double *v_out, int64_t *asleep_at_k,
                               int64_t *guards) {
  static char json[100000];
  int len = snprintf(json, sizeof json,
                     "{\"materials\":[{\"density\":2600,\"E\":5e6,\"nu\":0.3,\"restitution\":0.5,\"friction\":0.5}],"
                     "\"gravity\":[0,0,0],\"dt\":%g,\"skin\":0.001,\"threads\":1,\"sleep\":%s,\"particles\":[",
                     DT, sleep ? "{\"velocity\":1e-6,\"time\":0.002}" : "false");
  for (int a = 0; a < MS_NX; a++)
    for (int b = 0; b < MS_NY; b++)
      for (int c = 0; c < MS_NZ; c++)
        len += snprintf(json + len, sizeof json - (size_t)len, "%s{\"x\":[%.17g,%.17g,%.17g],\"r\":%g}",
                        a + b + c ? "," : "", (2 * R + GAP) * a, (2 * R + GAP) * b, (2 * R + GAP) * c, R);
  snprintf(json + len, sizeof json - (size_t)len, "]}");
  dem_model m;
  dem_state s;
  proto_err err;
  cJSON *j = cJSON_Parse(json);
  const double x_near = -R - GAP2, x_far = -0.1;
  double x[12], v[12];
  ms_plate(jump ? x_far : x_near, 0, x, v);
  const int32_t tri[6] = {0, 1, 2, 0, 2, 3};
  if (!j || dem_model_from_json(&m, j, "processes.dem", &err) || dem_model_set_surface(&m, 4, x, 2, tri, &err) ||
      dem_state_init(&m, &s, 0, &err)) {
    fprintf(stderr, "setup: %s\n", err.msg);
    exit(2);
  }
  cJSON_Delete(j);
  int64_t first = -1;
  for (int k = 0; k < MS_K + MS_STEPS; k++) {
    if (k < MS_K) ms_plate(jump ? x_far + (jump == 2) * VSLOW * k * DT : x_near, (jump == 2) * VSLOW, x, v);
    else ms_plate(x_near + VP * (k - MS_K) * DT, VP, x, v);
    dem_mesh_set_nodes(&m, &s, 0, x, v);
    if (k == MS_K) *asleep_at_k = s.sleeping;
    if (dem_step(&m, &s, &err)) { fprintf(stderr, "%s\n", err.msg); exit(1); }
    if (first < 0 && s.contacts > 0) first = k;
  }
  dem_gather(&s, s.x, 3, x_out);
  dem_gather(&s, s.v, 3, v_out);
  *guards = s.work->guard_updates;
  dem_state_free(&s);
  dem_model_free(&m);
  return first;
}

static void mesh_starts(int jump) {
  static double xa[3 * MS_N], va[3 * MS_N], xs[3 * MS_N], vs[3 * MS_N];
  int64_t asleep_a = 0, asleep_s = 0, guards = 0;
  const int64_t fa = mesh_starts_run(0, jump, xa, va, &asleep_a, &guards);
  const int64_t fs = mesh_starts_run(1, jump, xs, vs, &asleep_s, &guards);
  double dx = 0, dv = 0;
  for (int q = 0; q < 3 * MS_N; q++) {
    dx = fmax(dx, fabs(xa[q] - xs[q]));
    dv = fmax(dv, fabs(va[q] - vs[q]));
  }
  const char *what[3] = {"from rest beside the grains", "after a jump of 0.1 m from rest",
                         "after a jump of 0.1 m at 1 cm/s"};
  printf("plate starting at step %d %s: %lld of %d grains asleep then; first contact at step %lld all awake, "
         "%lld with sleep (%lld guard updates of the region); largest difference x %.3g m, v %.3g m/s\n", MS_K,
         what[jump], (long long)asleep_s, MS_N, (long long)fa, (long long)fs, (long long)guards, dx, dv);
  CHECK(asleep_s == MS_N, "the case tests nothing: %lld of %d grains asleep when the plate starts",
        (long long)asleep_s, MS_N);
  CHECK(fa > MS_K && fa < MS_K + 10, "all awake: the plate touched at step %lld", (long long)fa);
  CHECK(fs == fa, "plate %s: the contact started at step %lld with sleep, %lld all awake", what[jump],
        (long long)fs, (long long)fa);
  CHECK(dx < TOL_X && dv < TOL_V, "sleep differs from all awake beyond round-off: x %.3g m, v %.3g m/s", dx, dv);
}

/* ---- sparse x, v with sleep: the same bits as dense ----
 * Two copies of a 16 x 4 x 3 lattice at rest in zero gravity with sleep on;
 * a coupled plate (x in [-0.4, 0.03] m, over the first grains) sinks into
 * them, its far tail (no grain near) faster than the rest: node speed
 * 0.2 m/s + 2 |x| for x < 0, so the surface's fastest node is far from every
 * grain. A gets every node each step (dense), B what the coupler sends with
 * sleep: the nodes of the triangles that meet the box dem_reach_box +
 * dem_sleep_reach grown by reach_speed times the largest node speed, and the
 * fastest node (coupler/schedule.c reach_nodes). Both count the jumps of the
 * nodes near the grains (dem_sleep_jump_box), as dem_server does. At every
 * step: the grains, the region and the asleep count the same bits, no grain of
 * B outside its box. Not vacuous: B gets a part of the surface, grains sleep
 * and wake; and without the fastest node B's region differs. In A and B at
 * every step (asleep_invariants): no asleep grain within r + skin of the plate
 * and no touching awake–asleep pair missing from the list (fails with the
 * region's margin cut to a tenth: ~21 000 violations). */
#define SP_NX 16
#define SP_NY 4
#define SP_NZ 3
#define SP_N (SP_NX * SP_NY * SP_NZ)
#define SP_NA 44 /* plate nodes along x */
#define SP_NW 4  /* across */
#define SP_NN (SP_NA * SP_NW)
#define SP_NT ((SP_NA - 1) * (SP_NW - 1) * 2)
#define SP_STEPS 1500

static void sp_surface(int k, double *x, double *v, int32_t *tri) {
  const double top = (SP_NZ - 1) * (2 * R + GAP) + R;
  for (int a = 0; a < SP_NA; a++)
    for (int b = 0; b < SP_NW; b++) {
      const int q = a * SP_NW + b;
      const double x0 = -0.4 + 0.43 * a / (SP_NA - 1), vz = -0.2 - 2.0 * (x0 < 0 ? -x0 : 0);
      v[3 * q] = 0; v[3 * q + 1] = 0; v[3 * q + 2] = vz;
      x[3 * q] = x0; x[3 * q + 1] = -0.01 + 0.06 * b / (SP_NW - 1); x[3 * q + 2] = top + 0.001 + vz * k * DT;
    }
  for (int a = 0; tri && a < SP_NA - 1; a++)
    for (int b = 0; b < SP_NW - 1; b++) {
      int32_t *t = &tri[6 * (a * (SP_NW - 1) + b)], n0 = a * SP_NW + b;
      t[0] = n0; t[1] = n0 + SP_NW; t[2] = n0 + SP_NW + 1;
      t[3] = n0; t[4] = n0 + SP_NW + 1; t[5] = n0 + 1;
    }
}

static void sp_scene(dem_model *m, dem_state *s) {
  static char json[100000];
  int len = snprintf(json, sizeof json,
                     "{\"materials\":[{\"density\":2600,\"E\":5e6,\"nu\":0.3,\"restitution\":0.5,\"friction\":0.5}],"
                     "\"gravity\":[0,0,0],\"dt\":%g,\"skin\":0.001,\"threads\":1,"
                     "\"sleep\":{\"velocity\":1e-4,\"time\":0.002},\"particles\":[", DT);
  for (int a = 0; a < SP_NX; a++)
    for (int b = 0; b < SP_NY; b++)
      for (int c = 0; c < SP_NZ; c++)
        len += snprintf(json + len, sizeof json - (size_t)len, "%s{\"x\":[%.17g,%.17g,%.17g],\"r\":%g}",
                        a + b + c ? "," : "", (2 * R + GAP) * a, (2 * R + GAP) * b, (2 * R + GAP) * c, R);
  snprintf(json + len, sizeof json - (size_t)len, "]}");
  static double x[3 * SP_NN], v[3 * SP_NN];
  static int32_t tri[3 * SP_NT];
  sp_surface(0, x, v, tri);
  proto_err err;
  cJSON *j = cJSON_Parse(json);
  if (!j || dem_model_from_json(m, j, "processes.dem", &err) || dem_model_set_surface(m, SP_NN, x, SP_NT, tri, &err) ||
      dem_state_init(m, s, 0, &err)) {
    fprintf(stderr, "setup: %s\n", err.msg);
    exit(2);
  }
  cJSON_Delete(j);
}

/* The active block's two invariants, by brute force: no asleep grain lies
 * within r + skin of a triangle of the mesh (asleep grains have no mesh
 * candidates: dem_sleep.c's margin keeps r_max + 2 skin between), and every
 * touching awake–asleep pair is in the awake grain's row (evaluated there,
 * as with a fixed grain). Returns the violations of this step. */
static int asleep_invariants(const dem_model *m, const dem_state *s) {
  const struct dem_work *w = s->work;
  int bad = 0;
  for (int i = w->n_active; i < s->n; i++)
    for (int mi = 0; mi < m->n_meshes; mi++)
      for (int t = 0; t < m->meshes[mi].n_tri; t++) {
        const int32_t *tn = &m->meshes[mi].tri[3 * t];
        const double *x = s->mesh_x[mi], *p = &s->x[3 * i];
        double q[3], z[3], dd = 0;
        dem_closest_on_triangle(p, &x[3 * tn[0]], &x[3 * tn[1]], &x[3 * tn[2]], q, z);
        for (int a = 0; a < 3; a++) dd += (p[a] - q[a]) * (p[a] - q[a]);
        const double reach = s->radius[i] + m->skin;
        bad += dd < reach * reach;
      }
  for (int i = 0; i < w->n_active; i++)
    for (int j = w->n_active; j < s->n; j++) {
      double dd = 0;
      for (int a = 0; a < 3; a++) dd += (s->x[3 * i + a] - s->x[3 * j + a]) * (s->x[3 * i + a] - s->x[3 * j + a]);
      const double rs = s->radius[i] + s->radius[j];
      if (dd >= rs * rs) continue;
      int listed = 0;
      for (int k = w->nl_start[i]; k < w->nl_start[i + 1]; k++) listed |= w->nl_j[k] == j;
      bad += !listed;
    }
  return bad;
}

static int box_differ, escape_differ, cached_box_steps; /* sparse_sleep_run's reach box checks */

/* Steps where B differed (grains or region); *sparse_steps, *least_awake, *escaped of B. */
static int sparse_sleep_run(int with_fastest, int *sparse_steps, int64_t *most_asleep, int *escapes,
                            int64_t *wakes, int *broken) {
  static double x[3 * SP_NN], v[3 * SP_NN], rx[3 * SP_NN], rv[3 * SP_NN];
  static int32_t tri[3 * SP_NT], idx[SP_NN];
  static uint8_t mark[SP_NN], seen[SP_NN], live[SP_NT];
  dem_model ma, mb;
  dem_state a, b;
  proto_err err;
  sp_scene(&ma, &a);
  sp_scene(&mb, &b);
  sp_surface(0, x, v, tri);
  int differ = 0;
  *sparse_steps = *escapes = *broken = 0;
  *most_asleep = 0;
  for (int k = 0; k < SP_STEPS; k++) {
    sp_surface(k, x, v, NULL);
    double box[6], jb[6], per_speed, v2 = 0;
    dem_reach_box(&ma, &a, DT, box);
    dem_sleep_jump_box(&a, box, DT);
    dem_mesh_set_nodes(&ma, &a, 0, x, v);
    dem_reach_box(&mb, &b, DT, jb);
    memcpy(box, jb, sizeof box);
    dem_sleep_reach(&mb, &b, box, &per_speed);
    int fast = -1;
    for (int q = 0; q < SP_NN; q++) {
      const double *u = &v[3 * q], w2 = u[0] * u[0] + u[1] * u[1] + u[2] * u[2];
      if (w2 > v2) v2 = w2, fast = q;
    }
    for (int d = 0; d < 3; d++) box[d] -= per_speed * sqrt(v2), box[3 + d] += per_speed * sqrt(v2);
    int64_t n = proto_reach_nodes(x, v, DT, tri, SP_NT, SP_NN, box, mark, idx);
    if (with_fastest && !mark[fast]) {
      int64_t j = n++;
      for (; j > 0 && idx[j - 1] > fast; j--) idx[j] = idx[j - 1];
      idx[j] = fast;
    }
    for (int64_t q = 0; q < n; q++) {
      memcpy(&rx[3 * q], &x[3 * idx[q]], 3 * sizeof(double));
      memcpy(&rv[3 * q], &v[3 * idx[q]], 3 * sizeof(double));
    }
    *sparse_steps += n < SP_NN;
    dem_sleep_jump_box(&b, jb, DT);
    dem_mesh_set_nodes_sparse(&mb, &b, 0, n, idx, rx, rv, seen, live);
    if (dem_step(&ma, &a, &err) || dem_step(&mb, &b, &err)) { fprintf(stderr, "step %d: %s\n", k, err.msg); exit(1); }
    const int escaped = dem_reach_escaped(&b, jb) >= 0;
    *escapes += escaped;
    double got[6], want[6];
    int outside;
    dem_reach_box(&mb, &b, DT, got);
    dem_test_reach_by_hand(&mb, &b, DT, want, jb, &outside);
    box_differ += memcmp(got, want, sizeof want) != 0;
    escape_differ += outside != escaped;
    cached_box_steps += b.work->box_all && b.work->sweep_step == b.step && b.work->n_active < b.n;
    *broken += asleep_invariants(&mb, &b) + asleep_invariants(&ma, &a);
    const struct dem_work *wa = a.work, *wb = b.work;
    differ += memcmp(a.x, b.x, sizeof(double) * 3 * SP_N) || memcmp(a.v, b.v, sizeof(double) * 3 * SP_N) ||
              memcmp(wa->region_lo, wb->region_lo, sizeof wa->region_lo) ||
              memcmp(wa->region_hi, wb->region_hi, sizeof wa->region_hi) || a.sleeping != b.sleeping ||
              memcmp(a.mesh_force[0], b.mesh_force[0], sizeof(double) * 3 * SP_NN);
    *most_asleep = b.sleeping > *most_asleep ? b.sleeping : *most_asleep;
  }
  *wakes = b.work->wake_rebuilds;
  dem_state_free(&a);
  dem_state_free(&b);
  dem_model_free(&ma);
  dem_model_free(&mb);
  return differ;
}

static void sparse_with_sleep(void) {
  int sparse_steps, escapes, broken;
  int64_t most_asleep, wakes;
  const int differ = sparse_sleep_run(1, &sparse_steps, &most_asleep, &escapes, &wakes, &broken);
  printf("sparse x, v with sleep: %d of %d steps differ from dense; %d steps sparse; up to %lld of %d grains "
         "asleep, %lld wake rebuilds; %d steps with a grain outside its box\n", differ, SP_STEPS, sparse_steps,
         (long long)most_asleep, SP_N, (long long)wakes, escapes);
  CHECK(sparse_steps == SP_STEPS && most_asleep > SP_N / 4 && wakes > 0,
        "the case tests nothing: %d sparse steps, up to %lld asleep, %lld wakes", sparse_steps,
        (long long)most_asleep, (long long)wakes);
  CHECK(differ == 0 && escapes == 0, "sparse with sleep differs from dense at %d steps (%d escapes)", differ, escapes);
  printf("  the reach box differs from its definition at %d steps, the escape check from brute force at %d "
         "(%d steps took the step's sweeps with grains asleep)\n", box_differ, escape_differ, cached_box_steps);
  CHECK(box_differ == 0 && escape_differ == 0, "the reach box (%d steps) or the escape check (%d) is not its "
        "definition's with grains asleep", box_differ, escape_differ);
  CHECK(cached_box_steps > SP_STEPS / 4, "only %d of %d steps took the step's sweeps with grains asleep",
        cached_box_steps, SP_STEPS);
  printf("  asleep grains within r + skin of the plate, or touching an awake one unlisted: %d\n", broken);
  CHECK(broken == 0, "%d times an asleep grain was within r + skin of the plate or touched an awake grain unlisted",
        broken);
  const int differ_nofast = sparse_sleep_run(0, &sparse_steps, &most_asleep, &escapes, &wakes, &broken);
  printf("  without the fastest node: %d of %d steps differ\n", differ_nofast, SP_STEPS);
  CHECK(differ_nofast > 0, "the fastest node is not needed here: the case does not test it");
}

int main(void) {
  sparse_with_sleep();
  asleep_springs();
  for (int v = 0; v < 3; v++) mesh_starts(v);
  CHECK(far_plate(0), "a rigid plate coming from far missed or invented contacts");
  CHECK(far_plate(1), "a coupled surface coming from far missed or invented contacts");
  static double xa[3 * N], va[3 * N], xs[3 * N], vs[3 * N], x0[3 * N];
  static uint8_t asleep[N], dummy[N];
  double pa[3], ps[3];
  dem_model ma, ms;
  dem_state a, s;
  scene(lattice(0, 1), &ma, &a);
  scene(lattice(1, 1), &ms, &s);
  dem_gather(&a, a.x, 3, x0);
  const double p0 = (double)(NY * NZ) * V0 / a.inv_mass[0]; /* the first layer's */
  int64_t least = N;
  steps(&ma, &a, STEPS, NULL);
  steps(&ms, &s, STEPS, &least);
  by_id(&a, xa, va, pa, dummy);
  by_id(&s, xs, vs, ps, asleep);
  double dx = 0, dv = 0;
  int reached = 0, still = 0, moved_asleep = 0;
  for (int g = 0; g < N; g++) {
    int moved = 0;
    for (int k = 0; k < 3; k++) {
      dx = fmax(dx, fabs(xa[3 * g + k] - xs[3 * g + k]));
      dv = fmax(dv, fabs(va[3 * g + k] - vs[3 * g + k]));
      moved |= xa[3 * g + k] != x0[3 * g + k];
    }
    reached += moved;
    if (asleep[g]) {
      still++;
      moved_asleep += memcmp(&xs[3 * g], &x0[3 * g], 3 * sizeof(double)) != 0;
    }
  }
  printf("%d grains, %d steps: the pulse moved %d of them (all awake); with sleep at least %lld awake at once, "
         "%d asleep at the end (%d of them moved)\n", N, STEPS, reached, (long long)least, still, moved_asleep);
  printf("largest difference to all awake: x %.3g m, v %.3g m/s; momentum x %.17g / %.17g (start %.17g) kg m/s; "
         "energy %.17g / %.17g J\n", dx, dv, pa[0], ps[0], p0, a.kinetic_energy + a.elastic_energy,
         s.kinetic_energy + s.elastic_energy);
  CHECK(reached > 3 * NY * NZ && reached < N - 3 * NY * NZ,
        "the case tests nothing: the pulse moved %d of %d grains (want some layers, not all)", reached, N);
  CHECK(least < N / 2, "the grains ahead of the pulse did not fall asleep (at least %lld awake)", (long long)least);
  CHECK(still > 0 && moved_asleep == 0, "%d grains asleep at the end, %d of them moved", still, moved_asleep);
  CHECK(dx < TOL_X && dv < TOL_V, "sleep differs from all awake beyond round-off: x %.3g m, v %.3g m/s", dx, dv);
  /* momentum: no walls, no gravity; equal to round-off in both runs */
  CHECK(fabs(pa[0] - p0) < 1e-12 * p0 && fabs(ps[0] - p0) < 1e-12 * p0,
        "momentum not conserved: %.17g and %.17g against %.17g", pa[0], ps[0], p0);
  const double ea = a.kinetic_energy + a.elastic_energy, es = s.kinetic_energy + s.elastic_energy;
  CHECK(fabs(ea - es) < 1e-9 * ea, "energy with sleep %.17g J, all awake %.17g J", es, ea);

  /* 2 threads, and 2 threads with an export/import half way: bitwise the 1-thread run */
  for (int variant = 0; variant < 2; variant++) {
    dem_model m2;
    dem_state s2;
    scene(lattice(1, 2), &m2, &s2);
    if (variant == 0) {
      steps(&m2, &s2, STEPS, NULL);
    } else {
      steps(&m2, &s2, STEPS / 2, NULL);
      proto_msg msg = {0};
      proto_err err;
      proto_msg_reset(&msg, "state", "state", 0, 0);
      CHECK(dem_state_export(&m2, &s2, &msg, &err) == 0, "export: %s", err.msg);
      dem_model m3;
      dem_state s3;
      scene(lattice(1, 2), &m3, &s3);
      CHECK(dem_state_import(&m3, &s3, &msg, &err) == 0, "import: %s", err.msg);
      proto_msg_free(&msg);
      dem_state_free(&s2);
      dem_model_free(&m2);
      m2 = m3;
      s2 = s3;
      steps(&m2, &s2, STEPS - STEPS / 2, NULL);
    }
    double x2[3 * N], v2[3 * N], p2[3];
    by_id(&s2, x2, v2, p2, dummy);
    const int same = !memcmp(x2, xs, sizeof x2) && !memcmp(v2, vs, sizeof v2) &&
                     s2.kinetic_energy == s.kinetic_energy && s2.sleeping == s.sleeping && s2.rebuilds == s.rebuilds;
    printf("2 threads%s: %s the 1-thread run\n", variant ? ", export/import half way" : "",
           same ? "bitwise" : "NOT");
    CHECK(same, "2 threads%s differ from 1 thread with sleep on", variant ? " (export/import)" : "");
    dem_state_free(&s2);
    dem_model_free(&m2);
  }
  dem_state_free(&a);
  dem_state_free(&s);
  dem_model_free(&ma);
  dem_model_free(&ms);
  return cosim_test_done("test_dem_active");
}
