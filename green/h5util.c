/* h5util.c — doubles as a dataset of the green/ files, through proto_h5. */
#include <stdio.h>

#include "green/h5util.h"

int grn_h5_write(proto_h5 *f, const char *group, const char *name, int ndim,
                 const int64_t *dims, const double *data, proto_err *err) {
  proto_array a = {.dtype = PROTO_F8, .ndim = ndim, .data = data,
                   .nbytes = sizeof(double)};
  snprintf(a.name, sizeof a.name, "%s", name);
  for (int i = 0; i < ndim && i < PROTO_MAX_NDIM; i++) {
    a.shape[i] = dims[i];
    a.nbytes *= (size_t)dims[i];
  }
  return proto_h5_write_array(f, group, &a, err);
}
