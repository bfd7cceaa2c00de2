/* dem_internal.h — private to dem_server/: the work struct behind dem_state
 * and small vector/contact helpers shared by the .c files. */
#ifndef COSIM_DEM_INTERNAL_H
#define COSIM_DEM_INTERNAL_H

#include "dem_server/dem.h"
#include <math.h>

/* Binary bounding-volume tree over a mesh's triangles (seed 000 §4.2). Nodes in
 * pre-order (children after parents) so a refit is one reverse sweep. */
typedef struct dem_bvh {
  int n_nodes;
  double *lo, *hi;      /* [n_nodes*3] boxes */
  int32_t *left, *right;/* children; left < 0: leaf holding triangle ~left */
  double area_built;    /* sum of box surface areas right after the build */
} dem_bvh;

/* Contact features of a sphere–triangle contact (seed 000 fig. 10). */
#define DEM_CHUNK 512 /* grains per chunk of deterministic partial sums */

enum { DEM_FEAT_VERTEX = 1, DEM_FEAT_EDGE = 2, DEM_FEAT_FACE = 3 };

struct dem_work {
  int nthreads;
  /* half neighbour list in CSR by slot (j > i), with per-pair history and the
   * per-pair results that the deterministic gather sums */
  int *nl_start, *nl_j;
  double *nl_shear, *pair_f, *pair_roll; /* [cap*3]: spring, F on i, rolling torque on i */
  double *pair_c; /* [cap*4]: n × F_t and δ/2 (torque on i is −(r_i − δ/2) n × F_t) */
  double *pair_u;                                 /* [n] elastic energy of i's own pairs */
  int cap;
  int *old_start, *old_j;
  double *old_shear;
  int old_cap, have_old;
  int *rev_start, *rev_k, *rev_fill; /* pairs in which a slot is the partner j */
  int *old_of;                       /* new slot -> old slot during a rebuild */
  double *x_ref;                     /* positions at the last rebuild */
  /* cells */
  int *cell_start, *cell_of;
  int cell_cap;
  double cell_lo[3], cell_size;
  int cell_dim[3];
  /* plane walls: per plane p and slot i */
  double *wall_shear;          /* [n*n_planes*3], grain-major */
  uint64_t *plane_mask;        /* [n] planes within r + skin at the last rebuild */
  double *wall_part;           /* [chunks*n_planes*3] per-chunk wall totals */
  double *ke_part;             /* [chunks] per-chunk kinetic energy */
  double *mass, *inertia;      /* [n] (inertia 0 for non-rotating grains) */
  double *wall_u;              /* [n] elastic energy in wall contacts */
  uint8_t *wall_contacts;      /* [n] number of wall contacts of i */
  /* meshes: contact slots per grain (history carried by feature key, or by
   * normal when a contact moves across an edge onto the next triangle) */
  int64_t *mc_key;  /* [n*K], 0 = free */
  int32_t *mc_tri;  /* [n*K] global triangle: mesh << 24 | tri is not assumed, see mc_mesh */
  int8_t *mc_mesh;  /* [n*K] */
  double *mc_shear, *mc_normal, *mc_zeta, *mc_force; /* [n*K*3] */
  double *mesh_f, *mesh_t; /* [n*3] force/torque on grain from meshes */
  dem_bvh bvh[DEM_MAX_MESHES];
  /* scratch for permutations */
  double *tmp;   /* [n*4] */
  int64_t *itmp; /* [n*K] */
  /* per-grain diagnostics */
  int *pair_contacts; /* [n] */
  double *ratio;      /* [n] max overlap ratio of i's contacts */
};

/* ---- vectors ---- */
static inline double dem_dot(const double *a, const double *b) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
static inline void dem_cross(const double *a, const double *b, double *c) {
  c[0] = a[1] * b[2] - a[2] * b[1];
  c[1] = a[2] * b[0] - a[0] * b[2];
  c[2] = a[0] * b[1] - a[1] * b[0];
}

/* One Hertz–Mindlin contact, LIGGGHTS `model hertz tangential history`
 * (notes §1.1; seed 000 eq. 22–27 in LIGGGHTS' form):
 *   n: unit normal towards grain i; delta > 0: overlap; rstar, mstar: eq. 16–17
 *   (walls: r_i, m_i); vc: velocity of i's contact point relative to the other
 *   body's; shear: the tangential spring (eq. 20), updated in place.
 * Out: F (force on i), c = n × F_t, *u = elastic energy ∫F_n dδ = 2/5 kn δ²;
 * returns F_n.
 * Sn = 2Y*√(R*δ), St = 8G*√(R*δ), kn = 4/3 Y*√(R*δ), kt = St,
 * γn = −2√(5/6) β √(Sn m*), γt = −2√(5/6) β √(St m*): one square root for both
 * dampings (l->damp_n = −2√(5/6) β √(2Y*), l->damp_t = −2√(5/6) β √(8G*)). */
static inline __attribute__((always_inline)) double dem_hertz(const dem_pair_law *l, double delta, double rstar,
                               double mstar, const double *n, const double *vc,
                               double dt, double *shear, double *F, double *c, double *u) {
  const double sqrt_rd = sqrt(rstar * delta);
  const double kn = (4.0 / 3.0) * l->Estar * sqrt_rd, kt = 8.0 * l->Gstar * sqrt_rd;
  const double q = sqrt(sqrt_rd * mstar);
  const double gamman = l->damp_n * q, gammat = l->damp_t * q;
  const double vn = dem_dot(vc, n);
  const double Fn = kn * delta - gamman * vn; /* eq. 22: damping opposes vn */
  *u = 0.4 * kn * delta * delta;
  const double vt[3] = {vc[0] - vn * n[0], vc[1] - vn * n[1], vc[2] - vn * n[2]};
  for (int k = 0; k < 3; k++) shear[k] += vt[k] * dt; /* eq. 20 */
  const double rsht = dem_dot(shear, n);               /* project into the tangent plane */
  for (int k = 0; k < 3; k++) shear[k] -= rsht * n[k];
  double Ft[3] = {-kt * shear[0], -kt * shear[1], -kt * shear[2]};
  const double shr2 = dem_dot(shear, shear);
  const double Ft_friction = l->mu * fabs(Fn);
  if (kt * kt * shr2 > Ft_friction * Ft_friction) { /* sliding: Coulomb, spring reset, no damping */
    if (shr2 > 0) {
      const double ratio = Ft_friction / (kt * sqrt(shr2)), ikt = 1.0 / kt;
      for (int k = 0; k < 3; k++) { Ft[k] *= ratio; shear[k] = -Ft[k] * ikt; }
    } else {
      Ft[0] = Ft[1] = Ft[2] = 0;
    }
  } else { /* sticking: spring + dashpot (eq. 24, 27) */
    for (int k = 0; k < 3; k++) Ft[k] -= gammat * vt[k];
  }
  for (int k = 0; k < 3; k++) F[k] = Fn * n[k] + Ft[k];
  dem_cross(n, Ft, c);
  return Fn;
}

/* LIGGGHTS `rolling_friction cdt`: torque −μ_r |F_n| R* ω̂_rel on i. */
static inline void dem_rolling(const dem_pair_law *l, double Fn, double rstar,
                               const double *w_rel, double *torque_i) {
  double wm = sqrt(dem_dot(w_rel, w_rel));
  double s = wm > 0 ? -l->mu_roll * fabs(Fn) * rstar / wm : 0.0;
  for (int k = 0; k < 3; k++) torque_i[k] = s * w_rel[k];
}

/* dem_neigh.c */
int dem_neigh_alloc(const dem_model *m, dem_state *s, proto_err *err);
void dem_neigh_free(struct dem_work *w);
int dem_neigh_rebuild(const dem_model *m, dem_state *s, proto_err *err);
/* dem_mesh.c */
int dem_mesh_alloc(const dem_model *m, dem_state *s, proto_err *err);
void dem_mesh_free(const dem_model *m, dem_state *s);
void dem_mesh_move(const dem_model *m, dem_state *s, double dt);
void dem_mesh_forces(const dem_model *m, dem_state *s);
int dem_bvh_build(dem_bvh *b, const double *x, const int32_t *tri, int n_tri);
void dem_bvh_refit(dem_bvh *b, const double *x, const int32_t *tri);
void dem_bvh_free(dem_bvh *b);
/* Refit; rebuild when refitting has doubled the total box area. */
void dem_bvh_update(dem_bvh *b, const double *x, const int32_t *tri, int n_tri);
/* Closest point of triangle (a,b,c) to p; zeta: barycentric weights. */
void dem_closest_on_triangle(const double *p, const double *a, const double *b,
                             const double *c, double *q, double *zeta);
/* dem_force.c */
void dem_compute_forces(const dem_model *m, dem_state *s);

#endif
