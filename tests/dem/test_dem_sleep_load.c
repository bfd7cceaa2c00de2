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
 * 0.85 of a radius in one step). */
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

static const char *column(int sleep) {
  static char json[4096];
  const double zp = 2 * NG * R + NG * 1e-6 + GAP + SPEED * REST_STEPS * DT;
  int len = snprintf(json, sizeof json,
           "{\"materials\":[{\"density\":2600,\"E\":5e6,\"nu\":0.3,\"restitution\":0.3,\"friction\":0.6}],"
           "\"dt\":%g,\"threads\":1,\"sleep\":%s,"
           "\"walls\":[{\"type\":\"box\",\"lo\":[0,0,0],\"hi\":[0.02,0.02,1],\"open_top\":true},"
           "{\"type\":\"mesh\",\"nodes\":[[0.0,0.0,%.17g],[0.02,0.0,%.17g],[0.02,0.02,%.17g],[0.0,0.02,%.17g]],"
           "\"triangles\":[[0,1,2],[0,2,3]],\"velocity\":[0,0,%g]}],\"particles\":[",
           DT, sleep ? "{\"velocity\":0.005,\"time\":0.01,\"distance\":0}" : "false", zp, zp, zp, zp, -SPEED);
  for (int g = 0; g < NG; g++)
    len += snprintf(json + len, sizeof json - (size_t)len, "%s{\"x\":[0.01,0.01,%.17g],\"r\":%g}", g ? "," : "",
                    (2 * g + 1) * R + (g + 1) * 1e-6, R);
  snprintf(json + len, sizeof json - (size_t)len, "]}");
  return json;
}

/* The largest overlap/smaller radius over the pairs with an awake grain. */
static double awake_pairs_ratio(const dem_state *s) {
  double worst = 0;
  for (int i = 0; i < s->n; i++)
    for (int j = i + 1; j < s->n; j++) {
      if (s->work->asleep && s->work->asleep[i] && s->work->asleep[j]) continue;
      const double *a = &s->x[3 * i], *b = &s->x[3 * j];
      const double d[3] = {a[0] - b[0], a[1] - b[1], a[2] - b[2]};
      const double ov = s->radius[i] + s->radius[j] - sqrt(dem_dot(d, d));
      const double r = s->radius[i] < s->radius[j] ? s->radius[i] : s->radius[j];
      if (ov / r > worst) worst = ov / r;
    }
  return worst;
}

/* Runs the column; returns the plate's vertical force at the end. */
static double press(int sleep, int64_t *asleep_at_touch, int64_t *asleep_end, int *hidden) {
  dem_model m;
  dem_state s;
  proto_err err;
  scene(column(sleep), &m, &s);
  *hidden = 0;
  for (int k = 0; k < REST_STEPS + PRESS_STEPS; k++) {
    if (dem_step(&m, &s, &err)) { fprintf(stderr, "%s\n", err.msg); exit(1); }
    if (k == REST_STEPS) *asleep_at_touch = s.sleeping;
    if (awake_pairs_ratio(&s) > s.max_overlap_ratio * (1 + 1e-12) + 1e-15) (*hidden)++;
  }
  const double f = s.wall_force[3 * 1 + 2];
  *asleep_end = s.sleeping;
  printf("sleep %s: asleep when the plate arrives %lld, at the end %lld; plate force %.6g N, "
         "largest overlap %.4f of a radius; steps hiding an overlap %d\n", sleep ? "on " : "off",
         (long long)*asleep_at_touch, (long long)*asleep_end, f, s.max_overlap_ratio, *hidden);
  dem_state_free(&s);
  dem_model_free(&m);
  return f;
}

int main(void) {
  int64_t t0, e0, t1, e1;
  int h0, h1;
  const double awake = press(0, &t0, &e0, &h0), slept = press(1, &t1, &e1, &h1);
  CHECK(fabs(awake) > 0.05, "the plate does not press the column (%g N)", awake);
  CHECK(t1 == 2, "the two lower grains were not asleep when the plate arrived (%lld)", (long long)t1);
  CHECK(e1 == 0, "grains still asleep under the plate (%lld)", (long long)e1);
  CHECK(fabs(slept - awake) < 0.01 * fabs(awake),
        "plate force with sleep %.6g N, all awake %.6g N (%.2f %%)", slept, awake,
        100 * (slept - awake) / awake);
  CHECK(h0 == 0 && h1 == 0, "the largest overlap left out a contact with an awake grain (%d, %d steps)", h0,
        h1);
  return cosim_test_done("test_dem_sleep_load");
}
