/* io.c — green.h5 and springs.h5 as specified in green/FORMATS.md. */
#include <hdf5.h>
#include <math.h>
#include <stdlib.h>

#include "green/green.h"
#include "green/h5util.h"

int grn_write_green(const char *path, const grn_grid *g, int Q, double rate,
                    const char *sampling, const char *model, const double *gk,
                    const double *stat, const double *stat_relaxed, double sum_check,
                    double h, const grn_material *mat, proto_err *err) {
  hid_t f = H5Fcreate(path, H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  if (f < 0)
    return proto_fail(err, "%s: cannot create", path);
  hid_t grp = H5Gcreate2(f, "/green", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  const hsize_t wy = 2 * g->ny - 1, wx = 2 * g->nx - 1;
  int rc = 0;
  if (gk) {
    hsize_t dims[3] = {(hsize_t)Q, wy, wx};
    rc |= grn_h5_write(grp, "g", 3, dims, gk, err);
  }
  hsize_t d2[2] = {wy, wx};
  if (!rc) rc |= grn_h5_write(grp, "static", 2, d2, stat, err);
  if (!rc && stat_relaxed) {
    rc |= grn_h5_write(grp, "static_relaxed", 2, d2, stat_relaxed, err);
    grn_h5_attr_d(grp, "sum_check", sum_check);
  }
  grn_h5_attr_i(grp, "nx", g->nx);
  grn_h5_attr_i(grp, "ny", g->ny);
  grn_h5_attr_d(grp, "dx", g->dx);
  grn_h5_attr_d(grp, "dy", g->dy);
  grn_h5_attr_d(grp, "rate", gk ? rate : 0.0);
  grn_h5_attr_i(grp, "Q", gk ? Q : 1);
  grn_h5_attr_s(grp, "sampling", gk ? sampling : "static");
  grn_h5_attr_s(grp, "model", model);
  if (mat) {
    if (h > 0) grn_h5_attr_d(grp, "thickness", h);
    grn_h5_attr_d(grp, "E", mat->E[0]);
    grn_h5_attr_d(grp, "nu", mat->nu);
    grn_h5_attr_d(grp, "rho", mat->rho);
    grn_h5_attr_d(grp, "loss_factor", mat->eta[0]);
    if (mat->n > 1) { /* the whole table, columns f, E, eta */
      double *tab = malloc(3 * mat->n * sizeof *tab);
      for (int i = 0; tab && i < mat->n; i++) {
        tab[3 * i] = mat->f[i];
        tab[3 * i + 1] = mat->E[i];
        tab[3 * i + 2] = mat->eta[i];
      }
      hsize_t dt[2] = {(hsize_t)mat->n, 3};
      if (tab && !rc) rc |= grn_h5_write(grp, "material_table", 2, dt, tab, err);
      free(tab);
    }
  }
  H5Gclose(grp);
  if (H5Fclose(f) < 0 && !rc)
    rc = proto_fail(err, "%s: write failed", path);
  return rc ? -1 : 0;
}

int grn_write_springs(const char *path, const grn_springs *sp,
                      const char *film_rule, proto_err *err) {
  hid_t f = H5Fcreate(path, H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  if (f < 0)
    return proto_fail(err, "%s: cannot create", path);
  hid_t grp = H5Gcreate2(f, "/springs", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  const hsize_t M = (hsize_t)sp->nx * sp->ny;
  hsize_t dz[2] = {(hsize_t)sp->ny, (hsize_t)sp->nx}, dk[2] = {M, (hsize_t)sp->K},
          dp[2] = {M, 11}, df[2] = {M, (hsize_t)sp->Kf}, de[1] = {M};
  int rc = grn_h5_write(grp, "z_road", 2, dz, sp->z_road, err);
  if (!rc) rc = grn_h5_write(grp, "d", 2, dk, sp->d, err);
  if (!rc) rc = grn_h5_write(grp, "F", 2, dk, sp->F, err);
  if (!rc) rc = grn_h5_write(grp, "k", 2, dk, sp->k, err);
  if (!rc && sp->poly) rc = grn_h5_write(grp, "poly", 2, dp, sp->poly, err);
  if (!rc) rc = grn_h5_write(grp, "err_hermite", 1, de, sp->err_hermite, err);
  if (!rc && sp->poly) rc = grn_h5_write(grp, "err_poly", 1, de, sp->err_poly, err);
  if (!rc) rc = grn_h5_write(grp, "raw_d", 2, df, sp->raw_d, err);
  if (!rc) rc = grn_h5_write(grp, "raw_F", 2, df, sp->raw_F, err);
  if (!rc) rc = grn_h5_write(grp, "raw_k", 2, df, sp->raw_k, err);
  grn_h5_attr_i(grp, "nx", sp->nx);
  grn_h5_attr_i(grp, "ny", sp->ny);
  grn_h5_attr_d(grp, "dx", sp->dx);
  grn_h5_attr_d(grp, "dy", sp->dy);
  grn_h5_attr_s(grp, "film_thickness_rule", film_rule);
  grn_h5_attr_d(grp, "release_force", sp->release_force);
  H5Gclose(grp);
  if (H5Fclose(f) < 0 && !rc)
    rc = proto_fail(err, "%s: write failed", path);
  return rc;
}
