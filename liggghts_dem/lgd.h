/* lgd.h — the one public header of cosim's LIGGGHTS-backed DEM (prefix lgd_).
 *
 * The same scene as dem_server (a dem_model read from the same config section
 * by dem_model_from_json, dem_server/dem.h) run by LIGGGHTS 3.8 through its
 * library interface, over MPI: `pair gran model hertz tangential history`,
 * `fix wall/gran` primitive planes for plane/box walls, `fix mesh/surface/stress`
 * meshes for mesh walls and for the coupled tread surface, whose nodes are moved
 * to the coupler's positions every DEM step. The grains' forces on the surface
 * go to its nodes by the barycentric rule of seed 000 eq. 42, from LIGGGHTS'
 * per-contact forces and contact points, as impulse over the coupling step / Δt.
 *
 * Every function taking an lgd_sim is collective over the sim's communicator
 * (all ranks call it, in the same order); results (lgd_out) live on rank 0.
 * Errors are agreed: if any rank fails, every rank returns -1 with the first
 * failing rank's message. LIGGGHTS' own input errors end the process (LIGGGHTS
 * calls exit); its screen output goes to lgd_options.screen.
 */
#ifndef COSIM_LGD_H
#define COSIM_LGD_H

#include <mpi.h>
#include <stdint.h>

#include "dem_server/dem.h"

typedef struct lgd_options {
  const char *screen;  /* LIGGGHTS' screen on rank 0 (NULL: /dev/null); kept short */
  const char *tmp_dir; /* where rank 0 writes the input files (NULL: $TMPDIR or /tmp) */
  int frozen_activity; /* 1: keep LIGGGHTS' own edge/corner activity of the initial
                          shape (its behaviour; for measuring the trap, lgd_topo) */
  double face_tolerance; /* LIGGGHTS mesh `precision` (m); 0: from the grain size
                            (lgd_script.c); for measuring its effect */
  int skip_settle;     /* 1: no settling and no bed saving (a restart replaces the bed) */
  const struct lgd_resume *resume; /* non-NULL: start from a checkpoint (lgd_save) */
} lgd_options;

/* A checkpoint of a sim (lgd_save): LIGGGHTS' own restart file (grains,
 * velocities, the tangential contact history of pairs, plane walls and mesh
 * contacts) and what the sim holds beside it. Any rank count may resume it (LIGGGHTS reads one
 * restart file on any number of ranks). */
typedef struct lgd_resume {
  const char *restart;       /* LIGGGHTS restart file (rank 0 reads it) */
  double t, coupling_dt;     /* the sim's clock and coupling step (0: none yet) */
  const double *surface_x, *surface_v; /* [n_nodes*3] the coupled surface's nodes
                                          after the last DEM step (NULL: none) */
  const double *force, *torque; /* [n_grains*3] each, config order: the last DEM
                                   step's, which velocity Verlet starts from (rank 0) */
} lgd_resume;

/* Per-step results, valid on rank 0 after lgd_step. Forces are averages over
 * the coupling step (impulse / Δt, the sum over DEM sub-steps / their count). */
typedef struct lgd_out {
  double series[DEM_N_SERIES]; /* dem_server's summary columns (dem_series_col),
                                  end of step */
  double *wall_force;  /* [n_walls*3] force ON each wall, config order (N) */
  double *nodal_force; /* [n_nodes*3] force of the grains ON each coupled surface
                          node (N); NULL without a coupled surface */
  int64_t substeps;    /* DEM steps in the last coupling step */
} lgd_out;

/* Where the time goes on rank 0 (seconds, summed over lgd_step calls). */
enum { LGD_LIG_LOOP, LGD_LIG_PAIR, LGD_LIG_NEIGH, LGD_LIG_COMM, LGD_LIG_MODIFY, LGD_LIG_OUTPUT,
       LGD_LIG_TIMERS };
typedef struct lgd_timing {
  int64_t steps, substeps;
  double total;   /* inside lgd_step */
  double run;     /* LIGGGHTS `run 1` calls (its loop and the call's own set-up) */
  double surface; /* node positions, activity rule, copying them into LIGGGHTS */
  double forces;  /* contacts onto the nodes, wall forces */
  double summary; /* series values, checks, reductions */
  double lig[LGD_LIG_TIMERS]; /* LIGGGHTS' own timer inside the runs: loop, pair,
                                 neighbour lists, communication, fixes (LIGGGHTS 3.8
                                 leaves it 0: walls, meshes and integration are the
                                 loop minus the others), output */
} lgd_timing;

typedef struct lgd_sim lgd_sim;

/* dem_server's reader (dem_model_from_json) on every rank of comm, but only
 * rank 0 keeps the grains: the others hold one stand-in grain and rank 0's
 * grain-dependent values (Rayleigh time, hence dt, skin, settling settings). Such a
 * model is only for lgd_open (which takes the grain count from rank 0).
 * Collective; errors agreed (rank 0's message). */
int lgd_model_from_json(dem_model *m, const cJSON *section, const char *path, MPI_Comm comm,
                        proto_err *err);

/* What LIGGGHTS cannot express, refused with the key path (a material's own
 * G, walls that are not axis-aligned planes, more types than LIGGGHTS takes).
 * Pure: no MPI, no LIGGGHTS. */
int lgd_check_model(const dem_model *m, proto_err *err);

/* Starts LIGGGHTS on comm with the model (every rank passes the same scene;
 * only rank 0's grains are read: lgd_model_from_json), computes the initial forces and, when
 * the model asks for it (generated bed, settle_max_steps > 0), settles the bed
 * and then restarts the clock at t = 0 (and saves the bed if asked). The model
 * must outlive the sim and is not changed by it. The DEM step is the sim's:
 * dem_model_dt(m, coupling_dt) (0 = no coupling step), re-split by lgd_step
 * when the coupling step changes. */
int lgd_open(lgd_sim **out, MPI_Comm comm, const dem_model *m, double coupling_dt,
             const lgd_options *o, proto_err *err);
/* One coupling step of length dt: the coupled surface (if any) starts at x with
 * node velocities v (every rank passes them) and moves with v through the
 * sub-steps, as in dem_server. */
int lgd_step(lgd_sim *s, double dt, const double *x, const double *v, proto_err *err);
/* Writes the checkpoint: LIGGGHTS' restart file at path (given on rank 0;
 * rank 0 writes it) and fills r (path, clock; pointers into the sim: the
 * surface valid until its next step, forces until the next lgd_save or
 * lgd_close). Refuses what a restart would not reproduce (a
 * mesh wall moved by LIGGGHTS). Collective. */
int lgd_save(lgd_sim *s, const char *path, struct lgd_resume *r, proto_err *err);
/* Results of the last step (rank 0; other ranks get zeros). */
const lgd_out *lgd_result(const lgd_sim *s);
/* Grain positions, velocities, angular velocities in config order, on rank 0
 * (arrays [n_grains*3]; NULL allowed on other ranks). */
int lgd_gather(lgd_sim *s, double *x, double *v, double *omega, proto_err *err);
const lgd_timing *lgd_time(const lgd_sim *s);
/* The DEM step LIGGGHTS integrates with now (s). */
double lgd_dt(const lgd_sim *s);
/* Triangles LIGGGHTS holds for model mesh k (after lgd_open). */
int lgd_mesh_triangles(const lgd_sim *s, int mesh);
/* The edge/corner activity LIGGGHTS uses now for mesh k ([n_tri*3] each, on
 * every rank; layout of lgd_topo_activity). */
int lgd_mesh_activity(lgd_sim *s, int mesh, uint8_t *edge_active, uint8_t *corner_active,
                      proto_err *err);
/* Stops LIGGGHTS and frees the sim (collective). NULL is allowed. */
void lgd_close(lgd_sim *s);

/* LIGGGHTS' rule for which triangle edges and corners take part in contact
 * (SurfaceMesh::buildNeighbours, surface_mesh_I.h), evaluated on any shape of
 * a fixed topology: LIGGGHTS itself evaluates it once, on the initial shape
 * (docs/liggghts.md §2), so a tread that starts flat would keep
 * every interior edge inactive however it bends. */
typedef struct lgd_topo {
  int n_nodes, n_tri, n_edges, n_fans;
  const int32_t *tri;     /* [n_tri*3], not owned */
  int32_t *edge_node;     /* [n_edges*2] a < b */
  int32_t *tri_edge;      /* [n_tri*3] edge of triangle t from corner k to k+1 */
  int32_t *edge_start;    /* [n_edges+1] CSR into edge_tri */
  int32_t *edge_tri;      /* triangles sharing each edge, ascending */
  int32_t *corner_fan;    /* [n_tri*3] fan (edge-connected triangles around a node) */
  int32_t *fan_start;     /* [n_fans+1] CSR into fan_slot: tri*3+corner */
  int32_t *fan_slot;
  int32_t *fan_edge_start;/* [n_fans+1] CSR into fan_edge: distinct incident edges */
  int32_t *fan_edge;
  double *normal, *dir;   /* scratch: unit normals [n_tri*3], unit edges [n_edges*3] */
} lgd_topo;

#define LGD_CURVATURE (1.0 - 1e-5) /* LIGGGHTS' default: |cos| above it = coplanar */

int lgd_topo_build(lgd_topo *t, int n_nodes, int n_tri, const int32_t *tri, proto_err *err);
/* Flags for the shape x: edge_active[3t+k] (edge k→k+1 of triangle t),
 * corner_active[3t+k] (node k), 1 = takes part in contact. */
void lgd_topo_activity(lgd_topo *t, const double *x, uint8_t *edge_active,
                       uint8_t *corner_active);
void lgd_topo_free(lgd_topo *t);

#endif
