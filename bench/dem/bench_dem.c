/* bench_dem — times dem_step on a settling bed read from a LAMMPS/LIGGGHTS data
 * file (the same initial state both codes get) or generated, single scene.
 * usage: bench_dem DATA|BED.h5|--bed=SCALE L|LXxLY NSETTLE NRUN THREADS [DT] [KEFILE|-] [SAVE.h5]
 * Prints wall time of the settling and the timed phases, KE and contacts. */
#include "dem_server/dem.h"

#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <time.h>

static double cpu_now(void) {
  struct timespec ts;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

static int read_data(const char *path, dem_model *m, proto_err *err) {
  FILE *f = fopen(path, "r");
  if (!f) return proto_fail(err, "%s: cannot open", path);
  char line[512];
  long n = 0;
  while (fgets(line, sizeof line, f)) {
    if (strstr(line, " atoms")) n = atol(line);
    if (strncmp(line, "Atoms", 5) == 0) break;
  }
  if (n <= 0 || dem_model_alloc_grains(m, (int)n, err)) { fclose(f); return -1; }
  long got = 0;
  while (got < n && fgets(line, sizeof line, f)) {
    long id; int type; double d, rho, x, y, z;
    if (sscanf(line, "%ld %d %lf %lf %lf %lf %lf", &id, &type, &d, &rho, &x, &y, &z) != 7) continue;
    long i = id - 1;
    m->x0[3 * i] = x; m->x0[3 * i + 1] = y; m->x0[3 * i + 2] = z;
    m->radius[i] = 0.5 * d;
    got++;
  }
  while (fgets(line, sizeof line, f))
    if (strncmp(line, "Velocities", 10) == 0) break;
  long gv = 0;
  while (gv < n && fgets(line, sizeof line, f)) {
    long id; double vx, vy, vz;
    if (sscanf(line, "%ld %lf %lf %lf", &id, &vx, &vy, &vz) != 4) continue;
    m->v0[3 * (id - 1)] = vx; m->v0[3 * (id - 1) + 1] = vy; m->v0[3 * (id - 1) + 2] = vz;
    gv++;
  }
  fclose(f);
  return got == n ? 0 : proto_fail(err, "%s: %ld of %ld atoms", path, got, n);
}

int main(int argc, char **argv) {
  dem_openmp_env(argv); /* short barrier spin: the machine may be shared */
  if (argc < 6) {
    fprintf(stderr, "usage: %s DATA|--bed=SCALE L NSETTLE NRUN THREADS [DT] [KEFILE]\n", argv[0]);
    return 2;
  }
  const double L = atof(argv[2]);
  const char *by = strchr(argv[2], 'x'); /* "LXxLY": a rectangular box */
  const double Ly = by ? atof(by + 1) : L;
  const long nsettle = atol(argv[3]), nrun = atol(argv[4]);
  const int threads = atoi(argv[5]);
  const double dt = argc > 6 ? atof(argv[6]) : 5e-5;
  char json[1024];
  /* the settling-bed scene (docs/dem-bench.md §3): E = 5e6, nu = 0.3, e = 0.5, mu = 0.6, rho = 2600; skin 2 mm; L x L box */
  snprintf(json, sizeof json,
           "{\"materials\":[{\"density\":2600,\"E\":5e6,\"nu\":0.3,\"restitution\":0.5,\"friction\":0.6}],"
           "\"threads\":%d,\"dt\":%.17g,\"skin\":0.002,\"overlap_tolerance\":0.1,\"unsafe_dt\":true,"
           "\"walls\":[{\"type\":\"box\",\"lo\":[0,0,0],\"hi\":[%.17g,%.17g,100],\"open_top\":true}],"
           "\"particles\":[{\"x\":[0.01,0.01,0.01],\"r\":0.001}]}", threads, dt, L, Ly);
  proto_err err;
  dem_model m;
  dem_state s;
  cJSON *j = cJSON_Parse(json);
  if (dem_model_from_json(&m, j, "bench", &err)) { fprintf(stderr, "%s\n", err.msg); return 1; }
  cJSON_Delete(j);
  if (strncmp(argv[1], "--bed=", 6) == 0) {
    dem_bed_spec b;
    dem_bed_paper(&b, atof(argv[1] + 6));
    b.size[0] = L;
    b.size[1] = Ly;
    if (dem_bed_place(&m, &b, &err)) { fprintf(stderr, "%s\n", err.msg); return 1; }
  } else if (strstr(argv[1], ".h5")) {
    if (dem_bed_load(&m, argv[1], &err)) { fprintf(stderr, "%s\n", err.msg); return 1; }
  } else if (read_data(argv[1], &m, &err)) {
    fprintf(stderr, "%s\n", err.msg);
    return 1;
  }
  m.rayleigh_time = dem_model_rayleigh(&m);
  if (dem_state_init(&m, &s, 0, &err)) { fprintf(stderr, "%s\n", err.msg); return 1; }
  printf("dt = %.4g s = %.4g Rayleigh times\nthreads: %s\n", s.dt, s.dt / m.rayleigh_time, s.threads_why);
  FILE *ke = argc > 7 && strcmp(argv[7], "-") ? fopen(argv[7], "w") : NULL;
  double t0 = omp_get_wtime(), c0 = cpu_now();
  for (long k = 1; k <= nsettle + nrun; k++) {
    if (k == nsettle + 1) {
      double t1 = omp_get_wtime(), c1 = cpu_now();
      printf("settle %ld steps: %.3f s wall %.3f s cpu  %.3g p-steps/s (wall)  rebuilds %lld\n", nsettle,
             t1 - t0, c1 - c0, nsettle ? (double)m.n_grains * nsettle / (t1 - t0) : 0, (long long)s.rebuilds);
      t0 = t1;
      c0 = c1;
      s.rebuilds = 0;
    }
    const int threads_before = s.threads;
    if (dem_step(&m, &s, &err)) { fprintf(stderr, "%s\n", err.msg); return 1; }
    if (s.threads != threads_before) printf("step %ld: %s\n", k, s.threads_why);
    if (ke && k % 100 == 0) {
      double ktr = 0, zmax = 0;
      for (int i = 0; i < s.n; i++) {
        ktr += 0.5 * (s.v[3 * i] * s.v[3 * i] + s.v[3 * i + 1] * s.v[3 * i + 1] + s.v[3 * i + 2] * s.v[3 * i + 2]) / s.inv_mass[i];
        if (s.x[3 * i + 2] + s.radius[i] > zmax) zmax = s.x[3 * i + 2] + s.radius[i];
      }
      fprintf(ke, "%ld %.9g %.9g %.9g %.6g\n", k, ktr, s.kinetic_energy - ktr, zmax, dem_coordination(&m, &s));
    }
  }
  double t1 = omp_get_wtime(), c1 = cpu_now();
  struct rusage ru;
  getrusage(RUSAGE_SELF, &ru);
  /* bed height: mean top of the highest 1 % ... use the simple measure of docs/dem-bench.md §4: zmax and mean z */
  double zsum = 0;
  for (int i = 0; i < s.n; i++) zsum += s.x[3 * i + 2];
  printf("run %ld steps: %.3f s wall %.3f s cpu  %.3g p-steps/s (wall)  rebuilds %lld\n", nrun, t1 - t0, c1 - c0,
         (double)m.n_grains * nrun / (t1 - t0), (long long)s.rebuilds);
  printf("threads at the end: %s\n", s.threads_why);
  printf("N %d threads %d KE %.9g contacts %lld coordination %.4f mean_z %.6g maxrss_kb %ld\n",
         m.n_grains, s.threads, s.kinetic_energy, (long long)s.contacts, dem_coordination(&m, &s),
         zsum / s.n, ru.ru_maxrss);
  if (ke) fclose(ke);
  if (argc > 8 && dem_bed_save(&m, &s, argv[8], &err)) fprintf(stderr, "%s\n", err.msg);
  dem_state_free(&s);
  dem_model_free(&m);
  return 0;
}
