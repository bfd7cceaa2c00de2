/* h5util.c — HDF5 datasets and attributes for green/ (doubles, ints, text). */
#include <string.h>

#include "green/h5util.h"

int grn_h5_write(hid_t loc, const char *name, int ndim, const hsize_t *dims,
                 const double *data, proto_err *err) {
  hid_t sp = H5Screate_simple(ndim, dims, NULL);
  hid_t ds = H5Dcreate2(loc, name, H5T_IEEE_F64LE, sp, H5P_DEFAULT, H5P_DEFAULT,
                        H5P_DEFAULT);
  herr_t st = ds < 0 ? -1 : H5Dwrite(ds, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, data);
  if (ds >= 0) H5Dclose(ds);
  H5Sclose(sp);
  return st < 0 ? proto_fail(err, "HDF5: cannot write dataset %s", name) : 0;
}

static int attr_write(hid_t loc, const char *name, hid_t type, hid_t mem,
                      const void *v) {
  hid_t sp = H5Screate(H5S_SCALAR);
  if (H5Aexists(loc, name) > 0)
    H5Adelete(loc, name);
  hid_t a = H5Acreate2(loc, name, type, sp, H5P_DEFAULT, H5P_DEFAULT);
  herr_t st = a < 0 ? -1 : H5Awrite(a, mem, v);
  if (a >= 0) H5Aclose(a);
  H5Sclose(sp);
  return st < 0 ? -1 : 0;
}

int grn_h5_attr_d(hid_t loc, const char *name, double v) {
  return attr_write(loc, name, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, &v);
}
int grn_h5_attr_i(hid_t loc, const char *name, long v) {
  return attr_write(loc, name, H5T_STD_I64LE, H5T_NATIVE_LONG, &v);
}
int grn_h5_attr_s(hid_t loc, const char *name, const char *v) {
  hid_t t = H5Tcopy(H5T_C_S1);
  H5Tset_size(t, strlen(v) + 1);
  H5Tset_strpad(t, H5T_STR_NULLTERM);
  int rc = attr_write(loc, name, t, t, v);
  H5Tclose(t);
  return rc;
}
