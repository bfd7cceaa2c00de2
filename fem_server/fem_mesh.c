/* fem_mesh.c — mesh container, groups, checks, boundary faces, TET10 promotion. */
#include "fem_server/fem.h"
#include "fem_server/fem_internal.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Outward faces of a positively oriented tet (right-hand rule). */
const int fem_tet_face[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
/* Gmsh TET10: node 4+k sits on edge k. */
const int fem_tet10_edge[6][2] = {{0, 1}, {1, 2}, {0, 2}, {0, 3}, {2, 3}, {1, 3}};

int fem_edge_mid(int a, int b) {
  for (int k = 0; k < 6; k++)
    if ((fem_tet10_edge[k][0] == a && fem_tet10_edge[k][1] == b) ||
        (fem_tet10_edge[k][0] == b && fem_tet10_edge[k][1] == a))
      return 4 + k;
  return -1;
}

void fem_face_nodes(const fem_mesh *m, int32_t e, int f, int32_t out[6]) {
  const int32_t *c = m->conn + (size_t)e * m->nodes_per_elem;
  const int *fc = fem_tet_face[f];
  for (int i = 0; i < 3; i++) out[i] = c[fc[i]];
  if (m->nodes_per_elem == 10)
    for (int i = 0; i < 3; i++) out[3 + i] = c[fem_edge_mid(fc[i], fc[(i + 1) % 3])];
}

void fem_mesh_free(fem_mesh *m) {
  if (!m) return;
  free(m->x);
  free(m->conn);
  for (int g = 0; g < m->n_groups; g++) {
    free(m->groups[g].face_elem);
    free(m->groups[g].face_local);
  }
  free(m->groups);
  memset(m, 0, sizeof *m);
}

int fem_mesh_group(const fem_mesh *m, const char *name, proto_err *err) {
  for (int g = 0; g < m->n_groups; g++)
    if (strcmp(m->groups[g].name, name) == 0) return g;
  char list[512] = "";
  size_t len = 0;
  for (int g = 0; g < m->n_groups && len + FEM_NAME_LEN + 3 < sizeof list; g++)
    len += (size_t)snprintf(list + len, sizeof list - len, "%s%s", g ? ", " : "",
                            m->groups[g].name);
  proto_fail(err, "no surface group '%s' in the mesh (groups: %s)", name,
             m->n_groups ? list : "none");
  return -1;
}

int fem_mesh_add_group(fem_mesh *m, const char *name, proto_err *err) {
  if (strlen(name) >= FEM_NAME_LEN)
    return proto_fail(err, "group name '%s' too long", name);
  fem_group *g = realloc(m->groups, sizeof *g * (size_t)(m->n_groups + 1));
  if (!g) return proto_fail(err, "out of memory (groups)");
  m->groups = g;
  memset(&g[m->n_groups], 0, sizeof *g);
  snprintf(g[m->n_groups].name, FEM_NAME_LEN, "%s", name);
  return m->n_groups++;
}

int fem_mesh_group_add_face(fem_mesh *m, int gi, int32_t elem, int face,
                            proto_err *err) {
  fem_group *g = &m->groups[gi];
  int32_t n = g->n_faces;
  if ((n & (n - 1)) == 0) { /* grow at powers of two */
    int32_t cap = n ? 2 * n : 16;
    int32_t *fe = realloc(g->face_elem, sizeof *fe * (size_t)cap);
    if (fe) g->face_elem = fe;
    int8_t *fl = realloc(g->face_local, sizeof *fl * (size_t)cap);
    if (fl) g->face_local = fl;
    if (!fe || !fl) return proto_fail(err, "out of memory (group faces)");
  }
  g->face_elem[n] = elem;
  g->face_local[n] = (int8_t)face;
  g->n_faces = n + 1;
  return 0;
}

double fem_tet_volume6(const double *x0, const double *x1, const double *x2,
                       const double *x3) {
  double a[3], b[3], c[3];
  for (int i = 0; i < 3; i++) {
    a[i] = x1[i] - x0[i];
    b[i] = x2[i] - x0[i];
    c[i] = x3[i] - x0[i];
  }
  return a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) +
         a[2] * (b[0] * c[1] - b[1] * c[0]);
}

int fem_mesh_check(const fem_mesh *m, proto_err *err) {
  if (m->n_nodes <= 0 || m->n_elems <= 0)
    return proto_fail(err, "mesh is empty (%d nodes, %d elements)", m->n_nodes,
                      m->n_elems);
  if (m->nodes_per_elem != 4 && m->nodes_per_elem != 10)
    return proto_fail(err, "unsupported element with %d nodes", m->nodes_per_elem);
  const int npe = m->nodes_per_elem;
  uint8_t *used = calloc((size_t)m->n_nodes, 1);
  if (!used) return proto_fail(err, "out of memory");
  int rc = 0;
  for (int32_t e = 0; e < m->n_elems && rc == 0; e++) {
    const int32_t *c = m->conn + (size_t)e * npe;
    for (int a = 0; a < npe; a++) {
      if (c[a] < 0 || c[a] >= m->n_nodes) {
        rc = proto_fail(err, "element %d: node index %d out of range [0, %d)", e,
                        c[a], m->n_nodes);
        break;
      }
      used[c[a]] = 1;
    }
    if (rc) break;
    const double *x0 = m->x + 3 * (size_t)c[0], *x1 = m->x + 3 * (size_t)c[1];
    const double *x2 = m->x + 3 * (size_t)c[2], *x3 = m->x + 3 * (size_t)c[3];
    double v6 = fem_tet_volume6(x0, x1, x2, x3);
    double lmax = 0;
    const double *xs[4] = {x0, x1, x2, x3};
    for (int i = 0; i < 4; i++)
      for (int j = i + 1; j < 4; j++) {
        double d2 = 0;
        for (int k = 0; k < 3; k++) d2 += (xs[i][k] - xs[j][k]) * (xs[i][k] - xs[j][k]);
        if (d2 > lmax) lmax = d2;
      }
    lmax = sqrt(lmax);
    double rel = v6 / (lmax * lmax * lmax + 1e-300);
    if (!(fabs(rel) > 1e-9))
      rc = proto_fail(err, "element %d is degenerate (6V/l_max^3 = %.3g, nodes %d %d %d %d)",
                      e, rel, c[0], c[1], c[2], c[3]);
    else if (rel < 0)
      rc = proto_fail(err, "element %d is inverted (negative volume %.3g m^3, nodes %d %d %d %d)",
                      e, v6 / 6, c[0], c[1], c[2], c[3]);
  }
  for (int32_t i = 0; i < m->n_nodes && rc == 0; i++)
    if (!used[i])
      rc = proto_fail(err, "node %d (%g, %g, %g) belongs to no element (orphan node)",
                      i, m->x[3 * i], m->x[3 * i + 1], m->x[3 * i + 2]);
  free(used);
  return rc;
}

/* ------------------------------------------------------------- face keys */

typedef struct face_key {
  int32_t v[3]; /* sorted corners */
  int32_t elem;
  int8_t local;
} face_key;

static int face_key_cmp(const void *pa, const void *pb) {
  const face_key *a = pa, *b = pb;
  for (int i = 0; i < 3; i++)
    if (a->v[i] != b->v[i]) return a->v[i] < b->v[i] ? -1 : 1;
  return 0;
}

static void sort3(int32_t *v) {
  int32_t t;
  if (v[0] > v[1]) { t = v[0]; v[0] = v[1]; v[1] = t; }
  if (v[1] > v[2]) { t = v[1]; v[1] = v[2]; v[2] = t; }
  if (v[0] > v[1]) { t = v[0]; v[0] = v[1]; v[1] = t; }
}

/* All element faces sorted by corner set; boundary faces appear once. */
static face_key *all_faces(const fem_mesh *m, proto_err *err) {
  size_t nf = 4 * (size_t)m->n_elems;
  face_key *k = malloc(sizeof *k * nf);
  if (!k) {
    proto_fail(err, "out of memory (faces)");
    return NULL;
  }
  for (int32_t e = 0; e < m->n_elems; e++)
    for (int f = 0; f < 4; f++) {
      face_key *q = &k[4 * (size_t)e + f];
      for (int i = 0; i < 3; i++)
        q->v[i] = m->conn[(size_t)e * m->nodes_per_elem + fem_tet_face[f][i]];
      sort3(q->v);
      q->elem = e;
      q->local = (int8_t)f;
    }
  qsort(k, nf, sizeof *k, face_key_cmp);
  return k;
}

fem_face_index *fem_face_index_build(const fem_mesh *m, proto_err *err) {
  face_key *k = all_faces(m, err);
  if (!k) return NULL;
  size_t nf = 4 * (size_t)m->n_elems, nb = 0;
  for (size_t i = 0; i < nf;) {
    size_t j = i + 1;
    while (j < nf && face_key_cmp(&k[i], &k[j]) == 0) j++;
    if (j - i == 1) k[nb++] = k[i];
    i = j;
  }
  fem_face_index *ix = malloc(sizeof *ix);
  if (!ix) {
    free(k);
    proto_fail(err, "out of memory");
    return NULL;
  }
  ix->keys = k;
  ix->n = nb;
  return ix;
}

void fem_face_index_free(fem_face_index *ix) {
  if (!ix) return;
  free(ix->keys);
  free(ix);
}

int fem_face_index_find(const fem_face_index *ix, const int32_t corners[3],
                        int32_t *elem, int *local) {
  face_key q;
  memcpy(q.v, corners, sizeof q.v);
  sort3(q.v);
  const face_key *k = ix->keys;
  const face_key *hit = bsearch(&q, k, ix->n, sizeof *k, face_key_cmp);
  if (!hit) return -1;
  *elem = hit->elem;
  *local = hit->local;
  return 0;
}

int fem_mesh_add_boundary_group(fem_mesh *m, const char *name,
                                const char *const *exclude, int n_exclude,
                                proto_err *err) {
  fem_face_index *ix = fem_face_index_build(m, err);
  if (!ix) return -1;
  uint8_t *skip = calloc(ix->n ? ix->n : 1, 1);
  int rc = skip ? 0 : proto_fail(err, "out of memory");
  for (int x = 0; x < n_exclude && rc == 0; x++) {
    int g = fem_mesh_group(m, exclude[x], err);
    if (g < 0) {
      rc = -1;
      break;
    }
    for (int32_t i = 0; i < m->groups[g].n_faces; i++) {
      int32_t corners[6], e;
      int loc;
      fem_face_nodes(m, m->groups[g].face_elem[i], m->groups[g].face_local[i], corners);
      if (fem_face_index_find(ix, corners, &e, &loc) == 0) {
        const face_key *k = ix->keys;
        face_key q = {{corners[0], corners[1], corners[2]}, 0, 0};
        sort3(q.v);
        const face_key *hit = bsearch(&q, k, ix->n, sizeof *k, face_key_cmp);
        skip[hit - k] = 1;
      }
    }
  }
  int g = rc == 0 ? fem_mesh_add_group(m, name, err) : -1;
  if (g < 0) rc = -1;
  for (size_t i = 0; i < ix->n && rc == 0; i++)
    if (!skip[i]) rc = fem_mesh_group_add_face(m, g, ix->keys[i].elem, ix->keys[i].local, err);
  free(skip);
  fem_face_index_free(ix);
  return rc;
}

static int cmp_i32(const void *a, const void *b) {
  int32_t x = *(const int32_t *)a, y = *(const int32_t *)b;
  return (x > y) - (x < y);
}

int fem_group_nodes(const fem_mesh *m, int g, int32_t **out, int32_t *n,
                    proto_err *err) {
  const fem_group *gr = &m->groups[g];
  int per = m->nodes_per_elem == 10 ? 6 : 3;
  int32_t *v = malloc(sizeof *v * ((size_t)gr->n_faces * per + 1));
  if (!v) return proto_fail(err, "out of memory");
  size_t k = 0;
  for (int32_t i = 0; i < gr->n_faces; i++) {
    int32_t fn[6];
    fem_face_nodes(m, gr->face_elem[i], gr->face_local[i], fn);
    for (int j = 0; j < per; j++) v[k++] = fn[j];
  }
  qsort(v, k, sizeof *v, cmp_i32);
  size_t u = 0;
  for (size_t i = 0; i < k; i++)
    if (u == 0 || v[i] != v[u - 1]) v[u++] = v[i];
  *out = v;
  *n = (int32_t)u;
  return 0;
}

/* ------------------------------------------------------- TET10 promotion */

typedef struct edge_rec {
  int32_t a, b; /* a < b */
  int32_t slot; /* elem*6 + k */
} edge_rec;

static int edge_cmp(const void *pa, const void *pb) {
  const edge_rec *x = pa, *y = pb;
  if (x->a != y->a) return x->a < y->a ? -1 : 1;
  if (x->b != y->b) return x->b < y->b ? -1 : 1;
  return 0;
}

int fem_mesh_to_tet10(fem_mesh *m, fem_snap_fn snap, void *ctx, proto_err *err) {
  if (m->nodes_per_elem == 10) return 0;
  size_t ne = (size_t)m->n_elems, nr = 6 * ne;
  edge_rec *r = malloc(sizeof *r * nr);
  int32_t *conn = malloc(sizeof *conn * 10 * ne);
  if (!r || !conn) {
    free(r);
    free(conn);
    return proto_fail(err, "out of memory (tet10)");
  }
  for (size_t e = 0; e < ne; e++)
    for (int k = 0; k < 6; k++) {
      int32_t a = m->conn[4 * e + fem_tet10_edge[k][0]];
      int32_t b = m->conn[4 * e + fem_tet10_edge[k][1]];
      r[6 * e + k] = (edge_rec){a < b ? a : b, a < b ? b : a, (int32_t)(6 * e + k)};
    }
  qsort(r, nr, sizeof *r, edge_cmp);
  size_t n_edges = 0;
  for (size_t i = 0; i < nr; i++)
    if (i == 0 || edge_cmp(&r[i], &r[i - 1]) != 0) n_edges++;
  double *x = realloc(m->x, sizeof *x * 3 * ((size_t)m->n_nodes + n_edges));
  if (!x) {
    free(r);
    free(conn);
    return proto_fail(err, "out of memory (tet10 nodes)");
  }
  m->x = x;
  int32_t next = m->n_nodes;
  for (size_t e = 0; e < ne; e++)
    for (int a = 0; a < 4; a++) conn[10 * e + a] = m->conn[4 * e + a];
  for (size_t i = 0; i < nr; i++) {
    if (i == 0 || edge_cmp(&r[i], &r[i - 1]) != 0) {
      double *xm = x + 3 * (size_t)next;
      for (int d = 0; d < 3; d++) xm[d] = 0.5 * (x[3 * (size_t)r[i].a + d] + x[3 * (size_t)r[i].b + d]);
      if (snap) snap(ctx, x + 3 * (size_t)r[i].a, x + 3 * (size_t)r[i].b, xm);
      next++;
    }
    size_t e = (size_t)r[i].slot / 6;
    int k = r[i].slot % 6;
    conn[10 * e + 4 + k] = next - 1;
  }
  free(r);
  free(m->conn);
  m->conn = conn;
  m->n_nodes = next;
  m->nodes_per_elem = 10;
  return 0;
}
