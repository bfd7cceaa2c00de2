/* terra.h — the one public header of cosim's terramechanics part (prefix ter_).
 *
 * The classical rigid-wheel prediction that the DEM–FEM tyre is compared
 * with (../shared notes "terramechanics", §2–§5): Bekker pressure–sinkage,
 * Wong–Reece normal stress on the rim, Janosi–Hanamoto shear, the force
 * balance and the sinkage at a given load and slip; the fits that measure
 * the soil parameters from virtual plate-sinkage and shear-box tests (§6),
 * and those tests themselves, run with dem_server's library on the scenes'
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

/* Soil parameters of the model (notes §2, §3). */
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

/* Forces at sinkage z and slip s (notes §4; theta_2 = 0). n_mid = 0: 16-point
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

#endif
