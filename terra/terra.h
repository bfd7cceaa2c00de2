/* terra.h — the one public header of cosim's terramechanics part (prefix ter_).
 *
 * The classical rigid-wheel prediction that the DEM–FEM tyre is compared
 * with: Bekker pressure–sinkage (Bekker 1969), Wong–Reece normal stress on the
 * rim (Wong & Reece 1967), Janosi–Hanamoto shear (Janosi & Hanamoto 1961), the
 * force balance and the sinkage at a given load and slip; the fits that
 * measure the soil parameters from virtual plate-sinkage and shear-box tests
 * (docs/terramechanics.md §2–3), and those tests themselves, run with dem_server's library on the scenes'
 * grains (ter_dem.c).
 *
 * Units SI; angles in radians inside (degrees only in JSON, key phi_deg).
 * Every fallible call takes a proto_err and returns -1 on error.
 */
#ifndef COSIM_TERRA_H
#define COSIM_TERRA_H

#include <stdint.h>
#include <stdio.h>

#include "proto/proto.h"

/* ------------------------------------------------------------ soil, wheel */

/* Soil parameters of the model (Bekker 1969; Wong & Reece 1967). */
typedef struct ter_soil {
  double n;      /* sinkage exponent */
  double k_c;    /* cohesive modulus, N/m^(n+1) */
  double k_phi;  /* frictional modulus, N/m^(n+2) */
  double c;      /* cohesion, Pa */
  double phi;    /* angle of internal friction, rad */
  double K;      /* shear deformation modulus, m */
  double c1, c2; /* angle of maximum stress theta_m = (c1 + c2 s) theta_1 */
} ter_soil;

/* Rigid wheel: radius r, width b (Bekker's b, the smaller contact side). */
typedef struct ter_wheel {
  double r, b;
} ter_wheel;

/* Checks ranges; errors name path.<key>. */
int ter_soil_check(const ter_soil *p, const char *path, proto_err *err);
/* JSON object {"n", "k_c", "k_phi", "c", "phi_deg", "K", "c1", "c2"} (c1,
 * c2 optional: 0.43, 0.32); unknown keys are errors. The one reader of the
 * soil object; ter_soil_write is its writer. */
int ter_soil_read(const cJSON *obj, const char *path, ter_soil *p, proto_err *err);
/* Adds the soil object's keys to obj. Returns 0, or -1 out of memory. */
int ter_soil_write(cJSON *obj, const ter_soil *p);
void ter_soil_defaults(ter_soil *p); /* c1 = 0.43, c2 = 0.32, the rest 0 */

/* ------------------------------------------------------------ wheel model */

typedef struct ter_forces {
  double z, s;              /* sinkage (m), slip */
  double theta1, thetam;    /* entry angle, angle of maximum stress (rad) */
  double W;                 /* vertical load carried, N */
  double Ft;                /* gross traction: horizontal component of the shear, N */
  double R;                 /* running (compaction) resistance, N */
  double DP;                /* drawbar pull Ft - R, N */
  double T;                 /* driving torque, N m */
  double eff;               /* tractive efficiency DP r (1 - s) / T (0 if T = 0) */
} ter_forces;

/* Forces at sinkage z and slip s (Wong & Reece 1967, the force balance; theta_2 = 0). n_mid = 0: 16-point
 * Gauss–Legendre on [0, theta_m] and [theta_m, theta_1] (sigma has a kink
 * at theta_m); n_mid > 0: the midpoint rule with n_mid points on
 * [0, theta_1] (a brute-force cross-check). Needs 0 < z < r, 0 <= s < 1. */
void ter_wheel_forces(const ter_wheel *w, const ter_soil *p, double z, double s, int n_mid,
                      ter_forces *out);
/* Sinkage at which the wheel carries W at slip s (bisection on (0, 0.9 r]:
 * W(z) rises monotonically; to 1e-10 r), and the forces there. Fails with
 * "no equilibrium (immobilised)" if even 0.9 r does not carry W. */
int ter_solve(const ter_wheel *w, const ter_soil *p, double W, double s, ter_forces *out,
              proto_err *err);
/* Closed-form small-sinkage estimate (Bekker 1969):
 * z0 = [3 W / ((3 - n) (k_c + b k_phi) sqrt(2 r))]^(2/(2n+1)). */
double ter_bekker_z0(const ter_wheel *w, const ter_soil *p, double W);
/* Compaction resistance from plate work: b (k_c/b + k_phi) z^(n+1)/(n+1). */
double ter_compaction_resistance(const ter_wheel *w, const ter_soil *p, double z);

/* n-point Gauss–Legendre nodes and weights on [-1, 1] (n <= 64). */
void ter_gauss_legendre(int n, double *x, double *wt);

/* ----------------------------------------------------------------- series */

/* A table of numbers with named columns and "key: value" metadata: the
 * records of the virtual tests (CSV, ter_io.c is its one reader and writer):
 *   # key: value        (metadata lines)
 *   col0,col1,...       (header)
 *   1.0,2.0,...         (rows) */
#define TER_MAX_COLS 32
#define TER_MAX_META 32
#define TER_NAME 48
typedef struct ter_series {
  int ncol;
  char col[TER_MAX_COLS][TER_NAME];
  int n, cap;
  double *row;  /* [n * ncol] */
  int nmeta;
  char meta_key[TER_MAX_META][TER_NAME];
  char meta_val[TER_MAX_META][128];
} ter_series;

int ter_series_init(ter_series *t, int ncol, const char *const *cols, proto_err *err);
void ter_series_free(ter_series *t);
int ter_series_add(ter_series *t, const double *row, proto_err *err);
int ter_series_meta(ter_series *t, const char *key, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
/* Column index by name, or -1. Metadata value by key (NULL if absent). */
int ter_series_col(const ter_series *t, const char *name);
const char *ter_series_get_meta(const ter_series *t, const char *key);
int ter_series_meta_num(const ter_series *t, const char *key, double *out, proto_err *err);
int ter_series_write(const ter_series *t, const char *path, proto_err *err);
int ter_series_read(ter_series *t, const char *path, proto_err *err);

/* ------------------------------------------------------------------ fits */

/* Least-squares line y = a + b x; se_a, se_b standard errors (may be NULL). */
int ter_fit_line(int n, const double *x, const double *y, double *a, double *b, double *se_a,
                 double *se_b, proto_err *err);

/* Bekker fit over several plates (Bekker 1969; docs/terramechanics.md §2): per plate i, points
 * (z, p) with z_lo <= z <= z_hi and p > 0; ln p = ln k_i + n ln z with one
 * shared n (linear least squares), and each plate's own n for the check;
 * then k_i = k_c / b_i + k_phi (regression on 1/b; exact for 2 plates). */
typedef struct ter_plate_fit {
  int n_plates;
  double b[8];        /* plate widths, m */
  double k_eq[8];     /* per plate, shared n, N/m^(n+2) */
  double n_own[8];    /* per plate, own n */
  double k_own[8];    /* per plate, with its own n */
  int points[8];
  double n;           /* shared exponent */
  double k_c, k_phi;  /* Bekker moduli */
  double rms_log;     /* rms residual of ln p (shared n) */
} ter_plate_fit;
int ter_fit_plates(int n_plates, const double *b, const ter_series *const *plates,
                   const char *zcol, const char *pcol, double z_lo, double z_hi,
                   ter_plate_fit *out, proto_err *err);

/* Janosi–Hanamoto fit tau = tau_f (1 - exp(-j/K)) over 0 < j <= j_hi by
 * least squares (tau_f in closed form for each K, golden section on ln K).
 * rms: residual rms, Pa. */
int ter_fit_janosi(int n, const double *j, const double *tau, double j_hi, double *tau_f,
                   double *K, double *rms, proto_err *err);

/* ------------------------------------------------------------- DEM tests */

/* Where the scene's soil comes from: its DEM section (materials, gravity,
 * dt...; particles and walls are replaced by the test's own), the grain,
 * container-wall and plate (tyre surface) materials. */
typedef struct ter_dem_soil {
  const cJSON *section; /* processes.<dem> of the scene */
  char path[128];       /* its key path, for errors */
  int grain_material, wall_material, plate_material;
  int threads;          /* OpenMP threads (0 = dem's default) */
} ter_dem_soil;
/* Finds the DEM section in a scene (the process whose exec is dem_server)
 * and its materials. */
int ter_dem_soil_from_scene(const cJSON *scene, ter_dem_soil *soil, proto_err *err);

/* Virtual bevameter (Bekker 1969; docs/terramechanics.md §2): the scene's bed (the paper's three layers,
 * grains per m^2 x depth_factor) settled in a square box of side container,
 * a rigid square plate of side width pushed at constant speed from just above
 * the highest grain under it to sinkage z_max, the sinkage counted from the
 * surface (the mean top of the grains under its footprint).
 * Rows every dz of sinkage (means over the bin): z, p (base force / area),
 * p_skirt (vertical force on the plate's sides / area), inertial number I,
 * max overlap ratio, kinetic energy per grain. */
/* Preparation of the packing (a sand bin compacted before the test): while
 * the grains settle (and, in the shear box, while the platen consolidates
 * them), every contact law's sliding friction is `friction` and its rolling
 * friction `rolling`; the scene's laws are restored before the test proper
 * (and the shear box's platen then holds sigma_n again before shearing).
 * Low friction while settling packs the grains denser. on = 0: the scene's
 * laws throughout (the default). rolling > 0 needs a scene with rolling
 * friction on some pair (the DEM keeps rolling state only then). */
typedef struct ter_prep {
  int on;
  double friction, rolling;
} ter_prep;

typedef struct ter_plate_spec {
  double width, container, depth_factor, speed, z_max, dz;
  uint64_t seed;
  double settle_ke;         /* J per grain */
  int64_t settle_max_steps;
  ter_prep prep;
  double p_max;             /* Pa: stop once a bin's mean pressure exceeds it (0 = at z_max only) */
} ter_plate_spec;
void ter_plate_defaults(ter_plate_spec *p);
int ter_plate_test(const ter_dem_soil *soil, const ter_plate_spec *spec, FILE *log,
                   ter_series *out, proto_err *err);

/* Virtual direct shear (ASTM D3080; Wang & Gutierrez 2010): grains of diameters uniform in
 * [d_min, d_max] settled in a split box (length x width, lower half of
 * height/2, the upper ring above), a rough top platen servo-controlled to
 * sigma_n (proportional law on its velocity), then the upper half moved at
 * speed to j_max. Rows every dj: j, tau (force on the lower half / current
 * overlap area), tau_upper (the same from the upper half and platen),
 * sigma (platen force / area), dilation (platen rise since shear start),
 * inertial number I = speed / (10 sqrt(sigma/rho)). */
typedef struct ter_shear_spec {
  double length, width, height, d_min, d_max;
  double sigma_n, speed, j_max, dj;
  double servo_gain;   /* platen speed per relative stress error, m/s */
  double servo_vmax;   /* m/s */
  uint64_t seed;
  double settle_ke;
  int64_t settle_max_steps;
  ter_prep prep;
} ter_shear_spec;
void ter_shear_defaults(ter_shear_spec *p);
int ter_shear_test(const ter_dem_soil *soil, const ter_shear_spec *spec, FILE *log,
                   ter_series *out, proto_err *err);

/* A prepared bed for a scene: the scene's own DEM section (its generated bed,
 * materials, walls), settled with the preparation's laws for up to the
 * section's settle_max_steps (or settle_max_steps here if > 0) to its
 * settle_ke_per_grain, the scene's laws restored, settled again (same
 * limits), then saved with dem_bed_save to `out` (load it with particles
 * {"file": ...}). Reports the bed's solid fraction in `slabs` equal
 * horizontal slabs from the floor to the mean top (grains counted by the
 * part of their volume inside a slab; x-y: the footprint inset by `inset`
 * m from the walls) in solid_fraction[] (at most 16), and the mean top. */
typedef struct ter_bed_spec {
  ter_prep prep;
  int64_t settle_max_steps; /* 0: the section's */
  uint64_t seed;            /* 0: the section's */
  double inset;             /* m */
  int slabs;
} ter_bed_spec;
typedef struct ter_bed_result {
  int grains;
  double top, solid_fraction[16], bulk_density[16];
  double max_overlap;
} ter_bed_result;
int ter_prepare_bed(const ter_dem_soil *soil, const ter_bed_spec *spec, const char *out, FILE *log,
                    ter_bed_result *res, proto_err *err);

/* Solid fraction of the grains in the box [lo, hi]: the volume of each
 * grain whose centre lies in the box's x-y rectangle, cut to lo[2] <= z <=
 * hi[2] (exact sphere segment), over the box's volume. */
double ter_solid_fraction(int n, const double *x, const double *radius, const double lo[3],
                          const double hi[3]);

#endif
