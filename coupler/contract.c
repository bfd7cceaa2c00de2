/* contract.c — the coupling contract: the role table's step and done rows
 * (proto/roles.c), each of which names the coupler field it reads or fills
 * and whether replies are summed, bound once at start-up to the fields of
 * runner.h. A row that names no field, an unknown field, or a field of another
 * shape or dtype stops the run before any process starts, with a message
 * that names the row (PROTOCOL.md "Roles"). An index row ("<name>_index",
 * the sparse form of an [n, ...] row) goes with the row it indexes. The
 * contract also holds the fields themselves (the shipped ones, and those a
 * new role's contract declares) and the order of the step (which role or
 * coupler action runs in which stage): a new role is its rows here, its
 * field, and its row in the order (CONTRIBUTING.md "Adding a role").
 * Pure: no sockets, no run. */
#include "runner.h"

#include <stdio.h>
#include <string.h>

/* The shipped fields' names and shapes, as the role table must declare them. */
static const cpl_field_spec shipped_fields[CPL_N_FIELDS] = {
    [CPL_F_SURF_X] = {"surface.x", 2, {PROTO_DIM_NODES, 3}, 0},
    [CPL_F_SURF_V] = {"surface.v", 2, {PROTO_DIM_NODES, 3}, 0},
    [CPL_F_SURF_FORCE] = {"surface.force", 2, {PROTO_DIM_NODES, 3}, 0},
    [CPL_F_RIM_R] = {"rim.R", 2, {3, 3}, 0},
    [CPL_F_RIM_C] = {"rim.c", 1, {3}, 0},
    [CPL_F_RIM_OMEGA] = {"rim.omega", 1, {3}, 0},
    [CPL_F_RIM_V] = {"rim.v", 1, {3}, 0},
    [CPL_F_ROAD_D] = {"road.d", 1, {1}, 0},
    [CPL_F_ROAD_FORCE] = {"road.force", 1, {1}, 0},
    [CPL_F_LUG_D] = {"lug.d", 1, {1}, 1},
    [CPL_F_LUG_FORCE] = {"lug.force", 1, {1}, 1},
    [CPL_F_LUG_COP] = {"lug.cop", 1, {2}, 1},
    [CPL_F_LUG_ORIGIN] = {"lug.origin", 1, {2}, 1},
    [CPL_F_LUG_BASE] = {"lug.base", 1, {PROTO_DIM_CELLS}, 1},
    [CPL_F_LUG_CELL_FORCE] = {"lug.cell_force", 1, {PROTO_DIM_CELLS}, 1},
};

/* The serial step (seed 000's staggered scheme, PROTOCOL.md "Schedule"): the
 * grains, or the lug blocks (their lugs chosen first), on the surface of
 * t_{k-1}; their forces onto the tread's nodes and the rim moved with their
 * load; the tread with their forces; the blocks on the road of t_k. An
 * action does nothing in a scene without its processes. */
static const cpl_stage_row shipped_stages[] = {
    {0, -1, CPL_ACT_LUG},       {0, PROTO_ROLE_DEM, CPL_ACT_NONE},
    {0, PROTO_ROLE_LUG, CPL_ACT_NONE}, {1, -1, CPL_ACT_LUG_FORCE},
    {1, -1, CPL_ACT_RIM},       {1, PROTO_ROLE_FEM, CPL_ACT_NONE},
    {2, -1, CPL_ACT_ROAD},      {2, PROTO_ROLE_BLOCK, CPL_ACT_NONE}};

const cpl_stage_row *cpl_contract_stages(int *n) {
  *n = (int)(sizeof shipped_stages / sizeof shipped_stages[0]);
  return shipped_stages;
}

int cpl_field_parse(const char *name) {
  for (int f = 0; name && f < CPL_N_FIELDS; f++)
    if (strcmp(name, shipped_fields[f].name) == 0) return f;
  return -1;
}

static int field_of(const cpl_contract *c, const char *name) {
  for (int f = 0; name && f < c->nfields; f++)
    if (strcmp(name, c->field[f].name) == 0) return f;
  return -1;
}

/* "role table row fem/step 'x'" into out. */
static const char *row_name(const proto_array_spec *s, char *out, size_t cap) {
  snprintf(out, cap, "role table row %s/%s '%s'", proto_role_name(s->role),
           proto_msg_type(s->msg), s->name);
  return out;
}

/* One step/done row against its field. */
static int bind_row(const cpl_contract *c, const proto_array_spec *s, cpl_binding *b,
                    proto_err *err) {
  char what[96];
  row_name(s, what, sizeof what);
  if (!s->field)
    return proto_fail(err, "%s: names no coupler field (every step and done array "
                      "reads or fills one)", what);
  const int f = field_of(c, s->field);
  if (f < 0) return proto_fail(err, "%s: unknown coupler field '%s'", what, s->field);
  int same = s->dtype == PROTO_F8 && s->ndim == c->field[f].ndim;
  for (int d = 0; same && d < s->ndim; d++) same = s->dims[d] == c->field[f].dims[d];
  if (!same)
    return proto_fail(err, "%s: its dtype/shape does not match the coupler field '%s' "
                      "(f8, %d dims)", what, s->field, c->field[f].ndim);
  if (s->sum && s->msg != PROTO_MSG_DONE)
    return proto_fail(err, "%s: only replies (done) can be summed", what);
  if (c->field[f].per_process && s->sum)
    return proto_fail(err, "%s: the field '%s' holds one row per process: not summed", what,
                      s->field);
  *b = (cpl_binding){s->role, s->msg, s->name, f, s->sum, s, NULL};
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
    if (!s->field || strcmp(s->field, c->field[bd->field].name) != 0 ||
        bd->spec->dims[0] != PROTO_DIM_NODES)
      return proto_fail(err, "%s: must name the field of its [n, ...] row '%s' ('%s')",
                        what, bd->array, c->field[bd->field].name);
    bd->index = s;
    return 0;
  }
  return proto_fail(err, "%s: no earlier row of its role and message that it indexes",
                    what);
}

/* The order of the step: each row a coupler action or a role the
 * contract knows (it has rows), stages from 0 in order. */
static int take_stages(cpl_contract *c, const cpl_stage_row *st, int n, proto_err *err) {
  if (n < 1 || n > CPL_MAX_STAGE_ROWS)
    return proto_fail(err, "the step's order: %d rows (1 to %d)", n, CPL_MAX_STAGE_ROWS);
  for (int i = 0; i < n; i++) {
    int known = st[i].role < 0 ? st[i].action != CPL_ACT_NONE : 0;
    for (int b = 0; b < c->n && !known; b++) known = (int)c->b[b].role == st[i].role;
    if (!known || st[i].role >= CPL_MAX_ROLES || st[i].stage < (i ? st[i - 1].stage : 0) ||
        st[i].stage > (i ? st[i - 1].stage + 1 : 0))
      return proto_fail(err, "the step's order, row %d (stage %d, role %d): a role with "
                        "rows in the table or a coupler action, stages 0, 1, ... in order",
                        i, st[i].stage, st[i].role);
    c->stage[i] = st[i];
  }
  c->nstages = n;
  for (int b = 0; b < c->n; b++) { /* a role with rows runs somewhere in the step */
    int placed = 0;
    for (int i = 0; i < n && !placed; i++) placed = st[i].role == (int)c->b[b].role;
    if (!placed)
      return proto_fail(err, "role table row %s/%s '%s': its role (%d) has no place in the "
                        "step's order", proto_role_name(c->b[b].role),
                        proto_msg_type(c->b[b].msg), c->b[b].array, (int)c->b[b].role);
  }
  return 0;
}

/* (role table rows, fields, the step's order) -> (bindings row -> field) */
int cpl_contract_build_with(cpl_contract *c, const proto_array_spec *t, int n,
                            const cpl_field_spec *more, int nmore,
                            const cpl_stage_row *stages, int nstages, proto_err *err) {
  char what[96];
  int used[CPL_MAX_FIELDS] = {0};
  c->n = 0;
  if (nmore < 0 || nmore > CPL_MAX_FIELDS - CPL_N_FIELDS)
    return proto_fail(err, "%d further coupler fields (at most %d)", nmore,
                      CPL_MAX_FIELDS - CPL_N_FIELDS);
  c->nfields = CPL_N_FIELDS;
  memcpy(c->field, shipped_fields, sizeof shipped_fields);
  for (int f = 0; f < CPL_MAX_FIELDS; f++) c->field_role[f] = -1;
  for (int f = 0; f < nmore; f++) {
    const cpl_field_spec *m = &more[f];
    int ok = m->name && field_of(c, m->name) < 0 && (m->ndim == 1 || m->ndim == 2) &&
             (!m->per_process || m->dims[0] > 0);
    for (int d = 0; ok && d < m->ndim; d++) ok = m->dims[d] > 0 || m->dims[d] == PROTO_DIM_NODES;
    if (!ok)
      return proto_fail(err, "coupler field '%s': a new name, 1 or 2 dims, each > 0 or the "
                        "surface's n", m->name ? m->name : "(null)");
    c->field[c->nfields++] = *m;
  }
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
    if ((unsigned)s->role >= CPL_MAX_ROLES)
      return proto_fail(err, "%s: role %d (at most %d roles)", row_name(s, what, sizeof what),
                        (int)s->role, CPL_MAX_ROLES);
    if (c->n == CPL_MAX_BINDINGS)
      return proto_fail(err, "%s: more than %d step/done rows",
                        row_name(s, what, sizeof what), CPL_MAX_BINDINGS);
    if (bind_row(c, s, &c->b[c->n], err) < 0) return -1;
    const int f = c->b[c->n++].field;
    if (c->field[f].per_process && used[f] && c->field_role[f] != (int)s->role)
      return proto_fail(err, "%s: the field '%s' holds one row per process of role '%s': "
                        "another role cannot bind it", row_name(s, what, sizeof what),
                        s->field, proto_role_name((proto_role)c->field_role[f]));
    c->field_role[f] = (int)s->role;
    used[f] = 1;
  }
  for (int f = 0; f < c->nfields; f++)
    if (!used[f])
      return proto_fail(err, "coupler field '%s': no role table row reads or fills it",
                        c->field[f].name);
  return take_stages(c, stages, nstages, err);
}

int cpl_contract_build(cpl_contract *c, const proto_array_spec *t, int n, proto_err *err) {
  int ns;
  const cpl_stage_row *st = cpl_contract_stages(&ns);
  return cpl_contract_build_with(c, t, n, NULL, 0, st, ns, err);
}
