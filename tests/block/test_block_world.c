/* road.kind "world" (lug_block, scenario tire_road): the heights under a
 * block are those of one road in world coordinates, whichever place it
 * lands on. A block moved by one cell sees the same heights one element
 * over; a block back at a place sees that place's heights again; the field
 * over many cells has mean ~0 and the given rms; another seed is another
 * road. From a surface file (road.file): the map's own heights less their
 * mean when the pitches agree, repeated with its period; at another pitch a
 * long cosine is interpolated within its bilinear error bound. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <unistd.h>

#include "green/green.h"

#include "contact_block/blk.h"
#include "cosim_test.h"

enum { NX = 64, NY = 32 };

/* A map of MX x MY points at pitch (pdx, pdy): z = A cos(2 pi i / MX) + 0.1 A sin(2 pi j / MY) + c. */
static void write_map(const char *path, int MX, int MY, double pdx, double pdy, double A, double c) {
  proto_err err = {0};
  grn_surface sf = {MX, MY, pdx, pdy, malloc(sizeof(double) * MX * MY)};
  for (int j = 0; j < MY; j++)
    for (int i = 0; i < MX; i++)
      sf.z[j * MX + i] = A * cos(2 * M_PI * i / MX) + 0.1 * A * sin(2 * M_PI * j / MY) + c;
  OK(grn_surface_write_h5(path, &sf, NULL, &err));
  free(sf.z);
}

static void map_road(void) {
  proto_err err = {0};
  char path[256];
  snprintf(path, sizeof path, "/tmp/test_block_world_%d.h5", (int)getpid());
  const double dx = 1e-3, dy = 2e-3, A = 3e-5, c = 7e-5;
  enum { MX = 48, MY = 20 }; /* the map is shorter than the block: it repeats under it */
  blk_model a;
  OK(blk_model_init(&a, NX, NY, dx, dy, &err));
  write_map(path, MX, MY, dx, dy, A, c);
  OK(blk_road_world_map(&a, path, &err));
  /* block centred at world (0, 0): element (i, j) lies in world cell (i - NX/2, j - NY/2) */
  double worst = 0;
  for (int j = 0; j < NY; j++)
    for (int i = 0; i < NX; i++) {
      const int mi = ((i - NX / 2) % MX + MX) % MX, mj = ((j - NY / 2) % MY + MY) % MY;
      const double want = A * cos(2 * M_PI * mi / MX) + 0.1 * A * sin(2 * M_PI * mj / MY);
      worst = fmax(worst, fabs(a.z_road[j * NX + i] - want));
    }
  CHECK(worst < 1e-18, "same pitch: the map's heights less their mean (worst %.2e m)", worst);
  double first[NX * NY];
  for (int e = 0; e < a.M; e++) first[e] = a.z_road[e];
  blk_road_world(&a, MX * dx * 3, -MY * dy * 2);
  int same = 1;
  for (int e = 0; e < a.M; e++) same &= a.z_road[e] == first[e];
  CHECK(same, "whole periods away: the same heights (the map repeats)");
  /* another pitch: the map at 4 dx, the block's cells sample it between its points */
  write_map(path, MX, MY, 4 * dx, 2 * dy, A, c);
  OK(blk_road_world_map(&a, path, &err));
  blk_road_world(&a, 0.05, 0.01);
  worst = 0;
  for (int j = 0; j < NY; j++)
    for (int i = 0; i < NX; i++) {
      const double xw = 0.05 + (i + 0.5 - 0.5 * NX) * dx, yw = 0.01 + (j + 0.5 - 0.5 * NY) * dy;
      const double xc = (floor(xw / dx) + 0.5) * dx, yc = (floor(yw / dy) + 0.5) * dy;
      const double u = xc / (4 * dx) - 0.5, v = yc / (2 * dy) - 0.5; /* map points at (k + 1/2) pitch */
      const double want = A * cos(2 * M_PI * u / MX) + 0.1 * A * sin(2 * M_PI * v / MY);
      worst = fmax(worst, fabs(a.z_road[j * NX + i] - want));
    }
  /* bilinear error <= h^2/8 max|z''| per direction */
  const double bound = A * pow(2 * M_PI / MX, 2) / 8 + 0.1 * A * pow(2 * M_PI / MY, 2) / 8;
  CHECK(worst <= bound, "another pitch: within the bilinear bound (%.2e <= %.2e m)", worst, bound);
  CHECK(blk_road_world_map(&a, "/nonexistent/road.h5", &err) != 0 && err.msg[0],
        "a missing file is refused: %s", err.msg);
  remove(path);
  blk_model_free(&a);
}

int main(void) {
  blk_model a, b;
  proto_err err = {0};
  const double dx = 1e-3, dy = 2e-3, rms = 3e-5;
  OK(blk_model_init(&a, NX, NY, dx, dy, &err));
  OK(blk_model_init(&b, NX, NY, dx, dy, &err));
  a.road_world = b.road_world = 1;
  a.road_rms = b.road_rms = rms;
  a.road_seed = b.road_seed = 7;
  blk_road_world(&a, 0.1234, -0.02);
  blk_road_world(&b, 0.1234 + dx, -0.02 + dy);
  int shifted = 1;
  for (int j = 0; j + 1 < NY; j++)
    for (int i = 0; i + 1 < NX; i++)
      shifted &= b.z_road[j * NX + i] == a.z_road[(j + 1) * NX + i + 1];
  CHECK(shifted, "one cell over: the same heights one element over");
  double first = a.z_road[5];
  blk_road_world(&a, 3.0, 0.5);
  CHECK(a.z_road[5] != first, "another place, other heights");
  blk_road_world(&a, 0.1234, -0.02);
  CHECK(a.z_road[5] == first, "back at a place: its heights again");
  double sum = 0, sq = 0;
  const int n = 40;
  for (int k = 0; k < n; k++) { /* 40 patches far apart: 81 920 cells */
    blk_road_world(&a, 1.0 * k, 0.0);
    for (int e = 0; e < a.M; e++) sum += a.z_road[e], sq += a.z_road[e] * a.z_road[e];
  }
  const double N = (double)n * a.M, mean = sum / N, sd = sqrt(sq / N - mean * mean);
  CHECK(fabs(mean) < 4 * rms / sqrt(N) && fabs(sd / rms - 1) < 0.02,
        "mean %.3g (4 sigma %.3g), rms %.4g of %.4g", mean, 4 * rms / sqrt(N), sd, rms);
  b.road_seed = 8;
  blk_road_world(&b, 0.1234, -0.02);
  blk_road_world(&a, 0.1234, -0.02);
  CHECK(b.z_road[5] != a.z_road[5], "another seed, another road");
  blk_model_free(&a);
  blk_model_free(&b);
  map_road();
  return cosim_test_done("test_block_world");
}
