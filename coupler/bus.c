/* bus.c — the monitor bus: an XSUB/XPUB proxy in its own thread. Publishers
 * (the coupler, participants) connect to the XSUB side; monitors subscribe
 * on the XPUB side. XPUB drops for a subscriber whose queue is full, so a
 * slow or dead monitor never slows the run. */
#include "internal.h"

#include <errno.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <zmq.h>

struct cpl_bus {
  void *xsub, *xpub, *control_thread, *control_main, *pub;
  pthread_t thread;
  int started;
};

static void *proxy_thread(void *arg) {
  cpl_bus *b = arg;
  zmq_proxy_steerable(b->xsub, b->xpub, NULL, b->control_thread);
  return NULL;
}

static int bind_or_fail(void *s, const char *ep, proto_err *err) {
  if (zmq_bind(s, ep) == 0) return 0;
  return proto_fail(err, "bus: cannot bind %s: %s", ep, zmq_strerror(errno));
}

static void bound(void *s, char *out, size_t cap) {
  size_t len = cap;
  if (zmq_getsockopt(s, ZMQ_LAST_ENDPOINT, out, &len) != 0 && cap) out[0] = 0;
}

cpl_bus *cpl_bus_start(void *ctx, const char *inner, const char *public_ep,
                       int hwm, char *inner_out, char *public_out, size_t cap,
                       proto_err *err) {
  cpl_bus *b = calloc(1, sizeof *b);
  if (!b) return NULL;
  int linger = 0;
  b->xsub = zmq_socket(ctx, ZMQ_XSUB);
  proto_socket_limits(b->xsub);
  b->xpub = zmq_socket(ctx, ZMQ_XPUB);
  b->control_thread = zmq_socket(ctx, ZMQ_PAIR);
  b->control_main = zmq_socket(ctx, ZMQ_PAIR);
  b->pub = zmq_socket(ctx, ZMQ_PUB);
  void *all[] = {b->xsub, b->xpub, b->control_thread, b->control_main, b->pub};
  for (int i = 0; i < 5; i++)
    zmq_setsockopt(all[i], ZMQ_LINGER, &linger, sizeof linger);
  zmq_setsockopt(b->xpub, ZMQ_SNDHWM, &hwm, sizeof hwm);
  zmq_setsockopt(b->pub, ZMQ_SNDHWM, &hwm, sizeof hwm);
  char ctl[64];
  snprintf(ctl, sizeof ctl, "inproc://cosim-bus-control-%p", (void *)b);
  char own[64];
  snprintf(own, sizeof own, "inproc://cosim-bus-in-%p", (void *)b);
  int ok = bind_or_fail(b->xsub, inner, err) == 0;
  if (ok) bound(b->xsub, inner_out, cap);
  ok = ok && bind_or_fail(b->xpub, public_ep, err) == 0;
  if (ok) bound(b->xpub, public_out, cap);
  if (!ok || bind_or_fail(b->xsub, own, err) < 0 ||
      bind_or_fail(b->control_thread, ctl, err) < 0 ||
      zmq_connect(b->control_main, ctl) != 0 || zmq_connect(b->pub, own) != 0) {
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
    zmq_send(b->control_main, "TERMINATE", 9, 0);
    pthread_join(b->thread, NULL);
  }
  zmq_close(b->pub);
  zmq_close(b->control_main);
  zmq_close(b->control_thread);
  zmq_close(b->xpub);
  zmq_close(b->xsub);
  free(b);
}
