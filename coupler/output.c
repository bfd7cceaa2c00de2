/* output.c — results.h5 (README.md "Output"): a group per participant with
 * its time series (declared in its ready message, one row per step) and its
 * snapshots at output steps (arrays "snap.<name>" → /<p>/steps/<k>/<name>),
 * the coupler's own series, the config as an attribute, and an XDMF file per
 * participant with snapshots so ParaView opens them as a time series. */
#include "internal.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#define MAX_SETS 8
#define MAX_COLS 64
#define MAX_ATTRS 16

typedef struct out_set {
  char name[PROTO_NAME_LEN]; /* dataset name under the group */
  proto_series *series;
  int ncols;
} out_set;

typedef struct out_part {
  char name[PROTO_NAME_LEN];
  int nsets;
  out_set sets[MAX_SETS];
  /* summary: the "series" dataset's columns and last row */
  int ncols;
  char columns[MAX_COLS][PROTO_NAME_LEN];
  double last[MAX_COLS];
  int have_last;
  /* snapshots */
  proto_xdmf *xdmf;
  proto_xdmf_topology topo;
  char geometry[PROTO_NAME_LEN];
  char cells[CPL_PATH_LEN]; /* dataset path of the connectivity, "" = points */
  int64_t ncells;
  int nattrs;
  char attrs[MAX_ATTRS][PROTO_NAME_LEN];
} out_part;

struct cpl_output {
  proto_h5 *h5;
  char path[CPL_PATH_LEN];
  char dir[CPL_PATH_LEN];
  int64_t keep_rows; /* continuing a file: its rows of steps 1..keep_rows; -1: new */
  double dt;         /* coupling step (which XDMF grids a restart keeps) */
  int io_failed;     /* a write or flush failed */
  int nparts;
  out_part parts[CPL_MAX_PROCS + 1]; /* + the coupler itself */
};

/* An I/O call's result: a failure marks the output as failed (exit 4). */
static int io(cpl_output *o, int rc) {
  if (rc < 0) o->io_failed = 1;
  return rc;
}

cpl_output *cpl_output_open(const cpl_scene *s, int64_t continue_step, proto_err *err) {
  if (cpl_mkdirs(s->output_dir, err) < 0) return NULL;
  cpl_output *o = calloc(1, sizeof *o);
  if (!o) return NULL;
  snprintf(o->dir, sizeof o->dir, "%s", s->output_dir);
  snprintf(o->path, sizeof o->path, "%s/%s", s->output_dir, CPL_RESULTS_FILE);
  o->dt = s->dt;
  o->keep_rows = continue_step >= 0 && proto_h5_probe(o->path) == 1 ? continue_step : -1;
  o->h5 = o->keep_rows >= 0 ? proto_h5_open(o->path, 1, err) : proto_h5_create(o->path, err);
  char *config = cJSON_Print(s->root);
  int rc = o->h5 && config ? proto_h5_attr_str(o->h5, "/", "config", config, err)
                           : -1;
  free(config);
  if (rc < 0) {
    cpl_output_close(o, NULL);
    return NULL;
  }
  return o;
}

int cpl_output_io_failed(const cpl_output *o) { return o && o->io_failed; }

const char *cpl_output_path(const cpl_output *o) { return o->path; }

static out_part *part(cpl_output *o, const char *name) {
  for (int i = 0; i < o->nparts; i++)
    if (strcmp(o->parts[i].name, name) == 0) return &o->parts[i];
  if (o->nparts == CPL_MAX_PROCS + 1) return NULL;
  out_part *p = &o->parts[o->nparts++];
  memset(p, 0, sizeof *p);
  snprintf(p->name, sizeof p->name, "%s", name);
  return p;
}

/* The dataset whose last row the run's summary shows: a participant's
 * "series", the coupler's "traction" (tyre scenes). */
static int is_summary(const out_part *p, const char *ds) {
  return strcmp(ds, strcmp(p->name, "coupler") == 0 ? "traction" : PROTO_A_SERIES) == 0;
}

static void keep_last(out_part *p, const char *ds, int ncols, const double *row) {
  if (!is_summary(p, ds)) return;
  memcpy(p->last, row, sizeof(double) * (size_t)ncols);
  p->have_last = 1;
}

static int add_set(cpl_output *o, out_part *p, const char *ds, int ncols,
                   const char *const *cols, proto_err *err) {
  if (p->nsets == MAX_SETS)
    return proto_fail(err, "%s: more than %d series", p->name, MAX_SETS);
  char path[CPL_PATH_LEN];
  snprintf(path, sizeof path, "/%s/%s", p->name, ds);
  out_set *set = &p->sets[p->nsets];
  set->series = o->keep_rows >= 0
                    ? proto_h5_series_resume(o->h5, path, ncols, cols, o->keep_rows, err)
                    : proto_h5_series(o->h5, path, ncols, cols, err);
  if (!set->series) return -1;
  snprintf(set->name, sizeof set->name, "%s", ds);
  set->ncols = ncols;
  p->nsets++;
  if (is_summary(p, ds)) {
    p->ncols = ncols;
    for (int i = 0; i < ncols; i++)
      snprintf(p->columns[i], sizeof p->columns[i], "%s", cols[i]);
  }
  return 0;
}

static int declare_series(cpl_output *o, out_part *p, const cJSON *series,
                          proto_err *err) {
  for (const cJSON *ds = series ? series->child : NULL; ds; ds = ds->next) {
    int n = cJSON_IsArray(ds) ? cJSON_GetArraySize(ds) : 0;
    if (n < 1 || n > MAX_COLS)
      return proto_fail(err, "%s: ready.series.%s: expected 1..%d column "
                        "names", p->name, ds->string, MAX_COLS);
    const char *cols[MAX_COLS];
    for (int i = 0; i < n; i++) {
      const cJSON *c = cJSON_GetArrayItem(ds, i);
      if (!cJSON_IsString(c))
        return proto_fail(err, "%s: ready.series.%s[%d]: expected a string",
                          p->name, ds->string, i);
      cols[i] = c->valuestring;
    }
    if (add_set(o, p, ds->string, n, cols, err) < 0) return -1;
  }
  return 0;
}

static int declare_snapshot(cpl_output *o, out_part *p, const cJSON *snap,
                            const proto_msg *ready, proto_err *err) {
  static const char *const kinds[] = {"points", "tet4", "tet10", "tri3"};
  const cJSON *kind = cJSON_GetObjectItemCaseSensitive(snap, "kind");
  const cJSON *geom = cJSON_GetObjectItemCaseSensitive(snap, "geometry");
  const cJSON *cells = cJSON_GetObjectItemCaseSensitive(snap, "cells");
  const cJSON *attrs = cJSON_GetObjectItemCaseSensitive(snap, "attributes");
  int k = -1;
  for (int i = 0; i < 4 && cJSON_IsString(kind); i++)
    if (strcmp(kind->valuestring, kinds[i]) == 0) k = i;
  if (k < 0 || !cJSON_IsString(geom))
    return proto_fail(err, "%s: ready.snapshot needs kind (points, tet4, "
                      "tet10, tri3) and geometry", p->name);
  p->topo = (proto_xdmf_topology)k;
  snprintf(p->geometry, sizeof p->geometry, "%s", geom->valuestring);
  if (cJSON_IsString(cells)) {
    char name[PROTO_NAME_LEN + 8];
    snprintf(name, sizeof name, "%s%s", PROTO_P_MESH, cells->valuestring);
    const proto_array *a = proto_msg_find(ready, name);
    if (!a || a->ndim != 2)
      return proto_fail(err, "%s: ready.snapshot.cells names '%s', which the "
                        "ready message does not carry as a 2-D array",
                        p->name, name);
    p->ncells = a->shape[0];
    snprintf(p->cells, sizeof p->cells, "/%s/mesh/%s", p->name,
             cells->valuestring);
  }
  for (const cJSON *a = attrs ? attrs->child : NULL; a; a = a->next)
    if (cJSON_IsString(a) && p->nattrs < MAX_ATTRS)
      snprintf(p->attrs[p->nattrs++], PROTO_NAME_LEN, "%s", a->valuestring);
  char path[CPL_PATH_LEN + 64];
  snprintf(path, sizeof path, "%s/%s.xdmf", o->dir, p->name);
  p->xdmf = o->keep_rows >= 0 ? proto_xdmf_resume(path, CPL_RESULTS_FILE,
                                                  ((double)o->keep_rows + 0.5) * o->dt, err)
                              : proto_xdmf_open(path, CPL_RESULTS_FILE, err);
  return p->xdmf ? 0 : io(o, -1);
}

/* Continuing a file: the snapshots of steps after keep_rows go. */
typedef struct prune_ctx {
  cpl_output *o;
  const char *group;
  proto_err *err;
} prune_ctx;

static int prune_one(const char *name, void *ctx) {
  prune_ctx *c = ctx;
  char *end;
  long long k = strtoll(name, &end, 10);
  if (*end || k <= c->o->keep_rows) return 0;
  char path[CPL_PATH_LEN + PROTO_NAME_LEN];
  snprintf(path, sizeof path, "%s/%s", c->group, name);
  return proto_h5_unlink(c->o->h5, path, c->err) < 0 ? -1 : 0;
}

static int prune_steps(cpl_output *o, const char *name, proto_err *err) {
  char group[CPL_PATH_LEN];
  snprintf(group, sizeof group, "/%s/steps", name);
  prune_ctx c = {o, group, err};
  return io(o, proto_h5_list(o->h5, group, prune_one, &c, err));
}

int cpl_output_participant(cpl_output *o, const char *name,
                           const proto_msg *ready, proto_err *err) {
  out_part *p = part(o, name);
  if (!p) return proto_fail(err, "too many participants");
  if (o->keep_rows >= 0 && prune_steps(o, name, err) < 0) return -1;
  if (declare_series(o, p, cJSON_GetObjectItemCaseSensitive(ready->header,
                                                            PROTO_H_SERIES),
                     err) < 0)
    return -1;
  char group[CPL_PATH_LEN];
  snprintf(group, sizeof group, "/%s/mesh", name);
  for (int i = 0; i < ready->narrays; i++) {
    const proto_array *a = &ready->arrays[i];
    const size_t plen = strlen(PROTO_P_MESH);
    if (strncmp(a->name, PROTO_P_MESH, plen) != 0) continue;
    proto_array copy = *a;
    snprintf(copy.name, sizeof copy.name, "%s", a->name + plen);
    if (io(o, proto_h5_write_array(o->h5, group, &copy, err)) < 0) return -1;
  }
  const cJSON *snap = cJSON_GetObjectItemCaseSensitive(ready->header, PROTO_H_SNAPSHOT);
  if (cJSON_IsObject(snap) && declare_snapshot(o, p, snap, ready, err) < 0)
    return -1;
  return 0;
}

static out_set *find_set(out_part *p, const char *name) {
  for (int i = 0; i < p->nsets; i++)
    if (strcmp(p->sets[i].name, name) == 0) return &p->sets[i];
  return NULL;
}

static int append_series(cpl_output *o, out_part *p, const proto_msg *done,
                         proto_err *err) {
  for (int i = 0; i < done->narrays; i++) {
    const proto_array *a = &done->arrays[i];
    const size_t plen = strlen(PROTO_P_SERIES);
    const char *ds = strcmp(a->name, PROTO_A_SERIES) == 0 ? PROTO_A_SERIES
                     : strncmp(a->name, PROTO_P_SERIES, plen) == 0 ? a->name + plen
                                                                   : NULL;
    if (!ds) continue;
    out_set *set = find_set(p, ds);
    if (!set)
      return proto_fail(err, "%s: array '%s' belongs to no series declared in "
                        "its ready message", p->name, a->name);
    int64_t shape[1] = {set->ncols};
    if (!proto_msg_get(done, a->name, PROTO_F8, 1, shape, err)) return -1;
    if (io(o, proto_series_append(set->series, a->data, err)) < 0) return -1;
    /* written first, so the file shows the bad row; then the run stops */
    const double *row = a->data;
    for (int c = 0; c < set->ncols; c++)
      if (!isfinite(row[c]))
        return proto_fail(err, "%s: %s column %d (%s) is %g at t = %g s "
                          "(the solver blew up; see its log)", p->name, ds, c,
                          strcmp(ds, PROTO_A_SERIES) == 0 ? p->columns[c] : "-",
                          row[c], done->t);
    keep_last(p, ds, set->ncols, a->data);
  }
  return 0;
}

static int write_snapshot(cpl_output *o, out_part *p, const proto_msg *done,
                          proto_err *err) {
  char group[CPL_PATH_LEN];
  snprintf(group, sizeof group, "/%s/steps/%lld", p->name, (long long)done->step);
  const proto_array *geometry = NULL;
  char gname[PROTO_NAME_LEN + 8];
  snprintf(gname, sizeof gname, "%s%s", PROTO_P_SNAP, p->geometry);
  for (int i = 0; i < done->narrays; i++) {
    const proto_array *a = &done->arrays[i];
    const size_t plen = strlen(PROTO_P_SNAP);
    if (strncmp(a->name, PROTO_P_SNAP, plen) != 0) continue;
    proto_array copy = *a;
    snprintf(copy.name, sizeof copy.name, "%s", a->name + plen);
    if (io(o, proto_h5_write_array(o->h5, group, &copy, err)) < 0) return -1;
    if (strcmp(a->name, gname) == 0) geometry = a;
  }
  if (!p->xdmf || !geometry) return 0;
  char geo[CPL_PATH_LEN + PROTO_NAME_LEN], paths[MAX_ATTRS][CPL_PATH_LEN + PROTO_NAME_LEN];
  const char *attr_paths[MAX_ATTRS];
  int64_t cols[MAX_ATTRS], rows[MAX_ATTRS];
  int n = 0;
  snprintf(geo, sizeof geo, "%s/%s", group, p->geometry);
  for (int i = 0; i < p->nattrs; i++) {
    char an[PROTO_NAME_LEN + 8];
    snprintf(an, sizeof an, "%s%s", PROTO_P_SNAP, p->attrs[i]);
    const proto_array *a = proto_msg_find(done, an);
    if (!a) continue;
    snprintf(paths[n], sizeof paths[n], "%s/%s", group, p->attrs[i]);
    attr_paths[n] = paths[n];
    rows[n] = a->shape[0];
    cols[n] = a->ndim > 1 ? a->shape[1] : 1;
    n++;
  }
  char grid[PROTO_NAME_LEN + 32];
  snprintf(grid, sizeof grid, "%s_%lld", p->name, (long long)done->step);
  return proto_xdmf_step(p->xdmf, grid, done->t, p->topo, geometry->shape[0],
                         geo, p->ncells, p->cells[0] ? p->cells : NULL, n,
                         attr_paths, cols, rows) < 0
             ? io(o, proto_fail(err, "%s/%s.xdmf: cannot write the step: %s (errno %d)",
                                o->dir, p->name, strerror(errno), errno))
             : 0;
}

int cpl_output_done(cpl_output *o, const char *name, const proto_msg *done,
                    int output_step, proto_err *err) {
  out_part *p = part(o, name);
  if (!p) return proto_fail(err, "unknown participant %s", name);
  if (append_series(o, p, done, err) < 0) return -1;
  if (output_step && write_snapshot(o, p, done, err) < 0) return -1;
  return 0;
}

int cpl_output_coupler_row(cpl_output *o, const char *dataset, int ncols,
                           const char *const *columns, const double *row,
                           proto_err *err) {
  out_part *p = part(o, "coupler");
  if (!p) return proto_fail(err, "too many output groups");
  out_set *set = find_set(p, dataset);
  if (!set) {
    if (add_set(o, p, dataset, ncols, columns, err) < 0) return -1;
    set = &p->sets[p->nsets - 1];
  }
  keep_last(p, dataset, ncols, row);
  return io(o, proto_series_append(set->series, row, err));
}

int cpl_output_flush(cpl_output *o, proto_err *err) {
  return o ? io(o, proto_h5_flush(o->h5, err)) : 0;
}

int64_t cpl_output_pending_bytes(const cpl_output *o) {
  /* the series' row buffers (the coupler's own, made at the first step, are
   * in the margin) and HDF5's metadata of what a step adds: a few object
   * headers, chunk-index nodes; generous */
  const int64_t margin = 1 << 20;
  return margin + (int64_t)(o ? proto_h5_buffer_bytes(o->h5) : 0);
}

int cpl_output_endpoints(cpl_output *o, const char *control, const char *bus,
                         proto_err *err) {
  return io(o, proto_h5_attr_str(o->h5, "/", "control_endpoint", control, err) < 0 ||
                       proto_h5_attr_str(o->h5, "/", "bus_monitor", bus, err) < 0
                   ? -1
                   : 0);
}

int cpl_output_summary(const cpl_output *o, char *out, size_t cap) {
  size_t len = 0;
  out[0] = 0;
  for (int i = 0; i < o->nparts && len < cap; i++) {
    const out_part *p = &o->parts[i];
    if (!p->have_last) continue;
    len += (size_t)snprintf(out + len, cap - len, "  %s:", p->name);
    for (int c = 0; c < p->ncols && len < cap; c++)
      len += (size_t)snprintf(out + len, cap - len, " %s=%.6g", p->columns[c],
                              p->last[c]);
    if (len < cap) len += (size_t)snprintf(out + len, cap - len, "\n");
  }
  return 0;
}

int cpl_output_close(cpl_output *o, proto_err *err) {
  if (!o) return 0;
  int rc = 0;
  for (int i = 0; i < o->nparts; i++)
    if (o->parts[i].xdmf && proto_xdmf_close(o->parts[i].xdmf) < 0 && rc == 0)
      rc = proto_fail(err, "%s/%s.xdmf: cannot write: %s (errno %d)", o->dir,
                      o->parts[i].name, strerror(errno), errno);
  if (o->h5 && proto_h5_close(o->h5, rc < 0 ? NULL : err) < 0) rc = -1;
  free(o);
  return rc;
}
