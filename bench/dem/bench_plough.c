/* bench_plough — a wheel mesh (bench/dem/wheel.py) pressed into a settled bed
 * and driven through it, timed: the "disturbed bed" case of
 * bench/results/dem.md. Phase 1: the wheel goes down at VDESC for NDESC steps;
 * phase 2: it moves at VX along x for NMOVE steps, turning at OMEGA about its
 * axis (y); its nodes are set every COUPLE steps as a coupled surface is.
 * usage: bench_plough BED.h5 MESH.txt L|LXxLY NDESC VDESC NMOVE VX OMEGA THREADS [SLEEP [COUPLE [OUT.h5]]]
 * SLEEP: 0 off, 1 on with defaults, a sleep velocity (m/s), or the "sleep" object as JSON.
 * Prints the wall time of each phase, the mean force of the grains on the
 * wheel over the second half of phase 2, and for the descent and each half of
 * phase 2 (move1, move2) the sleeping grains, the mean number
 * of awake grains per step (CPU ns per awake grain-step) and the rebuilds by
 * kind. Under valgrind --tool=callgrind each phase is dumped on its own
 * (instruction counts do not depend on the machine's load).
 * PLOUGH_MODEL=FILE.json replaces the built-in model (materials, dt, sleep,
 * walls, ...) by a dem_server section, e.g. a scene's `processes.soil` with
 * "dt" added (its "particles" is ignored: the grains are BED.h5's; THREADS,
 * SLEEP and L are then not used): a scene's own laws with a mesh moved
 * through its bed (bench/tire_soil/plough_tread.py). */
#include "dem_server/dem_internal.h"

#include <math.h>
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#if defined(__has_include)
#if __has_include(<valgrind/callgrind.h>)
#include <valgrind/callgrind.h>
#endif
#endif
#ifndef CALLGRIND_DUMP_STATS_AT
#define CALLGRIND_DUMP_STATS_AT(name) ((void)(name))
#endif

static double cpu_now(void) {
  struct timespec ts;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

/* What one phase cost: rebuilds by kind since the last report, mean awake grains. */
typedef struct phase_count {
  long long rebuilds, full, wake, steps;
  double awake;
} phase_count;

static void phase_report(const char *name, long steps, double wall, double cpu, const dem_state *s, phase_count *pc) {
  const struct dem_work *w = s->work;
  const long long reb = s->rebuilds - pc->rebuilds, full = w->full_rebuilds - pc->full;
  const long long wake = w->wake_rebuilds - pc->wake;
  const double awake = pc->steps ? pc->awake / (double)pc->steps : (double)s->n;
  printf("%s %ld steps: %.3f s wall %.3f s cpu, %lld rebuilds, %lld contacts, %lld sleeping\n", name, steps, wall, cpu,
         reb, (long long)s->contacts, (long long)s->sleeping);
  printf("%s: mean awake %.0f of %d grains, %.1f ns cpu per awake grain-step; rebuilds full %lld, wake %lld, "
         "partial %lld\n", name, awake, s->n, steps ? 1e9 * cpu / (awake * (double)steps) : 0.0, full, wake,
         reb - full - wake);
  *pc = (phase_count){s->rebuilds, w->full_rebuilds, w->wake_rebuilds, 0, 0};
}

static int read_mesh(const char *path, double *c0, int *nn, double **x, int *nt, int32_t **tri) {
  FILE *f = fopen(path, "r");
  if (!f || fscanf(f, " centre %lf %lf %lf", &c0[0], &c0[1], &c0[2]) != 3 || fscanf(f, " nodes %d", nn) != 1 ||
      *nn <= 0)
    return -1;
  *x = malloc(sizeof(double) * 3 * (size_t)*nn);
  for (int i = 0; i < 3 * *nn; i++)
    if (fscanf(f, "%lf", &(*x)[i]) != 1) return -1;
  if (fscanf(f, " triangles %d", nt) != 1 || *nt <= 0) return -1;
  *tri = malloc(sizeof(int32_t) * 3 * (size_t)*nt);
  for (int i = 0; i < 3 * *nt; i++)
    if (fscanf(f, "%d", &(*tri)[i]) != 1) return -1;
  fclose(f);
  return 0;
}

/* A dem_server section from a file (proto_json_load), its "particles"
 * replaced by one grain (the bed's grains replace it; the section must
 * still have one). */
static cJSON *read_model(const char *path, proto_err *err) {
  cJSON *j = proto_json_load(path, err);
  if (j && !cJSON_IsObject(j)) {
    proto_fail(err, "%s: not a JSON object", path);
    cJSON_Delete(j);
    return NULL;
  }
  if (j) {
    cJSON_DeleteItemFromObject(j, "particles");
    cJSON_AddItemToObject(j, "particles", cJSON_Parse("[{\"x\":[0.01,0.01,0.01],\"r\":0.001}]"));
  }
  return j;
}

/* Rigid motion: centre c0 + V t (after the descent), turned by φ about y. */
static void place(int nn, const double *x0, const double *c0, const double *c, double phi, const double *vel,
                  double omega, double *x, double *v) {
  const double cp = cos(phi), sp = sin(phi);
  for (int a = 0; a < nn; a++) {
    const double rx = x0[3 * a] - c0[0], ry = x0[3 * a + 1] - c0[1], rz = x0[3 * a + 2] - c0[2];
    const double qx = cp * rx + sp * rz, qz = -sp * rx + cp * rz; /* rotation about +y */
    x[3 * a] = c[0] + qx; x[3 * a + 1] = c[1] + ry; x[3 * a + 2] = c[2] + qz;
    v[3 * a] = vel[0] + omega * qz; v[3 * a + 1] = vel[1]; v[3 * a + 2] = vel[2] - omega * qx; /* V + ω ŷ × q */
  }
}

int main(int argc, char **argv) {
  dem_openmp_env(argv); /* short barrier spin: the machine may be shared */
  if (argc < 10) {
    fprintf(stderr, "usage: %s BED.h5 MESH.txt L NDESC VDESC NMOVE VX OMEGA THREADS [SLEEP [COUPLE [OUT.h5]]]\n", argv[0]);
    return 2;
  }
  const double L = atof(argv[3]), vdesc = atof(argv[5]), vx = atof(argv[7]), omega = atof(argv[8]);
  const char *by = strchr(argv[3], 'x'); /* "LXxLY": a rectangular box */
  const double Ly = by ? atof(by + 1) : L;
  const long ndesc = atol(argv[4]), nmove = atol(argv[6]);
  const int threads = atoi(argv[9]), couple = argc > 11 ? atoi(argv[11]) : 10;
  const double sleep = argc > 10 ? atof(argv[10]) : 0;
  char sleep_json[256] = "false";
  if (argc > 10 && argv[10][0] == '{') snprintf(sleep_json, sizeof sleep_json, "%s", argv[10]);
  else if (sleep == 1) snprintf(sleep_json, sizeof sleep_json, "true");
  else if (sleep > 0) snprintf(sleep_json, sizeof sleep_json, "{\"velocity\": %.17g}", sleep);
  char json[1280];
  snprintf(json, sizeof json,
           "{\"materials\":[{\"density\":2600,\"E\":5e6,\"nu\":0.3,\"restitution\":0.5,\"friction\":0.6}],"
           "\"threads\":%d,\"dt\":5e-5,\"skin\":0.002,\"overlap_tolerance\":0.1,\"sleep\":%s,"
           "\"walls\":[{\"type\":\"box\",\"lo\":[0,0,0],\"hi\":[%.17g,%.17g,100],\"open_top\":true}],"
           "\"particles\":[{\"x\":[0.01,0.01,0.01],\"r\":0.001}]}", threads, sleep_json, L, Ly);
  proto_err err = {{0}};
  dem_model m;
  dem_state s;
  const char *model_file = getenv("PLOUGH_MODEL");
  cJSON *j = model_file ? read_model(model_file, &err) : cJSON_Parse(json);
  if (!j || dem_model_from_json(&m, j, model_file ? model_file : "bench", &err) || dem_bed_load(&m, argv[1], &err)) {
    fprintf(stderr, "%s\n", err.msg);
    return 1;
  }
  cJSON_Delete(j);
  int nn, nt;
  double *x0, c0[3];
  int32_t *tri;
  if (read_mesh(argv[2], c0, &nn, &x0, &nt, &tri)) { fprintf(stderr, "%s: bad mesh file\n", argv[2]); return 1; }
  m.rayleigh_time = dem_model_rayleigh(&m);
  if (dem_model_set_surface(&m, nn, x0, nt, tri, &err) || dem_state_init(&m, &s, 0, &err)) {
    fprintf(stderr, "%s\n", err.msg);
    return 1;
  }
  const int mesh = m.n_meshes - 1, wall = m.meshes[mesh].wall;
  printf("%d grains, wheel %d nodes %d triangles; threads: %s\n", m.n_grains, nn, nt, s.threads_why);
  double *x = malloc(sizeof(double) * 3 * nn), *v = malloc(sizeof(double) * 3 * nn);
  double t0 = omp_get_wtime(), u0 = cpu_now(), tm0 = t0, um0 = u0, sum[3] = {0, 0, 0}, sum2[3] = {0, 0, 0};
  long navg = 0;
  phase_count pc = {s.rebuilds, s.work->full_rebuilds, s.work->wake_rebuilds, 0, 0};
  const long trace = getenv("PLOUGH_TRACE") ? atol(getenv("PLOUGH_TRACE")) : 0; /* print every N steps */
  const double vd[3] = {0, 0, -vdesc}, vm[3] = {vx, 0, 0};
  for (long k = 0; k < ndesc + nmove; k++) {
    if (k < ndesc ? k == 0 : (k - ndesc) % couple == 0) {
      const double td = (k < ndesc ? k : ndesc) * s.dt, tm = (k < ndesc ? 0 : k - ndesc) * s.dt;
      const double c[3] = {c0[0] + vx * tm, c0[1], c0[2] - vdesc * td};
      place(nn, x0, c0, c, k < ndesc ? 0 : omega * tm, k < ndesc ? vd : vm, k < ndesc ? 0 : omega, x, v);
      dem_mesh_set_nodes(&m, &s, mesh, x, v);
    }
    if (k == ndesc) {
      double t1 = omp_get_wtime(), u1 = cpu_now();
      CALLGRIND_DUMP_STATS_AT("descent");
      phase_report("descent", ndesc, t1 - t0, u1 - u0, &s, &pc);
      t0 = tm0 = t1;
      u0 = um0 = u1;
    }
    if (k == ndesc + nmove / 2 && k > ndesc) { /* the first half of the move: the bed still falling asleep */
      double t1 = omp_get_wtime(), u1 = cpu_now();
      CALLGRIND_DUMP_STATS_AT("move1");
      phase_report("move1", nmove / 2, t1 - t0, u1 - u0, &s, &pc);
      t0 = t1;
      u0 = u1;
    }
    if (dem_step(&m, &s, &err)) { fprintf(stderr, "%s\n", err.msg); return 1; }
    pc.awake += s.n - s.sleeping;
    pc.steps++;
    if (trace && (k + 1) % trace == 0)
      printf("step %ld t %.5f wheel force %.6g %.6g %.6g N, %lld contacts, %lld sleeping, KE %.4g J\n", k + 1, s.t,
             s.wall_force[3 * wall], s.wall_force[3 * wall + 1], s.wall_force[3 * wall + 2], (long long)s.contacts,
             (long long)s.sleeping, s.kinetic_energy);
    if (k >= ndesc + nmove / 2) {
      for (int a = 0; a < 3; a++) {
        sum[a] += s.wall_force[3 * wall + a];
        sum2[a] += s.wall_force[3 * wall + a] * s.wall_force[3 * wall + a];
      }
      navg++;
    }
  }
  double t1 = omp_get_wtime(), u1 = cpu_now();
  CALLGRIND_DUMP_STATS_AT("move2");
  phase_report("move2", nmove - nmove / 2, t1 - t0, u1 - u0, &s, &pc);
  printf("move %ld steps: %.3f s wall %.3f s cpu, %lld rebuilds, %lld contacts, %lld sleeping\n", nmove, t1 - tm0,
         u1 - um0, (long long)s.rebuilds, (long long)s.contacts, (long long)s.sleeping);
  for (int a = 0; a < 3; a++) sum[a] /= navg > 0 ? navg : 1;
  printf("wheel force (grains on the wheel), mean over the last %ld steps: %.6g %.6g %.6g N  (sd %.4g %.4g %.4g)\n",
         navg, sum[0], sum[1], sum[2], sqrt(fmax(0, sum2[0] / navg - sum[0] * sum[0])),
         sqrt(fmax(0, sum2[1] / navg - sum[1] * sum[1])), sqrt(fmax(0, sum2[2] / navg - sum[2] * sum[2])));
  printf("threads at the end: %s\n", s.threads_why);
  if (argc > 12 && dem_bed_save(&m, &s, argv[12], &err)) fprintf(stderr, "%s\n", err.msg);
  free(x); free(v); free(x0); free(tri);
  dem_state_free(&s);
  dem_model_free(&m);
  return 0;
}
