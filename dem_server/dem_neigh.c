/* dem_neigh.c — O(N) neighbour search: linked cells, grains re-sorted by cell
 * for memory locality, a half Verlet list with skin whose contact history is
 * carried across rebuilds (and across the re-sorting). */
#include "dem_server/dem_internal.h"

#include <float.h>
#include <stdlib.h>
#include <string.h>

#define GROW(ptr, count, type) ((ptr) = realloc((ptr), sizeof(type) * (size_t)(count)))

int dem_neigh_alloc(const dem_model *m, dem_state *s, proto_err *err) {
  struct dem_work *w = s->work;
  size_t n = (size_t)s->n;
  w->nl_start = calloc(n + 1, sizeof(int));
  w->old_start = calloc(n + 1, sizeof(int));
  w->rev_start = calloc(n + 1, sizeof(int));
  w->rev_fill = calloc(n + 1, sizeof(int));
  w->old_of = calloc(n, sizeof(int));
  w->x_ref = calloc(3 * n, sizeof(double));
  w->plane_mask = calloc(n, sizeof(uint64_t));
  w->plane_touch = calloc(n, sizeof(uint64_t));
  w->cell_of = calloc(n, sizeof(int));
  w->pair_u = calloc(n, sizeof(double));
  w->pair_contacts = calloc(n, sizeof(int));
  w->ratio = calloc(n, sizeof(double));
  w->cap = w->old_cap = 8 * s->n + 64;
  w->nl_j = malloc(sizeof(int) * (size_t)w->cap);
  w->rev_k = malloc(sizeof(int) * (size_t)w->cap);
  w->nl_shear = calloc(3 * (size_t)w->cap, sizeof(double));
  w->pair_ft = malloc(6 * sizeof(double) * (size_t)w->cap);
  w->pair_touch = calloc((size_t)w->cap, 1);
  if (m->has_rolling) w->pair_roll = malloc(3 * sizeof(double) * (size_t)w->cap);
  w->old_j = malloc(sizeof(int) * (size_t)w->old_cap);
  w->old_shear = malloc(3 * sizeof(double) * (size_t)w->old_cap);
  if (!w->nl_start || !w->old_start || !w->rev_start || !w->rev_fill || !w->old_of ||
      !w->x_ref || !w->plane_mask || !w->plane_touch || !w->cell_of || !w->pair_u || !w->pair_contacts || !w->ratio || !w->nl_j ||
      !w->rev_k || !w->nl_shear || !w->pair_ft || !w->pair_touch || !w->old_j || !w->old_shear ||
      (m->has_rolling && !w->pair_roll))
    return proto_fail(err, "out of memory for the neighbour list of %d grains", s->n);
  return 0;
}

void dem_neigh_free(struct dem_work *w) {
  free(w->nl_start); free(w->old_start); free(w->rev_start); free(w->rev_fill);
  free(w->old_of); free(w->x_ref); free(w->plane_mask); free(w->plane_touch); free(w->cell_of); free(w->cell_start);
  free(w->pair_u); free(w->pair_contacts); free(w->ratio);
  free(w->nl_j); free(w->rev_k); free(w->nl_shear); free(w->pair_ft); free(w->pair_touch);
  free(w->pair_roll); free(w->old_j); free(w->old_shear);
}

/* ---- permutation of every per-grain array by old_of (new slot <- old slot) ---- */
static void perm_d(double *a, int cols, const int *old_of, int n, double *tmp) {
  for (int i = 0; i < n; i++)
    for (int k = 0; k < cols; k++) tmp[(size_t)i * cols + k] = a[(size_t)old_of[i] * cols + k];
  memcpy(a, tmp, sizeof(double) * (size_t)n * cols);
}
static void perm_i32(int32_t *a, const int *old_of, int n, int64_t *tmp) {
  for (int i = 0; i < n; i++) tmp[i] = a[old_of[i]];
  for (int i = 0; i < n; i++) a[i] = (int32_t)tmp[i];
}
static void perm_u8(uint8_t *a, const int *old_of, int n, int64_t *tmp) {
  for (int i = 0; i < n; i++) tmp[i] = a[old_of[i]];
  for (int i = 0; i < n; i++) a[i] = (uint8_t)tmp[i];
}

static void permute_grains(const dem_model *m, dem_state *s) {
  struct dem_work *w = s->work;
  const int n = s->n, *o = w->old_of;
  double *tmp = w->tmp;
  perm_d(s->x, 3, o, n, tmp); perm_d(s->v, 3, o, n, tmp); perm_d(s->omega, 3, o, n, tmp);
  perm_d(s->q, 4, o, n, tmp);
  perm_d(s->radius, 1, o, n, tmp); perm_d(s->inv_mass, 1, o, n, tmp);
  perm_d(s->inv_inertia, 1, o, n, tmp);
  perm_d(w->mass, 1, o, n, tmp); perm_d(w->inertia, 1, o, n, tmp);
  perm_i32(s->material, o, n, w->itmp); perm_i32(s->id, o, n, w->itmp);
  perm_u8(s->fix_rotation, o, n, w->itmp);
  for (int p = 0; p < m->n_planes; p++) perm_d(dem_wall_shear(w, n, 0, p), 3, o, n, w->tmp);
  if (m->n_meshes > 0) {
    const int K = DEM_MESH_SLOTS;
    for (int k = 0; k < K; k++) {
      /* slot arrays are [n][K]: permute each of the K columns */
      for (int i = 0; i < n; i++) w->itmp[i] = w->mc_key[(size_t)o[i] * K + k];
      for (int i = 0; i < n; i++) w->mc_key[(size_t)i * K + k] = w->itmp[i];
      for (int i = 0; i < n; i++) w->itmp[i] = w->mc_mesh[(size_t)o[i] * K + k];
      for (int i = 0; i < n; i++) w->mc_mesh[(size_t)i * K + k] = (int8_t)w->itmp[i];
    }
    perm_d(w->mc_shear, 3 * K, o, n, w->mc_force); /* mc_force is recomputed: usable as scratch */
    perm_d(w->mc_normal, 3 * K, o, n, w->mc_force);
  }
}

/* Grid over the grains' bounding box; cells at least one interaction range wide. */
static int setup_cells(const dem_model *m, dem_state *s, proto_err *err) {
  struct dem_work *w = s->work;
  double lo[3] = {DBL_MAX, DBL_MAX, DBL_MAX}, hi[3] = {-DBL_MAX, -DBL_MAX, -DBL_MAX}, rmax = 0;
  for (int i = 0; i < s->n; i++) {
    for (int k = 0; k < 3; k++) {
      double xk = s->x[3 * i + k];
      if (!isfinite(xk))
        return proto_fail(err, "step %lld: grain %d has a non-finite position", (long long)s->step,
                          (int)s->id[i]);
      if (xk < lo[k]) lo[k] = xk;
      if (xk > hi[k]) hi[k] = xk;
    }
    if (s->radius[i] > rmax) rmax = s->radius[i];
  }
  double size = 2 * rmax + m->skin;
  long long total;
  for (;;) {
    total = 1;
    for (int k = 0; k < 3; k++) {
      double cnt = floor((hi[k] - lo[k]) / size) + 1;
      w->cell_dim[k] = (int)(cnt < 1e6 ? cnt : 1e6);
      total *= w->cell_dim[k];
    }
    if (total <= 4LL * s->n + 1000) break;
    size *= 1.26; /* sparse scene (grains flying off): coarser cells, bounded memory */
  }
  w->cell_size = size;
  memcpy(w->cell_lo, lo, sizeof lo);
  if (total + 1 > w->cell_cap) {
    if (!GROW(w->cell_start, total + 1, int)) return proto_fail(err, "out of memory for cells");
    w->cell_cap = (int)total + 1;
  }
  return (int)total;
}

static inline int cell_coord(const struct dem_work *w, double x, int k) {
  int c = (int)((x - w->cell_lo[k]) / w->cell_size);
  return c < 0 ? 0 : (c >= w->cell_dim[k] ? w->cell_dim[k] - 1 : c);
}

/* Counting sort of grains by cell: old_of[new slot] = old slot. */
static void sort_by_cell(dem_state *s, int ncell) {
  struct dem_work *w = s->work;
  memset(w->cell_start, 0, sizeof(int) * (size_t)(ncell + 1));
  for (int i = 0; i < s->n; i++) {
    int c = (cell_coord(w, s->x[3 * i + 2], 2) * w->cell_dim[1] + cell_coord(w, s->x[3 * i + 1], 1)) *
                w->cell_dim[0] + cell_coord(w, s->x[3 * i], 0);
    w->cell_of[i] = c;
    w->cell_start[c + 1]++;
  }
  for (int c = 0; c < ncell; c++) w->cell_start[c + 1] += w->cell_start[c];
  for (int i = 0; i < s->n; i++) w->old_of[w->cell_start[w->cell_of[i]]++] = i;
  for (int c = ncell; c > 0; c--) w->cell_start[c] = w->cell_start[c - 1];
  w->cell_start[0] = 0;
}

/* Visits the candidate partners j > i of slot i; count-only when out is NULL. */
static int list_row(const dem_model *m, const dem_state *s, int i, int *out) {
  const struct dem_work *w = s->work;
  const double *xi = &s->x[3 * i];
  int c[3], cnt = 0;
  for (int k = 0; k < 3; k++) c[k] = cell_coord(w, xi[k], k);
  for (int dz = -1; dz <= 1; dz++) {
    int z = c[2] + dz;
    if (z < 0 || z >= w->cell_dim[2]) continue;
    for (int dy = -1; dy <= 1; dy++) {
      int y = c[1] + dy;
      if (y < 0 || y >= w->cell_dim[1]) continue;
      int x0 = c[0] > 0 ? c[0] - 1 : 0, x1 = c[0] + 1 < w->cell_dim[0] ? c[0] + 1 : c[0];
      int row = (z * w->cell_dim[1] + y) * w->cell_dim[0];
      /* cells x0..x1 of a row are contiguous slots */
      int j0 = w->cell_start[row + x0], j1 = w->cell_start[row + x1 + 1];
      if (j0 <= i) j0 = i + 1;
      for (int j = j0; j < j1; j++) {
        double d[3] = {s->x[3 * j] - xi[0], s->x[3 * j + 1] - xi[1], s->x[3 * j + 2] - xi[2]};
        double cut = s->radius[i] + s->radius[j] + m->skin;
        if (dem_dot(d, d) < cut * cut) {
          if (out) out[cnt] = j;
          cnt++;
        }
      }
    }
  }
  return cnt;
}

/* History of new pair (i, j) from the previous list (in old slots). */
static void carry_history(const struct dem_work *w, int i, int j, double *shear) {
  const int oi = w->old_of[i], oj = w->old_of[j];
  shear[0] = shear[1] = shear[2] = 0;
  if (!w->have_old) return;
  for (int k = w->old_start[oi]; k < w->old_start[oi + 1]; k++)
    if (w->old_j[k] == oj) {
      memcpy(shear, &w->old_shear[3 * k], 3 * sizeof(double));
      return;
    }
  for (int k = w->old_start[oj]; k < w->old_start[oj + 1]; k++)
    if (w->old_j[k] == oi) { /* stored from j's side: the spring of i is the opposite */
      for (int d = 0; d < 3; d++) shear[d] = -w->old_shear[3 * k + d];
      return;
    }
}

int dem_neigh_reserve(const dem_model *m, dem_state *s, int need, proto_err *err) {
  struct dem_work *w = s->work;
  if (need <= w->cap) return 0;
  int cap = need + need / 4 + 64; /* rare: only when the list outgrows its capacity */
  if (!GROW(w->nl_j, cap, int) || !GROW(w->rev_k, cap, int) || !GROW(w->nl_shear, 3 * cap, double) ||
      !GROW(w->pair_ft, 6 * cap, double) || !GROW(w->pair_touch, cap, uint8_t) ||
      (m->has_rolling && !GROW(w->pair_roll, 3 * cap, double)))
    return proto_fail(err, "out of memory for %d neighbour pairs", need);
  w->cap = cap;
  return 0;
}

/* For each slot, the pairs where it is the partner j, in list order. */
void dem_neigh_reverse(dem_state *s) {
  struct dem_work *w = s->work;
  const int n = s->n;
  memset(w->rev_start, 0, sizeof(int) * (size_t)(n + 1));
  for (int k = 0; k < w->nl_start[n]; k++) w->rev_start[w->nl_j[k] + 1]++;
  for (int i = 0; i < n; i++) w->rev_start[i + 1] += w->rev_start[i];
  memcpy(w->rev_fill, w->rev_start, sizeof(int) * (size_t)n);
  for (int i = 0; i < n; i++)
    for (int k = w->nl_start[i]; k < w->nl_start[i + 1]; k++) w->rev_k[w->rev_fill[w->nl_j[k]]++] = k;
}

int dem_neigh_rebuild(const dem_model *m, dem_state *s, proto_err *err) {
  struct dem_work *w = s->work;
  const int n = s->n;
  int ncell = setup_cells(m, s, err);
  if (ncell < 0) return -1;
  sort_by_cell(s, ncell);
  /* the current list becomes the old one (old slot numbering) */
  int npairs = w->nl_start[n];
  if (npairs > w->old_cap) {
    if (!GROW(w->old_j, npairs, int) || !GROW(w->old_shear, 3 * npairs, double))
      return proto_fail(err, "out of memory for %d neighbour pairs", npairs);
    w->old_cap = npairs;
  }
  memcpy(w->old_start, w->nl_start, sizeof(int) * (size_t)(n + 1));
  memcpy(w->old_j, w->nl_j, sizeof(int) * (size_t)npairs);
  memcpy(w->old_shear, w->nl_shear, 3 * sizeof(double) * (size_t)npairs);
  permute_grains(m, s);
  /* count pass, prefix sum, fill pass (parallel and deterministic) */
#pragma omp parallel for schedule(dynamic, 256) num_threads(w->nthreads)
  for (int i = 0; i < n; i++) w->nl_start[i + 1] = list_row(m, s, i, NULL);
  w->nl_start[0] = 0;
  for (int i = 0; i < n; i++) w->nl_start[i + 1] += w->nl_start[i];
  if (dem_neigh_reserve(m, s, w->nl_start[n], err)) return -1;
#pragma omp parallel for schedule(dynamic, 256) num_threads(w->nthreads)
  for (int i = 0; i < n; i++) {
    list_row(m, s, i, &w->nl_j[w->nl_start[i]]);
    for (int k = w->nl_start[i]; k < w->nl_start[i + 1]; k++) {
      double *sh = &w->nl_shear[3 * k];
      carry_history(w, i, w->nl_j[k], sh);
      w->pair_touch[k] = sh[0] != 0 || sh[1] != 0 || sh[2] != 0; /* a spring to reset if open */
    }
  }
  w->have_old = 1;
  dem_neigh_reverse(s);
  /* planes a grain can touch before the next rebuild (it moves < skin/2);
   * the springs of the others are cleared */
  for (int i = 0; i < n; i++) {
    uint64_t mask = 0, touch = 0;
    for (int p = 0; p < m->n_planes; p++) {
      const dem_plane *pl = &m->planes[p];
      double *sh = dem_wall_shear(w, n, i, p);
      double d[3] = {s->x[3 * i] - pl->point[0], s->x[3 * i + 1] - pl->point[1], s->x[3 * i + 2] - pl->point[2]};
      if (dem_dot(d, pl->normal) < s->radius[i] + m->skin) {
        mask |= (uint64_t)1 << p;
        if (sh[0] != 0 || sh[1] != 0 || sh[2] != 0) touch |= (uint64_t)1 << p;
      } else {
        memset(sh, 0, 3 * sizeof(double));
      }
    }
    w->plane_mask[i] = mask;
    w->plane_touch[i] = touch;
  }
  /* quaternions: the hot loop does not renormalise (|dq| = 1 + O(h⁶)); here */
  for (int i = 0; i < n; i++) {
    double *q = &s->q[4 * i];
    const double nrm = 1.0 / sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    for (int k = 0; k < 4; k++) q[k] *= nrm;
  }
  memcpy(w->x_ref, s->x, 3 * sizeof(double) * (size_t)n);
  s->rebuilds++;
  return 0;
}
