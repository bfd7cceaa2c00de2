/* proto_participant.h — proto's participants: the handshake/step loop, CURVE keys.
 * Part of proto.h, the one public header: include "proto/proto.h", not this. */
#ifndef COSIM_PROTO_PARTICIPANT_H
#define COSIM_PROTO_PARTICIPANT_H
#ifndef COSIM_PROTO_H
#error "include proto/proto.h, not proto_participant.h"
#endif

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
/* Zero copy (PROTOCOL.md "Shared memory"): when this process's arrays travel
 * by shared memory, the start of the buffer its next message is written to
 * (nbytes fit; 8-byte aligned: carve several arrays at offsets that are
 * multiples of 8), else NULL. An array of a reply added from there is sent
 * without a copy; valid until that reply is sent. */
void *proto_peer_reply_buffer(proto_peer *peer, size_t nbytes);
/* "shm" or "socket": how this process's arrays travel (after the handshake). */
const char *proto_peer_transport(const proto_peer *peer);
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

#endif
