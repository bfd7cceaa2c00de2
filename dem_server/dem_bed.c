/* dem_bed.c — the soil bed of seed 000 (table 2): three layers of grains,
 * placed without overlap on jittered lattices, settled under gravity by the
 * caller (dem_settle); beds saved to and loaded from HDF5. */
#include "dem_server/dem_internal.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define DEM_BED_MAX_OVERLAP "max_overlap" /* dataset: largest overlap when saved */

void dem_bed_paper(dem_bed_spec *b, double scale) {
  memset(b, 0, sizeof *b);
  /* 1.0 × 1.0 m, 21 812 grains; diameters 15.6, 7.8, 6.9 ± 0.345 mm, the
   * smallest on top. The paper gives no per-layer counts: equal thirds. */
  const double d[3] = {15.6e-3, 7.8e-3, 6.9e-3}, spread[3] = {0, 0, 0.345e-3};
  const int64_t total = (int64_t)llround(21812 * scale);
  b->n_layers = 3;
  for (int k = 0; k < 3; k++) {
    b->layers[k].diameter = d[k];
    b->layers[k].spread = spread[k];
    b->layers[k].count = total / 3 + (k < total % 3);
  }
  b->size[0] = b->size[1] = 1.0 * sqrt(scale);
  b->gap = 0.5e-3;
  b->seed = 1;
}

/* splitmix64: reproducible placement from the seed */
static double uniform(uint64_t *st) {
  uint64_t z = (*st += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  z ^= z >> 31;
  return (double)(z >> 11) * (1.0 / 9007199254740992.0);
}

int dem_bed_place(dem_model *m, const dem_bed_spec *b, proto_err *err) {
  int64_t total = 0;
  for (int k = 0; k < b->n_layers; k++) total += b->layers[k].count;
  if (total <= 0 || total > DEM_MAX_GRAINS)
    return proto_fail(err, "bed: %lld grains (1 to %lld)", (long long)total, (long long)DEM_MAX_GRAINS);
  if (dem_model_alloc_grains(m, (int)total, err)) return -1;
  uint64_t st = b->seed;
  double z = 0;
  int i = 0;
  for (int k = 0; k < b->n_layers; k++) {
    const dem_bed_layer *L = &b->layers[k];
    const double dmax = L->diameter + L->spread, a = dmax + b->gap; /* lattice pitch */
    /* lattice cells per row; more than DEM_MAX_GRAINS would stay empty (and
     * a footprint of 1e30 m must not overflow the int) */
    const int nx = (int)fmin(b->size[0] / a, (double)DEM_MAX_GRAINS),
              ny = (int)fmin(b->size[1] / a, (double)DEM_MAX_GRAINS);
    if (nx < 1 || ny < 1)
      return proto_fail(err, "bed: footprint %g x %g m smaller than one grain of layer %d",
                        b->size[0], b->size[1], k);
    for (int64_t c = 0; c < L->count; c++, i++) {
      const int64_t cell = c % ((int64_t)nx * ny), level = c / ((int64_t)nx * ny);
      const int ix = (int)(cell % nx), iy = (int)(cell / nx);
      const double d = L->diameter + L->spread * (2 * uniform(&st) - 1);
      const double jit = 0.45 * (a - d); /* stays inside its lattice cell: no overlap */
      m->x0[3 * i] = (ix + 0.5) * a + jit * (2 * uniform(&st) - 1);
      m->x0[3 * i + 1] = (iy + 0.5) * a + jit * (2 * uniform(&st) - 1);
      m->x0[3 * i + 2] = z + (level + 0.5) * a;
      m->radius[i] = 0.5 * d;
      m->material[i] = b->material;
    }
    const int64_t levels = (L->count + (int64_t)nx * ny - 1) / ((int64_t)nx * ny);
    z += levels * a;
  }
  return 0;
}

/* ------------------------------------------------------------------ HDF5 */

/* Dataset "/<name>": n rows of cols columns ([n] when rank is 1). */
static int write_ds(proto_h5 *f, const char *name, proto_dtype dtype, int rank, int64_t n,
                    int64_t cols, const void *data, proto_err *err) {
  proto_array a = {.dtype = dtype, .ndim = rank, .shape = {n, cols}, .data = data,
                   .nbytes = (size_t)(n * cols) * proto_dtype_size(dtype)};
  snprintf(a.name, sizeof a.name, "%s", name);
  return proto_h5_write_array(f, "/", &a, err);
}

int dem_bed_save(const dem_model *m, const dem_state *s, const char *path, proto_err *err) {
  const int64_t n = s->n;
  double *buf = malloc(sizeof(double) * 9 * (size_t)n + 1);
  int32_t *mat = malloc(sizeof(int32_t) * (size_t)n + 1);
  proto_h5 *f = buf && mat ? proto_h5_create(path, err) : NULL;
  if (!f) {
    free(buf);
    free(mat);
    return buf && mat ? -1 : proto_fail(err, "%s: out of memory", path);
  }
  dem_gather(s, s->x, 3, buf);
  dem_gather(s, s->v, 3, buf + 3 * n);
  dem_gather(s, s->omega, 3, buf + 6 * n);
  int rc = write_ds(f, "x", PROTO_F8, 2, n, 3, buf, err);
  if (!rc) rc = write_ds(f, "v", PROTO_F8, 2, n, 3, buf + 3 * n, err);
  if (!rc) rc = write_ds(f, "omega", PROTO_F8, 2, n, 3, buf + 6 * n, err);
  dem_gather(s, s->radius, 1, buf);
  if (!rc) rc = write_ds(f, "r", PROTO_F8, 1, n, 1, buf, err);
  for (int i = 0; i < s->n; i++) mat[s->id[i]] = s->material[i];
  if (!rc) rc = write_ds(f, "material", PROTO_I4, 1, n, 1, mat, err);
  const double worst = dem_worst_overlap(m, s);
  if (!rc) rc = write_ds(f, DEM_BED_MAX_OVERLAP, PROTO_F8, 1, 1, 1, &worst, err);
  if (proto_h5_close(f, rc ? NULL : err) < 0) rc = -1;
  free(buf);
  free(mat);
  return rc ? proto_wrap(err, "%s: cannot write the bed", path) : 0;
}

/* A per-grain dataset of n rows and cols columns ([n] or [n, 1] when cols
 * is 1) into out; optional datasets may be absent. */
static int read_grains(proto_h5in *f, const char *name, int64_t n, int cols, int integer,
                       void *out, int optional, proto_err *err) {
  if (!proto_h5in_exists(f, name))
    return optional ? 0 : proto_fail(err, "%s: dataset '%s' missing", proto_h5in_path(f), name);
  int rank = cols == 1 ? proto_h5in_rank(f, name, err) : 2;
  if (rank < 0) return -1;
  if (rank != 1 && rank != 2) rank = 2; /* the reader names the expected rank */
  int64_t dims[2] = {n, cols};
  void *buf = NULL;
  int rc = integer ? proto_h5in_read_i4(f, name, rank, dims, n * cols, (int32_t **)&buf, err)
                   : proto_h5in_read_f8(f, name, rank, dims, n * cols, (double **)&buf, err);
  if (rc == 0) memcpy(out, buf, (size_t)(n * cols) * (integer ? sizeof(int32_t) : sizeof(double)));
  free(buf);
  return rc;
}

int dem_bed_load(dem_model *m, const char *path, proto_err *err) {
  proto_h5in *f = proto_h5in_open(path, err);
  if (!f) return -1;
  int rc = -1;
  /* the grain count from r, bounded before anything is allocated */
  int rank = proto_h5in_exists(f, "r") ? proto_h5in_rank(f, "r", err) : -1;
  int64_t dims[2] = {-1, 1};
  double *r = NULL;
  if (rank < 0) {
    proto_fail(err, "%s: no dataset 'r' (grain radii)", path);
  } else if (proto_h5in_read_f8(f, "r", rank == 2 ? 2 : 1, dims, DEM_MAX_GRAINS, &r, err) == 0) {
    const int64_t n = dims[0];
    if (n == 0) {
      proto_fail(err, "%s: dataset 'r' holds no grains", path);
    } else if (!dem_model_alloc_grains(m, (int)n, err) &&
               !read_grains(f, "x", n, 3, 0, m->x0, 0, err) &&
               !read_grains(f, "v", n, 3, 0, m->v0, 1, err) &&
               !read_grains(f, "omega", n, 3, 0, m->omega0, 1, err) &&
               !read_grains(f, "material", n, 1, 1, m->material, 1, err) &&
               !read_grains(f, DEM_BED_MAX_OVERLAP, 1, 1, 0, &m->bed_max_overlap, 1, err)) {
      memcpy(m->radius, r, (size_t)n * sizeof(double));
      rc = 0;
      if (!(m->bed_max_overlap >= 0 && m->bed_max_overlap < 1))
        rc = proto_fail(err, "%s: %s = %g (expected a fraction in [0, 1))", path, DEM_BED_MAX_OVERLAP,
                        m->bed_max_overlap);
      for (int i = 0; i < m->n_grains && !rc; i++)
        if (!(m->radius[i] > 0))
          rc = proto_fail(err, "%s: grain %d has radius %g (must be > 0)", path, i, m->radius[i]);
    }
  }
  free(r);
  proto_h5in_close(f);
  return rc;
}

static int ascending(const void *a, const void *b) {
  const double x = *(const double *)a, y = *(const double *)b;
  return (x > y) - (x < y);
}

int dem_bed_top(const dem_state *s, const double lo[2], const double hi[2], double percentile,
                double *top, int *count, proto_err *err) {
  double *tops = malloc(sizeof(double) * (size_t)(s->n > 0 ? s->n : 1));
  if (!tops) return proto_fail(err, "out of memory (bed top)");
  int n = 0;
  for (int i = 0; i < s->n; i++) {
    const double *x = &s->x[3 * (size_t)i];
    if (x[0] >= lo[0] && x[0] <= hi[0] && x[1] >= lo[1] && x[1] <= hi[1])
      tops[n++] = x[2] + s->radius[i];
  }
  *count = n;
  *top = NAN;
  if (n > 0) {
    qsort(tops, (size_t)n, sizeof *tops, ascending);
    /* nearest rank: the smallest value with at least `percentile` % at or below it */
    int rank = (int)ceil(percentile / 100.0 * n);
    *top = tops[rank < 1 ? 0 : rank > n ? n - 1 : rank - 1];
  }
  free(tops);
  return 0;
}
