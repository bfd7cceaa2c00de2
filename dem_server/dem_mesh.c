/* dem_mesh.c — sphere–triangle contacts (seed 000 §4.2–4.4): BVH over the
 * triangles, closest point with face/edge/vertex classification by the
 * barycentric coordinates ζ (eq. 35), one force per grain for a shared edge or
 * vertex, and the reaction distributed onto the nodes by ζ (eq. 42). */
#include "dem_server/dem_internal.h"

#include <float.h>
#include <stdlib.h>
#include <string.h>

/* ------------------------------------------------------------ geometry */

/* Ericson, Real-Time Collision Detection §5.1.5, returning the barycentric
 * weights (ζ_a, ζ_b, ζ_c) of the closest point q; clamped cases give exact zeros. */
void dem_closest_on_triangle(const double *p, const double *a, const double *b,
                             const double *c, double *q, double *zeta) {
  double ab[3], ac[3], ap[3], bp[3], cp[3];
  for (int k = 0; k < 3; k++) {
    ab[k] = b[k] - a[k]; ac[k] = c[k] - a[k]; ap[k] = p[k] - a[k];
    bp[k] = p[k] - b[k]; cp[k] = p[k] - c[k];
  }
  double u = 1, v = 0, w = 0;
  const double d1 = dem_dot(ab, ap), d2 = dem_dot(ac, ap);
  const double d3 = dem_dot(ab, bp), d4 = dem_dot(ac, bp);
  const double d5 = dem_dot(ab, cp), d6 = dem_dot(ac, cp);
  const double vc = d1 * d4 - d3 * d2, vb = d5 * d2 - d1 * d6, va = d3 * d6 - d5 * d4;
  if (d1 <= 0 && d2 <= 0) {
    u = 1; v = 0; w = 0;
  } else if (d3 >= 0 && d4 <= d3) {
    u = 0; v = 1; w = 0;
  } else if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    v = d1 / (d1 - d3); u = 1 - v; w = 0;
  } else if (d6 >= 0 && d5 <= d6) {
    u = 0; v = 0; w = 1;
  } else if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    w = d2 / (d2 - d6); u = 1 - w; v = 0;
  } else if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    w = (d4 - d3) / ((d4 - d3) + (d5 - d6)); v = 1 - w; u = 0;
  } else {
    const double denom = 1.0 / (va + vb + vc);
    v = vb * denom; w = vc * denom; u = 1 - v - w;
  }
  zeta[0] = u; zeta[1] = v; zeta[2] = w;
  for (int k = 0; k < 3; k++) q[k] = u * a[k] + v * b[k] + w * c[k];
}

/* ----------------------------------------------------------------- BVH */

static void tri_box(const double *x, const int32_t *t, double *lo, double *hi) {
  for (int k = 0; k < 3; k++) {
    double a = x[3 * t[0] + k], b = x[3 * t[1] + k], c = x[3 * t[2] + k];
    lo[k] = dem_min(a, dem_min(b, c));
    hi[k] = dem_max(a, dem_max(b, c));
  }
}

typedef struct build_ctx {
  dem_bvh *b;
  const double *x;
  const int32_t *tri;
  int32_t *ids;
  double *key;
  int next;
} build_ctx;

/* Orders ids by key (shell sort; build time only, no qsort context needed). */
static void sort_range(int32_t *ids, double *key, int n) {
  for (int gap = n / 2; gap > 0; gap /= 2)
    for (int i = gap; i < n; i++) {
      double k = key[i];
      int32_t id = ids[i];
      int j = i;
      for (; j >= gap && key[j - gap] > k; j -= gap) { key[j] = key[j - gap]; ids[j] = ids[j - gap]; }
      key[j] = k; ids[j] = id;
    }
}

/* Splits the triangles ids[lo..hi) in half along the longest axis of their
 * centroids (seed 000 §4.2: halved by extent and by count). */
static int build_node(build_ctx *c, int lo, int hi) {
  dem_bvh *b = c->b;
  int node = c->next++;
  double blo[3] = {DBL_MAX, DBL_MAX, DBL_MAX}, bhi[3] = {-DBL_MAX, -DBL_MAX, -DBL_MAX};
  double clo[3] = {DBL_MAX, DBL_MAX, DBL_MAX}, chi[3] = {-DBL_MAX, -DBL_MAX, -DBL_MAX};
  for (int i = lo; i < hi; i++) {
    double tl[3], th[3];
    tri_box(c->x, &c->tri[3 * c->ids[i]], tl, th);
    for (int k = 0; k < 3; k++) {
      blo[k] = fmin(blo[k], tl[k]); bhi[k] = fmax(bhi[k], th[k]);
      double m = 0.5 * (tl[k] + th[k]);
      clo[k] = fmin(clo[k], m); chi[k] = fmax(chi[k], m);
    }
  }
  memcpy(&b->lo[3 * node], blo, sizeof blo);
  memcpy(&b->hi[3 * node], bhi, sizeof bhi);
  if (hi - lo == 1) {
    b->left[node] = ~c->ids[lo];
    b->right[node] = -1;
    return node;
  }
  int axis = 0;
  for (int k = 1; k < 3; k++)
    if (chi[k] - clo[k] > chi[axis] - clo[axis]) axis = k;
  for (int i = lo; i < hi; i++) {
    double tl[3], th[3];
    tri_box(c->x, &c->tri[3 * c->ids[i]], tl, th);
    c->key[i] = tl[axis] + th[axis];
  }
  sort_range(&c->ids[lo], &c->key[lo], hi - lo);
  int mid = lo + (hi - lo) / 2;
  b->left[node] = build_node(c, lo, mid);
  b->right[node] = build_node(c, mid, hi);
  return node;
}

static double box_area_sum(const dem_bvh *b) {
  double s = 0;
  for (int i = 0; i < b->n_nodes; i++) {
    double e[3];
    for (int k = 0; k < 3; k++) e[k] = b->hi[3 * i + k] - b->lo[3 * i + k];
    s += 2 * (e[0] * e[1] + e[1] * e[2] + e[2] * e[0]);
  }
  return s;
}

int dem_bvh_build(dem_bvh *b, const double *x, const int32_t *tri, int n_tri) {
  int nn = n_tri > 0 ? 2 * n_tri - 1 : 0;
  if (nn > b->n_nodes || !b->lo) {
    dem_bvh_free(b);
    b->lo = malloc(sizeof(double) * 3 * (size_t)(nn + 1));
    b->hi = malloc(sizeof(double) * 3 * (size_t)(nn + 1));
    b->left = malloc(sizeof(int32_t) * (size_t)(nn + 1));
    b->right = malloc(sizeof(int32_t) * (size_t)(nn + 1));
    if (!b->lo || !b->hi || !b->left || !b->right) return -1;
  }
  b->n_nodes = nn;
  if (n_tri == 0) return 0;
  build_ctx c = {b, x, tri, malloc(sizeof(int32_t) * (size_t)n_tri),
                 malloc(sizeof(double) * (size_t)n_tri), 0};
  if (!c.ids || !c.key) { free(c.ids); free(c.key); return -1; }
  for (int i = 0; i < n_tri; i++) c.ids[i] = i;
  build_node(&c, 0, n_tri);
  free(c.ids);
  free(c.key);
  b->area_built = box_area_sum(b);
  return 0;
}

void dem_bvh_refit(dem_bvh *b, const double *x, const int32_t *tri) {
  for (int i = b->n_nodes - 1; i >= 0; i--) {
    if (b->left[i] < 0) {
      tri_box(x, &tri[3 * (~b->left[i])], &b->lo[3 * i], &b->hi[3 * i]);
    } else {
      int l = b->left[i], r = b->right[i];
      for (int k = 0; k < 3; k++) {
        b->lo[3 * i + k] = dem_min(b->lo[3 * l + k], b->lo[3 * r + k]);
        b->hi[3 * i + k] = dem_max(b->hi[3 * l + k], b->hi[3 * r + k]);
      }
    }
  }
}

void dem_bvh_free(dem_bvh *b) {
  free(b->lo); free(b->hi); free(b->left); free(b->right);
  memset(b, 0, sizeof *b);
}

static inline int sphere_box(const double *p, double r, const double *lo, const double *hi) {
  double d2 = 0;
  for (int k = 0; k < 3; k++) {
    double e = p[k] < lo[k] ? lo[k] - p[k] : (p[k] > hi[k] ? p[k] - hi[k] : 0);
    d2 += e * e;
  }
  return d2 < r * r;
}

/* ------------------------------------------------------- state / motion */

int dem_mesh_alloc(const dem_model *m, dem_state *s, proto_err *err) {
  struct dem_work *w = s->work;
  size_t nk = (size_t)s->n * DEM_MESH_SLOTS;
  for (int mi = 0; mi < m->n_meshes; mi++) {
    const dem_mesh *me = &m->meshes[mi];
    size_t bytes = sizeof(double) * 3 * (size_t)(me->n_nodes ? me->n_nodes : 1);
    s->mesh_x[mi] = malloc(bytes);
    s->mesh_v[mi] = calloc(1, bytes);
    s->mesh_force[mi] = calloc(1, bytes);
    if (!s->mesh_x[mi] || !s->mesh_v[mi] || !s->mesh_force[mi])
      return proto_fail(err, "out of memory for mesh %d", mi);
    memcpy(s->mesh_x[mi], me->x0, bytes);
    for (int a = 0; a < me->n_nodes; a++) memcpy(&s->mesh_v[mi][3 * a], me->velocity, 3 * sizeof(double));
    dem_mesh_velocities_changed(m, s, mi);
    if (dem_bvh_build(&w->bvh[mi], s->mesh_x[mi], me->tri, me->n_tri))
      return proto_fail(err, "out of memory for the BVH of mesh %d", mi);
  }
  if (m->n_meshes == 0) return 0;
  for (int mi = 0; mi < m->n_meshes; mi++) {
    if (m->meshes[mi].n_tri >= 1 << DEM_TRI_BITS)
      return proto_fail(err, "mesh %d: %d triangles, at most %d", mi, m->meshes[mi].n_tri, (1 << DEM_TRI_BITS) - 1);
    if (!(w->mesh_xref[mi] = malloc(sizeof(double) * 3 * (size_t)(m->meshes[mi].n_nodes + 1))) ||
        !(w->mesh_node_moved[mi] = calloc((size_t)m->meshes[mi].n_nodes + 1, 1)))
      return proto_fail(err, "out of memory for mesh %d", mi);
  }
  w->ml_start = calloc((size_t)s->n + 1, sizeof(int));
  w->ml_cbuf = calloc((size_t)w->nchunk, sizeof(int32_t *));
  w->ml_cbuf_cap = calloc((size_t)w->nchunk, sizeof(int));
  w->mc_key = calloc(nk, sizeof(int64_t));
  w->mc_tri = calloc(nk, sizeof(int32_t));
  w->mc_mesh = calloc(nk, 1);
  w->mc_shear = calloc(3 * nk, sizeof(double));
  w->mc_normal = calloc(3 * nk, sizeof(double));
  w->mc_zeta = calloc(3 * nk, sizeof(double));
  w->mc_force = calloc(3 * nk, sizeof(double));
  w->mc_couple = calloc(3 * nk, sizeof(double));
  w->mesh_f = calloc(3 * (size_t)s->n, sizeof(double));
  w->chunk_mesh = calloc((size_t)w->nchunk + 1, 1);
  w->mesh_t = calloc(3 * (size_t)s->n, sizeof(double));
  if (!w->mc_key || !w->mc_tri || !w->mc_mesh || !w->mc_shear || !w->mc_normal || !w->mc_zeta ||
      !w->mc_force || !w->mc_couple || !w->mesh_f || !w->mesh_t || !w->chunk_mesh || !w->ml_start || !w->ml_cbuf || !w->ml_cbuf_cap)
    return proto_fail(err, "out of memory for mesh contacts");
  return 0;
}

void dem_mesh_free(const dem_model *m, dem_state *s) {
  struct dem_work *w = s->work;
  for (int mi = 0; mi < DEM_MAX_MESHES; mi++) {
    free(s->mesh_x[mi]); free(s->mesh_v[mi]); free(s->mesh_force[mi]);
    s->mesh_x[mi] = s->mesh_v[mi] = s->mesh_force[mi] = NULL;
    dem_bvh_free(&w->bvh[mi]);
    free(w->mesh_xref[mi]);
    free(w->mesh_node_moved[mi]);
    w->mesh_node_moved[mi] = NULL;
  }
  if (w->ml_cbuf)
    for (int c = 0; c < w->nchunk; c++) free(w->ml_cbuf[c]);
  free(w->ml_cbuf); free(w->ml_cbuf_cap); free(w->ml_start); free(w->ml_key);
  (void)m;
  free(w->mc_key); free(w->mc_tri); free(w->mc_mesh); free(w->mc_shear); free(w->mc_normal);
  free(w->mc_zeta); free(w->mc_force); free(w->mc_couple); free(w->mesh_f); free(w->mesh_t); free(w->chunk_mesh);
}

/* Meshes move with their node velocities (constant for rigid meshes, the
 * FEM's velocities between two coupling steps). The BVH is refitted only
 * when the candidate lists are rebuilt (dem_mesh_lists). */
void dem_mesh_move(const dem_model *m, dem_state *s, double dt) {
  double vmax = 0; /* of all meshes: the active region's guard (dem_sleep_guard) */
  for (int mi = 0; mi < m->n_meshes; mi++) {
    const dem_mesh *me = &m->meshes[mi];
    double *x = s->mesh_x[mi];
    const double *v = s->mesh_v[mi];
    if (!s->work->mesh_moving[mi]) continue; /* all velocities zero */
    for (int a = 0; a < 3 * me->n_nodes; a++) x[a] += v[a] * dt;
    s->work->mesh_moved[mi] += s->work->mesh_vmax[mi] * dt; /* a bound on any node's move */
    vmax = s->work->mesh_vmax[mi] > vmax ? s->work->mesh_vmax[mi] : vmax;
  }
  s->work->region_moved += vmax * dt;
}

/* A mesh moves if any node velocity is not zero; one that starts moving
 * needs its lists (and the sleep "near" flags) redone. */
void dem_mesh_velocities_changed(const dem_model *m, dem_state *s, int mi) {
  const double *v = s->mesh_v[mi];
  double v2 = 0;
  for (int a = 0; a < m->meshes[mi].n_nodes; a++) {
    const double q = dem_dot(&v[3 * a], &v[3 * a]);
    v2 = q > v2 ? q : v2;
  }
  const int moving = v2 > 0;
  if (moving && !s->work->mesh_moving[mi]) s->work->lists_dirty = 1;
  s->work->mesh_moving[mi] = (uint8_t)moving;
  s->work->mesh_vmax[mi] = sqrt(v2);
}

/* New node positions of a far mesh (dem_mesh_set_nodes): how far they are
 * from where the lists were built (its far test, dem_mesh_lists_check). */
void dem_mesh_nodes_set(const dem_model *m, dem_state *s, int mi) {
  struct dem_work *w = s->work;
  if (!w->mesh_far[mi] || !w->mesh_xref[mi]) return;
  const double *x = s->mesh_x[mi], *x0 = w->mesh_xref[mi];
  double worst = 0;
  for (int a = 0; a < m->meshes[mi].n_nodes; a++) {
    const double d0 = x[3 * a] - x0[3 * a], d1 = x[3 * a + 1] - x0[3 * a + 1], d2 = x[3 * a + 2] - x0[3 * a + 2];
    const double dd = d0 * d0 + d1 * d1 + d2 * d2;
    worst = dd > worst ? dd : worst;
  }
  w->mesh_moved[mi] = isfinite(worst) ? sqrt(worst) : INFINITY;
}

void dem_bvh_update(dem_bvh *b, const double *x, const int32_t *tri, int n_tri) {
  dem_bvh_refit(b, x, tri);
  if (box_area_sum(b) > 2.0 * b->area_built) dem_bvh_build(b, x, tri, n_tri);
}

/* ------------------------------------------------------------ contacts */

typedef struct cand {
  int mesh, tri, feat;   /* feat: DEM_FEAT_*, the count of fnode */
  int32_t fnode[3]; /* the nodes of the feature the closest point lies on */
  int64_t key;
  double q[3], zeta[3], d2;
} cand;
#define MAX_CAND 64

/* Feature key: kind, mesh and the sorted node ids of the feature (a face by
 * its triangle). Unique across meshes; never 0. */
static int64_t feature_key(int mesh, int feat, int64_t a, int64_t b) {
  return ((int64_t)feat << 60) | ((int64_t)mesh << 56) | (a << 28) | b;
}

static void classify(cand *c, const int32_t *t) {
  const double eps = 1e-12; /* ζ below this counts as zero (on an edge/vertex) */
  int cnt = 0;
  for (int k = 0; k < 3; k++)
    if (c->zeta[k] > eps) c->fnode[cnt++] = t[k];
  if (cnt == 0) c->fnode[cnt++] = t[0]; /* degenerate: all ζ tiny */
  c->feat = cnt; /* DEM_FEAT_* is the feature's node count */
  const int64_t a = c->fnode[0], b = cnt > 1 ? c->fnode[1] : 0;
  if (cnt == DEM_FEAT_FACE) c->key = feature_key(c->mesh, DEM_FEAT_FACE, 0, c->tri);
  else if (cnt == DEM_FEAT_EDGE) c->key = feature_key(c->mesh, DEM_FEAT_EDGE, a < b ? a : b, a < b ? b : a);
  else c->key = feature_key(c->mesh, DEM_FEAT_VERTEX, 0, a);
}

/* Whether triangle t holds every node of c's feature (so the closest point). */
static int holds_feature(const int32_t *t, const cand *c) {
  for (int k = 0; k < c->feat; k++)
    if (t[0] != c->fnode[k] && t[1] != c->fnode[k] && t[2] != c->fnode[k]) return 0;
  return 1;
}

/* Candidates are kept sorted by (mesh, triangle), the MAX_CAND first ones if
 * there are more: the order (and so the force sums) does not depend on the
 * BVH's shape, which differs after a rebuild or a state import. */
static int insert_cand(cand *out, int nc, const cand *c) {
  int k = nc < MAX_CAND ? nc : MAX_CAND - 1;
  if (nc == MAX_CAND && (out[k].mesh < c->mesh || (out[k].mesh == c->mesh && out[k].tri < c->tri)))
    return nc; /* full, and c comes after every kept one */
  for (; k > 0 && (out[k - 1].mesh > c->mesh || (out[k - 1].mesh == c->mesh && out[k - 1].tri > c->tri)); k--)
    out[k] = out[k - 1];
  out[k] = *c;
  return nc < MAX_CAND ? nc + 1 : nc;
}

/* Touching triangles of grain i among its candidates (in (mesh, triangle)
 * order already). */
static int collect(const dem_model *m, const dem_state *s, int i, cand *out) {
  const struct dem_work *w = s->work;
  int nc = 0;
  const double *p = &s->x[3 * i];
  const double r = s->radius[i];
  for (int k = w->ml_start[i]; k < w->ml_start[i + 1]; k++) {
    const int mi = w->ml_key[k] >> DEM_TRI_BITS, t = w->ml_key[k] & ((1 << DEM_TRI_BITS) - 1);
    if (s->mesh_live[mi] && !s->mesh_live[mi][t]) continue; /* stale nodes (dem_nodeset.c) */
    const double *x = s->mesh_x[mi];
    const int32_t *tn = &m->meshes[mi].tri[3 * t];
    cand c = {.mesh = mi, .tri = t};
    dem_closest_on_triangle(p, &x[3 * tn[0]], &x[3 * tn[1]], &x[3 * tn[2]], c.q, c.zeta);
    double d[3] = {p[0] - c.q[0], p[1] - c.q[1], p[2] - c.q[2]};
    c.d2 = dem_dot(d, d);
    if (c.d2 >= r * r || c.d2 == 0) continue;
    classify(&c, tn);
    nc = insert_cand(out, nc, &c);
  }
  return nc;
}

/* ------------------------------------------------- mesh candidate lists
 * Per grain, the triangles within r + skin (closest point) when the list was
 * built; valid while no grain moved more than skin/2 (the grain list rebuild
 * criterion: dem_neigh_rebuild rebuilds these too) and no mesh node moved
 * more than skin/2: a triangle left out stays farther than r. So the BVH is
 * walked (and refitted) only at rebuilds, not per grain and step. */

/* Triangles of mesh mi within `reach` of p into keys (room for `room`), in
 * increasing triangle order; the count, or −1 when out of room. */
static int bvh_query(const dem_bvh *b, const double *x, const int32_t *tri, int mi, const double *p, double reach,
                     int32_t *keys, int room) {
  int cnt = 0, stack[64], sp = 0;
  if (b->n_nodes == 0) return 0;
  stack[sp++] = 0;
  while (sp > 0) {
    const int nd = stack[--sp];
    if (!sphere_box(p, reach, &b->lo[3 * nd], &b->hi[3 * nd])) continue;
    if (b->left[nd] >= 0) {
      stack[sp++] = b->right[nd]; /* depth ≤ log2(triangles) + 1 (median splits) */
      stack[sp++] = b->left[nd];
      continue;
    }
    const int t = ~b->left[nd];
    const int32_t *tn = &tri[3 * t];
    double q[3], z[3];
    dem_closest_on_triangle(p, &x[3 * tn[0]], &x[3 * tn[1]], &x[3 * tn[2]], q, z);
    const double d[3] = {p[0] - q[0], p[1] - q[1], p[2] - q[2]};
    if (dem_dot(d, d) >= reach * reach) continue;
    if (cnt == room) return -1;
    int k = cnt++;
    const int32_t key = (int32_t)(mi << DEM_TRI_BITS | t);
    for (; k > 0 && keys[k - 1] > key; k--) keys[k] = keys[k - 1];
    keys[k] = key;
  }
  return cnt;
}

/* Lists of grains lo..hi−1 into the chunk's buffer; lengths into ml_start[i + 1]. */
static int lists_chunk(const dem_model *m, dem_state *s, int c, int lo, int hi) {
  struct dem_work *w = s->work;
  int used = 0;
  for (int i = lo; i < hi; i++) {
    const double *p = &s->x[3 * i], reach = s->radius[i] + m->skin;
    int got = 0;
    if (i >= w->n_active) { /* asleep: outside the region, no mesh comes near (dem_sleep.c) */
      w->ml_start[i + 1] = 0;
      continue;
    }
    for (int mi = 0; mi < m->n_meshes; mi++) {
      const dem_bvh *b = &w->bvh[mi];
      if (b->n_nodes == 0 || !sphere_box(p, reach, b->lo, b->hi)) continue; /* most grains */
      int k;
      while ((k = bvh_query(b, s->mesh_x[mi], m->meshes[mi].tri, mi, p, reach, w->ml_cbuf[c] + used + got,
                            w->ml_cbuf_cap[c] - used - got)) < 0) {
        const int cap = 2 * w->ml_cbuf_cap[c] + 256;
        int32_t *nb = realloc(w->ml_cbuf[c], sizeof(int32_t) * (size_t)cap);
        if (!nb) return -1;
        w->ml_cbuf[c] = nb;
        w->ml_cbuf_cap[c] = cap;
      }
      got += k;
    }
    w->ml_start[i + 1] = got;
    used += got;
  }
  return 0;
}

/* Which meshes are far from every awake grain: the distance between the
 * mesh's node box and the box of the awake grains' centres, minus r_max +
 * skin (the list reach), is the gap; such a mesh has no candidates, and the
 * lists stay valid while no node moved more than gap + skin/2 (the grains move
 * less than skin/2 before the next rebuild, which builds these lists again):
 * a surface far from every grain costs one comparison per step
 * (dem_mesh_lists_check), not a scan of its nodes. */
static void far_meshes(const dem_model *m, dem_state *s) {
  struct dem_work *w = s->work;
  const int na = w->n_active;
  double glo[3] = {INFINITY, INFINITY, INFINITY}, ghi[3] = {-INFINITY, -INFINITY, -INFINITY}, rmax = 0;
  for (int i = 0; i < na; i++) {
    for (int k = 0; k < 3; k++) {
      glo[k] = dem_min(glo[k], s->x[3 * i + k]);
      ghi[k] = dem_max(ghi[k], s->x[3 * i + k]);
    }
    rmax = dem_max(rmax, s->radius[i]);
  }
  w->grains_rmax = rmax;
  for (int mi = 0; mi < m->n_meshes; mi++) {
    const dem_bvh *b = &w->bvh[mi]; /* refitted: its root is the node box */
    w->mesh_far[mi] = 0;
    w->mesh_moved[mi] = 0;
    if (b->n_nodes == 0 || na == 0) continue;
    double d2 = 0;
    for (int k = 0; k < 3; k++) {
      const double e = fmax(0.0, fmax(b->lo[k] - ghi[k], glo[k] - b->hi[k]));
      d2 += e * e;
    }
    const double gap = sqrt(d2) - rmax - m->skin;
    w->mesh_gap[mi] = gap;
    w->mesh_far[mi] = gap > 0;
  }
}

/* The lists of every grain from the current positions (refits the BVHs). */
int dem_mesh_lists_build(const dem_model *m, dem_state *s, proto_err *err) {
  struct dem_work *w = s->work;
  /* the awake grains only (slots [0, n_active)): an asleep grain touches no
   * mesh and has no candidates (dem_sleep.c), so its rows stay empty */
  const int n = w->n_active, nchunk = (n + DEM_CHUNK - 1) / DEM_CHUNK;
  for (int mi = 0; mi < m->n_meshes; mi++) {
    const dem_mesh *me = &m->meshes[mi];
    dem_bvh_update(&w->bvh[mi], s->mesh_x[mi], me->tri, me->n_tri);
  }
  int oom = 0;
#pragma omp parallel for schedule(dynamic, 1) num_threads(w->nthreads) reduction(| : oom)
  for (int c = 0; c < nchunk; c++)
    oom |= lists_chunk(m, s, c, c * DEM_CHUNK, (c + 1) * DEM_CHUNK < n ? (c + 1) * DEM_CHUNK : n) != 0;
  if (oom) return proto_fail(err, "out of memory for the mesh contact candidates");
  w->ml_start[0] = 0;
  for (int i = 0; i < n; i++) w->ml_start[i + 1] += w->ml_start[i];
  for (int i = n; i < s->n; i++) w->ml_start[i + 1] = w->ml_start[n]; /* asleep: no candidates */
  for (int c = nchunk; c < w->nchunk; c++) w->chunk_mesh[c] = 0;
  const size_t total = (size_t)w->ml_start[n];
  if (total > w->ml_cap) {
    int32_t *k = realloc(w->ml_key, sizeof(int32_t) * (total + total / 4 + 64));
    if (!k) return proto_fail(err, "out of memory for %zu mesh contact candidates", total);
    w->ml_key = k;
    w->ml_cap = total + total / 4 + 64;
  }
#pragma omp parallel for schedule(dynamic, 1) num_threads(w->nthreads)
  for (int c = 0; c < nchunk; c++) {
    const int lo = c * DEM_CHUNK, hi = (c + 1) * DEM_CHUNK < n ? (c + 1) * DEM_CHUNK : n;
    const int len = w->ml_start[hi] - w->ml_start[lo];
    if (len > 0) memcpy(&w->ml_key[w->ml_start[lo]], w->ml_cbuf[c], sizeof(int32_t) * (size_t)len);
    /* a chunk without candidates and contacts skips the mesh sweep until the next build
     * (keys appear only through candidates) */
    int live = len > 0;
    for (size_t k = (size_t)lo * DEM_MESH_SLOTS; !live && k < (size_t)hi * DEM_MESH_SLOTS; k++) live = w->mc_key[k] != 0;
    w->chunk_mesh[c] = (uint8_t)live;
  }
  far_meshes(m, s);
  return 0;
}

/* Rebuild: the lists and the node positions they are valid around. */
int dem_mesh_lists(const dem_model *m, dem_state *s, proto_err *err) {
  struct dem_work *w = s->work;
  if (dem_mesh_lists_build(m, s, err)) return -1;
  for (int mi = 0; mi < m->n_meshes; mi++) {
    memcpy(w->mesh_xref[mi], s->mesh_x[mi], sizeof(double) * 3 * (size_t)m->meshes[mi].n_nodes);
    w->mesh_set[mi] = 0;
  }
  w->lists_dirty = 0;
  return 0;
}

/* Some node of mesh mi moved more than skin/2 since the build: do the lists
 * still hold? A grain i touches a triangle only within r_i of its centre. A
 * triangle whose nodes all moved at most skin/2 comes no nearer than r_i to a
 * grain it was not listed for (the grains move less than skin/2 too: the
 * Verlet argument). One with a node moved more touches no grain now if its
 * node box lies farther than r_max + skin from the box of the awake centres
 * (far_meshes' test, per triangle). The check runs at every step the mesh
 * moves or is set, right after the drift (dem_step: step_cbox holds this
 * step's awake centres; grains_rmax is the build's, and the awake set changes
 * only with a build) and before the forces, so a triangle clear now is looked
 * at again before it can touch. Clear: every triangle with a node flagged in
 * mesh_node_moved is (the caller builds the lists when a position is not
 * finite: the health check then names it). The nodes a sparse exchange did
 * not send keep their stale positions, and those coming into the sent set
 * jump from them: without this test every node entering the set rebuilt the
 * lists (5.7x the rebuilds of the dense exchange on the paper scene). */
static int moved_clear(const dem_model *m, const dem_state *s, int mi) {
  const struct dem_work *w = s->work;
  if (w->n_active == 0) return 0;
  const double *glo = w->step_cbox, *ghi = w->step_cbox + 3; /* this step's drift: the awake centres */
  const double reach = w->grains_rmax + m->skin;
  const dem_mesh *me = &m->meshes[mi];
  const double *x = s->mesh_x[mi];
  const uint8_t *moved = w->mesh_node_moved[mi];
  for (int t = 0; t < me->n_tri; t++) {
    const int32_t *tn = &me->tri[3 * t];
    if (!(moved[tn[0]] | moved[tn[1]] | moved[tn[2]])) continue;
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (int a = 0; a < 3; a++) {
      const double *p = &x[3 * (size_t)tn[a]];
      for (int k = 0; k < 3; k++) {
        lo[k] = dem_min(lo[k], p[k]);
        hi[k] = dem_max(hi[k], p[k]);
      }
    }
    double e2 = 0;
    for (int k = 0; k < 3; k++) {
      const double e = dem_max(0.0, dem_max(lo[k] - ghi[k], glo[k] - hi[k]));
      e2 += e * e;
    }
    if (!(e2 > reach * reach)) return 0; /* near a grain */
  }
  return 1;
}

void dem_mesh_list_counts(const dem_state *s, int64_t *built, int64_t *kept) {
  *built = s->work->mesh_builds;
  *kept = s->work->mesh_clear;
}

int dem_mesh_lists_check(const dem_model *m, dem_state *s, proto_err *err) {
  const double lim2 = 0.25 * m->skin * m->skin;
  if (s->work->lists_dirty) return dem_mesh_lists(m, s, err);
  for (int mi = 0; mi < m->n_meshes; mi++) {
    if (!s->work->mesh_moving[mi] && !s->work->mesh_set[mi]) continue; /* not moved since the build */
    if (s->work->mesh_far[mi]) { /* far from every grain: one comparison */
      if (s->work->mesh_moved[mi] < s->work->mesh_gap[mi] + 0.5 * m->skin) continue;
      s->work->mesh_builds++;
      return dem_mesh_lists(m, s, err);
    }
    const double *x = s->mesh_x[mi], *x0 = s->work->mesh_xref[mi];
    uint8_t *moved = s->work->mesh_node_moved[mi];
    int any = 0, finite = 1;
    for (int a = 0; a < m->meshes[mi].n_nodes; a++) {
      const double d0 = x[3 * a] - x0[3 * a], d1 = x[3 * a + 1] - x0[3 * a + 1], d2 = x[3 * a + 2] - x0[3 * a + 2];
      const double dd = d0 * d0 + d1 * d1 + d2 * d2;
      moved[a] = !(dd <= lim2); /* or not finite */
      any |= moved[a];
      finite &= isfinite(dd);
    }
    if (!any) continue;
    if (finite && moved_clear(m, s, mi)) {
      s->work->mesh_clear++;
      continue;
    }
    s->work->mesh_builds++;
    return dem_mesh_lists(m, s, err); /* moved near a grain, or not finite */
  }
  return 0;
}

/* One force per touched patch. A face contact is a local minimum of the
 * distance to the surface: always kept (concave corners touch several faces).
 * An edge or vertex contact at q is one only if q is a local minimum over the
 * triangles around it; else one of them holds a point nearer the grain (the
 * squared distance is convex on a triangle, so a local minimum on it is its
 * minimum) — q is a shadow of that nearer contact and dropped. Candidates in
 * order of distance (faces first), the rule is: drop an edge or vertex contact
 * whose feature an earlier candidate's triangle holds (an edge shared by two
 * triangles, a vertex by a fan, the neighbours' shadows on a flat or convex
 * patch). A triangle that merely shares a node with a nearer one can still
 * carry a true contact: a grain on a groove's floor touching the lug's convex
 * edge above it. */
static int dedupe(const dem_model *m, cand *c, int nc) {
  int na = 0;
  for (int k = 0; k < nc; k++) /* faces first */
    if (c[k].feat == DEM_FEAT_FACE) {
      cand t = c[na]; c[na] = c[k]; c[k] = t;
      na++;
    }
  for (int a = na; a < nc; a++) /* the rest by distance (insertion sort, few) */
    for (int b = a; b > na && c[b].d2 < c[b - 1].d2; b--) {
      cand t = c[b]; c[b] = c[b - 1]; c[b - 1] = t;
    }
  int nkeep = na;
  for (int k = na; k < nc; k++) {
    int keep = 1;
    for (int a = 0; a < k && keep; a++)
      if (c[a].mesh == c[k].mesh && holds_feature(&m->meshes[c[a].mesh].tri[3 * c[a].tri], &c[k])) keep = 0;
    if (keep) { /* move to the kept prefix; seen candidates stay before k */
      cand t = c[k];
      for (int b = k; b > nkeep; b--) c[b] = c[b - 1];
      c[nkeep++] = t;
    }
  }
  return nkeep;
}

/* History of a new contact: same feature key, else a contact of the same mesh
 * whose normal hardly turned (the grain moved over an edge onto the next
 * triangle: one continuing contact). */
static void find_history(const int64_t *okey, const int8_t *omesh, const double *onormal,
                         const double *oshear, uint8_t *used, const cand *c,
                         const double *n, double *shear) {
  const int K = DEM_MESH_SLOTS;
  int best = -1;
  for (int k = 0; k < K && best < 0; k++)
    if (okey[k] == c->key && !used[k]) best = k;
  for (int k = 0; k < K && best < 0; k++)
    if (okey[k] != 0 && !used[k] && omesh[k] == c->mesh && dem_dot(&onormal[3 * k], n) > 0.9)
      best = k;
  if (best < 0) { shear[0] = shear[1] = shear[2] = 0; return; }
  used[best] = 1;
  memcpy(shear, &oshear[3 * best], 3 * sizeof(double));
}

/* Mesh contacts of grain i: force and torque into mesh_f/mesh_t, contact
 * slots (history), its overlap ratio; elastic energy added to *u. Returns
 * the number of contacts. */
int dem_mesh_grain(const dem_model *m, dem_state *s, int i, double *u) {
  struct dem_work *w = s->work;
  const int K = DEM_MESH_SLOTS;
  cand c[MAX_CAND];
  int nc = collect(m, s, i, c);
  nc = dedupe(m, c, nc);
  if (nc > K) nc = K;
  int64_t okey[DEM_MESH_SLOTS];
  int8_t omesh[DEM_MESH_SLOTS];
  double onormal[3 * DEM_MESH_SLOTS], oshear[3 * DEM_MESH_SLOTS];
  uint8_t used[DEM_MESH_SLOTS] = {0};
  size_t base = (size_t)i * K;
  memcpy(okey, &w->mc_key[base], sizeof okey);
  memcpy(omesh, &w->mc_mesh[base], sizeof omesh);
  memcpy(onormal, &w->mc_normal[3 * base], sizeof onormal);
  memcpy(oshear, &w->mc_shear[3 * base], sizeof oshear);
  double *f = &w->mesh_f[3 * i], *t = &w->mesh_t[3 * i];
  f[0] = f[1] = f[2] = t[0] = t[1] = t[2] = 0;
  const double r = s->radius[i], mass = w->mass[i];
  for (int k = 0; k < K; k++) w->mc_key[base + k] = 0;
  for (int k = 0; k < nc; k++) {
    const dem_mesh *me = &m->meshes[c[k].mesh];
    const int32_t *tn = &me->tri[3 * c[k].tri];
    const double dist = sqrt(c[k].d2);
    double n[3], vc[3], wxn[3], F[3], nxf[3];
    for (int d = 0; d < 3; d++) n[d] = (s->x[3 * i + d] - c[k].q[d]) / dist;
    double *shear = &w->mc_shear[3 * (base + k)];
    find_history(okey, omesh, onormal, oshear, used, &c[k], n, shear);
    /* contact point velocities: grain at −(r − δ/2) n (LIGGGHTS' contact point
     * in the middle of the overlap); the wall's interpolated by ζ */
    const double delta = r - dist, cr = r - 0.5 * delta;
    dem_cross(&s->omega[3 * i], n, wxn);
    const double *vn = s->mesh_v[c[k].mesh];
    for (int d = 0; d < 3; d++)
      vc[d] = s->v[3 * i + d] - cr * wxn[d] -
              (c[k].zeta[0] * vn[3 * tn[0] + d] + c[k].zeta[1] * vn[3 * tn[1] + d] +
               c[k].zeta[2] * vn[3 * tn[2] + d]);
    const dem_pair_law *l = &m->law[s->material[i]][me->material];
    double up;
    double Fn = dem_hertz(l, delta, r, mass, n, vc, s->dt, shear, F, nxf, &up);
    double tr[3] = {0, 0, 0};
    if (m->has_rolling && l->mu_roll > 0) {
      dem_rolling(l, Fn, r, &s->omega[3 * i], tr);
      for (int d = 0; d < 3; d++) t[d] += tr[d];
    }
    /* the grain's moment about the closest point q: its contact point is
     * (dist - cr) n = -δ/2 n from q, plus the rolling torque; with
     * surface_couple the nodes take minus that besides their ζ-shares of -F
     * (dem_mesh_reactions) */
    double *couple = &w->mc_couple[3 * (base + k)];
    for (int d = 0; d < 3; d++) {
      f[d] += F[d];
      t[d] -= cr * nxf[d];
      couple[d] = 0.5 * delta * nxf[d] - tr[d];
    }
    w->mc_key[base + k] = c[k].key;
    w->mc_mesh[base + k] = (int8_t)c[k].mesh;
    w->mc_tri[base + k] = c[k].tri;
    memcpy(&w->mc_normal[3 * (base + k)], n, sizeof n);
    memcpy(&w->mc_zeta[3 * (base + k)], c[k].zeta, sizeof c[k].zeta);
    memcpy(&w->mc_force[3 * (base + k)], F, sizeof F);
    *u += up;
    if (delta / r > w->ratio[i]) w->ratio[i] = delta / r;
  }
  return nc;
}

/* Adds to the nodal forces of triangle tn a pure couple of moment M (zero
 * sum): the least-norm one, h_a = b × e_a with e_a = x_a − centroid and
 * J b = M, J = Σ (|e_a|² I − e_a e_aᵀ) (then Σ e_a × h_a = J b = M). */
static void add_couple(const double *x, const int32_t *tn, const double *M, double *nf) {
  if (M[0] == 0 && M[1] == 0 && M[2] == 0) return;
  double e[3][3], cen[3] = {0, 0, 0}, J[9] = {0};
  for (int a = 0; a < 3; a++)
    for (int d = 0; d < 3; d++) cen[d] += x[3 * tn[a] + d] / 3;
  for (int a = 0; a < 3; a++) {
    for (int d = 0; d < 3; d++) e[a][d] = x[3 * tn[a] + d] - cen[d];
    const double e2 = dem_dot(e[a], e[a]);
    for (int p = 0; p < 3; p++)
      for (int q = 0; q < 3; q++) J[3 * p + q] += (p == q ? e2 : 0) - e[a][p] * e[a][q];
  }
  /* Cramer's rule; J is positive definite unless the triangle is degenerate */
  const double det = J[0] * (J[4] * J[8] - J[5] * J[7]) - J[1] * (J[3] * J[8] - J[5] * J[6]) +
                     J[2] * (J[3] * J[7] - J[4] * J[6]);
  const double scale = J[0] + J[4] + J[8];
  if (!(det > 1e-12 * scale * scale * scale)) return;
  double b[3];
  for (int c = 0; c < 3; c++) {
    double A[9];
    memcpy(A, J, sizeof A);
    for (int p = 0; p < 3; p++) A[3 * p + c] = M[p];
    b[c] = (A[0] * (A[4] * A[8] - A[5] * A[7]) - A[1] * (A[3] * A[8] - A[5] * A[6]) +
            A[2] * (A[3] * A[7] - A[4] * A[6])) / det;
  }
  for (int a = 0; a < 3; a++) {
    double h[3];
    dem_cross(b, e[a], h);
    for (int d = 0; d < 3; d++) nf[3 * tn[a] + d] += h[d];
  }
}

/* The reactions onto the nodes by ζ (seed 000 eq. 42) and the force on each
 * mesh wall: a serial sweep in slot order over the chunks that have mesh
 * contacts (dem_force.c counts them per chunk). */
void dem_mesh_reactions(const dem_model *m, dem_state *s) {
  struct dem_work *w = s->work;
  for (int mi = 0; mi < m->n_meshes; mi++)
    memset(s->mesh_force[mi], 0, sizeof(double) * 3 * (size_t)m->meshes[mi].n_nodes);
  const int K = DEM_MESH_SLOTS, nchunk = (s->n + DEM_CHUNK - 1) / DEM_CHUNK;
  for (int c = 0; c < nchunk; c++) {
    if (w->chunk[c].mesh_contacts == 0) continue;
    const int end = (c + 1) * DEM_CHUNK < s->n ? (c + 1) * DEM_CHUNK : s->n;
    for (int i = c * DEM_CHUNK; i < end; i++)
      for (int k = 0; k < K; k++) {
        size_t sl = (size_t)i * K + k;
        if (w->mc_key[sl] == 0) continue;
        int mi = w->mc_mesh[sl];
        const int32_t *tn = &m->meshes[mi].tri[3 * w->mc_tri[sl]];
        double *nf = s->mesh_force[mi];
        const double *F = &w->mc_force[3 * sl], *z = &w->mc_zeta[3 * sl];
        for (int a = 0; a < 3; a++)
          for (int d = 0; d < 3; d++) nf[3 * tn[a] + d] -= z[a] * F[d];
        if (m->surface_couple) add_couple(s->mesh_x[mi], tn, &w->mc_couple[3 * sl], nf);
        double *wf = &s->wall_force[3 * m->meshes[mi].wall];
        for (int d = 0; d < 3; d++) wf[d] -= F[d];
      }
  }
}
