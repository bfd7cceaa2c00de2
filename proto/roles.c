/* roles.c — the role table (proto.h "role table", PROTOCOL.md "Roles"): the
 * one place where the arrays each role exchanges are declared, with what they
 * mean over a coupling step [t_{k-1}, t_k] in which a participant may take
 * several sub-steps. Both sides validate messages against it. */
#include "proto.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

static const char *const role_names[PROTO_N_ROLES] = {"dem", "fem", "block", "lug"};
static const char *const msg_types[PROTO_N_MSGS] = {
    "hello", "welcome", "ready", "step", "done", "stop", "bye", "error",
    "checkpoint", "state", "restore", "restored", "heartbeat"};
/* Direction of each message kind: 1 participant → coupler, 0 the other way. */
static const int from_participant[PROTO_N_MSGS] = {1, 0, 1, 0, 1, 0, 1, 1,
                                                   0, 1, 0, 1, 1};

#define N3 {PROTO_DIM_NODES, 3}
#define M3 {PROTO_DIM_TRIS, 3}
#define K1 {PROTO_DIM_ROWS}

static const proto_array_spec table[] = {
    /* ---- fem: the tread. It declares the coupled surface. */
    {PROTO_ROLE_FEM, PROTO_MSG_READY, PROTO_A_SURFACE_X0, PROTO_F8, 2, N3, "m",
     PROTO_WHEN_ALWAYS,
     "coupled surface nodes in the rim frame at rest (after any initial static "
     "solve); binds n",
     NULL, 0},
    {PROTO_ROLE_FEM, PROTO_MSG_READY, PROTO_A_SURFACE_TRI, PROTO_I4, 2, M3, "-",
     PROTO_WHEN_ALWAYS,
     "surface triangles, indices into surface_x0, outward normals by the "
     "right-hand rule; binds m",
     NULL, 0},
    {PROTO_ROLE_FEM, PROTO_MSG_STEP, PROTO_A_NODAL_FORCE, PROTO_F8, 2, N3, "N",
     PROTO_WHEN_ALWAYS,
     "force of the grains on each surface node, world frame, constant over "
     "[t_{k-1}, t_k]: the impulse the grains exchanged with the node over the "
     "coupling step divided by dt. Apply it unchanged in every sub-step "
     "(zero at step 1)",
     "surface.force", 0},
    {PROTO_ROLE_FEM, PROTO_MSG_STEP, PROTO_A_NODAL_FORCE_INDEX, PROTO_I4, 1, K1, "-",
     PROTO_WHEN_INDEX,
     "optional, only to a fem whose ready says sparse: the nodes whose rows "
     "nodal_force then carries (k rows); every other node's force is zero",
     "surface.force", 0},
    {PROTO_ROLE_FEM, PROTO_MSG_STEP, PROTO_A_RIM_R, PROTO_F8, 2, {3, 3}, "-",
     PROTO_WHEN_ALWAYS, "rotation rim -> world at t_k, row-major",
     "rim.R", 0},
    {PROTO_ROLE_FEM, PROTO_MSG_STEP, PROTO_A_RIM_C, PROTO_F8, 1, {3}, "m",
     PROTO_WHEN_ALWAYS, "rim centre at t_k, world frame",
     "rim.c", 0},
    {PROTO_ROLE_FEM, PROTO_MSG_STEP, PROTO_A_RIM_OMEGA, PROTO_F8, 1, {3},
     "rad/s", PROTO_WHEN_ALWAYS, "rim angular velocity over the step, world",
     "rim.omega", 0},
    {PROTO_ROLE_FEM, PROTO_MSG_STEP, PROTO_A_RIM_V, PROTO_F8, 1, {3}, "m/s",
     PROTO_WHEN_ALWAYS, "rim centre velocity over the step, world",
     "rim.v", 0},
    {PROTO_ROLE_FEM, PROTO_MSG_DONE, PROTO_A_X, PROTO_F8, 2, N3, "m",
     PROTO_WHEN_ALWAYS, "surface node positions at t_k, world frame",
     "surface.x", 0},
    {PROTO_ROLE_FEM, PROTO_MSG_DONE, PROTO_A_V, PROTO_F8, 2, N3, "m/s",
     PROTO_WHEN_ALWAYS, "surface node velocities at t_k, world frame",
     "surface.v", 0},
    /* ---- dem: the grains. Gets the surface when the scene has one. */
    {PROTO_ROLE_DEM, PROTO_MSG_WELCOME, PROTO_A_SURFACE_X0, PROTO_F8, 2, N3, "m",
     PROTO_WHEN_SURFACE,
     "the coupled surface in the world frame at t = 0 (only when the scene has "
     "one); binds n",
     NULL, 0},
    {PROTO_ROLE_DEM, PROTO_MSG_WELCOME, PROTO_A_SURFACE_TRI, PROTO_I4, 2, M3,
     "-", PROTO_WHEN_SURFACE, "its triangles (as the fem's); binds m",
     NULL, 0},
    {PROTO_ROLE_DEM, PROTO_MSG_STEP, PROTO_A_X, PROTO_F8, 2, N3, "m",
     PROTO_WHEN_SURFACE, "surface node positions at t_{k-1}, world frame",
     "surface.x", 0},
    {PROTO_ROLE_DEM, PROTO_MSG_STEP, PROTO_A_V, PROTO_F8, 2, N3, "m/s",
     PROTO_WHEN_SURFACE,
     "surface velocity over the step: within [t_{k-1}, t_k] the surface is at "
     "x + (t - t_{k-1}) v (contact damping and friction use v)",
     "surface.v", 0},
    {PROTO_ROLE_DEM, PROTO_MSG_STEP, PROTO_A_X_INDEX, PROTO_I4, 1, K1, "-",
     PROTO_WHEN_INDEX,
     "optional, after a done that gave a reach box: the nodes whose rows x then "
     "carries (k rows): those of every triangle whose box over the step meets "
     "the box (header reach); the other nodes cannot touch the grains this step",
     "surface.x", 0},
    {PROTO_ROLE_DEM, PROTO_MSG_STEP, PROTO_A_V_INDEX, PROTO_I4, 1, K1, "-",
     PROTO_WHEN_INDEX, "with x_index: the same nodes, the rows v carries",
     "surface.v", 0},
    {PROTO_ROLE_DEM, PROTO_MSG_DONE, PROTO_A_NODAL_FORCE, PROTO_F8, 2, N3, "N",
     PROTO_WHEN_SURFACE,
     "force of the grains ON each surface node, world frame, as the impulse "
     "over [t_{k-1}, t_k] divided by dt: (1/dt) sum_j dt_j f_j over the "
     "sub-steps j of the step, f_j the nodal force evaluated in sub-step j "
     "(each evaluation kicks the grains with -dt_j f_j in total). Its sum is "
     "minus the impulse/dt the grains received from the surface",
     "surface.force", 1},
    {PROTO_ROLE_DEM, PROTO_MSG_DONE, PROTO_A_NODAL_FORCE_INDEX, PROTO_I4, 1, K1,
     "-", PROTO_WHEN_INDEX,
     "optional, when the step's header said sparse: the nodes whose rows "
     "nodal_force then carries (k rows); every other node's force is zero "
     "(+0.0)",
     "surface.force", 0},
    /* ---- block: the tread block on the road. */
    {PROTO_ROLE_BLOCK, PROTO_MSG_STEP, PROTO_A_D_ROAD, PROTO_F8, 1, {1}, "m",
     PROTO_WHEN_ALWAYS,
     "road displacement towards the block at t_k (positive = indentation)",
     "road.d", 0},
    {PROTO_ROLE_BLOCK, PROTO_MSG_DONE, PROTO_A_FORCE, PROTO_F8, 1, {1}, "N",
     PROTO_WHEN_ALWAYS,
     "total normal contact force (positive = compression, negative = "
     "adhesion): at t_k, or the impulse over the step divided by dt if the "
     "block sub-steps",
     "road.force", 1},
    /* ---- lug: a tread block under one lug of the rolling tyre at a time
     * (scenario tire_road): each process has its own row of the fields. */
    {PROTO_ROLE_LUG, PROTO_MSG_READY, PROTO_A_CELL_XY, PROTO_F8, 2, {PROTO_DIM_CELLS, 2}, "m",
     PROTO_WHEN_ALWAYS,
     "centres of its block's cells relative to the grid's centre (x along the "
     "rolling direction, y along the axle); binds c",
     NULL, 0},
    {PROTO_ROLE_LUG, PROTO_MSG_STEP, PROTO_A_D_ROAD, PROTO_F8, 1, {1}, "m",
     PROTO_WHEN_ALWAYS,
     "approach of its lug face towards the road at t_k (road height minus the "
     "face's area-weighted mean height; positive = indentation); a large "
     "negative value while it serves no lug. Header reset: true when it takes "
     "a new lug (the block's history starts afresh)",
     "lug.d", 0},
    {PROTO_ROLE_LUG, PROTO_MSG_STEP, PROTO_A_ORIGIN, PROTO_F8, 1, {2}, "m",
     PROTO_WHEN_ALWAYS,
     "world (x, y) of its lug face's area centre at t_{k-1} (0, 0 while it serves no "
     "lug): where on the road the block is (a road in world coordinates is taken "
     "there when it takes the lug)",
     "lug.origin", 0},
    {PROTO_ROLE_LUG, PROTO_MSG_STEP, PROTO_A_BASE, PROTO_F8, 1, {PROTO_DIM_CELLS}, "m",
     PROTO_WHEN_ALWAYS,
     "the lug face's shape: each cell's base offset towards the road relative to "
     "the face's mean height at t_{k-1} (the cell's own approach is d_road + "
     "base); all 0 for a face taken as flat; a cell beyond the face's edge gets "
     "-1 m (no rubber there: it never touches)",
     "lug.base", 0},
    {PROTO_ROLE_LUG, PROTO_MSG_DONE, PROTO_A_FORCE, PROTO_F8, 1, {1}, "N",
     PROTO_WHEN_ALWAYS,
     "total normal contact force on its lug face (positive = compression) at "
     "t_k, held over the step",
     "lug.force", 0},
    {PROTO_ROLE_LUG, PROTO_MSG_DONE, PROTO_A_COP, PROTO_F8, 1, {2}, "m",
     PROTO_WHEN_ALWAYS,
     "centre of pressure relative to the block grid's centre (x along the "
     "rolling direction, y along the axle); 0 when the force is 0",
     "lug.cop", 0},
    {PROTO_ROLE_LUG, PROTO_MSG_DONE, PROTO_A_CELL_FORCE, PROTO_F8, 1, {PROTO_DIM_CELLS}, "N",
     PROTO_WHEN_ALWAYS,
     "each cell's normal contact force at t_k (positive = compression): its sum "
     "is force; the coupler spreads it onto the face's nodes",
     "lug.cell_force", 0},
};

const proto_array_spec *proto_role_table(int *n) {
  *n = (int)(sizeof table / sizeof table[0]);
  return table;
}

/* Index of name in names[0..n), or -1. */
static int index_of(const char *name, const char *const *names, int n) {
  for (int i = 0; name && i < n; i++)
    if (strcmp(name, names[i]) == 0) return i;
  return -1;
}

const char *proto_role_name(proto_role r) {
  return (unsigned)r < PROTO_N_ROLES ? role_names[r] : "?";
}

int proto_role_parse(const char *name) { return index_of(name, role_names, PROTO_N_ROLES); }

const char *proto_msg_type(proto_msg_kind k) {
  return (unsigned)k < PROTO_N_MSGS ? msg_types[k] : "?";
}

int proto_msg_kind_parse(const char *type) { return index_of(type, msg_types, PROTO_N_MSGS); }

void proto_dims_init(proto_dims *d) {
  memset(d, 0, sizeof *d);
  d->nodes = d->tris = d->cells = -1;
}

static int64_t *dim_slot(proto_dims *d, int64_t sym) { /* NULL: k, per message */
  return sym == PROTO_DIM_NODES ? &d->nodes : sym == PROTO_DIM_TRIS ? &d->tris
         : sym == PROTO_DIM_CELLS ? &d->cells : NULL;
}

const char *proto_dim_symbol(int64_t sym) {
  return sym == PROTO_DIM_NODES ? "n" : sym == PROTO_DIM_TRIS ? "m"
         : sym == PROTO_DIM_ROWS ? "k" : sym == PROTO_DIM_CELLS ? "c" : "?";
}

/* "[n=25, 3]" (or "[n, 3]" while n is unbound). */
static void want_str(const proto_array_spec *s, const proto_dims *d, char *out,
                     size_t cap) {
  size_t len = (size_t)snprintf(out, cap, "[");
  for (int i = 0; i < s->ndim && len < cap; i++) {
    const char *sep = i ? ", " : "";
    int64_t v = s->dims[i];
    if (v >= 0) {
      len += (size_t)snprintf(out + len, cap - len, "%s%lld", sep, (long long)v);
    } else {
      const int64_t *slot = dim_slot((proto_dims *)d, v);
      int64_t bound = slot ? *slot : -1;
      if (bound >= 0)
        len += (size_t)snprintf(out + len, cap - len, "%s%s=%lld", sep,
                                proto_dim_symbol(v), (long long)bound);
      else
        len += (size_t)snprintf(out + len, cap - len, "%s%s", sep, proto_dim_symbol(v));
    }
  }
  if (len < cap) snprintf(out + len, cap - len, "]");
}

static void got_str(const proto_array *a, char *out, size_t cap) {
  size_t len = (size_t)snprintf(out, cap, "%s [", proto_dtype_name(a->dtype));
  for (int i = 0; i < a->ndim && len < cap; i++)
    len += (size_t)snprintf(out + len, cap - len, "%s%lld", i ? ", " : "",
                            (long long)a->shape[i]);
  if (len < cap) snprintf(out + len, cap - len, "]");
}

static int spec_fail(const proto_array_spec *s, const proto_dims *d,
                     const proto_array *a, proto_err *err) {
  char want[96], got[96] = "";
  want_str(s, d, want, sizeof want);
  if (a) got_str(a, got, sizeof got);
  return proto_fail(err, "%s (role %s): %s array '%s': expected %s %s (%s)%s%s",
                    proto_msg_type(s->msg), role_names[s->role],
                    a ? "wrong shape or dtype of" : "missing", s->name,
                    proto_dtype_name(s->dtype), want, s->meaning,
                    a ? ", got " : "", got);
}

/* Checks one array against its spec, binding unbound symbolic dims. */
static int check_one(const proto_array_spec *s, const proto_array *a,
                     proto_dims *d, proto_err *err) {
  if (a->dtype != s->dtype || a->ndim != s->ndim) return spec_fail(s, d, a, err);
  proto_dims trial = *d;
  for (int i = 0; i < s->ndim; i++) {
    int64_t want = s->dims[i];
    if (want >= 0) { /* literal (0: a sparse array of no rows) */
      if (a->shape[i] != want) return spec_fail(s, d, a, err);
      continue;
    }
    int64_t *slot = dim_slot(&trial, want);
    if (!slot) return spec_fail(s, d, a, err); /* k outside a sparse form */
    if (*slot < 0) *slot = a->shape[i];
    else if (*slot != a->shape[i]) return spec_fail(s, d, a, err);
  }
  *d = trial;
  return 0;
}

/* ------------------------------------------- participant-defined arrays */

/* A column name is free text for people (HDF5 attribute, the run summary):
 * 1..PROTO_NAME_LEN-1 bytes of printable UTF-8. */
static int column_ok(const char *c) {
  char copy[PROTO_NAME_LEN];
  size_t n = strlen(c);
  if (n == 0 || n >= sizeof copy) return 0;
  memcpy(copy, c, n + 1);
  proto_sanitize(copy);
  return strcmp(copy, c) == 0 && strcspn(c, "\n\t") == n;
}

/* The name of the array that carries dataset ds's row in a done. */
static void series_array(const char *ds, char *out, size_t cap) {
  if (strcmp(ds, PROTO_A_SERIES) == 0) snprintf(out, cap, "%s", PROTO_A_SERIES);
  else snprintf(out, cap, "%s%s", PROTO_P_SERIES, ds);
}

/* ready.series: {dataset: [column names]}; kept in d for the dones. */
static int check_series_decl(const cJSON *series, proto_dims *d, proto_err *err) {
  d->n_series = 0;
  if (!series) return 0;
  if (!cJSON_IsObject(series))
    return proto_fail(err, "ready.series: expected an object {dataset: [column "
                      "names]}");
  for (const cJSON *ds = series->child; ds; ds = ds->next) {
    if (d->n_series == PROTO_MAX_SERIES)
      return proto_fail(err, "ready.series: more than %d datasets", PROTO_MAX_SERIES);
    if (proto_name_check(ds->string, PROTO_NAME_PLAIN, "ready.series: dataset",
                         err) < 0)
      return -1;
    int ncols = cJSON_IsArray(ds) ? cJSON_GetArraySize(ds) : 0;
    if (ncols < 1 || ncols > PROTO_MAX_COLUMNS)
      return proto_fail(err, "ready.series.%s: expected a list of 1 to %d column "
                        "names", ds->string, PROTO_MAX_COLUMNS);
    int i = 0;
    for (const cJSON *c = ds->child; c; c = c->next, i++)
      if (!cJSON_IsString(c) || !column_ok(c->valuestring))
        return proto_fail(err, "ready.series.%s[%d]: expected a column name of 1 "
                          "to %d printable characters", ds->string, i,
                          PROTO_NAME_LEN - 1);
    snprintf(d->series[d->n_series], PROTO_NAME_LEN, "%s", ds->string);
    d->series_cols[d->n_series++] = ncols;
  }
  return 0;
}

/* ready.snapshot: the names it gives become HDF5 paths and XDMF text. */
static int check_snapshot_decl(const cJSON *snap, proto_err *err) {
  if (!snap || cJSON_IsNull(snap)) return 0;
  if (!cJSON_IsObject(snap))
    return proto_fail(err, "ready.snapshot: expected an object {kind, geometry, "
                      "cells, attributes}");
  static const char *const names[] = {"kind", "geometry", "cells"};
  for (int k = 0; k < 3; k++) {
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(snap, names[k]);
    char what[32];
    snprintf(what, sizeof what, "ready.snapshot.%s", names[k]);
    if (!v || cJSON_IsNull(v)) continue;
    if (!cJSON_IsString(v)) return proto_fail(err, "%s: expected a name", what);
    if (proto_name_check(v->valuestring, PROTO_NAME_PLAIN, what, err) < 0) return -1;
  }
  const cJSON *attrs = cJSON_GetObjectItemCaseSensitive(snap, "attributes");
  if (!attrs || cJSON_IsNull(attrs)) return 0;
  int n = cJSON_IsArray(attrs) ? cJSON_GetArraySize(attrs) : -1;
  if (n < 0 || n > PROTO_MAX_SNAP_ATTRS)
    return proto_fail(err, "ready.snapshot.attributes: expected a list of at most "
                      "%d names", PROTO_MAX_SNAP_ATTRS);
  int i = 0;
  for (const cJSON *a = attrs->child; a; a = a->next, i++) {
    char what[48];
    snprintf(what, sizeof what, "ready.snapshot.attributes[%d]", i);
    if (!cJSON_IsString(a)) return proto_fail(err, "%s: expected a name", what);
    if (proto_name_check(a->valuestring, PROTO_NAME_PLAIN, what, err) < 0) return -1;
  }
  return 0;
}

/* A done carries exactly the declared series: one f8 row each. */
static int check_done_series(const proto_msg *m, const proto_dims *d,
                             proto_err *err) {
  for (int i = 0; i < d->n_series; i++) {
    char name[PROTO_NAME_LEN + 8];
    series_array(d->series[i], name, sizeof name);
    const proto_array *a = proto_msg_find(m, name);
    if (!a || a->dtype != PROTO_F8 || a->ndim != 1 || a->shape[0] != d->series_cols[i])
      return proto_fail(err, "done: %s array '%s' (f8 [%d]): ready declared the "
                        "series dataset '%s' with %d columns, so every done "
                        "carries its row", a ? "wrong shape or dtype of" : "missing",
                        name, d->series_cols[i], d->series[i], d->series_cols[i]);
  }
  const size_t plen = strlen(PROTO_P_SERIES);
  for (int i = 0; i < m->narrays; i++) {
    const char *name = m->arrays[i].name;
    const char *ds = strcmp(name, PROTO_A_SERIES) == 0 ? name
                     : strncmp(name, PROTO_P_SERIES, plen) == 0 ? name + plen
                                                                : NULL;
    int declared = 0;
    for (int k = 0; ds && k < d->n_series; k++) {
      char want[PROTO_NAME_LEN + 8];
      series_array(d->series[k], want, sizeof want);
      declared |= strcmp(want, name) == 0;
    }
    if (ds && !declared)
      return proto_fail(err, "done: array '%s' belongs to no series dataset "
                        "declared in ready.series", name);
  }
  return 0;
}

/* The index row of s ("<name>_index", WHEN_INDEX) in the table, or NULL. */
static const proto_array_spec *index_row(const proto_array_spec *t, int n,
                                         const proto_array_spec *s) {
  char iname[PROTO_NAME_LEN + 8];
  snprintf(iname, sizeof iname, "%s%s", s->name, PROTO_SUFFIX_INDEX);
  for (int i = 0; i < n; i++)
    if (t[i].role == s->role && t[i].msg == s->msg && t[i].when == PROTO_WHEN_INDEX &&
        strcmp(t[i].name, iname) == 0)
      return &t[i];
  return NULL;
}

/* Row s's sparse form in m: 0 dense (no index array), 1 sparse with *rows
 * listed nodes (i4 [k], strictly increasing, each in [0, n)), -1 naming the
 * defect. */
static int check_index(const proto_array_spec *t, int n, const proto_array_spec *s,
                       const proto_msg *m, const proto_dims *d, int64_t *rows,
                       proto_err *err) {
  const proto_array_spec *is = index_row(t, n, s);
  const proto_array *ia = is ? proto_msg_find(m, is->name) : NULL;
  if (!ia) return 0;
  if (ia->dtype != PROTO_I4 || ia->ndim != 1 || s->dims[0] != PROTO_DIM_NODES ||
      d->nodes < 0 || ia->shape[0] > d->nodes)
    return spec_fail(is, d, ia, err);
  const int32_t *idx = ia->data;
  for (int64_t j = 0; j < ia->shape[0]; j++)
    if (idx[j] < 0 || idx[j] >= d->nodes || (j > 0 && idx[j] <= idx[j - 1]))
      return proto_fail(err, "%s (role %s): %s[%lld] = %d: expected node indices in "
                        "[0, %lld), strictly increasing (%s)", proto_msg_type(s->msg),
                        role_names[s->role], is->name, (long long)j, (int)idx[j],
                        (long long)d->nodes, is->meaning);
  *rows = ia->shape[0];
  return 1;
}

int proto_role_check(proto_role role, proto_msg_kind kind, const proto_msg *m,
                     proto_dims *d, proto_err *err) {
  if (kind == PROTO_MSG_READY &&
      (check_series_decl(cJSON_GetObjectItemCaseSensitive(m->header, PROTO_H_SERIES),
                         d, err) < 0 ||
       check_snapshot_decl(cJSON_GetObjectItemCaseSensitive(m->header, PROTO_H_SNAPSHOT),
                           err) < 0))
    return -1;
  if (kind == PROTO_MSG_DONE && check_done_series(m, d, err) < 0) return -1;
  int n;
  const proto_array_spec *t = proto_role_table(&n);
  int declaring = kind == PROTO_MSG_WELCOME || kind == PROTO_MSG_READY;
  if (declaring)
    for (int i = 0; i < n; i++)
      if (t[i].role == role && t[i].msg == kind && t[i].when == PROTO_WHEN_SURFACE &&
          proto_msg_find(m, t[i].name))
        d->surface = 1;
  for (int i = 0; i < n; i++) {
    const proto_array_spec *s = &t[i];
    if (s->role != role || s->msg != kind) continue;
    if (s->when == PROTO_WHEN_INDEX) continue; /* checked with the array it indexes */
    if (s->when == PROTO_WHEN_SURFACE && !d->surface) continue;
    const proto_array *a = proto_msg_find(m, s->name);
    if (!a) return spec_fail(s, d, NULL, err);
    int64_t rows = 0;
    const int r = check_index(t, n, s, m, d, &rows, err);
    if (r < 0) return -1;
    proto_array_spec sparse = *s;
    if (r == 1) sparse.dims[0] = rows; /* the sparse form: k rows */
    if (check_one(&sparse, a, d, err) < 0) return -1;
  }
  return 0;
}

/* Per node, one bit per side of the box its swept segment [x, x + v dt]
 * (grown by the rounding) reaches: bit 2d if its low end reaches down to
 * the box's top on axis d, bit 2d+1 if its high end reaches up to the
 * bottom. A triangle's box over the step meets the box iff its nodes' bits
 * together are all six: min_i(lo_i) - r <= top iff some lo_i - r <= top
 * (rounding is monotone), and the same for the max. So per node once, then
 * three byte loads per triangle (it tested x and y per corner). */
enum { REACH_ALL_SIDES = 63, REACH_SENT = 64 };

int64_t proto_reach_nodes(const double *x, const double *v, double dt, const int32_t *tri,
                          int64_t n_tri, int64_t n, const double box[6], uint8_t *mark,
                          int32_t *index) {
  /* min(p, q) - r <= top iff p - r <= top or q - r <= top (rounding is
   * monotone; finite: checked on arrival): no branch on the sign of v */
  const double r = PROTO_REACH_ROUNDING;
  for (int64_t a = 0; a < n; a++) {
    unsigned bits = 0;
    for (int d = 0; d < 3; d++) {
      const double p = x[3 * a + d], q = p + v[3 * a + d] * dt;
      const unsigned lo = (unsigned)(p - r <= box[3 + d]) | (unsigned)(q - r <= box[3 + d]);
      const unsigned hi = (unsigned)(p + r >= box[d]) | (unsigned)(q + r >= box[d]);
      bits |= (lo | hi << 1) << (2 * d);
    }
    mark[a] = (uint8_t)bits;
  }
  for (int64_t t = 0; t < n_tri; t++) {
    const int32_t *tn = &tri[3 * t];
    if (((mark[tn[0]] | mark[tn[1]] | mark[tn[2]]) & REACH_ALL_SIDES) == REACH_ALL_SIDES)
      for (int a = 0; a < 3; a++) mark[tn[a]] |= REACH_SENT;
  }
  int64_t k = 0;
  for (int64_t a = 0; a < n; a++) {
    mark[a] = (mark[a] & REACH_SENT) != 0; /* as the contract says: 1 for a node sent */
    if (mark[a]) index[k++] = (int32_t)a;
  }
  return k;
}

int64_t proto_first_nonfinite(const double *a, int64_t n) {
  /* the exponent's eleven bits all ones (inf, nan) carry into bit 63 when
   * one more unit of the exponent is added: one add, and, or per value,
   * no branch (the loop vectorises); the index only when one is there */
  const uint64_t exp = 0x7ff0000000000000u, one = 0x0010000000000000u;
  uint64_t carry = 0;
  for (int64_t j = 0; j < n; j++) {
    uint64_t u;
    memcpy(&u, &a[j], sizeof u);
    carry |= (u & exp) + one;
  }
  if (!(carry >> 63)) return -1;
  for (int64_t j = 0; j < n; j++)
    if (!isfinite(a[j])) return j;
  return -1;
}

const double *proto_msg_dense(const proto_msg *m, const char *name, int64_t n, int cols,
                              double *scratch) {
  const int32_t *idx;
  const int64_t k = proto_msg_sparse(m, name, &idx);
  const double *a = proto_msg_data(m, name);
  if (k < 0) return a;
  memset(scratch, 0, sizeof(double) * (size_t)n * (size_t)cols); /* +0.0, as dense */
  for (int64_t j = 0; j < k; j++)
    memcpy(&scratch[(size_t)idx[j] * (size_t)cols], &a[j * cols], sizeof(double) * (size_t)cols);
  return scratch;
}

int64_t proto_msg_sparse(const proto_msg *m, const char *name, const int32_t **index) {
  char iname[PROTO_NAME_LEN + 8];
  snprintf(iname, sizeof iname, "%s%s", name, PROTO_SUFFIX_INDEX);
  const proto_array *ia = proto_msg_find(m, iname);
  *index = ia ? ia->data : NULL;
  return ia ? ia->shape[0] : -1;
}

const void *proto_msg_data(const proto_msg *m, const char *name) {
  const proto_array *a = proto_msg_find(m, name);
  return a ? a->data : NULL;
}

cJSON *proto_role_table_json(void) {
  int n;
  const proto_array_spec *t = proto_role_table(&n);
  cJSON *root = cJSON_CreateObject();
  cJSON_AddNumberToObject(root, "version", PROTO_VERSION);
  cJSON *msgs = cJSON_AddArrayToObject(root, "messages");
  for (int k = 0; k < PROTO_N_MSGS; k++) {
    cJSON *o = cJSON_CreateObject();
    cJSON_AddStringToObject(o, "type", msg_types[k]);
    cJSON_AddStringToObject(o, "direction", from_participant[k]
                                                ? "participant->coupler"
                                                : "coupler->participant");
    cJSON_AddItemToArray(msgs, o);
  }
  cJSON *dims = cJSON_AddObjectToObject(root, "dims");
  cJSON_AddStringToObject(dims, "n", "surface nodes (bound by surface_x0)");
  cJSON_AddStringToObject(dims, "m", "surface triangles (bound by surface_tri)");
  cJSON_AddStringToObject(dims, "k", "rows of a sparse array: the length of its "
                          "<name>_index in the same message");
  cJSON_AddStringToObject(dims, "c", "a lug block's cells (bound by cell_xy)");
  cJSON *prefixes = cJSON_AddObjectToObject(root, "prefixes");
  cJSON_AddStringToObject(prefixes, PROTO_A_SERIES, "done: the row of the series dataset");
  cJSON_AddStringToObject(prefixes, PROTO_P_SERIES, "done: rows of further datasets");
  cJSON_AddStringToObject(prefixes, PROTO_P_SNAP, "done at output steps: snapshot arrays");
  cJSON_AddStringToObject(prefixes, PROTO_P_MESH, "ready: arrays written once");
  cJSON_AddStringToObject(prefixes, PROTO_P_STATE, "state: the participant's state");
  cJSON *roles = cJSON_AddObjectToObject(root, "roles");
  for (int r = 0; r < PROTO_N_ROLES; r++) {
    cJSON *ro = cJSON_AddObjectToObject(roles, role_names[r]);
    for (int i = 0; i < n; i++) {
      const proto_array_spec *s = &t[i];
      if ((int)s->role != r) continue;
      cJSON *list = cJSON_GetObjectItemCaseSensitive(ro, msg_types[s->msg]);
      if (!list) list = cJSON_AddArrayToObject(ro, msg_types[s->msg]);
      cJSON *a = cJSON_CreateObject();
      cJSON_AddStringToObject(a, "name", s->name);
      cJSON_AddStringToObject(a, "dtype", proto_dtype_name(s->dtype));
      cJSON *shape = cJSON_AddArrayToObject(a, "shape");
      for (int k = 0; k < s->ndim; k++)
        cJSON_AddItemToArray(shape, s->dims[k] > 0
                                        ? cJSON_CreateNumber((double)s->dims[k])
                                        : cJSON_CreateString(proto_dim_symbol(s->dims[k])));
      cJSON_AddStringToObject(a, "units", s->units);
      cJSON_AddStringToObject(a, "direction", from_participant[s->msg]
                                                  ? "participant->coupler"
                                                  : "coupler->participant");
      cJSON_AddStringToObject(a, "when", s->when == PROTO_WHEN_SURFACE ? "with_surface"
                                         : s->when == PROTO_WHEN_INDEX ? "sparse_index"
                                                                       : "always");
      cJSON_AddStringToObject(a, "meaning", s->meaning);
      if (s->field) {
        cJSON_AddStringToObject(a, "field", s->field);
        cJSON_AddBoolToObject(a, "summed", s->sum);
      }
      cJSON_AddItemToArray(list, a);
    }
  }
  return root;
}

int64_t proto_sparse_rows(const double *f, int64_t n, int32_t *idx, double *rows) {
  int64_t k = 0;
  for (int64_t a = 0; a < n; a++) {
    const double *r = &f[3 * a];
    if (r[0] == 0 && r[1] == 0 && r[2] == 0 && !signbit(r[0]) && !signbit(r[1]) &&
        !signbit(r[2]))
      continue;
    idx[k] = (int32_t)a;
    memcpy(&rows[3 * k++], r, 3 * sizeof(double));
  }
  return k;
}
