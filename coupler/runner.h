/* runner.h — the state of one coupled run (cpl_runner: its const plan, its
 * per-step data, its session) and the functions of the files that share it:
 * run.c (setup, handshake, teardown), contract.c (the fields, the order of
 * the step, the role table bound to the fields), loop.c (the orchestrator)
 * and its stages: schedule.c (exchange), scenario_step.c (scenario),
 * implicit.c with accel.c (the implicit scheme's repeats), record.c,
 * liveness.c, timing.c and checkpoint.c. Internal to the coupler. */
#ifndef COSIM_COUPLER_RUNNER_H
#define COSIM_COUPLER_RUNNER_H

#include <stdio.h>

#include "internal.h"

/* ------------------------------------------------------------ fields
 * What the coupler holds between the processes (PROTOCOL.md "Schedule"):
 * the coupled surface, the rim frame and the road. Each field has its
 * current value (`cur`, what requests read unless the scheme points them
 * elsewhere) and an output buffer (`out`, where replies land, summed over
 * the processes that give it); a stage's outputs are committed by swapping
 * the two, so that a buffer still being sent is never overwritten. */
typedef enum cpl_field_id {
  CPL_F_SURF_X,     /* [n,3] surface positions (t_{k-1} in requests) */
  CPL_F_SURF_V,     /* [n,3] surface velocity over the step */
  CPL_F_SURF_FORCE, /* [n,3] force of the grains on the surface nodes */
  CPL_F_RIM_R,      /* [3,3] the rim frame at t_k (scenario) */
  CPL_F_RIM_C,
  CPL_F_RIM_OMEGA,
  CPL_F_RIM_V,
  CPL_F_ROAD_D,     /* [1] road displacement at t_k (scenario / road body) */
  CPL_F_ROAD_FORCE, /* [1] force of the blocks on the road */
  CPL_F_LUG_D,      /* [P] per lug process: its lug face's approach (tire_road) */
  CPL_F_LUG_FORCE,  /* [P] per lug process: its force on the face */
  CPL_F_LUG_COP,    /* [P,2] per lug process: its centre of pressure */
  CPL_F_LUG_ORIGIN, /* [P,2] per lug process: where its lug's face is (world x, y) */
  CPL_F_LUG_BASE,   /* [P,c] per lug process: its face's shape under its cells */
  CPL_F_LUG_CELL_FORCE, /* [P,c] per lug process: its cells' forces */
  CPL_N_FIELDS
} cpl_field_id;

typedef struct cpl_field {
  const char *name;
  int64_t len;      /* doubles */
  double *cur, *out;
  int given;        /* outputs of this step: number of processes that gave it */
} cpl_field;

/* A field as the contract declares it: its name and shape (dims as the role
 * table's: PROTO_DIM_NODES for the surface's n). The shipped fields are those
 * of cpl_field_id; a contract may declare more (a new role's), up to
 * CPL_MAX_FIELDS, with ids from CPL_N_FIELDS on. */
#define CPL_MAX_FIELDS (CPL_N_FIELDS + 4)
typedef struct cpl_field_spec {
  const char *name;
  int ndim;
  int64_t dims[2];
  int per_process; /* one row of dims per process of the role that binds it:
                      the process's own value, never summed (lug.*) */
} cpl_field_spec;

/* A role-table row bound to a field (contract.c): requests read in[field];
 * replies are summed (several processes of one role: forces add) or copied
 * into out. */
typedef struct cpl_binding {
  proto_role role;
  proto_msg_kind msg; /* PROTO_MSG_STEP (request) or PROTO_MSG_DONE (reply) */
  const char *array;
  int field;          /* a cpl_field_id, or a further field of the contract */
  int sum;
  const proto_array_spec *spec; /* its row */
  const proto_array_spec *index; /* its sparse form's "<array>_index" row, or NULL */
} cpl_binding;

/* The serial scheme's step as the contract orders it: a stage runs a
 * coupler action (role < 0) or every process of a role; parallel and
 * implicit take the same rows, actions first, in one stage (schedule.c). */
typedef enum cpl_action {
  CPL_ACT_NONE,
  CPL_ACT_RIM,  /* advance the rim frame by the scenario (uses the vertical load) */
  CPL_ACT_ROAD, /* road displacement of t_k: profile, or the road body */
  CPL_ACT_LUG,  /* tire_road: lugs to lug processes, each face's approach */
  CPL_ACT_LUG_FORCE /* tire_road: the lug processes' forces (and the road's penalty
                       elsewhere) onto the surface nodes */
} cpl_action;
typedef struct cpl_stage_row {
  int stage;
  int role;           /* a proto_role, or -1: the coupler's action */
  cpl_action action;
} cpl_stage_row;

/* The coupling contract: the fields, every step/done row of the role table
 * bound to one, and the order of the step — built once before the run starts. */
#define CPL_MAX_BINDINGS 32
#define CPL_MAX_STAGE_ROWS 12
#define CPL_MAX_ROLES 8 /* the shipped roles (PROTO_N_ROLES) and a newcomer's */
typedef struct cpl_contract {
  int n;
  cpl_binding b[CPL_MAX_BINDINGS];
  int nfields;
  cpl_field_spec field[CPL_MAX_FIELDS];
  int field_role[CPL_MAX_FIELDS]; /* the role of a per-process field's rows */
  int nstages;
  cpl_stage_row stage[CPL_MAX_STAGE_ROWS];
} cpl_contract;

/* contract.c: binds the table's step/done rows t[0..n) to the shipped fields
 * and takes the shipped order of the step; -1 with a message naming the row
 * (or the field no row binds). */
int cpl_contract_build(cpl_contract *c, const proto_array_spec *t, int n, proto_err *err);
/* The same with further fields (ids CPL_N_FIELDS, ...) and the step's order
 * given: a new role's contract (tests/coupler/test_contract.c). */
int cpl_contract_build_with(cpl_contract *c, const proto_array_spec *t, int n,
                            const cpl_field_spec *more, int nmore,
                            const cpl_stage_row *stages, int nstages, proto_err *err);
/* The shipped order of the serial step (cpl_contract_build's). */
const cpl_stage_row *cpl_contract_stages(int *n);
int cpl_field_parse(const char *name); /* a shipped field, -1 if unknown */

/* ------------------------------------------------------------ schedule
 * The step as data: exchanges in order. All requests of one stage are sent
 * before any reply is awaited (processes of a stage compute at the same
 * time); a coupler action runs before the stage's requests. */
typedef struct cpl_exchange {
  int stage;
  int peer;          /* process index, or -1: a coupler action */
  cpl_action action;
} cpl_exchange;

#define CPL_MAX_EXCHANGES (CPL_MAX_PROCS + 4)

/* Sparse exchange with one process (schedule.c, PROTOCOL.md "Sparse
 * exchange"): what its last done said and the buffers its requests are
 * gathered into (allocated with the fields, none in the loop). */
typedef struct cpl_sparse {
  int takes_force;      /* fem: its ready said sparse (nodal_force may come sparse) */
  int has_reach;        /* dem: its last done gave a reach box */
  int use_reach;        /* the box this step's requests choose x_index by */
  double reach[6], reach_use[6]; /* [lo xyz, hi xyz], m */
  double reach_speed, speed_use; /* s: grow reach by this times the largest node speed (0: not) */
  int32_t *index;       /* [n] the nodes sent */
  double *rows[2];      /* [n*3] their rows (x and v, or the force) */
  double *dense;        /* [n*3] a sparse reply, expanded */
  uint8_t *mark;        /* [n] node chosen */
  /* bytes of the [n, ...] arrays to it and from it, and what dense would be */
  double out_bytes, out_dense, in_bytes, in_dense;
} cpl_sparse;

typedef struct cpl_peer {
  cpl_process *proc;
  proto_role role;   /* from its hello */
  int rank;          /* its place among the processes of its role (scene order) */
  int connected;     /* hello received */
  int stopped;       /* bye received or known gone */
  int rollback;      /* ready.rollback: it can repeat a step */
  proto_dims dims;   /* the role table's n, m for this process */
  proto_msg reply;   /* its last reply (kept for output until the next step) */
  /* timing of the current step (timing.c) */
  double t_sent, busy, compute;
  /* liveness (liveness.c), times on the coupler's watch clock */
  int pid;           /* from its hello */
  double hb_s;       /* the heartbeat interval its hello announced; 0: none */
  double heard;      /* its last message */
  double progressed; /* its last new progress report */
  double progress;   /* fraction it last reported (< 0: unknown) */
  char what[64];     /* what it said it was doing (printable) */
  int shown;         /* progress shown so far (tenths), -1: nothing yet */
  int initialized;   /* its ready arrived */
  cpl_sparse sp;     /* sparse exchange (schedule.c) */
  /* transport (run.c, PROTOCOL.md "Shared memory"): same host (its hello's
   * host and boot id are ours), our segment for it and its for us; shm_on
   * once its ready took the offer */
  int same_host;
  proto_shm *shm_out, *shm_in;
  int shm_on;
  int awaited; /* a request went out and its reply has not come (cpl_send) */
  uint64_t shm_sent, shm_posted; /* messages to it through our segment, posted whole
                                    (read at teardown, for the timing table) */
  char shm_why[160]; /* why it keeps the socket, for the schedule printout */
} cpl_peer;

/* The shared surface of the tread: node positions in the rim frame at rest
 * (from the fem's ready) and the triangles. Its world values are fields. */
typedef struct cpl_surface {
  int64_t n_nodes, n_tris;
  double *x0;    /* [n,3] rim frame (owned) */
  int32_t *tri;  /* [m,3] */
} cpl_surface;

/* The plan of a run: what the handshake fixes and no step changes — the
 * contract, who has which role, the coupled surface and the schedule. Built
 * by run.c (contract before the processes start, the rest after their
 * ready); read-only from the first step on. */
typedef struct cpl_plan {
  cpl_contract contract; /* the role table bound to the fields (contract.c) */
  int n_of_role[CPL_MAX_ROLES];
  int fem;               /* the process giving the surface, or -1 */
  cpl_surface surf;
  int nex;               /* the step's exchanges in order (schedule.c) */
  cpl_exchange ex[CPL_MAX_EXCHANGES];
  /* tire_road: the lug faces of the surface and the columns of /coupler/lugs */
  cpl_lugs lugs;
  int n_lug_cols;
#define CPL_LUG_COLS 7 /* /coupler/lugs columns per lug process */
  const char **lug_cols;
  char *lug_col_text;
} cpl_plan;

/* The data of a run (as MuJoCo's mjData beside mjModel): what the steps
 * change — the fields and what requests read, the scenario's rim and road,
 * the implicit scheme's iterate and its counters. */
typedef struct cpl_data {
  cpl_field fields[CPL_MAX_FIELDS];
  const double *in[CPL_MAX_FIELDS]; /* what requests send (set by the scheme) */
  cpl_rim rim;
  cpl_road road;
  /* tire_road: who serves which lug, each lug's approach [lugs], the road's
   * penalty force this step (N) */
  cpl_lug_slots lug;
  double *lug_d;
  double *lug_reach; /* [lugs] m: the approach of each face's deepest node (shaped faces) */
  double lug_penalty;
  /* implicit scheme (implicit.c) */
  double *xi, *xt;        /* interface vector: iterate and H(iterate) */
  double *x_start;        /* surface positions at t_{k-1} */
  double *v_dem;          /* secant velocity (d - x_start)/dt the DEM moves at */
  double *f_fem;          /* force the FEM gets: iterate + carried defect */
  double *carry;          /* impulse defect of the last step / dt */
  double road_iter;       /* road force iterate */
  int iterations, converged;
  double residual[3];     /* relative residual per interface field at exit */
  int64_t steps_unconverged;
} cpl_data;

typedef struct cpl_timing cpl_timing;
typedef struct cpl_accel cpl_accel;
typedef struct cpl_ckpt cpl_ckpt;

typedef struct cpl_runner {
  cpl_scene *scene;
  const cpl_run_opts *opts;
  void *ctx, *router;
  cpl_bus *bus;
  cpl_output *out;
  char run_dir[CPL_PATH_LEN];
  char ctl_endpoint[CPL_PATH_LEN];
  cpl_bus_eps bus_eps; /* as bound (port 0 resolved) */
  int n;
  double children_checked; /* cpl_watch time of the last waitpid round (liveness.c) */
  cpl_peer peers[CPL_MAX_PROCS];
  cpl_child children[CPL_MAX_PROCS];
  int nchildren;
  cpl_affinity affinity; /* coupling.affinity, planned before the children start */
  /* the plan: run.c builds it through `draft` during the handshake and
   * seals it (draft = NULL) before the first step; every stage reads it
   * through `plan`, which the compiler keeps read-only */
  const cpl_plan *plan;
  cpl_plan *draft;
  cpl_data data;     /* what changes from step to step */
  /* implicit scheme (implicit.c): the accelerator's history */
  cpl_accel *accel;
  /* timing */
  cpl_timing *timing;
  double wall_start, t_blocked; /* t_blocked: time in receive this step */
  proto_msg inbox; /* receive buffer, swapped into the sender's reply slot */
  int failed_peer; /* index of the participant that failed, or -1 */
  int exit_code;   /* when the kind of failure is not a participant's: 1, 4 */
  proto_err err;
  /* liveness: the watch clock advances only while the coupler looks */
  double watch, watch_wall;
  int strangers;   /* messages from unknown identities, ignored */
  /* output.dir, security, restart */
  int lock_fd;
  cpl_zap *zap;
  cpl_ckpt *ckpt;  /* the checkpoint a restart continues from */
  int64_t k0;      /* the last step done before this run (restart), else 0 */
  int progress_shown; /* tenths of the run shown in a batch log (record.c) */
} cpl_runner;

/* liveness.c: receives the next message from `expect` (a peer index, or -1
 * for any peer), watching the children, their heartbeats, the deadline
 * (timeout_s without news: a progress report restarts it; `key` names it in
 * the message) and Ctrl-C. Heartbeats are taken in passing; messages from
 * unknown identities are logged and ignored. The sender's index goes to
 * *from. Returns -1 with r->err set and r->failed_peer naming the culprit
 * when one can be named. m == NULL: the message lands in the sender's reply
 * slot. */
int cpl_receive(cpl_runner *r, int expect, double timeout_s, const char *key,
                proto_msg *m, int *from);
int cpl_send(cpl_runner *r, int peer, const proto_msg *m);
/* The watch clock (s): advances with the wall clock while the coupler runs,
 * by at most a second at a time, so its own pauses (Ctrl-Z, SIGSTOP) do not
 * count as the participants' silence. */
double cpl_watch(cpl_runner *r);
/* The same with the wall clock given (s): what cpl_watch does with
 * proto_now(); tests drive it with a fake clock. */
double cpl_watch_at(cpl_runner *r, double now);
/* -1 naming the first connected peer that announced heartbeats and has
 * been silent for more than coupling.heartbeat_timeout on the watch clock
 * (now); r->failed_peer set. */
int cpl_check_silence(cpl_runner *r, double now);
/* Copies s into out with anything a terminal would act on replaced. */
void cpl_printable(char *out, size_t cap, const char *s);
/* A hello: its role, pid and heartbeat interval. */
int cpl_take_hello(cpl_runner *r, int from, const proto_msg *m);

/* checkpoint.c (README "Checkpoints and restart") */
/* Writes output.dir/checkpoint_<k>.h5 after step k: every participant's
 * state, the coupler's. Keeps the newest scene.checkpoint_keep. */
int cpl_checkpoint_write(cpl_runner *r, int64_t k);
/* Reads a checkpoint ("latest": the newest in output.dir) and checks that
 * the scene continues it (the keys that decide the results agree; branch:
 * but coupling.scheme and coupling.implicit). */
cpl_ckpt *cpl_checkpoint_read(const char *path, const cpl_scene *s, int branch,
                               proto_err *err);
int64_t cpl_checkpoint_step(const cpl_ckpt *c);
/* Restores the coupler and every participant from r->ckpt (after the
 * handshake and the scheme's set-up, before results.h5 is opened): the
 * coupler's state is checked against this run first (every piece there, of
 * its type and size). */
int cpl_checkpoint_restore(cpl_runner *r);
void cpl_checkpoint_free(cpl_ckpt *c);
/* Removes output.dir's checkpoints (a new results file starts: they belong
 * to the results it replaces). */
int cpl_checkpoint_clear(const char *dir, proto_err *err);

/* schedule.c */
/* The fields of the plan's contract for a surface of n nodes (n may be 0),
 * their buffers allocated. */
int cpl_fields_init(cpl_runner *r, int64_t n, proto_err *err);
void cpl_fields_free(cpl_runner *r);
/* (the contract's order of the step, the processes' roles, scheme) -> (the
 * plan's exchanges in order) */
void cpl_schedule_build(cpl_plan *p, const cpl_peer *peers, int n, cpl_scheme scheme);
/* Prints the schedule ("who gives what to whom"), one line per stage. */
void cpl_schedule_print(const cpl_runner *r, FILE *f);
/* The end-of-run lines of the sparse exchange: per process, the bytes of its
 * surface arrays each way as a share of the dense exchange's. */
void cpl_sparse_print(const cpl_runner *r, FILE *f);
/* Runs the stages of the schedule from `first` to `last`: its actions (if
 * actions), all requests of a stage, then all its replies; outputs are
 * summed/copied into the fields' out buffers in exchange order
 * (deterministic), then, if commit, swapped in. */
int cpl_run_stages(cpl_runner *r, int first, int last, int64_t k, int iteration,
                   int output, int commit, int actions);
int cpl_last_stage(const cpl_runner *r);
/* Peer i's step request of step k into m (reset first; m's buffers are
 * reused): the arrays of its role's step rows from the fields data.in
 * points at, dense or in their sparse form. */
void cpl_request_build(cpl_runner *r, int i, int64_t k, int iteration, int output,
                       proto_msg *m);
/* The replies already in the peers' reply slots of a stage into the fields'
 * out buffers (summed or copied in exchange order), swapped in if commit. */
void cpl_stage_take(cpl_runner *r, int stage, int commit);
/* Sets r->in to the fields' current values (serial, parallel). */
void cpl_inputs_current(cpl_runner *r);
void cpl_field_commit(cpl_runner *r, int id);

/* scenario_step.c: the scenario's stage. Runs a coupler action for step k
 * (rim frame; road profile or body) into the fields; -1 with r->err. */
int cpl_do_action(cpl_runner *r, cpl_action a, int64_t k);
/* (rim frame at t = 0, surface x0) -> (surface x, rim fields) */
void cpl_fields_from_rim(cpl_runner *r);
/* tire_road, after the fem's surface: its lug faces into the plan (through
 * r->draft), the lug processes' slots and the columns of /coupler/lugs. */
int cpl_lugs_setup(cpl_runner *r);
void cpl_lugs_teardown(cpl_plan *p, cpl_data *d);
/* The sum of the z components of the current surface force (N). */
double cpl_vertical_load(const cpl_runner *r);

/* loop.c, the orchestrator: the scheme's set-up after the handshake; then
 * per step the stages in order — exchange and scenario (schedule.c,
 * scenario_step.c; implicit.c repeats them), record (record.c), timing
 * (timing.c), checkpoint (checkpoint.c); liveness (liveness.c) runs inside
 * every receive. */
int cpl_scheme_init(cpl_runner *r);
int cpl_step_loop(cpl_runner *r);

/* implicit.c: the interface vector [surface x at t_k | surface force | road
 * force (force-driven road only)], and the step that iterates on it. */
enum { CPL_IF_X, CPL_IF_F, CPL_IF_ROAD, CPL_N_IF };
int cpl_implicit_init(cpl_runner *r);
/* (fields at t_{k-1}) -> (fields at t_k; data.iterations, converged, residual) */
int cpl_implicit_step(cpl_runner *r, int64_t k, int output);

/* record.c: (fields, replies of step k, rim) -> (results.h5 rows and
 * snapshots, the bus); at output steps results.h5 is flushed. */
int cpl_record(cpl_runner *r, int64_t k, int output);
/* (step k, steps per second) -> (the terminal's progress line, coupler.progress) */
void cpl_progress(cpl_runner *r, int64_t k, double rate, int final);

/* accel.c: acceleration of the implicit scheme on a vector of nf fields
 * (lengths len[f]). One time step: cpl_accel_begin; then per iteration
 * cpl_accel_next(x = input used, xt = H(x)) which tests convergence (per
 * field, ||xt_f - x_f|| <= tol ||xt_f - base_f||; base NULL = 0) and, if not
 * converged, overwrites x with the next input; cpl_accel_end at the end. */
#define CPL_ACCEL_MAX_FIELDS 4
cpl_accel *cpl_accel_create(const cpl_implicit *opt, int nf, const int64_t *len,
                            proto_err *err);
void cpl_accel_free(cpl_accel *a);
void cpl_accel_begin(cpl_accel *a);
/* Returns 1 converged, 0 not (x updated). res[f]: relative residuals. */
int cpl_accel_next(cpl_accel *a, double *x, const double *xt,
                   const double *const *base, double *res);
void cpl_accel_end(cpl_accel *a);
int cpl_accel_columns(const cpl_accel *a);
/* What carries over from one step to the next (restart: bitwise): up to cap
 * named buffers into v; returns how many. */
typedef struct cpl_stateval {
  const char *name;
  proto_dtype dtype;
  void *data;
  int64_t count;
} cpl_stateval;
int cpl_accel_state(cpl_accel *a, cpl_stateval *v, int cap);

/* timing.c: compute / transfer+encode / waiting per process and step, the
 * coupler's own mapping and output time; /coupler/timing rows; the
 * end-of-run table. */
cpl_timing *cpl_timing_create(const cpl_runner *r);
void cpl_timing_free(cpl_timing *t);
/* A reply of peer i arrived at `now` (compute seconds from its header). */
void cpl_timing_reply(cpl_runner *r, int i, double now, double compute);
/* Closes step k: wall and output seconds; appends the row, publishes it. */
int cpl_timing_step(cpl_runner *r, int64_t k, double wall, double output_s);
void cpl_timing_print(const cpl_runner *r, FILE *f);

/* Set by the SIGINT/SIGTERM handler: the only process-wide state, because a
 * signal handler can reach nothing else. */
extern volatile int cpl_interrupted;

#endif
