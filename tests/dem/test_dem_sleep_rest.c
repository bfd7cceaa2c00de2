/* The rest test of "sleep" (dem_sleep.c): a grain falls asleep when it is at
 * rest, not merely slow. Three free grains in zero gravity, far apart, no
 * walls, no meshes: one exactly still, one drifting slower than `velocity`
 * but by more than `displacement` x r within `time` (a creeping grain: it
 * must stay awake), one drifting by less than that (asleep, as the still
 * one). Then the drifting grains' state goes through an export and import
 * half way (the rest anchors travel: the same steps at rest after it).
 * And the wake batch: an asleep cluster next to a fast grain wakes as one
 * (the grains within one cell of a woken grain wake with it; with halo 0
 * only the grains the rule wakes), and with a wake_velocity above the
 * grain's speed only when it presses in. */
#include "dem_test.h"
#include "dem_server/dem_internal.h"

#define R 0.005
#define V_SLEEP 0.01   /* m/s */
#define T_SLEEP 0.005  /* s: 100 steps */
#define DT 5e-5
#define V_CREEP 5e-3   /* < V_SLEEP; moves 2.5e-5 m = 5e-3 R in T_SLEEP: not at rest */
#define V_TINY 5e-5    /* moves 2.5e-7 m = 5e-5 R in T_SLEEP: at rest (displacement 1e-4) */

static void three(dem_model *m, dem_state *s) {
  static char json[2000];
  snprintf(json, sizeof json,
           "{\"materials\":[{\"density\":2600,\"E\":5e6,\"nu\":0.3,\"restitution\":0.5,\"friction\":0.5}],"
           "\"gravity\":[0,0,0],\"dt\":%g,\"threads\":1,"
           "\"sleep\":{\"velocity\":%g,\"time\":%g,\"displacement\":1e-4},\"particles\":["
           "{\"x\":[0,0,0],\"r\":%g},{\"x\":[0.1,0,0],\"r\":%g,\"v\":[%g,0,0]},"
           "{\"x\":[0.2,0,0],\"r\":%g,\"v\":[0,%g,0]}]}",
           DT, V_SLEEP, T_SLEEP, R, R, V_CREEP, R, V_TINY);
  scene(json, m, s);
}

static int asleep_id(const dem_state *s, int id) {
  for (int i = 0; i < s->n; i++)
    if (s->id[i] == id) return s->work->asleep[i];
  return -1;
}

static void rest_not_slow(void) {
  dem_model m;
  dem_state s;
  proto_err err;
  three(&m, &s);
  for (int k = 0; k < 600; k++) CHECK(dem_step(&m, &s, &err) == 0, "step: %s", err.msg);
  printf("after 6 x time: still %d, creeping %d, tiny drift %d asleep\n", asleep_id(&s, 0), asleep_id(&s, 1),
         asleep_id(&s, 2));
  CHECK(asleep_id(&s, 0) == 1, "the still grain does not sleep");
  CHECK(asleep_id(&s, 1) == 0, "a grain creeping slower than the sleep velocity fell asleep");
  CHECK(asleep_id(&s, 2) == 1, "a grain drifting by less than displacement x r does not sleep");
  /* the anchors travel with the state: an import half way gives the same run */
  dem_model m2;
  dem_state a, b;
  three(&m2, &a);
  CHECK(dem_state_init(&m2, &b, 0, &err) == 0, "state: %s", err.msg);
  for (int k = 0; k < 150; k++) CHECK(dem_step(&m2, &a, &err) == 0 && dem_step(&m2, &b, &err) == 0, "step");
  proto_msg msg = {0};
  proto_msg_reset(&msg, "t", "state", 0, 0);
  CHECK(dem_state_export(&m2, &a, &msg, &err) == 0, "export: %s", err.msg);
  dem_state c;
  CHECK(dem_state_init(&m2, &c, 0, &err) == 0 && dem_state_import(&m2, &c, &msg, &err) == 0, "import: %s", err.msg);
  for (int k = 0; k < 150; k++) CHECK(dem_step(&m2, &b, &err) == 0 && dem_step(&m2, &c, &err) == 0, "step");
  char what[128];
  CHECK(dem_test_same_state(&m2, &b, &m2, &c, what, sizeof what), "import half way differs in %s", what);
  proto_msg_free(&msg);
  dem_state_free(&a); dem_state_free(&b); dem_state_free(&c);
  dem_model_free(&m2);
  dem_state_free(&s);
  dem_model_free(&m);
}

/* A 4 x 4 x 4 cluster at rest (touching nothing), asleep; a grain launched
 * at it wakes the 4 grains listed with it, and with each of them every asleep
 * grain within one cell (2 r + skin) wakes at once (16 in the first wake).
 * With `wake` (extra sleep keys) a wake_velocity above the launch speed: the
 * listing wakes nothing, the first wake comes when the grain presses into the
 * cluster beyond sleep.overlap of a radius. *first and *gap get the step of
 * the first wake and the lone grain's smallest gap to the cluster then (m,
 * negative: overlap); woke_expected: the grains that first wake (16 with the
 * halo, 4 with halo 0). */
static void wake_batch(const char *wake, int woke_expected, int *first_out, double *gap_out) {
  static char json[20000];
  int len = snprintf(json, sizeof json,
                     "{\"materials\":[{\"density\":2600,\"E\":5e6,\"nu\":0.3,\"restitution\":0.5,\"friction\":0.5}],"
                     "\"gravity\":[0,0,0],\"dt\":%g,\"skin\":0.001,\"threads\":1,"
                     "\"sleep\":{\"velocity\":%g,\"time\":%g%s},\"particles\":[", DT, V_SLEEP, T_SLEEP, wake);
  const double pitch = 2 * R + 1e-4, cell = 2 * R + 0.001;
  enum { NC = 64, NG = NC + 1 };
  for (int a = 0; a < NC; a++)
    len += snprintf(json + len, sizeof json - (size_t)len, "{\"x\":[%g,%g,%g],\"r\":%g},", (a % 4) * pitch,
                    (a / 4 % 4) * pitch, (a / 16) * pitch, R);
  snprintf(json + len, sizeof json - (size_t)len, "{\"x\":[-0.015,%g,%g],\"r\":%g}]}", 1.5 * pitch, 1.5 * pitch, R);
  dem_model m;
  dem_state s;
  proto_err err;
  scene(json, &m, &s);
  for (int k = 0; k < 200; k++) CHECK(dem_step(&m, &s, &err) == 0, "step: %s", err.msg);
  CHECK(s.sleeping == NG, "the cluster and the grain at rest do not sleep (%lld)", (long long)s.sleeping);
  for (int i = 0; i < s.n; i++) /* wake the lone grain by hand, as a region would, and launch it */
    if (s.id[i] == NC) dem_wake(s.work, i);
  CHECK(dem_step(&m, &s, &err) == 0, "step: %s", err.msg);
  for (int i = 0; i < s.n; i++)
    if (s.id[i] == NC) s.v[3 * i] = 1.0;
  /* the grains the lone one meets first: layer x = 0, (y, z) in {1, 2}^2 */
  const int struck[4] = {1 * 4 + 1 * 16, 2 * 4 + 1 * 16, 1 * 4 + 2 * 16, 2 * 4 + 2 * 16};
  const int64_t wakes0 = s.work->wake_rebuilds;
  int first = -1, woke_first = 0, missed = 0;
  *gap_out = 1; /* no wake: no gap */
  for (int k = 0; k < 400 && first < 0; k++) {
    CHECK(dem_step(&m, &s, &err) == 0, "step: %s", err.msg);
    if (s.sleeping == NC) continue; /* none of the cluster woke yet */
    first = k;
    double x[3 * NG], gap = 1;
    uint8_t asleep[NG];
    for (int i = 0; i < s.n; i++) {
      asleep[s.id[i]] = s.work->asleep[i];
      memcpy(&x[3 * s.id[i]], &s.x[3 * i], sizeof(double) * 3);
    }
    for (int a = 0; a < NC; a++) {
      const double *g = &x[3 * NC], e0 = x[3 * a] - g[0], e1 = x[3 * a + 1] - g[1], e2 = x[3 * a + 2] - g[2];
      gap = fmin(gap, sqrt(e0 * e0 + e1 * e1 + e2 * e2) - 2 * R);
      woke_first += !asleep[a];
      for (int q = 0; q < 4; q++) {
        const double *p = &x[3 * struck[q]], d0 = x[3 * a] - p[0], d1 = x[3 * a + 1] - p[1], d2 = x[3 * a + 2] - p[2];
        missed += asleep[a] && d0 * d0 + d1 * d1 + d2 * d2 < cell * cell;
      }
    }
    *gap_out = gap;
  }
  printf("the cluster's first wake%s (step %d, %lld wake rebuilds, gap %.3g R): %d grains, %d within a cell of the "
         "4 struck ones left asleep\n", wake, first, (long long)(s.work->wake_rebuilds - wakes0), *gap_out / R,
         woke_first, missed);
  /* with the halo the 4 struck, their 8 neighbours in the layer and the 4
   * behind them; without it the 4 alone, their neighbours left asleep */
  CHECK(first >= 0 && woke_first == woke_expected && (missed == 0) == (woke_expected > 4),
        "the first wake took %d grains (expected %d), left %d", woke_first, woke_expected, missed);
  *first_out = first;
  dem_state_free(&s);
  dem_model_free(&m);
}

/* sleep.wake_velocity below velocity: refused by name. */
static void wake_below_velocity(void) {
  cJSON *j = cJSON_Parse("{\"materials\":[{\"density\":2600,\"E\":5e6,\"nu\":0.3,\"restitution\":0.5,"
                         "\"friction\":0.5}],\"sleep\":{\"velocity\":0.01,\"wake_velocity\":0.005},"
                         "\"particles\":[{\"x\":[0,0,0],\"r\":0.005}]}");
  dem_model m;
  proto_err err = {{0}};
  const int rc = dem_model_from_json(&m, j, "processes.dem", &err);
  cJSON_Delete(j);
  printf("wake_velocity 0.005 < velocity 0.01 -> %s\n", rc ? err.msg : "accepted");
  CHECK(rc != 0, "wake_velocity below velocity accepted");
  if (rc) CHECK_MSG(err, "processes.dem.sleep.wake_velocity");
  else dem_model_free(&m);
}

/* A bad sleep value ("key": value inside "sleep"; sleep.distance neither a
 * number nor [x, y, z] of lengths, sleep.force not a number >= 0): refused
 * by name. */
static void bad_sleep(const char *entry, const char *name) {
  char json[400];
  snprintf(json, sizeof json, "{\"materials\":[{\"density\":2600,\"E\":5e6,\"nu\":0.3,\"restitution\":0.5,"
           "\"friction\":0.5}],\"sleep\":{%s},\"particles\":[{\"x\":[0,0,0],\"r\":0.005}]}", entry);
  cJSON *j = cJSON_Parse(json);
  dem_model m;
  proto_err err = {{0}};
  const int rc = dem_model_from_json(&m, j, "processes.dem", &err);
  cJSON_Delete(j);
  printf("sleep {%s} -> %s\n", entry, rc ? err.msg : "accepted");
  CHECK(rc != 0, "sleep {%s} accepted", entry);
  if (rc) CHECK_MSG(err, name);
  else dem_model_free(&m);
}

int main(void) {
  bad_sleep("\"distance\":[0.1, 0.2]", "processes.dem.sleep.distance");
  bad_sleep("\"distance\":[0.1, -0.2, 0.3]", "processes.dem.sleep.distance[1]");
  bad_sleep("\"distance\":\"far\"", "processes.dem.sleep.distance");
  bad_sleep("\"distance\":-1", "processes.dem.sleep.distance");
  bad_sleep("\"force\":-1", "processes.dem.sleep.force");
  bad_sleep("\"force\":\"strong\"", "processes.dem.sleep.force");
  bad_sleep("\"halo\":1.5", "processes.dem.sleep.halo");
  bad_sleep("\"halo\":-1", "processes.dem.sleep.halo");
  bad_sleep("\"test_steps\":7", "processes.dem.sleep.test_steps");
  bad_sleep("\"test_steps\":0", "processes.dem.sleep.test_steps");
  bad_sleep("\"test_steps\":2.5", "processes.dem.sleep.test_steps");
  rest_not_slow();
  int first_listed, first_pressed;
  double gap_listed, gap_pressed;
  wake_batch("", 16, &first_listed, &gap_listed);
  wake_batch(",\"wake_velocity\":2", 16, &first_pressed, &gap_pressed); /* launched at 1 m/s */
  int first_bare;
  double gap_bare;
  wake_batch(",\"halo\":0", 4, &first_bare, &gap_bare); /* the same first wake, without its batch */
  CHECK(first_bare == first_listed && gap_bare == gap_listed, "halo 0 moved the first wake: step %d gap %g R "
        "against %d, %g R", first_bare, gap_bare / R, first_listed, gap_listed / R);
  CHECK(gap_listed > 0, "the default wake came at a gap of %g R, not before the contact", gap_listed / R);
  CHECK(gap_pressed <= -0.02 * R && first_pressed > first_listed,
        "with wake_velocity above the launch speed the first wake came at step %d (%d by default), gap %g R: "
        "expected it when the overlap passes sleep.overlap 0.02 R", first_pressed, first_listed, gap_pressed / R);
  wake_below_velocity();
  return cosim_test_done("test_dem_sleep_rest");
}
