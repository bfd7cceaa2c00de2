/* dem_bed_touch.c — where a surface lowered straight down onto a settled
 * bed first touches a grain: (grains x, r; surface nodes, triangles) =>
 * (the surface's lowest node height at first touch). What `rim_center`
 * "auto" needs: the tread starts a gap above the first grain it would meet,
 * not above a percentile of the grain tops (the top few percent then start
 * inside the tread: issue 22's first-step overlap of 0.31 of a radius).
 *
 * Conservative on a grid: each x-y cell (side: the largest grain radius)
 * holds the lowest vertex height of the triangles whose x-y box meets it; a
 * grain's clearance is its top z + r against the lowest cell under its disk's
 * x-y box. So the answer is never below the exact vertical first touch of
 * the triangles' boxes and at most one cell's worth of surface slope above.
 * dem_bed_ready_top: the one rule both dem participants report by (this
 * with a surface, the percentile of all grain tops without). */
#include "dem_server/dem_internal.h"

#include <math.h>
#include <stdlib.h>

/* cells per axis at most: a surface far larger than its grains still gets a
 * grid that fits in memory (the cells grow, the answer stays conservative) */
#define DEM_TOUCH_MAX_CELLS 4096

static int cell_of(double v, double lo, double h, int n) {
  int c = (int)floor((v - lo) / h);
  return c < 0 ? 0 : c >= n ? n - 1 : c;
}

int dem_bed_touch_of(const double *xs, const double *r, int ng, const double *sx, int n_nodes,
                     const int32_t *tri, int n_tri, double *low_at_touch, int *count,
                     proto_err *err) {
  *low_at_touch = NAN;
  *count = 0;
  if (n_nodes <= 0 || n_tri <= 0 || ng <= 0) return 0;
  double lo[2], hi[2], zlow = INFINITY, rmax = 0;
  dem_footprint(sx, n_nodes, lo, hi);
  for (int i = 0; i < n_nodes; i++) zlow = fmin(zlow, sx[3 * (size_t)i + 2]);
  for (int i = 0; i < ng; i++) rmax = fmax(rmax, r[i]);
  double h = rmax > 0 ? rmax : 1;
  for (int k = 0; k < 2; k++)
    if ((hi[k] - lo[k]) / h > DEM_TOUCH_MAX_CELLS) h = (hi[k] - lo[k]) / DEM_TOUCH_MAX_CELLS;
  const int nx = (int)ceil((hi[0] - lo[0]) / h) + 1, ny = (int)ceil((hi[1] - lo[1]) / h) + 1;
  double *cell = malloc(sizeof(double) * (size_t)nx * (size_t)ny);
  if (!cell) return proto_fail(err, "out of memory (bed touch grid %d x %d)", nx, ny);
  for (size_t c = 0; c < (size_t)nx * (size_t)ny; c++) cell[c] = INFINITY;
  for (int t = 0; t < n_tri; t++) { /* each triangle's lowest vertex over its x-y box */
    double tlo[2] = {INFINITY, INFINITY}, thi[2] = {-INFINITY, -INFINITY}, zmin = INFINITY;
    for (int k = 0; k < 3; k++) {
      const double *p = &sx[3 * (size_t)tri[3 * (size_t)t + k]];
      for (int d = 0; d < 2; d++) tlo[d] = fmin(tlo[d], p[d]), thi[d] = fmax(thi[d], p[d]);
      zmin = fmin(zmin, p[2]);
    }
    const int x0 = cell_of(tlo[0], lo[0], h, nx), x1 = cell_of(thi[0], lo[0], h, nx);
    const int y0 = cell_of(tlo[1], lo[1], h, ny), y1 = cell_of(thi[1], lo[1], h, ny);
    for (int cx = x0; cx <= x1; cx++)
      for (int cy = y0; cy <= y1; cy++) {
        double *z = &cell[(size_t)cx * (size_t)ny + (size_t)cy];
        *z = fmin(*z, zmin);
      }
  }
  double need = -INFINITY;
  int n = 0;
  for (int i = 0; i < ng; i++) {
    const double *x = &xs[3 * (size_t)i];
    if (x[0] + r[i] < lo[0] || x[0] - r[i] > hi[0] || x[1] + r[i] < lo[1] || x[1] - r[i] > hi[1])
      continue;
    const int x0 = cell_of(x[0] - r[i], lo[0], h, nx), x1 = cell_of(x[0] + r[i], lo[0], h, nx);
    const int y0 = cell_of(x[1] - r[i], lo[1], h, ny), y1 = cell_of(x[1] + r[i], lo[1], h, ny);
    double under = INFINITY; /* the lowest surface over the grain's disk */
    for (int cx = x0; cx <= x1; cx++)
      for (int cy = y0; cy <= y1; cy++) under = fmin(under, cell[(size_t)cx * (size_t)ny + (size_t)cy]);
    if (!isfinite(under)) continue;
    n++;
    /* lowered by (under - (z + r)) the surface meets this grain: its lowest
     * node is then at zlow - (under - (z + r)) */
    need = fmax(need, x[2] + r[i] - (under - zlow));
  }
  free(cell);
  *count = n;
  if (n > 0) *low_at_touch = need;
  return 0;
}

int dem_bed_ready_top(const double *xs, const double *r, int ng, const double *sx, int n_nodes,
                      const int32_t *tri, int n_tri, double *top, int *count, proto_err *err) {
  if (n_nodes > 0 && n_tri > 0)
    return dem_bed_touch_of(xs, r, ng, sx, n_nodes, tri, n_tri, top, count, err);
  double lo[2], hi[2];
  dem_footprint(NULL, 0, lo, hi); /* the whole plane */
  return dem_bed_top_of(xs, r, ng, lo, hi, DEM_BED_TOP_PERCENTILE, top, count, err);
}
