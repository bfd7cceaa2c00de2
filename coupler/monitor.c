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

/* The monitor endpoint a run bound, from OUTPUT_DIR/endpoints.json. */
static int endpoint_from_dir(const char *dir, char *out, size_t cap) {
  char path[CPL_PATH_LEN + 32];
  snprintf(path, sizeof path, "%s/%s", dir, CPL_ENDPOINTS_FILE);
  proto_err err = {{0}};
  cJSON *o = proto_json_load(path, &err);
  const cJSON *bus = o ? cJSON_GetObjectItemCaseSensitive(o, "bus_monitor") : NULL;
  int rc = cJSON_IsString(bus) && bus->valuestring[0] ? 0 : -1;
  if (rc == 0) snprintf(out, cap, "%s", bus->valuestring);
  else if (o)
    fprintf(stderr, "cosim monitor: %s: the run has no monitor bus (bus.monitor)\n", path);
  else
    fprintf(stderr, "cosim monitor: '%s' is neither an endpoint (tcp://, ipc://) "
            "nor a run's output directory: %s\n", dir, err.msg);
  cJSON_Delete(o);
  return rc;
}

int cpl_monitor_main(int argc, char **argv) {
  const char *endpoint = NULL;
  const char *topics[16];
  int ntopics = 0;
  long count = -1;
  double timeout = -1;
  for (int i = 1; i < argc; i++) {
    if (strcmp(argv[i], "--topic") == 0 && i + 1 < argc && ntopics < 16)
      topics[ntopics++] = argv[++i];
    else if (strcmp(argv[i], "--count") == 0 && i + 1 < argc)
      count = atol(argv[++i]);
    else if (strcmp(argv[i], "--timeout") == 0 && i + 1 < argc)
      timeout = atof(argv[++i]);
    else if (argv[i][0] != '-' && !endpoint)
      endpoint = argv[i];
    else {
      fprintf(stderr, "usage: cosim monitor ENDPOINT [--topic PREFIX]... "
              "[--count N] [--timeout S]\n");
      return 1;
    }
  }
  if (!endpoint) {
    fprintf(stderr, "cosim monitor: ENDPOINT (the scene's bus.monitor) or a run's "
            "output directory is required\n");
    return 1;
  }
  char found[CPL_PATH_LEN];
  if (!strstr(endpoint, "://")) { /* a run's output.dir: its endpoints.json */
    if (endpoint_from_dir(endpoint, found, sizeof found) < 0) return 1;
    endpoint = found;
  }
  signal(SIGINT, on_int);
  signal(SIGTERM, on_int);
  void *ctx = zmq_ctx_new(), *sub = zmq_socket(ctx, ZMQ_SUB);
  proto_socket_limits(sub);
  int linger = 0;
  zmq_setsockopt(sub, ZMQ_LINGER, &linger, sizeof linger);
  if (ntopics == 0) zmq_setsockopt(sub, ZMQ_SUBSCRIBE, "", 0);
  for (int i = 0; i < ntopics; i++)
    zmq_setsockopt(sub, ZMQ_SUBSCRIBE, topics[i], strlen(topics[i]));
  if (zmq_connect(sub, endpoint) != 0) {
    fprintf(stderr, "cosim monitor: cannot connect to %s: %s\n", endpoint,
            zmq_strerror(zmq_errno()));
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
