/* dem_test.h — helpers for the DEM tests: scenes from JSON text, checks. */
#ifndef COSIM_DEM_TEST_H
#define COSIM_DEM_TEST_H

#include "dem_server/dem.h"
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

static int g_failures;

#define CHECK(cond, ...)                                   \
  do {                                                     \
    if (!(cond)) {                                         \
      fprintf(stderr, "FAIL %s:%d: ", __FILE__, __LINE__); \
      fprintf(stderr, __VA_ARGS__);                        \
      fprintf(stderr, "\n");                               \
      g_failures++;                                        \
    }                                                      \
  } while (0)

/* |got - want| <= rel * |want|, printed either way */
static inline int check_rel(const char *what, double got, double want, double rel) {
  double e = fabs(got - want) / fabs(want);
  printf("%-48s got %.9g want %.9g rel.err %.3g (tol %.3g) %s\n", what, got, want, e, rel,
         e <= rel ? "ok" : "FAIL");
  if (!(e <= rel)) g_failures++;
  return e <= rel;
}

/* Model + state from a JSON section; exits on error (test setup bug). */
static inline void scene(const char *json, dem_model *m, dem_state *s) {
  proto_err err = {{0}};
  cJSON *j = cJSON_Parse(json);
  if (!j) { fprintf(stderr, "bad test JSON: %s\n", json); exit(2); }
  if (dem_model_from_json(m, j, "processes.dem", &err) || dem_state_init(m, s, &err)) {
    fprintf(stderr, "setup: %s\n", err.msg);
    exit(2);
  }
  cJSON_Delete(j);
}

static inline int finish(const char *name) {
  if (g_failures) fprintf(stderr, "%s: %d failure(s)\n", name, g_failures);
  else printf("%s: all passed\n", name);
  return g_failures ? 1 : 0;
}

#endif
