/* fem_test.h — tiny check helpers shared by the fem tests. */
#ifndef FEM_TEST_H
#define FEM_TEST_H

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "fem_server/fem.h"

static int fem_test_failures = 0;

#define CHECK(cond, ...)                                                   \
  do {                                                                     \
    if (!(cond)) {                                                         \
      fem_test_failures++;                                                 \
      fprintf(stderr, "FAIL %s:%d: ", __FILE__, __LINE__);                 \
      fprintf(stderr, __VA_ARGS__);                                        \
      fprintf(stderr, "\n");                                               \
    }                                                                      \
  } while (0)

/* Aborts the test on a library error (prints the message). */
#define OK(call)                                                           \
  do {                                                                     \
    if ((call) != 0) {                                                     \
      fprintf(stderr, "FAIL %s:%d: %s: %s\n", __FILE__, __LINE__, #call,   \
              err.msg);                                                    \
      exit(1);                                                             \
    }                                                                      \
  } while (0)

static inline int fem_test_done(const char *name) {
  if (fem_test_failures) {
    fprintf(stderr, "%s: %d check(s) failed\n", name, fem_test_failures);
    return 1;
  }
  printf("%s: all checks passed\n", name);
  return 0;
}

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
