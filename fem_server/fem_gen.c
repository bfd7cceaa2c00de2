/* fem_gen.c — structured tetrahedral meshes: box, cylinder, lugged tread band.
 *
 * Each generator maps a structured (i, j, k) hexahedral grid to space and
 * splits every active cell into the 6 Kuhn (Freudenthal) tetrahedra around
 * its 0-7 diagonal. The split is translation invariant, so neighbouring
 * cells (also across a periodic seam) share face diagonals: conforming. */
#include "fem_server/fem.h"
#include "fem_server/fem_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct grid_spec {
  int n[3];            /* cells along i, j, k */
  int periodic_j;      /* j wraps around (full ring) */
  const uint8_t *active; /* [n0*n1*n2] or NULL = all, index i + n0*(j + n1*k) */
  void (*map)(const void *ctx, int i, int j, int k, double *x);
  const void *ctx;
} grid_spec;

/* Returns the group index (0-based in `names`) of a boundary face from the
 * grid indices of its 3 corners, or -1 for none. */
typedef int (*face_classifier)(const void *ctx, const int ijk[3][3]);

static int grid_mesh(fem_mesh *m, const grid_spec *g, int32_t **node_ijk,
                     proto_err *err) {
  const int n0 = g->n[0], n1 = g->n[1], n2 = g->n[2];
  if (n0 < 1 || n1 < 1 || n2 < 1 || (double)n0 * n1 * n2 > FEM_MAX_ELEMS / 6)
    return proto_fail(err, "grid of %d x %d x %d cells: more than the %lld elements (6 per "
                      "cell) a mesh may have", n0, n1, n2, (long long)FEM_MAX_ELEMS);
  const int p1 = g->periodic_j ? n1 : n1 + 1; /* node layers along j */
  size_t n_grid_nodes = (size_t)(n0 + 1) * p1 * (n2 + 1);
  size_t n_cells = 0;
  for (size_t c = 0; c < (size_t)n0 * n1 * n2; c++) n_cells += g->active ? g->active[c] != 0 : 1;
  memset(m, 0, sizeof *m);
  int32_t *id = malloc(sizeof *id * n_grid_nodes);
  m->conn = malloc(sizeof *m->conn * 24 * (n_cells ? n_cells : 1));
  if (!id || !m->conn) {
    free(id);
    return proto_fail(err, "out of memory (grid of %zu cells)", n_cells);
  }
  for (size_t q = 0; q < n_grid_nodes; q++) id[q] = -1;
  int32_t nn = 0;
  /* Kuhn tets: vertex bits (di, dj, dk) = (b0, b1, b2); path 0 -> 7. */
  static const int perm[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  int32_t ne = 0;
  for (int k = 0; k < n2; k++)
    for (int j = 0; j < n1; j++)
      for (int i = 0; i < n0; i++) {
        if (g->active && !g->active[i + (size_t)n0 * (j + (size_t)n1 * k)]) continue;
        int32_t v[8];
        for (int b = 0; b < 8; b++) {
          int ii = i + (b & 1), jj = j + ((b >> 1) & 1), kk = k + ((b >> 2) & 1);
          if (g->periodic_j) jj %= n1;
          size_t q = (size_t)ii + (size_t)(n0 + 1) * ((size_t)jj + (size_t)p1 * kk);
          if (id[q] < 0) id[q] = nn++;
          v[b] = id[q];
        }
        for (int t = 0; t < 6; t++) {
          int bits = 0;
          int32_t *c = m->conn + 4 * (size_t)ne++;
          c[0] = v[0];
          for (int s = 0; s < 3; s++) {
            bits |= 1 << perm[t][s];
            c[s + 1] = v[bits];
          }
        }
      }
  m->n_nodes = nn;
  m->n_elems = ne;
  m->nodes_per_elem = 4;
  m->x = malloc(sizeof *m->x * 3 * (size_t)(nn ? nn : 1));
  *node_ijk = malloc(sizeof **node_ijk * 3 * (size_t)(nn ? nn : 1));
  if (!m->x || !*node_ijk) {
    free(id);
    return proto_fail(err, "out of memory (grid nodes)");
  }
  for (int k = 0; k <= n2; k++)
    for (int j = 0; j < p1; j++)
      for (int i = 0; i <= n0; i++) {
        int32_t q = id[(size_t)i + (size_t)(n0 + 1) * ((size_t)j + (size_t)p1 * k)];
        if (q < 0) continue;
        g->map(g->ctx, i, j, k, m->x + 3 * (size_t)q);
        int32_t *ijk = *node_ijk + 3 * (size_t)q;
        ijk[0] = i;
        ijk[1] = j;
        ijk[2] = k;
      }
  free(id);
  /* Mapping may reverse orientation: make every tet positive. */
  for (int32_t e = 0; e < ne; e++) {
    int32_t *c = m->conn + 4 * (size_t)e;
    if (fem_tet_volume6(m->x + 3 * (size_t)c[0], m->x + 3 * (size_t)c[1],
                        m->x + 3 * (size_t)c[2], m->x + 3 * (size_t)c[3]) < 0) {
      int32_t t = c[2];
      c[2] = c[3];
      c[3] = t;
    }
  }
  return 0;
}

static int grid_groups(fem_mesh *m, const int32_t *node_ijk, face_classifier cls,
                       const void *ctx, const char *const *names, int n_names,
                       proto_err *err) {
  int base = m->n_groups;
  for (int q = 0; q < n_names; q++)
    if (fem_mesh_add_group(m, names[q], err) < 0) return -1;
  fem_face_index *ix = fem_face_index_build(m, err);
  if (!ix) return -1;
  int rc = 0;
  for (int32_t e = 0; e < m->n_elems && rc == 0; e++)
    for (int f = 0; f < 4 && rc == 0; f++) {
      int32_t fn[6], ee;
      int loc;
      fem_face_nodes(m, e, f, fn);
      if (fem_face_index_find(ix, fn, &ee, &loc) != 0) continue; /* interior */
      int ijk[3][3];
      for (int a = 0; a < 3; a++)
        for (int d = 0; d < 3; d++) ijk[a][d] = node_ijk[3 * (size_t)fn[a] + d];
      int q = cls(ctx, ijk);
      if (q >= 0) rc = fem_mesh_group_add_face(m, base + q, e, f, err);
    }
  fem_face_index_free(ix);
  return rc;
}

/* all three corners have index d equal to v */
static int on_plane(const int ijk[3][3], int d, int v) {
  return ijk[0][d] == v && ijk[1][d] == v && ijk[2][d] == v;
}

/* ------------------------------------------------------------------- box */

typedef struct box_ctx {
  double h[3];
  int n[3];
  double jitter;
} box_ctx;

static double hash_unit(uint32_t s) { /* deterministic value in [-1, 1] */
  s ^= s >> 16;
  s *= 0x7feb352dU;
  s ^= s >> 15;
  s *= 0x846ca68bU;
  s ^= s >> 16;
  return (double)s / 2147483647.5 - 1.0;
}

static void box_map(const void *vctx, int i, int j, int k, double *x) {
  const box_ctx *c = vctx;
  int idx[3] = {i, j, k};
  int interior = 1;
  for (int d = 0; d < 3; d++) interior &= idx[d] > 0 && idx[d] < c->n[d];
  for (int d = 0; d < 3; d++) {
    x[d] = idx[d] * c->h[d];
    if (interior && c->jitter > 0)
      x[d] += c->jitter * c->h[d] *
              hash_unit((uint32_t)(i * 73856093u) ^ (uint32_t)(j * 19349663u) ^
                        (uint32_t)(k * 83492791u) ^ (uint32_t)(d * 2654435761u));
  }
}

static int box_classify(const void *vctx, const int ijk[3][3]) {
  const box_ctx *c = vctx;
  for (int d = 0; d < 3; d++) {
    if (on_plane(ijk, d, 0)) return 2 * d;
    if (on_plane(ijk, d, c->n[d])) return 2 * d + 1;
  }
  return -1;
}

int fem_gen_box(fem_mesh *m, const double L[3], const int n[3], double jitter,
                proto_err *err) {
  box_ctx c = {{0}, {0}, jitter};
  for (int d = 0; d < 3; d++) {
    if (!(L[d] > 0) || n[d] < 1)
      return proto_fail(err, "box: size %g and cells %d along axis %d must be positive",
                        L[d], n[d], d);
    c.h[d] = L[d] / n[d];
    c.n[d] = n[d];
  }
  if (!(jitter >= 0 && jitter < 0.3)) return proto_fail(err, "box: jitter %g not in [0, 0.3)", jitter);
  grid_spec g = {{n[0], n[1], n[2]}, 0, NULL, box_map, &c};
  int32_t *ijk = NULL;
  static const char *const names[] = {"xmin", "xmax", "ymin", "ymax", "zmin", "zmax"};
  int rc = grid_mesh(m, &g, &ijk, err);
  if (rc == 0) rc = grid_groups(m, ijk, box_classify, &c, names, 6, err);
  free(ijk);
  if (rc) fem_mesh_free(m);
  return rc;
}

/* -------------------------------------------------------------- cylinder */

typedef struct cyl_ctx {
  double a, b, Lz, angle;
  int n[3];
  int periodic;
} cyl_ctx;

static void cyl_map(const void *vctx, int i, int j, int k, double *x) {
  const cyl_ctx *c = vctx;
  double r = c->a + (c->b - c->a) * i / c->n[0];
  double th = c->angle * j / c->n[1];
  x[0] = r * cos(th);
  x[1] = r * sin(th);
  x[2] = c->Lz * k / c->n[2];
}

static int cyl_classify(const void *vctx, const int ijk[3][3]) {
  const cyl_ctx *c = vctx;
  if (on_plane(ijk, 0, 0)) return 0;
  if (on_plane(ijk, 0, c->n[0])) return 1;
  if (on_plane(ijk, 2, 0)) return 2;
  if (on_plane(ijk, 2, c->n[2])) return 3;
  if (!c->periodic && on_plane(ijk, 1, 0)) return 4;
  if (!c->periodic && on_plane(ijk, 1, c->n[1])) return 5;
  return -1;
}

int fem_gen_cylinder(fem_mesh *m, double a, double b, double Lz, double angle,
                     const int n[3], proto_err *err) {
  if (!(a > 0 && b > a && Lz > 0))
    return proto_fail(err, "cylinder: need 0 < inner radius %g < outer radius %g and length %g > 0",
                      a, b, Lz);
  if (!(angle > 0 && angle <= 2 * M_PI + 1e-12))
    return proto_fail(err, "cylinder: angle %g not in (0, 2 pi]", angle);
  if (n[0] < 1 || n[1] < 1 || n[2] < 1) return proto_fail(err, "cylinder: cell counts must be >= 1");
  cyl_ctx c = {a, b, Lz, angle, {n[0], n[1], n[2]}, angle > 2 * M_PI - 1e-9};
  if (c.periodic && n[1] < 3) return proto_fail(err, "cylinder: a full ring needs >= 3 cells around");
  grid_spec g = {{n[0], n[1], n[2]}, c.periodic, NULL, cyl_map, &c};
  int32_t *ijk = NULL;
  static const char *const names[] = {"inner", "outer", "zmin", "zmax", "theta0", "theta1"};
  int rc = grid_mesh(m, &g, &ijk, err);
  if (rc == 0) rc = grid_groups(m, ijk, cyl_classify, &c, names, c.periodic ? 4 : 6, err);
  free(ijk);
  if (rc) fem_mesh_free(m);
  return rc;
}

void fem_snap_cylinder(void *radii, const double *xa, const double *xb, double *xm) {
  const double *R = radii;
  double ra = hypot(xa[0], xa[1]), rb = hypot(xb[0], xb[1]), rm = hypot(xm[0], xm[1]);
  for (int q = 0; q < 2; q++)
    if (fabs(ra - R[q]) < 1e-9 * R[q] && fabs(rb - R[q]) < 1e-9 * R[q] && rm > 0) {
      xm[0] *= R[q] / rm;
      xm[1] *= R[q] / rm;
    }
}

void fem_snap_tread(void *radii, const double *xa, const double *xb, double *xm) {
  const double *R = radii;
  double ra = hypot(xa[0], xa[2]), rb = hypot(xb[0], xb[2]), rm = hypot(xm[0], xm[2]);
  for (int q = 0; q < 3; q++)
    if (fabs(ra - R[q]) < 1e-9 * R[q] && fabs(rb - R[q]) < 1e-9 * R[q] && rm > 0) {
      xm[0] *= R[q] / rm;
      xm[2] *= R[q] / rm;
    }
}

/* ----------------------------------------------------------------- tread */

void fem_tread_defaults(fem_tread_params *p) {
  p->outer_diameter = 0.544;
  p->width = 0.165;
  p->wall = 0.016;
  p->groove_depth = 0.015;
  p->lugs = 32;
  p->lug_fraction = 0.5;
  p->lug_span = 0.6;
  p->refine = 1.0;
  p->phase = 0;
}

typedef struct tread_ctx {
  double r_in, wall, groove, width, phase;
  int n_wall, n_groove, n_theta, n_y;
} tread_ctx;

static void tread_map(const void *vctx, int i, int j, int k, double *x) {
  const tread_ctx *c = vctx;
  double r = i <= c->n_wall ? c->r_in + c->wall * i / c->n_wall
                            : c->r_in + c->wall + c->groove * (i - c->n_wall) / c->n_groove;
  double th = 2 * M_PI * j / c->n_theta + c->phase;
  x[0] = r * cos(th); /* rolling plane x-z, axle along y */
  x[1] = -0.5 * c->width + c->width * k / c->n_y;
  x[2] = r * sin(th);
}

static int tread_classify(const void *vctx, const int ijk[3][3]) {
  const tread_ctx *c = vctx;
  if (on_plane(ijk, 0, 0)) return 1; /* inner */
  int in_band = ijk[0][0] <= c->n_wall && ijk[1][0] <= c->n_wall && ijk[2][0] <= c->n_wall;
  if (in_band && (on_plane(ijk, 2, 0) || on_plane(ijk, 2, c->n_y))) return 0; /* rim */
  return 2; /* outer */
}

int fem_gen_tread(fem_mesh *m, const fem_tread_params *p, proto_err *err) {
  double ro = 0.5 * p->outer_diameter;
  if (!(p->wall > 0 && p->groove_depth > 0 && p->width > 0 && ro > p->wall + p->groove_depth))
    return proto_fail(err, "tread: need positive wall, groove_depth, width and outer radius > wall + groove_depth");
  if (p->lugs < 2 || !(p->lug_fraction > 0 && p->lug_fraction < 1) ||
      !(p->lug_span > 0 && p->lug_span <= 1) || !(p->refine > 0 && p->refine <= 16))
    return proto_fail(err, "tread: need lugs >= 2, lug_fraction and lug_span in (0, 1], refine in (0, 16]");
  tread_ctx c;
  c.r_in = ro - p->groove_depth - p->wall;
  c.wall = p->wall;
  c.groove = p->groove_depth;
  c.width = p->width;
  c.phase = p->phase;
  c.n_wall = (int)fmax(1, lround(2 * p->refine));
  c.n_groove = (int)fmax(1, lround(2 * p->refine));
  c.n_y = (int)fmax(2, lround(12 * p->refine));
  int pitch = (int)fmax(2, lround(4 * p->refine)); /* cells per lug pitch */
  c.n_theta = pitch * p->lugs;
  int lug_cells = (int)fmax(1, lround(p->lug_fraction * pitch));
  if (lug_cells >= pitch) lug_cells = pitch - 1;
  int span = (int)fmax(1, lround(p->lug_span * c.n_y));
  int n0 = c.n_wall + c.n_groove;
  uint8_t *act = malloc((size_t)n0 * c.n_theta * c.n_y);
  if (!act) return proto_fail(err, "out of memory (tread)");
  for (int k = 0; k < c.n_y; k++)
    for (int j = 0; j < c.n_theta; j++)
      for (int i = 0; i < n0; i++) {
        int lug = j / pitch, in_lug = (j % pitch) < lug_cells;
        /* lugs alternate between the two shoulders */
        int in_span = (lug % 2 == 0) ? k < span : k >= c.n_y - span;
        act[i + (size_t)n0 * (j + (size_t)c.n_theta * k)] =
            (uint8_t)(i < c.n_wall || (in_lug && in_span));
      }
  grid_spec g = {{n0, c.n_theta, c.n_y}, 1, act, tread_map, &c};
  int32_t *ijk = NULL;
  static const char *const names[] = {"rim", "inner", "outer"};
  int rc = grid_mesh(m, &g, &ijk, err);
  if (rc == 0) rc = grid_groups(m, ijk, tread_classify, &c, names, 3, err);
  free(ijk);
  free(act);
  if (rc) fem_mesh_free(m);
  return rc;
}
