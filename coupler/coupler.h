/* coupler.h — cosim's launcher, coupler loop, scenarios, output and monitor
 * bus (prefix cpl_). The `cosim` CLI is cpl_main(); the rest is exposed for
 * tests that want a scene's core keys or a scenario in-process. */
#ifndef COSIM_COUPLER_H
#define COSIM_COUPLER_H

#include "proto/proto.h"

#define CPL_MAX_PROCS 4
#define CPL_PATH_LEN 512

typedef enum { CPL_ROLE_DEM, CPL_ROLE_FEM, CPL_ROLE_BLOCK } cpl_role;

typedef struct cpl_process {
  char name[PROTO_NAME_LEN]; /* key under "processes"; also the role */
  cpl_role role;
  char exec[CPL_PATH_LEN];     /* as written in the config */
  char resolved[CPL_PATH_LEN]; /* absolute path found by cpl_resolve_exec */
  const cJSON *section;        /* processes.<name> (owned by the scene's root) */
} cpl_process;

typedef enum { CPL_SCN_NONE, CPL_SCN_TIRE_TRAVEL, CPL_SCN_INDENTATION } cpl_scenario_kind;
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
  double slip;            /* s in v = omega R (1 - s) */
  double omega;           /* rad/s during travel */
  double radius;          /* m, rolling radius R */
  /* indentation (block): d_road(t), positive = towards the block */
  cpl_profile profile;
  double depth;           /* m: final (linear/quadratic) or held depth */
  double ramp_time;       /* s: time to reach depth */
  double hold_time;       /* s: load-hold-unload hold */
  double amplitude;       /* m: sinusoidal amplitude about `depth` */
  double frequency;       /* Hz: sinusoidal */
  double road_mass;       /* kg: force-driven road body */
  double road_force;      /* N: external force pushing the road (force mode) */
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
  int64_t bus_hwm;
  double handshake_timeout, step_timeout; /* s */
  char attach_endpoint[CPL_PATH_LEN];
  cpl_scenario scenario;
  int nprocs;
  cpl_process procs[CPL_MAX_PROCS];
} cpl_scene;

/* Loads and validates the core keys (everything but the inside of each
 * processes.<name> section, which the participant validates itself). */
int cpl_scene_load(cpl_scene *s, const char *path, int nset,
                   char *const *sets, proto_err *err);
void cpl_scene_free(cpl_scene *s);
/* Finds a participant's executable: a path with '/' as given, else next to
 * the cosim binary, else on PATH. Fills p->resolved. */
int cpl_resolve_exec(cpl_process *p, proto_err *err);
/* Runs `<exec> --check-config -` on each section. */
int cpl_check_processes(cpl_scene *s, proto_err *err);

/* Scenario kinematics. Rim frame at time t: rotation R (row-major 3x3),
 * centre c, angular velocity w, velocity v. `phase` is advanced by
 * cpl_scenario_update from the measured vertical load. */
typedef struct cpl_rim {
  int travelling;   /* 0 sinkage, 1 travel */
  double angle;     /* rad about +y */
  double c[3], v[3], w[3], R[9];
} cpl_rim;
void cpl_rim_init(cpl_rim *rim, const cpl_scenario *s);
/* Advances the rim by dt given the vertical load (N, +z on the tire). */
void cpl_rim_advance(cpl_rim *rim, const cpl_scenario *s, double dt,
                     double vertical_load);
/* Prescribed road displacement at t (m); NAN for force-driven mode. */
double cpl_road_displacement(const cpl_scenario *s, double t);

/* `cosim` command line. */
int cpl_main(int argc, char **argv);

#endif
