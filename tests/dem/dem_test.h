/* dem_test.h — the DEM tests' shared checks (tests/common/cosim_test.h) and
 * scenes from JSON text. */
#ifndef COSIM_DEM_TEST_H
#define COSIM_DEM_TEST_H

#include "cosim_test.h"
#include "dem_server/dem.h"

/* Model + state from a JSON section; exits on error (test setup bug). */
static inline void scene(const char *json, dem_model *m, dem_state *s) {
  proto_err err = {{0}};
  cJSON *j = cJSON_Parse(json);
  if (!j) { fprintf(stderr, "bad test JSON: %s\n", json); exit(2); }
  if (dem_model_from_json(m, j, "processes.dem", &err) || dem_state_init(m, s, 0, &err)) {
    fprintf(stderr, "setup: %s\n", err.msg);
    exit(2);
  }
  cJSON_Delete(j);
}

#endif
