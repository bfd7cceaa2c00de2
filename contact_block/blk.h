/* blk.h — tread-block / road contact model (seed 002 ch. 3–5), prefix blk_.
 *
 * An elastic layer (Green's functions g per element offset) meets a rigid
 * road of nx × ny elements through one roughness spring per element. Each
 * time step solves, over the elements in contact (seed 002 eq. 4–8, with the
 * sign of d_el_old in eq. 8 corrected):
 *
 *   f_m(d) = d_road + z_road_m − z_free − d_el_m − d_m = 0
 *   d_el_m = Δt Σ_p g(0; m−p) F_p(d_p) + d_el_old_m          (eq. 4)
 *   d_el_old_m(n) = Δt Σ_{k≥1} Σ_p g(k; m−p) F_p(n−k)        (eq. 5)
 *   ∂f_i/∂d_j = −Δt g(0; i−j) k_j(d_j) − δ_ij                 (eq. 8)
 *
 * d is the spring compression (m), F the spring force (N, compression > 0).
 * The quasi-static mode replaces Δt g(0) by the time-summed g (static
 * compliance) and drops the history. With C = Δt g(0) symmetric positive
 * definite the step is the minimum of the convex dual (contact_block/README.md)
 *
 *   J(F) = ½ FᵀCF − bᵀF + Σ Ψ_m(F_m),  Ψ' = inverse spring law, F ≥ 0,
 *
 * solved densely (Cholesky, small grids) or matrix-free (C·x by FFT,
 * Polonsky–Keer constrained conjugate gradients, large grids).
 *
 * Model (blk_model: the scene, fixed during a run) and state (blk_state:
 * what changes each step) are separate; blk_step() allocates nothing.
 * Files read: green/FORMATS.md. Units SI. */
#ifndef COSIM_BLK_H
#define COSIM_BLK_H

#include <stddef.h>
#include <stdint.h>

#include "proto/proto.h"

typedef enum {
  BLK_NR_PLAIN = 0,     /* the thesis' Newton–Raphson: full steps (ch. 3.4), dense */
  BLK_NR_LINESEARCH = 1, /* same direction + Armijo backtracking on ½|f|², dense */
  /* robust, dense: projected Newton on the convex dual J with a Cholesky
   * factor of C_AA + diag(1/k_A) per iteration, Armijo on J */
  BLK_NR_DUAL = 2,
  /* matrix-free: Newton on J, each step a bound-constrained quadratic solved
   * by Polonsky–Keer constrained conjugate gradients (Jacobi-preconditioned),
   * products C·x by FFT (zero-padded, or circular for a periodic grid) */
  BLK_CG = 3,
  /* per step, by a cost model: with springs and P elements in contact at the
   * previous step, BLK_NR_DUAL (∝ P³) while P³ ≤ BLK_AUTO_KAPPA · M log2 M
   * (BLK_CG ∝ M log M), else BLK_CG; rigid contact: BLK_CG (measured,
   * bench/results/block.md "Dense or matrix-free") */
  BLK_AUTO = 4
} blk_method;

/* The dense solvers keep an M × M (auto: a cap × cap) Newton matrix. */
enum { BLK_DENSE_MAX = 4096, BLK_AUTO_DENSE_CAP = 800 };
#define BLK_AUTO_KAPPA 1e3

typedef enum {
  BLK_HIST_FFT = 0,       /* per spatial frequency, partitioned in time (full g) */
  BLK_HIST_DIRECT = 1,    /* the plain double sum (reference) */
  BLK_HIST_SEPARABLE = 2, /* g = g_time ⊗ g_space: time sums per element, one FFT */
  BLK_HIST_AUTO = 3       /* fft, or separable where fft's memory would pass 1 GiB */
} blk_history_kind;

typedef struct blk_solver_opts {
  blk_method method;
  int max_iter;         /* Newton iterations per step (thesis: 10) */
  double tol;           /* convergence: max_m |f_m| < tol, m */
  int quasi_static;     /* 1: compliance = time-summed g, no history */
  blk_history_kind history;
  double tail_tol;      /* drop g samples/offsets below tail_tol·max|g| */
  double max_force;     /* N per element: larger is a runaway and stops the run */
  int reuse_jacobian;   /* newton: keep the factorisation while the contact set is
                           unchanged and the residual drops 4× per step (chord) */
  int cg_max_iter;      /* constrained CG iterations per Newton step */
  int tangent;          /* 1: compute the tangent stiffness dF/dd each step */
} blk_solver_opts;

/* Parameters of the in-process synthetic dynamic Green's function (clearly
 * NOT a layer solution): g(o, t) = S(o)·h(t) with S the Love half-space
 * static compliance per offset o and h a unit-area time shape
 *   h(t) = β e^{−t/τ}/τ + (1−β) ω²/ω_d e^{−ζωt} sin(ω_d t),
 * a fast local (dashpot-like) part and one damped layer mode. Its time
 * integral is 1, so Δt Σ_k g(k) → S (the static limit). Stored separable. */
typedef struct blk_synth {
  double E, nu;        /* Pa, –: Love static compliance */
  double rate;         /* Hz */
  int Q;               /* samples */
  double f_mode;       /* Hz, layer mode */
  double zeta;         /* mode damping ratio */
  double beta;         /* weight of the fast part, 0..1 */
  double tau_fast;     /* s */
  int point_sampling;  /* 1: g_k = h(kΔt) (the thesis); 0: ZOH step increments */
} blk_synth;

typedef struct blk_model {
  /* grid: element m = j·nx + i, centre ((i+½)dx, (j+½)dy) */
  int nx, ny, M;
  double dx, dy;
  int periodic;   /* 1: the road and layer repeat over nx·dx × ny·dy */
  /* road: outermost heights per element and the initial gap */
  double *z_road; /* [M] m */
  double z_free;  /* m */
  /* a road in world coordinates (road.kind "world", lug_block): the heights
   * under the block are taken anew at each lug's origin (blk_road_world) */
  int road_world;
  double road_rms;
  uint64_t road_seed;
  /* or the heights of a surface file (road.file, `cosim road` or a measured
   * map), tiled periodically over the world, its mean removed: point (i, j)
   * at world ((i + 1/2) map_dx, (j + 1/2) map_dy); NULL: the hashed field */
  double *road_map; /* [map_ny][map_nx] m (owned) */
  int map_nx, map_ny;
  double map_dx, map_dy;
  /* roughness springs: monotone piecewise-cubic Hermite tables, knots
   * d[t][0..K-1] (d[0] = 0), F, k = dF/dd; linear beyond the last. Element e
   * uses table spr_table[e] scaled in force by spr_scale[e]. rigid: no
   * springs (hard contact, d_rs = 0): only the dual solvers apply. */
  int rigid;
  int n_knots, n_tables;
  double *spr_d, *spr_F, *spr_k; /* [n_tables][n_knots] */
  double *spr_W;                 /* [n_tables][n_knots] ∫F up to each knot (derived) */
  int *spr_table;                /* [M] */
  double *spr_scale;             /* [M] */
  /* adhesion (ch. 5.1): mirrored springs, contact breaks past the release force */
  int adhesion;
  double release_force; /* N */
  /* Green's functions per offset (Δj, Δi) (green/FORMATS.md layout): full
   * g[k][o], or separable g(k; o) = g_time[k] · g_space[o] (then g = NULL) */
  int Q;          /* samples; 1 for a static-only model */
  double rate;    /* Hz; 0 for static only */
  int nox, noy;   /* 2nx−1, 2ny−1 */
  double *g;      /* [Q][noy][nox] m/(N s) */
  double *g_time; /* [Q] 1/s */
  double *g_space; /* [noy][nox] m/N */
  double *g_static; /* [noy][nox] m/N */
  char green_model[64];
  char sampling[16]; /* "zoh", "point", "static" */
  blk_solver_opts solver;
} blk_model;

typedef struct blk_work blk_work; /* solver and history workspace */

typedef struct blk_state {
  int64_t n;        /* steps taken */
  double *d_rs;     /* [M] spring compression (−: elongation), m */
  double *force;    /* [M] spring force, N */
  double *d_el;     /* [M] layer displacement, m */
  double *d_el_old; /* [M] history part for the NEXT step, m (eq. 5) */
  int *attached;    /* [M] 1: in contact / adhered */
  double *base;     /* [M] input: the base's offset towards the road per element,
                       m (a lug face's shape, lug_block); 0 (the default, and
                       after a reset) is the thesis' flat base */
  /* last step */
  double d_road, total_force, residual;
  double stiffness; /* tangent dF/dd_road of this step's solve, N/m (0: not computed) */
  int n_contact, iterations, converged, line_search_cuts, factorizations;
  int products;     /* FFT products C·x in this step (matrix-free and tangent) */
  blk_method method; /* the solver used (BLK_AUTO resolved) */
  blk_work *work;
} blk_state;

/* ---- model building (all allocate; blk_model_free releases) */
/* Grid and defaults (linear springs absent, no Green's functions yet). */
int blk_model_init(blk_model *m, int nx, int ny, double dx, double dy,
                   proto_err *err);
void blk_model_free(blk_model *m);

/* Green's functions. _set copies; checks shape (noy = 2ny−1, nox = 2nx−1),
 * finiteness, and that g_static matches Δt Σ g when g is given (1e-6 rel). */
int blk_green_set(blk_model *m, int Q, double rate, int noy, int nox,
                  const double *g, const double *g_static, const char *sampling,
                  const char *model_name, proto_err *err);
/* Love half-space static compliance (quasi-static only; Love 1929, Johnson
 * 1985 eq. 3.25);
 * on a periodic grid the periodic half-space (green/green.h). */
int blk_green_halfspace(blk_model *m, double E, double nu, proto_err *err);
int blk_green_synthetic(blk_model *m, const blk_synth *s, proto_err *err);
/* Reads green.h5 (green/FORMATS.md). */
int blk_green_load(blk_model *m, const char *path, proto_err *err);
/* Limits of what a file may hold (checked before reading). */
#define BLK_MAX_GREEN_SAMPLES 65536 /* samples Q per Green's function */
#define BLK_MAX_SPRING_KNOTS 65536  /* knots K per spring table */
/* Refines the sampling rate by an integer factor (appendix C.2): "point"
 * samples by linear interpolation of g (the thesis), "zoh" samples by
 * cubic interpolation of the step response and differencing. */
int blk_green_refine(blk_model *m, int factor, proto_err *err);
/* A separable g stored in full (g[k][o]), e.g. to modify it sample by sample. */
int blk_green_materialize(blk_model *m, proto_err *err);
/* g(k; o) whatever the storage (o = offset index in [noy][nox]). */
double blk_green_at(const blk_model *m, int k, size_t o);

/* Springs. Linear: F = k d (k [M], or one value if per_element == 0). */
int blk_springs_linear(blk_model *m, const double *k, int per_element,
                       proto_err *err);
/* Tables [M][K]: d increasing from 0, F monotone from 0, k ≥ 0. */
int blk_springs_table(blk_model *m, int K, const double *d, const double *F,
                      const double *k, proto_err *err);
/* Synthetic stiffening springs F = s_m k0 d (1 + (d/d0)²), s_m a per-element
 * scatter in [1−spread, 1+spread] (seeded), tabulated on K knots to d_max. */
int blk_springs_stiffening(blk_model *m, double k0, double d0, double spread,
                           uint64_t seed, double d_max, int K, proto_err *err);
/* Multiplies every spring's force by e^{σ g − σ²/2}, g standard normal
 * (seeded): a heavy-tailed, log-normal scatter of mean 1 (a few elements
 * far stiffer than the rest, as the thesis found on its road, ch. 4.2.2). */
int blk_springs_lognormal(blk_model *m, double sigma, uint64_t seed, proto_err *err);
/* No roughness springs: hard contact (Signorini), d_rs = 0. */
int blk_springs_rigid(blk_model *m, proto_err *err);
/* Reads springs.h5 (green/FORMATS.md): tables and z_road. */
int blk_springs_load(blk_model *m, const char *path, proto_err *err);
/* The thesis' second cure (seed 002 ch. 4.2.2): the `count` stiffest springs,
 * ranked by their force at compression `at` (thesis: 80 at 9 µm), are
 * softened: factor > 0 scales their force and stiffness by factor; factor
 * <= 0 exchanges them for the next `count` in the ranking (the thesis). */
int blk_springs_soften(blk_model *m, int count, double at, double factor,
                       proto_err *err);
/* Spring force and stiffness of element e at compression d ≥ 0 (green's
 * spring law, green/green.h, on the element's table; blk_spring.c). */
void blk_spring_eval(const blk_model *m, int e, double d, double *F, double *k);
/* Stored energy W(d) = ∫_0^d F and the inverse law d(F), for d, F ≥ 0. */
double blk_spring_energy(const blk_model *m, int e, double d);
double blk_spring_inverse(const blk_model *m, int e, double F);

/* Road heights. */
int blk_road_set(blk_model *m, const double *z, proto_err *err);
/* Paraboloid z = −r²/(2R) about the grid centre (top at 0). */
int blk_road_paraboloid(blk_model *m, double R, proto_err *err);
/* Gaussian-ish random heights (rms, seeded), max shifted to 0. */
int blk_road_random(blk_model *m, double rms, uint64_t seed, proto_err *err);
/* The road of road.kind "world" under a block centred at world (x, y) (m):
 * a Gaussian height field of rms road_rms on the world grid of dx x dy cells,
 * element (i, j) taking the height of the cell its centre lies in (hashed
 * from road_seed and the cell's indices; or the map's, blk_road_world_map),
 * mean 0, not shifted: the same road
 * wherever a block lands on it. Called between passages (nothing in
 * contact), never inside a step. */
void blk_road_world(blk_model *m, double x, double y);
/* road.kind "world" from a surface file (grn_surface_read_h5: /road/heights,
 * dx, dy): its heights, mean removed, become the world's road, repeated with
 * the map's period; each element takes the height at its world cell's centre
 * (the map's own point when the pitches agree, else bilinear between its
 * four points). */
int blk_road_world_map(blk_model *m, const char *path, proto_err *err);

/* Full validation before a run (shapes, finiteness, monotone springs). */
int blk_model_check(const blk_model *m, proto_err *err);

/* ---- config: processes.<name> section (README.md lists the keys) */
int blk_model_from_config(blk_model *m, const cJSON *section,
                          const char *key_path, proto_err *err);

/* ---- running */
int blk_state_create(const blk_model *m, blk_state *s, proto_err *err);
void blk_state_free(blk_state *s);
/* Bytes allocated by blk_state_create for this model (state, solver, history). */
size_t blk_state_bytes(const blk_state *s);
/* Forgets the history (t = 0, nothing in contact). */
void blk_state_reset(const blk_model *m, blk_state *s);
/* One step to road displacement d_road (m, + = indentation). Not converging
 * within max_iter is not an error (s->converged = 0, as in the thesis); NaN
 * is (-1, message names step and element). */
int blk_step(const blk_model *m, blk_state *s, double d_road, proto_err *err);

/* The whole changing state as arrays "state.<x>" (proto.h state_save /
 * state_load: rollback of implicit coupling, checkpoints). Export adds arrays
 * pointing into s (and into `scalars`, the caller's buffer of
 * BLK_STATE_SCALARS doubles); import copies them back into a state created
 * for the same model; restored states step bit-identically. */
#define BLK_STATE_SCALARS 16
int blk_state_export(const blk_model *m, const blk_state *s, double *scalars,
                     proto_msg *out, proto_err *err);
int blk_state_import(const blk_model *m, blk_state *s, const proto_msg *in,
                     proto_err *err);

/* Reference: the layer displacement by the plain double sum (eq. 4–5, all
 * Q samples, no truncation) at the last row of a force record F_hist[n][M]
 * of n_rows rows (row r = step r+1), into d_el[M]. */
void blk_layer_displacement_ref(const blk_model *m, const double *F_hist,
                                int64_t n_rows, double *d_el);

#endif
