/* contract.c — the coupling contract: the role table's step and done rows
 * (proto/roles.c), each of which names the coupler field it reads or fills
 * and whether replies are summed, bound once at start-up to the fields of
 * runner.h. A row that names no field, an unknown field, or a field of another
 * shape or dtype stops the run before any process starts, with a message
 * that names the row (PROTOCOL.md "Roles"). An index row ("<name>_index",
 * the sparse form of an [n, ...] row) goes with the row it indexes.
 * Pure: no sockets, no run. */
#include "runner.h"

#include <stdio.h>
#include <string.h>

/* Each field's name and shape, as the table must declare it. */
static const struct {
  const char *name;
  int ndim;
  int64_t dims[2];
} field_shape[CPL_N_FIELDS] = {
    [CPL_F_SURF_X] = {"surface.x", 2, {PROTO_DIM_NODES, 3}},
    [CPL_F_SURF_V] = {"surface.v", 2, {PROTO_DIM_NODES, 3}},
    [CPL_F_SURF_FORCE] = {"surface.force", 2, {PROTO_DIM_NODES, 3}},
    [CPL_F_RIM_R] = {"rim.R", 2, {3, 3}},
    [CPL_F_RIM_C] = {"rim.c", 1, {3}},
    [CPL_F_RIM_OMEGA] = {"rim.omega", 1, {3}},
    [CPL_F_RIM_V] = {"rim.v", 1, {3}},
    [CPL_F_ROAD_D] = {"road.d", 1, {1}},
    [CPL_F_ROAD_FORCE] = {"road.force", 1, {1}},
};

const char *cpl_field_name(cpl_field_id id) {
  return (unsigned)id < CPL_N_FIELDS ? field_shape[id].name : "?";
}

int cpl_field_parse(const char *name) {
  for (int f = 0; name && f < CPL_N_FIELDS; f++)
    if (strcmp(name, field_shape[f].name) == 0) return f;
  return -1;
}

/* "role table row fem/step 'x'" into out. */
static const char *row_name(const proto_array_spec *s, char *out, size_t cap) {
  snprintf(out, cap, "role table row %s/%s '%s'", proto_role_name(s->role),
           proto_msg_type(s->msg), s->name);
  return out;
}

/* One step/done row against its field. */
static int bind_row(const proto_array_spec *s, cpl_binding *b, proto_err *err) {
  char what[96];
  row_name(s, what, sizeof what);
  if (!s->field)
    return proto_fail(err, "%s: names no coupler field (every step and done array "
                      "reads or fills one)", what);
  const int f = cpl_field_parse(s->field);
  if (f < 0) return proto_fail(err, "%s: unknown coupler field '%s'", what, s->field);
  int same = s->dtype == PROTO_F8 && s->ndim == field_shape[f].ndim;
  for (int d = 0; same && d < s->ndim; d++) same = s->dims[d] == field_shape[f].dims[d];
  if (!same)
    return proto_fail(err, "%s: its dtype/shape does not match the coupler field '%s' "
                      "(f8, %d dims)", what, s->field, field_shape[f].ndim);
  if (s->sum && s->msg != PROTO_MSG_DONE)
    return proto_fail(err, "%s: only replies (done) can be summed", what);
  *b = (cpl_binding){s->role, s->msg, s->name, (cpl_field_id)f, s->sum, s, NULL};
  return 0;
}

/* An index row (PROTO_WHEN_INDEX, "<name>_index"): i4 [k], bound to the
 * same field as the [n, ...] row it indexes, of the same role and message,
 * not summed; the binding of that row takes it (b->index). */
static int bind_index(const proto_array_spec *s, cpl_contract *c, proto_err *err) {
  char what[96], want[PROTO_NAME_LEN + 8];
  row_name(s, what, sizeof what);
  if (s->dtype != PROTO_I4 || s->ndim != 1 || s->dims[0] != PROTO_DIM_ROWS || s->sum)
    return proto_fail(err, "%s: an index row is i4 [k] and not summed", what);
  for (int b = 0; b < c->n; b++) {
    cpl_binding *bd = &c->b[b];
    snprintf(want, sizeof want, "%s%s", bd->array, PROTO_SUFFIX_INDEX);
    if (bd->role != s->role || bd->msg != s->msg || strcmp(want, s->name) != 0) continue;
    if (!s->field || strcmp(s->field, cpl_field_name(bd->field)) != 0 ||
        bd->spec->dims[0] != PROTO_DIM_NODES)
      return proto_fail(err, "%s: must name the field of its [n, ...] row '%s' ('%s')",
                        what, bd->array, cpl_field_name(bd->field));
    bd->index = s;
    return 0;
  }
  return proto_fail(err, "%s: no earlier row of its role and message that it indexes",
                    what);
}

/* (role table rows) -> (bindings row -> field) */
int cpl_contract_build(cpl_contract *c, const proto_array_spec *t, int n, proto_err *err) {
  char what[96];
  int used[CPL_N_FIELDS] = {0};
  c->n = 0;
  for (int i = 0; i < n; i++) {
    const proto_array_spec *s = &t[i];
    if (s->msg != PROTO_MSG_STEP && s->msg != PROTO_MSG_DONE) {
      if (s->field || s->sum)
        return proto_fail(err, "%s: only step and done arrays bind a coupler field",
                          row_name(s, what, sizeof what));
      continue;
    }
    if (s->when == PROTO_WHEN_INDEX) {
      if (bind_index(s, c, err) < 0) return -1;
      continue;
    }
    if (c->n == CPL_MAX_BINDINGS)
      return proto_fail(err, "%s: more than %d step/done rows",
                        row_name(s, what, sizeof what), CPL_MAX_BINDINGS);
    if (bind_row(s, &c->b[c->n], err) < 0) return -1;
    used[c->b[c->n++].field] = 1;
  }
  for (int f = 0; f < CPL_N_FIELDS; f++)
    if (!used[f])
      return proto_fail(err, "coupler field '%s': no role table row reads or fills it",
                        field_shape[f].name);
  return 0;
}
