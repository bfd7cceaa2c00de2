/* lgd_topo.c — which edges and corners of a triangle mesh take part in
 * contact, by LIGGGHTS 3.8's own rule (SurfaceMesh::buildNeighbours,
 * handleSharedEdge, handleCorner in surface_mesh_I.h), re-evaluated on the
 * current shape. LIGGGHTS evaluates it once at set-up: on a tread that starts
 * flat every interior edge and corner stays inactive, and a grain pressed onto
 * a ridge that forms later falls through it (docs/liggghts.md §2).
 *
 * The rule:
 * - an edge of one triangle only (a boundary) is active;
 * - an edge shared by triangles a < b (global ids): if they are coplanar
 *   (|n_a·n_b| ≥ curvature) and not folded over each other, inactive on both
 *   (a grain there touches a face); otherwise active on b only (one contact);
 * - a corner: take the fan of edge-connected triangles around the node; if two
 *   of its distinct incident edges are colinear (|d_i·d_j| > curvature) or none
 *   of the fan's incident edges is active, inactive everywhere; otherwise
 *   active on the fan's highest triangle id only. */
#include "liggghts_dem/lgd.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct edge_rec {
  int32_t a, b, slot; /* a < b; slot = tri*3 + k */
} edge_rec;

static int cmp_edge(const void *p, const void *q) {
  const edge_rec *x = p, *y = q;
  if (x->a != y->a) return x->a < y->a ? -1 : 1;
  if (x->b != y->b) return x->b < y->b ? -1 : 1;
  return x->slot < y->slot ? -1 : x->slot > y->slot;
}

static int find_root(int32_t *parent, int32_t i) {
  while (parent[i] != i) i = parent[i] = parent[parent[i]];
  return i;
}

/* Edges: unique node pairs, the triangles on each (CSR). */
static int build_edges(lgd_topo *t, proto_err *err) {
  const int nslot = 3 * t->n_tri;
  edge_rec *r = malloc(sizeof *r * (size_t)(nslot ? nslot : 1));
  t->tri_edge = malloc(sizeof(int32_t) * (size_t)(nslot ? nslot : 1));
  t->edge_node = malloc(sizeof(int32_t) * 2 * (size_t)(nslot ? nslot : 1));
  t->edge_start = malloc(sizeof(int32_t) * (size_t)(nslot + 1));
  t->edge_tri = malloc(sizeof(int32_t) * (size_t)(nslot ? nslot : 1));
  if (!r || !t->tri_edge || !t->edge_node || !t->edge_start || !t->edge_tri) {
    free(r);
    return proto_fail(err, "surface topology: out of memory");
  }
  for (int s = 0; s < nslot; s++) {
    int32_t u = t->tri[s], v = t->tri[3 * (s / 3) + (s % 3 + 1) % 3];
    r[s] = (edge_rec){u < v ? u : v, u < v ? v : u, s};
  }
  qsort(r, (size_t)nslot, sizeof *r, cmp_edge);
  int ne = 0;
  for (int s = 0; s < nslot; s++) {
    if (s == 0 || r[s].a != r[s - 1].a || r[s].b != r[s - 1].b) {
      t->edge_node[2 * ne] = r[s].a;
      t->edge_node[2 * ne + 1] = r[s].b;
      t->edge_start[ne++] = s;
    }
    t->edge_tri[s] = r[s].slot / 3; /* ascending triangle within an edge */
    t->tri_edge[r[s].slot] = ne - 1;
  }
  t->edge_start[ne] = nslot;
  t->n_edges = ne;
  free(r);
  t->dir = malloc(sizeof(double) * 3 * (size_t)(ne ? ne : 1));
  t->normal = malloc(sizeof(double) * 3 * (size_t)(t->n_tri ? t->n_tri : 1));
  return t->dir && t->normal ? 0 : proto_fail(err, "surface topology: out of memory");
}

/* Fans: per node, the triangles around it split into edge-connected groups
 * (LIGGGHTS walks from a triangle through its edge neighbours). */
static int build_fans(lgd_topo *t, proto_err *err) {
  const int nslot = 3 * t->n_tri, nn = t->n_nodes;
  int32_t *start = calloc((size_t)nn + 1, sizeof(int32_t));
  int32_t *slots = malloc(sizeof(int32_t) * (size_t)(nslot ? nslot : 1));
  int32_t *parent = malloc(sizeof(int32_t) * (size_t)(nslot ? nslot : 1));
  t->corner_fan = malloc(sizeof(int32_t) * (size_t)(nslot ? nslot : 1));
  t->fan_start = malloc(sizeof(int32_t) * (size_t)(nslot + 1));
  t->fan_slot = malloc(sizeof(int32_t) * (size_t)(nslot ? nslot : 1));
  t->fan_edge_start = malloc(sizeof(int32_t) * (size_t)(nslot + 1));
  t->fan_edge = malloc(sizeof(int32_t) * 2 * (size_t)(nslot ? nslot : 1));
  int rc = 0;
  if (!start || !slots || !parent || !t->corner_fan || !t->fan_start || !t->fan_slot ||
      !t->fan_edge_start || !t->fan_edge) {
    rc = proto_fail(err, "surface topology: out of memory");
    goto out;
  }
  for (int s = 0; s < nslot; s++) start[t->tri[s] + 1]++;
  for (int v = 0; v < nn; v++) start[v + 1] += start[v];
  {
    int32_t *fill = malloc(sizeof(int32_t) * (size_t)(nn ? nn : 1));
    if (!fill) { rc = proto_fail(err, "surface topology: out of memory"); goto out; }
    memcpy(fill, start, sizeof(int32_t) * (size_t)nn);
    for (int s = 0; s < nslot; s++) slots[fill[t->tri[s]]++] = s;
    free(fill);
  }
  for (int s = 0; s < nslot; s++) parent[s] = s;
  /* two slots of a node are in one fan when their triangles share an edge
   * through the node, i.e. a second node */
  for (int v = 0; v < nn; v++)
    for (int i = start[v]; i < start[v + 1]; i++)
      for (int j = i + 1; j < start[v + 1]; j++) {
        const int32_t *a = &t->tri[3 * (slots[i] / 3)], *b = &t->tri[3 * (slots[j] / 3)];
        int shared = 0;
        for (int k = 0; k < 3; k++)
          for (int l = 0; l < 3; l++) shared += a[k] == b[l];
        if (shared >= 2) {
          int ri = find_root(parent, slots[i]), rj = find_root(parent, slots[j]);
          if (ri != rj) parent[ri] = rj;
        }
      }
  /* number the fans (one per root), then list their slots and edges (CSR) */
  int nf = 0, nfe = 0;
  for (int s = 0; s < nslot; s++) t->corner_fan[s] = -1;
  for (int v = 0; v < nn; v++)
    for (int i = start[v]; i < start[v + 1]; i++) {
      const int r = find_root(parent, slots[i]);
      if (t->corner_fan[r] < 0) t->corner_fan[r] = nf++; /* the root is a slot of this node */
    }
  for (int s = 0; s < nslot; s++) t->corner_fan[s] = t->corner_fan[find_root(parent, s)];
  memset(t->fan_start, 0, sizeof(int32_t) * (size_t)(nf + 1));
  for (int s = 0; s < nslot; s++) t->fan_start[t->corner_fan[s] + 1]++;
  for (int f = 0; f < nf; f++) t->fan_start[f + 1] += t->fan_start[f];
  memcpy(parent, t->fan_start, sizeof(int32_t) * (size_t)nf); /* reuse as fill pointers */
  for (int s = 0; s < nslot; s++) t->fan_slot[parent[t->corner_fan[s]]++] = s;
  for (int f = 0; f < nf; f++) {
    t->fan_edge_start[f] = nfe;
    for (int p = t->fan_start[f]; p < t->fan_start[f + 1]; p++) {
      /* the slot's two incident edges (k→k+1 and k−1→k), once each */
      const int s = t->fan_slot[p], tr = s / 3, k = s % 3;
      const int32_t cand[2] = {t->tri_edge[3 * tr + k], t->tri_edge[3 * tr + (k + 2) % 3]};
      for (int c = 0; c < 2; c++) {
        int seen = 0;
        for (int e = t->fan_edge_start[f]; e < nfe && !seen; e++) seen = t->fan_edge[e] == cand[c];
        if (!seen) t->fan_edge[nfe++] = cand[c];
      }
    }
  }
  t->fan_edge_start[nf] = nfe;
  t->n_fans = nf;
out:
  free(start);
  free(slots);
  free(parent);
  return rc;
}

int lgd_topo_build(lgd_topo *t, int n_nodes, int n_tri, const int32_t *tri, proto_err *err) {
  memset(t, 0, sizeof *t);
  t->n_nodes = n_nodes;
  t->n_tri = n_tri;
  t->tri = tri;
  for (int i = 0; i < 3 * n_tri; i++)
    if (tri[i] < 0 || tri[i] >= n_nodes)
      return proto_fail(err, "surface_tri[%d]: node %d outside [0, %d)", i / 3, (int)tri[i], n_nodes);
  if (build_edges(t, err) || build_fans(t, err)) {
    lgd_topo_free(t);
    return -1;
  }
  return 0;
}

void lgd_topo_free(lgd_topo *t) {
  free(t->edge_node); free(t->tri_edge); free(t->edge_start); free(t->edge_tri);
  free(t->corner_fan); free(t->fan_start); free(t->fan_slot); free(t->fan_edge_start);
  free(t->fan_edge); free(t->normal); free(t->dir);
  memset(t, 0, sizeof *t);
}

static double dot3(const double *a, const double *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

/* LIGGGHTS' coplanarNeighsOverlap: the third nodes of both triangles lie on
 * the same side of the shared edge (a fold), which counts as not coplanar. */
static int folded(const lgd_topo *t, const double *x, int ta, int tb, int e) {
  const int32_t u = t->edge_node[2 * e], w = t->edge_node[2 * e + 1];
  double side[3], pa[3], pb[3];
  const double *d = &t->dir[3 * e], *n = &t->normal[3 * ta];
  side[0] = d[1] * n[2] - d[2] * n[1];
  side[1] = d[2] * n[0] - d[0] * n[2];
  side[2] = d[0] * n[1] - d[1] * n[0];
  int32_t ca = -1, cb = -1;
  for (int k = 0; k < 3; k++) {
    if (t->tri[3 * ta + k] != u && t->tri[3 * ta + k] != w) ca = t->tri[3 * ta + k];
    if (t->tri[3 * tb + k] != u && t->tri[3 * tb + k] != w) cb = t->tri[3 * tb + k];
  }
  for (int k = 0; k < 3; k++) {
    pa[k] = x[3 * ca + k] - x[3 * u + k];
    pb[k] = x[3 * cb + k] - x[3 * u + k];
  }
  return dot3(pa, side) * dot3(pb, side) > 0;
}

void lgd_topo_activity(lgd_topo *t, const double *x, uint8_t *edge_active, uint8_t *corner_active) {
  const double curv = LGD_CURVATURE;
  /* unit edge vectors: differences, then one branch-free pass that the
   * compiler vectorises (LIGGGHTS refuses zero-length edges: lgd_open) */
  for (int e = 0; e < t->n_edges; e++)
    for (int k = 0; k < 3; k++)
      t->dir[3 * e + k] = x[3 * t->edge_node[2 * e + 1] + k] - x[3 * t->edge_node[2 * e] + k];
  for (int e = 0; e < t->n_edges; e++) {
    double *d = &t->dir[3 * e];
    const double il = 1.0 / sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    d[0] *= il; d[1] *= il; d[2] *= il;
  }
  for (int i = 0; i < t->n_tri; i++) { /* LIGGGHTS: unit edge 0 × unit edge 1 */
    const int32_t *n = &t->tri[3 * i];
    const int e0 = t->tri_edge[3 * i], e1 = t->tri_edge[3 * i + 1];
    /* the edges are stored from the lower node: flip to the triangle's sense */
    const double s = (n[0] == t->edge_node[2 * e0] ? 1.0 : -1.0) * (n[1] == t->edge_node[2 * e1] ? 1.0 : -1.0);
    const double *a = &t->dir[3 * e0], *b = &t->dir[3 * e1];
    double *c = &t->normal[3 * i];
    c[0] = s * (a[1] * b[2] - a[2] * b[1]);
    c[1] = s * (a[2] * b[0] - a[0] * b[2]);
    c[2] = s * (a[0] * b[1] - a[1] * b[0]);
    const double il = 1.0 / sqrt(dot3(c, c)); /* degenerate triangles: refused (lgd_open) */
    for (int k = 0; k < 3; k++) c[k] *= il;
  }
  memset(edge_active, 1, 3 * (size_t)t->n_tri);
  for (int e = 0; e < t->n_edges; e++) {
    const int s0 = t->edge_start[e], s1 = t->edge_start[e + 1];
    for (int p = s0; p < s1; p++)
      for (int q = p + 1; q < s1; q++) {
        const int ta = t->edge_tri[p], tb = t->edge_tri[q]; /* ta < tb */
        const int coplanar = fabs(dot3(&t->normal[3 * ta], &t->normal[3 * tb])) >= curv;
        for (int k = 0; k < 3; k++) {
          if (t->tri_edge[3 * ta + k] == e)
            edge_active[3 * ta + k] = 0;
          if (t->tri_edge[3 * tb + k] == e)
            edge_active[3 * tb + k] = coplanar && !folded(t, x, ta, tb, e) ? 0 : 1;
        }
      }
  }
  memset(corner_active, 0, 3 * (size_t)t->n_tri);
  for (int f = 0; f < t->n_fans; f++) {
    int any = 0, top = -1;
    for (int p = t->fan_start[f]; p < t->fan_start[f + 1]; p++) {
      const int s = t->fan_slot[p], tr = s / 3, k = s % 3;
      any |= edge_active[3 * tr + k] | edge_active[3 * tr + (k + 2) % 3];
      if (top < 0 || tr > t->fan_slot[top] / 3) top = p;
    }
    int colinear = 0;
    for (int i = t->fan_edge_start[f]; i < t->fan_edge_start[f + 1] && !colinear; i++)
      for (int j = i + 1; j < t->fan_edge_start[f + 1] && !colinear; j++)
        colinear = fabs(dot3(&t->dir[3 * t->fan_edge[i]], &t->dir[3 * t->fan_edge[j]])) > curv;
    if (any && !colinear) corner_active[t->fan_slot[top]] = 1;
  }
}
