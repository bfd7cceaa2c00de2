/* green_internal.h — shared between the green/ sources only. */
#ifndef COSIM_GREEN_INTERNAL_H
#define COSIM_GREEN_INTERNAL_H
#include <complex.h>
#include <fftw3.h>

#include "green/green.h"

/* Zero-padded periodic box of Px x Py elements, with alias shells mx, my
 * folded into each grid wavenumber and smoothing length c. */
typedef struct grn_box {
  int Px, Py, nqx, mx, my;
  double c;
} grn_box;

int grn_box_init(grn_box *b, const grn_grid *g, double h, int pad);
double grn_box_qx(const grn_box *b, const grn_grid *g, int i, int gx);
double grn_box_qy(const grn_box *b, const grn_grid *g, int j, int gy);
double grn_element_shape(const grn_grid *g, double qx, double qy);
int grn_box_to_kernel(const grn_box *b, const grn_grid *g, fftw_complex *spec,
                      double *work, double *C, int n_kernels, int spec_stride,
                      int out_stride);
double grn_split_compliance(double q, double c, double E_star);
double grn_layer_factor(double tau, double nu);
double grn_layer_compliance(double q, double h, double E, double nu);
double complex grn_layer_dynamic_c(double q, double omega, double h, double rho,
                                   double complex mu, double complex lam);
#endif
