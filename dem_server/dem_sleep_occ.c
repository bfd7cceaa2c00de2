/* dem_sleep_occ.c — the grains' occupancy grid that the region reads
 * (dem_sleep.c region_update): which cells of a grid of side at least the
 * reach hold some grain, so that only the moving meshes' triangles near a
 * grain draw the region.
 *
 * Data flow: (x, radius, v of the grains; the asleep block by cell of the
 * last full rebuild; the box of the cells the candidate triangles will read)
 * => (w->occ, occ_lo, occ_h, occ_dim).
 *
 * Only the cells a query can read are marked: the candidate triangles (those
 * whose box meets the grains' box grown by the reach) are known before the
 * grid is filled, and a query reads the cells of one of their boxes grown by
 * the reach, all inside the union of those boxes. A cell there is marked
 * exactly as when every grain marked every cell: each grain that can meet
 * such a cell is visited (the awake ones all; the asleep ones from the cells
 * of the last full rebuild around the union, which hold them where they fell
 * asleep), and marking is idempotent. The asleep grains far from the tyre,
 * most of a deep bed, are not read at all.
 *
 * Every grain slower than sleep.wake_velocity marks its cells, the asleep
 * ones included (they stand where they fell asleep). A faster grain is awake
 * whatever the region (too fast to fall asleep) and wakes each asleep
 * neighbour it approaches (the wake rule): a triangle that only such grains
 * are near needs no region around it. On the sand scene these are the grains
 * the tread carries up behind the tyre, which drew the region's rear out to
 * -0.28 m of the rim instead of -0.20...-0.23 m
 * (bench/results/sand_calibration.md). */
#include "dem_server/dem_internal.h"

#include <math.h>
#include <string.h>

/* The cells [a, b] (per axis) of the occupancy grid from the floors fa, fb
 * of a box's ends over the cell side, clamped to the grid; 0 if the box lies
 * outside it. */
static int occ_clamp(const struct dem_work *w, const double *fa, const double *fb, int *a, int *b) {
  for (int k = 0; k < 3; k++) {
    if (fb[k] < 0 || fa[k] >= w->occ_dim[k]) return 0;
    a[k] = fa[k] < 0 ? 0 : (int)fa[k];
    b[k] = fb[k] >= w->occ_dim[k] ? w->occ_dim[k] - 1 : (int)fb[k];
  }
  return 1;
}

/* The cells [a, b] (per axis) of the occupancy grid that the box lo..hi
 * meets, clamped to the grid; 0 if the box lies outside it. */
static int occ_range(const struct dem_work *w, const double *lo, const double *hi, int *a, int *b) {
  double fa[3], fb[3];
  for (int k = 0; k < 3; k++) {
    fa[k] = floor((lo[k] - w->occ_lo[k]) / w->occ_h);
    fb[k] = floor((hi[k] - w->occ_lo[k]) / w->occ_h);
  }
  return occ_clamp(w, fa, fb, a, b);
}

static size_t occ_cell(const struct dem_work *w, int x, int y, int z) {
  return ((size_t)z * w->occ_dim[1] + y) * w->occ_dim[0] + x;
}

/* The cells (as doubles: floor of the offset over the side) where the
 * sphere boxes of nb grains start and end along axis k: occ_range's
 * arithmetic (occ_clamp then clamps them), the same IEEE operations, in a loop the compiler vectorises
 * (the divisions were 4 % of a sand-scene step, one grain at a time). */
__attribute__((target_clones("avx2", "default")))
static void occ_cells_axis(const double *restrict x, const double *restrict rad, int nb, double o, double h,
                           double *restrict lo, double *restrict hi) {
  double c[DEM_OCC_BLOCK];
  for (int q = 0; q < nb; q++) c[q] = x[3 * q]; /* the axis in sequence */
  for (int q = 0; q < nb; q++) {
    lo[q] = floor((c[q] - rad[q] - o) / h);
    hi[q] = floor((c[q] + rad[q] - o) / h);
  }
}

/* Marks the cells within qa..qb that the sphere boxes of slots lo..hi−1 meet
 * (an awake grain faster than vf2^½ marks none). */
static void occ_mark(const dem_state *s, int lo, int hi, const int *qa, const int *qb, double vf2) {
  struct dem_work *w = s->work;
  for (int i0 = lo; i0 < hi; i0 += DEM_OCC_BLOCK) {
    double fa[3][DEM_OCC_BLOCK], fb[3][DEM_OCC_BLOCK];
    const int nb = hi - i0 < DEM_OCC_BLOCK ? hi - i0 : DEM_OCC_BLOCK;
    for (int k = 0; k < 3; k++)
      occ_cells_axis(&s->x[3 * i0 + k], &s->radius[i0], nb, w->occ_lo[k], w->occ_h, fa[k], fb[k]);
    for (int q = 0; q < nb; q++) {
      const int i = i0 + q;
      if (i < w->n_active && dem_dot(&s->v[3 * i], &s->v[3 * i]) > vf2) continue; /* asleep: v = 0, not read */
      const double flo[3] = {fa[0][q], fa[1][q], fa[2][q]}, fhi[3] = {fb[0][q], fb[1][q], fb[2][q]};
      int a[3], b[3];
      if (!occ_clamp(w, flo, fhi, a, b)) continue;
      for (int k = 0; k < 3; k++) {
        a[k] = a[k] > qa[k] ? a[k] : qa[k];
        b[k] = b[k] < qb[k] ? b[k] : qb[k];
      }
      for (int z = a[2]; z <= b[2]; z++)
        for (int y = a[1]; y <= b[1]; y++)
          for (int c = a[0]; c <= b[0]; c++) __atomic_store_n(&w->occ[occ_cell(w, c, y, z)], 1, __ATOMIC_RELAXED);
    }
  }
}

/* The asleep grains whose centres lie within lo..hi (and some beyond: the
 * cells of the last full rebuild that meet it), marked as occ_mark does;
 * per row of cells (y, z), each cell's asleep grains one slot range. */
static void occ_mark_asleep(const dem_state *s, const double *lo, const double *hi, const int *qa, const int *qb,
                            double vf2) {
  const struct dem_work *w = s->work;
  int c0[3], c1[3];
  for (int k = 0; k < 3; k++) {
    c0[k] = dem_cell_coord(w, lo[k], k); /* monotone and clamped: every cell a centre in lo..hi can have */
    c1[k] = dem_cell_coord(w, hi[k], k);
  }
  const int ny = c1[1] - c0[1] + 1, rows = ny * (c1[2] - c0[2] + 1);
#pragma omp parallel for schedule(dynamic, 4) num_threads(w->nthreads) if (s->n >= w->occ_threads_min)
  for (int row = 0; row < rows; row++) {
    const int y = c0[1] + row % ny, z = c0[2] + row / ny;
    for (int x = c0[0]; x <= c1[0]; x++) {
      const int r = w->cell_rank[dem_cell_index(w, x, y, z)];
      occ_mark(s, w->frz_start[r], w->frz_start[r + 1], qa, qb, vf2);
    }
  }
}

void dem_occ_build(const dem_state *s, const double *glo, const double *ghi, double reach, double vfast,
                   const double *qlo, const double *qhi) {
  struct dem_work *w = s->work;
  const double rmax = w->region_rmax;
  double ext[3], h = reach;
  for (int k = 0; k < 3; k++) {
    w->occ_lo[k] = glo[k] - rmax;
    ext[k] = ghi[k] + rmax - w->occ_lo[k];
  }
  for (;;) { /* cells of side h, fewer than the grid's cap */
    double cells = 1;
    for (int k = 0; k < 3; k++) cells *= floor(ext[k] / h) + 1;
    if (cells <= DEM_REGION_OCC_CELLS) break;
    h *= 1.25;
  }
  w->occ_h = h;
  for (int k = 0; k < 3; k++) w->occ_dim[k] = (int)floor(ext[k] / h) + 1;
  memset(w->occ, 0, occ_cell(w, 0, 0, w->occ_dim[2]));
  int qa[3], qb[3];
  if (!occ_range(w, qlo, qhi, qa, qb)) return; /* no query reads a cell */
  const double vf2 = vfast * vfast;
  /* the awake grains (all of them without a grid of the asleep block): split
   * over the threads (a cell is marked, never cleared, so the grid is the
   * same for any split; relaxed atomic stores, as two threads may mark one) */
  const int every = w->grid_ok ? w->n_active : s->n;
  const int blocks = (every + DEM_OCC_BLOCK - 1) / DEM_OCC_BLOCK;
#pragma omp parallel for schedule(static) num_threads(w->nthreads) if (s->n >= w->occ_threads_min)
  for (int b = 0; b < blocks; b++) {
    const int lo = b * DEM_OCC_BLOCK;
    occ_mark(s, lo, lo + DEM_OCC_BLOCK < every ? lo + DEM_OCC_BLOCK : every, qa, qb, vf2);
  }
  if (every == s->n) return;
  /* an asleep grain that meets a cell qa..qb has its centre within rmax of
   * their box (a cell more on each side: the cells' rounding) */
  double lo[3], hi[3];
  for (int k = 0; k < 3; k++) {
    lo[k] = w->occ_lo[k] + (qa[k] - 1) * h - rmax;
    hi[k] = w->occ_lo[k] + (qb[k] + 2) * h + rmax;
  }
  occ_mark_asleep(s, lo, hi, qa, qb, vf2);
}

int dem_occ_hit(const struct dem_work *w, const double *lo, const double *hi, double reach) {
  const double glo[3] = {lo[0] - reach, lo[1] - reach, lo[2] - reach};
  const double ghi[3] = {hi[0] + reach, hi[1] + reach, hi[2] + reach};
  int a[3], b[3];
  if (!occ_range(w, glo, ghi, a, b)) return 0;
  for (int z = a[2]; z <= b[2]; z++)
    for (int y = a[1]; y <= b[1]; y++)
      for (int c = a[0]; c <= b[0]; c++)
        if (w->occ[occ_cell(w, c, y, z)]) return 1;
  return 0;
}
