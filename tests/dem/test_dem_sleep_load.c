/* Sleeping grains under a growing load ("sleep"): a column of seven grains
 * on the floor, the lowest two outside the region around the plate, falls
 * asleep there; the plate then presses the top grain down slower
 * than the sleep velocity. A sleeping grain is a fixed one, so the grains
 * below must wake once pressed (sleep.overlap), or the whole compression
 * would go into one contact (Hertz in series: ~8x the force). Checked against
 * the same column with sleep off: the plate's force at the end within 1 %;
 * and at every step the reported largest overlap covers every contact with
 * an awake grain (a sleeping grain's contacts with awake ones were hidden
 * from it, so a run stopped later on an overlap that jumped from 0.17 to
 * 0.85 of a radius in one step).
 *
 * The force rule (sleep.force, dem_sleep_push.c) alone, the overlap rule off
 * (overlap 1): the asleep grains wake when the push of the grain above has
 * grown by `force` times a grain's weight since they fell asleep, i.e. when
 * the plate, pressing quasi-statically, carries about that much (the push on
 * the upper asleep grain is the weight of the five above plus the plate's
 * force); the end force again within 1 % of all awake, also with the rule
 * tested every 20 steps (sleep.test_steps: the wake at a multiple of 20,
 * not before the force). With neither rule the
 * two stay asleep and the end force is far off (the test's own check that
 * the column can tell). */
#include "dem_test.h"
#include "dem_server/dem_internal.h"

#define R 0.003
#define GAP 2e-4       /* plate above the top grain at the start */
#define SPEED 1e-3     /* m/s, below the sleep velocity */
#define DT 5e-5
#define REST_STEPS 4000 /* 0.2 s: the column at rest and asleep before the plate arrives */
#define PRESS_STEPS 20000 /* then 0.6 mm more: ~0.2 R of compression in all */
/* Grains in the column: the region around the moving plate (dem_sleep.c:
 * margin r + 2 skin + c 5 dt, and half that again) keeps the upper ones awake;
 * the two lowest lie outside it and fall asleep. */
#define NG 7

#define SLEEP "{\"velocity\":0.005,\"time\":0.01,\"distance\":0"
#define FORCE 0.5 /* sleep.force of the force-rule case (grain weights) */

static const char *column(const char *sleep) {
  static char json[4096];
  const double zp = 2 * NG * R + NG * 1e-6 + GAP + SPEED * REST_STEPS * DT;
  int len = snprintf(json, sizeof json,
           "{\"materials\":[{\"density\":2600,\"E\":5e6,\"nu\":0.3,\"restitution\":0.3,\"friction\":0.6}],"
           "\"dt\":%g,\"threads\":1,\"sleep\":%s,"
           "\"walls\":[{\"type\":\"box\",\"lo\":[0,0,0],\"hi\":[0.02,0.02,1],\"open_top\":true},"
           "{\"type\":\"mesh\",\"nodes\":[[0.0,0.0,%.17g],[0.02,0.0,%.17g],[0.02,0.02,%.17g],[0.0,0.02,%.17g]],"
           "\"triangles\":[[0,1,2],[0,2,3]],\"velocity\":[0,0,%g]}],\"particles\":[",
           DT, sleep, zp, zp, zp, zp, -SPEED);
  for (int g = 0; g < NG; g++)
    len += snprintf(json + len, sizeof json - (size_t)len, "%s{\"x\":[0.01,0.01,%.17g],\"r\":%g}", g ? "," : "",
                    (2 * g + 1) * R + (g + 1) * 1e-6, R);
  snprintf(json + len, sizeof json - (size_t)len, "]}");
  return json;
}

/* The largest overlap/smaller radius over the pairs with a grain awake
 * during the step's sweep (awake at the end of the step before: was[id];
 * two grains asleep then, one of them woken at the end of this step, touch
 * as they did when both fell asleep, and the next sweep reports it). */
static double awake_pairs_ratio(const dem_state *s, const uint8_t *was) {
  double worst = 0;
  for (int i = 0; i < s->n; i++)
    for (int j = i + 1; j < s->n; j++) {
      if (s->work->asleep && s->work->asleep[i] && s->work->asleep[j]) continue;
      if (was[s->id[i]] && was[s->id[j]]) continue;
      const double *a = &s->x[3 * i], *b = &s->x[3 * j];
      const double d[3] = {a[0] - b[0], a[1] - b[1], a[2] - b[2]};
      const double ov = s->radius[i] + s->radius[j] - sqrt(dem_dot(d, d));
      const double r = s->radius[i] < s->radius[j] ? s->radius[i] : s->radius[j];
      if (ov / r > worst) worst = ov / r;
    }
  return worst;
}

/* Runs the column; returns the plate's vertical force at the end; *woke_f:
 * the plate's force (in grain weights) at the first step with fewer asleep
 * grains than when it arrived (-1: none woke); *d0: the vertical change of
 * push on grain 1 (the upper asleep one) when the plate arrived, in weights
 * (the column settled on after it fell asleep: it counts). */
static int64_t first_wake_step; /* s.step after the step of the first wake (press) */

static double press(const char *sleep, int64_t *asleep_at_touch, int64_t *asleep_end, int *hidden,
                    double *woke_f, double *d0) {
  dem_model m;
  dem_state s;
  proto_err err;
  scene(column(sleep), &m, &s);
  const double weight = 4.0 / 3.0 * M_PI * R * R * R * 2600 * 9.81;
  uint8_t was[NG] = {0};
  *hidden = 0;
  *woke_f = -1;
  *d0 = 0;
  for (int k = 0; k < REST_STEPS + PRESS_STEPS; k++) {
    if (dem_step(&m, &s, &err)) { fprintf(stderr, "%s\n", err.msg); exit(1); }
    const int64_t asleep = s.n - s.work->n_active;
    if (k == REST_STEPS) {
      *asleep_at_touch = asleep;
      dem_push_fresh(&m, &s); /* the book's `now` as of this step (gathered when read) */
      const double *p = s.work->push ? &s.work->push[DEM_PUSH_REC * 1] : NULL; /* grain 1, the upper asleep one */
      if (p && p[DEM_PUSH_STATE] == 1) *d0 = (p[DEM_PUSH_NOW + 2] - p[DEM_PUSH_B + 2]) / weight;
    }
    if (k > REST_STEPS && *woke_f < 0 && asleep < *asleep_at_touch) {
      *woke_f = s.wall_force[3 * 1 + 2] / weight;
      first_wake_step = s.step;
    }
    if (awake_pairs_ratio(&s, was) > s.max_overlap_ratio * (1 + 1e-12) + 1e-15) (*hidden)++;
    for (int i = 0; s.work->asleep && i < s.n; i++) was[s.id[i]] = s.work->asleep[i];
  }
  const double f = s.wall_force[3 * 1 + 2];
  *asleep_end = s.sleeping;
  printf("sleep %s: asleep when the plate arrives %lld, at the end %lld; plate force %.6g N, first wake at "
         "%.3f weights (change before it %.3f); largest overlap %.4f of a radius; steps hiding an overlap %d\n", sleep,
         (long long)*asleep_at_touch, (long long)*asleep_end, f, *woke_f, *d0, s.max_overlap_ratio, *hidden);
  dem_state_free(&s);
  dem_model_free(&m);
  return f;
}

int main(void) {
  int64_t t0, e0, t1, e1, t2, e2, t3, e3;
  int h0, h1, h2, h3;
  double w0, w1, w2, w3, x0, x1, x2, x3;
  char force[256];
  snprintf(force, sizeof force, "%s,\"overlap\":1,\"force\":%g}", SLEEP, FORCE);
  const double awake = press("false", &t0, &e0, &h0, &w0, &x0), slept = press(SLEEP "}", &t1, &e1, &h1, &w1, &x1);
  const double pushed = press(force, &t2, &e2, &h2, &w2, &x2);
  const double frozen = press(SLEEP ",\"overlap\":1}", &t3, &e3, &h3, &w3, &x3);
  /* the force rule tested every 20 steps (sleep.test_steps) */
  int64_t t4, e4;
  int h4;
  double w4, x4;
  snprintf(force, sizeof force, "%s,\"overlap\":1,\"force\":%g,\"test_steps\":20}", SLEEP, FORCE);
  const double pushed20 = press(force, &t4, &e4, &h4, &w4, &x4);
  CHECK(fabs(awake) > 0.05, "the plate does not press the column (%g N)", awake);
  CHECK(t1 == 2, "the two lower grains were not asleep when the plate arrived (%lld)", (long long)t1);
  CHECK(e1 == 0, "grains still asleep under the plate (%lld)", (long long)e1);
  CHECK(fabs(slept - awake) < 0.01 * fabs(awake),
        "plate force with sleep %.6g N, all awake %.6g N (%.2f %%)", slept, awake,
        100 * (slept - awake) / awake);
  CHECK(h0 == 0 && h1 == 0, "the largest overlap left out a contact with an awake grain (%d, %d steps)", h0,
        h1);
  /* the force rule alone */
  /* they woke when the plate's force and the change before it (d0, down: < 0)
   * made FORCE weights; within 0.1 of a weight (the column's vibration) */
  CHECK(t2 == 2, "force rule: asleep when the plate arrived %lld (expected 2)", (long long)t2);
  CHECK(fabs(w2 - (FORCE + x2)) < 0.1, "force rule: the grains woke with the plate at %.3f weights, expected "
        "%g - %.3f (the change before it)", w2, FORCE, -x2);
  CHECK(fabs(pushed - awake) < 0.01 * fabs(awake), "force rule: plate force %.6g N, all awake %.6g N (%.2f %%)",
        pushed, awake, 100 * (pushed - awake) / awake);
  CHECK(h2 == 0, "force rule: the largest overlap left out a contact with an awake grain (%d steps)", h2);
  /* tested every 20 steps: the wake comes at a test, not before the force
   * (within the column's vibration), and the end is the same */
  CHECK(t4 == 2 && first_wake_step % 20 == 0, "force rule every 20 steps: %lld asleep when the plate arrived, "
        "first wake after step %lld (expected 2, a multiple of 20)", (long long)t4, (long long)first_wake_step);
  CHECK(w4 > FORCE + x4 - 0.1, "force rule every 20 steps: woke with the plate at %.3f weights, before %g - %.3f",
        w4, FORCE, -x4);
  CHECK(fabs(pushed20 - awake) < 0.01 * fabs(awake), "force rule every 20 steps: plate force %.6g N, all awake "
        "%.6g N (%.2f %%)", pushed20, awake, 100 * (pushed20 - awake) / awake);
  CHECK(h4 == 0, "force rule every 20 steps: the largest overlap left out a contact with an awake grain (%d steps)",
        h4);
  /* neither rule: the column can tell */
  CHECK(e3 == 2 && fabs(frozen - awake) > 0.1 * fabs(awake), "neither rule: %lld asleep at the end, plate force "
        "%.6g N against %.6g N all awake (expected 2 and far off)", (long long)e3, frozen, awake);
  return cosim_test_done("test_dem_sleep_load");
}
