/* dem_neigh.c — O(N) neighbour search: linked cells visited in Morton
 * (Z-curve) order, grains re-sorted by cell so that neighbours are near in
 * memory and mostly in the same chunk of DEM_CHUNK slots (dem_force.c sums a
 * chunk's pairs in place and only the few crossing a chunk boundary through
 * a reverse index), a half Verlet list with skin whose contact history is
 * carried across rebuilds (and across the re-sorting). Every pass is
 * parallel except two counting sorts; the result does not depend on the
 * number of threads. */
#include "dem_server/dem_internal.h"

#include <float.h>
#include <stdlib.h>
#include <string.h>

#define PERM_MAX_TASKS (24 + DEM_MAX_PLANES)
#define PERM_MAX_REC (3 * DEM_MESH_SLOTS * sizeof(double))

/* realloc that keeps the old block on failure */
static int grow(void **p, size_t bytes) {
  void *q = realloc(*p, bytes ? bytes : 1);
  if (!q) return -1;
  *p = q;
  return 0;
}

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
  w->ratio = calloc(n, sizeof(double));
  w->nchunk = (s->n + DEM_CHUNK - 1) / DEM_CHUNK;
  w->cbuf = calloc((size_t)w->nchunk, sizeof(int *));
  w->cbuf_cap = calloc((size_t)w->nchunk, sizeof(int));
  const int threads = w->probe.cap > w->nthreads ? w->probe.cap : w->nthreads;
  for (int t = 0; t < threads; t++)
    if (!(w->perm_tmp[t] = malloc(PERM_MAX_REC * n + 1))) return proto_fail(err, "out of memory");
  if (!w->cbuf || !w->cbuf_cap || !w->nl_start || !w->old_start || !w->rev_start || !w->rev_fill || !w->old_of || !w->x_ref ||
      !w->plane_mask || !w->plane_touch || !w->cell_of || !w->ratio ||
      dem_neigh_reserve(m, s, 8 * s->n + 64, err))
    return proto_fail(err, "out of memory for the neighbour list of %d grains", s->n);
  return 0;
}

void dem_neigh_free(struct dem_work *w) {
  free(w->nl_start); free(w->old_start); free(w->rev_start); free(w->rev_fill);
  free(w->old_of); free(w->x_ref); free(w->plane_mask); free(w->plane_touch); free(w->cell_of);
  free(w->cell_start); free(w->cell_rank); free(w->ratio);
  if (w->cbuf)
    for (int c = 0; c < w->nchunk; c++) free(w->cbuf[c]);
  free(w->cbuf); free(w->cbuf_cap);
  free(w->nl_j); free(w->rev_k); free(w->nl_shear); free(w->pair_ft); free(w->pair_touch);
  free(w->pair_roll); free(w->old_j); free(w->old_shear);
  free(w->rev_of); free(w->rev_ft); free(w->rev_roll);
  for (int t = 0; t < DEM_MAX_THREADS; t++) free(w->perm_tmp[t]);
}

int dem_neigh_reserve(const dem_model *m, dem_state *s, int need, proto_err *err) {
  struct dem_work *w = s->work;
  const size_t cap = (size_t)need + (size_t)need / 4 + 64; /* rare: when the list outgrows it */
  if ((size_t)need > w->cap) {
    if (grow((void **)&w->nl_j, sizeof(int) * cap) || grow((void **)&w->nl_shear, 3 * sizeof(double) * cap))
      return proto_fail(err, "out of memory for %d neighbour pairs", need);
    w->cap = cap;
  }
  if ((size_t)need > w->pair_cap) {
    if (grow((void **)&w->rev_k, sizeof(int) * cap) || grow((void **)&w->pair_ft, 6 * sizeof(double) * cap) ||
        grow((void **)&w->pair_touch, cap) || grow((void **)&w->rev_of, sizeof(int) * cap) ||
        grow((void **)&w->rev_ft, 6 * sizeof(double) * cap) ||
        (m->has_rolling && (grow((void **)&w->pair_roll, 3 * sizeof(double) * cap) ||
                            grow((void **)&w->rev_roll, 3 * sizeof(double) * cap))))
      return proto_fail(err, "out of memory for %d neighbour pairs", need);
    w->pair_cap = cap;
  }
  return 0;
}

/* ------------------------------------------------ permutation of the grains */

/* One per-grain array: n records of `rec` bytes, permuted by old_of. */
typedef struct perm_task {
  void *a;
  size_t rec;
} perm_task;

static void perm_run(const perm_task *t, const int *restrict o, int n, char *restrict tmp) {
  const size_t rec = t->rec;
  char *restrict a = t->a;
  int i = 0;
  while (i < n && o[i] == i) i++; /* the slots that stay (a partial or wake rebuild: most) */
  const int first = i;
  while (i < n) { /* runs of consecutive old slots (a sorted block shifted) as one copy */
    int len = 1;
    while (i + len < n && o[i + len] == o[i] + len) len++;
    char *d = tmp + rec * (size_t)i;
    const char *src = a + rec * (size_t)o[i];
    if (len > 1) memcpy(d, src, rec * (size_t)len);
    else switch (rec) { /* the common sizes as fixed-size copies */
      case 4: memcpy(d, src, 4); break;
      case 8: memcpy(d, src, 8); break;
      case 24: memcpy(d, src, 24); break;
      case 32: memcpy(d, src, 32); break;
      default: memcpy(d, src, rec);
      }
    i += len;
  }
  memcpy(a + rec * (size_t)first, tmp + rec * (size_t)first, rec * (size_t)(n - first));
}

/* A wake rebuild's order over the asleep block (sort_wake): the woken first
 * (o[0..k), from anywhere), then the others in their order, each moved up by
 * the woken before it. Those move in place from the end, in runs (one copy
 * of the block, not two through tmp: the block is most of the grains' bytes),
 * the woken through tmp. */
static void perm_wake(const perm_task *t, const int *restrict o, int n, int k, char *restrict tmp) {
  const size_t rec = t->rec;
  char *a = t->a;
  for (int q = 0; q < k; q++) memcpy(tmp + rec * (size_t)q, a + rec * (size_t)o[q], rec);
  for (int i = n; i > k;) {
    int len = 1;
    while (i - len > k && o[i - len - 1] == o[i - len] - 1) len++;
    if (o[i - len] != i - len) memmove(a + rec * (size_t)(i - len), a + rec * (size_t)o[i - len], rec * (size_t)len);
    i -= len;
  }
  memcpy(a, tmp, rec * (size_t)k);
}

/* Every per-grain array that lives across steps; one array per task. A wake
 * rebuild (wake) leaves out the mesh contacts: an asleep grain has none, and
 * they are zero (fall_asleep, dem_sleep.c), so moving them changes nothing. */
static int perm_tasks(const dem_model *m, dem_state *s, perm_task *t, int wake) {
  struct dem_work *w = s->work;
  const size_t d = sizeof(double), K = DEM_MESH_SLOTS;
  int c = 0;
  t[c++] = (perm_task){s->x, 3 * d};
  t[c++] = (perm_task){s->v, 3 * d};
  t[c++] = (perm_task){s->omega, 3 * d};
  if (m->orientation) t[c++] = (perm_task){s->q, 4 * d}; /* else identity everywhere */
  t[c++] = (perm_task){s->radius, d};
  t[c++] = (perm_task){s->inv_mass, d};
  t[c++] = (perm_task){s->inv_inertia, d};
  t[c++] = (perm_task){w->mass, d};
  t[c++] = (perm_task){w->inertia, d};
  t[c++] = (perm_task){s->material, sizeof(int32_t)};
  t[c++] = (perm_task){s->id, sizeof(int32_t)};
  t[c++] = (perm_task){s->fix_rotation, 1};
  if (m->sleep.on) {
    t[c++] = (perm_task){w->asleep, 1};
    t[c++] = (perm_task){w->rest, sizeof(int32_t)};
    t[c++] = (perm_task){w->near, 1};
    t[c++] = (perm_task){w->rest_x, 3 * d};
  }
  if (w->compact) { /* at the end of a step (dem_sleep_update): the next half kick takes these */
    t[c++] = (perm_task){s->force, 3 * d};
    t[c++] = (perm_task){s->torque, 3 * d};
  }
  for (int p = 0; p < m->n_planes; p++) t[c++] = (perm_task){dem_wall_shear(w, s->n, 0, p), 3 * d};
  if (m->n_meshes > 0 && !wake) {
    t[c++] = (perm_task){w->mc_key, K * sizeof(int64_t)};
    t[c++] = (perm_task){w->mc_mesh, K};
    t[c++] = (perm_task){w->mc_shear, 3 * K * d};
    t[c++] = (perm_task){w->mc_normal, 3 * K * d};
  }
  return c;
}


/* Slots from..from+cnt−1 (all of them, the awake block of a partial rebuild,
 * or what follows the awake block at a wake rebuild); old_of within them. */
static int permute_grains(const dem_model *m, dem_state *s, int from, int cnt, proto_err *err) {
  struct dem_work *w = s->work;
  perm_task t[PERM_MAX_TASKS];
  const int nt = perm_tasks(m, s, t, from > 0);
  const int *order = w->old_of;
  if (from > 0) { /* a wake rebuild: relative to from (rev_start: scratch during a rebuild) */
    for (int i = 0; i < cnt; i++) w->rev_start[i] = w->old_of[from + i] - from;
    order = w->rev_start;
    for (int k = 0; k < nt; k++) t[k].a = (char *)t[k].a + (size_t)from * t[k].rec;
  }
  for (int k = 0; k < w->nthreads; k++)
    if (!w->perm_tmp[k] && !(w->perm_tmp[k] = malloc(PERM_MAX_REC * (size_t)s->n + 1)))
      return proto_fail(err, "out of memory for re-sorting %d grains", s->n);
#pragma omp parallel for schedule(dynamic, 1) num_threads(w->nthreads)
  for (int k = 0; k < nt; k++) {
    if (from > 0) perm_wake(&t[k], order, cnt, w->n_active - from, w->perm_tmp[omp_get_thread_num()]);
    else perm_run(&t[k], order, cnt, w->perm_tmp[omp_get_thread_num()]);
  }
  return 0;
}

/* ------------------------------------------------------------------ cells */

/* Grid over the grains' bounding box; cells at least one interaction range wide. */
static int setup_cells(const dem_model *m, dem_state *s, proto_err *err) {
  struct dem_work *w = s->work;
  double lo[3] = {DBL_MAX, DBL_MAX, DBL_MAX}, hi[3] = {-DBL_MAX, -DBL_MAX, -DBL_MAX}, rmax = 0;
  int bad = 0;
  const int n = s->n;
  const double *x = s->x;
#pragma omp parallel for schedule(static) num_threads(w->nthreads) \
    reduction(min : lo[:3]) reduction(max : hi[:3], rmax) reduction(| : bad)
  for (int i = 0; i < n; i++) {
    for (int k = 0; k < 3; k++) {
      const double xk = x[3 * i + k];
      bad |= !isfinite(xk);
      lo[k] = xk < lo[k] ? xk : lo[k];
      hi[k] = xk > hi[k] ? xk : hi[k];
    }
    rmax = s->radius[i] > rmax ? s->radius[i] : rmax;
  }
  for (int i = 0; bad && i < n; i++)
    if (!isfinite(x[3 * i] + x[3 * i + 1] + x[3 * i + 2]))
      return proto_fail(err, "step %lld: grain %d has a non-finite position", (long long)s->step, (int)s->id[i]);
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
    if (grow((void **)&w->cell_start, sizeof(int) * (size_t)(total + 1)) ||
        grow((void **)&w->cell_rank, sizeof(int) * (size_t)(total + 1)) ||
        (m->sleep.on && grow((void **)&w->frz_start, sizeof(int) * (size_t)(total + 1))))
      return proto_fail(err, "out of memory for cells");
    w->cell_cap = (int)total + 1;
    w->rank_dim[0] = -1; /* ranks to redo */
  }
  return (int)total;
}


/* Morton rank of every cell: the cells of a power-of-two cube visited in
 * Z-curve order, cubes outside the grid skipped (O(cells) for any shape). */
static void morton_visit(struct dem_work *w, int x, int y, int z, int size, int *next) {
  if (x >= w->cell_dim[0] || y >= w->cell_dim[1] || z >= w->cell_dim[2]) return;
  if (size == 1) {
    w->cell_rank[dem_cell_index(w, x, y, z)] = (*next)++;
    return;
  }
  const int h = size / 2;
  for (int c = 0; c < 8; c++) morton_visit(w, x + (c & 1) * h, y + (c >> 1 & 1) * h, z + (c >> 2) * h, h, next);
}

static void morton_ranks(struct dem_work *w) {
  if (!memcmp(w->rank_dim, w->cell_dim, sizeof w->rank_dim)) return; /* same grid shape */
  int size = 1, next = 0;
  while (size < w->cell_dim[0] || size < w->cell_dim[1] || size < w->cell_dim[2]) size *= 2;
  morton_visit(w, 0, 0, 0, size, &next);
  memcpy(w->rank_dim, w->cell_dim, sizeof w->rank_dim);
}

/* Counting sort of grains by the Morton rank of their cell, the awake grains
 * first (slots 0..na−1), then the asleep ones: old_of[new slot] = old slot;
 * cell_start (awake) and frz_start (asleep) indexed by rank. A partial
 * rebuild (cnt = na) sorts the awake block only and keeps frz_start. */
static void sort_by_cell(const dem_model *m, dem_state *s, int ncell, int cnt) {
  struct dem_work *w = s->work;
  const int n = s->n;
  const uint8_t *asleep = m->sleep.on && cnt == n ? w->asleep : NULL;
  morton_ranks(w);
#pragma omp parallel for schedule(static) num_threads(w->nthreads)
  for (int i = 0; i < cnt; i++) {
    const double *x = &s->x[3 * i];
    w->cell_of[i] = dem_cell_rank_at(w, x);
  }
  int na = 0;
  for (int i = 0; i < cnt; i++) na += !(asleep && asleep[i]);
  for (int pass = 0; pass < (asleep ? 2 : 1); pass++) {
    int *start = pass ? w->frz_start : w->cell_start;
    memset(start, 0, sizeof(int) * (size_t)(ncell + 1));
    for (int i = 0; i < cnt; i++)
      if (!asleep || asleep[i] == pass) start[w->cell_of[i] + 1]++;
    start[0] = pass ? na : 0;
    for (int c = 0; c < ncell; c++) start[c + 1] += start[c];
    for (int i = 0; i < cnt; i++)
      if (!asleep || asleep[i] == pass) w->old_of[start[w->cell_of[i]]++] = i;
    for (int c = ncell; c > 0; c--) start[c] = start[c - 1];
    start[0] = pass ? na : 0;
  }
  if (m->sleep.on && cnt == n) w->n_active = na;
  for (int i = cnt; i < n; i++) w->old_of[i] = i; /* partial: the asleep block stays */
}

/* Wake rebuild (only grains woke since the last rebuild): the awake block
 * stays as it is, the woken grains follow it sorted by cell (cell_start: their
 * ranges), the rest of the asleep block after them in its order (still sorted
 * by cell: frz_start counted again). */
static void sort_wake(dem_state *s, int ncell) {
  struct dem_work *w = s->work;
  const int n = s->n, na_old = w->n_active;
  morton_ranks(w);
  for (int i = 0; i < na_old; i++) w->old_of[i] = i;
#pragma omp parallel for schedule(static) num_threads(w->nthreads)
  for (int i = na_old; i < n; i++) {
    const double *x = &s->x[3 * i];
    w->cell_of[i] = dem_cell_rank_at(w, x);
  }
  int na = na_old;
  for (int i = na_old; i < n; i++) na += !w->asleep[i];
  for (int pass = 0; pass < 2; pass++) {
    int *start = pass ? w->frz_start : w->cell_start;
    const int first = pass ? na : na_old;
    memset(start, 0, sizeof(int) * (size_t)(ncell + 1));
    for (int i = na_old; i < n; i++)
      if (w->asleep[i] == pass) start[w->cell_of[i] + 1]++;
    start[0] = first;
    for (int c = 0; c < ncell; c++) start[c + 1] += start[c];
    for (int i = na_old; i < n; i++)
      if (w->asleep[i] == pass) w->old_of[start[w->cell_of[i]]++] = i;
    for (int c = ncell; c > 0; c--) start[c] = start[c - 1];
    start[0] = first;
  }
  w->n_active = na;
}

/* Wake rebuild: an awake row keeps its pairs, renumbered; its woken partners
 * (now awake) move before the asleep ones, in increasing slot. */
static void awake_row_renumber(struct dem_work *w, int i, const int *new_of, int na_old) {
  const int k0 = w->nl_start[i], k1 = w->nl_start[i + 1];
  memcpy(&w->nl_j[k0], &w->old_j[k0], sizeof(int) * (size_t)(k1 - k0));
  memcpy(&w->nl_shear[3 * k0], &w->old_shear[3 * k0], 3 * sizeof(double) * (size_t)(k1 - k0));
  int kt = k1; /* the tail: partners that were asleep */
  while (kt > k0 && w->nl_j[kt - 1] >= na_old) kt--;
  const int na = w->n_active;
  int q = kt;
  for (int pass = 0; pass < 2; pass++) /* woken first (sorted below), then asleep, each in order */
    for (int k = kt; k < k1; k++) {
      const int j = new_of[w->old_j[k]];
      if ((j >= na) != pass) continue;
      int p = q++;
      for (; pass == 0 && p > kt && w->nl_j[p - 1] > j; p--) { /* few: insertion */
        w->nl_j[p] = w->nl_j[p - 1];
        memcpy(&w->nl_shear[3 * p], &w->nl_shear[3 * (p - 1)], 3 * sizeof(double));
      }
      w->nl_j[p] = j;
      memcpy(&w->nl_shear[3 * p], &w->old_shear[3 * k], 3 * sizeof(double));
    }
  for (int k = k0; k < k1; k++) {
    const double *sh = &w->nl_shear[3 * k];
    if (k >= kt) w->pair_touch[k] = sh[0] != 0 || sh[1] != 0 || sh[2] != 0;
  }
}

/* Candidates of one cell: the slots of its neighbour cells that come at or
 * after it in Morton order (earlier cells hold only smaller slots), in
 * increasing slot order, with positions and radii as structure of arrays so
 * that the distance tests of each row vectorise. */
typedef struct cand_set {
  int n, cap;
  int *j;
  double *x, *y, *z, *r;
  uint8_t *hit;
} cand_set;

static void cand_bind(cand_set *c, void *mem, int n) {
  /* mem: PERM_MAX_REC * n bytes (the thread's re-sorting scratch, idle now) */
  c->n = 0;
  c->cap = n;
  c->x = mem;
  c->y = c->x + n;
  c->z = c->y + n;
  c->r = c->z + n;
  c->j = (int *)(c->r + n);
  c->hit = (uint8_t *)(c->j + n);
}

/* Slot ranges [lo, hi) of the cells around cc in one class (start by rank),
 * those with rank >= min_rank, inserted by start (disjoint) after nr. */
static int cell_ranges(const struct dem_work *w, const int *start, int rank_min, const int *cc, int *lo, int *hi,
                       int nr) {
  const int first = nr;
  for (int z = cc[2] > 0 ? cc[2] - 1 : 0; z <= cc[2] + 1 && z < w->cell_dim[2]; z++)
    for (int y = cc[1] > 0 ? cc[1] - 1 : 0; y <= cc[1] + 1 && y < w->cell_dim[1]; y++)
      for (int x = cc[0] > 0 ? cc[0] - 1 : 0; x <= cc[0] + 1 && x < w->cell_dim[0]; x++) {
        const int r = w->cell_rank[dem_cell_index(w, x, y, z)];
        if (r < rank_min || start[r] == start[r + 1]) continue;
        int q = nr++;
        for (; q > first && lo[q - 1] > start[r]; q--) { lo[q] = lo[q - 1]; hi[q] = hi[q - 1]; }
        lo[q] = start[r];
        hi[q] = start[r + 1];
      }
  return nr;
}

/* Candidates of a cell in increasing slot order: an awake row's are the
 * awake grains of the cells around at or after its cell in Morton order
 * (earlier cells hold only smaller slots) and the asleep grains of all cells
 * around (slots after every awake one); an asleep row's (full rebuilds) the
 * asleep grains of the cells around at or after its cell. */
static void cell_candidates(const dem_model *m, const struct dem_work *w, const dem_state *s, int rank, int awake,
                            const int *cc, cand_set *c) {
  int lo[54], hi[54], nr = 0;
  if (awake) nr = cell_ranges(w, w->cell_start, rank, cc, lo, hi, 0);
  if (m->sleep.on) nr = cell_ranges(w, w->frz_start, awake ? 0 : rank, cc, lo, hi, nr);
  c->n = 0;
  for (int q = 0; q < nr; q++)
    for (int j = lo[q]; j < hi[q]; j++) {
      const int k = c->n++;
      c->j[k] = j;
      c->x[k] = s->x[3 * j]; c->y[k] = s->x[3 * j + 1]; c->z[k] = s->x[3 * j + 2];
      c->r[k] = s->radius[j];
    }
}

/* Partners j > i of slot i within reach (r_i + r_j + skin) among the cell's
 * candidates, into out in increasing j; returns the count, −1 if out is
 * shorter than the candidates. */
static int list_row(const dem_model *m, const dem_state *s, int i, cand_set *restrict c, int *restrict out,
                    int room) {
  const double xi0 = s->x[3 * i], xi1 = s->x[3 * i + 1], xi2 = s->x[3 * i + 2], ri = s->radius[i] + m->skin;
  int q0 = 0;
  while (q0 < c->n && c->j[q0] <= i) q0++;
  if (c->n - q0 > room) return -1;
  const double *restrict cx = c->x, *restrict cy = c->y, *restrict cz = c->z, *restrict cr = c->r;
  uint8_t *restrict hit = c->hit;
  for (int q = q0; q < c->n; q++) { /* vectorised */
    const double d0 = cx[q] - xi0, d1 = cy[q] - xi1, d2 = cz[q] - xi2, cut = ri + cr[q];
    hit[q] = d0 * d0 + d1 * d1 + d2 * d2 < cut * cut;
  }
  int cnt = 0;
  for (int q = q0; q < c->n; q++) {
    out[cnt] = c->j[q];
    cnt += hit[q];
  }
  return cnt;
}

/* Rows lo..hi−1 into the chunk's buffer (grown if needed: rare, at the
 * first rebuilds); row lengths into nl_start[i + 1]. */
static int list_chunk(const dem_model *m, dem_state *s, int c, int lo, int hi, void *scratch) {
  struct dem_work *w = s->work;
  cand_set cs;
  cand_bind(&cs, scratch, s->n);
  int used = 0, rank = -1, na = w->n_active;
  for (int i = lo; i < hi; i++) {
    const int ri = w->cell_of[w->old_of[i]]; /* cell_of: rank by old slot */
    if (i == lo || ri != rank || i == na) { /* a new cell (or class): its candidates */
      rank = ri;
      int cc[3];
      for (int k = 0; k < 3; k++) cc[k] = dem_cell_coord(w, s->x[3 * i + k], k);
      cell_candidates(m, w, s, rank, i < na, cc, &cs);
    }
    for (;;) {
      int *row = w->cbuf[c] ? w->cbuf[c] + used : NULL; /* no buffer yet: room 0 */
      int room = w->cbuf_cap[c] - used, got = list_row(m, s, i, &cs, row, room);
      if (got >= 0) {
        w->nl_start[i + 1] = got;
        used += got;
        break;
      }
      const int cap = 2 * w->cbuf_cap[c] + cs.n + (hi - lo) * 8;
      int *nb = realloc(w->cbuf[c], sizeof(int) * (size_t)cap);
      if (!nb) return -1;
      w->cbuf[c] = nb;
      w->cbuf_cap[c] = cap;
    }
  }
  return 0;
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

void dem_rebuild_kinds(const dem_state *s, int64_t *full, int64_t *wake) {
  *full = s->work->full_rebuilds;
  *wake = s->work->wake_rebuilds;
}

/* The pairs (i', j) whose row i' lies in an earlier chunk than j: for each
 * j in descending i' (the order dem_force.c adds their shares in), with
 * their shares' slots (rev_of, rev_ft and rev_roll zeroed: every pair is open
 * until its row is screened). */
void dem_neigh_reverse(dem_state *s) {
  struct dem_work *w = s->work;
  int n = s->n;
  if (w->asleep) { /* the awake grains come first (found again after a state import) */
    int na = 0;
    while (na < n && !w->asleep[na]) na++;
    w->n_active = n = na; /* asleep grains gather nothing */
  }
  memset(w->rev_start, 0, sizeof(int) * (size_t)(n + 1));
  for (int i = 0; i < n; i++) {
    const int end = (i / DEM_CHUNK + 1) * DEM_CHUNK;
    for (int k = w->nl_start[i]; k < w->nl_start[i + 1]; k++)
      if (w->nl_j[k] >= end && w->nl_j[k] < n) w->rev_start[w->nl_j[k] + 1]++;
  }
  for (int i = 0; i < n; i++) w->rev_start[i + 1] += w->rev_start[i];
  memcpy(w->rev_fill, w->rev_start, sizeof(int) * (size_t)n);
  for (int i = n - 1; i >= 0; i--) {
    const int end = (i / DEM_CHUNK + 1) * DEM_CHUNK;
    for (int k = w->nl_start[i]; k < w->nl_start[i + 1]; k++)
      if (w->nl_j[k] >= end && w->nl_j[k] < n) w->rev_k[w->rev_fill[w->nl_j[k]]++] = k;
  }
  const int nk = w->nl_start[s->n], nrev = w->rev_start[n];
  if (nk > 0) memset(w->rev_of, 0xff, sizeof(int) * (size_t)nk); /* −1 */
  for (int q = 0; q < nrev; q++) w->rev_of[w->rev_k[q]] = q;
  if (nrev > 0) memset(w->rev_ft, 0, 6 * sizeof(double) * (size_t)nrev);
  if (nrev > 0 && w->rev_roll) memset(w->rev_roll, 0, 3 * sizeof(double) * (size_t)nrev);
}

int dem_neigh_asleep_cells(const dem_model *m, dem_state *s, proto_err *err) {
  struct dem_work *w = s->work;
  const int n = s->n, na = w->n_active, ncell = w->cell_dim[0] * w->cell_dim[1] * w->cell_dim[2];
  (void)m;
  morton_ranks(w);
  memset(w->frz_start, 0, sizeof(int) * (size_t)(ncell + 1));
  int prev = 0;
  for (int i = na; i < n; i++) {
    const double *x = &s->x[3 * i];
    const int r = dem_cell_rank_at(w, x);
    if (r < prev)
      return proto_fail(err, "state import: asleep grains not in the order of their cells (slot %d)", i);
    prev = r;
    w->frz_start[r + 1]++;
  }
  w->frz_start[0] = na;
  for (int c = 0; c < ncell; c++) w->frz_start[c + 1] += w->frz_start[c];
  w->grid_ok = 1;
  return 0;
}

/* Wake rebuild: the rows of the asleep block, copied from the old list with
 * the new slot numbers, without the pairs with a woken grain (the woken
 * grain's own row lists them again); new_of: old slot → new (scratch).
 * Lengths into nl_start[i + 1] (fill 0), then the entries (fill 1). */
static void asleep_rows(dem_state *s, const int *new_of, int fill) {
  struct dem_work *w = s->work;
  const int n = s->n, na = w->n_active;
  /* each row reads its old row and writes its own range (or length): rows in
   * parallel, the same bytes as in one thread */
#pragma omp parallel for schedule(static, 1024) num_threads(w->nthreads)
  for (int i = na; i < n; i++) {
    const int oi = w->old_of[i];
    int k = fill ? w->nl_start[i] : 0;
    for (int q = w->old_start[oi]; q < w->old_start[oi + 1]; q++) {
      const int j = new_of[w->old_j[q]];
      if (j < na) continue; /* woke */
      if (fill) {
        w->nl_j[k] = j;
        memcpy(&w->nl_shear[3 * k], &w->old_shear[3 * q], 3 * sizeof(double));
        const double *sh = &w->nl_shear[3 * k];
        w->pair_touch[k] = sh[0] != 0 || sh[1] != 0 || sh[2] != 0;
      }
      k++;
    }
    if (!fill) w->nl_start[i + 1] = k;
  }
}

/* Slot i listed again: planes it can touch before the next rebuild (it
 * moves < skin/2; the springs of the others cleared), its quaternion
 * renormalised (the hot loop does not: |dq| = 1 + O(h⁶)), its reference. */
static void grain_refresh(const dem_model *m, dem_state *s, int i) {
  struct dem_work *w = s->work;
  const int n = s->n;
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
  if (m->orientation) {
    double *q = &s->q[4 * i];
    const double nrm = 1.0 / sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    for (int k = 0; k < 4; k++) q[k] *= nrm;
  }
  memcpy(&w->x_ref[3 * i], &s->x[3 * i], 3 * sizeof(double));
}

/* The rows of slots lo..hi−1 from the cells (list_chunk per chunk piece) and
 * their history; lengths already summed into nl_start. */
static int rows_from_cells(const dem_model *m, dem_state *s, int lo, int hi, int pass) {
  struct dem_work *w = s->work;
  int oom = 0;
  const int c0 = lo / DEM_CHUNK, c1 = (hi + DEM_CHUNK - 1) / DEM_CHUNK;
#pragma omp parallel for schedule(dynamic, 1) num_threads(w->nthreads) reduction(| : oom)
  for (int c = c0; c < c1; c++) {
    const int a = c * DEM_CHUNK > lo ? c * DEM_CHUNK : lo, b = (c + 1) * DEM_CHUNK < hi ? (c + 1) * DEM_CHUNK : hi;
    if (pass == 0) {
      oom |= list_chunk(m, s, c, a, b, w->perm_tmp[omp_get_thread_num()]) != 0;
      continue;
    }
    for (int i = a; i < b; i++) {
      const int from = w->nl_start[i] - w->nl_start[a], len = w->nl_start[i + 1] - w->nl_start[i];
      if (len > 0) memcpy(&w->nl_j[w->nl_start[i]], w->cbuf[c] + from, sizeof(int) * (size_t)len);
      for (int k = w->nl_start[i]; k < w->nl_start[i + 1]; k++) {
        double *sh = &w->nl_shear[3 * k];
        carry_history(w, i, w->nl_j[k], sh);
        w->pair_touch[k] = sh[0] != 0 || sh[1] != 0 || sh[2] != 0;
      }
      grain_refresh(m, s, i);
    }
  }
  return oom;
}

/* Only grains woke since the last rebuild (dem_sleep_update): the awake rows
 * keep their pairs (renumbered; the awake grains keep their reference, so the
 * Verlet guarantee holds: a pair left out was farther than r_i + r_j + skin
 * when the row was built, and each grain moves less than skin/2 from its own
 * reference), the woken grains get rows from the cells, the asleep rows are
 * copied without the pairs with woken grains. O(awake pairs + n) copies, no
 * search outside the woken grains. */
static int wake_rebuild(const dem_model *m, dem_state *s, int ncell, proto_err *err) {
  struct dem_work *w = s->work;
  const int n = s->n, na_old = w->n_active;
  sort_wake(s, ncell);
  const int na = w->n_active;
  { int *t = w->old_start; w->old_start = w->nl_start; w->nl_start = t; }
  { int *t = w->old_j; w->old_j = w->nl_j; w->nl_j = t; }
  { double *t = w->old_shear; w->old_shear = w->nl_shear; w->nl_shear = t; }
  { size_t t = w->old_cap; w->old_cap = w->cap; w->cap = t; }
  if (permute_grains(m, s, na_old, n - na_old, err)) return -1;
  int *new_of = w->rev_fill; /* scratch until dem_neigh_reverse */
#pragma omp parallel for schedule(static) num_threads(w->nthreads)
  for (int i = 0; i < n; i++) new_of[w->old_of[i]] = i; /* a permutation: no two i write one slot */
  memcpy(w->nl_start, w->old_start, sizeof(int) * (size_t)(na_old + 1));
  if (rows_from_cells(m, s, na_old, na, 0))
    return proto_fail(err, "out of memory for the neighbour list of %d grains", n);
  for (int i = na_old; i < na; i++) w->nl_start[i + 1] += w->nl_start[i];
  asleep_rows(s, new_of, 0);
  for (int i = na; i < n; i++) w->nl_start[i + 1] += w->nl_start[i];
  if (dem_neigh_reserve(m, s, w->nl_start[n], err)) return -1;
#pragma omp parallel for schedule(dynamic, 256) num_threads(w->nthreads)
  for (int i = 0; i < na_old; i++) awake_row_renumber(w, i, new_of, na_old);
  rows_from_cells(m, s, na_old, na, 1);
  asleep_rows(s, new_of, 1);
  w->compact = 0;
  s->sleeping = n - na;
  w->wake_rebuilds++;
  dem_neigh_reverse(s);
  s->rebuilds++;
  return m->n_meshes > 0 ? dem_mesh_lists(m, s, err) : 0;
}

/* A partial rebuild keeps the asleep block and the grid of the last full
 * one: possible when the asleep set did not change and the awake grains are
 * within one cell of that grid (outside it they would crowd its border cells;
 * clamped coordinates still find every pair). Returns 1 if possible, −1 on a
 * non-finite position. */
static int partial_ok(const dem_model *m, dem_state *s, proto_err *err) {
  struct dem_work *w = s->work;
  if (!m->sleep.on || w->compact || !w->grid_ok || w->n_active == s->n) return 0;
  const int na = w->n_active;
  const double *x = s->x;
  double lo[3] = {DBL_MAX, DBL_MAX, DBL_MAX}, hi[3] = {-DBL_MAX, -DBL_MAX, -DBL_MAX};
  int bad = 0;
#pragma omp parallel for schedule(static) num_threads(w->nthreads) reduction(min : lo[:3]) reduction(max : hi[:3]) \
    reduction(| : bad)
  for (int i = 0; i < na; i++)
    for (int k = 0; k < 3; k++) {
      const double xk = x[3 * i + k];
      bad |= !isfinite(xk);
      lo[k] = xk < lo[k] ? xk : lo[k];
      hi[k] = xk > hi[k] ? xk : hi[k];
    }
  for (int i = 0; bad && i < na; i++)
    if (!isfinite(x[3 * i] + x[3 * i + 1] + x[3 * i + 2]))
      return proto_fail(err, "step %lld: grain %d has a non-finite position", (long long)s->step, (int)s->id[i]);
  for (int k = 0; k < 3; k++)
    if (lo[k] < w->cell_lo[k] - w->cell_size || hi[k] > w->cell_lo[k] + (w->cell_dim[k] + 1) * w->cell_size) return 0;
  return 1;
}

int dem_neigh_rebuild(const dem_model *m, dem_state *s, proto_err *err) {
  struct dem_work *w = s->work;
  const int n = s->n;
  /* wake: only grains woke (dem_sleep_update), the grid kept */
  const int wake = m->sleep.on && w->compact == DEM_COMPACT_WAKE && w->grid_ok;
  const int partial = wake ? 0 : partial_ok(m, s, err);
  if (partial < 0) return -1;
  int ncell = 0;
  if (!partial && !wake) {
    if ((ncell = setup_cells(m, s, err)) < 0) return -1;
  } else {
    ncell = w->cell_dim[0] * w->cell_dim[1] * w->cell_dim[2];
  }
  if (wake) return wake_rebuild(m, s, ncell, err);
  sort_by_cell(m, s, ncell, partial ? w->n_active : n);
  const int na = w->n_active;
  const int cnt = partial ? na : n; /* slots listed again from the cells */
  /* the current list becomes the old one (old slot numbering): swap buffers */
  { int *t = w->old_start; w->old_start = w->nl_start; w->nl_start = t; }
  { int *t = w->old_j; w->old_j = w->nl_j; w->nl_j = t; }
  { double *t = w->old_shear; w->old_shear = w->nl_shear; w->nl_shear = t; }
  { size_t t = w->old_cap; w->old_cap = w->cap; w->cap = t; }
  if (permute_grains(m, s, 0, partial ? na : n, err)) return -1;
  /* rows per chunk into the chunk's buffer, prefix sum, copy and carry the
   * history (parallel and deterministic); a partial rebuild copies the
   * asleep block's rows (its pairs among asleep grains) as they were */
  const int nchunk = (cnt + DEM_CHUNK - 1) / DEM_CHUNK;
  int oom = 0;
#pragma omp parallel for schedule(dynamic, 1) num_threads(w->nthreads) reduction(| : oom)
  for (int c = 0; c < nchunk; c++)
    oom |= list_chunk(m, s, c, c * DEM_CHUNK, (c + 1) * DEM_CHUNK < cnt ? (c + 1) * DEM_CHUNK : cnt,
                      w->perm_tmp[omp_get_thread_num()]) != 0;
  if (oom) return proto_fail(err, "out of memory for the neighbour list of %d grains", n);
  w->nl_start[0] = 0;
  for (int i = 0; i < cnt; i++) w->nl_start[i + 1] += w->nl_start[i];
  for (int i = cnt; i < n; i++) w->nl_start[i + 1] = w->nl_start[i] + (w->old_start[i + 1] - w->old_start[i]);
  if (dem_neigh_reserve(m, s, w->nl_start[n], err)) return -1;
  if (cnt < n) {
    const size_t from = (size_t)w->old_start[cnt], to = (size_t)w->nl_start[cnt], len = (size_t)w->nl_start[n] - to;
    memcpy(&w->nl_j[to], &w->old_j[from], sizeof(int) * len);
    memcpy(&w->nl_shear[3 * to], &w->old_shear[3 * from], 3 * sizeof(double) * len);
    /* pair_touch of an asleep row is (spring != 0), set when the row was
     * last built and not changed since (asleep rows are not screened):
     * moved with the rows (before the awake rows below overwrite it) */
    memmove(&w->pair_touch[to], &w->pair_touch[from], len);
  }
#pragma omp parallel for schedule(dynamic, 256) num_threads(w->nthreads)
  for (int i = 0; i < cnt; i++) {
    const int c = i / DEM_CHUNK, from = w->nl_start[i] - w->nl_start[c * DEM_CHUNK];
    const int len = w->nl_start[i + 1] - w->nl_start[i];
    if (len > 0) memcpy(&w->nl_j[w->nl_start[i]], w->cbuf[c] + from, sizeof(int) * (size_t)len);
    for (int k = w->nl_start[i]; k < w->nl_start[i + 1]; k++) {
      double *sh = &w->nl_shear[3 * k];
      carry_history(w, i, w->nl_j[k], sh);
      w->pair_touch[k] = sh[0] != 0 || sh[1] != 0 || sh[2] != 0; /* a spring to reset if open */
    }
    grain_refresh(m, s, i);
  }
  w->have_old = 1;
  if (!partial) {
    w->grid_ok = m->sleep.on;
    w->compact = 0;
    s->sleeping = n - na;
  }
  w->full_rebuilds += !partial;
  dem_neigh_reverse(s);
  s->rebuilds++;
  return m->n_meshes > 0 ? dem_mesh_lists(m, s, err) : 0;
}
