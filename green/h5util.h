/* h5util.h — small HDF5 helpers for writing the green/ files (FORMATS.md);
 * they are read through proto_h5in_* (proto.h). */
#ifndef COSIM_GREEN_H5UTIL_H
#define COSIM_GREEN_H5UTIL_H
#include <hdf5.h>

#include "proto/proto.h"

int grn_h5_write(hid_t loc, const char *name, int ndim, const hsize_t *dims,
                 const double *data, proto_err *err);
int grn_h5_attr_d(hid_t loc, const char *name, double v);
int grn_h5_attr_i(hid_t loc, const char *name, long v);
int grn_h5_attr_s(hid_t loc, const char *name, const char *v);
#endif
