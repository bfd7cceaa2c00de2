/* dem_test.h — the DEM tests' shared checks (tests/common/cosim_test.h) and
 * scenes from JSON text. */
#ifndef COSIM_DEM_TEST_H
#define COSIM_DEM_TEST_H

#include "cosim_test.h"
#include "dem_server/dem.h"

#include <string.h>

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

/* Every array of a's and b's state export (dem_state_export) equal, bit for
 * bit (names, shapes, bytes); what names the first that is not, or the count. */
static inline int dem_test_same_state(const dem_model *ma, const dem_state *a, const dem_model *mb,
                                      const dem_state *b, char *what, size_t cap) {
  proto_msg ea = {0}, eb = {0};
  proto_err err;
  proto_msg_reset(&ea, "a", "state", 0, 0);
  proto_msg_reset(&eb, "b", "state", 0, 0);
  int same = dem_state_export(ma, a, &ea, &err) == 0 && dem_state_export(mb, b, &eb, &err) == 0 &&
             ea.narrays == eb.narrays;
  snprintf(what, cap, same ? "" : "the array sets");
  for (int k = 0; k < ea.narrays && same; k++) {
    const proto_array *x = &ea.arrays[k], *y = &eb.arrays[k];
    same = !strcmp(x->name, y->name) && x->nbytes == y->nbytes && x->ndim == y->ndim &&
           !memcmp(x->shape, y->shape, sizeof x->shape) &&
           (x->nbytes == 0 || !memcmp(x->data, y->data, x->nbytes)); /* empty: no data pointer */
    if (!same) snprintf(what, cap, "%s", x->name);
  }
  if (same) snprintf(what, cap, "%d arrays", ea.narrays);
  proto_msg_free(&ea);
  proto_msg_free(&eb);
  return same;
}

#endif
