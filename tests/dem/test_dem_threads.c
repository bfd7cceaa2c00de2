/* A generated bed settling in an open box while a plate (mesh wall) ploughs
 * through it: results bitwise identical for 1, 2 and 4 OpenMP threads, and
 * when the thread count changes between steps (as "threads": "auto" does);
 * the Verlet list finds every contact a brute-force O(N²) search finds; beds
 * round-trip through HDF5. */
#include "dem_test.h"
#include "dem_server/dem_internal.h"
#include <string.h>
#include <unistd.h>

static const char *JSON =
    "{\"materials\":[{\"density\":2600,\"E\":5e6,\"nu\":0.3,\"restitution\":0.5,\"friction\":0.6}],"
    "\"threads\":%d,\"dt\":5e-5,\"orientation\":true,"
    "\"walls\":[{\"type\":\"box\",\"lo\":[0,0,0],\"hi\":[0.3162277660,0.3162277660,1],\"open_top\":true},"
    "{\"type\":\"mesh\",\"nodes\":[[0,0.02,0.01],[0,0.3,0.01],[0,0.3,0.12],[0,0.02,0.12]],"
    "\"triangles\":[[0,1,2],[0,2,3]],\"velocity\":[0.5,0,0]}],"
    "\"particles\":{\"generate\":\"bed\",\"scale\":0.1,\"seed\":7}}";

/* threads < 0: cycle 1, 2, 3, 4 threads, changing every 97 steps */
static void run(int threads, int steps, double *out, dem_model *m, dem_state *s) {
  char json[1024];
  snprintf(json, sizeof json, JSON, threads > 0 ? threads : 1);
  proto_err err;
  scene(json, m, s);
  for (int k = 0; k < steps; k++) {
    if (threads < 0 && k % 97 == 0) s->work->nthreads = s->threads = 1 + (k / 97) % 4;
    if (dem_step(m, s, &err)) { fprintf(stderr, "%s\n", err.msg); exit(1); }
  }
  const int n = s->n;
  dem_gather(s, s->x, 3, out);
  dem_gather(s, s->v, 3, out + 3 * n);
  dem_gather(s, s->omega, 3, out + 6 * n);
  for (int i = 0; i < n; i++) memcpy(&out[9 * n + 4 * s->id[i]], &s->q[4 * i], 4 * sizeof(double));
}

int main(void) {
  const int steps = 1000, variants[] = {1, 2, 4, -1};
  dem_model m[4];
  dem_state s[4];
  double *out[4];
  int n = 0;
  for (int v = 0; v < 4; v++) {
    if (v == 0) {
      char json[1024];
      snprintf(json, sizeof json, JSON, 1);
      scene(json, &m[0], &s[0]);
      n = m[0].n_grains;
      dem_state_free(&s[0]);
      dem_model_free(&m[0]);
    }
    out[v] = malloc(sizeof(double) * 13 * n);
    run(variants[v], steps, out[v], &m[v], &s[v]);
    printf("%d grains, %d steps, threads %s: KE %.17g, %lld contacts, %lld rebuilds, plate force %.9g N\n", n, steps,
           variants[v] > 0 ? (const char[][8]){"", "1", "2", "", "4"}[variants[v]] : "1-4",
           s[v].kinetic_energy, (long long)s[v].contacts, (long long)s[v].rebuilds, s[v].wall_force[3]);
  }
  CHECK(n > 4 * DEM_CHUNK, "too few grains for several chunks per thread");
  CHECK(s[0].rebuilds > 10 && s[0].contacts > n / 2 && fabs(s[0].wall_force[3]) > 0.1,
        "scene too quiet to test anything (plate force %g)", s[0].wall_force[3]);
  for (int v = 1; v < 4; v++) {
    CHECK(memcmp(out[0], out[v], sizeof(double) * 13 * n) == 0, "x, v, ω or q differ: 1 thread vs variant %d", v);
    CHECK(s[0].kinetic_energy == s[v].kinetic_energy && s[0].elastic_energy == s[v].elastic_energy &&
              s[0].contacts == s[v].contacts,
          "summary differs: 1 thread vs variant %d", v);
    CHECK(memcmp(s[0].wall_force, s[v].wall_force, sizeof(double) * 3 * m[0].n_walls) == 0,
          "wall forces differ: 1 thread vs variant %d", v);
  }
  /* brute-force contact count */
  dem_state *s1 = &s[0];
  int64_t brute = 0;
  for (int i = 0; i < s1->n; i++)
    for (int j = i + 1; j < s1->n; j++) {
      double d[3] = {s1->x[3 * i] - s1->x[3 * j], s1->x[3 * i + 1] - s1->x[3 * j + 1], s1->x[3 * i + 2] - s1->x[3 * j + 2]};
      double rs = s1->radius[i] + s1->radius[j];
      brute += d[0] * d[0] + d[1] * d[1] + d[2] * d[2] < rs * rs;
    }
  double z = dem_coordination(&m[0], s1) * n / 2;
  printf("grain-grain contacts: list %.0f, brute force %lld\n", z, (long long)brute);
  CHECK(fabs(z - (double)brute) < 0.5, "neighbour list misses contacts");
  /* HDF5 round trip */
  char path[] = "/tmp/test_dem_bed_XXXXXX";
  int fd = mkstemp(path);
  close(fd);
  proto_err err;
  CHECK(dem_bed_save(&m[0], s1, path, &err) == 0, "save: %s", err.msg);
  dem_model m3;
  memset(&m3, 0, sizeof m3);
  CHECK(dem_bed_load(&m3, path, &err) == 0, "load: %s", err.msg);
  CHECK(m3.n_grains == n && memcmp(m3.x0, out[0], sizeof(double) * 3 * n) == 0, "bed positions not restored");
  double *r = malloc(sizeof(double) * n);
  dem_gather(s1, s1->radius, 1, r);
  CHECK(memcmp(m3.radius, r, sizeof(double) * n) == 0, "bed radii not restored");
  unlink(path);
  free(r);
  dem_model_free(&m3);
  for (int v = 0; v < 4; v++) {
    dem_state_free(&s[v]);
    dem_model_free(&m[v]);
    free(out[v]);
  }
  return cosim_test_done("test_dem_threads");
}
