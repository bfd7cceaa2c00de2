/* blk_io.c — reads the Green's-function and spring files of cosim_green
 * (green/FORMATS.md) through proto's HDF5 input layer: every dataset's shape
 * is checked against the block's grid (and a limit on samples or knots)
 * before it is read, attributes hold one value each, values are finite. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "contact_block/blk.h"

/* Relative mismatch of a file's element size taken as round-off. */
#define BLK_SIZE_TOL 1e-9

int blk_green_load(blk_model *m, const char *path, proto_err *err) {
  proto_h5in *f = proto_h5in_open(path, err);
  if (!f) return -1;
  int rc = -1;
  double *g = NULL, *st = NULL;
  double rate = 0, fdx = 0, fdy = 0;
  char sampling[16] = "", model[64] = "";
  if (!proto_h5in_exists(f, "/green")) {
    proto_fail(err, "%s: group /green missing", path);
    goto done;
  }
  if (proto_h5in_attr_f8(f, "/green", "rate", &rate, err) < 0 ||
      proto_h5in_attr_f8(f, "/green", "dx", &fdx, err) < 0 ||
      proto_h5in_attr_f8(f, "/green", "dy", &fdy, err) < 0 ||
      proto_h5in_attr_str(f, "/green", "sampling", sampling, sizeof sampling, err) < 0 ||
      proto_h5in_attr_str(f, "/green", "model", model, sizeof model, err) < 0)
    goto done;
  if (rate < 0) {
    proto_fail(err, "%s:/green: attribute rate is %g Hz (0: static, > 0: dynamic)", path,
               rate);
    goto done;
  }
  /* the element size the file was computed for must be the block's */
  if (fdx != 0 && fdy != 0 &&
      (fabs(fdx / m->dx - 1) > BLK_SIZE_TOL || fabs(fdy / m->dy - 1) > BLK_SIZE_TOL)) {
    proto_fail(err, "%s: elements of %g x %g m, the block's are %g x %g m (grid.dx, "
               "grid.dy)", path, fdx, fdy, m->dx, m->dy);
    goto done;
  }
  /* the offset grid must be the block's: known before anything is read */
  int64_t ds[2] = {m->noy, m->nox}, dg[3] = {-1, m->noy, m->nox};
  const int64_t no = (int64_t)m->noy * m->nox;
  if (proto_h5in_read_f8(f, "/green/static", 2, ds, no, &st, err) < 0 ||
      (rate > 0 && proto_h5in_read_f8(f, "/green/g", 3, dg, BLK_MAX_GREEN_SAMPLES * no,
                                      &g, err) < 0)) {
    proto_wrap(err, "green: offset grid [2ny-1, 2nx-1] = [%d, %d] of a %d x %d block, at "
               "most %d samples", m->noy, m->nox, m->nx, m->ny, BLK_MAX_GREEN_SAMPLES);
    goto done;
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
  proto_h5in_close(f);
  return rc;
}

int blk_springs_load(blk_model *m, const char *path, proto_err *err) {
  proto_h5in *f = proto_h5in_open(path, err);
  if (!f) return -1;
  int rc = -1;
  double *d = NULL, *F = NULL, *k = NULL, *z = NULL;
  /* M tables of K knots; K from /springs/d, then F and k must agree */
  int64_t dd[2] = {m->M, -1}, dF[2], dk[2], dz[2] = {m->ny, m->nx};
  const int64_t max = (int64_t)m->M * BLK_MAX_SPRING_KNOTS;
  if (proto_h5in_read_f8(f, "/springs/d", 2, dd, max, &d, err) < 0) goto shape;
  dF[0] = dk[0] = m->M;
  dF[1] = dk[1] = dd[1];
  if (proto_h5in_read_f8(f, "/springs/F", 2, dF, max, &F, err) < 0 ||
      proto_h5in_read_f8(f, "/springs/k", 2, dk, max, &k, err) < 0)
    goto shape;
  if (blk_springs_table(m, (int)dd[1], d, F, k, err)) {
    proto_wrap(err, "%s", path);
    goto done;
  }
  if (proto_h5in_exists(f, "/springs/z_road")) {
    if (proto_h5in_read_f8(f, "/springs/z_road", 2, dz, m->M, &z, err) < 0) {
      proto_wrap(err, "springs: z_road must be [ny, nx] = [%d, %d]", m->ny, m->nx);
      goto done;
    }
    if (blk_road_set(m, z, err)) {
      proto_wrap(err, "%s", path);
      goto done;
    }
  }
  double rf = 0;
  if (proto_h5in_attr_f8(f, "/springs", "release_force", &rf, err) < 0) goto done;
  if (rf > 0) m->release_force = rf;
  rc = 0;
  goto done;
shape:
  proto_wrap(err, "springs: /springs/d, F, k must all be [M, K] with M = %d elements and "
             "2 <= K <= %d knots", m->M, BLK_MAX_SPRING_KNOTS);
done:
  free(d);
  free(F);
  free(k);
  free(z);
  proto_h5in_close(f);
  return rc;
}
