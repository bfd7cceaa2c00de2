/* bus.c — the monitor bus: a proxy in its own thread. Publishers (the
 * coupler, participants) connect to the XSUB side; monitors subscribe on two
 * XPUB sides: the monitor stream (progress, series, timing, summaries:
 * small messages) and the snapshot stream (snapshots, and any message larger
 * than BUS_SMALL_MAX). XPUB drops for a subscriber whose queue is full, so a
 * slow or dead monitor never slows the run; the split bounds what one can
 * make the run queue and send in bytes, not only in messages: at most
 * bus.hwm small messages and bus.snapshot_hwm snapshots (a monitor that
 * subscribes to everything on the monitor stream gets no snapshots at all:
 * those cost the run most, bench/results/reliability.md). */
#include "internal.h"

#include <errno.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <zmq.h>

#define BUS_SMALL_MAX (64 << 10) /* bytes: larger messages go to the snapshot stream */
#define BUS_MAX_PARTS (PROTO_MAX_ARRAYS + 2) /* topic, header, arrays */
#define SNAPSHOT_SUFFIX ".snapshot"

struct cpl_bus {
  void *xsub, *xpub, *xsnap, *control_thread, *control_main, *pub;
  pthread_t thread;
  int started;
};

static const char *const TERMINATE = "TERMINATE";

/* Forwards one whole message (all its parts) from `from` to `to`. */
static void forward(void *from, void *to) {
  int more = 1;
  while (more) {
    zmq_msg_t m;
    zmq_msg_init(&m);
    if (zmq_msg_recv(&m, from, 0) < 0) {
      zmq_msg_close(&m);
      return;
    }
    more = zmq_msg_more(&m);
    if (zmq_msg_send(&m, to, (more ? ZMQ_SNDMORE : 0) | ZMQ_DONTWAIT) < 0) zmq_msg_close(&m);
  }
}

static int is_snapshot(const zmq_msg_t *topic) {
  size_t n = zmq_msg_size(topic), k = strlen(SNAPSHOT_SUFFIX);
  return n >= k && memcmp((const char *)zmq_msg_data((zmq_msg_t *)topic) + n - k,
                          SNAPSHOT_SUFFIX, k) == 0;
}

/* One published message: read whole, then sent to the stream it belongs to
 * (parts beyond BUS_MAX_PARTS are dropped with the message). */
static void route(cpl_bus *b) {
  zmq_msg_t parts[BUS_MAX_PARTS];
  int n = 0, more = 1, over = 0;
  size_t bytes = 0;
  while (more) {
    zmq_msg_t scratch, *m = n < BUS_MAX_PARTS ? &parts[n] : &scratch;
    zmq_msg_init(m);
    if (zmq_msg_recv(m, b->xsub, 0) < 0) {
      zmq_msg_close(m);
      over = 1;
      break;
    }
    more = zmq_msg_more(m);
    bytes += zmq_msg_size(m);
    if (m == &scratch) {
      zmq_msg_close(m);
      over = 1;
    } else {
      n++;
    }
  }
  void *to = n > 0 && (is_snapshot(&parts[0]) || bytes > BUS_SMALL_MAX) ? b->xsnap : b->xpub;
  for (int i = 0; i < n; i++) {
    if (over || zmq_msg_send(&parts[i], to, (i + 1 < n ? ZMQ_SNDMORE : 0) | ZMQ_DONTWAIT) < 0)
      zmq_msg_close(&parts[i]);
  }
}

static void *proxy_thread(void *arg) {
  cpl_bus *b = arg;
  zmq_pollitem_t items[] = {{b->control_thread, 0, ZMQ_POLLIN, 0},
                            {b->xsub, 0, ZMQ_POLLIN, 0},
                            {b->xpub, 0, ZMQ_POLLIN, 0},
                            {b->xsnap, 0, ZMQ_POLLIN, 0}};
  while (zmq_poll(items, 4, -1) >= 0 || zmq_errno() == EINTR) {
    if (items[0].revents & ZMQ_POLLIN) break; /* TERMINATE */
    if (items[1].revents & ZMQ_POLLIN) route(b);
    /* subscriptions of either stream go upstream to the publishers */
    if (items[2].revents & ZMQ_POLLIN) forward(b->xpub, b->xsub);
    if (items[3].revents & ZMQ_POLLIN) forward(b->xsnap, b->xsub);
  }
  return NULL;
}

static int bind_ep(void *s, char *ep, const char *key, proto_err *err) {
  if (zmq_bind(s, ep) != 0)
    return proto_fail(err, "bus.%s: cannot bind %s: %s", key, ep, zmq_strerror(errno));
  size_t len = CPL_PATH_LEN;
  if (zmq_getsockopt(s, ZMQ_LAST_ENDPOINT, ep, &len) != 0) ep[0] = 0;
  return 0;
}

static int secure(void *s, const char *secret, const char *domain, proto_err *err) {
  return secret ? proto_curve_server(s, secret, domain, err) : 0;
}

cpl_bus *cpl_bus_start(void *ctx, cpl_bus_eps *eps, int hwm, int snapshot_hwm,
                       const char *curve_secret, proto_err *err) {
  cpl_bus *b = calloc(1, sizeof *b);
  if (!b) return NULL;
  int linger = 0;
  b->xsub = zmq_socket(ctx, ZMQ_XSUB);
  proto_socket_limits(b->xsub);
  b->xpub = zmq_socket(ctx, ZMQ_XPUB);
  b->xsnap = zmq_socket(ctx, ZMQ_XPUB);
  b->control_thread = zmq_socket(ctx, ZMQ_PAIR);
  b->control_main = zmq_socket(ctx, ZMQ_PAIR);
  b->pub = zmq_socket(ctx, ZMQ_PUB);
  void *all[] = {b->xsub, b->xpub, b->xsnap, b->control_thread, b->control_main, b->pub};
  for (int i = 0; i < 6; i++) zmq_setsockopt(all[i], ZMQ_LINGER, &linger, sizeof linger);
  zmq_setsockopt(b->xpub, ZMQ_SNDHWM, &hwm, sizeof hwm);
  zmq_setsockopt(b->xsnap, ZMQ_SNDHWM, &snapshot_hwm, sizeof snapshot_hwm);
  zmq_setsockopt(b->pub, ZMQ_SNDHWM, &hwm, sizeof hwm);
  char ctl[64], own[64];
  snprintf(ctl, sizeof ctl, "inproc://cosim-bus-control-%p", (void *)b);
  snprintf(own, sizeof own, "inproc://cosim-bus-in-%p", (void *)b);
  int ok = secure(b->xsub, curve_secret, CPL_ZAP_BUS, err) == 0 &&
           secure(b->xpub, curve_secret, CPL_ZAP_MONITOR, err) == 0 &&
           secure(b->xsnap, curve_secret, CPL_ZAP_MONITOR, err) == 0 &&
           bind_ep(b->xsub, eps->inner, "inner", err) == 0 &&
           bind_ep(b->xpub, eps->monitor, "monitor", err) == 0 &&
           bind_ep(b->xsnap, eps->snapshots, "snapshots", err) == 0;
  /* the coupler's own publisher: inproc, which CURVE does not apply to */
  if (!ok || zmq_bind(b->xsub, own) != 0 || zmq_bind(b->control_thread, ctl) != 0 ||
      zmq_connect(b->control_main, ctl) != 0 || zmq_connect(b->pub, own) != 0) {
    if (ok) proto_fail(err, "bus: cannot set up its inproc sockets");
    cpl_bus_stop(b);
    return NULL;
  }
  if (pthread_create(&b->thread, NULL, proxy_thread, b) != 0) {
    proto_fail(err, "bus: cannot start the proxy thread");
    cpl_bus_stop(b);
    return NULL;
  }
  b->started = 1;
  return b;
}

void *cpl_bus_pub(cpl_bus *b) { return b ? b->pub : NULL; }

void cpl_bus_stop(cpl_bus *b) {
  if (!b) return;
  if (b->started) {
    zmq_send(b->control_main, TERMINATE, strlen(TERMINATE), 0);
    pthread_join(b->thread, NULL);
  }
  zmq_close(b->pub);
  zmq_close(b->control_main);
  zmq_close(b->control_thread);
  zmq_close(b->xsnap);
  zmq_close(b->xpub);
  zmq_close(b->xsub);
  free(b);
}
