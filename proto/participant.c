/* participant.c — the loop every solver process runs (PROTOCOL.md, "Control
 * channel"): hello → welcome → configure/init → ready → step... → stop. */
#include "proto.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <zmq.h>

struct proto_peer {
  void *ctx;
  void *dealer;
  void *bus; /* PUB to the coupler's bus proxy, or NULL */
  char name[PROTO_NAME_LEN];
  double idle_timeout_s; /* exit when the coupler is silent this long */
};

int proto_peer_publish(proto_peer *peer, const proto_msg *m) {
  if (!peer || !peer->bus) return 0;
  return proto_publish(peer->bus, m);
}

int proto_ready_series(proto_msg *ready, const char *dataset, int ncols,
                       const char *const *columns) {
  cJSON *h = proto_msg_header(ready);
  cJSON *series = cJSON_GetObjectItemCaseSensitive(h, "series");
  if (!series) series = cJSON_AddObjectToObject(h, "series");
  cJSON *cols = cJSON_CreateStringArray(columns, ncols);
  return series && cols && cJSON_AddItemToObject(series, dataset, cols) ? 0 : -1;
}

int proto_ready_snapshot(proto_msg *ready, const char *kind,
                         const char *geometry, const char *cells, int nattrs,
                         const char *const *attributes) {
  cJSON *snap = cJSON_AddObjectToObject(proto_msg_header(ready), "snapshot");
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

static void usage(const char *prog, const char *role) {
  fprintf(stderr,
          "usage: %s --endpoint ENDPOINT --name NAME\n"
          "       %s --check-config FILE|- [--name NAME]\n"
          "A cosim %s participant. Normally started by `cosim run`, which passes\n"
          "the endpoint; start it by hand for `cosim run --attach` (see README).\n"
          "--check-config validates a config section (processes.NAME of a scene,\n"
          "as a JSON object) and exits 0 if it is valid.\n",
          prog, prog, role);
}

typedef struct args {
  const char *endpoint;
  const char *name;
  const char *check;
} args;

static int parse_args(int argc, char **argv, const proto_participant_ops *ops,
                      args *a) {
  memset(a, 0, sizeof *a);
  a->endpoint = getenv("COSIM_ENDPOINT");
  a->name = getenv("COSIM_NAME");
  for (int i = 1; i < argc; i++) {
    const char *opt = argv[i];
    const char **dst = strcmp(opt, "--endpoint") == 0       ? &a->endpoint
                       : strcmp(opt, "--name") == 0         ? &a->name
                       : strcmp(opt, "--check-config") == 0 ? &a->check
                                                            : NULL;
    if (strcmp(opt, "-h") == 0 || strcmp(opt, "--help") == 0) {
      usage(argv[0], ops->role);
      return 1;
    }
    if (!dst || i + 1 >= argc) {
      fprintf(stderr, "%s: unknown or incomplete option '%s'\n", argv[0], opt);
      usage(argv[0], ops->role);
      return -1;
    }
    *dst = argv[++i];
  }
  if (!a->name) a->name = ops->role;
  if (!a->check && !a->endpoint) {
    fprintf(stderr, "%s: --endpoint is required\n", argv[0]);
    usage(argv[0], ops->role);
    return -1;
  }
  return 0;
}

static int check_config(const args *a, const proto_participant_ops *ops,
                        void *user) {
  proto_err err = {{0}};
  cJSON *section = NULL;
  if (strcmp(a->check, "-") == 0) {
    size_t cap = 1 << 16, len = 0;
    char *text = malloc(cap);
    size_t got;
    while (text && (got = fread(text + len, 1, cap - len - 1, stdin)) > 0) {
      len += got;
      if (len + 1 == cap) text = realloc(text, cap *= 2);
    }
    if (!text) {
      fprintf(stderr, "out of memory\n");
      return 1;
    }
    text[len] = 0;
    section = proto_json_parse(text, "<stdin>", &err);
    free(text);
  } else {
    section = proto_json_load(a->check, &err);
  }
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
  if (message) cJSON_AddStringToObject(proto_msg_header(&m), "message", message);
  proto_err err;
  int rc = proto_send(p->dealer, &m, 0, &err);
  proto_msg_free(&m);
  return rc;
}

/* Waits for the next message from the coupler; -1 on timeout or decode error
 * (err says which). */
static int wait_message(proto_peer *p, proto_msg *m, double timeout_s,
                        proto_err *err) {
  double until = proto_now() + timeout_s;
  while (1) {
    double left = until - proto_now();
    if (left <= 0)
      return proto_fail(err, "the coupler was silent for %.0f s; giving up",
                        timeout_s);
    int r = proto_poll_in(p->dealer, left > 0.25 ? 250 : (int)(left * 1000) + 1);
    if (r > 0) return proto_recv(p->dealer, m, NULL, err);
    if (getppid() == 1 && getenv("COSIM_LAUNCHED"))
      return proto_fail(err, "the launcher died; exiting");
  }
}

static const char *json_str(const cJSON *o, const char *key) {
  const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, key);
  return cJSON_IsString(v) ? v->valuestring : NULL;
}

static double json_num(const cJSON *o, const char *key, double def) {
  const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, key);
  return cJSON_IsNumber(v) ? v->valuedouble : def;
}

/* welcome → configure → init → ready. */
static int handshake(proto_peer *p, const proto_participant_ops *ops,
                     void *user, proto_msg *welcome, proto_err *err) {
  double hello_timeout = 30;
  const char *env = getenv("COSIM_HANDSHAKE_TIMEOUT");
  if (env) hello_timeout = atof(env);
  if (wait_message(p, welcome, hello_timeout, err) < 0)
    return proto_wrap(err, "waiting for welcome");
  if (strcmp(welcome->type, "welcome") != 0)
    return proto_fail(err, "expected 'welcome', got '%s'", welcome->type);
  const cJSON *run = cJSON_GetObjectItemCaseSensitive(welcome->header, "run");
  const cJSON *section =
      cJSON_GetObjectItemCaseSensitive(welcome->header, "config");
  if (!cJSON_IsObject(run) || !cJSON_IsObject(section))
    return proto_fail(err, "welcome lacks 'run' or 'config'");
  char key_path[PROTO_NAME_LEN + 16];
  snprintf(key_path, sizeof key_path, "processes.%s", p->name);
  const char *outdir = json_str(run, "output_dir");
  proto_run_info info = {
      .name = p->name,
      .key_path = key_path,
      .output_dir = outdir ? outdir : ".",
      .dt = json_num(run, "dt", 0),
      .t_end = json_num(run, "t_end", 0),
      .n_steps = (int64_t)json_num(run, "n_steps", 0),
      .output_every = (int64_t)json_num(run, "output_every", 0),
  };
  p->idle_timeout_s = json_num(run, "idle_timeout_s", 600);
  const char *bus = json_str(run, "bus");
  if (bus && bus[0]) {
    p->bus = zmq_socket(p->ctx, ZMQ_PUB);
    int hwm = 1000, linger = 0;
    zmq_setsockopt(p->bus, ZMQ_SNDHWM, &hwm, sizeof hwm);
    zmq_setsockopt(p->bus, ZMQ_LINGER, &linger, sizeof linger);
    if (zmq_connect(p->bus, bus) != 0)
      return proto_fail(err, "cannot connect to bus %s: %s", bus,
                        zmq_strerror(errno));
  }
  if (ops->configure(user, &info, section, err) < 0) return -1;
  proto_msg ready = {0};
  proto_msg_reset(&ready, p->name, "ready", 0, 0);
  cJSON_AddStringToObject(proto_msg_header(&ready), "role", ops->role);
  int rc = ops->init ? ops->init(user, welcome, &ready, err) : 0;
  if (rc == 0) rc = proto_send(p->dealer, &ready, 0, err);
  proto_msg_free(&ready);
  return rc;
}

/* Steps until "stop". Returns 0 on a clean stop. */
static int step_loop(proto_peer *p, const proto_participant_ops *ops,
                     void *user, proto_err *err) {
  proto_msg req = {0}, reply = {0};
  int rc = 0;
  while (rc == 0) {
    if (wait_message(p, &req, p->idle_timeout_s, err) < 0) {
      rc = -1;
      break;
    }
    if (strcmp(req.type, "stop") == 0) {
      send_simple(p, "bye", req.step, req.t, NULL);
      break;
    }
    if (strcmp(req.type, "step") != 0) {
      rc = proto_fail(err, "unexpected message '%s' from the coupler", req.type);
      break;
    }
    double dt = json_num(req.header, "dt", 0);
    proto_msg_reset(&reply, p->name, "done", req.step, req.t + dt);
    rc = ops->step(user, p, &req, &reply, err);
    if (rc < 0) proto_wrap(err, "step %lld (t = %g s)", (long long)req.step, req.t);
    if (rc == 0) rc = proto_send(p->dealer, &reply, 0, err);
  }
  proto_msg_free(&req);
  proto_msg_free(&reply);
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
  p.ctx = zmq_ctx_new();
  p.dealer = zmq_socket(p.ctx, ZMQ_DEALER);
  int linger = 2000;
  zmq_setsockopt(p.dealer, ZMQ_LINGER, &linger, sizeof linger);
  zmq_setsockopt(p.dealer, ZMQ_ROUTING_ID, p.name, strlen(p.name));
  proto_err err = {{0}};
  proto_msg welcome = {0};
  int rc = 0;
  if (zmq_connect(p.dealer, a.endpoint) != 0) {
    rc = proto_fail(&err, "cannot connect to %s: %s", a.endpoint,
                    zmq_strerror(errno));
  } else {
    proto_msg hello = {0};
    proto_msg_reset(&hello, p.name, "hello", 0, 0);
    cJSON_AddStringToObject(proto_msg_header(&hello), "role", ops->role);
    cJSON_AddStringToObject(proto_msg_header(&hello), "name", p.name);
    cJSON_AddNumberToObject(proto_msg_header(&hello), "pid", (double)getpid());
    rc = proto_send(p.dealer, &hello, 0, &err);
    proto_msg_free(&hello);
  }
  if (rc == 0) rc = handshake(&p, ops, user, &welcome, &err);
  if (rc == 0) rc = step_loop(&p, ops, user, &err);
  if (rc < 0) {
    fprintf(stderr, "%s (%s): error: %s\n", p.name, ops->role, err.msg);
    send_simple(&p, "error", 0, 0, err.msg);
  }
  proto_msg_free(&welcome);
  if (ops->finish) ops->finish(user);
  if (p.bus) zmq_close(p.bus);
  zmq_close(p.dealer);
  zmq_ctx_term(p.ctx);
  return rc < 0 ? 1 : 0;
}
