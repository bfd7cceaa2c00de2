/* runner.h — the state of one coupled run (cpl_runner) and the functions of
 * the files that share it: run.c (setup, handshake, teardown), contract.c
 * (the role table bound to the fields), schedule.c (the exchanges of a step,
 * walked as data), scenario_step.c (the scenario's stage), loop.c (the
 * schemes), accel.c (implicit acceleration), liveness.c, checkpoint.c and
 * timing.c. Internal to the coupler. */
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
  CPL_N_FIELDS
} cpl_field_id;

typedef struct cpl_field {
  const char *name;
  int64_t len;      /* doubles */
  double *cur, *out;
  int given;        /* outputs of this step: number of processes that gave it */
} cpl_field;

/* A role-table row bound to a field (contract.c): requests read in[field];
 * replies are summed (several processes of one role: forces add) or copied
 * into out. */
typedef struct cpl_binding {
  proto_role role;
  proto_msg_kind msg; /* PROTO_MSG_STEP (request) or PROTO_MSG_DONE (reply) */
  const char *array;
  cpl_field_id field;
  int sum;
  const proto_array_spec *spec; /* its row */
  const proto_array_spec *index; /* its sparse form's "<array>_index" row, or NULL */
} cpl_binding;

/* Every step/done row of the role table, bound once before the run starts. */
#define CPL_MAX_BINDINGS 32
typedef struct cpl_contract {
  int n;
  cpl_binding b[CPL_MAX_BINDINGS];
} cpl_contract;

/* contract.c: binds the table's step/done rows t[0..n) to the fields; -1
 * with a message naming the row (or the field no row binds). */
int cpl_contract_build(cpl_contract *c, const proto_array_spec *t, int n, proto_err *err);
const char *cpl_field_name(cpl_field_id id); /* "surface.x", ... */
int cpl_field_parse(const char *name);       /* -1 if unknown */

/* ------------------------------------------------------------ schedule
 * The step as data: exchanges in order. All requests of one stage are sent
 * before any reply is awaited (processes of a stage compute at the same
 * time); a coupler action runs before the stage's requests. */
typedef enum cpl_action {
  CPL_ACT_NONE,
  CPL_ACT_RIM,  /* advance the rim frame by the scenario (uses the vertical load) */
  CPL_ACT_ROAD  /* road displacement of t_k: profile, or the road body */
} cpl_action;

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
  int n_of_role[PROTO_N_ROLES];
  int fem;               /* the process giving the surface, or -1 */
  cpl_surface surf;
  int nex;               /* the step's exchanges in order (schedule.c) */
  cpl_exchange ex[CPL_MAX_EXCHANGES];
} cpl_plan;

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
  cpl_peer peers[CPL_MAX_PROCS];
  cpl_child children[CPL_MAX_PROCS];
  int nchildren;
  cpl_plan plan;     /* fixed once the handshake is done */
  /* the data of the step: fields, scenario state, implicit iterate, counters */
  cpl_field fields[CPL_N_FIELDS];
  const double *in[CPL_N_FIELDS]; /* what requests send (set by the scheme) */
  cpl_rim rim;
  cpl_road road;
  /* implicit scheme (loop.c) */
  cpl_accel *accel;
  double *xi, *xt;        /* interface vector: iterate and H(iterate) */
  double *x_start;        /* surface positions at t_{k-1} */
  double *v_dem;          /* secant velocity (d - x_start)/dt the DEM moves at */
  double *f_fem;          /* force the FEM gets: iterate + carried defect */
  double *carry;          /* impulse defect of the last step / dt */
  double road_iter;       /* road force iterate */
  int iterations, converged;
  double residual[3];     /* relative residual per interface field at exit */
  int64_t steps_unconverged;
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
  int progress_shown; /* tenths of the run shown in a batch log (loop.c) */
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
 * the scene continues it (the keys that decide the results agree). */
cpl_ckpt *cpl_checkpoint_read(const char *path, const cpl_scene *s, proto_err *err);
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
/* Allocates the fields for a surface of n nodes (n may be 0). */
int cpl_fields_init(cpl_runner *r, int64_t n, proto_err *err);
void cpl_fields_free(cpl_runner *r);
/* Builds the exchange list of the scheme from the processes' roles. */
void cpl_schedule_build(cpl_runner *r);
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
/* The replies already in the peers' reply slots of a stage into the fields'
 * out buffers (summed or copied in exchange order), swapped in if commit. */
void cpl_stage_take(cpl_runner *r, int stage, int commit);
/* Sets r->in to the fields' current values (serial, parallel). */
void cpl_inputs_current(cpl_runner *r);
void cpl_field_commit(cpl_runner *r, cpl_field_id id);

/* scenario_step.c: the scenario's stage. Runs a coupler action for step k
 * (rim frame; road profile or body) into the fields; -1 with r->err. */
int cpl_do_action(cpl_runner *r, cpl_action a, int64_t k);
/* The sum of the z components of the current surface force (N). */
double cpl_vertical_load(const cpl_runner *r);

/* loop.c: the scheme's set-up (implicit: its vectors and accelerator),
 * after the handshake; then the loop over all steps. */
int cpl_scheme_init(cpl_runner *r);
int cpl_step_loop(cpl_runner *r);

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
