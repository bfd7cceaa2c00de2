/* Sleeping grains ("sleep"): two layers of grains resting on the floor of a
 * box fall asleep; sleeping grains do not move; a plate (mesh) moving into
 * them wakes the grains it approaches and no sleeping grain ever touches it;
 * results stay bitwise identical for 1, 2 and 4 threads and across
 * export/import, as without sleep; all of it again with the force rule
 * (sleep.force, its book by grain id through the export), whose book,
 * gathered only when a test or a base needs it, gives the bits of one
 * gathered after every step (dem_push_fresh). */
#include "dem_test.h"
#include "dem_server/dem_internal.h"
#include <string.h>

#define R 0.003
#define NL 20 /* grains per row of the lower layer */

static const char *g_force = ""; /* "" or ",\"force\":F" inside "sleep" */

static char *scene_json(int threads) {
  static char json[200000];
  const double s = 2 * R + 2e-4, h = sqrt(4 * R * R - 0.5 * s * s), L = NL * s + 0.01;
  int len = snprintf(json, sizeof json,
      "{\"materials\":[{\"density\":2600,\"E\":5e6,\"nu\":0.3,\"restitution\":0.3,\"friction\":0.6}],"
      "\"threads\":%d,\"dt\":5e-5,\"sleep\":{\"velocity\":0.005,\"time\":0.01,\"distance\":0.005%s},"
      "\"walls\":[{\"type\":\"box\",\"lo\":[0,0,0],\"hi\":[%.17g,%.17g,1],\"open_top\":true},"
      /* a plate across the box coming in along +x from x = -0.07: arrives at t = 0.175 s */
      "{\"type\":\"mesh\",\"nodes\":[[-0.07,0.002,0.001],[-0.07,%.17g,0.001],[-0.07,%.17g,0.03],[-0.07,0.002,0.03]],"
      "\"triangles\":[[0,1,2],[0,2,3]],\"velocity\":[0.4,0,0]}],\"particles\":[",
      threads, g_force, L, L, L - 0.002, L - 0.002);
  len = dem_test_two_layers(json, len, sizeof json, NL, R, s, h);
  snprintf(json + len, sizeof json - len, "]}");
  return json;
}

/* x, v by grain id, and asleep by id */
static void by_id(const dem_state *s, double *xv, uint8_t *asleep) {
  dem_gather(s, s->x, 3, xv);
  dem_gather(s, s->v, 3, xv + 3 * s->n);
  for (int i = 0; i < s->n && asleep; i++) asleep[s->id[i]] = s->work->asleep[i];
}

static void roundtrip(const dem_model *m, dem_state *from, int threads, dem_model *m2, dem_state *s2) {
  proto_err err;
  proto_msg msg = {0};
  proto_msg_reset(&msg, "state", "state", 0, 0);
  CHECK(dem_state_export(m, from, &msg, &err) == 0, "export: %s", err.msg);
  scene(scene_json(threads), m2, s2);
  CHECK(dem_state_import(m2, s2, &msg, &err) == 0, "import: %s", err.msg);
  proto_msg_free(&msg);
}

static double run(void) {
  const int rest = 2000, plough = 2400; /* the plate reaches the grains at step 3500 */
  printf("sleep%s:\n", g_force);
  dem_model m;
  dem_state s;
  scene(scene_json(1), &m, &s);
  const int n = s.n;
  double *x0 = malloc(sizeof(double) * 6 * n), *x1 = malloc(sizeof(double) * 6 * n);
  uint8_t *a0 = malloc(n), *a1 = malloc(n);
  dem_test_steps(&m, &s, rest);
  printf("%d grains after %d steps: %lld asleep, KE %.3g J\n", n, rest, (long long)s.sleeping, s.kinetic_energy);
  CHECK(s.sleeping > 0.85 * n, "the grains at rest do not sleep (%lld of %d)", (long long)s.sleeping, n);
  /* sleeping grains stay where they are */
  by_id(&s, x0, a0);
  dem_test_steps(&m, &s, 200);
  by_id(&s, x1, a1);
  int still = 0, moved = 0;
  for (int g = 0; g < n; g++)
    if (a0[g] && a1[g]) {
      still++;
      moved += memcmp(&x0[3 * g], &x1[3 * g], 3 * sizeof(double)) != 0;
    }
  printf("%d grains asleep throughout 200 steps, %d of them moved\n", still, moved);
  CHECK(still > 0.85 * n && moved == 0, "sleeping grains moved (%d of %d)", moved, still);
  /* a settled state to start the thread and import comparisons from */
  dem_model mr;
  dem_state ref;
  roundtrip(&m, &s, 1, &mr, &ref);
  /* the plate comes in: grains near it wake, none asleep touches it */
  int64_t least = s.sleeping, touching_asleep = 0, contact_steps = 0;
  for (int k = 0; k < plough; k++) {
    dem_test_steps(&m, &s, 1);
    least = s.sleeping < least ? s.sleeping : least;
    for (int i = 0; i < n; i++)
      for (int q = 0; q < DEM_MESH_SLOTS; q++)
        if (s.work->mc_key[(size_t)i * DEM_MESH_SLOTS + q]) {
          contact_steps++;
          touching_asleep += s.work->asleep[i];
        }
  }
  printf("plate at x = %.3f: %lld grain-plate contact-steps, %lld of them by sleeping grains; asleep now %lld "
         "(least %lld), plate force %.4g N\n", s.mesh_x[0][0], (long long)contact_steps, (long long)touching_asleep,
         (long long)s.sleeping, (long long)least, s.wall_force[3]);
  CHECK(contact_steps > 1000 && touching_asleep == 0, "sleeping grains touched the plate (%lld)", (long long)touching_asleep);
  CHECK(least < 0.8 * n, "the plate woke too few grains (least asleep %lld)", (long long)least);
  by_id(&s, x0, NULL);
  const double ke = s.kinetic_energy;
  /* from the settled state with 1, 2 and 4 threads, and with an export/import half way */
  for (int t = 1; t <= 4; t *= 2) {
    dem_model mt;
    dem_state st;
    roundtrip(&mr, &ref, t, &mt, &st);
    /* the region's passes over every grain split over the threads even on
     * this small bed (dem_sleep_occ.c dem_occ_build): the same bits as the
     * straight run's one pass */
    if (st.work->asleep) st.work->occ_threads_min = t > 1 ? 0 : DEM_OCC_THREADS_MIN;
    if (t == 2) {
      dem_test_steps(&mt, &st, plough / 2);
      dem_model mh;
      dem_state sh;
      roundtrip(&mt, &st, 1, &mh, &sh);
      if (sh.work->asleep) sh.work->occ_threads_min = 0;
      dem_state_free(&st);
      dem_model_free(&mt);
      mt = mh;
      st = sh;
      dem_test_steps(&mt, &st, plough - plough / 2);
    } else {
      dem_test_steps(&mt, &st, plough);
    }
    by_id(&st, x1, NULL);
    printf("%d thread(s)%s: KE %.17g (straight %.17g)\n", t, t == 2 ? ", export/import half way" : "",
           st.kinetic_energy, ke);
    CHECK(memcmp(x0, x1, sizeof(double) * 6 * n) == 0 && st.kinetic_energy == ke && st.sleeping == s.sleeping,
          "%d threads differ with sleep", t);
    /* the last region update's occupancy grid and near flags, byte for byte */
    const struct dem_work *wa = s.work, *wb = st.work;
    const size_t cells = (size_t)wa->occ_dim[0] * wa->occ_dim[1] * wa->occ_dim[2];
    CHECK(wa->region_step == wb->region_step && memcmp(wa->occ_dim, wb->occ_dim, sizeof wa->occ_dim) == 0 &&
          memcmp(wa->occ, wb->occ, cells) == 0 && wa->n_active == wb->n_active &&
          memcmp(wa->near, wb->near, (size_t)wa->n_active) == 0,
          "%d threads: the region's occupancy (%zu cells) or near flags differ", t, cells);
    dem_state_free(&st);
    dem_model_free(&mt);
  }
  if (*g_force) { /* the force rule's book gathered after every step, as before it
     * was gathered only when read: dem_push_fresh gathers when the step did not */
    dem_model mt;
    dem_state st;
    roundtrip(&mr, &ref, 1, &mt, &st);
    int skipped = 0;
    for (int k = 0; k < plough; k++) {
      dem_test_steps(&mt, &st, 1);
      skipped += st.work->push && !dem_push_current(st.work) && st.work->n_active < st.n;
      dem_push_fresh(&mt, &st);
    }
    by_id(&st, x1, NULL);
    printf("book gathered after every step (%d steps had left it): KE %.17g (straight %.17g)\n", skipped,
           st.kinetic_energy, ke);
    CHECK(memcmp(x0, x1, sizeof(double) * 6 * n) == 0 && st.kinetic_energy == ke && st.sleeping == s.sleeping,
          "the book gathered after every step differs");
    CHECK(skipped > 100, "the force rule's gather ran at %d of %d steps: the check above "
          "did not test leaving it out", plough - skipped, plough);
    dem_state_free(&st);
    dem_model_free(&mt);
  }
  dem_state_free(&ref);
  dem_model_free(&mr);
  dem_state_free(&s);
  dem_model_free(&m);
  free(x0); free(x1); free(a0); free(a1);
  return ke;
}

int main(void) {
  const double plain = run();
  g_force = ",\"force\":0.05"; /* a twentieth of a grain's weight: the plate's push wakes grains sooner */
  const double pushed = run();
  CHECK(pushed != plain, "the force rule changed nothing here (KE %.17g both): the checks above did not test it",
        plain);
  return cosim_test_done("test_dem_sleep");
}
