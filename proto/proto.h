/* proto.h — the one public header of cosim's base part (prefix proto_).
 *
 * What lives here, shared by every other part (one concept per header, all
 * included from this one, which is the only one other parts include):
 *   1. errors        proto_err.h: a message buffer every fallible call fills
 *   2. messages      proto_msg.h: names, multipart [topic][JSON header][raw
 *                    array]... (PROTOCOL.md), sockets, the clock
 *   3. role table    (below) what each role (dem, fem, block) exchanges: array
 *                    names, dtypes, shapes, meaning; checked by both sides
 *   4. participants  proto_participant.h: proto_participant_main(), the
 *                    handshake/step loop a solver process plugs into with
 *                    callbacks (step, state save/load); CURVE keys
 *   5. config        proto_cfg.h: JSON loading with line/column errors and a key
 *                    reader that names the key path in every error and rejects
 *                    unknown keys
 *   6. output        proto_h5.h: HDF5 time series / snapshots, the one HDF5
 *                    reader, and the XDMF companion file
 *
 * Nothing here knows any physics. Units are SI unless a comment says otherwise.
 */
#ifndef COSIM_PROTO_H
#define COSIM_PROTO_H

#include <stddef.h>
#include <stdint.h>
#include <cjson/cJSON.h>

#define PROTO_VERSION 1

#include "proto_err.h"
#include "proto_msg.h"

/* ------------------------------------------------------------- role table
 *
 * The contract between the coupler and each role, declared once (roles.c):
 * for every role and message the arrays it carries (name, dtype, shape with
 * symbolic dims, units, when present, meaning over a sub-stepped coupling
 * step). proto_participant_main and the coupler both validate against it;
 * `cosim roles --json` prints it for other languages. PROTOCOL.md explains
 * it in prose. */

typedef enum proto_role {
  PROTO_ROLE_DEM = 0,   /* grains: gets the surface, returns nodal forces */
  PROTO_ROLE_FEM = 1,   /* the tread: gets forces + rim frame, returns the surface */
  PROTO_ROLE_BLOCK = 2, /* tread block on the road: gets d_road, returns force */
  PROTO_ROLE_LUG = 3,   /* a tread block serving the lugs of a rolling tyre (tire_road):
                           gets its lug face's approach d_road, returns force and its
                           centre of pressure */
  PROTO_N_ROLES
} proto_role;

/* Message types, in the order of a run (PROTOCOL.md "Control channel"). */
typedef enum proto_msg_kind {
  PROTO_MSG_HELLO, PROTO_MSG_WELCOME, PROTO_MSG_READY, PROTO_MSG_STEP,
  PROTO_MSG_DONE, PROTO_MSG_STOP, PROTO_MSG_BYE, PROTO_MSG_ERROR,
  /* checkpoint/restart (issue 11 builds on these): the coupler asks for the
   * participant's state and gets it back as arrays "state.<x>" */
  PROTO_MSG_CHECKPOINT, PROTO_MSG_STATE, PROTO_MSG_RESTORE, PROTO_MSG_RESTORED,
  /* liveness: a participant that announced heartbeat_s in its hello sends
   * one whenever it has been silent that long (PROTOCOL.md "Liveness") */
  PROTO_MSG_HEARTBEAT,
  PROTO_N_MSGS
} proto_msg_kind;

/* Array names of the role table. */
#define PROTO_A_SURFACE_X0 "surface_x0"
#define PROTO_A_SURFACE_TRI "surface_tri"
#define PROTO_A_NODAL_FORCE "nodal_force"
#define PROTO_A_RIM_R "rim_R"
#define PROTO_A_RIM_C "rim_c"
#define PROTO_A_RIM_OMEGA "rim_omega"
#define PROTO_A_RIM_V "rim_v"
#define PROTO_A_X "x"
#define PROTO_A_V "v"
#define PROTO_A_D_ROAD "d_road"
#define PROTO_A_FORCE "force"
#define PROTO_A_COP "cop"
#define PROTO_A_ORIGIN "origin"
#define PROTO_A_CELL_XY "cell_xy"
#define PROTO_A_BASE "base"
#define PROTO_A_CELL_FORCE "cell_force"
/* Sparse form of an [n, ...] array (PROTOCOL.md "Sparse exchange"): the
 * array has k rows, the rows of the nodes listed in "<name>_index" (i4 [k],
 * increasing). Rows not listed are zero (forces) or not carried (positions,
 * velocities: the node is out of the dem's reach this step). */
#define PROTO_SUFFIX_INDEX "_index"
#define PROTO_A_NODAL_FORCE_INDEX "nodal_force_index"
#define PROTO_A_X_INDEX "x_index"
#define PROTO_A_V_INDEX "v_index"
/* Participant-defined arrays, by prefix (PROTOCOL.md "Series", "Snapshots") */
#define PROTO_A_SERIES "series"  /* the row of the "series" dataset */
#define PROTO_P_SERIES "series." /* rows of further datasets */
#define PROTO_P_SNAP "snap."     /* snapshot arrays at output steps */
#define PROTO_P_MESH "mesh."     /* written once from ready */
#define PROTO_P_STATE "state."   /* the participant's whole changing state */

/* Header keys beyond the fixed ones (v, type, step, t, arrays). */
#define PROTO_H_ROLE "role"           /* hello, ready: role name */
#define PROTO_H_NAME "name"           /* hello */
#define PROTO_H_PID "pid"             /* hello */
#define PROTO_H_CONFIG "config"       /* welcome: the process's section */
#define PROTO_H_RUN "run"             /* welcome: run information */
#define PROTO_H_DT "dt"               /* step: coupling step, s */
#define PROTO_H_RESET "reset"         /* step (lug): a new lug: its history starts afresh */
#define PROTO_H_IDLE "idle"           /* step (lug): it serves no lug: nothing to compute */
#define PROTO_H_OUTPUT "output"       /* step: snapshot wanted (bool) */
#define PROTO_H_ITERATION "iteration" /* step, done: 0, or n >= 1 = repeat n of step k */
#define PROTO_H_COMPUTE_S "compute_s" /* done: seconds spent in the participant's step */
#define PROTO_H_ROLLBACK "rollback"   /* ready: true if state_save/state_load exist */
#define PROTO_H_SERIES "series"       /* ready: {dataset: [column names]} */
#define PROTO_H_SNAPSHOT "snapshot"   /* ready: how to show snapshots */
#define PROTO_H_MESSAGE "message"     /* error */
#define PROTO_H_HEARTBEAT_S "heartbeat_s" /* hello: the longest it stays silent, s */
#define PROTO_H_PHASE "phase"         /* heartbeat: "welcome", "init", "step", "idle" */
#define PROTO_H_PROGRESS "progress"   /* heartbeat: fraction done in [0, 1], or absent */
#define PROTO_H_WHAT "what"           /* heartbeat: what it is doing ("settling the bed") */
#define PROTO_H_BED_TOP "bed_top"     /* ready (dem, optional): lowest surface node at first touch, m */
#define PROTO_H_BED_TOP_GRAINS "bed_top_grains" /* ready (dem): grains it was taken over */
#define PROTO_H_RESTART_STEP "restart_step" /* welcome run: the checkpoint's step, 0 if none */
#define PROTO_H_SPARSE "sparse"       /* step: the coupler takes sparse replies (bool);
                                       * ready (fem): it takes a sparse nodal_force */
#define PROTO_H_REACH "reach"         /* done (dem): [lo xyz, hi xyz] the box its grains
                                       * can reach in the next step, m; step (dem): the
                                       * box x_index was chosen by */
#define PROTO_H_REACH_SPEED "reach_speed" /* done (dem), optional: s; grow reach by this
                                       * times the surface's largest node speed |v| of
                                       * the step, and send that node too */

/* A participant says something at least this often (s): a heartbeat when it
 * has nothing else to say. */
#define PROTO_HEARTBEAT_S 1.0
/* Participants read their CURVE keys from this file (PROTOCOL.md
 * "Security"); the path comes in this environment variable or --curve. */
#define PROTO_ENV_CURVE "COSIM_CURVE_FILE"

/* Symbolic dimensions of the table (a positive dim is literal). */
enum { PROTO_DIM_NODES = -1, /* n: surface nodes (bound by surface_x0) */
       PROTO_DIM_TRIS = -2,  /* m: surface triangles (bound by surface_tri) */
       PROTO_DIM_ROWS = -3,  /* k: rows of a sparse array (its index, per message) */
       PROTO_DIM_CELLS = -4  /* c: a lug block's cells (bound by its cell_xy) */ };

/* "n", "m", "k", "c" ("?" for another value). */
const char *proto_dim_symbol(int64_t sym);

typedef enum proto_when {
  PROTO_WHEN_ALWAYS = 0,
  PROTO_WHEN_SURFACE = 1, /* only when the participant has a coupled surface */
  PROTO_WHEN_INDEX = 2    /* optional "<name>_index" of the [n, ...] row <name>
                           * of the same role and message: with it, <name> has
                           * k rows (its sparse form) */
} proto_when;

typedef struct proto_array_spec {
  proto_role role;
  proto_msg_kind msg;
  const char *name;
  proto_dtype dtype;
  int ndim;
  int64_t dims[PROTO_MAX_NDIM]; /* > 0 literal, or PROTO_DIM_* */
  const char *units;
  proto_when when;
  const char *meaning; /* incl. its meaning over a sub-stepped coupling step */
  /* The coupler's side of a step/done row (NULL / 0 for the handshake): the
   * coupler field the request reads or the reply fills (coupler/README.md
   * "Fields"), and whether the replies of several processes of the role are
   * summed (forces add) rather than copied. */
  const char *field;
  int sum;
} proto_array_spec;

/* The table; *n gets its length. */
const proto_array_spec *proto_role_table(int *n);
const char *proto_role_name(proto_role r);  /* "dem", "fem", "block" */
int proto_role_parse(const char *name);     /* -1 if unknown */
const char *proto_msg_type(proto_msg_kind k); /* "hello", ... */
int proto_msg_kind_parse(const char *type);   /* -1 if unknown */
const char *proto_dtype_name(proto_dtype d);  /* "f8", ... */
size_t proto_dtype_size(proto_dtype d);       /* bytes per element */
/* The table as JSON (caller frees): {"version", "roles": {role: {msg: [...]}},
 * "messages", "dims"}. */
cJSON *proto_role_table_json(void);

/* Limits of what a ready message may declare (PROTOCOL.md "Series",
 * "Snapshots"). */
#define PROTO_MAX_SERIES 8       /* series datasets per participant */
#define PROTO_MAX_COLUMNS 64     /* columns per series dataset */
#define PROTO_MAX_SNAP_ATTRS 16  /* snapshot attributes shown in XDMF */

/* What one side of a conversation has bound so far: the sizes the table's
 * symbolic dims refer to (a dim < 0 is unbound: the first array that has it
 * binds it), and the series datasets the participant declared in its ready
 * message, which every done must then carry. */
typedef struct proto_dims {
  int64_t nodes, tris, cells; /* -1 until bound */
  int surface;         /* a coupled surface exists (WHEN_SURFACE arrays due) */
  int n_series;        /* datasets declared in ready.series */
  char series[PROTO_MAX_SERIES][PROTO_NAME_LEN]; /* their names */
  int series_cols[PROTO_MAX_SERIES];             /* their column counts */
} proto_dims;
void proto_dims_init(proto_dims *d);
/* Checks message m (kind of role) against the table: every array the table
 * lists for it (and due under d->surface) is present with its dtype and
 * shape. In welcome/ready, the presence of any WHEN_SURFACE array sets
 * d->surface. Errors name the array, the expected shape with its symbols
 * and values, and its meaning. Beyond the table: a ready's "series" and
 * "snapshot" declarations are checked (names by proto_name_check, column
 * lists, limits) and the series kept in d; a done must then carry exactly
 * the declared series arrays (f8 [columns] each), so no row goes missing
 * from one dataset while the others grow. */
int proto_role_check(proto_role role, proto_msg_kind kind, const proto_msg *m,
                     proto_dims *d, proto_err *err);
/* Data of an array already checked by proto_role_check (NULL if absent). */
const void *proto_msg_data(const proto_msg *m, const char *name);
/* The sparse form of array `name` in a checked message: its row count k and
 * *index the k node indices (increasing, < n), or -1 (*index NULL) when the
 * array is dense (no "<name>_index"). */
int64_t proto_msg_sparse(const proto_msg *m, const char *name, const int32_t **index);
/* The f8 array `name` [n, cols] of a checked message as dense rows: the
 * array itself, or its sparse form expanded into scratch [n*cols] (rows not
 * listed +0.0: what the dense form holds there when the sender packs only
 * the rows that are not all +0.0, as the forces are). */
const double *proto_msg_dense(const proto_msg *m, const char *name, int64_t n, int cols,
                              double *scratch);
/* The sparse form of a force field f [n*3]: the rows that are not
 * (+0, +0, +0) bit for bit (the rows a dense field would differ in from
 * zeros) as idx [k] (increasing) and rows [k*3]; returns k. The one rule for
 * which force rows travel (the dem's reply, the coupler's message to the fem). */
int64_t proto_sparse_rows(const double *f, int64_t n, int32_t *idx, double *rows);
/* x_index's contract (PROTOCOL.md "Sparse exchange"): the nodes of every
 * triangle tri [n_tri*3] whose box over a step of dt — its nodes at x and
 * at x + v dt [n*3], grown by PROTO_REACH_ROUNDING — meets box [lo xyz, hi
 * xyz]. A node moves on that segment within the step, so the triangle stays
 * inside the box of its six end points: one left out does not meet the box
 * all step. Into index (increasing; mark [n]: 1 for a node in it, else 0);
 * returns the count. */
int64_t proto_reach_nodes(const double *x, const double *v, double dt, const int32_t *tri,
                          int64_t n_tri, int64_t n, const double box[6], uint8_t *mark,
                          int32_t *index);
/* The first of a [n] that is not finite (inf, nan), or -1: the arrays that
 * cross every step are checked with it (a scan without a branch per value). */
int64_t proto_first_nonfinite(const double *a, int64_t n);
/* m: how far a node's end of step may lie from x + v dt by rounding (a dem
 * moves it by v dt/nsub per sub-step: < nsub * 2.2e-16 * |x|, below 1e-9 m for
 * |x| < 10 m and up to 10^5 sub-steps). */
#define PROTO_REACH_ROUNDING 1e-9

#include "proto_participant.h"
#include "proto_shm.h"
#include "proto_cfg.h"
#include "proto_h5.h"

#endif
