/* check.h — tiny assertion helpers for the proto/coupler unit tests. */
#ifndef COSIM_TEST_CHECK_H
#define COSIM_TEST_CHECK_H
#include <stdio.h>
#include <string.h>

static int check_failures = 0;
#define CHECK(cond)                                                        \
  do {                                                                     \
    if (!(cond)) {                                                         \
      fprintf(stderr, "%s:%d: CHECK failed: %s\n", __FILE__, __LINE__,     \
              #cond);                                                      \
      check_failures++;                                                    \
    }                                                                      \
  } while (0)
/* An error message must contain `needle`. */
#define CHECK_MSG(err, needle)                                             \
  do {                                                                     \
    if (!strstr((err).msg, (needle))) {                                    \
      fprintf(stderr, "%s:%d: message '%s' lacks '%s'\n", __FILE__,        \
              __LINE__, (err).msg, (needle));                              \
      check_failures++;                                                    \
    }                                                                      \
  } while (0)
#define CHECK_DONE()                                                       \
  do {                                                                     \
    if (check_failures) {                                                  \
      fprintf(stderr, "%d check(s) failed\n", check_failures);             \
      return 1;                                                            \
    }                                                                      \
    printf("all checks passed\n");                                         \
    return 0;                                                              \
  } while (0)
#endif
