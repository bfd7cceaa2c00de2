/* io.c — green.h5 and springs.h5 as specified in green/FORMATS.md. */
#include <math.h>
#include <stdlib.h>

#include "green/green.h"
#include "green/h5util.h"

#define G_GREEN "/green"
#define G_SPRINGS "/springs"

int grn_write_green(const char *path, const grn_grid *g, int Q, double rate,
                    const char *sampling, const char *model, const double *gk,
                    const double *stat, const double *stat_relaxed, double sum_check,
                    double h, const grn_material *mat, proto_err *err) {
  proto_h5 *f = proto_h5_create(path, err);
  if (!f) return -1;
  const int64_t wy = 2 * (int64_t)g->ny - 1, wx = 2 * (int64_t)g->nx - 1;
  const int64_t dims[3] = {Q, wy, wx}, d2[2] = {wy, wx};
  int rc = gk ? grn_h5_write(f, G_GREEN, "g", 3, dims, gk, err) : 0;
  if (!rc) rc = grn_h5_write(f, G_GREEN, "static", 2, d2, stat, err);
  if (!rc && stat_relaxed) {
    rc = grn_h5_write(f, G_GREEN, "static_relaxed", 2, d2, stat_relaxed, err);
    if (!rc) rc = proto_h5_attr_f8(f, G_GREEN, "sum_check", sum_check, err);
  }
  if (!rc) rc = proto_h5_attr_i8(f, G_GREEN, "nx", g->nx, err);
  if (!rc) rc = proto_h5_attr_i8(f, G_GREEN, "ny", g->ny, err);
  if (!rc) rc = proto_h5_attr_f8(f, G_GREEN, "dx", g->dx, err);
  if (!rc) rc = proto_h5_attr_f8(f, G_GREEN, "dy", g->dy, err);
  if (!rc) rc = proto_h5_attr_f8(f, G_GREEN, "rate", gk ? rate : 0.0, err);
  if (!rc) rc = proto_h5_attr_i8(f, G_GREEN, "Q", gk ? Q : 1, err);
  if (!rc) rc = proto_h5_attr_str(f, G_GREEN, "sampling", gk ? sampling : "static", err);
  if (!rc) rc = proto_h5_attr_str(f, G_GREEN, "model", model, err);
  if (!rc && mat) {
    if (h > 0) rc = proto_h5_attr_f8(f, G_GREEN, "thickness", h, err);
    if (!rc) rc = proto_h5_attr_f8(f, G_GREEN, "E", mat->E[0], err);
    if (!rc) rc = proto_h5_attr_f8(f, G_GREEN, "nu", mat->nu, err);
    if (!rc) rc = proto_h5_attr_f8(f, G_GREEN, "rho", mat->rho, err);
    if (!rc) rc = proto_h5_attr_f8(f, G_GREEN, "loss_factor", mat->eta[0], err);
    if (!rc && mat->n > 1) { /* the whole table, columns f, E, eta */
      double *tab = malloc(3 * mat->n * sizeof *tab);
      for (int i = 0; tab && i < mat->n; i++) {
        tab[3 * i] = mat->f[i];
        tab[3 * i + 1] = mat->E[i];
        tab[3 * i + 2] = mat->eta[i];
      }
      const int64_t dt[2] = {mat->n, 3};
      rc = tab ? grn_h5_write(f, G_GREEN, "material_table", 2, dt, tab, err)
               : proto_fail(err, "%s: out of memory", path);
      free(tab);
    }
  }
  return proto_h5_close(f, rc ? NULL : err) < 0 || rc ? -1 : 0;
}

int grn_write_springs(const char *path, const grn_springs *sp,
                      const char *film_rule, proto_err *err) {
  proto_h5 *f = proto_h5_create(path, err);
  if (!f) return -1;
  const int64_t M = (int64_t)sp->nx * sp->ny;
  const int64_t dz[2] = {sp->ny, sp->nx}, dk[2] = {M, sp->K}, dp[2] = {M, GRN_POLY_COEFFS},
                df[2] = {M, sp->Kf}, de[1] = {M};
  int rc = grn_h5_write(f, G_SPRINGS, "z_road", 2, dz, sp->z_road, err);
  if (!rc) rc = grn_h5_write(f, G_SPRINGS, "d", 2, dk, sp->d, err);
  if (!rc) rc = grn_h5_write(f, G_SPRINGS, "F", 2, dk, sp->F, err);
  if (!rc) rc = grn_h5_write(f, G_SPRINGS, "k", 2, dk, sp->k, err);
  if (!rc && sp->poly) rc = grn_h5_write(f, G_SPRINGS, "poly", 2, dp, sp->poly, err);
  if (!rc) rc = grn_h5_write(f, G_SPRINGS, "err_hermite", 1, de, sp->err_hermite, err);
  if (!rc && sp->poly) rc = grn_h5_write(f, G_SPRINGS, "err_poly", 1, de, sp->err_poly, err);
  if (!rc) rc = grn_h5_write(f, G_SPRINGS, "raw_d", 2, df, sp->raw_d, err);
  if (!rc) rc = grn_h5_write(f, G_SPRINGS, "raw_F", 2, df, sp->raw_F, err);
  if (!rc) rc = grn_h5_write(f, G_SPRINGS, "raw_k", 2, df, sp->raw_k, err);
  if (!rc) rc = proto_h5_attr_i8(f, G_SPRINGS, "nx", sp->nx, err);
  if (!rc) rc = proto_h5_attr_i8(f, G_SPRINGS, "ny", sp->ny, err);
  if (!rc) rc = proto_h5_attr_f8(f, G_SPRINGS, "dx", sp->dx, err);
  if (!rc) rc = proto_h5_attr_f8(f, G_SPRINGS, "dy", sp->dy, err);
  if (!rc) rc = proto_h5_attr_str(f, G_SPRINGS, "film_thickness_rule", film_rule, err);
  if (!rc) rc = proto_h5_attr_f8(f, G_SPRINGS, "release_force", sp->release_force, err);
  return proto_h5_close(f, rc ? NULL : err) < 0 || rc ? -1 : 0;
}
