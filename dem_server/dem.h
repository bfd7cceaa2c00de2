/* dem.h — the one public header of cosim's DEM part (prefix dem_).
 *
 * Spheres with Hertz–Mindlin contacts, exactly LIGGGHTS 3.8
 * `pair gran model hertz tangential history` (seed 000 eq. 16–27; the Coulomb
 * rule of LIGGGHTS 3.8 `src/tangential_model_history.h`), velocity Verlet (eq. 4–5) with
 * optional quaternion orientation, linked cells + Verlet list with skin,
 * plane/box walls and triangle meshes (closest point, eq. 35; nodal reaction
 * by ζ, eq. 42; BVH and per-grain candidate lists). Any number of OpenMP
 * threads gives bitwise identical results.
 *
 * Model (the scene, read-only during a run) and state (what changes) are
 * separate, MuJoCo style. Per-grain arrays in the state are structure of arrays
 * and are reordered by cell at neighbour-list rebuilds; `id` maps a slot to the
 * grain's index in the model (config order). Units SI.
 */
#ifndef COSIM_DEM_H
#define COSIM_DEM_H

#include <stdint.h>
#include "proto/proto.h"

#define DEM_MAX_MATERIALS 8
#define DEM_MAX_WALLS 32
#define DEM_MAX_PLANES 64
#define DEM_MAX_MESHES 8
#define DEM_MESH_SLOTS 6 /* mesh contacts kept per grain */
/* "sleep" defaults: at rest below 2 mm/s for 20 ms, outside the region around
 * the moving meshes (its margin: dem_sleep.c; `distance` only widens it);
 * woken when pressed beyond 0.02 of the smaller radius: a settled bed's
 * grains rest at overlaps of ~0.004 (20 MPa) to 0.01 (5 MPa) of their radius
 * at the bottom of 0.13 m of grains, so 0.02 means the load on the contact
 * has grown 3-10x (Hertz: F ~ overlap^1.5) since the grain fell asleep */
#define DEM_SLEEP_VELOCITY 2e-3
#define DEM_SLEEP_TIME 0.02
#define DEM_SLEEP_DISTANCE 0.0
#define DEM_SLEEP_OVERLAP 0.02
/* at rest: its centre moved less than 1e-3 of its radius over `time` (for
 * the paper bed's 3.5 mm grains and 20 ms: creep below 0.18 mm/s). Slow is
 * not at rest: the paper bed loaded by positions still creeps at 0.3-0.5
 * mm/s (median) and the velocity alone froze two thirds of it, which changed
 * the tread's load by a quarter; `velocity` 2e-4 m/s (about this bound for a
 * steady creep) gave the all-awake load (bench/results/tire_soil.md). 1e-3 is
 * 1/20 of `overlap`: a grain frozen while creeping below it reaches the wake
 * overlap only after 20 x `time`. */
#define DEM_SLEEP_DISPLACEMENT 1e-3
/* force rule off by default (dem_sleep_push.c): a scene that loads the bed
 * slowly through its asleep grains sets it (the deep tyre scene) */
#define DEM_SLEEP_FORCE 0.0
/* the woken grains' halo, in cells (dem_sleep.c wake_halo): a whole cell by
 * default, so a disturbance spreading into the asleep block wakes it in
 * batches, not one layer per wake rebuild */
#define DEM_SLEEP_HALO 1.0

typedef struct dem_material {
  double density, E, nu, G; /* G = E/(2(1+nu)) unless given */
  double restitution;       /* e in (0, 1] */
  double friction;          /* Coulomb μ */
  double rolling_friction;  /* μ_r of LIGGGHTS `rolling_friction cdt`, 0 = off */
} dem_material;

/* Per material pair, LIGGGHTS' effective values (LIGGGHTS 3.8
 * `src/normal_model_hertz.h`). Restitution,
 * friction and rolling friction: the mean of the two materials', or the
 * config's "pairs" entry for that pair (LIGGGHTS' peratomtypepair tables). */
typedef struct dem_pair_law {
  double Estar; /* Y* = 1/((1-ν1²)/E1 + (1-ν2²)/E2), seed 000 eq. 21 */
  double Gstar; /* 1/(2(2-ν1)(1+ν1)/E1 + 2(2-ν2)(1+ν2)/E2), eq. 26 with G = E/(2(1+ν)) */
  double beta;  /* ln e / sqrt(ln² e + π²) (≤ 0) */
  double mu, mu_roll;
  double damp_n, damp_t; /* −2√(5/6) β √(2Y*), −2√(5/6) β √(8G*): γ = damp·√(√(R*δ) m*) */
  int clamp;             /* F_n never attractive (LIGGGHTS `limitForce on`): the model's limit_force */
} dem_pair_law;

typedef enum dem_wall_kind { DEM_WALL_PLANE, DEM_WALL_BOX, DEM_WALL_MESH } dem_wall_kind;

typedef struct dem_wall {
  dem_wall_kind kind;
  int material;
  int plane0, nplanes; /* planes of this wall in model->planes */
  int mesh;            /* index in model->meshes (DEM_WALL_MESH) */
  double lo[3], hi[3]; /* box extent */
} dem_wall;

/* An infinite plane; grains live on the side the normal points to. */
typedef struct dem_plane {
  double point[3], normal[3];
  int material, wall;
} dem_plane;

typedef struct dem_mesh {
  int n_nodes, n_tri;
  double *x0;        /* [n_nodes*3] node positions at t = 0 */
  int32_t *tri;      /* [n_tri*3] node indices */
  double velocity[3];/* rigid meshes: constant translation velocity */
  int material, wall;
  int coupled;       /* node positions/velocities set each step (FEM surface) */
} dem_mesh;

/* "sleep" (dem_sleep.c): a grain slower than `velocity` (also |ω| r) for
 * `time`, its centre within `displacement` × its radius of where it was when
 * that time began, resting on something and outside the region around the moving
 * meshes (their box grown by a margin of at least `distance`) stops: not
 * integrated, not in the list rebuild, its contacts with other sleeping
 * grains frozen; it wakes when an awake grain listed with it moves faster
 * than `velocity` or presses into it beyond `overlap` of the smaller radius,
 * when its awake neighbours' push on it has changed since it fell asleep by
 * more than `force` times its weight, or the region reaches it. */
typedef struct dem_sleep_config {
  int on;
  double velocity, time, overlap;
  double distance[3]; /* the region's least margin along x, y, z (m; "distance": a number for all
                         three, or [x, y, z]: a tyre's stress reaches the floor below it, less far
                         beside it) */
  double displacement; /* at rest: moved less than this fraction of the radius over `time` */
  double wake_velocity; /* an awake grain faster than this wakes its listed asleep neighbours (m/s;
                           "wake_velocity", default DEM_WAKE_FACTOR x velocity) */
  double force;         /* wake when the awake neighbours' push changed by this x the grain's weight
                           (0: off; dem_sleep_push.c) */
  double halo;          /* with a woken grain the asleep grains within halo x one cell of the last
                           full rebuild (2 r_max + skin) wake too (0 to 1, default 1; 0: only those
                           a rule or the region wakes) */
  int test_steps;       /* steps between the force rule's tests and the batches falling asleep
                           ("test_steps", a multiple of the region's update interval, by default
                           that interval: each test that wakes a grain costs a wake rebuild) */
} dem_sleep_config;

/* Preparation of a packing ("particles.prepare" of a generated bed; terra's
 * --prep-friction): while the bed settles, every contact law's sliding
 * friction is `friction` and its rolling friction `rolling` (every material
 * and pair, walls and meshes included), then the scene's laws come back
 * before t = 0. Low friction while settling packs the grains denser
 * (bench/results/sand_calibration.md). on = 0: the scene's laws throughout. */
typedef struct dem_prep {
  int on;
  double friction, rolling;
} dem_prep;
/* Largest preparation friction accepted: beyond it a value is a typo (a
 * Coulomb limit of 10 |F_n| never lets a contact slide). */
#define DEM_PREP_FRICTION_MAX 10.0

/* Config values kept as given (the derived ones live in dem_model). */
typedef struct dem_model_config {
  double dt_given;     /* "dt", 0 = use dt_fraction */
  double dt_fraction;  /* "dt_fraction" of the Rayleigh time */
  double skin;         /* "skin", < 0 = default */
  double settle_ke;    /* generated beds: settle until KE per grain below this (J) */
  double settle_steps; /* ... or this many steps (0 = no settling) */
  char save_bed[512];  /* generated beds: HDF5 file written after settling ("" = none) */
  char bed_file[512];  /* "particles.file": the bed read ("" = none) */
  int bed_positions;   /* "particles.state": "positions": ignore the bed's saved state */
  dem_prep prep;       /* generated beds: "particles.prepare" (the laws while settling) */
  int substrate_grains; /* generated beds: grains of the substrate, the model's first (dem_bed_place) */
  int substrate_first;  /* "particles.substrate.settle_first": settle it alone first (dem_bed_presettle) */
  int64_t substrate_steps; /* its steps settling alone (dem_bed_presettle), 0 = none */
} dem_model_config;

typedef struct dem_model {
  char key_path[128]; /* "processes.<name>", for messages */
  dem_model_config cfg;
  int n_materials;
  dem_material mat[DEM_MAX_MATERIALS];
  dem_pair_law law[DEM_MAX_MATERIALS][DEM_MAX_MATERIALS];
  int n_walls, n_planes, n_meshes;
  dem_wall walls[DEM_MAX_WALLS];
  dem_plane planes[DEM_MAX_PLANES];
  dem_mesh meshes[DEM_MAX_MESHES];
  int surface_material; /* material of the coupled FEM surface */
  double gravity[3];
  double rayleigh_time;  /* over the smallest grain (Li, Xu & Thornton 2005) */
  double skin;           /* neighbour-list skin (m) */
  double overlap_tolerance;   /* initial overlap allowed, fraction of the smaller radius */
  double bed_max_overlap;     /* a bed file saved by dem_bed_save records its largest overlap
                               * (a settled bed has them): accepted up to that too, 0 = none */
  double max_overlap_ratio;   /* overlap/radius that stops a run as unstable */
  int unsafe_dt;         /* skip the stability refusal (stress tests only) */
  int threads;           /* OpenMP threads, 0 = "auto" (dem_threads.c) */
  int has_rolling;
  int limit_force;       /* "limit_force": F_n = max(F_n, 0) (damping never pulls) */
  int surface_couple;    /* "surface_couple": mesh nodes also take the contact's moment
                          * (exact angular momentum across the surface; dem_mesh.c) */
  int orientation;       /* "orientation": integrate q (spheres need it only for output) */
  dem_sleep_config sleep; /* "sleep": grains at rest far from moving meshes stop */
  int n_grains;
  double *x0, *v0, *omega0, *radius; /* [n*3], [n*3], [n*3], [n] */
  int32_t *material;                 /* [n] */
  uint8_t *fix_rotation;             /* [n] 1 = grain does not rotate */
} dem_model;

struct dem_work; /* private: neighbour lists, cells, histories, BVH, scratch */

typedef struct dem_state {
  int n;
  int64_t step;
  double t;
  double dt; /* DEM step (s): dem_state_set_dt, which a new coupling step re-splits */
  /* per grain (slot order, see id) */
  double *x, *v, *omega, *q; /* q: quaternion [n*4] (w, x, y, z), body→world; identity
                              * unless the model's `orientation` is on */
  double *force, *torque;    /* contact forces/torques (gravity enters the kick as g) */
  double *radius, *inv_mass, *inv_inertia;
  int32_t *material, *id;
  uint8_t *fix_rotation;
  /* meshes: current node positions/velocities and the force grains exert on nodes */
  double *mesh_x[DEM_MAX_MESHES], *mesh_v[DEM_MAX_MESHES], *mesh_force[DEM_MAX_MESHES];
  /* sparse exchange (dem_nodeset.c): per triangle, 1 if its nodes' positions
   * are this step's; a triangle marked 0 touches no grain. NULL: all are.
   * Set from each step request, not part of the exported state. */
  const uint8_t *mesh_live[DEM_MAX_MESHES];
  /* per-step summary */
  double kinetic_energy;   /* translational + rotational, J */
  double elastic_energy;   /* normal Hertz energy stored in contacts, J */
  int64_t contacts;        /* grain–grain + grain–wall contacts (evaluated ones: not those
                            * between sleeping grains) */
  int64_t sleeping;        /* grains asleep ("sleep" on) */
  double max_overlap_ratio;/* max overlap / radius */
  double *wall_force;      /* [n_walls*3] force ON each wall, N */
  int64_t rebuilds;        /* neighbour-list rebuilds: partial + full + wake (dem_rebuild_kinds) */
  int threads;             /* OpenMP threads in use (may change in "auto" mode) */
  char threads_why[256];   /* how that number was chosen, for the log */
  struct dem_work *work;
} dem_state;

/* ---- model ---- */
/* Reads a config section `processes.<name>` (key path `path`). Accepts and
 * ignores "exec". Needs no run information; refuses a dt above the stability
 * limit (dem_model_dt without a coupling step). */
int dem_model_from_json(dem_model *m, const cJSON *section, const char *path,
                        proto_err *err);
/* The DEM step: the configured dt, or dt_fraction·T_R; when coupling_dt > 0
 * it is split into equal sub-steps not larger than that. Refuses a step above
 * the stability limit (with the limit and the key in the message). The model
 * is not changed: the step lives in the state (dem_state_set_dt). */
int dem_model_dt(const dem_model *m, double coupling_dt, double *dt, proto_err *err);
/* Adds the coupled FEM surface as a mesh wall (world positions at t = 0). */
int dem_model_set_surface(dem_model *m, int n_nodes, const double *x0, int n_tri,
                          const int32_t *tri, proto_err *err);
void dem_model_free(dem_model *m);
double dem_rayleigh_time(double r, double density, double E, double nu);
/* Smallest Rayleigh time over the model's grains (set m->rayleigh_time to it
 * after replacing grains, before dem_state_init). */
double dem_model_rayleigh(const dem_model *m);
/* Stability limit: largest dt accepted, as a fraction of T_R. */
#define DEM_DT_LIMIT_FRACTION 0.5

/* ---- state ---- */
/* Allocates everything the run needs, sets the step (dem_state_set_dt with
 * coupling_dt, 0 = none), checks the initial configuration (overlaps, grains
 * outside walls/domain) and computes the initial forces (the tangential
 * springs take vt·dt: they depend on the step). */
int dem_state_init(const dem_model *m, dem_state *s, double coupling_dt, proto_err *err);
/* s->dt = dem_model_dt(m, coupling_dt): call when the coupling step changes.
 * On failure s->dt is unchanged. */
int dem_state_set_dt(const dem_model *m, dem_state *s, double coupling_dt, proto_err *err);
void dem_state_free(dem_state *s);
/* One DEM step of s->dt. Fails (with where and why) on NaN, runaway overlap. */
int dem_step(const dem_model *m, dem_state *s, proto_err *err);
/* Call first in main(): unless GOMP_SPINCOUNT or OMP_WAIT_POLICY is set,
 * sets GOMP_SPINCOUNT=10000 and re-executes the program (libgomp reads it
 * when loaded): threads waiting at a barrier then sleep soon instead of
 * spinning on a core that another process needs (dem_threads.c). */
void dem_openmp_env(char **argv);
/* Advances by `duration` in equal steps of s->dt (duration/s->dt rounded). */
int dem_advance(const dem_model *m, dem_state *s, double duration, proto_err *err);
/* Sets coupled mesh nodes: positions at the current time and velocities. */
void dem_mesh_set_nodes(const dem_model *m, dem_state *s, int mesh,
                        const double *x, const double *v);
/* Sparse exchange (dem_nodeset.c, PROTOCOL.md "Sparse exchange"). */
/* Sets the k nodes idx[0..k) of a coupled mesh from rows x, v [k*3]; the
 * others keep their positions and stand still (v = 0), and every triangle
 * with such a node is marked not live in live[n_tri] (node_seen: [n_nodes]
 * scratch), which s->mesh_live[mesh] then points to. */
void dem_mesh_set_nodes_sparse(const dem_model *m, dem_state *s, int mesh, int64_t k,
                               const int32_t *idx, const double *x, const double *v,
                               uint8_t *node_seen, uint8_t *live);
/* Of s->rebuilds, the full ones (every grain listed; with sleep: grains fell
 * asleep) and the wake ones (woken grains joined the awake block); the rest
 * were partial (the awake grains moved a skin's half). For the log. */
void dem_rebuild_kinds(const dem_state *s, int64_t *full, int64_t *wake);
/* The mesh candidate lists built for a mesh's node moves alone (not with a
 * neighbour rebuild), and the checks that found every moved triangle clear
 * of the grains and kept them (dem_mesh.c moved_clear). For the log. */
void dem_mesh_list_counts(const dem_state *s, int64_t *built, int64_t *kept);
/* The awake grains at rest outside the region (they wait for a batch to fall
 * asleep), summed over the checks, and the checks so far (dem_sleep.c). For the log. */
void dem_sleep_waiting(const dem_state *s, int64_t *sum, int64_t *checks);

/* The box the grains can reach in the next coupling step of length dt:
 * every grain's sphere box grown by the margin of dem_nodeset.c, [lo, hi]. */
void dem_reach_box(const dem_model *m, const dem_state *s, double dt, double box[6]);
/* The slot of a grain whose sphere box is not inside box, or -1. */
int dem_reach_escaped(const dem_state *s, const double box[6]);
/* With "sleep" (dem_sleep.c): box (from dem_reach_box) grown to what the
 * active region looks at, and *per_speed (s): the coupler grows it further by
 * that times the surface's largest node speed of the step; 0 without sleep. */
void dem_sleep_reach(const dem_model *m, const dem_state *s, double box[6], double *per_speed);
/* With "sleep": before the next dem_mesh_set_nodes(_sparse), only the nodes
 * of the triangles whose path over dt meets box count for the region's guard
 * (the same nodes in a dense and a sparse exchange). */
void dem_sleep_jump_box(dem_state *s, const double box[6], double dt);
/* Copies per-grain data back into model order (out[id]). cols = 3 or 1. */
void dem_gather(const dem_state *s, const double *slot_data, int cols, double *out);
/* Mean coordination number (contacts per grain, grain–grain only). */
double dem_coordination(const dem_model *m, const dem_state *s);

/* Columns of the per-step summary, the "series" dataset of dem_server and
 * liggghts_dem (names: DEM_SERIES, dem_state.c). */
typedef enum dem_series_col {
  DEM_SERIES_T,            /* s, end of the coupling step */
  DEM_SERIES_KINETIC,      /* dem_state.kinetic_energy */
  DEM_SERIES_CONTACTS,     /* dem_state.contacts */
  DEM_SERIES_MAX_OVERLAP,  /* dem_state.max_overlap_ratio */
  DEM_SERIES_ELASTIC,      /* dem_state.elastic_energy */
  DEM_SERIES_COORDINATION, /* dem_coordination */
  DEM_N_SERIES
} dem_series_col;
extern const char *const DEM_SERIES[DEM_N_SERIES];
/* Snapshot arrays ("snap.<name>") of dem_server and liggghts_dem: x, v, omega
 * [n,3] and r [n] (names: DEM_SNAP); the wall-force dataset ("series.<name>",
 * columns t, then Fx Fy Fz per wall). */
typedef enum dem_snap_array { DEM_SNAP_X, DEM_SNAP_V, DEM_SNAP_OMEGA, DEM_SNAP_R, DEM_N_SNAP } dem_snap_array;
extern const char *const DEM_SNAP[DEM_N_SNAP];
#define DEM_WALL_FORCES "wall_forces"
/* What a dem participant declares in its ready message (dem_server and
 * liggghts_dem alike): the series, the points snapshot, and the wall-force
 * dataset's columns (t, wall<w>_F<x|y|z>). */
int dem_ready_declare(const dem_model *m, proto_msg *ready, proto_err *err);

/* ---- state export / import (rollback, checkpoints) ----
 * export adds arrays named "state.<x>" to `out` that hold everything that
 * changes during a run (grains in slot order with their permutation `id`,
 * neighbour list with springs and rebuild reference, wall and mesh contact
 * springs with their keys, mesh nodes, clock, last forces, counters with a
 * fingerprint of the model). The arrays point into the state (or scratch it
 * owns; allocated on the first call only): send or copy them before the next
 * dem_step. import restores such a set into a state made by dem_state_init()
 * from the same model; stepping on is then bitwise identical to never having
 * stopped. It checks every array (name, dtype, shape, contents that index
 * other arrays) and the model fingerprint before changing anything, and fails
 * with a message naming the array. Two differences of the model are accepted:
 * sleep off in the state and on in the model; other meshes when no grain
 * touches a mesh in the state (the grains continue, the meshes stay where
 * this state has them, without contacts). */
int dem_state_export(const dem_model *m, const dem_state *s, proto_msg *out, proto_err *err);
int dem_state_import(const dem_model *m, dem_state *s, const proto_msg *in, proto_err *err);

/* ---- beds ---- */
typedef struct dem_bed_layer {
  double diameter, spread; /* uniform in diameter ± spread */
  int64_t count;
  int substrate; /* 1 (dem_bed_substrate): its lattice centred in the footprint (no strip at the walls wider
                    than half the remainder) and its random draws from a stream of its own (the layers above
                    are the bed they are without it); 0: from x = y = 0, the bed's one stream */
} dem_bed_layer;

typedef struct dem_bed_spec {
  double size[2];          /* box footprint Lx, Ly */
  int n_layers;            /* bottom first */
  dem_bed_layer layers[4];
  int material;
  double gap;              /* clearance between placed grains (m) */
  uint64_t seed;
} dem_bed_spec;

/* The paper's bed (seed 000 table 2) scaled: counts × scale, footprint × sqrt(scale). */
void dem_bed_paper(dem_bed_spec *b, double scale);
/* A substrate under b's layers (inserted as the bottom layer): grains of
 * diameter ± spread on full lattice levels of the footprint, as many levels
 * as fit in depth (m; each level one lattice pitch, diameter + spread + gap).
 * Coarser grains of the same material meant to stand in for more of the bed
 * below the layers the tyre reaches, at a fraction of their count (dem_server
 * README "Config": what the plate measured of it). The grains above must
 * not fall into it: a lattice window (pitch √2 - diameter + spread) and the
 * strips at the walls (half the footprint's remainder) narrower than the
 * smallest grain of the layer above (dem_bed_place does not check it; the
 * paper's bottom layer is 15.6 mm: a 26 mm substrate leaves 11.5 mm windows).
 * Fails if b has no room for a layer or depth holds no level; the error
 * names `what`'s keys. */
int dem_bed_substrate(dem_bed_spec *b, double diameter, double spread, double depth, const char *what,
                      proto_err *err);
/* Places grains without overlap on jittered lattices in the model's grain
 * arrays (replaces any) and counts a substrate's in m->cfg.substrate_grains.
 * Does not settle. */
int dem_bed_place(dem_model *m, const dem_bed_spec *b, proto_err *err);
/* A placed bed's substrate settled alone, then the layers above lowered onto
 * it (dem_model_from_json calls it for a generated bed with a substrate,
 * settle_first on and settle_max_steps > 0; dem_bed_presettle.c says why and
 * what it changes). The substrate's grains take the
 * settled positions in m->x0 (at rest), every other grain moves down by the
 * same height, the clearance the substrate left above it. With the
 * preparation's laws if m->cfg.prep is on, at the substrate's own step
 * (dt_fraction of its Rayleigh time), at least DEM_SETTLE_MIN_TIME, then
 * until its kinetic energy per kilogram is below settle_ke_per_grain per the
 * mean mass of the other grains (the same rms speed the bed's test stands
 * for), at most settle_max_steps. The substrate-less bed passes unchanged. */
int dem_bed_presettle(dem_model *m, proto_err *err);
/* Progress of a long call: the fraction done in [0, 1] and what is being
 * done. The library only calls it (a participant passes it on as its
 * heartbeats' progress, proto_peer_progress); it may be NULL. */
typedef void (*dem_progress_fn)(void *ctx, double fraction, const char *what);
/* Runs until the kinetic energy per grain is below ke_per_grain or
 * max_steps, reporting progress now and then (the fraction of max_steps). */
int dem_settle(const dem_model *m, dem_state *s, double ke_per_grain,
               int64_t max_steps, dem_progress_fn progress, void *ctx, proto_err *err);
/* Simulated time a bed placed at rest on the lattice settles before the
 * kinetic-energy test may end it: its grains start with no kinetic energy,
 * and with a 6-9 us step (E = 100-200 MPa) the test alone ended a bed after
 * 101 steps, still in free fall; by 0.1 s the top layer has fallen its ~30
 * gaps of 0.5 mm (55 ms) and rearranges (terra/README.md "Settling"). */
#define DEM_SETTLE_MIN_TIME 0.1 /* s */
/* dem_settle of a placed bed: at least DEM_SETTLE_MIN_TIME (capped by
 * max_steps) before the kinetic-energy test, at most max_steps in all
 * (dem_bed_settle's phases, terra's tests). */
int dem_settle_placed(const dem_model *m, dem_state *s, double ke_per_grain, int64_t max_steps,
                      dem_progress_fn progress, void *ctx, proto_err *err);
/* The preparation checked against the model: values in [0,
 * DEM_PREP_FRICTION_MAX], and a rolling friction > 0 only in a model that
 * has some (the state keeps rolling state only then); messages name
 * key.friction / key.rolling_friction. p->on = 0 passes. */
int dem_prep_check(const dem_model *m, const dem_prep *p, const char *key, proto_err *err);
/* The override itself: every law's mu and mu_roll become the preparation's
 * (nothing else of the law changes). The caller keeps the scene's laws
 * (m->law) to put them back; dem_bed_settle works on a copy instead. */
void dem_prep_laws(dem_model *m, const dem_prep *p);
/* A generated bed's settling, as its config says (dem_server's init): with
 * m->cfg.prep on, dem_settle on a copy of the model with the preparation's
 * laws (dem_prep_laws), then with the scene's (m): the tangential springs
 * stay as they are at the switch and the scene's Coulomb rule limits them
 * at the next step, the rolling torques (no history) start with it; each
 * phase up to settle_max_steps to settle_ke_per_grain, the first as
 * dem_settle_placed, the second without its minimum time (the bed is at
 * rest when the laws change).
 * Without: one such phase with the scene's laws. Then the clock is reset (t = 0, step
 * 0); *steps (may be NULL) gets the steps settled. */
int dem_bed_settle(const dem_model *m, dem_state *s, dem_progress_fn progress, void *ctx, int64_t *steps,
                   proto_err *err);
/* Most grains a model may have (generated or read). */
#define DEM_MAX_GRAINS ((int64_t)100000000)
/* HDF5 beds: datasets x [n,3], v [n,3], omega [n,3], r [n], material [n] (i4),
 * max_overlap [1]: the largest overlap (grain pairs: of the smaller radius;
 * walls: of the radius) of the state saved, which loading accepts (a settled
 * bed is compressed by its weight); a file without it gets overlap_tolerance.
 * The load checks every shape against r's n (<= DEM_MAX_GRAINS) before it
 * allocates; values must be finite, radii > 0 (materials: the caller). */
int dem_bed_save(const dem_model *m, const dem_state *s, const char *path, proto_err *err);
int dem_bed_load(dem_model *m, const char *path, proto_err *err);
/* A saved bed also holds the whole state (group /state: dem_state_export's
 * arrays) and /settled_with [dt, gx, gy, gz] (dem_bed_save writes under a
 * temporary name, then renames: a bed file is always whole). After
 * dem_state_init of a model read from m->cfg.bed_file, dem_bed_continue
 * imports that state (dem_state_import): the run then continues the one
 * that saved the bed, bit for bit. A state of another model is refused,
 * naming the parts that differ (the positions-only load is
 * "particles.state": "positions"). A file without /state (an old bed, or one
 * made elsewhere) leaves s as dem_state_init made it (positions only). *info
 * says which, and the dt and gravity of the saving run (for the log). */
typedef struct dem_bed_info {
  int continued;          /* 1: the saved state was imported; 0: positions only */
  int has_state;          /* the file has one */
  double dt, gravity[3];  /* of the run that saved it (NAN if not recorded) */
  char friction[256];     /* the pairs whose saved friction differs ("0-1: friction 0.3 -> 1.2"), or "" */
  int other_meshes;       /* continued with other meshes than the saving run's (no grain touched one) */
} dem_bed_info;
int dem_bed_continue(const dem_model *m, dem_state *s, dem_bed_info *info, proto_err *err);

/* The bed's top: the `percentile` (in (0, 100]) of the grain tops z + r over
 * the grains whose centre lies in the x-y rectangle [lo, hi] (nearest rank);
 * NAN and *count = 0 if none does. For placing a tyre over a settled bed. */
int dem_bed_top(const dem_state *s, const double lo[2], const double hi[2], double percentile,
                double *top, int *count, proto_err *err);
/* The same over n grains' centres x [n*3] and radii r [n] (liggghts_dem's,
 * gathered); dem_bed_top is this over the state's grains. */
int dem_bed_top_of(const double *x, const double *r, int n, const double lo[2], const double hi[2],
                   double percentile, double *top, int *count, proto_err *err);
/* The x-y box [lo, hi] of n points x [n*3]: the coupled surface's footprint
 * the participants take bed_top under; the whole plane when n == 0. */
void dem_footprint(const double *x, int64_t n, double lo[2], double hi[2]);
/* Where a surface (nodes sx [n_nodes*3], triangles tri [n_tri*3]) lowered
 * straight down first touches one of ng grains (x [ng*3], r [ng]): the height
 * its lowest node has then (*low_at_touch; NAN and *count = 0 if no grain
 * lies under it; *count: the grains under it). Conservative by at most one
 * grid cell (the largest radius) of surface slope (dem_bed_touch.c). What
 * the participants report as `bed_top` when the welcome brought a surface. */
int dem_bed_touch_of(const double *x, const double *r, int ng, const double *sx, int n_nodes,
                     const int32_t *tri, int n_tri, double *low_at_touch, int *count,
                     proto_err *err);
/* What a dem participant reports as `bed_top` in its ready, one rule for
 * dem_server and liggghts_dem: with a surface (n_nodes, n_tri > 0) where it
 * first touches a grain (dem_bed_touch_of), without one the
 * DEM_BED_TOP_PERCENTILE of all grain tops; NAN and *count = 0 if none. */
int dem_bed_ready_top(const double *x, const double *r, int ng, const double *sx, int n_nodes,
                      const int32_t *tri, int n_tri, double *top, int *count, proto_err *err);
/* The percentile reported as `bed_top` without a surface. */
#define DEM_BED_TOP_PERCENTILE 95.0

/* Allocates the model's grain arrays for n grains (zeroed). */
int dem_model_alloc_grains(dem_model *m, int n, proto_err *err);

#endif
