/* scenario_lugmap.c — the block grid laid on each lug face (scenario
 * tire_road, docs/tire-road.md "The face's shape"): which face triangle lies
 * under each of a lug process's cells, the face's shape under the cells (the
 * blocks' base, lug.base) and the cells' forces back onto the face's nodes
 * (lug.cell_force). One linear interpolation and its transpose, so the
 * forces the tread gets sum to the blocks' and have their moment. Pure
 * functions, like scenario_lugs.c. */
#include "coupler.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* A cell on the edge between two triangles, or on the face's border, lies in
 * both to round-off: its barycentric coordinates may be this far below 0
 * (relative) and still count as inside. */
#define LUGMAP_EDGE_TOL 1e-9

/* (lug j's nodes at rest, rim frame) -> (their place in the plane tangent at
 * the face's area centre: u along the circumference, +x at the bottom, v
 * along the axle; m) */
static void face_plane(const cpl_lugs *L, int j, const double *x0, double (*uv)[2]) {
  double c[3] = {0, 0, 0};
  for (int32_t e = L->start[j]; e < L->start[j + 1]; e++)
    for (int d = 0; d < 3; d++) c[d] += L->weight[e] / L->area[j] * x0[3 * (size_t)L->node[e] + d];
  const double r = hypot(c[0], c[2]); /* the axle along y: e_r = (c_x, 0, c_z) / r */
  const double t[2] = {r > 0 ? -c[2] / r : 1, r > 0 ? c[0] / r : 0}; /* e_t (x, z): e_r = -z gives +x */
  for (int32_t e = L->start[j]; e < L->start[j + 1]; e++) {
    const double *p = &x0[3 * (size_t)L->node[e]];
    uv[L->node[e]][0] = (p[0] - c[0]) * t[0] + (p[2] - c[2]) * t[1];
    uv[L->node[e]][1] = p[1] - c[1];
  }
}

/* The barycentric coordinates of q in the triangle (a, b, c); 0 if degenerate. */
static int barycentric(const double *a, const double *b, const double *c, const double *q,
                       double l[3]) {
  const double det = (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]);
  const double scale = fabs(b[0] - a[0]) + fabs(b[1] - a[1]) + fabs(c[0] - a[0]) + fabs(c[1] - a[1]);
  if (!(fabs(det) > 1e-12 * scale * scale)) return 0;
  l[1] = ((q[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (q[1] - a[1])) / det;
  l[2] = ((b[0] - a[0]) * (q[1] - a[1]) - (q[0] - a[0]) * (b[1] - a[1])) / det;
  l[0] = 1 - l[1] - l[2];
  return 1;
}

/* (surface at rest, the grid's cell centres) -> (each lug's cells on its
 * face triangles) */
int cpl_lugs_map(cpl_lugs *L, const double *x0, const int32_t *tri, int64_t n_tris,
                 const double *cell_xy, int cells, proto_err *err) {
  free(L->cell_node), free(L->cell_w);
  L->cell_node = NULL, L->cell_w = NULL, L->cells = cells, L->covered = 0;
  int32_t nn = 0; /* nodes up to the largest on a face */
  for (int32_t e = 0; e < L->start[L->n]; e++) nn = L->node[e] + 1 > nn ? L->node[e] + 1 : nn;
  const size_t slots = (size_t)L->n * (size_t)cells * 3;
  int32_t *lug_of = malloc(sizeof(int32_t) * (size_t)nn);
  double(*uv)[2] = malloc(sizeof(double[2]) * (size_t)nn);
  double *best = malloc(sizeof(double) * (size_t)L->n * (size_t)cells); /* min coordinate */
  double *face_area = calloc((size_t)L->n, sizeof(double)); /* in the tangent plane */
  L->cell_node = malloc(sizeof(int32_t) * slots);
  L->cell_w = calloc(slots, sizeof(double));
  if (!lug_of || !uv || !best || !face_area || !L->cell_node || !L->cell_w) {
    free(lug_of), free(uv), free(best), free(face_area);
    return proto_fail(err, "out of memory (the lug processes' %d cells on %d lug faces)", cells,
                      L->n);
  }
  for (int32_t i = 0; i < nn; i++) lug_of[i] = -1;
  for (int j = 0; j < L->n; j++) {
    for (int32_t e = L->start[j]; e < L->start[j + 1]; e++) lug_of[L->node[e]] = j;
    face_plane(L, j, x0, uv);
  }
  for (size_t s = 0; s < slots; s++) L->cell_node[s] = -1;
  for (size_t s = 0; s < (size_t)L->n * (size_t)cells; s++) best[s] = -INFINITY;
  for (int64_t t = 0; t < n_tris; t++) { /* each face triangle takes the cells it covers */
    const int32_t *v = &tri[3 * t];
    if (v[0] >= nn || v[1] >= nn || v[2] >= nn) continue;
    const int j = lug_of[v[0]];
    if (j < 0 || lug_of[v[1]] != j || lug_of[v[2]] != j) continue;
    const double *a = uv[v[0]], *b = uv[v[1]], *c = uv[v[2]];
    const double lo[2] = {fmin(a[0], fmin(b[0], c[0])), fmin(a[1], fmin(b[1], c[1]))};
    const double hi[2] = {fmax(a[0], fmax(b[0], c[0])), fmax(a[1], fmax(b[1], c[1]))};
    const double pad = LUGMAP_EDGE_TOL * (hi[0] - lo[0] + hi[1] - lo[1]);
    face_area[j] += 0.5 * fabs((b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]));
    for (int q = 0; q < cells; q++) {
      const double *p = &cell_xy[2 * q];
      double l[3];
      if (p[0] < lo[0] - pad || p[0] > hi[0] + pad || p[1] < lo[1] - pad || p[1] > hi[1] + pad ||
          !barycentric(a, b, c, p, l))
        continue;
      const double m = fmin(l[0], fmin(l[1], l[2]));
      const size_t at = (size_t)j * (size_t)cells + (size_t)q;
      if (m < -LUGMAP_EDGE_TOL || m <= best[at]) continue; /* the triangle it lies deepest in */
      best[at] = m;
      for (int k = 0; k < 3; k++) L->cell_node[3 * at + k] = v[k], L->cell_w[3 * at + k] = l[k];
    }
  }
  double h[2] = {INFINITY, INFINITY}; /* the grid's spacing: a cell's area is h[0] h[1] */
  for (int q = 0; q < cells; q++)
    for (int d = 0; d < 2; d++) {
      const double gap = fabs(cell_xy[2 * q + d] - cell_xy[d]);
      if (gap > 0) h[d] = fmin(h[d], gap);
    }
  const double cell_area = isfinite(h[0]) && isfinite(h[1]) ? h[0] * h[1] : 0;
  L->covered = 1, L->beyond = 0;
  for (int j = 0; j < L->n; j++) {
    int on = 0;
    for (int q = 0; q < cells; q++) on += L->cell_node[3 * ((size_t)j * (size_t)cells + (size_t)q)] >= 0;
    L->covered = fmin(L->covered, cells > 0 ? (double)on / cells : 0);
    if (cell_area > 0) L->beyond = fmax(L->beyond, 1 - on * cell_area / face_area[j]);
  }
  free(lug_of), free(uv), free(best), free(face_area);
  return 0;
}

/* (lug j's face at x) -> (the blocks' base under each cell, m) */
void cpl_lug_base(const cpl_lugs *L, int j, const double *x, double *base) {
  double zbar = 0; /* the face's mean height, as cpl_lug_approach takes it */
  for (int32_t e = L->start[j]; e < L->start[j + 1]; e++)
    zbar += L->weight[e] * x[3 * (size_t)L->node[e] + 2];
  zbar /= L->area[j];
  const int32_t *n = &L->cell_node[3 * (size_t)j * (size_t)L->cells];
  const double *w = &L->cell_w[3 * (size_t)j * (size_t)L->cells];
  for (int q = 0; q < L->cells; q++, n += 3, w += 3)
    base[q] = n[0] < 0 ? CPL_LUG_OFF_FACE
                       : zbar - (w[0] * x[3 * (size_t)n[0] + 2] + w[1] * x[3 * (size_t)n[1] + 2] +
                                 w[2] * x[3 * (size_t)n[2] + 2]);
}

/* (the cells' forces) -> (lug j's nodal forces, += f) */
double cpl_lug_spread_cells(const cpl_lugs *L, int j, const double *cell_force, double *f) {
  const int32_t *n = &L->cell_node[3 * (size_t)j * (size_t)L->cells];
  const double *w = &L->cell_w[3 * (size_t)j * (size_t)L->cells];
  double sum = 0;
  for (int q = 0; q < L->cells; q++, n += 3, w += 3) {
    if (n[0] < 0 || cell_force[q] == 0) continue;
    for (int k = 0; k < 3; k++) f[3 * (size_t)n[k] + 2] += w[k] * cell_force[q];
    sum += cell_force[q];
  }
  return sum;
}
