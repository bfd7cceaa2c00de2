/* cosim_test.h — the check helpers every C test shares (one owner): CHECK with
 * an optional printf-style message, near-equality checks printed either way,
 * library-call checks that need `proto_err err` in scope, and the summary that
 * decides the exit code. A failure names file:line, the condition and the
 * values. Part-specific builders live in tests/<part>/<part>_test.h, which
 * include this header. */
#ifndef COSIM_TEST_H
#define COSIM_TEST_H

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Failed checks so far in this test program. */
static int cosim_test_failures = 0;
/* Nonzero: this process does not decide checks (e.g. MPI ranks other than 0,
 * which hold no results); CHECKs are skipped without evaluating. */
static int cosim_test_mute = 0;

#if defined(__GNUC__)
__attribute__((format(printf, 4, 5)))
#endif
static inline void cosim_test_fail_(const char *file, int line, const char *cond,
                                    const char *fmt, ...) {
  cosim_test_failures++;
  fprintf(stderr, "FAIL %s:%d: %s%s", file, line, cond, strcmp(fmt, " ") ? ":" : "");
  va_list ap;
  va_start(ap, fmt);
  vfprintf(stderr, fmt, ap);
  va_end(ap);
  fputc('\n', stderr);
}

/* CHECK(cond) or CHECK(cond, "printf format", args...): counts and reports a
 * failure, the test goes on. */
#define CHECK(cond, ...)                                                        \
  do {                                                                          \
    if (!cosim_test_mute && !(cond))                                            \
      cosim_test_fail_(__FILE__, __LINE__, #cond, " " __VA_ARGS__);             \
  } while (0)

/* The message of a failed call (err.msg) must contain `needle`. */
#define CHECK_MSG(err, needle)                                                  \
  do {                                                                          \
    if (!cosim_test_mute && !strstr((err).msg, (needle)))                       \
      cosim_test_fail_(__FILE__, __LINE__, "message", " '%s' lacks '%s'",       \
                       (err).msg, (needle));                                    \
  } while (0)

/* `call` must fail (non-zero) with a message containing `needle`; needs
 * `proto_err err` in scope. */
#define FAILS_WITH(call, needle)                                                \
  do {                                                                          \
    err.msg[0] = 0;                                                             \
    int rc_ = (call);                                                           \
    CHECK(rc_ != 0 && strstr(err.msg, needle),                                  \
          "%s: expected an error with '%s', got rc %d '%s'", #call, needle, rc_,  \
          err.msg);                                                             \
  } while (0)

/* A library call that must succeed for the test to go on (a set-up step):
 * stops the test with its message. Needs `proto_err err` in scope. */
#define OK(call)                                                                \
  do {                                                                          \
    if ((call) != 0) {                                                          \
      fprintf(stderr, "FAIL %s:%d: %s: %s\n", __FILE__, __LINE__, #call,        \
              err.msg);                                                         \
      exit(1);                                                                  \
    }                                                                           \
  } while (0)

static inline int cosim_check_rel_(const char *file, int line, const char *what, double got,
                                   double want, double tol) {
  if (cosim_test_mute) return 1;
  const double e = fabs(got - want) / fmax(fabs(want), 1e-300);
  const int ok = e <= tol; /* NaN fails */
  printf("%-48s got %.9g want %.9g rel.err %.3g (tol %.3g) %s\n", what, got, want, e, tol,
         ok ? "ok" : "FAIL");
  if (!ok)
    cosim_test_fail_(file, line, what, " got %.17g want %.17g, rel.err %.3g > tol %.3g", got,
                     want, e, tol);
  return ok;
}

static inline int cosim_check_small_(const char *file, int line, const char *what, double value,
                                     double tol) {
  if (cosim_test_mute) return 1;
  const int ok = value <= tol; /* NaN fails */
  printf("%-60s %.3g (tol %.3g) %s\n", what, value, tol, ok ? "ok" : "FAIL");
  if (!ok) cosim_test_fail_(file, line, what, " %.17g > tol %.3g", value, tol);
  return ok;
}

/* |got − want| <= tol·|want|, printed either way; returns whether it held. */
#define CHECK_REL(what, got, want, tol) \
  cosim_check_rel_(__FILE__, __LINE__, (what), (got), (want), (tol))
/* value <= tol (an error measure), printed either way; returns whether it held. */
#define CHECK_SMALL(what, value, tol) \
  cosim_check_small_(__FILE__, __LINE__, (what), (value), (tol))

/* The summary line and the exit code of the test program: return it from main. */
static inline int cosim_test_done(const char *name) {
  if (cosim_test_failures) {
    fprintf(stderr, "%s: %d check(s) failed\n", name, cosim_test_failures);
    return 1;
  }
  printf("%s: all checks passed\n", name);
  return 0;
}

#endif
