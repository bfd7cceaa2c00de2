/* participant.c — the loop every solver process runs (PROTOCOL.md, "Control
 * channel"): hello → welcome → configure/init → ready → step... → stop.
 * A welcome that offers the coupler's shared-memory segment is answered
 * with ours: from then on large arrays travel in the segments (shm.c).
 * Messages are checked against the role table both ways; the state is saved
 * at each step start when the coupler may repeat steps (implicit scheme) and
 * restored for a repeat; each reply carries the seconds step() took. */
#include "proto.h"

#include <errno.h>
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>
#include <zmq.h>

/* Liveness (PROTOCOL.md "Liveness"): the participant is never silent for
 * longer than PROTO_HEARTBEAT_S. While the main thread waits for the
 * coupler it sends the heartbeats itself; while it computes (configure,
 * init, step, state) a heartbeat thread does, through the same socket under
 * a mutex. That thread reads only the progress record below, never the
 * solver's data: a process that is stopped or dead goes silent, whatever
 * its init or step time. */
#define HEARTBEAT_DUE_S (0.5 * PROTO_HEARTBEAT_S) /* silent this long: send one */
/* The thread sleeps until the next heartbeat is due (it wakes twice a second
 * while the main thread computes, not ten times); when the main thread holds
 * the socket (sending, or waiting: then it sends its own) it looks again
 * after this long, so the silence stays below HEARTBEAT_DUE_S plus the main
 * thread's wait slice (WAIT_SLICE_MS) plus this: 0.95 s, inside the promised
 * PROTO_HEARTBEAT_S (s). */
#define HEARTBEAT_BUSY_RETRY_S (0.2 * PROTO_HEARTBEAT_S)
#define HEARTBEAT_MIN_WAIT_S 1e-3 /* s: never a busy loop */
#define WAIT_SLICE_MS 250                        /* waits poll in slices */
#define WHAT_LEN 96
#define WELCOME_TIMEOUT_S 600.0 /* started by hand: give up on a coupler gone this long */

/* The phases a heartbeat names. */
static const char *const PHASE_WELCOME = "welcome";
static const char *const PHASE_INIT = "init";
static const char *const PHASE_IDLE = "idle";
static const char *const PHASE_STEP = "step";
static const char *const PHASE_STATE = "state";

/* What the heartbeats say: set by the main thread (proto_peer_progress,
 * phase changes), read by the heartbeat thread; guarded by its mutex. */
typedef struct progress_rec {
  pthread_mutex_t lock;
  const char *phase;
  int64_t step;
  double fraction; /* < 0: unknown */
  char what[WHAT_LEN];
} progress_rec;

/* A deep copy of the state arrays at the start of a step (rollback). The
 * arena only grows, so a steady run allocates nothing per step. */
typedef struct state_copy {
  proto_msg live;   /* what state_save added (points at the participant's buffers) */
  proto_msg saved;  /* the same arrays, pointing into arena */
  unsigned char *arena;
  size_t cap;
  int64_t step;     /* the step whose start it holds; -1 = none */
} state_copy;

struct proto_peer {
  void *ctx;
  void *dealer;
  void *bus; /* PUB to the coupler's bus proxy, or NULL */
  char name[PROTO_NAME_LEN];
  proto_role role;
  double idle_timeout_s; /* exit when the coupler is silent this long */
  pid_t parent;          /* the launcher (or wrapper) that started us */
  int rollback;          /* welcome run.rollback: the coupler may repeat steps */
  double run_dt;         /* welcome run.dt: a step request without dt uses it */
  proto_dims dims;       /* the role table's n, m as this conversation bound them */
  state_copy state;
  /* the dealer is shared with the heartbeat thread: io guards it */
  pthread_mutex_t io;
  double last_sent;      /* when anything was last sent (under io) */
  pthread_t hb_thread;
  int hb_started;
  /* the heartbeat thread's sleep, cut short by hb_stop (under hb_lock) */
  pthread_mutex_t hb_lock;
  pthread_cond_t hb_wake; /* on CLOCK_MONOTONIC */
  int hb_stop;
  progress_rec prog;
  int curve_on;          /* CURVE keys from --curve / COSIM_CURVE_FILE */
  proto_curve curve;
  /* shared memory (PROTOCOL.md "Shared memory"): the coupler's segment
   * (read) and ours (written), used once the ready is out */
  proto_shm *shm_in, *shm_out;
  int shm_on;
};

int proto_peer_publish(proto_peer *peer, const proto_msg *m) {
  if (!peer || !peer->bus) return 0;
  return proto_publish(peer->bus, m);
}

void proto_peer_progress(proto_peer *peer, double fraction, const char *what) {
  if (!peer) return;
  pthread_mutex_lock(&peer->prog.lock);
  peer->prog.fraction = fraction > 1 ? 1 : fraction;
  if (what) snprintf(peer->prog.what, sizeof peer->prog.what, "%s", what);
  pthread_mutex_unlock(&peer->prog.lock);
}

/* A new phase clears the progress of the last one. */
static void set_phase(proto_peer *p, const char *phase, int64_t step) {
  pthread_mutex_lock(&p->prog.lock);
  p->prog.phase = phase;
  p->prog.step = step;
  p->prog.fraction = -1;
  p->prog.what[0] = 0;
  pthread_mutex_unlock(&p->prog.lock);
}

void *proto_peer_reply_buffer(proto_peer *peer, size_t nbytes) {
  return peer && peer->shm_on ? proto_shm_next(peer->shm_out, nbytes) : NULL;
}

const char *proto_peer_transport(const proto_peer *peer) {
  return peer && peer->shm_on ? "shm" : "socket";
}

/* Sends on the dealer (large arrays through our segment once shared memory
 * is on); the caller holds io. */
static int send_locked(proto_peer *p, const proto_msg *m, proto_err *err) {
  int rc = proto_send_via(p->dealer, NULL, m, 0, p->shm_on ? p->shm_out : NULL, err);
  if (rc == 0) p->last_sent = proto_now();
  return rc;
}

static int peer_send(proto_peer *p, const proto_msg *m, proto_err *err) {
  pthread_mutex_lock(&p->io);
  int rc = send_locked(p, m, err);
  pthread_mutex_unlock(&p->io);
  return rc;
}

/* One heartbeat with the current progress record; the caller holds io. */
static void heartbeat_locked(proto_peer *p) {
  proto_msg m = {0};
  pthread_mutex_lock(&p->prog.lock);
  progress_rec r = p->prog;
  pthread_mutex_unlock(&p->prog.lock);
  proto_msg_reset(&m, p->name, proto_msg_type(PROTO_MSG_HEARTBEAT), r.step, 0);
  cJSON *h = proto_msg_header(&m);
  cJSON_AddStringToObject(h, PROTO_H_PHASE, r.phase ? r.phase : PHASE_IDLE);
  if (r.fraction >= 0) cJSON_AddNumberToObject(h, PROTO_H_PROGRESS, r.fraction);
  if (r.what[0]) cJSON_AddStringToObject(h, PROTO_H_WHAT, r.what);
  proto_err ignore;
  /* never block on a coupler that does not read: a full queue drops it
   * (and the next one is due an interval later either way) */
  proto_send(p->dealer, &m, ZMQ_DONTWAIT, &ignore);
  p->last_sent = proto_now();
  proto_msg_free(&m);
}

/* A heartbeat if the process has been silent HEARTBEAT_DUE_S (the caller
 * holds io); the seconds until the next one is due. */
static double beat_if_due(proto_peer *p) {
  const double silent = proto_now() - p->last_sent;
  if (silent < HEARTBEAT_DUE_S) return HEARTBEAT_DUE_S - silent;
  heartbeat_locked(p);
  return HEARTBEAT_DUE_S;
}

static void *heartbeat_main(void *arg) {
  proto_peer *p = arg;
  double wait = HEARTBEAT_DUE_S;
  pthread_mutex_lock(&p->hb_lock);
  while (!p->hb_stop) {
    struct timespec until;
    clock_gettime(CLOCK_MONOTONIC, &until);
    const long long ns = until.tv_nsec + (long long)(wait * 1e9);
    until.tv_sec += (time_t)(ns / 1000000000LL);
    until.tv_nsec = (long)(ns % 1000000000LL);
    while (!p->hb_stop && pthread_cond_timedwait(&p->hb_wake, &p->hb_lock, &until) == 0) {
    } /* woken early (the stop, or spuriously): the loop decides */
    if (p->hb_stop) break;
    pthread_mutex_unlock(&p->hb_lock);
    /* busy: the main thread is sending, or waiting (then it sends its own) */
    wait = HEARTBEAT_BUSY_RETRY_S;
    if (pthread_mutex_trylock(&p->io) == 0) {
      wait = beat_if_due(p);
      pthread_mutex_unlock(&p->io);
    }
    if (wait < HEARTBEAT_MIN_WAIT_S) wait = HEARTBEAT_MIN_WAIT_S;
    pthread_mutex_lock(&p->hb_lock);
  }
  pthread_mutex_unlock(&p->hb_lock);
  return NULL;
}

int proto_ready_series(proto_msg *ready, const char *dataset, int ncols,
                       const char *const *columns) {
  cJSON *h = proto_msg_header(ready);
  cJSON *series = cJSON_GetObjectItemCaseSensitive(h, PROTO_H_SERIES);
  if (!series) series = cJSON_AddObjectToObject(h, PROTO_H_SERIES);
  cJSON *cols = cJSON_CreateStringArray(columns, ncols);
  return series && cols && cJSON_AddItemToObject(series, dataset, cols) ? 0 : -1;
}

int proto_ready_snapshot(proto_msg *ready, const char *kind,
                         const char *geometry, const char *cells, int nattrs,
                         const char *const *attributes) {
  cJSON *snap = cJSON_AddObjectToObject(proto_msg_header(ready), PROTO_H_SNAPSHOT);
  if (!snap) return -1;
  cJSON_AddStringToObject(snap, "kind", kind);
  cJSON_AddStringToObject(snap, "geometry", geometry);
  if (cells)
    cJSON_AddStringToObject(snap, "cells", cells);
  else
    cJSON_AddNullToObject(snap, "cells");
  cJSON *attrs = cJSON_CreateStringArray(attributes, nattrs);
  return attrs && cJSON_AddItemToObject(snap, "attributes", attrs) ? 0 : -1;
}

int proto_state_get(const proto_msg *state, const char *name, proto_dtype dtype,
                    size_t count, void *dst, proto_err *err) {
  char full[PROTO_NAME_LEN];
  snprintf(full, sizeof full, "%s%s", PROTO_P_STATE, name);
  const proto_array *a = proto_msg_find(state, full);
  if (!a) return proto_fail(err, "state: missing array '%s'", full);
  size_t want = count * proto_dtype_size(dtype);
  if (a->dtype != dtype || a->nbytes != want)
    return proto_fail(err, "state: array '%s' is %s with %zu bytes, expected %s "
                      "with %zu bytes", full, proto_dtype_name(a->dtype),
                      a->nbytes, proto_dtype_name(dtype), want);
  if (want) memcpy(dst, a->data, want);
  return 0;
}

static void usage(const char *prog, const char *role) {
  fprintf(stderr,
          "usage: %s --endpoint ENDPOINT --name NAME [--curve KEYFILE]\n"
          "       %s --check-config FILE|- [--name NAME]\n"
          "A cosim %s participant. Normally started by `cosim run`, which passes\n"
          "the endpoint; start it by hand for `cosim run --attach` (see README).\n"
          "--curve (or the environment variable " PROTO_ENV_CURVE ") names the key\n"
          "file of a run with security.curve, as `cosim run --attach` prints it.\n"
          "--check-config validates a config section (processes.NAME of a scene,\n"
          "as a JSON object) and exits 0 if it is valid.\n",
          prog, prog, role);
}

typedef struct args {
  const char *endpoint;
  const char *name;
  const char *check;
  const char *curve; /* key file */
} args;

static int parse_args(int argc, char **argv, const proto_participant_ops *ops,
                      args *a) {
  memset(a, 0, sizeof *a);
  a->endpoint = getenv("COSIM_ENDPOINT");
  a->name = getenv("COSIM_NAME");
  a->curve = getenv(PROTO_ENV_CURVE);
  for (int i = 1; i < argc; i++) {
    const char *opt = argv[i];
    const char **dst = strcmp(opt, "--endpoint") == 0       ? &a->endpoint
                       : strcmp(opt, "--name") == 0         ? &a->name
                       : strcmp(opt, "--check-config") == 0 ? &a->check
                       : strcmp(opt, "--curve") == 0        ? &a->curve
                                                            : NULL;
    if (strcmp(opt, "-h") == 0 || strcmp(opt, "--help") == 0) {
      usage(argv[0], proto_role_name(ops->role));
      return 1;
    }
    if (!dst || i + 1 >= argc) {
      fprintf(stderr, "%s: unknown or incomplete option '%s'\n", argv[0], opt);
      usage(argv[0], proto_role_name(ops->role));
      return -1;
    }
    *dst = argv[++i];
  }
  if (!a->name) a->name = proto_role_name(ops->role);
  if (!a->check && !a->endpoint) {
    fprintf(stderr, "%s: --endpoint is required\n", argv[0]);
    usage(argv[0], proto_role_name(ops->role));
    return -1;
  }
  return 0;
}

static int check_config(const args *a, const proto_participant_ops *ops,
                        void *user) {
  proto_err err = {{0}};
  cJSON *section = proto_json_load(a->check, &err); /* "-": stdin */
  char key_path[PROTO_NAME_LEN + 16];
  snprintf(key_path, sizeof key_path, "processes.%s", a->name);
  proto_run_info info = {.name = a->name, .key_path = key_path,
                         .output_dir = "."};
  int rc = section ? ops->configure(user, &info, section, &err) : -1;
  cJSON_Delete(section);
  if (ops->finish) ops->finish(user);
  if (rc < 0) {
    fprintf(stderr, "%s\n", err.msg);
    return 1;
  }
  return 0;
}

static int send_simple(proto_peer *p, const char *type, int64_t step,
                       double t, const char *message) {
  proto_msg m = {0};
  proto_msg_reset(&m, p->name, type, step, t);
  if (message) cJSON_AddStringToObject(proto_msg_header(&m), PROTO_H_MESSAGE, message);
  proto_err err;
  int rc = peer_send(p, &m, &err);
  proto_msg_free(&m);
  return rc;
}

static int launched(void) { return getenv("COSIM_LAUNCHED") != NULL; }

static proto_shm *coupler_segment(void *ctx, const char *identity);

/* Waits for the next message from the coupler, sending heartbeats while it
 * waits; timeout_s <= 0: no limit (a launched participant watches its
 * launcher instead). -1 on timeout or decode error (err says which). */
static int wait_message(proto_peer *p, proto_msg *m, const char *phase,
                        double timeout_s, proto_err *err) {
  set_phase(p, phase, p->prog.step);
  const double began = proto_now();
  double until = timeout_s > 0 ? began + timeout_s : 0;
  while (1) {
    double left = until > 0 ? until - proto_now() : WAIT_SLICE_MS * 1e-3;
    if (left <= 0)
      return proto_fail(err, "the coupler was silent for %.0f s; giving up",
                        timeout_s);
    int slice = left > WAIT_SLICE_MS * 1e-3 ? WAIT_SLICE_MS : (int)(left * 1000) + 1;
    pthread_mutex_lock(&p->io);
    beat_if_due(p);
    proto_shm *bell = p->shm_on ? p->shm_in : NULL;
    int r = proto_wait_in(p->dealer, &bell, 1, slice, began), rc = 0;
    if (r > 0)
      rc = proto_recv_found(p->dealer, r, &bell, m, NULL, p->shm_on ? coupler_segment : NULL,
                            p, err);
    if (r >= 2) proto_shm_ring(p->shm_out); /* the coupler posts: it maps ours, so post too */
    pthread_mutex_unlock(&p->io);
    if (r > 0) return rc;
    /* the launcher (or a wrapper between it and us, e.g. mpirun) is gone */
    if (getppid() != p->parent && launched())
      return proto_fail(err, "the launcher died; exiting");
  }
}

/* The reader of the coupler's segment (the dealer has one sender). */
static proto_shm *coupler_segment(void *ctx, const char *identity) {
  (void)identity;
  return ((proto_peer *)ctx)->shm_in;
}

static const char *json_str(const cJSON *o, const char *key) {
  const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, key);
  return cJSON_IsString(v) ? v->valuestring : NULL;
}

/* A number of the welcome's run object; def if absent, not finite or beyond
 * +-2^53 (the counts among them are converted to integers). */
static double json_num(const cJSON *o, const char *key, double def) {
  const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, key);
  return cJSON_IsNumber(v) && fabs(v->valuedouble) <= PROTO_MAX_HEADER_INT
             ? v->valuedouble : def;
}

/* A welcome that offers the coupler's segment: map it and make ours. The
 * ready says which transport this process takes, and why not shm when the
 * offer could not be taken (then everything stays on the socket). */
static int shm_accept(proto_peer *p, const proto_msg *welcome, proto_msg *ready) {
  const cJSON *seg = cJSON_GetObjectItemCaseSensitive(welcome->header, PROTO_H_SHM_SEGMENT);
  cJSON *h = proto_msg_header(ready);
  if (!seg) return cJSON_AddStringToObject(h, PROTO_H_TRANSPORT, "socket") ? 0 : -1;
  proto_err why = {{0}};
  p->shm_in = proto_shm_reader();
  if (!p->shm_in || proto_shm_attach(p->shm_in, seg, &why) < 0 ||
      !(p->shm_out = proto_shm_writer(PROTO_SHM_INITIAL_BYTES, &why)) ||
      proto_shm_announce(p->shm_out, h) < 0) {
    proto_shm_free(p->shm_in);
    proto_shm_free(p->shm_out);
    p->shm_in = p->shm_out = NULL;
    cJSON_DeleteItemFromObjectCaseSensitive(h, PROTO_H_SHM_SEGMENT);
    cJSON_AddStringToObject(h, PROTO_H_SHM_ERROR, why.msg[0] ? why.msg : "out of memory");
    return cJSON_AddStringToObject(h, PROTO_H_TRANSPORT, "socket") ? 0 : -1;
  }
  return cJSON_AddStringToObject(h, PROTO_H_TRANSPORT, "shm") ? 0 : -1;
}

/* welcome → configure → init → ready. */
static int handshake(proto_peer *p, const proto_participant_ops *ops,
                     void *user, proto_msg *welcome, proto_err *err) {
  /* the welcome may come after the other participants' init (minutes): a
   * launched participant waits as long as its launcher lives */
  double welcome_timeout = launched() ? 0 : WELCOME_TIMEOUT_S;
  const char *env = getenv("COSIM_HANDSHAKE_TIMEOUT");
  if (env) welcome_timeout = atof(env);
  if (wait_message(p, welcome, PHASE_WELCOME, welcome_timeout, err) < 0)
    return proto_wrap(err, "waiting for welcome");
  set_phase(p, PHASE_INIT, 0);
  if (strcmp(welcome->type, proto_msg_type(PROTO_MSG_WELCOME)) != 0)
    return proto_fail(err, "expected 'welcome', got '%s'", welcome->type);
  const cJSON *run = cJSON_GetObjectItemCaseSensitive(welcome->header, PROTO_H_RUN);
  const cJSON *section =
      cJSON_GetObjectItemCaseSensitive(welcome->header, PROTO_H_CONFIG);
  if (!cJSON_IsObject(run) || !cJSON_IsObject(section))
    return proto_fail(err, "welcome lacks 'run' or 'config'");
  if (proto_role_check(p->role, PROTO_MSG_WELCOME, welcome, &p->dims, err) < 0)
    return -1;
  char key_path[PROTO_NAME_LEN + 16];
  snprintf(key_path, sizeof key_path, "processes.%s", p->name);
  const char *outdir = json_str(run, "output_dir");
  p->rollback = cJSON_IsTrue(cJSON_GetObjectItemCaseSensitive(run, PROTO_H_ROLLBACK));
  proto_run_info info = {
      .name = p->name,
      .key_path = key_path,
      .output_dir = outdir ? outdir : ".",
      .dt = json_num(run, PROTO_H_DT, 0),
      .t_end = json_num(run, "t_end", 0),
      .n_steps = (int64_t)json_num(run, "n_steps", 0),
      .output_every = (int64_t)json_num(run, "output_every", 0),
      .rollback = p->rollback,
      .restart_step = (int64_t)json_num(run, PROTO_H_RESTART_STEP, 0),
      .peer = p,
  };
  p->idle_timeout_s = json_num(run, "idle_timeout_s", 600);
  p->run_dt = info.dt;
  const char *bus = json_str(run, "bus");
  if (bus && bus[0]) {
    p->bus = zmq_socket(p->ctx, ZMQ_PUB);
    int hwm = 1000, linger = 0;
    zmq_setsockopt(p->bus, ZMQ_SNDHWM, &hwm, sizeof hwm);
    zmq_setsockopt(p->bus, ZMQ_LINGER, &linger, sizeof linger);
    if (p->curve_on && proto_curve_client(p->bus, &p->curve, err) < 0) return -1;
    if (zmq_connect(p->bus, bus) != 0)
      return proto_fail(err, "cannot connect to bus %s: %s", bus,
                        zmq_strerror(errno));
  }
  if (ops->configure(user, &info, section, err) < 0) return -1;
  proto_msg ready = {0};
  proto_msg_reset(&ready, p->name, proto_msg_type(PROTO_MSG_READY), 0, 0);
  cJSON *h = proto_msg_header(&ready);
  cJSON_AddStringToObject(h, PROTO_H_ROLE, proto_role_name(p->role));
  cJSON_AddBoolToObject(h, PROTO_H_ROLLBACK, ops->state_save && ops->state_load);
  int rc = ops->init ? ops->init(user, welcome, &ready, err) : 0;
  if (rc == 0 && proto_role_check(p->role, PROTO_MSG_READY, &ready, &p->dims, err) < 0)
    rc = proto_wrap(err, "the ready message built by init()");
  if (rc == 0 && shm_accept(p, welcome, &ready) < 0) rc = proto_fail(err, "out of memory");
  if (rc == 0) rc = peer_send(p, &ready, err); /* the ready itself: frames */
  proto_msg_free(&ready);
  p->shm_on = rc == 0 && p->shm_out != NULL;
  return rc;
}

/* Copies what state_save produced into the arena (grown only when needed). */
static int state_take(proto_peer *p, const proto_participant_ops *ops,
                      void *user, int64_t k, proto_err *err) {
  state_copy *c = &p->state;
  proto_msg_reset(&c->live, p->name, proto_msg_type(PROTO_MSG_STATE), k, 0);
  if (ops->state_save(user, &c->live, err) < 0)
    return proto_wrap(err, "state_save at the start of step %lld", (long long)k);
  size_t total = 0, plen = strlen(PROTO_P_STATE);
  for (int i = 0; i < c->live.narrays; i++) {
    if (strncmp(c->live.arrays[i].name, PROTO_P_STATE, plen) != 0)
      return proto_fail(err, "state_save added '%s': state arrays are named "
                         "%s<x>", c->live.arrays[i].name, PROTO_P_STATE);
    total += (c->live.arrays[i].nbytes + 7) & ~(size_t)7;
  }
  if (total > c->cap) {
    unsigned char *bigger = realloc(c->arena, total);
    if (!bigger) return proto_fail(err, "out of memory for a %zu-byte state copy", total);
    c->arena = bigger;
    c->cap = total;
  }
  proto_msg_reset(&c->saved, p->name, proto_msg_type(PROTO_MSG_STATE), k, 0);
  size_t off = 0;
  for (int i = 0; i < c->live.narrays; i++) {
    proto_array a = c->live.arrays[i];
    if (a.nbytes) memcpy(c->arena + off, a.data, a.nbytes);
    a.data = c->arena + off;
    c->saved.arrays[c->saved.narrays++] = a;
    off += (a.nbytes + 7) & ~(size_t)7;
  }
  c->step = k;
  return 0;
}

/* Rollback before a repeat of step k (iteration >= 1). */
static int state_restore(proto_peer *p, const proto_participant_ops *ops,
                         void *user, const proto_step_info *si, proto_err *err) {
  if (!ops->state_load || !p->rollback)
    return proto_fail(err, "the coupler asked for iteration %d of step %lld, but "
                      "%s", si->iteration, (long long)si->k,
                      ops->state_load ? "the welcome did not announce rollback"
                                      : "this participant cannot roll back "
                                        "(no state_save/state_load)");
  if (p->state.step != si->k)
    return proto_fail(err, "iteration %d of step %lld requested, but the saved "
                      "state is that of step %lld", si->iteration,
                      (long long)si->k, (long long)p->state.step);
  if (ops->state_load(user, &p->state.saved, err) < 0)
    return proto_wrap(err, "state_load for iteration %d of step %lld",
                      si->iteration, (long long)si->k);
  return 0;
}

static int parse_step(const proto_peer *p, const proto_msg *req,
                      proto_step_info *si, proto_err *err) {
  const cJSON *h = req->header;
  const cJSON *dt = cJSON_GetObjectItemCaseSensitive(h, PROTO_H_DT);
  double step_dt = dt ? (cJSON_IsNumber(dt) ? dt->valuedouble : -1) : p->run_dt;
  if (!(step_dt > 0) || !isfinite(step_dt))
    return proto_fail(err, "step %lld: header field 'dt' must be a positive "
                      "number", (long long)req->step);
  int64_t iteration;
  if (proto_header_int(req, PROTO_H_ITERATION, 0, INT32_MAX, 0, &iteration, err) < 0)
    return proto_wrap(err, "step %lld", (long long)req->step);
  si->k = req->step;
  si->t = req->t;
  si->dt = step_dt;
  si->t_end = req->t + si->dt;
  si->output = cJSON_IsTrue(cJSON_GetObjectItemCaseSensitive(h, PROTO_H_OUTPUT));
  si->iteration = (int)iteration;
  return 0;
}

/* One step request → rollback if repeated, state copy if first, step(),
 * checks, reply with the compute seconds. */
static int do_step(proto_peer *p, const proto_participant_ops *ops, void *user,
                   const proto_msg *req, proto_msg *reply, proto_err *err) {
  proto_step_info si;
  if (parse_step(p, req, &si, err) < 0) return -1;
  if (proto_role_check(p->role, PROTO_MSG_STEP, req, &p->dims, err) < 0)
    return proto_wrap(err, "step %lld", (long long)si.k);
  double t0 = proto_now();
  set_phase(p, PHASE_STEP, si.k);
  if (si.iteration > 0) {
    if (state_restore(p, ops, user, &si, err) < 0) return -1;
  } else if (p->rollback && ops->state_save) {
    if (state_take(p, ops, user, si.k, err) < 0) return -1;
  }
  proto_msg_reset(reply, p->name, proto_msg_type(PROTO_MSG_DONE), si.k, si.t_end);
  if (ops->step(user, p, &si, req, reply, err) < 0)
    return proto_wrap(err, "step %lld (t = %g s)", (long long)si.k, si.t);
  double compute = proto_now() - t0;
  if (proto_role_check(p->role, PROTO_MSG_DONE, reply, &p->dims, err) < 0)
    return proto_wrap(err, "the reply step() built for step %lld", (long long)si.k);
  cJSON *h = proto_msg_header(reply);
  cJSON_AddNumberToObject(h, PROTO_H_ITERATION, si.iteration);
  cJSON_AddNumberToObject(h, PROTO_H_COMPUTE_S, compute);
  return peer_send(p, reply, err);
}

/* checkpoint → state (the live arrays, zero-copy: valid until the next
 * request, lock-step); restore → restored. */
static int do_state(proto_peer *p, const proto_participant_ops *ops, void *user,
                    const proto_msg *req, proto_msg *reply, proto_err *err) {
  int kind = proto_msg_kind_parse(req->type);
  if (!ops->state_save || !ops->state_load)
    return proto_fail(err, "'%s' requested, but this participant has no "
                      "state_save/state_load", req->type);
  set_phase(p, PHASE_STATE, req->step);
  if (kind == PROTO_MSG_CHECKPOINT) {
    proto_msg_reset(reply, p->name, proto_msg_type(PROTO_MSG_STATE), req->step, req->t);
    if (ops->state_save(user, reply, err) < 0) return proto_wrap(err, "state_save");
  } else {
    if (ops->state_load(user, req, err) < 0) return proto_wrap(err, "state_load");
    proto_msg_reset(reply, p->name, proto_msg_type(PROTO_MSG_RESTORED), req->step, req->t);
    p->state.step = -1;
  }
  return peer_send(p, reply, err);
}

/* Steps until "stop". Returns 0 on a clean stop. */
static int step_loop(proto_peer *p, const proto_participant_ops *ops,
                     void *user, proto_err *err) {
  proto_msg req = {0}, reply = {0};
  int rc = 0;
  while (rc == 0) {
    if (wait_message(p, &req, PHASE_IDLE, p->idle_timeout_s, err) < 0) {
      rc = -1;
      break;
    }
    int kind = proto_msg_kind_parse(req.type);
    if (kind == PROTO_MSG_STOP) {
      send_simple(p, proto_msg_type(PROTO_MSG_BYE), req.step, req.t, NULL);
      break;
    }
    if (kind == PROTO_MSG_STEP)
      rc = do_step(p, ops, user, &req, &reply, err);
    else if (kind == PROTO_MSG_CHECKPOINT || kind == PROTO_MSG_RESTORE)
      rc = do_state(p, ops, user, &req, &reply, err);
    else
      rc = proto_fail(err, "unexpected message '%s' from the coupler", req.type);
  }
  proto_msg_free(&req);
  proto_msg_free(&reply);
  return rc;
}

/* Connects the dealer (a CURVE client when keys are given) and says hello
 * at once, before any long init: the coupler then knows the process lives. */
static int connect_and_hello(proto_peer *p, const args *a, proto_err *err) {
  if (a->curve && a->curve[0]) {
    if (proto_curve_read(a->curve, &p->curve, err) < 0) return -1;
    p->curve_on = 1;
    if (proto_curve_client(p->dealer, &p->curve, err) < 0) return -1;
  }
  if (zmq_connect(p->dealer, a->endpoint) != 0)
    return proto_fail(err, "cannot connect to %s: %s", a->endpoint, zmq_strerror(errno));
  proto_msg hello = {0};
  proto_msg_reset(&hello, p->name, proto_msg_type(PROTO_MSG_HELLO), 0, 0);
  cJSON *h = proto_msg_header(&hello);
  cJSON_AddStringToObject(h, PROTO_H_ROLE, proto_role_name(p->role));
  cJSON_AddStringToObject(h, PROTO_H_NAME, p->name);
  cJSON_AddNumberToObject(h, PROTO_H_PID, (double)getpid());
  cJSON_AddNumberToObject(h, PROTO_H_HEARTBEAT_S, PROTO_HEARTBEAT_S);
  char host[256], boot[64];
  if (proto_shm_host(host, sizeof host, boot, sizeof boot) == 0) {
    /* "this process can map segments, on this host": the coupler's offer */
    cJSON *o = cJSON_AddObjectToObject(h, PROTO_H_HOST);
    cJSON_AddStringToObject(o, "name", host);
    cJSON_AddStringToObject(o, "boot_id", boot);
  }
  int rc = peer_send(p, &hello, err);
  proto_msg_free(&hello);
  if (rc == 0 && pthread_create(&p->hb_thread, NULL, heartbeat_main, p) == 0)
    p->hb_started = 1;
  else if (rc == 0)
    rc = proto_fail(err, "cannot start the heartbeat thread");
  return rc;
}

int proto_participant_main(int argc, char **argv,
                           const proto_participant_ops *ops, void *user) {
  args a;
  int prc = parse_args(argc, argv, ops, &a);
  if (prc != 0) return prc > 0 ? 0 : 2;
  if (a.check) return check_config(&a, ops, user);

  proto_peer p = {0};
  snprintf(p.name, sizeof p.name, "%s", a.name);
  p.role = ops->role;
  p.parent = getppid();
  p.state.step = -1;
  pthread_mutex_init(&p.io, NULL);
  pthread_mutex_init(&p.prog.lock, NULL);
  pthread_mutex_init(&p.hb_lock, NULL);
  pthread_condattr_t hb_attr;
  pthread_condattr_init(&hb_attr);
  pthread_condattr_setclock(&hb_attr, CLOCK_MONOTONIC);
  pthread_cond_init(&p.hb_wake, &hb_attr);
  pthread_condattr_destroy(&hb_attr);
  set_phase(&p, PHASE_WELCOME, 0);
  proto_dims_init(&p.dims);
  p.ctx = zmq_ctx_new();
  p.dealer = zmq_socket(p.ctx, ZMQ_DEALER);
  proto_socket_limits(p.dealer);
  int linger = 2000;
  zmq_setsockopt(p.dealer, ZMQ_LINGER, &linger, sizeof linger);
  zmq_setsockopt(p.dealer, ZMQ_ROUTING_ID, p.name, strlen(p.name));
  proto_err err = {{0}};
  proto_msg welcome = {0};
  int rc = connect_and_hello(&p, &a, &err);
  if (rc == 0) rc = handshake(&p, ops, user, &welcome, &err);
  if (rc == 0) rc = step_loop(&p, ops, user, &err);
  if (rc < 0) {
    fprintf(stderr, "%s (%s): error: %s\n", p.name, proto_role_name(p.role), err.msg);
    send_simple(&p, proto_msg_type(PROTO_MSG_ERROR), 0, 0, err.msg);
  }
  if (p.hb_started) {
    pthread_mutex_lock(&p.hb_lock);
    p.hb_stop = 1;
    pthread_cond_signal(&p.hb_wake);
    pthread_mutex_unlock(&p.hb_lock);
    pthread_join(p.hb_thread, NULL);
  }
  proto_msg_free(&welcome);
  proto_msg_free(&p.state.live);
  proto_msg_free(&p.state.saved);
  free(p.state.arena);
  if (ops->finish) ops->finish(user);
  if (rc == 0 && p.shm_on) { /* what "without a copy" came to (PROTOCOL.md "Shared memory") */
    uint64_t copied = 0, placed = 0;
    proto_shm_counts(p.shm_out, &copied, &placed);
    fprintf(stderr, "%s: shared memory: %llu arrays written in place (zero copy), %.1f MB copied "
            "into the segment\n", p.name, (unsigned long long)placed, 1e-6 * (double)copied);
  }
  proto_shm_free(p.shm_in); /* after every message that may point into it */
  proto_shm_free(p.shm_out);
  if (p.bus) zmq_close(p.bus);
  zmq_close(p.dealer);
  zmq_ctx_term(p.ctx);
  pthread_mutex_destroy(&p.io);
  pthread_mutex_destroy(&p.prog.lock);
  return rc < 0 ? 1 : 0;
}
