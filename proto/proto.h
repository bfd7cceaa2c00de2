/* proto.h — the one public header of cosim's base part (prefix proto_).
 *
 * What lives here, shared by every other part:
 *   1. errors        proto_err: a message buffer every fallible call fills
 *   2. messages      multipart [topic][JSON header][raw array]... (PROTOCOL.md)
 *   3. role table    what each role (dem, fem, block) exchanges: array names,
 *                    dtypes, shapes, meaning; checked by both sides
 *   4. participants  proto_participant_main(): the handshake/step loop a solver
 *                    process plugs into with callbacks (step, state save/load)
 *   5. config        JSON loading with line/column errors and a key reader that
 *                    names the key path in every error and rejects unknown keys
 *   6. output        HDF5 time series / snapshots and the XDMF companion file
 *
 * Nothing here knows any physics. Units are SI unless a comment says otherwise.
 */
#ifndef COSIM_PROTO_H
#define COSIM_PROTO_H

#include <stddef.h>
#include <stdint.h>
#include <cjson/cJSON.h>

#define PROTO_VERSION 1

/* ------------------------------------------------------------------ errors */

typedef struct proto_err {
  char msg[1024];
} proto_err;

/* Formats into err->msg (if err is not NULL) and returns -1, so callers can
 * `return proto_fail(err, "...")`. */
int proto_fail(proto_err *err, const char *fmt, ...)
    __attribute__((format(printf, 2, 3)));
/* Prefixes the existing message: "context: <old message>". Returns -1. */
int proto_wrap(proto_err *err, const char *fmt, ...)
    __attribute__((format(printf, 2, 3)));
/* Makes text safe to print on a terminal, in place: control characters
 * (C0 but newline and tab, DEL, C1) and bytes that are not UTF-8 become
 * '?'. proto_fail and proto_wrap apply it to every message, so names and
 * messages that came from a file or the wire never reach a terminal as
 * escape sequences. */
void proto_sanitize(char *text);

/* ---------------------------------------------------------------- messages */

typedef enum proto_dtype {
  PROTO_F8 = 0, /* little-endian IEEE double, "f8" */
  PROTO_I4 = 1, /* little-endian int32, "i4" */
  PROTO_I8 = 2, /* little-endian int64, "i8" */
  PROTO_U1 = 3  /* bytes, "u1" */
} proto_dtype;

#define PROTO_MAX_ARRAYS 64
#define PROTO_MAX_NDIM 3
#define PROTO_NAME_LEN 48

/* Names that become HDF5 paths, file names, XDMF text or terminal output
 * (process names, array names, series datasets, snapshot names, message
 * types, topics) follow one grammar, checked here and nowhere else:
 * 1 to PROTO_NAME_LEN - 1 characters; a segment is [A-Za-z0-9_-]+; a plain
 * name is one segment, a dotted name (array names with a prefix such as
 * "series.wall_forces", bus topics "soil.series") segments joined by single
 * dots. So no '/', no empty, "." or ".." segment, no space, quote or control
 * character. `what` names the name in the error ("array name", "process
 * name"); the offending name is quoted sanitised. */
typedef enum { PROTO_NAME_PLAIN = 0, PROTO_NAME_DOTTED = 1 } proto_name_kind;
int proto_name_check(const char *name, proto_name_kind kind, const char *what,
                     proto_err *err);
/* The same grammar for a name stored in cap bytes (a scene's name). */
int proto_name_check_len(const char *name, size_t cap, proto_name_kind kind,
                         const char *what, proto_err *err);

typedef struct proto_array {
  char name[PROTO_NAME_LEN];
  proto_dtype dtype;
  int ndim;
  int64_t shape[PROTO_MAX_NDIM];
  const void *data; /* send: caller's buffer; recv: inside the received frame
                       (8-byte aligned; copied only if the frame was not) */
  size_t nbytes;
} proto_array;

/* One message. `header` holds any header fields beyond the fixed ones
 * (v, type, step, t, arrays); it is owned by the message. */
typedef struct proto_msg {
  char topic[PROTO_NAME_LEN];
  char type[PROTO_NAME_LEN];
  int64_t step;
  double t;
  cJSON *header; /* extra fields; may be NULL */
  int narrays;
  proto_array arrays[PROTO_MAX_ARRAYS];
  struct proto_msg_frames *frames_; /* recv side: the frames the arrays point into */
} proto_msg;

/* Resets a message for building; frees what a previous recv or build owned. */
void proto_msg_reset(proto_msg *m, const char *topic, const char *type,
                     int64_t step, double t);
void proto_msg_free(proto_msg *m);
/* Adds an array that points at the caller's buffer (no copy). The buffer must
 * stay valid and unchanged until the peer has answered (lock-step) — for the
 * bus, proto_publish copies. shape has ndim entries. Returns -1 if full or
 * if the name breaks proto_name_check (dotted), which the receiver enforces. */
int proto_msg_add(proto_msg *m, const char *name, proto_dtype dtype, int ndim,
                  const int64_t *shape, const void *data);
/* Shorthands for the common cases. */
int proto_msg_add_f8(proto_msg *m, const char *name, int64_t rows, int64_t cols,
                     const double *data); /* cols == 0: 1-D [rows] */
int proto_msg_add_i4(proto_msg *m, const char *name, int64_t rows, int64_t cols,
                     const int32_t *data);
/* Extra header fields (created on demand). */
cJSON *proto_msg_header(proto_msg *m);

/* Finds an array by name and checks it: dtype, ndim and each shape entry
 * (an expected entry < 0 means "any"). Returns NULL and fills err with a
 * message naming the message type, the array and what was expected. */
const proto_array *proto_msg_get(const proto_msg *m, const char *name,
                                 proto_dtype dtype, int ndim,
                                 const int64_t *shape, proto_err *err);
/* "[2,3]" (an entry < 0 is shown as "*"), for messages. */
void proto_shape_str(char *out, size_t cap, int ndim, const int64_t *shape);
/* The same for f8 arrays: rows x cols (cols == 0: 1-D; -1: any). */
const double *proto_msg_get_f8(const proto_msg *m, const char *name,
                               int64_t rows, int64_t cols, proto_err *err);
const proto_array *proto_msg_find(const proto_msg *m, const char *name);

/* Sends [topic][header][arrays...] on a ZeroMQ socket (zero-copy for arrays).
 * flags: 0 or ZMQ_DONTWAIT. For ROUTER sockets first send the identity
 * frame with ZMQ_SNDMORE yourself (proto_send_to does that). */
int proto_send(void *socket, const proto_msg *m, int flags, proto_err *err);
int proto_send_to(void *router, const char *identity, const proto_msg *m,
                  proto_err *err);
/* Receives and validates one message: frame count, JSON header, version,
 * dtype names, shapes against byte counts, limits. On any defect returns -1
 * with a message and leaves the socket ready for the next message.
 * `identity` (may be NULL) receives the ROUTER identity frame when the
 * socket is a ROUTER (size PROTO_NAME_LEN). */
int proto_recv(void *socket, proto_msg *m, char *identity, proto_err *err);
/* Decodes already-received frames (used by proto_recv and by tests/fuzzers).
 * frames[i]/sizes[i]: topic, header, arrays. The arrays are not copied:
 * they must outlive m. */
int proto_decode(proto_msg *m, int nframes, const void *const *frames,
                 const size_t *sizes, proto_err *err);

/* Largest array frame accepted (bytes); larger frames are rejected. */
#define PROTO_MAX_FRAME_BYTES ((size_t)1 << 30)
/* Largest header frame accepted (bytes): a welcome carries a config section. */
#define PROTO_MAX_HEADER_BYTES ((size_t)64 << 20)
/* Integer header fields (step, iteration) are within +-2^53: exact doubles. */
#define PROTO_MAX_HEADER_INT 9007199254740992.0
/* Reads an optional integer header field of a received message into *out
 * (def when absent): it must be an integer in [lo, hi]. Errors name the
 * message type and the field. */
int proto_header_int(const proto_msg *m, const char *key, int64_t lo,
                     int64_t hi, int64_t def, int64_t *out, proto_err *err);

/* Sets the input limits of a receiving socket: a peer that sends a frame
 * larger than PROTO_MAX_FRAME_BYTES is disconnected by ZeroMQ before the
 * frame is allocated (proto_recv would refuse it only after). */
int proto_socket_limits(void *socket);
/* Waits up to timeout_ms for the socket to become readable.
 * Returns 1 readable, 0 timeout, -1 interrupted (EINTR). */
int proto_poll_in(void *socket, int timeout_ms);
/* Monotonic wall clock in seconds. */
double proto_now(void);

/* Publishes a copy of the message on a bus socket (PUB), never blocking:
 * a full queue drops the message (slow monitors never slow a run). */
int proto_publish(void *pub, const proto_msg *m);

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
#define PROTO_H_BED_TOP "bed_top"     /* ready (dem, optional): settled bed's top under the surface, m */
#define PROTO_H_BED_TOP_GRAINS "bed_top_grains" /* ready (dem): grains it was taken over */
#define PROTO_H_RESTART_STEP "restart_step" /* welcome run: the checkpoint's step, 0 if none */

/* A participant says something at least this often (s): a heartbeat when it
 * has nothing else to say. */
#define PROTO_HEARTBEAT_S 1.0
/* Participants read their CURVE keys from this file (PROTOCOL.md
 * "Security"); the path comes in this environment variable or --curve. */
#define PROTO_ENV_CURVE "COSIM_CURVE_FILE"

/* Symbolic dimensions of the table (a positive dim is literal). */
enum { PROTO_DIM_NODES = -1, /* n: surface nodes (bound by surface_x0) */
       PROTO_DIM_TRIS = -2   /* m: surface triangles (bound by surface_tri) */ };

typedef enum proto_when {
  PROTO_WHEN_ALWAYS = 0,
  PROTO_WHEN_SURFACE = 1 /* only when the participant has a coupled surface */
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
  int64_t nodes, tris; /* -1 until bound */
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

/* ------------------------------------------------------------ participants
 *
 * A solver process is `int main(int c, char **v) { return
 * proto_participant_main(c, v, &ops, &my_state); }`. The loop:
 *   connect a DEALER (identity = --name) to --endpoint, send "hello" with
 *   the role, receive "welcome" (this process's config section and run
 *   information), call configure() and init(), reply "ready", then answer
 *   each "step" with step(), until "stop" (reply "bye").
 * Requests and replies are checked against the role table, both ways.
 * Any callback error is sent back as an "error" message and the process
 * exits non-zero. The process also exits when the coupler is silent for
 * longer than the deadline given in "welcome", or its parent dies.
 *
 * Rollback (implicit coupling): when the run may repeat a step (welcome
 * run.rollback), the loop calls state_save at the start of every step and
 * keeps a deep copy of those arrays (buffers grown only when needed); a step
 * request with iteration >= 1 restores that copy with state_load before
 * step() runs again. A participant without state_save/state_load says so in
 * ready ("rollback": false) and the coupler refuses the implicit scheme for
 * it by name. The same callbacks answer "checkpoint" and "restore".
 *
 * Command line: NAME --endpoint EP --name NAME [--check-config FILE|-]
 * --check-config validates a config section (JSON, "-" = stdin) and exits
 * 0 or 1 with the message on stderr, without connecting anywhere. */

typedef struct proto_peer proto_peer; /* the participant's sockets */

typedef struct proto_run_info {
  const char *name;       /* participant name (the processes.<name> key) */
  const char *key_path;   /* "processes.<name>", for error messages */
  const char *output_dir; /* run's output directory */
  double dt;              /* coupling step, s */
  double t_end;           /* end time, s */
  int64_t n_steps;
  int64_t output_every;   /* snapshot every this many steps */
  int rollback;           /* the coupler may repeat steps (implicit scheme) */
  int64_t restart_step;   /* > 0: the run restarts from a checkpoint of this
                             step; state_load follows init, so init may skip
                             work whose result the state replaces (settling) */
  proto_peer *peer;       /* for proto_peer_progress from init (NULL in
                             --check-config) */
} proto_run_info;

/* One step request, parsed (the callback never reads the header). */
typedef struct proto_step_info {
  int64_t k;     /* step number, >= 1 */
  double t;      /* t_{k-1}: the step advances from t to t + dt */
  double dt;     /* coupling step, s */
  double t_end;  /* t_k = t + dt (the reply's t) */
  int output;    /* add snapshot arrays "snap.<name>" to the reply */
  int iteration; /* 0; n >= 1: the n-th repeat of step k (state already
                    restored to the start of step k by the loop) */
} proto_step_info;

typedef struct proto_participant_ops {
  proto_role role; /* stubs use the role they stand in for */
  /* Parses and validates this process's config section into the solver's
   * model. Errors name the key path (use proto_cfg_*). Called for
   * --check-config too (then info->dt etc. may be 0). */
  int (*configure)(void *user, const proto_run_info *info, const cJSON *section,
                   proto_err *err);
  /* Called after configure with the coupler's welcome message (which may
   * carry arrays, e.g. the FEM surface for the DEM). Adds to `ready` what
   * the coupler needs: series declarations (proto_ready_series), arrays
   * (surface mesh ...). May be NULL. */
  int (*init)(void *user, const proto_msg *welcome, proto_msg *ready,
              proto_err *err);
  /* One coupling step: read the request's arrays (already checked against
   * the role table: use proto_msg_data), advance, fill the reply. Arrays
   * added to the reply must stay valid until the next call. */
  int (*step)(void *user, proto_peer *peer, const proto_step_info *info,
              const proto_msg *request, proto_msg *reply, proto_err *err);
  /* Frees everything (always called once, also after errors). May be NULL. */
  void (*finish)(void *user);
  /* Optional. Adds arrays named "state.<x>" that together are the whole
   * changing state (pointing at the participant's own buffers: the loop
   * copies them). Equal state in, equal results out: anything step()
   * depends on and changes belongs here. */
  int (*state_save)(void *user, proto_msg *state, proto_err *err);
  /* Optional. Restores the arrays state_save produced (checked by name,
   * dtype and size by the participant). */
  int (*state_load)(void *user, const proto_msg *state, proto_err *err);
} proto_participant_ops;

/* Declarations for the ready message (PROTOCOL.md "Series", "Snapshots"):
 * a time-series dataset with its column names, and how the snapshot arrays
 * are to be shown (kind "points"/"tet4"/"tet10"/"tri3"; cells NULL for
 * points). Return -1 only when out of memory. */
int proto_ready_series(proto_msg *ready, const char *dataset, int ncols,
                       const char *const *columns);
int proto_ready_snapshot(proto_msg *ready, const char *kind,
                         const char *geometry, const char *cells, int nattrs,
                         const char *const *attributes);
/* Adds an f8 array under a prefix: "<prefix><name>" (PROTO_P_SNAP,
 * PROTO_P_STATE, PROTO_P_SERIES, PROTO_P_MESH). cols == 0: 1-D. */
int proto_msg_add_prefixed(proto_msg *m, const char *prefix, const char *name,
                           proto_dtype dtype, int64_t rows, int64_t cols,
                           const void *data);
/* For state_load: the array "state.<name>" with exactly `count` elements of
 * dtype, copied into dst; errors name the array. */
int proto_state_get(const proto_msg *state, const char *name, proto_dtype dtype,
                    size_t count, void *dst, proto_err *err);

int proto_participant_main(int argc, char **argv,
                           const proto_participant_ops *ops, void *user);
/* Publishes on the bus from inside step() (topic "<name>.<what>"). */
int proto_peer_publish(proto_peer *peer, const proto_msg *m);
/* Reports progress of a long init (or step): fraction in [0, 1] (< 0:
 * unknown) and what is being done. Only records the values (cheap: call it
 * as often as you like); the loop's heartbeat thread sends them, so the
 * coupler shows them and knows the process is alive. peer may be NULL. */
void proto_peer_progress(proto_peer *peer, double fraction, const char *what);

/* ------------------------------------------------------------------ CURVE
 * (PROTOCOL.md "Security"). Keys are 40-character Z85 strings. A key file is
 * a JSON object {"server_public", "public", "secret"}: what a client needs
 * to connect to a coupler that runs with security.curve. */
#define PROTO_KEY_LEN 41 /* Z85 key + NUL */
typedef struct proto_curve {
  char server_public[PROTO_KEY_LEN]; /* the coupler's */
  char public_key[PROTO_KEY_LEN], secret_key[PROTO_KEY_LEN]; /* this client's */
} proto_curve;
/* Makes a key pair (public, secret: PROTO_KEY_LEN bytes each). */
int proto_curve_keypair(char *public_key, char *secret_key, proto_err *err);
/* Writes a client key file, mode 0600 (refuses to replace another file). */
int proto_curve_write(const char *path, const proto_curve *k, proto_err *err);
/* Reads a key file; refuses one that others may read (mode & 077). */
int proto_curve_read(const char *path, proto_curve *k, proto_err *err);
/* Makes socket a CURVE client of the server in k (before connect). */
int proto_curve_client(void *socket, const proto_curve *k, proto_err *err);
/* Makes socket a CURVE server with the given secret key (before bind);
 * domain: the ZAP domain its clients are checked in. */
int proto_curve_server(void *socket, const char *secret_key, const char *domain,
                       proto_err *err);

/* ------------------------------------------------------------------ config */

#define PROTO_PATH_CAP 256 /* key paths in messages ("processes.dem.walls[2].n") */
/* Largest JSON text read (a scene, a section on stdin). */
#define PROTO_MAX_JSON_BYTES ((size_t)256 << 20)

/* Parses JSON text; malformed input reports line and column:
 * "scene.json:12:5: malformed JSON near '...'". A key given twice in any
 * object (cJSON would keep both silently) is an error naming its path:
 * "scene.json: processes.dem.materials[1].E: duplicate key (given 2
 * times)". Returns NULL on error. */
cJSON *proto_json_parse(const char *text, const char *source_name,
                        proto_err *err);
cJSON *proto_json_load(const char *path, proto_err *err); /* "-": stdin */
/* The duplicate-key check alone, on a parsed tree (path: its key path, may
 * be "" for the root). Received headers get it too (proto_decode). */
int proto_json_check_unique(const cJSON *node, const char *path,
                            proto_err *err);
/* Applies one --set override (README "--set"). Two forms:
 *   KEY.PATH=VALUE   VALUE is text. It stays a string when it is not as a
 *                    whole one JSON value ("output.dir=2024/run1" is the
 *                    string "2024/run1"), and when the scene has a string at
 *                    KEY.PATH (then "output.dir=2024" is the string "2024";
 *                    only a "quoted" VALUE is read as a JSON string there).
 *                    Otherwise a number, true, false, null, a "quoted
 *                    string", {...} or [...] is that JSON value.
 *   KEY.PATH:=JSON   VALUE must be one JSON value, of any type.
 * Missing object keys on the path are created; an index [i] must exist.
 * A value that the key's reader does not accept is reported by the reader
 * (e.g. "output.dir: expected a string, got a number"). */
int proto_json_set(cJSON *root, const char *assignment, proto_err *err);

/* Key reader: wraps an object and its path; every getter marks the key as
 * used, and proto_cfg_end() reports any key nobody asked for (typos).
 * All getters return 0 on success (value stored) or -1 with err naming the
 * path and what was expected. A missing optional key leaves *out as the
 * default given. */
typedef struct proto_cfg {
  const cJSON *obj;
  char path[PROTO_PATH_CAP];
  uint64_t used; /* bitmask over the object's first 64 keys */
  proto_err *err;
} proto_cfg;

typedef enum { PROTO_OPTIONAL = 0, PROTO_REQUIRED = 1 } proto_need;

/* Starts reading obj (must be an object) at path; fails if it is not. */
int proto_cfg_open(proto_cfg *c, const cJSON *obj, const char *path,
                   proto_err *err);
/* Opens a child object: key missing and optional -> returns 1, c->obj NULL. */
int proto_cfg_child(proto_cfg *parent, const char *key, proto_need need,
                    proto_cfg *child);
int proto_cfg_num(proto_cfg *c, const char *key, proto_need need, double lo,
                  double hi, double *out); /* lo <= v <= hi */
/* Like proto_cfg_num but the upper bound is exclusive: lo <= v < hi. */
int proto_cfg_num_below(proto_cfg *c, const char *key, proto_need need,
                        double lo, double hi, double *out);
int proto_cfg_int(proto_cfg *c, const char *key, proto_need need, int64_t lo,
                  int64_t hi, int64_t *out);
int proto_cfg_bool(proto_cfg *c, const char *key, proto_need need, int *out);
/* Copies a string (cap bytes incl. NUL). */
int proto_cfg_str(proto_cfg *c, const char *key, proto_need need, char *out,
                  size_t cap);
/* A string that must be one of the NULL-terminated `choices`; *out = index. */
int proto_cfg_enum(proto_cfg *c, const char *key, proto_need need,
                   const char *const *choices, int *out);
/* A numeric array of exactly n entries (n < 0: any length up to cap);
 * *count gets the length (may be NULL). */
int proto_cfg_vec(proto_cfg *c, const char *key, proto_need need, double *out,
                  int n, int cap, int *count);
/* The raw node for custom reading (arrays of objects...); marks it used.
 * Returns NULL if missing (error only if required). */
const cJSON *proto_cfg_raw(proto_cfg *c, const char *key, proto_need need);
/* Path of an element, "parent.key[3]", for errors in custom readers. */
void proto_cfg_subpath(const proto_cfg *c, const char *key, int index,
                       char *out, size_t cap);
/* Reports the first unknown key: "<path>.<key>: unknown key". */
int proto_cfg_end(proto_cfg *c);
/* The keys nobody asked for, comma-separated into out; returns how many.
 * For stubs, which accept the section of the solver they stand in for. */
int proto_cfg_unused(const proto_cfg *c, char *out, size_t cap);

/* ------------------------------------------------------------------ output
 *
 * One HDF5 file per run. Time series are 2-D f8 datasets (one row per
 * step, chunked, growing), with the column names in the attribute
 * "columns"; snapshots are groups "<group>/steps/<n>" of arrays. */

typedef struct proto_h5 proto_h5;        /* the file */
typedef struct proto_series proto_series; /* one growing 2-D dataset */

proto_h5 *proto_h5_create(const char *path, proto_err *err);
/* Opens an existing file (writable: to continue it, read-only otherwise). */
proto_h5 *proto_h5_open(const char *path, int writable, proto_err *err);
/* What is at path: 0 nothing, 1 an HDF5 file, 2 anything else (another
 * kind of file, or one that cannot be read). Never changes the file. */
int proto_h5_probe(const char *path);
/* Writes every buffered row and flushes HDF5's caches to the file. Errors
 * name the file, the object and the system error ("No space left on device
 * (errno 28)"); the rows stay buffered, so a later flush may still write
 * them. */
int proto_h5_flush(proto_h5 *f, proto_err *err);
/* Flushes and closes; the handle is freed either way. -1 (err may be NULL)
 * if anything failed. HDF5 never closes a file again at exit. */
int proto_h5_close(proto_h5 *f, proto_err *err);
/* Stores a string attribute (e.g. the config) on an object ("/" = root; a
 * missing one becomes a group): variable-length UTF-8. */
int proto_h5_attr_str(proto_h5 *f, const char *group, const char *name,
                      const char *value, proto_err *err);
/* A number (f8) or an integer (i8) attribute, likewise (one value). */
int proto_h5_attr_f8(proto_h5 *f, const char *group, const char *name, double v,
                     proto_err *err);
int proto_h5_attr_i8(proto_h5 *f, const char *group, const char *name, int64_t v,
                     proto_err *err);
/* "/dem/series" with the given columns; parent groups made as needed. */
proto_series *proto_h5_series(proto_h5 *f, const char *path, int ncols,
                              const char *const *columns, proto_err *err);
/* An existing series, to append to after its first keep_rows rows (the
 * rest is cut off): its columns must be these. */
proto_series *proto_h5_series_resume(proto_h5 *f, const char *path, int ncols,
                                     const char *const *columns, int64_t keep_rows,
                                     proto_err *err);
int proto_series_append(proto_series *s, const double *row, proto_err *err);
int64_t proto_series_rows(const proto_series *s);
/* The most the series' row buffers can hold (bytes): what a flush may
 * have to write besides HDF5's own metadata. */
size_t proto_h5_buffer_bytes(const proto_h5 *f);
/* Writes an array (any dtype/shape of proto_array) as dataset
 * "<group>/<a->name>"; groups made as needed. */
int proto_h5_write_array(proto_h5 *f, const char *group, const proto_array *a,
                         proto_err *err);

/* Continuing a results file (its own writer); every other file is read
 * through the HDF5 input layer below. */
int proto_h5_exists(proto_h5 *f, const char *path); /* 1 if a link is there */
int proto_h5_unlink(proto_h5 *f, const char *path, proto_err *err); /* absent: ok */
/* Calls fn(name, ctx) for each member of group, in name order; fn returns
 * 0 to go on, 1 to stop, -1 to stop with an error (returned). A missing
 * group has no members. */
int proto_h5_list(proto_h5 *f, const char *group,
                  int (*fn)(const char *name, void *ctx), void *ctx, proto_err *err);

/* ------------------------------------------------------------- HDF5 input
 *
 * Reading HDF5 files (roads, springs, Green's functions, saved beds,
 * checkpoints), which may be damaged or hostile. Objects are looked up level
 * by level; a dataset's class must be numeric and its rank and dims are
 * checked against what the reader expects, its element count
 * (overflow-checked) against max_elems, before anything is allocated; its
 * values must be finite (read_f8); an attribute must hold exactly one value.
 * Errors name "<file>:<object>: <what>". */
typedef struct proto_h5in proto_h5in;
#define PROTO_H5IN_MAX_RANK 4

proto_h5in *proto_h5in_open(const char *path, proto_err *err);
void proto_h5in_close(proto_h5in *f); /* NULL is fine */
const char *proto_h5in_path(const proto_h5in *f);
/* 1 if the object (group or dataset, "/a/b") exists, else 0. */
int proto_h5in_exists(proto_h5in *f, const char *obj);
/* The rank of dataset obj, or -1. */
int proto_h5in_rank(proto_h5in *f, const char *obj, proto_err *err);
/* Reads dataset obj of the given rank as doubles (any integer or float
 * type). dims[i] in: the size expected, or -1 for any; out: the size found.
 * *out is malloc'ed (caller frees). */
int proto_h5in_read_f8(proto_h5in *f, const char *obj, int rank, int64_t *dims,
                       int64_t max_elems, double **out, proto_err *err);
/* The same as int32 (integer types only; values beyond int32 saturate: the
 * caller checks the range it needs). */
int proto_h5in_read_i4(proto_h5in *f, const char *obj, int rank, int64_t *dims,
                       int64_t max_elems, int32_t **out, proto_err *err);
/* Attribute `name` of object obj: 0 read, 1 absent (out untouched), -1 bad
 * (not one value, wrong type, not finite). Strings are truncated to cap. */
int proto_h5in_attr_f8(proto_h5in *f, const char *obj, const char *name,
                       double *v, proto_err *err);
int proto_h5in_attr_str(proto_h5in *f, const char *obj, const char *name,
                        char *out, size_t cap, proto_err *err);
/* The same, whole (at most 1 MiB): *out malloc'ed, caller frees. */
int proto_h5in_attr_strdup(proto_h5in *f, const char *obj, const char *name,
                           char **out, proto_err *err);
/* Calls fn(name, ctx) for each member of group, in name order; fn returns
 * 0 to go on, 1 to stop, -1 to stop with an error (returned). A missing
 * group is an error. */
int proto_h5in_list(proto_h5in *f, const char *group,
                    int (*fn)(const char *name, void *ctx), void *ctx, proto_err *err);
/* Reads dataset obj as stored (a checkpoint's state, bit for bit): elements
 * exactly f8, i4, i8 or u1, rank 1 to PROTO_MAX_NDIM, at most max_bytes,
 * values as they are (NaN included: a state may hold "not yet" NaNs).
 * *data is malloc'ed (caller frees); *a describes it (data = *data), named
 * by obj's last element. */
int proto_h5in_read_array(proto_h5in *f, const char *obj, size_t max_bytes,
                          proto_array *a, void **data, proto_err *err);

/* XDMF companion: describes snapshot groups of the HDF5 file so ParaView can
 * open them as a time series. Points (grains) or tetrahedra (a mesh). */
typedef struct proto_xdmf proto_xdmf;
typedef enum { PROTO_XDMF_POINTS, PROTO_XDMF_TET4, PROTO_XDMF_TET10,
               PROTO_XDMF_TRI3 } proto_xdmf_topology;
/* h5_name is the HDF5 file name as seen from the XDMF file (same folder). */
proto_xdmf *proto_xdmf_open(const char *path, const char *h5_name,
                            proto_err *err);
/* One time step. geometry: "<group>/x" dataset path ([n,3]); cells: a
 * dataset path of connectivity ([m,4]/[m,10]/[m,3], i4) or NULL for points;
 * attrs: dataset paths with their names taken from the last path element,
 * node-centred if their first dimension is n, else cell-centred. */
int proto_xdmf_step(proto_xdmf *x, const char *grid_name, double t,
                    proto_xdmf_topology topo, int64_t n_nodes,
                    const char *geometry, int64_t n_cells, const char *cells,
                    int n_attrs, const char *const *attrs,
                    const int64_t *attr_cols /* 1 scalar, 3 vector, 6/9 tensor */,
                    const int64_t *attr_rows);
/* Continues an XDMF file this layer wrote: its grids later than t_keep are
 * dropped (a restart recomputes them). A missing file is created. */
proto_xdmf *proto_xdmf_resume(const char *path, const char *h5_name, double t_keep,
                              proto_err *err);
/* Rewrites the closing tags so the file is valid after every step. */
int proto_xdmf_close(proto_xdmf *x);

#endif
