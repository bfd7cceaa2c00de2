/* road.kind "world" (lug_block, scenario tire_road): the heights under a
 * block are those of one road in world coordinates, whichever place it
 * lands on. A block moved by one cell sees the same heights one element
 * over; a block back at a place sees that place's heights again; the field
 * over many cells has mean ~0 and the given rms; another seed is another
 * road. */
#include <math.h>

#include "contact_block/blk.h"
#include "cosim_test.h"

enum { NX = 64, NY = 32 };

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
  return cosim_test_done("test_block_world");
}
