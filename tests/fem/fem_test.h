/* fem_test.h — the fem tests' shared checks (tests/common/cosim_test.h) and
 * mesh helpers. */
#ifndef FEM_TEST_H
#define FEM_TEST_H

#include <math.h>

#include "cosim_test.h"
#include "fem_server/fem.h"

/* Node nearest to p. */
static inline int32_t fem_test_node_at(const fem_mesh *m, double x, double y, double z) {
  int32_t best = -1;
  double bd = INFINITY;
  for (int32_t i = 0; i < m->n_nodes; i++) {
    double d = hypot(hypot(m->x[3 * i] - x, m->x[3 * i + 1] - y), m->x[3 * i + 2] - z);
    if (d < bd) { bd = d; best = i; }
  }
  return best;
}

#endif
