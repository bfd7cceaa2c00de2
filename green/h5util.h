/* h5util.h — datasets of the green/ files (FORMATS.md), written through
 * proto's HDF5 writer (proto_h5_*); they are read through proto_h5in_*. */
#ifndef COSIM_GREEN_H5UTIL_H
#define COSIM_GREEN_H5UTIL_H
#include "proto/proto.h"

/* Doubles of shape dims[0..ndim) as dataset "<group>/<name>". */
int grn_h5_write(proto_h5 *f, const char *group, const char *name, int ndim,
                 const int64_t *dims, const double *data, proto_err *err);
#endif
