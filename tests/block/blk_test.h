/* blk_test.h — the block tests' shared checks (tests/common/cosim_test.h) and
 * their small scene: a rough road on stiffening roughness springs and a
 * synthetic (labelled) dynamic layer. */
#ifndef BLK_TEST_H
#define BLK_TEST_H
#include "contact_block/blk.h"
#include "cosim_test.h"

static inline int blk_test_scene(blk_model *m, int n, int Q, int point_sampling, proto_err *err) {
  if (blk_model_init(m, n, n, 1e-3, 1e-3, err)) return -1;
  if (blk_road_random(m, 1e-5, 3, err)) return -1;
  if (blk_springs_stiffening(m, 2e5, 2e-5, 0.5, 7, 5e-4, 33, err)) return -1;
  blk_synth sy = {.E = 25e6, .nu = 0.49, .rate = 51200, .Q = Q, .f_mode = 2000,
                  .zeta = 0.1, .beta = 0.25, .tau_fast = 2e-5,
                  .point_sampling = point_sampling};
  if (blk_green_synthetic(m, &sy, err)) return -1;
  m->solver.method = BLK_NR_DUAL;
  m->solver.max_iter = 50;
  return 0;
}
#endif
