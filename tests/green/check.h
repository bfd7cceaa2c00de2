/* check.h — minimal assertions for the green tests. */
#ifndef GRN_TEST_CHECK_H
#define GRN_TEST_CHECK_H
#include <math.h>
#include <stdio.h>

static int check_failures = 0;
#define CHECK(cond, ...)                                                       \
  do {                                                                         \
    if (!(cond)) {                                                             \
      fprintf(stderr, "%s:%d: FAIL %s: ", __FILE__, __LINE__, #cond);          \
      fprintf(stderr, __VA_ARGS__);                                            \
      fprintf(stderr, "\n");                                                   \
      check_failures++;                                                        \
    }                                                                          \
  } while (0)
#define CHECK_REL(a, b, tol, what)                                             \
  do {                                                                         \
    double a_ = (a), b_ = (b);                                                 \
    double r_ = fabs(a_ - b_) / fmax(fabs(b_), 1e-300);                        \
    printf("%-40s %.6e vs %.6e rel %.2e (tol %.1e)\n", what, a_, b_, r_,       \
           (double)(tol));                                                     \
    CHECK(r_ <= (tol), "%s: %.9e vs %.9e", what, a_, b_);                      \
  } while (0)
#define CHECK_DONE()                                                           \
  do {                                                                         \
    if (check_failures)                                                        \
      fprintf(stderr, "%d check(s) failed\n", check_failures);                 \
    return check_failures ? 1 : 0;                                             \
  } while (0)
#endif
