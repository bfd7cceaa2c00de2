/* The active region's box ("sleep"): `distance` widens the box around the
 * triangles that can reach a grain before the next update; it does not make
 * farther triangles count (dem_sleep.c region_update).
 *
 * Two layers of grains rest on the floor of a box; a small plate glides
 * along x above them, never touching one (its velocity makes it a moving
 * mesh).
 * 1. The plate a gap g above the grains' centres, with reach < g < distance:
 *    it can reach no grain before the next update, so it holds none awake and
 *    the bed falls asleep (the box of every triangle within distance kept the
 *    grains under the plate awake: 0 of 761 slept).
 * 2. The plate within reach: every grain within `distance` of the plate's
 *    footprint is awake, and the region holds none beyond its largest extent
 *    (the plate's path grown by the margin and the hysteresis; grains outside
 *    it fall asleep in batches, dem_sleep.c fall_asleep).
 * 3. `distance` per axis, [d, 0, d]: along x as in 2, but beside the plate
 *    (along y) the region reaches only the reach and its hysteresis.
 * 4. Within reach of a grain, not of the grains' box: without gravity, one
 *    more grain floats at rest above the plate's height in the far corner
 *    (as a grain carried up in a tread's groove, or a heap against a far
 *    wall): the plate as in 1 is within the reach of the grains' box but of
 *    no grain, so it holds none awake (by the grains' box alone it did: the
 *    sand scene's region grew to the whole tyre).
 * 5. Within reach of a fast grain only: the plate as in 1, and without
 *    gravity one more grain just under the plate, moving with it (as a grain
 *    the tread carries): faster than wake_velocity it is awake whatever the
 *    region and wakes what it approaches, so the plate holds nothing awake
 *    for it: the bed falls asleep, the grain itself stays awake (counted, it
 *    held the bed under the plate awake: the sand scene's region reached
 *    back to the grains carried behind the tyre).
 * 6. The occupancy marks only the cells the candidate triangles can read
 *    (dem_sleep_occ.c), finding the asleep grains from the cells of the last
 *    full rebuild: on 2's bed (the grains beyond the region asleep), with
 *    cells of a grain's radius, every cell of a query box is marked exactly
 *    when some grain's sphere box (an asleep grain's, or a slow awake one's)
 *    meets it, counted over every grain; for a box around the plate (all
 *    awake), one over the far end (asleep) and the whole grid. */
#include "dem_test.h"
#include "dem_server/dem_internal.h"
#include <string.h>

#define R 0.003
#define NL 20          /* grains per row of the lower layer */
#define DISTANCE 0.04  /* sleep.distance (m) */
#define PLATE 0.02     /* the plate's side (m) */
#define SPEED 0.02     /* the plate's speed along x (m/s) */
#define DT 5e-5
#define STEPS 2400     /* 0.12 s: the rest time 0.01 s many times over */

/* lone: without gravity, one more grain: 1 at (L - 0.01, 0.01, the plate's
 * height + 0.005), at rest; 2 under the plate's centre, its top 1 mm below
 * the plate, moving with the plate (faster than wake_velocity, 0.01 m/s here
 * instead of the default 4 x 0.005) */
static char *scene_json_lone(double gap, const char *distance, int lone) {
  static char json[200000];
  const double s = 2 * R + 2e-4, h = sqrt(4 * R * R - 0.5 * s * s), L = NL * s + 0.01;
  const double ztop = R + 1e-5 + h + 1e-5; /* the upper layer's centres */
  const double zp = ztop + gap, x0 = 0.03, y0 = 0.5 * L - 0.5 * PLATE;
  int len = snprintf(json, sizeof json,
      "{\"materials\":[{\"density\":2600,\"E\":5e6,\"nu\":0.3,\"restitution\":0.3,\"friction\":0.6}],"
      "\"dt\":%g,%s\"sleep\":{\"velocity\":0.005,%s\"time\":0.01,\"distance\":%s},"
      "\"walls\":[{\"type\":\"box\",\"lo\":[0,0,0],\"hi\":[%.17g,%.17g,1],\"open_top\":true},"
      "{\"type\":\"mesh\",\"nodes\":[[%.17g,%.17g,%.17g],[%.17g,%.17g,%.17g],[%.17g,%.17g,%.17g],"
      "[%.17g,%.17g,%.17g]],\"triangles\":[[0,1,2],[0,2,3]],\"velocity\":[%g,0,0]}],\"particles\":[",
      DT, lone ? "\"gravity\":[0,0,0]," : "", lone == 2 ? "\"wake_velocity\":0.01," : "", distance, L, L,
      x0, y0, zp, x0 + PLATE, y0, zp, x0 + PLATE, y0 + PLATE, zp, x0, y0 + PLATE, zp, SPEED);
  len = dem_test_two_layers(json, len, sizeof json, NL, R, s, h);
  if (lone == 1)
    len += snprintf(json + len, sizeof json - len, ",{\"x\":[%.17g,0.01,%.17g],\"r\":%g}", L - 0.01, zp + 0.005, R);
  if (lone == 2)
    len += snprintf(json + len, sizeof json - len, ",{\"x\":[%.17g,%.17g,%.17g],\"r\":%g,\"v\":[%g,0,0]}",
                    x0 + 0.5 * PLATE, y0 + 0.5 * PLATE, zp - R - 0.001, R, SPEED);
  snprintf(json + len, sizeof json - len, "]}");
  return json;
}

static char *scene_json(double gap, const char *distance) { return scene_json_lone(gap, distance, 0); }

/* the reach (region_margin without distance) at the plate's speed */
static double reach(const dem_model *m, const dem_state *s) {
  const double c = sqrt(m->mat[0].E / m->mat[0].density), N = DEM_REGION_STEPS;
  return fmax(R, s->work->region_rmax) + 2 * m->skin + c * N * DT + SPEED * (N + 1) * DT;
}

/* gaps along x and y from a grain's centre to the plate's footprint */
static void plate_gaps(const dem_state *s, int i, double *dx, double *dy) {
  const double *p = s->mesh_x[0], *x = &s->x[3 * i];
  *dx = fmax(0, fmax(p[0] - x[0], x[0] - p[3]));
  *dy = fmax(0, fmax(p[1] - x[1], x[1] - p[7]));
}

/* distance in x-y from a grain's centre to the plate's footprint: Euclidean,
 * and along the farther axis (the region is a box) */
static double to_plate(const dem_state *s, int i, int box) {
  double dx, dy;
  plate_gaps(s, i, &dx, &dy);
  return box ? fmax(dx, dy) : sqrt(dx * dx + dy * dy);
}

/* Part 6: cells within the query box qlo..qhi whose mark differs from a count
 * over every grain; *by_asleep: cells that only asleep grains mark. */
static int occ_mismatch(const dem_model *m, dem_state *s, const double *qlo, const double *qhi, int *marked,
                        int *by_asleep) {
  struct dem_work *w = s->work;
  double glo[3] = {INFINITY, INFINITY, INFINITY}, ghi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (int i = 0; i < s->n; i++)
    for (int k = 0; k < 3; k++) {
      glo[k] = fmin(glo[k], s->x[3 * i + k]);
      ghi[k] = fmax(ghi[k], s->x[3 * i + k]);
    }
  dem_occ_build(s, glo, ghi, R, m->sleep.wake_velocity, qlo, qhi); /* cells of a radius: many, fine */
  const int *d = w->occ_dim, ncell = d[0] * d[1] * d[2];
  uint8_t *want = calloc((size_t)ncell, 1), *awake = calloc((size_t)ncell, 1);
  CHECK(want && awake, "out of memory for %d cells", ncell);
  if (!want || !awake) exit(1);
  const double h = w->occ_h, vw2 = m->sleep.wake_velocity * m->sleep.wake_velocity;
  for (int i = 0; i < s->n; i++) {
    const double *x = &s->x[3 * i], *v = &s->v[3 * i], r = s->radius[i];
    if (!w->asleep[i] && v[0] * v[0] + v[1] * v[1] + v[2] * v[2] > vw2) continue;
    int a[3], b[3];
    for (int k = 0; k < 3; k++) {
      a[k] = (int)fmax(0, floor((x[k] - r - w->occ_lo[k]) / h));
      b[k] = (int)fmin(d[k] - 1, floor((x[k] + r - w->occ_lo[k]) / h));
    }
    for (int z = a[2]; z <= b[2]; z++)
      for (int y = a[1]; y <= b[1]; y++)
        for (int c = a[0]; c <= b[0]; c++) {
          want[(z * d[1] + y) * d[0] + c] = 1;
          awake[(z * d[1] + y) * d[0] + c] |= !w->asleep[i];
        }
  }
  int q0[3], q1[3], bad = 0;
  for (int k = 0; k < 3; k++) {
    q0[k] = (int)fmax(0, floor((qlo[k] - w->occ_lo[k]) / h));
    q1[k] = (int)fmin(d[k] - 1, floor((qhi[k] - w->occ_lo[k]) / h));
  }
  *marked = *by_asleep = 0;
  for (int z = q0[2]; z <= q1[2]; z++)
    for (int y = q0[1]; y <= q1[1]; y++)
      for (int c = q0[0]; c <= q1[0]; c++) {
        const int cell = (z * d[1] + y) * d[0] + c;
        bad += w->occ[cell] != want[cell];
        *marked += want[cell];
        *by_asleep += want[cell] && !awake[cell];
      }
  free(want);
  free(awake);
  return bad;
}

int main(void) {
  dem_model m;
  dem_state s;
  char distance_all[32], distance_xz[64]; /* one number; part 3: along x and z only */
  snprintf(distance_all, sizeof distance_all, "%.17g", DISTANCE);
  snprintf(distance_xz, sizeof distance_xz, "[%.17g, 0, %.17g]", DISTANCE, DISTANCE);
  /* 1. out of reach, within distance */
  scene(scene_json(0.027, distance_all), &m, &s);
  const double g1 = 0.027, rc = reach(&m, &s);
  dem_test_steps(&m, &s, STEPS);
  printf("plate %.3f m above the grains' centres (reach %.4f m, distance %.3f m): %lld of %d asleep, region %s\n", g1,
         rc, DISTANCE, (long long)s.sleeping, s.n, s.work->region_on ? "on" : "off");
  CHECK(rc < g1 && g1 < DISTANCE, "the gap %.3f m does not lie between the reach %.4f and distance %.3f m", g1, rc,
        DISTANCE);
  CHECK(s.sleeping == s.n && !s.work->region_on, "a plate out of reach held %lld of %d grains awake",
        (long long)(s.n - s.sleeping), s.n);
  dem_state_free(&s);
  dem_model_free(&m);

  /* 2. within reach */
  const double g2 = 0.004; /* the grains' tops are R below their centres: 1 mm clear */
  scene(scene_json(g2, distance_all), &m, &s);
  const double margin = DISTANCE + reach(&m, &s) - fmax(R, s.work->region_rmax) - 2 * m.skin;
  dem_test_steps(&m, &s, STEPS);
  int inside = 0, inside_asleep = 0, far = 0, far_held = 0;
  const double farther = margin + 0.5 * reach(&m, &s) + SPEED * STEPS * DT + R; /* beyond anything the region held */
  for (int i = 0; i < s.n; i++) {
    const double d = to_plate(&s, i, 0);
    if (d < DISTANCE - R) { inside++; inside_asleep += s.work->asleep[i]; }
    if (to_plate(&s, i, 1) > farther) { far++; far_held += !s.work->asleep[i] && s.work->near[i]; }
  }
  printf("plate %.3f m above: %d grains within distance of it, %d asleep; %d beyond %.4f m, %d held awake by the region, "
         "%lld of %d asleep in all\n", g2, inside, inside_asleep, far, farther, far_held, (long long)s.sleeping, s.n);
  CHECK(inside > 20 && inside_asleep == 0, "%d of %d grains within distance of the plate sleep", inside_asleep, inside);
  CHECK(far > 20 && far_held == 0, "the region holds %d of %d grains beyond it awake", far_held, far);
  CHECK(s.wall_force[3] == 0 && s.wall_force[4] == 0 && s.wall_force[5] == 0, "the plate touched a grain");

  /* 6. the occupancy where the queries read it, on this bed */
  CHECK(s.work->grid_ok && s.sleeping > 20, "part 6 needs a grid of the asleep block (%lld of %d asleep)",
        (long long)s.sleeping, s.n);
  const double *p = s.mesh_x[0], rq = reach(&m, &s);
  const double boxes[3][6] = {
      {p[0] - rq, p[1] - rq, p[2] - 2 * rq, p[3] + rq, p[7] + rq, p[2] + rq}, /* around the plate */
      {0.1, -1, -1, 1, 1, 1},                                                  /* the far end, asleep */
      {-1, -1, -1, 1, 1, 1}};                                                  /* the whole grid */
  for (int b = 0; b < 3; b++) {
    int marked, by_asleep;
    const int bad = occ_mismatch(&m, &s, boxes[b], boxes[b] + 3, &marked, &by_asleep);
    printf("occupancy in query box %d: %d cells marked (%d by asleep grains alone), %d differ from every grain's\n", b,
           marked, by_asleep, bad);
    CHECK(bad == 0 && marked > 0 && (b == 0 || by_asleep > 0),
          "query box %d: %d cells differ (%d marked, %d by asleep grains)", b, bad, marked, by_asleep);
  }
  dem_state_free(&s);
  dem_model_free(&m);

  /* 3. distance along x and z only */
  scene(scene_json(g2, distance_xz), &m, &s);
  CHECK(m.sleep.distance[0] == DISTANCE && m.sleep.distance[1] == 0 && m.sleep.distance[2] == DISTANCE,
        "sleep.distance %s read as [%g, %g, %g]", distance_xz, m.sleep.distance[0], m.sleep.distance[1],
        m.sleep.distance[2]);
  dem_test_steps(&m, &s, STEPS);
  const double side = reach(&m, &s) * 1.5 + R; /* beyond the y margin (the reach) and the hysteresis */
  int ahead = 0, ahead_asleep = 0, beside = 0, beside_held = 0;
  for (int i = 0; i < s.n; i++) {
    double dx, dy;
    plate_gaps(&s, i, &dx, &dy);
    if (dy == 0 && dx < DISTANCE - R) { ahead++; ahead_asleep += s.work->asleep[i]; }
    if (dy > side) { beside++; beside_held += !s.work->asleep[i] && s.work->near[i]; }
  }
  printf("distance %s: %d grains within %.3f m along x of the plate, %d asleep; %d beyond %.4f m beside it, %d held "
         "awake by the region\n", distance_xz, ahead, DISTANCE, ahead_asleep, beside, side, beside_held);
  CHECK(ahead > 10 && ahead_asleep == 0, "%d of %d grains within distance along x sleep", ahead_asleep, ahead);
  CHECK(beside > 20 && beside_held == 0, "the region holds %d of %d grains beside the plate awake", beside_held,
        beside);
  dem_state_free(&s);
  dem_model_free(&m);

  /* 4. a lone grain above the plate's height, far from it */
  scene(scene_json_lone(g1, distance_all, 1), &m, &s);
  const int lone = s.n - 1; /* the last grain given (ids follow the input) */
  double gtop = -INFINITY;
  for (int i = 0; i < s.n; i++) gtop = fmax(gtop, s.x[3 * i + 2] + s.radius[i]);
  const double zplate = s.mesh_x[0][2];
  dem_test_steps(&m, &s, STEPS);
  printf("a lone grain %.4f m above the plate (grains' box top %.4f m): %lld of %d asleep, region %s\n",
         gtop - zplate, gtop, (long long)s.sleeping, s.n, s.work->region_on ? "on" : "off");
  CHECK(gtop > zplate && lone > 0, "the lone grain does not lift the grains' box above the plate");
  CHECK(s.sleeping == s.n && !s.work->region_on, "a plate out of reach of every grain (within the grains' box's) "
        "held %lld of %d grains awake", (long long)(s.n - s.sleeping), s.n);
  dem_state_free(&s);
  dem_model_free(&m);

  /* 5. a fast grain within reach of the plate, the bed out of it */
  scene(scene_json_lone(g1, distance_all, 2), &m, &s);
  const double vw = m.sleep.wake_velocity;
  CHECK(SPEED > vw, "the carried grain's %g m/s is not above wake_velocity %g m/s", SPEED, vw);
  dem_test_steps(&m, &s, STEPS);
  int carried = -1;
  for (int i = 0; i < s.n; i++)
    if (s.id[i] == s.n - 1) carried = i;
  printf("a grain moving under the plate at %g m/s (wake_velocity %g): %lld of %d asleep, it %s, region %s\n", SPEED,
         vw, (long long)s.sleeping, s.n, carried >= 0 && !s.work->asleep[carried] ? "awake" : "ASLEEP",
         s.work->region_on ? "on" : "off");
  CHECK(carried >= 0 && !s.work->asleep[carried] && s.sleeping == s.n - 1,
        "a plate within reach of one fast grain only held %lld of %d grains awake (the fast one %s)",
        (long long)(s.n - s.sleeping), s.n, carried >= 0 && !s.work->asleep[carried] ? "awake" : "asleep");
  dem_state_free(&s);
  dem_model_free(&m);
  return cosim_test_done("test_dem_region");
}
