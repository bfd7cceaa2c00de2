/* ter_test.h — check helpers of the terra tests. */
#ifndef TER_TEST_H
#define TER_TEST_H

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "terra/terra.h"

static int ter_failures = 0;

/* CHECK(condition, printf-style message) */
#define CHECK(cond, ...)                                                   \
  do {                                                                     \
    if (!(cond)) {                                                         \
      ter_failures++;                                                      \
      fprintf(stderr, "FAIL %s:%d: ", __FILE__, __LINE__);                 \
      fprintf(stderr, __VA_ARGS__);                                        \
      fputc('\n', stderr);                                                 \
    }                                                                      \
  } while (0)

/* Stops the test when a library call fails (err must be in scope). */
#define OK(call)                                                           \
  do {                                                                     \
    if ((call) != 0) {                                                     \
      fprintf(stderr, "FAIL %s:%d: %s: %s\n", __FILE__, __LINE__, #call,   \
              err.msg);                                                    \
      exit(1);                                                             \
    }                                                                      \
  } while (0)

/* A failing call whose message contains `needle`. */
#define FAILS_WITH(call, needle)                                           \
  do {                                                                     \
    err.msg[0] = 0;                                                        \
    int rc_ = (call);                                                      \
    CHECK(rc_ != 0 && strstr(err.msg, needle), "%s: expected an error with '%s', got rc %d '%s'", \
          #call, needle, rc_, err.msg);                                    \
  } while (0)

static inline int ter_test_done(const char *name) {
  if (ter_failures) {
    fprintf(stderr, "%s: %d check(s) failed\n", name, ter_failures);
    return 1;
  }
  printf("%s: all checks passed\n", name);
  return 0;
}

#endif
