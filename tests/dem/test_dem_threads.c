/* A small generated bed settling in an open box: results bitwise identical
 * for 1 and 2 OpenMP threads (no racy sums); the Verlet list finds every
 * contact a brute-force O(N²) search finds; beds round-trip through HDF5. */
#include "dem_test.h"
#include <string.h>
#include <unistd.h>

static const char *JSON =
    "{\"materials\":[{\"density\":2600,\"E\":5e6,\"nu\":0.3,\"restitution\":0.5,\"friction\":0.6}],"
    "\"threads\":%d,\"dt\":5e-5,"
    "\"walls\":[{\"type\":\"box\",\"lo\":[0,0,0],\"hi\":[0.1414213562,0.1414213562,1],\"open_top\":true}],"
    "\"particles\":{\"generate\":\"bed\",\"scale\":0.02,\"seed\":7}}";

static void run(int threads, int steps, double *x_out, dem_model *m, dem_state *s) {
  char json[1024];
  snprintf(json, sizeof json, JSON, threads);
  proto_err err;
  scene(json, m, s);
  for (int k = 0; k < steps; k++)
    if (dem_step(m, s, &err)) { fprintf(stderr, "%s\n", err.msg); exit(1); }
  dem_gather(s, s->x, 3, x_out);
}

int main(void) {
  const int steps = 3000;
  dem_model m1, m2;
  dem_state s1, s2;
  int n;
  {
    char json[1024];
    snprintf(json, sizeof json, JSON, 1);
    dem_model m;
    dem_state s;
    scene(json, &m, &s);
    n = m.n_grains;
    dem_state_free(&s);
    dem_model_free(&m);
  }
  double *x1 = malloc(sizeof(double) * 3 * n), *x2 = malloc(sizeof(double) * 3 * n);
  run(1, steps, x1, &m1, &s1);
  run(2, steps, x2, &m2, &s2);
  printf("%d grains, %d steps: KE %.9g (1 thread) %.9g (2 threads), %lld contacts, %lld rebuilds\n",
         n, steps, s1.kinetic_energy, s2.kinetic_energy, (long long)s1.contacts, (long long)s1.rebuilds);
  CHECK(memcmp(x1, x2, sizeof(double) * 3 * n) == 0, "positions differ between 1 and 2 threads");
  CHECK(s1.kinetic_energy == s2.kinetic_energy, "kinetic energy differs between 1 and 2 threads");
  CHECK(s1.rebuilds > 1 && s1.contacts > n, "scene too quiet to test anything");
  /* brute-force contact count */
  int64_t brute = 0;
  for (int i = 0; i < s1.n; i++)
    for (int j = i + 1; j < s1.n; j++) {
      double d[3] = {s1.x[3 * i] - s1.x[3 * j], s1.x[3 * i + 1] - s1.x[3 * j + 1], s1.x[3 * i + 2] - s1.x[3 * j + 2]};
      double rs = s1.radius[i] + s1.radius[j];
      brute += d[0] * d[0] + d[1] * d[1] + d[2] * d[2] < rs * rs;
    }
  double z = dem_coordination(&m1, &s1) * n / 2;
  printf("grain-grain contacts: list %.0f, brute force %lld\n", z, (long long)brute);
  CHECK(fabs(z - (double)brute) < 0.5, "neighbour list misses contacts");
  /* HDF5 round trip */
  char path[] = "/tmp/test_dem_bed_XXXXXX";
  int fd = mkstemp(path);
  close(fd);
  proto_err err;
  CHECK(dem_bed_save(&m1, &s1, path, &err) == 0, "save: %s", err.msg);
  dem_model m3;
  memset(&m3, 0, sizeof m3);
  CHECK(dem_bed_load(&m3, path, &err) == 0, "load: %s", err.msg);
  CHECK(m3.n_grains == n && memcmp(m3.x0, x1, sizeof(double) * 3 * n) == 0, "bed positions not restored");
  double *r = malloc(sizeof(double) * n);
  dem_gather(&s1, s1.radius, 1, r);
  CHECK(memcmp(m3.radius, r, sizeof(double) * n) == 0, "bed radii not restored");
  unlink(path);
  free(r);
  dem_model_free(&m3);
  dem_state_free(&s1); dem_state_free(&s2);
  dem_model_free(&m1); dem_model_free(&m2);
  free(x1); free(x2);
  return finish("test_dem_threads");
}
