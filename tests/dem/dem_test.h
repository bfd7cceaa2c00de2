/* dem_test.h — the DEM tests' shared checks (tests/common/cosim_test.h) and
 * scenes from JSON text. */
#ifndef COSIM_DEM_TEST_H
#define COSIM_DEM_TEST_H

#include "cosim_test.h"
#include "dem_server/dem.h"

#include <math.h>
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

/* A scene that must be refused (by the model or the state's init), with an
 * error containing want; prints what it said. */
static inline void expect_error(const char *name, const char *json, const char *want) {
  dem_model m;
  dem_state s;
  proto_err err = {{0}};
  cJSON *j = cJSON_Parse(json);
  if (!j) { fprintf(stderr, "bad JSON in %s\n", name); exit(2); }
  int rc = dem_model_from_json(&m, j, "processes.dem", &err);
  if (rc == 0) {
    rc = dem_state_init(&m, &s, 0, &err);
    if (rc == 0) dem_state_free(&s);
    dem_model_free(&m);
  }
  cJSON_Delete(j);
  printf("%-28s -> %s\n", name, rc ? err.msg : "(accepted)");
  CHECK(rc != 0, "%s: accepted", name);
  CHECK(rc == 0 || strstr(err.msg, want), "%s: message lacks '%s'", name, want);
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

/* n steps of dem_step; exits on an error (the tests that call it expect none). */
static inline void dem_test_steps(const dem_model *m, dem_state *s, int n) {
  proto_err err;
  for (int k = 0; k < n; k++)
    if (dem_step(m, s, &err)) { fprintf(stderr, "%s\n", err.msg); exit(1); }
}

/* Grains of radius r on two layers (nl x nl, and (nl-1) x (nl-1) in the hollows
 * above) resting on the floor: appended to json at len as the "particles" list's
 * entries; returns the new length. s is the lower layer's spacing, h the upper
 * layer's height above it. */
static inline int dem_test_two_layers(char *json, int len, size_t cap, int nl, double r, double s, double h) {
  for (int layer = 0; layer < 2; layer++)
    for (int a = 0; a < nl - layer; a++)
      for (int b = 0; b < nl - layer; b++)
        len += snprintf(json + len, cap - (size_t)len, "%s{\"x\":[%.17g,%.17g,%.17g],\"r\":%g}",
                        len && json[len - 1] == '[' ? "" : ",", 0.005 + s * (a + 0.5 * layer),
                        0.005 + s * (b + 0.5 * layer), r + 1e-5 + layer * (h + 1e-5), r);
  return len;
}

/* The sparse exchange's reach box from its definition (dem_server/dem_nodeset.c):
 * every grain's sphere box, asleep ones included, grown by skin + 2 v_max dt,
 * by a sweep of its own (the dem takes them from its step's sweeps); with
 * check, *outside says whether a sphere lies outside that box. */
static inline void dem_test_reach_by_hand(const dem_model *m, const dem_state *s, double dt, double box[6],
                                          const double *check, int *outside) {
  double v2 = 0;
  int out = 0;
  for (int d = 0; d < 3; d++) box[d] = INFINITY, box[3 + d] = -INFINITY;
  for (int i = 0; i < s->n; i++) {
    const double *x = &s->x[3 * i], *v = &s->v[3 * i], r = s->radius[i];
    const double w2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
    v2 = w2 > v2 ? w2 : v2;
    for (int d = 0; d < 3; d++) {
      box[d] = x[d] - r < box[d] ? x[d] - r : box[d];
      box[3 + d] = x[d] + r > box[3 + d] ? x[d] + r : box[3 + d];
      if (check) out |= !(x[d] - r >= check[d] && x[d] + r <= check[3 + d]);
    }
  }
  const double delta = m->skin + 2 * sqrt(v2) * dt;
  for (int d = 0; d < 3; d++) box[d] -= delta, box[3 + d] += delta;
  if (outside) *outside = out;
}

#endif
