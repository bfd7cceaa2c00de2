/* scenario_lugs.c — the physics of scenario tire_road (docs/tire-road.md):
 * the tread's lug faces found on its surface, each face's approach towards
 * the road plane, which lug process serves which lug, a block's force
 * spread back onto its face's nodes (force and moment kept), and the road's
 * penalty on the nodes off the lug faces. Pure functions, like scenario.c;
 * scenario_step.c moves their values into the fields. */
#include "coupler.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static int32_t root_of(int32_t *up, int32_t i) {
  while (up[i] != i) i = up[i] = up[up[i]];
  return i;
}

/* The surface triangles whose three nodes lie on the outer radius. */
static int on_top(const uint8_t *top, const int32_t *t) { return top[t[0]] && top[t[1]] && top[t[2]]; }

static double tri_area(const double *x0, const int32_t *t) {
  const double *a = &x0[3 * t[0]], *b = &x0[3 * t[1]], *c = &x0[3 * t[2]];
  const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  const double v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
  const double w[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2],
                       u[0] * v[1] - u[1] * v[0]};
  return 0.5 * sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
}

void cpl_lugs_free(cpl_lugs *L) {
  free(L->start);
  free(L->node);
  free(L->weight);
  free(L->area);
  free(L->on_lug);
  free(L->cell_node);
  free(L->cell_w);
  memset(L, 0, sizeof *L);
}

/* (surface x0, triangles) -> (lug faces: connected sets of top triangles) */
int cpl_lugs_find(const double *x0, int64_t n, const int32_t *tri, int64_t m, double tol,
                  cpl_lugs *L, proto_err *err) {
  memset(L, 0, sizeof *L);
  double ro = 0; /* axle along y: the radius is sqrt(x^2 + z^2) */
  for (int64_t i = 0; i < n; i++) ro = fmax(ro, hypot(x0[3 * i], x0[3 * i + 2]));
  L->outer_radius = ro;
  uint8_t *top = calloc((size_t)n + 1, 1);
  int32_t *up = malloc(sizeof(int32_t) * ((size_t)n + 1));
  int32_t *lug_of = malloc(sizeof(int32_t) * ((size_t)n + 1));
  double *w = calloc((size_t)n + 1, sizeof(double));
  L->on_lug = calloc((size_t)n + 1, 1);
  if (!top || !up || !lug_of || !w || !L->on_lug) goto oom;
  for (int64_t i = 0; i < n; i++) {
    top[i] = hypot(x0[3 * i], x0[3 * i + 2]) >= ro - tol;
    up[i] = (int32_t)i;
    lug_of[i] = -1;
  }
  for (int64_t t = 0; t < m; t++) {
    const int32_t *v = &tri[3 * t];
    if (!on_top(top, v)) continue;
    const double a = tri_area(x0, v) / 3;
    for (int k = 0; k < 3; k++) {
      w[v[k]] += a;
      L->on_lug[v[k]] = 1;
      int32_t p = root_of(up, v[0]), q = root_of(up, v[k]);
      if (p != q) up[q < p ? p : q] = q < p ? q : p; /* the smaller index is the root */
    }
  }
  for (int64_t i = 0; i < n; i++) /* lugs numbered by their smallest node */
    if (L->on_lug[i] && root_of(up, (int32_t)i) == i) lug_of[i] = (int32_t)L->n++;
  if (L->n == 0) {
    free(top), free(up), free(lug_of), free(w);
    cpl_lugs_free(L);
    return proto_fail(err, "scenario tire_road: the tread surface has no lug faces (no "
                      "triangle with all its nodes within scenario.lug_tolerance = %g m of "
                      "the outer radius %g m)", tol, ro);
  }
  L->start = calloc((size_t)L->n + 1, sizeof(int32_t));
  L->area = calloc((size_t)L->n, sizeof(double));
  int64_t on = 0;
  for (int64_t i = 0; i < n; i++) on += L->on_lug[i];
  L->node = malloc(sizeof(int32_t) * (size_t)on);
  L->weight = malloc(sizeof(double) * (size_t)on);
  int32_t *fill = calloc((size_t)L->n, sizeof(int32_t)); /* the next place of each lug */
  if (!L->start || !L->area || !L->node || !L->weight || !fill) {
    free(fill);
    goto oom;
  }
  for (int64_t i = 0; i < n; i++)
    if (L->on_lug[i]) L->start[lug_of[root_of(up, (int32_t)i)] + 1]++;
  for (int j = 0; j < L->n; j++) L->start[j + 1] += L->start[j], fill[j] = L->start[j];
  for (int64_t i = 0; i < n; i++) { /* each lug's nodes in ascending order */
    if (!L->on_lug[i]) continue;
    const int32_t j = lug_of[root_of(up, (int32_t)i)], at = fill[j]++;
    L->node[at] = (int32_t)i;
    L->weight[at] = w[i];
    L->area[j] += w[i];
  }
  free(fill), free(top), free(up), free(lug_of), free(w);
  return 0;
oom:
  free(top), free(up), free(lug_of), free(w);
  cpl_lugs_free(L);
  return proto_fail(err, "out of memory (lugs)");
}

double cpl_lug_approach(const cpl_lugs *L, int j, const double *x, double road_z) {
  double z = 0;
  for (int32_t e = L->start[j]; e < L->start[j + 1]; e++)
    z += L->weight[e] * x[3 * (size_t)L->node[e] + 2];
  return road_z - z / L->area[j];
}

double cpl_lug_reach(const cpl_lugs *L, int j, const double *x, double road_z) {
  double z = INFINITY;
  for (int32_t e = L->start[j]; e < L->start[j + 1]; e++) z = fmin(z, x[3 * (size_t)L->node[e] + 2]);
  return road_z - z;
}

void cpl_lug_centre(const cpl_lugs *L, int j, const double *x, double c[2]) {
  c[0] = c[1] = 0;
  for (int32_t e = L->start[j]; e < L->start[j + 1]; e++)
    for (int d = 0; d < 2; d++) c[d] += L->weight[e] / L->area[j] * x[3 * (size_t)L->node[e] + d];
}

/* (block force F, centre of pressure) -> (lug j's nodal forces, += f) */
void cpl_lug_spread(const cpl_lugs *L, int j, const double *x, double F, const double cop[2],
                    double *f) {
  const double A = L->area[j];
  double c[2], S[3] = {0, 0, 0}; /* centre; second moment xx, xy, yy */
  cpl_lug_centre(L, j, x, c);
  for (int32_t e = L->start[j]; e < L->start[j + 1]; e++) {
    const double *p = &x[3 * (size_t)L->node[e]], a = L->weight[e] / A;
    const double q[2] = {p[0] - c[0], p[1] - c[1]};
    S[0] += a * q[0] * q[0], S[1] += a * q[0] * q[1], S[2] += a * q[1] * q[1];
  }
  const double det = S[0] * S[2] - S[1] * S[1];
  double b[2] = {0, 0}; /* S b = cop; a degenerate face takes the force at its centre */
  if (det > 1e-12 * (S[0] + S[2]) * (S[0] + S[2]) && det > 0) {
    b[0] = (S[2] * cop[0] - S[1] * cop[1]) / det;
    b[1] = (S[0] * cop[1] - S[1] * cop[0]) / det;
  }
  for (int32_t e = L->start[j]; e < L->start[j + 1]; e++) {
    const double *p = &x[3 * (size_t)L->node[e]];
    const double q[2] = {p[0] - c[0], p[1] - c[1]};
    f[3 * (size_t)L->node[e] + 2] += F * L->weight[e] / A * (1 + b[0] * q[0] + b[1] * q[1]);
  }
}

/* (each lug's approach, each process's last force) -> (who serves which lug) */
int cpl_lug_assign(cpl_lug_slots *S, int n_lugs, const double *d, double engage,
                   const double *force, proto_err *err) {
  int held_by[CPL_LUG_MAX_LUGS];
  if (n_lugs > CPL_LUG_MAX_LUGS)
    return proto_fail(err, "scenario tire_road: %d lugs (at most %d)", n_lugs, CPL_LUG_MAX_LUGS);
  for (int j = 0; j < n_lugs; j++) held_by[j] = -1;
  for (int s = 0; s < S->n; s++) {
    S->reset[s] = 0;
    const int j = S->lug[s];
    if (j < 0) continue;
    if (d[j] < -engage && force[s] == 0) S->lug[s] = -1; /* left the road, nothing held */
    else held_by[j] = s;
  }
  for (;;) { /* the nearest lug without a process, while there is one within engage */
    int best = -1;
    for (int j = 0; j < n_lugs; j++)
      if (held_by[j] < 0 && d[j] >= -engage && (best < 0 || d[j] > d[best])) best = j;
    if (best < 0) return 0;
    int free_slot = -1;
    for (int s = 0; s < S->n && free_slot < 0; s++)
      if (S->lug[s] < 0) free_slot = s;
    if (free_slot < 0)
      return proto_fail(err, "scenario tire_road: lug %d comes within scenario.lug_engage = %g m "
                        "of the road while all %d lug processes serve other lugs: add "
                        "processes of role lug", best, engage, S->n);
    S->lug[free_slot] = best;
    S->reset[free_slot] = 1;
    S->handovers++;
    held_by[best] = free_slot;
  }
}

double cpl_road_penalty(const cpl_lugs *L, const double *x, int64_t n, double road_z, double k,
                        double *f) {
  double sum = 0;
  for (int64_t i = 0; i < n; i++) {
    const double pen = road_z - x[3 * i + 2];
    if (L->on_lug[i] || !(pen > 0)) continue;
    f[3 * i + 2] += k * pen;
    sum += k * pen;
  }
  return sum;
}
