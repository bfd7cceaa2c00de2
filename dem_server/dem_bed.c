/* dem_bed.c — the soil bed of seed 000 (table 2): three layers of grains,
 * placed without overlap on jittered lattices, settled under gravity by the
 * caller (dem_settle); beds saved to and loaded from HDF5. */
#include "dem_server/dem_internal.h"

#include <hdf5.h>

#define DEM_BED_MAX_OVERLAP "max_overlap" /* dataset: largest overlap when saved */
#include <stdlib.h>
#include <string.h>

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
  if (total <= 0 || total > 100000000) return proto_fail(err, "bed: %lld grains", (long long)total);
  if (dem_model_alloc_grains(m, (int)total, err)) return -1;
  uint64_t st = b->seed;
  double z = 0;
  int i = 0;
  for (int k = 0; k < b->n_layers; k++) {
    const dem_bed_layer *L = &b->layers[k];
    const double dmax = L->diameter + L->spread, a = dmax + b->gap; /* lattice pitch */
    const int nx = (int)(b->size[0] / a), ny = (int)(b->size[1] / a);
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

static int write_ds(hid_t f, const char *name, hid_t type, int rank, hsize_t n, hsize_t cols,
                    const void *data) {
  hsize_t dims[2] = {n, cols};
  hid_t sp = H5Screate_simple(rank, dims, NULL);
  hid_t ds = H5Dcreate2(f, name, type, sp, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  herr_t rc = ds >= 0 ? H5Dwrite(ds, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data) : -1;
  if (ds >= 0) H5Dclose(ds);
  H5Sclose(sp);
  return rc < 0 ? -1 : 0;
}

int dem_bed_save(const dem_model *m, const dem_state *s, const char *path, proto_err *err) {
  const size_t n = (size_t)s->n;
  double *buf = malloc(sizeof(double) * 9 * n + 1);
  int32_t *mat = malloc(sizeof(int32_t) * n + 1);
  if (!buf || !mat) { free(buf); free(mat); return proto_fail(err, "%s: out of memory", path); }
  hid_t f = H5Fcreate(path, H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  int rc = f < 0 ? -1 : 0;
  dem_gather(s, s->x, 3, buf);
  dem_gather(s, s->v, 3, buf + 3 * n);
  dem_gather(s, s->omega, 3, buf + 6 * n);
  if (!rc) rc = write_ds(f, "x", H5T_NATIVE_DOUBLE, 2, n, 3, buf);
  if (!rc) rc = write_ds(f, "v", H5T_NATIVE_DOUBLE, 2, n, 3, buf + 3 * n);
  if (!rc) rc = write_ds(f, "omega", H5T_NATIVE_DOUBLE, 2, n, 3, buf + 6 * n);
  dem_gather(s, s->radius, 1, buf);
  if (!rc) rc = write_ds(f, "r", H5T_NATIVE_DOUBLE, 1, n, 1, buf);
  for (int i = 0; i < s->n; i++) mat[s->id[i]] = s->material[i];
  if (!rc) rc = write_ds(f, "material", H5T_NATIVE_INT32, 1, n, 1, mat);
  const double worst = dem_worst_overlap(m, s);
  if (!rc) rc = write_ds(f, DEM_BED_MAX_OVERLAP, H5T_NATIVE_DOUBLE, 1, 1, 1, &worst);
  if (f >= 0 && H5Fclose(f) < 0) rc = -1;
  free(buf);
  free(mat);
  return rc ? proto_fail(err, "%s: cannot write the bed (HDF5 error)", path) : 0;
}

static int read_ds(hid_t f, const char *name, hid_t type, hsize_t n, hsize_t cols, void *out,
                   int optional, const char *path, proto_err *err) {
  if (H5Lexists(f, name, H5P_DEFAULT) <= 0)
    return optional ? 0 : proto_fail(err, "%s: dataset '%s' missing", path, name);
  hid_t ds = H5Dopen2(f, name, H5P_DEFAULT);
  hid_t sp = H5Dget_space(ds);
  hsize_t dims[2] = {0, 0};
  int rank = H5Sget_simple_extent_dims(sp, dims, NULL);
  int ok = dims[0] == n && (cols == 1 ? (rank == 1 || (rank == 2 && dims[1] == 1)) : (rank == 2 && dims[1] == cols));
  herr_t rc = ok ? H5Dread(ds, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, out) : -1;
  H5Sclose(sp);
  H5Dclose(ds);
  if (!ok) return proto_fail(err, "%s: dataset '%s' must have shape [%llu, %llu]", path, name,
                             (unsigned long long)n, (unsigned long long)cols);
  return rc < 0 ? proto_fail(err, "%s: cannot read '%s'", path, name) : 0;
}

int dem_bed_load(dem_model *m, const char *path, proto_err *err) {
  H5E_auto2_t fn;
  void *data;
  H5Eget_auto2(H5E_DEFAULT, &fn, &data);
  H5Eset_auto2(H5E_DEFAULT, NULL, NULL);
  hid_t f = H5Fopen(path, H5F_ACC_RDONLY, H5P_DEFAULT);
  int rc = -1;
  if (f < 0) {
    proto_fail(err, "%s: cannot open the bed file", path);
    goto out;
  }
  hid_t ds = H5Dopen2(f, "r", H5P_DEFAULT);
  hsize_t dims[2] = {0, 0};
  if (ds >= 0) {
    hid_t sp = H5Dget_space(ds);
    H5Sget_simple_extent_dims(sp, dims, NULL);
    H5Sclose(sp);
    H5Dclose(ds);
  }
  if (ds < 0 || dims[0] == 0) {
    proto_fail(err, "%s: no dataset 'r' (grain radii)", path);
  } else if (!dem_model_alloc_grains(m, (int)dims[0], err) &&
             !read_ds(f, "x", H5T_NATIVE_DOUBLE, dims[0], 3, m->x0, 0, path, err) &&
             !read_ds(f, "r", H5T_NATIVE_DOUBLE, dims[0], 1, m->radius, 0, path, err) &&
             !read_ds(f, "v", H5T_NATIVE_DOUBLE, dims[0], 3, m->v0, 1, path, err) &&
             !read_ds(f, "omega", H5T_NATIVE_DOUBLE, dims[0], 3, m->omega0, 1, path, err) &&
             !read_ds(f, "material", H5T_NATIVE_INT32, dims[0], 1, m->material, 1, path, err) &&
             !read_ds(f, DEM_BED_MAX_OVERLAP, H5T_NATIVE_DOUBLE, 1, 1, &m->bed_max_overlap, 1, path, err)) {
    rc = 0;
    if (!(m->bed_max_overlap >= 0 && m->bed_max_overlap < 1))
      rc = proto_fail(err, "%s: %s = %g (expected a fraction in [0, 1))", path, DEM_BED_MAX_OVERLAP, m->bed_max_overlap);
    for (int i = 0; i < m->n_grains && !rc; i++)
      if (!(m->radius[i] > 0)) rc = proto_fail(err, "%s: grain %d has radius %g (must be > 0)", path, i, m->radius[i]);
  }
  H5Fclose(f);
out:
  H5Eset_auto2(H5E_DEFAULT, fn, data);
  return rc;
}
