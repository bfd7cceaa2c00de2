/* blk_io.c — reads the Green's-function and spring files of cosim_green
 * (green/FORMATS.md). */
#include <hdf5.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "contact_block/blk.h"

/* Relative mismatch of a file's element size taken as round-off. */
#define BLK_SIZE_TOL 1e-9

/* Reads a 2-D/3-D f8 dataset; dims (rank entries) out; data malloc'ed. */
static double *read_dataset(hid_t f, const char *path, const char *file, int rank,
                            hsize_t *dims, proto_err *err) {
  if (H5Lexists(f, path, H5P_DEFAULT) <= 0) {
    proto_fail(err, "%s: dataset %s missing", file, path);
    return NULL;
  }
  hid_t ds = H5Dopen2(f, path, H5P_DEFAULT);
  if (ds < 0) {
    proto_fail(err, "%s: cannot open %s", file, path);
    return NULL;
  }
  hid_t sp = H5Dget_space(ds);
  int r = H5Sget_simple_extent_ndims(sp);
  double *buf = NULL;
  if (r != rank) {
    proto_fail(err, "%s: %s has rank %d, expected %d", file, path, r, rank);
  } else {
    H5Sget_simple_extent_dims(sp, dims, NULL);
    size_t n = 1;
    for (int i = 0; i < rank; i++) n *= dims[i];
    buf = malloc((n ? n : 1) * sizeof(double));
    if (!buf) {
      proto_fail(err, "out of memory");
    } else if (H5Dread(ds, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, buf) < 0) {
      proto_fail(err, "%s: cannot read %s", file, path);
      free(buf);
      buf = NULL;
    }
  }
  H5Sclose(sp);
  H5Dclose(ds);
  return buf;
}

static int attr_double(hid_t obj, const char *name, double *out) {
  if (H5Aexists(obj, name) <= 0) return -1;
  hid_t a = H5Aopen(obj, name, H5P_DEFAULT);
  int rc = H5Aread(a, H5T_NATIVE_DOUBLE, out) < 0 ? -1 : 0;
  H5Aclose(a);
  return rc;
}

static void attr_string(hid_t obj, const char *name, char *out, size_t cap) {
  out[0] = 0;
  if (H5Aexists(obj, name) <= 0) return;
  hid_t a = H5Aopen(obj, name, H5P_DEFAULT);
  hid_t t = H5Aget_type(a);
  if (H5Tget_class(t) == H5T_STRING) {
    hid_t mt = H5Tcopy(H5T_C_S1);
    if (H5Tis_variable_str(t) > 0) {
      H5Tset_size(mt, H5T_VARIABLE);
      char *s = NULL;
      if (H5Aread(a, mt, &s) >= 0 && s) {
        snprintf(out, cap, "%s", s);
        H5free_memory(s);
      }
    } else {
      size_t n = H5Tget_size(t);
      char *s = calloc(n + 1, 1);
      H5Tset_size(mt, n + 1);
      if (s && H5Aread(a, mt, s) >= 0) snprintf(out, cap, "%s", s);
      free(s);
    }
    H5Tclose(mt);
  }
  H5Tclose(t);
  H5Aclose(a);
}

static hid_t open_file(const char *path, proto_err *err) {
  H5Eset_auto2(H5E_DEFAULT, NULL, NULL);
  hid_t f = H5Fopen(path, H5F_ACC_RDONLY, H5P_DEFAULT);
  if (f < 0) proto_fail(err, "%s: cannot open as HDF5", path);
  return f;
}

int blk_green_load(blk_model *m, const char *path, proto_err *err) {
  hid_t f = open_file(path, err);
  if (f < 0) return -1;
  int rc = -1;
  double *g = NULL, *st = NULL;
  hid_t grp = H5Gopen2(f, "/green", H5P_DEFAULT);
  if (grp < 0) {
    proto_fail(err, "%s: group /green missing", path);
    goto done;
  }
  double rate = 0, fdx = 0, fdy = 0;
  attr_double(grp, "rate", &rate);
  /* the element size the file was computed for must be the block's */
  if (attr_double(grp, "dx", &fdx) == 0 && attr_double(grp, "dy", &fdy) == 0 &&
      (fabs(fdx / m->dx - 1) > BLK_SIZE_TOL || fabs(fdy / m->dy - 1) > BLK_SIZE_TOL)) {
    proto_fail(err, "%s: elements of %g x %g m, the block's are %g x %g m (grid.dx, "
               "grid.dy)", path, fdx, fdy, m->dx, m->dy);
    goto done;
  }
  char sampling[16], model[64];
  attr_string(grp, "sampling", sampling, sizeof sampling);
  attr_string(grp, "model", model, sizeof model);
  hsize_t ds[3], dg[3] = {0, 0, 0};
  st = read_dataset(f, "/green/static", path, 2, ds, err);
  if (!st) goto done;
  if (rate > 0) {
    g = read_dataset(f, "/green/g", path, 3, dg, err);
    if (!g) goto done;
    if (dg[1] != ds[0] || dg[2] != ds[1]) {
      proto_fail(err, "%s: /green/g offsets [%llu, %llu] differ from /green/static "
                 "[%llu, %llu]", path, (unsigned long long)dg[1],
                 (unsigned long long)dg[2], (unsigned long long)ds[0],
                 (unsigned long long)ds[1]);
      goto done;
    }
  }
  if (blk_green_set(m, rate > 0 ? (int)dg[0] : 1, rate, (int)ds[0], (int)ds[1], g, st,
                    rate > 0 ? (sampling[0] ? sampling : "zoh") : "static", model, err)) {
    proto_wrap(err, "%s", path);
    goto done;
  }
  rc = 0;
done:
  free(g);
  free(st);
  if (grp >= 0) H5Gclose(grp);
  H5Fclose(f);
  return rc;
}

int blk_springs_load(blk_model *m, const char *path, proto_err *err) {
  hid_t f = open_file(path, err);
  if (f < 0) return -1;
  int rc = -1;
  double *d = NULL, *F = NULL, *k = NULL, *z = NULL;
  hsize_t dd[2], dF[2], dk[2], dz[2];
  if (!(d = read_dataset(f, "/springs/d", path, 2, dd, err))) goto done;
  if (!(F = read_dataset(f, "/springs/F", path, 2, dF, err))) goto done;
  if (!(k = read_dataset(f, "/springs/k", path, 2, dk, err))) goto done;
  if (dd[0] != (hsize_t)m->M || dF[0] != dd[0] || dk[0] != dd[0] || dF[1] != dd[1] ||
      dk[1] != dd[1]) {
    proto_fail(err, "%s: /springs/d, F, k must all be [M, K] with M = %d (got [%llu, "
               "%llu], [%llu, %llu], [%llu, %llu])", path, m->M,
               (unsigned long long)dd[0], (unsigned long long)dd[1],
               (unsigned long long)dF[0], (unsigned long long)dF[1],
               (unsigned long long)dk[0], (unsigned long long)dk[1]);
    goto done;
  }
  if (blk_springs_table(m, (int)dd[1], d, F, k, err)) {
    proto_wrap(err, "%s", path);
    goto done;
  }
  if (H5Lexists(f, "/springs/z_road", H5P_DEFAULT) > 0) {
    if (!(z = read_dataset(f, "/springs/z_road", path, 2, dz, err))) goto done;
    if (dz[0] != (hsize_t)m->ny || dz[1] != (hsize_t)m->nx) {
      proto_fail(err, "%s: /springs/z_road must be [ny, nx] = [%d, %d]", path, m->ny,
                 m->nx);
      goto done;
    }
    if (blk_road_set(m, z, err)) {
      proto_wrap(err, "%s", path);
      goto done;
    }
  }
  hid_t grp = H5Gopen2(f, "/springs", H5P_DEFAULT);
  if (grp >= 0) {
    double rf;
    if (attr_double(grp, "release_force", &rf) == 0 && rf > 0) m->release_force = rf;
    H5Gclose(grp);
  }
  rc = 0;
done:
  free(d);
  free(F);
  free(k);
  free(z);
  H5Fclose(f);
  return rc;
}
