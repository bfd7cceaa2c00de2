/* green.h — road surfaces, roughness springs and elastic-layer Green's functions
 * (seed 002 ch. 3). Prefix grn_. Files: green/FORMATS.md. Units SI.
 *
 * Offset arrays ("kernels") have shape [2ny-1][2nx-1]: entry
 * [dj + ny - 1][di + nx - 1] is the response at element offset (di, dj). */
#ifndef COSIM_GREEN_H
#define COSIM_GREEN_H

#include <stdint.h>

#include "proto/proto.h"

/* ------------------------------------------------------------ half-space */

/* Love (1929) closed form: surface normal displacement at (x, y) of an elastic
 * half-space (E, nu) under a unit total force spread uniformly over the
 * rectangle |x'| <= a, |y'| <= b (a, b half-widths). Returns m/N. */
double grn_love_compliance(double x, double y, double a, double b, double E,
                           double nu);
/* The same with the point kernel 1/r replaced by 1/sqrt(r² + c²) (a smoothed
 * Boussinesq load, c > 0): the long-range part split off in wavenumber space,
 * whose transform is 2 e^{-qc}/(E* q). Returns m/N. */
double grn_love_smoothed(double x, double y, double a, double b, double c,
                         double E, double nu);

/* Smallest n' >= n whose only prime factors are 2, 3, 5 (fast FFT sizes). */
int grn_fft_size(int n);

/* ------------------------------------------------------------ elements */

typedef struct grn_grid {
  int nx, ny;    /* elements */
  double dx, dy; /* element size, m */
} grn_grid;

/* Love coefficients for every offset: C[(dj+ny-1)(2nx-1) + di+nx-1], m/N. */
void grn_static_love(const grn_grid *g, double E, double nu, double *C);
/* The same for a half-space whose load repeats over nx·dx × ny·dy (periodic
 * road): C(Δ) = C(Δ − n) in the same layout. The uniform mode is set to zero
 * mean displacement per period (the image sum of 1/r diverges): periodic.c. */
int grn_static_love_periodic(const grn_grid *g, double E, double nu, double *C,
                             proto_err *err);

/* Static surface stiffness (Pa/m) of a layer of thickness h bonded to a rigid
 * base, frictionless free top, at wavenumber q (the bonded-layer stiffness of
 * ContactMechanics' PeriodicFFTElasticHalfSpace; checked in tests/green). q = 0 gives the P-wave modulus / h (inf at nu = 0.5). */
double grn_layer_stiffness(double q, double h, double E, double nu);

/* Static influence coefficients of the bonded layer (centre-point
 * displacement per unit force spread over one element), every offset, m/N.
 * Love part in closed form + smooth wavenumber remainder by FFT on a
 * zero-padded periodic box (pad = extra elements per side, 0 = automatic). */
int grn_static_layer(const grn_grid *g, double h, double E, double nu, int pad,
                     double *C, proto_err *err);

/* ------------------------------------------------------------ material */

#define GRN_TABLE_MAX 64
/* Viscoelastic layer material: Young's modulus E(f) and its loss factor
 * eta(f) tabulated at increasing frequencies f (Hz), interpolated linearly in
 * E and in log(eta) over log f, held constant outside the table. */
typedef struct grn_material {
  int n;
  double f[GRN_TABLE_MAX], E[GRN_TABLE_MAX], eta[GRN_TABLE_MAX];
  double nu, rho;
} grn_material;

/* Seed 002 appendix B tread layer (top layer; the 3 mm aluminium bottom layer
 * is taken as the rigid backing): rho 1300, nu 0.499, E 25 MPa at 0 Hz to
 * 50 MPa at high f, eta 0.005 at 10 Hz to 0.55 at 50 kHz. */
void grn_material_default(grn_material *m);
/* Checks ranges and order; errors name the entry ("f[3] = 10 after 20"). */
int grn_material_check(const grn_material *m, proto_err *err);
/* Reads a text table "f E eta" per line ('#' comments). nu, rho untouched. */
int grn_material_load(grn_material *m, const char *path, proto_err *err);
void grn_material_at(const grn_material *m, double f, double *E, double *eta);

/* Dynamic surface compliance u_z/p (m/Pa) of the layer at wavenumber q and
 * angular frequency omega > 0, complex Lamé constants mu, lambda (4x4
 * potential system of the wavenumber method, Larsson & Kropp 2002; quasi-static formula when |k_s| << q). */
int grn_layer_dynamic(double q, double omega, double h, double rho,
                      double mu_re, double mu_im,
                      double lambda_re, double lambda_im, double *H_re,
                      double *H_im);

/* ------------------------------------------------------------ dynamic */

typedef void (*grn_progress_fn)(void *user, double fraction, const char *what);

typedef struct grn_dyn_opts {
  int Q;              /* samples per Green's function */
  double rate;        /* Hz */
  int oversample;     /* fine time steps per sample (spectrum to oversample*rate/2) */
  int period_factor;  /* transform period = 2 * period_factor * Q / rate */
  int pad;            /* extra elements per side of the periodic box (0 auto) */
  grn_progress_fn progress;
  void *progress_user;
} grn_dyn_opts;

void grn_dyn_opts_default(grn_dyn_opts *o); /* 256 samples, 51.2 kHz, 4, 4 */

/* Impulse responses of the viscoelastic layer for every offset:
 * g_zoh, g_point [Q][2ny-1][2nx-1] (m/(N s)), static [2ny-1][2nx-1] (m/N, the
 * layer with the f = 0 modulus). Either g array may be NULL. */
int grn_dynamic(const grn_grid *g, const grn_material *mat, double h,
                const grn_dyn_opts *o, double *g_zoh, double *g_point,
                double *stat, proto_err *err);

/* Causal response from a one-sided spectrum ("two times the real part"):
 * spec_re/spec_im at f_k = k*df, k = 0..nf-1, with 2*(nf-1)*df*dt equal to an
 * integer (the oversampling). Writes Q samples at rate 1/dt: zoh[k] =
 * (step(t_{k+1}) - step(t_k))/dt, point[k] = g(k dt). Either may be NULL. */
int grn_causal_response(int nf, double df, const double *spec_re,
                        const double *spec_im, double dt, int Q, double *zoh,
                        double *point, proto_err *err);

/* ------------------------------------------------------------ surfaces */

typedef struct grn_surface {
  int Nx, Ny;    /* points */
  double dx, dy; /* pitch, m */
  double *z;     /* heights [Ny][Nx], m (owned) */
} grn_surface;

typedef struct grn_surface_params {
  int Nx, Ny;
  double dx, dy;
  double hurst;        /* 0 < H < 1: PSD ∝ q^{-2(1+H)} */
  double rms;          /* m */
  double lambda_short; /* m, short-wavelength cut-off (PSD 0 above) */
  double lambda_long;  /* m, roll-off wavelength (PSD flat below its q) */
  uint64_t seed;
} grn_surface_params;

int grn_surface_generate(const grn_surface_params *p, grn_surface *s,
                         proto_err *err);
void grn_surface_free(grn_surface *s);
/* Plain-text grid: one row per line (y), values along x, '#' comments; the
 * pitch from "# dx = ..." / "# dy = ..." lines or the arguments (> 0). */
int grn_surface_read_text(const char *path, double dx, double dy,
                          grn_surface *s, proto_err *err);
/* Largest road read or made (points). */
#define GRN_MAX_POINTS ((int64_t)1 << 28)
/* HDF5 /road/heights [Ny][Nx] with attributes dx, dy (FORMATS.md). */
int grn_surface_read_h5(const char *path, grn_surface *s, proto_err *err);
int grn_surface_write_h5(const char *path, const grn_surface *s,
                         const grn_surface_params *p /* may be NULL */,
                         proto_err *err);
/* Radially averaged PSD in nbins log bins over [q_lo, q_hi]; returns the
 * least-squares slope of log C vs log q. */
double grn_surface_psd_slope(const grn_surface *s, double q_lo, double q_hi,
                             proto_err *err);
double grn_surface_rms(const grn_surface *s);
/* Element of the block grid (nx x ny over the surface) -> highest point. */
int grn_surface_downsample_max(const grn_surface *s, int nx, int ny,
                               double *z_road, proto_err *err);

/* ------------------------------------------------------------ flat punch */

/* Stiffness of a rigid frictionless flat punch of radius a on an elastic
 * layer of thickness h bonded to a rigid base, relative to the half-space
 * value 2 E* a: phi(a/h) >= 1, from a Nyström solve of the Fredholm equation
 * built on the layer kernel of grn_layer_stiffness (tabulated once). */
typedef struct grn_punch_table {
  int n;
  double nu;
  double *lam; /* a/h, increasing (log-spaced) */
  double *phi; /* K / (2 E* a) */
  double *loglam, *logphi1, *slope; /* monotone cubic of log(φ−1) vs log λ */
} grn_punch_table;

int grn_punch_table_build(grn_punch_table *t, double nu, double lam_min,
                          double lam_max, int n, proto_err *err);
void grn_punch_table_free(grn_punch_table *t);
/* phi at a/h: monotone cubic in log(φ − 1) over log(a/h); beyond the table continued with the
 * thin-film law ∝ (a/h)³ matched at the end, and -> 1 below it. */
double grn_punch_phi(const grn_punch_table *t, double lam);
/* Single solve (used to build the table and by tests). */
int grn_punch_solve(double lam, double nu, int npts, double *phi,
                    proto_err *err);

/* ------------------------------------------------------------ springs */

typedef struct grn_spring_opts {
  int K;              /* knots per element */
  double E, nu;       /* rubber modulus for the springs */
  double d_max_frac;  /* knots span [0, d_max_frac * (z_max - z_min)] */
  double h_floor_frac;/* h(d) >= h_floor_frac * (z_max - z_min) */
  double film_h;      /* > 0: constant film thickness (m) instead of the
                         thesis rule h(d) = z_max - z_min - d */
  int refine;         /* raw-curve depths per knot interval */
  double release_force; /* N, adhesion release (attribute only) */
  int poly;           /* also fit the 10th-order polynomial */
} grn_spring_opts;

void grn_spring_opts_default(grn_spring_opts *o);

/* Coefficients c_0..c_10 of the thesis' 10th-order spring polynomial
 * (seed 002 ch. 3.2). */
enum { GRN_POLY_COEFFS = 11 };

typedef struct grn_springs {
  int nx, ny, K;
  double dx, dy;
  double *z_road;  /* [ny][nx] */
  double *d, *F, *k; /* [M][K] */
  double *poly;    /* [M][GRN_POLY_COEFFS] or NULL */
  double *err_hermite, *err_poly; /* [M]: max |F_fit - F_raw| / F_raw(d_max) */
  int Kf;            /* raw-curve depths per element */
  double *raw_d, *raw_F, *raw_k; /* [M][Kf] */
  double release_force;
} grn_springs;

/* Raw spring curve of one element's fine heights z[j*stride + i] (cols x
 * rows points of pitch ds_x, ds_y): at nd depths d (d[0] = 0, up to
 * d_max_frac of the relief) dF/dd = Σ_patches 2E* a φ(a/h(d)) and F its
 * trapezoid integral. */
int grn_spring_raw(const double *z, int cols, int rows, int stride,
                   double ds_x, double ds_y, const grn_punch_table *pt,
                   const grn_spring_opts *o, int nd, double *d, double *F,
                   double *kraw, proto_err *err);
/* pchip.c — Fritsch–Carlson slopes of a monotone cubic Hermite interpolant. */
void grn_pchip_slopes(int n, const double *x, const double *y, double *m);
/* Fritsch–Carlson limiter alone: clamps given slopes m (e.g. known
 * derivatives) so that the Hermite interpolant is monotone. */
void grn_pchip_limit(int n, const double *x, const double *y, double *m);
/* The interpolant at t (linear beyond either end knot); dydt may be NULL. */
double grn_pchip_eval(int n, const double *x, const double *y, const double *m,
                      double t, double *dydt);
/* The knot interval x[lo] <= t < x[lo+1] of x[0] <= t < x[n-1] (x increasing). */
int grn_pchip_interval(int n, const double *x, double t);
/* The cubic piece lo at t and, if dydt, its derivative. */
double grn_pchip_piece(const double *x, const double *y, const double *m, int lo,
                       double t, double *dydt);
/* Least-squares F = Σ c_i d^i (i = 0..10, c_0 = 0) with dF/dd >= 0 on [0,
 * d_max] enforced by active constraints at check points. */
int grn_polyfit_monotone(int n, const double *d, const double *F, double *c,
                         proto_err *err);
double grn_poly_eval(const double *c, double d, double *dFdd);

/* spring_law.c — the roughness-spring law (seed 002 ch. 3.2 and 5.1), used
 * by contact_block too. One spring's knot table: K knots d (increasing, d[0]
 * = 0), forces F, slopes k. */
typedef struct grn_spring_table {
  int K;
  const double *d, *F, *k;
} grn_spring_table;
/* Compression branch: scale · F(d) and scale · dF/dd (>= 0) at d > 0 (cubic
 * Hermite, linear beyond the last knot); 0 and 0 for d <= 0. */
void grn_spring_compressed(const grn_spring_table *t, double scale, double d, double *F,
                           double *k);
/* The signed law: the compression branch at d > 0; at d <= 0 the mirrored
 * tensile branch (F(d) = −F(−d), seed 002 fig. 13) if held (attached by
 * adhesion), else 0. */
void grn_spring_force(const grn_spring_table *t, double scale, double d, int held,
                      double *F, double *k);
/* Release force of the adhesion, N: seed 002 ch. 5.1 (fig. 39) sets 0.6 N as
 * the default release criterion (appendix C.4: the runs with it). */
#define GRN_RELEASE_FORCE_DEFAULT 0.6
/* Adhesion: a held spring at force F lets go once its tension exceeds the
 * release force (seed 002 ch. 5.1). */
static inline int grn_spring_released(double F, double release_force) {
  return -F > release_force;
}

/* Spring force of element e at compression d (FORMATS.md): the Hermite
 * table for d >= 0 (linear beyond the last knot); for d < 0 the mirrored
 * branch while *attached, released (F = 0, *attached = 0) once −F exceeds
 * release_force. d >= 0 sets *attached = 1. k gets dF/dd (may be NULL). */
double grn_spring_eval(const grn_springs *sp, int e, double d, int *attached,
                       double *k);

int grn_springs_build(const grn_surface *s, int nx, int ny,
                      const grn_spring_opts *o, grn_springs *out,
                      grn_progress_fn progress, void *user, proto_err *err);
void grn_springs_free(grn_springs *sp);

/* ------------------------------------------------------------ files */

/* green.h5 (FORMATS.md), the one writer: gk [Q][2ny−1][2nx−1] (NULL: static
 * only), stat the static compliance, stat_relaxed (dynamic files, may be
 * NULL) the independent f = 0 layer and sum_check its deviation. */
int grn_write_green(const char *path, const grn_grid *g, int Q, double rate,
                    const char *sampling, const char *model, const double *gk,
                    const double *stat, const double *stat_relaxed, double sum_check,
                    double h, const grn_material *mat, proto_err *err);
int grn_write_springs(const char *path, const grn_springs *sp,
                      const char *film_rule, proto_err *err);

#endif
