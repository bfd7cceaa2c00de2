/* bench_lgd_bed — a large generated bed (the paper's three layers scaled to N
 * grains, default 10^6, in a box) run by liggghts_dem's engine under MPI:
 * start-up time, ms per DEM step (one step per lgd_step, as in a coupled run)
 * after some settling steps, LIGGGHTS' own split, and memory per grain (the
 * resident set of every rank). Prints one JSON object (rank 0).
 *   mpirun -np 2 build/bin/bench_lgd_bed [N] [settle_steps] [timed_steps] */
#include "liggghts_dem/lgd.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Resident set and its peak of this process (MB). */
static void rss(double *now, double *peak) {
  FILE *f = fopen("/proc/self/status", "r");
  char line[256];
  *now = *peak = 0;
  while (f && fgets(line, sizeof line, f)) {
    if (!strncmp(line, "VmRSS:", 6)) *now = atof(line + 6) / 1024;
    if (!strncmp(line, "VmHWM:", 6)) *peak = atof(line + 6) / 1024;
  }
  if (f) fclose(f);
}

/* Sum over the ranks of this rank's RSS (MB). */
static double rss_sum(void) {
  double now, peak, sum = 0;
  rss(&now, &peak);
  MPI_Reduce(&now, &sum, 1, MPI_DOUBLE, MPI_SUM, 0, MPI_COMM_WORLD);
  return sum;
}

int main(int argc, char **argv) {
  MPI_Init(&argc, &argv);
  int rank, size;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  const double n = argc > 1 ? atof(argv[1]) : 1e6;
  const int settle = argc > 2 ? atoi(argv[2]) : 400, timed = argc > 3 ? atoi(argv[3]) : 100;
  const double scale = n / 21812.0, side = sqrt(scale);
  /* the scene as liggghts_dem reads it (the bed on rank 0 only); the bed is
   * placed by dem_server's generator through its API, as the reader caps the
   * `scale` key at 10 */
  char json[1024];
  snprintf(json, sizeof json,
           "{\"materials\":[{\"density\":2600,\"E\":5e6,\"nu\":0.3,\"restitution\":0.5,\"friction\":0.6}],"
           "\"gravity\":[0,0,-9.81],\"dt\":5e-5,\"skin\":0.002,\"particles\":[{\"x\":[0.01,0.01,0.01],\"r\":0.00345}],"
           "\"walls\":[{\"type\":\"box\",\"lo\":[0,0,0],\"hi\":[%.17g,%.17g,1],\"open_top\":true}]}",
           side, side);
  proto_err err = {{0}};
  const double mem0 = rss_sum();
  double t0 = MPI_Wtime();
  cJSON *j = cJSON_Parse(json);
  dem_model m;
  if (lgd_model_from_json(&m, j, "processes.dem", MPI_COMM_WORLD, &err)) {
    fprintf(stderr, "rank %d: %s\n", rank, err.msg);
    MPI_Abort(MPI_COMM_WORLD, 2);
  }
  cJSON_Delete(j);
  if (rank == 0) {
    dem_bed_spec b;
    dem_bed_paper(&b, scale);
    b.size[0] = b.size[1] = side;
    if (dem_bed_place(&m, &b, &err)) {
      fprintf(stderr, "bed: %s\n", err.msg);
      MPI_Abort(MPI_COMM_WORLD, 2);
    }
    m.rayleigh_time = dem_model_rayleigh(&m);
  }
  MPI_Bcast(&m.rayleigh_time, 1, MPI_DOUBLE, 0, MPI_COMM_WORLD);
  const double t_model = MPI_Wtime() - t0, mem_model = rss_sum();
  lgd_sim *sim;
  char tmp[64];
  snprintf(tmp, sizeof tmp, "/tmp");
  lgd_options o = {.tmp_dir = tmp};
  t0 = MPI_Wtime();
  if (lgd_open(&sim, MPI_COMM_WORLD, &m, 0, &o, &err)) {
    fprintf(stderr, "rank %d: %s\n", rank, err.msg);
    MPI_Abort(MPI_COMM_WORLD, 2);
  }
  const double t_open = MPI_Wtime() - t0, mem_open = rss_sum();
  for (int k = 0; k < settle; k++)
    if (lgd_step(sim, lgd_dt(sim), NULL, NULL, &err)) {
      fprintf(stderr, "rank %d: %s\n", rank, err.msg);
      MPI_Abort(MPI_COMM_WORLD, 2);
    }
  const lgd_timing before = *lgd_time(sim);
  MPI_Barrier(MPI_COMM_WORLD);
  t0 = MPI_Wtime();
  for (int k = 0; k < timed; k++)
    if (lgd_step(sim, lgd_dt(sim), NULL, NULL, &err)) {
      fprintf(stderr, "rank %d: %s\n", rank, err.msg);
      MPI_Abort(MPI_COMM_WORLD, 2);
    }
  MPI_Barrier(MPI_COMM_WORLD);
  const double t_steps = MPI_Wtime() - t0;
  const lgd_timing *after = lgd_time(sim);
  const double mem_end = rss_sum();
  double peak_local, now_local, peak_max = 0;
  rss(&now_local, &peak_local);
  MPI_Reduce(&peak_local, &peak_max, 1, MPI_DOUBLE, MPI_MAX, 0, MPI_COMM_WORLD);
  if (rank == 0) {
    const double k = 1e3 / timed;
    const double *a = after->lig, *b = before.lig;
    const lgd_out *out = lgd_result(sim);
    printf("{\"ranks\": %d, \"grains\": %d, \"box_side_m\": %.4g, \"settle_steps\": %d, \"timed_steps\": %d, "
           "\"t_model_s\": %.3f, \"t_open_s\": %.3f, \"ms_per_step\": %.3f, "
           "\"ms_liggghts_loop\": %.3f, \"ms_pair\": %.3f, \"ms_neigh\": %.3f, \"ms_comm\": %.3f, "
           "\"ms_run_calls\": %.3f, \"ms_walls\": %.3f, \"ms_summary\": %.3f, \"ns_per_particle_step_per_rank\": %.2f, "
           "\"mem_start_mb\": %.1f, \"mem_model_mb\": %.1f, \"mem_open_mb\": %.1f, \"mem_end_mb\": %.1f, "
           "\"peak_rank_mb\": %.1f, \"contacts\": %.0f, \"coordination\": %.3f, \"kinetic_energy\": %.4g}\n",
           size, m.n_grains, side, settle, timed, t_model, t_open, t_steps * k,
           (a[LGD_LIG_LOOP] - b[LGD_LIG_LOOP]) * k, (a[LGD_LIG_PAIR] - b[LGD_LIG_PAIR]) * k,
           (a[LGD_LIG_NEIGH] - b[LGD_LIG_NEIGH]) * k, (a[LGD_LIG_COMM] - b[LGD_LIG_COMM]) * k,
           (after->run - before.run) * k, (after->forces - before.forces) * k,
           (after->summary - before.summary) * k, t_steps / timed / m.n_grains * size * 1e9, mem0, mem_model,
           mem_open, mem_end, peak_max, out->series[DEM_SERIES_CONTACTS],
           out->series[DEM_SERIES_COORDINATION], out->series[DEM_SERIES_KINETIC]);
  }
  lgd_close(sim);
  dem_model_free(&m);
  MPI_Finalize();
  return 0;
}
