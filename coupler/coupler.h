/* coupler.h — cosim's launcher, coupler loop, scenarios, output and monitor
 * bus (prefix cpl_). The `cosim` CLI is cpl_main(); the rest is exposed for
 * tests that want a scene's core keys or a scenario in-process. */
#ifndef COSIM_COUPLER_H
#define COSIM_COUPLER_H

#include "proto/proto.h"

#define CPL_MAX_PROCS 16
#define CPL_PATH_LEN 512
#define CPL_MAX_ARGV 16 /* exec as a list: launcher prefix + participant */
/* The coupler's own name in results.h5 (/coupler/...) and on the bus
 * ("coupler.progress"): no process may take it. */
#define CPL_RESERVED_NAME "coupler"

/* One process of the scene. Its role is not part of the scene: the process
 * says it in its hello (names are free). */
typedef struct cpl_process {
  char name[PROTO_NAME_LEN]; /* key under "processes" */
  int argc;                  /* exec: one string, or a list (launcher prefix,
                                e.g. mpirun -np 2, then the participant) */
  const char *argv[CPL_MAX_ARGV]; /* as written (strings owned by the scene) */
  char exec[CPL_PATH_LEN];        /* argv joined by spaces, for messages */
  /* cpl_resolve_exec: argv[0] as an absolute path; and the participant (the
   * last element) next to the cosim binary if it is there, else as given */
  char resolved[CPL_PATH_LEN];
  char participant[CPL_PATH_LEN];
  const cJSON *section; /* processes.<name> (owned by the scene's root) */
} cpl_process;

/* coupling.scheme (PROTOCOL.md "Schemes") */
typedef enum { CPL_SCHEME_SERIAL, CPL_SCHEME_PARALLEL, CPL_SCHEME_IMPLICIT } cpl_scheme;
typedef enum { CPL_ACCEL_IQN_ILS, CPL_ACCEL_AITKEN, CPL_ACCEL_CONSTANT } cpl_accel_kind;

/* coupling.implicit: iterate each step until the interface fields stop
 * changing (Degroote et al. 2009; docs/coupling-schemes.md §3). */
typedef struct cpl_implicit {
  double tolerance;        /* relative change per field */
  int64_t max_iterations;  /* per step */
  cpl_accel_kind acceleration;
  double relaxation;       /* constant omega; Aitken's first; IQN's initial step */
  int64_t reuse;           /* IQN-ILS: past steps whose columns are kept */
  int64_t max_columns;     /* IQN-ILS */
  double filter;           /* IQN-ILS QR2 limit (Haelterman et al. 2016) */
} cpl_implicit;

typedef enum {
  CPL_SCN_NONE, CPL_SCN_TIRE_TRAVEL, CPL_SCN_INDENTATION,
  CPL_SCN_TIRE_ROAD /* the tyre rolls on a road: tread blocks (role lug) under its lugs */
} cpl_scenario_kind;
/* tire_travel and tire_road: the rim sinks, then travels (same keys and rigs). */
static inline int cpl_scenario_rolls(cpl_scenario_kind k) {
  return k == CPL_SCN_TIRE_TRAVEL || k == CPL_SCN_TIRE_ROAD;
}
/* scenario.rig: what holds the rim during travel: its height frozen and its
 * speed set (kinematic), the height a degree of freedom carrying the load
 * (load), or that and the carriage free along the travel against a ramped
 * resistive force, the wheel at a fixed omega (dbp: the drawbar-pull rig) */
typedef enum { CPL_RIG_KINEMATIC, CPL_RIG_LOAD, CPL_RIG_DBP } cpl_rig;
/* dbp rig: the running averages are kept as this many sub-sums of the
 * window (no per-step history): the window averaged is the scene's to
 * within 1/CPL_DBP_BINS of it. */
#define CPL_DBP_BINS 32
/* dbp rig defaults (Project Chrono's ChVehicleCosimDBPRig: 0.1 s filter
 * window; its force ramp begins after 0.2 s + 0.5 s of the wheel's spin-up,
 * here the wheel turns from the travel start, so the hold is the 0.2 s). */
#define CPL_DBP_WINDOW 0.1
#define CPL_DBP_HOLD 0.2
/* The dbp rig's row (cpl_dbp_row) of /coupler/dbp: phase (0 sinkage, 1 hold, 2 ramp), the
 * carriage's speed, the resistive force (mean over the step), the slip,
 * and the running means over scenario.dbp_window of T_H, T_R, T_P, the
 * vertical load, the resistive force and the slip (the traction row of the
 * same step added to the rim's sums: call once per step). */
enum { CPL_DBP_T, CPL_DBP_PHASE, CPL_DBP_SPEED, CPL_DBP_FORCE, CPL_DBP_SLIP,
       CPL_DBP_TH_AVG, CPL_DBP_TR_AVG, CPL_DBP_TP_AVG, CPL_DBP_LOAD_AVG, CPL_DBP_FORCE_AVG,
       CPL_DBP_SLIP_AVG, CPL_N_DBP };
#define CPL_DBP_NAVG (CPL_N_DBP - CPL_DBP_TH_AVG)
/* The load rig's default mass is sinkage_force / this (dead-weight tester). */
#define CPL_STANDARD_GRAVITY 9.81
/* Default clearance of the lowest tread node above the bed for "auto". */
#define CPL_AUTO_GAP 0.002
/* Height of the lowest tread node while an "auto" rim waits for the bed. */
#define CPL_AUTO_PARK_Z 1000.0
/* The load rig is refused above this omega dt (semi-implicit Euler on the
 * soil's spring is unstable at 2: half of that). */
#define CPL_RIG_MAX_OMEGA_DT 1.0

typedef enum {
  CPL_PROFILE_LINEAR, CPL_PROFILE_QUADRATIC, CPL_PROFILE_LOAD_HOLD_UNLOAD,
  CPL_PROFILE_SINUSOIDAL, CPL_PROFILE_FORCE
} cpl_profile;

/* The scenario: what the coupler prescribes (seed 000 §5: sinkage then
 * travel at slip; seed 002 app. C.3/fig. 40/49: road indentation histories). */
typedef struct cpl_scenario {
  cpl_scenario_kind kind;
  /* tire_travel: rim rotates about +y, travels along +x, sinks along -z */
  double rim_center[3];   /* m, at t = 0 */
  double sinkage_velocity;/* m/s */
  double sinkage_force;   /* N: vertical load that ends the sinkage phase */
  double sinkage_depth;   /* m: or the sinkage below the start that ends it (0: none) */
  double slip;            /* s in v = omega R (1 - s) */
  double omega;           /* rad/s during travel */
  double spin_up;         /* s: kinematic rig, omega and v rise linearly from 0 (0: at once) */
  double radius;          /* m, rolling radius R */
  int rim_auto;           /* rim_center[2] is "auto": set from the dems' bed_top */
  double auto_gap;        /* m: lowest tread node above the bed top ("auto") */
  cpl_rig rig;
  double rig_mass;        /* kg (load rig) */
  double rig_damping;     /* N s/m (load rig), against the ground; default 0 */
  /* dbp rig: carriage of carriage_mass along +x, m x'' = F_x - F_res(tau),
   * tau the time since travel start: F_res = dbp_force_start while tau <
   * dbp_hold, then dbp_force_start + dbp_force_rate (tau - dbp_hold) */
  double carriage_mass;   /* kg; default rig_mass */
  double dbp_hold;        /* s */
  double dbp_force_start; /* N (negative: a push) */
  double dbp_force_rate;  /* N/s */
  double dbp_window;      /* s: running averages of the dbp series */
  /* indentation (block): d_road(t), positive = towards the block */
  cpl_profile profile;
  double depth;           /* m: final (linear/quadratic) or held depth */
  double ramp_time;       /* s: time to reach depth */
  double hold_time;       /* s: load-hold-unload hold */
  double amplitude;       /* m: sinusoidal amplitude about `depth` */
  double frequency;       /* Hz: sinusoidal */
  double road_mass;       /* kg: force-driven road body */
  double road_force;      /* N: external force pushing the road (force mode) */
  /* tire_road (scenario_lugs.c): the road plane z = road_z; a lug whose face
   * comes within lug_engage of it is given a lug process; surface nodes off
   * the lug faces below it are pushed up by road_penalty (N/m) per node */
  double road_z;          /* m */
  double lug_engage;      /* m */
  double lug_tolerance;   /* m: a lug-face node lies this close to the outer radius */
  double road_penalty;    /* N/m */
  int lug_flat;           /* lug_face "flat": each block takes its face as flat at the
                             face's mean height, its force back at its centre of
                             pressure; "shaped" (0, the default): the face's shape
                             under each cell, the cells' forces back (scenario_lugs.c) */
} cpl_scenario;

typedef struct cpl_scene {
  cJSON *root; /* the whole config after --set overrides (owned) */
  char source[CPL_PATH_LEN];
  char name[128];
  double dt, t_end;
  int64_t n_steps;
  char output_dir[CPL_PATH_LEN];
  int64_t output_every;
  char bus_monitor[CPL_PATH_LEN]; /* public SUB endpoint, "" = no bus */
  char bus_snapshots[CPL_PATH_LEN]; /* the snapshot stream's endpoint */
  int64_t bus_hwm;          /* messages a slow monitor may have queued */
  int64_t bus_snapshot_hwm; /* snapshots a slow monitor may have queued */
  /* deadlines, s, on the coupler's pause-free clock (PROTOCOL.md "Liveness") */
  double hello_timeout;     /* started -> hello */
  double heartbeat_timeout; /* silence of a participant that sends heartbeats */
  double handshake_timeout; /* welcome -> ready without new progress */
  double step_timeout;      /* request -> reply without new progress */
  int64_t checkpoint_every; /* steps; 0: no checkpoints */
  int64_t checkpoint_keep;  /* the newest this many are kept */
  int curve;                /* security.curve */
  char attach_endpoint[CPL_PATH_LEN]; /* port 0: any free port */
  cpl_scheme scheme;
  /* coupling.transport: how arrays travel to same-host participants
   * (PROTOCOL.md "Shared memory"): shared memory when it works, or always
   * the socket */
  enum { CPL_TRANSPORT_AUTO, CPL_TRANSPORT_SOCKET } transport;
  int sparse;               /* coupling.sparse: only the surface near grains travels */
  /* coupling.affinity: "handoff" puts the coupler's loop and each OpenMP
   * participant's main thread on one core (affinity.c) */
  enum { CPL_AFFINITY_NONE, CPL_AFFINITY_HANDOFF } affinity;
  cpl_implicit implicit;
  cpl_scenario scenario;
  int nprocs;
  cpl_process procs[CPL_MAX_PROCS];
} cpl_scene;

/* Loads and validates the core keys (everything but the inside of each
 * processes.<name> section, which the participant validates itself).
 * Whether the processes' roles fit the scenario is known only after their
 * hellos (cpl_check_roles). */
int cpl_scene_load(cpl_scene *s, const char *path, int nset,
                   char *const *sets, proto_err *err);
/* The same from parsed JSON (taken over: cpl_scene_free frees it); source
 * names it in errors. */
int cpl_scene_from_json(cpl_scene *s, cJSON *json, const char *source,
                        int nset, char *const *sets, proto_err *err);
void cpl_scene_free(cpl_scene *s);
/* Finds a process's executable (argv[0]): a path with '/' as given, else
 * next to the cosim binary, else on PATH. Fills p->resolved and
 * p->participant (the last element: resolved the same way when it is next
 * to cosim or given with a '/', else passed on as written). */
int cpl_resolve_exec(cpl_process *p, proto_err *err);
/* Runs `<participant> --check-config - --name NAME` on each section (the
 * last element of exec alone: a check needs no launcher). */
int cpl_check_processes(cpl_scene *s, proto_err *err);
/* The scenario's needs against the roles the processes announced:
 * tire_travel needs a dem and exactly one fem, indentation a block; one
 * coupled surface (at most one fem). roles[i] is process i's role. */
int cpl_check_roles(const cpl_scene *s, const proto_role *roles, proto_err *err);
const char *cpl_scheme_name(cpl_scheme s);
/* The section as a participant sees it (welcome, --check-config): as in the
 * scene, except that "exec" is one string, the participant (its last
 * element), whatever launcher prefix the scene gives. Caller frees. */
cJSON *cpl_section_for_participant(const cpl_process *p);

/* Scenario kinematics. Rim frame at time t: rotation R (row-major 3x3),
 * centre c, angular velocity w, velocity v. `phase` is advanced by
 * cpl_scenario_update from the measured vertical load. */
typedef struct cpl_rim {
  int travelling;   /* 0 sinkage, 1 travel */
  double angle;     /* rad about +y */
  double c[3], v[3], w[3], R[9];
  double c0[3];     /* the centre at t = 0 (an "auto" height resolved) */
  /* load rig: the soil's stiffness from the sinkage phase, by least squares
   * of the load over the height while it rose from W/2 to W (W =
   * sinkage_force): n, sums of dz, F, dz², dz F with dz = z - z_fit */
  double z_touch;   /* height at the first step with load > 0 (NAN before) */
  double z_fit;     /* height where the fit began (NAN before) */
  double fit[5];
  double stiffness; /* N/m measured (0: unknown) */
  double mass, damping; /* kg, N s/m in use during travel */
  /* dbp rig */
  double travel_time;     /* s since travel started (the ramp's clock tau) */
  double resistive_force; /* N: F_res's mean over the last step (impulse / dt) */
  /* running averages (cpl_dbp_row): sums of CPL_DBP_NAVG quantities in a
   * ring of CPL_DBP_BINS bins of avg_n[0] steps each; avg_n[1] steps in
   * the current bin, avg_n[2] bins complete, avg_n[3] the ring's head */
  double avg_bins[CPL_DBP_BINS][CPL_DBP_NAVG];
  double avg_part[CPL_DBP_NAVG];
  int64_t avg_n[4];
} cpl_rim;
void cpl_rim_init(cpl_rim *rim, const cpl_scenario *s);
/* Puts the rim (its frame the identity, at t = 0) at the height where the
 * lowest of the n surface nodes x0 (rim frame) is at z (m); n = 0: the rim
 * centre at z. rim_center [x, y, "auto"] (README "Scenario keys"): z is the
 * highest settled bed top + scenario.auto_gap. */
void cpl_rim_place(cpl_rim *rim, const double *x0, int64_t n, double z);
/* Advances the rim by dt given the grains' force on the tread (N, the sum
 * over its nodes of the step's impulse / dt; force[2] the vertical load).
 * Fails (err names the key) when the load rig would not be stable. */
int cpl_rim_advance(cpl_rim *rim, const cpl_scenario *s, double dt,
                    const double force[3], proto_err *err);
/* dbp rig: the mean of F_res (N) over the travel-clock interval [a, b] (s),
 * the exact integral of the hold-then-ramp law over it / (b - a). */
double cpl_dbp_resistance(const cpl_scenario *s, double a, double b);
/* slip 1 - v_x / (omega R) of the rim (0 while it does not turn) */
double cpl_rim_slip(const cpl_rim *rim, const cpl_scenario *s);
/* Prescribed road displacement at t (m); NAN for force-driven mode. */
double cpl_road_displacement(const cpl_scenario *s, double t);

/* ---- tire_road (scenario_lugs.c): the lugs of the tread and the blocks
 * that serve them. A lug face is a connected set of surface triangles whose
 * nodes all lie on the tread's outer radius (rim frame: axle along y); its
 * nodes carry area-lumped weights (a third of each triangle's area). */
typedef struct cpl_lugs {
  int n;                /* lugs */
  int32_t *start;       /* [n+1]: lug j's nodes are node[start[j] .. start[j+1]) */
  int32_t *node;        /* surface node indices */
  double *weight;       /* m², per entry of node */
  double *area;         /* [n] m² */
  uint8_t *on_lug;      /* [n_nodes]: 1 for a node of a lug face */
  double outer_radius;  /* m */
  /* the lug processes' block grid on each face (cpl_lugs_map): cell c of lug
   * j lies on the face triangle of the nodes cell_node[3 (j cells + c) + 0..2]
   * with the barycentric weights cell_w[...]; nodes -1: beyond the face */
  int cells;            /* the grid's cells (0 before cpl_lugs_map) */
  int32_t *cell_node;   /* [n][cells][3] surface node indices */
  double *cell_w;       /* [n][cells][3] */
  double covered;       /* the smallest share of a lug's cells on its face */
  double beyond;        /* the largest share of a face's area (in the tangent plane)
                           that no cell covers: 1 - cells on it x cell area / area */
} cpl_lugs;
/* Finds the lug faces of a surface (x0 rim frame, tri); tol: how close to
 * the outer radius a face node lies (m). -1 with err if none is found. */
int cpl_lugs_find(const double *x0, int64_t n_nodes, const int32_t *tri, int64_t n_tris,
                  double tol, cpl_lugs *L, proto_err *err);
void cpl_lugs_free(cpl_lugs *L);
/* Lug j's approach towards the road plane z = road_z (m, positive =
 * indentation): road_z minus the area-weighted mean height of its face
 * nodes at the world positions x. */
double cpl_lug_approach(const cpl_lugs *L, int j, const double *x, double road_z);
/* The approach of lug j's deepest face node (m): road_z minus their lowest
 * height. A shaped face (scenario.lug_face) is engaged and released by it. */
double cpl_lug_reach(const cpl_lugs *L, int j, const double *x, double road_z);
/* Lug j's area centre, world (x, y) (m), at the positions x. */
void cpl_lug_centre(const cpl_lugs *L, int j, const double *x, double c[2]);
/* Adds to f (nodal forces, [n, 3]) a block's normal force F (N, +z, the
 * road pushing the face up) spread over lug j's nodes, the weights w_i =
 * (a_i/A)(1 + b . (p_i - p_c)) with p_i the nodes' world (x, y), p_c their
 * area-weighted centre and b such that sum w_i (p_i - p_c) = cop: the nodal
 * forces sum to F ez and have its moment about p_c (F at p_c + cop). */
void cpl_lug_spread(const cpl_lugs *L, int j, const double *x, double F, const double cop[2],
                    double *f);
/* Lays the block grid (cell centres cell_xy [cells][2] about the grid's
 * centre, x along the rolling direction, y along the axle) on every lug face
 * of the surface at rest (x0 rim frame, tri; scenario_lugmap.c): the face's
 * nodes are placed in the plane tangent at its area centre (u along the
 * tread's circumference, the direction that is +x when the face is at the
 * bottom; v along the axle), and each cell takes the face triangle it falls
 * in there. -1 with err if out of memory. */
int cpl_lugs_map(cpl_lugs *L, const double *x0, const int32_t *tri, int64_t n_tris,
                 const double *cell_xy, int cells, proto_err *err);
#define CPL_LUG_BEYOND_WARN 0.05 /* a face's area share beyond the grid that warns */
#define CPL_LUG_OFF_FACE (-1.0) /* m: the base offset of a cell beyond its face's edge:
                                   no rubber there, it never meets the road */
/* Lug j's shape under the cells at the world positions x (m, + = towards
 * the road): the face's area-weighted mean height minus the face's height
 * under each cell (linear on its triangle); CPL_LUG_OFF_FACE beyond it. */
void cpl_lug_base(const cpl_lugs *L, int j, const double *x, double *base);
/* Adds each cell's normal force (N, +z) to f ([n, 3]) on the nodes of the
 * triangle under it by its barycentric weights: the transpose of
 * cpl_lug_base's interpolation, so the nodal forces sum to the cells' and
 * have their moment (each cell's force where the face is under it). A cell
 * beyond the face carries none (CPL_LUG_OFF_FACE keeps it off the road);
 * returns the sum of the forces spread. */
double cpl_lug_spread_cells(const cpl_lugs *L, int j, const double *cell_force, double *f);
/* Which lug process serves which lug (-1: none), and reset[s]: process s
 * took a new lug this step (its block starts afresh). */
#define CPL_LUG_IDLE_D (-1.0) /* m: the approach sent to a process with no lug (far) */
#define CPL_LUG_MAX_LUGS 512  /* lugs on one tread (the generated one has 32 to 128) */
typedef struct cpl_lug_slots {
  int n;                  /* lug processes */
  int lug[CPL_MAX_PROCS];
  int reset[CPL_MAX_PROCS];
  double ahead[CPL_MAX_PROCS]; /* m: its face's centre ahead of the rim centre (x) */
  int64_t handovers;      /* lugs taken so far */
} cpl_lug_slots;
/* One step's assignment from each lug's approach d[j] (m) and each process's
 * last force (N): a process whose lug has moved out beyond engage with no
 * force left is freed; every lug within engage of the road without a
 * process takes the lowest free one (nearest lug first). -1 with err when
 * more lugs are within engage than there are processes. */
int cpl_lug_assign(cpl_lug_slots *S, int n_lugs, const double *d, double engage,
                   const double *force, proto_err *err);
/* The road's penalty on the nodes off the lug faces: f_z += k (road_z - z)
 * for each node below the plane (N); returns their sum. */
double cpl_road_penalty(const cpl_lugs *L, const double *x, int64_t n, double road_z, double k,
                        double *f);

/* The road body of the force-driven indentation (seed 002 fig. 49):
 * road_mass pushed by road_force against the contact force. */
typedef struct cpl_road {
  double d, v, a;     /* displacement, velocity, acceleration at t_{k-1} */
  double force_last;  /* contact force of the last step */
} cpl_road;
/* Explicit (serial, parallel): the force of the last step moves the body
 * from t_{k-1} to t_k, v += dt a, d += dt v (symplectic Euler, equal to
 * central differences); returns d at t_k. */
double cpl_road_explicit(cpl_road *road, const cpl_scenario *s, double dt);
/* Implicit: the trapezoidal rule (Newmark average acceleration, beta =
 * 1/4, gamma = 1/2) with the contact force of t_k: *v, *a at t_k; returns
 * d at t_k; road (t_{k-1}) is not changed. */
double cpl_road_trapezoid(const cpl_road *road, const cpl_scenario *s, double dt,
                          double force, double *v, double *a);

/* Traction of seed 000 §5 from the grains' forces F on the tread nodes at
 * positions X (n nodes, [n,3] world): T_H the sum of the positive x forces
 * (along travel), T_R of the negative ones (against it), T_P = T_H - |T_R|,
 * the vertical load (sum of z), the sinkage c0_z - c_z of the rim, and the
 * torque about the axle (y of sum (x - c) x f). */
enum { CPL_TR_T, CPL_TR_TH, CPL_TR_TR, CPL_TR_TP, CPL_TR_LOAD, CPL_TR_SINK, CPL_TR_TORQUE,
       CPL_N_TRACTION };
void cpl_traction(const double *F, const double *X, int64_t n, const cpl_rim *rim, double t,
                  double row[CPL_N_TRACTION]);
/* Fills row (see CPL_DBP_*) and adds the step's values to the running sums. */
extern const char *const cpl_dbp_columns[CPL_N_DBP];
void cpl_dbp_row(cpl_rim *rim, const cpl_scenario *s, double dt,
                 const double traction[CPL_N_TRACTION], double row[CPL_N_DBP]);

/* `cosim` command line. */
int cpl_main(int argc, char **argv);

#endif
