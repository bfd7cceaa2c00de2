/* monitor.c — `cosim monitor ENDPOINT`: tails the bus in a terminal. One line
 * per message: topic, type, step, t, and each array (first values). */
#include "internal.h"

#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <zmq.h>

static volatile sig_atomic_t stop_monitor = 0;
static void on_int(int sig) { (void)sig; stop_monitor = 1; }

static void print_array(const proto_array *a) {
  printf(" %s[", a->name);
  for (int d = 0; d < a->ndim; d++)
    printf("%s%lld", d ? "," : "", (long long)a->shape[d]);
  printf("]=");
  int64_t n = (int64_t)(a->nbytes / (a->dtype == PROTO_I4 ? 4 : a->dtype == PROTO_U1 ? 1 : 8));
  for (int64_t i = 0; i < n && i < 8; i++) {
    if (a->dtype == PROTO_F8) printf("%s%.6g", i ? "," : "", ((const double *)a->data)[i]);
    else if (a->dtype == PROTO_I4) printf("%s%d", i ? "," : "", ((const int32_t *)a->data)[i]);
    else if (a->dtype == PROTO_I8) printf("%s%lld", i ? "," : "", (long long)((const int64_t *)a->data)[i]);
    else printf("%s%u", i ? "," : "", ((const unsigned char *)a->data)[i]);
  }
  if (n > 8) printf(",...");
}

/* What a monitor needs to know of a run, from OUTPUT_DIR/endpoints.json:
 * the monitor stream, the snapshot stream, and with CURVE the key file. */
typedef struct run_eps {
  char monitor[CPL_PATH_LEN], snapshots[CPL_PATH_LEN], key_file[CPL_PATH_LEN];
} run_eps;

static void copy_str(const cJSON *o, const char *key, char *out, size_t cap) {
  const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, key);
  snprintf(out, cap, "%s", cJSON_IsString(v) ? v->valuestring : "");
}

static int endpoints_from_dir(const char *dir, run_eps *e) {
  char path[CPL_PATH_LEN + 32];
  snprintf(path, sizeof path, "%s/%s", dir, CPL_ENDPOINTS_FILE);
  proto_err err = {{0}};
  cJSON *o = proto_json_load(path, &err);
  if (o) {
    copy_str(o, "bus_monitor", e->monitor, sizeof e->monitor);
    copy_str(o, "bus_snapshots", e->snapshots, sizeof e->snapshots);
    copy_str(o, "monitor_key_file", e->key_file, sizeof e->key_file);
  }
  int rc = e->monitor[0] ? 0 : -1;
  if (o && rc < 0)
    fprintf(stderr, "cosim monitor: %s: the run has no monitor bus (bus.monitor)\n", path);
  else if (!o)
    fprintf(stderr, "cosim monitor: '%s' is neither an endpoint (tcp://, ipc://) "
            "nor a run's output directory: %s\n", dir, err.msg);
  cJSON_Delete(o);
  return rc;
}

/* Connects sub to the run's streams, as a CURVE client if keys are given. */
static int connect_sub(void *sub, const run_eps *e) {
  proto_err err = {{0}};
  proto_curve keys;
  if (e->key_file[0] && (proto_curve_read(e->key_file, &keys, &err) < 0 ||
                         proto_curve_client(sub, &keys, &err) < 0)) {
    fprintf(stderr, "cosim monitor: %s\n", err.msg);
    return -1;
  }
  const char *eps[] = {e->monitor, e->snapshots};
  for (int i = 0; i < 2; i++)
    if (eps[i][0] && zmq_connect(sub, eps[i]) != 0) {
      fprintf(stderr, "cosim monitor: cannot connect to %s: %s\n", eps[i],
              zmq_strerror(zmq_errno()));
      return -1;
    }
  return 0;
}

int cpl_monitor_main(int argc, char **argv) {
  const char *endpoint = NULL;
  const char *topics[16];
  int ntopics = 0;
  long count = -1;
  double timeout = -1;
  const char *curve = NULL;
  for (int i = 1; i < argc; i++) {
    if (strcmp(argv[i], "--topic") == 0 && i + 1 < argc && ntopics < 16)
      topics[ntopics++] = argv[++i];
    else if (strcmp(argv[i], "--count") == 0 && i + 1 < argc)
      count = atol(argv[++i]);
    else if (strcmp(argv[i], "--timeout") == 0 && i + 1 < argc)
      timeout = atof(argv[++i]);
    else if (strcmp(argv[i], "--curve") == 0 && i + 1 < argc)
      curve = argv[++i];
    else if (argv[i][0] != '-' && !endpoint)
      endpoint = argv[i];
    else {
      fprintf(stderr, "usage: cosim monitor ENDPOINT|OUTPUT_DIR [--topic PREFIX]... "
              "[--count N] [--timeout S] [--curve KEYFILE]\n");
      return 1;
    }
  }
  if (!endpoint) {
    fprintf(stderr, "cosim monitor: ENDPOINT (the scene's bus.monitor) or a run's "
            "output directory is required\n");
    return 1;
  }
  run_eps eps = {{0}, {0}, {0}};
  if (!strstr(endpoint, "://")) { /* a run's output.dir: both streams, its keys */
    if (endpoints_from_dir(endpoint, &eps) < 0) return 1;
  } else {
    snprintf(eps.monitor, sizeof eps.monitor, "%s", endpoint);
  }
  if (curve) snprintf(eps.key_file, sizeof eps.key_file, "%s", curve);
  signal(SIGINT, on_int);
  signal(SIGTERM, on_int);
  void *ctx = zmq_ctx_new(), *sub = zmq_socket(ctx, ZMQ_SUB);
  proto_socket_limits(sub);
  int linger = 0;
  zmq_setsockopt(sub, ZMQ_LINGER, &linger, sizeof linger);
  if (ntopics == 0) zmq_setsockopt(sub, ZMQ_SUBSCRIBE, "", 0);
  for (int i = 0; i < ntopics; i++)
    zmq_setsockopt(sub, ZMQ_SUBSCRIBE, topics[i], strlen(topics[i]));
  if (connect_sub(sub, &eps) < 0) {
    zmq_close(sub);
    zmq_ctx_term(ctx);
    return 1;
  }
  proto_msg m = {0};
  proto_err err;
  long seen = 0;
  double until = timeout > 0 ? proto_now() + timeout : 0;
  while (!stop_monitor && (count < 0 || seen < count) &&
         (until == 0 || proto_now() < until)) {
    if (proto_poll_in(sub, 200) <= 0) continue;
    if (proto_recv(sub, &m, NULL, &err) < 0) {
      printf("! %s\n", err.msg);
      continue;
    }
    printf("%s %s step=%lld t=%.6g", m.topic, m.type, (long long)m.step, m.t);
    for (int i = 0; i < m.narrays; i++) print_array(&m.arrays[i]);
    printf("\n");
    fflush(stdout);
    seen++;
  }
  proto_msg_free(&m);
  zmq_close(sub);
  zmq_ctx_term(ctx);
  return 0;
}
