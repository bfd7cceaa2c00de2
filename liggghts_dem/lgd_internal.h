/* lgd_internal.h — private to liggghts_dem/: the LIGGGHTS input built from a
 * dem_model (lgd_script.c), the C++ shim over LIGGGHTS internals the C library
 * interface cannot reach (lgd_shim.cpp), and the sim's state (lgd_sim.c). */
#ifndef COSIM_LGD_INTERNAL_H
#define COSIM_LGD_INTERNAL_H

#include <math.h>
#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* ---- names shared by the script and the sim ---- */
/* primitive wall of model plane %d; at most 9 characters: LIGGGHTS 3.8's
 * `store_force` names its per-grain fix "force_<id>" in a buffer sized by the
 * style name "wall/gran" (FixWallGran::post_create), so a longer id overflows
 * it (found by AddressSanitizer) */
#define LGD_FIX_PLANE "lgdw%d"
#define LGD_FIX_MESH "lgd_mesh%d"    /* fix mesh/surface/stress of model mesh %d */
#define LGD_FIX_MESHWALL "lgd_meshwall"
#define LGD_ID_LEN 32

/* ---- one contact of a grain with a mesh triangle (owned grains) ---- */
enum { LGD_ROW_TRI, LGD_ROW_TYPE, LGD_ROW_R, LGD_ROW_DIST, LGD_ROW_CP, LGD_ROW_F = LGD_ROW_CP + 3,
       LGD_ROW_LEN = LGD_ROW_F + 3 };

typedef struct lgd_rows {
  double *v; /* [n*LGD_ROW_LEN]: triangle id, grain type, radius, centre–contact
                distance, contact point (3), force on the grain (3) */
  int n, cap;
} lgd_rows;

/* Local contact statistics (owned grains; a pair with a ghost counts half). */
typedef struct lgd_stats {
  double contacts, pair_contacts, energy, max_ratio;
} lgd_stats;

/* ---- the shim (lgd_shim.cpp); all return -1 if the fix is missing ---- */
/* Call before the first run: the mesh moves by node (registerMove) and has the
 * per-node velocity property "v" that the wall reads. */
int lgd_shim_mesh_enable_motion(void *lmp, const char *fix_id);
/* Triangles of the mesh over all ranks (valid after the first run). */
int lgd_shim_mesh_size(void *lmp, const char *fix_id);
/* Collective. Sets every owned and ghost copy of each triangle from the
 * global node arrays: positions, velocities, and edge/corner activity (left
 * as LIGGGHTS set it up when the flag arrays are NULL). */
int lgd_shim_mesh_set(void *lmp, const char *fix_id, const int32_t *tri, const double *x,
                      const double *v, const uint8_t *edge_active, const uint8_t *corner_active);
/* Activity flags of the triangles this rank owns, as 1 + flag by global id
 * (0 where not owned; the caller combines ranks by maximum). */
int lgd_shim_mesh_flags(void *lmp, const char *fix_id, uint8_t *edge_active, uint8_t *corner_active);
/* Appends this rank's contacts with the mesh (store_force_contact_stress). */
int lgd_shim_mesh_contacts(void *lmp, const char *fix_id, lgd_rows *rows);
/* Call before write_restart: the per-grain sizes LIGGGHTS writes for its
 * per-contact stores are updated (else read_restart overruns them). */
void lgd_shim_restart_sizes(void *lmp);
/* Total force ON the mesh from its stress module (the same on every rank). */
int lgd_shim_mesh_force(void *lmp, const char *fix_id, double *f);
/* Grain–grain contacts of this rank from the pair neighbour list; estar is
 * [ntypes*ntypes] by (type-1). */
void lgd_shim_pair_stats(void *lmp, const double *estar, int ntypes, lgd_stats *st);
/* Adds LIGGGHTS' timer of the last run to acc[LGD_SHIM_TIMERS]: loop, pair,
 * neigh, comm, modify, output (the order of lgd_timing.lig). */
#define LGD_SHIM_TIMERS 6
void lgd_shim_timer_add(void *lmp, double *acc);
/* Empties LIGGGHTS' screen file when it grew beyond max_bytes (rank 0). */
void lgd_shim_screen_trim(void *lmp, long max_bytes);
/* Grows rows to hold n more; -1 when out of memory. */
int lgd_rows_reserve(lgd_rows *r, int more);

/* One contact into the statistics: overlap δ, radius for the ratio, R*, Y*,
 * weight (1, or 1/2 for a pair listed on two ranks). The elastic energy is
 * dem_server's: the normal Hertz energy 2/5 kn δ², kn = 4/3 Y* √(R* δ). */
static inline void lgd_stats_add(lgd_stats *st, double overlap, double r, double rstar,
                                 double estar, double weight) {
  st->contacts += weight;
  st->energy += weight * 0.4 * (4.0 / 3.0) * estar * sqrt(rstar * overlap) * overlap * overlap;
  if (overlap / r > st->max_ratio) st->max_ratio = overlap / r;
}

#ifdef __cplusplus
}
#endif

#ifndef __cplusplus
#include "liggghts_dem/lgd.h"

/* LIGGGHTS atom type (1-based) of a material; grains that do not rotate get
 * their own types (integrated by `fix nve`). */
static inline int lgd_type(const dem_model *m, int material, int fixed_rotation) {
  return material + 1 + (fixed_rotation ? m->n_materials : 0);
}
int lgd_n_types(const dem_model *m); /* reads the grains: rank 0 */
/* Axis (0, 1, 2) of a plane wall's normal; -1 if it is not along one. */
int lgd_plane_axis(const dem_plane *p);

/* The input: every LIGGGHTS command, one per line, plus the data and mesh
 * files it reads (written by rank 0 into dir). */
typedef struct lgd_script {
  char *text;
  size_t len, cap;
} lgd_script;
/* face_tolerance: LIGGGHTS mesh `precision`, 0 = chosen from the grain size;
 * dt: the DEM step (dem_model_dt); restart: a LIGGGHTS restart file to read
 * the grains (and their contact history) from instead of the model's (NULL);
 * surface_x: the coupled surface's nodes (NULL: the model's x0). */
int lgd_script_build(const dem_model *m, const char *dir, double face_tolerance, double dt,
                     const char *restart, const double *surface_x, lgd_script *s, proto_err *err);
void lgd_script_free(lgd_script *s);
/* Y* per type pair [ntypes*ntypes] (caller frees). */
double *lgd_estar_table(const dem_model *m, int ntypes);
#endif

#endif
