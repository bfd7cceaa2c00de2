/* h5members.h — the one HDF5 group walk, shared by the results file's
 * writer (output.c) and the HDF5 input layer (h5read.c); not part of
 * proto.h. */
#ifndef COSIM_PROTO_H5MEMBERS_H
#define COSIM_PROTO_H5MEMBERS_H
#include <hdf5.h>

/* Calls fn(name, ctx) for each member of the open group g, in name order,
 * until fn returns nonzero; *fn_rc gets its last result (0, 1 stop, -1
 * error). Returns HDF5's result (< 0: the group could not be walked). */
herr_t proto_h5_members(hid_t g, int (*fn)(const char *name, void *ctx), void *ctx,
                        int *fn_rc);
#endif
