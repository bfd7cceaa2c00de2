/* bus.c — the monitor bus: a proxy in its own thread. Publishers (the
 * coupler, participants) connect to the XSUB side; monitors subscribe on two
 * XPUB sides: the monitor stream (progress, series, timing, summaries:
 * small messages) and the snapshot stream (snapshots, and any message larger
 * than BUS_SMALL_MAX). XPUB drops for a subscriber whose queue is full, so a
 * slow or dead monitor never slows the run; the split bounds what one can
 * make the run queue and send in bytes, not only in messages: at most
 * bus.hwm small messages and bus.snapshot_hwm snapshots (a monitor that
 * subscribes to everything on the monitor stream gets no snapshots at all:
 * those cost the run most, bench/results/reliability.md).
 *
 * Off the loop's way: the bus has a ZeroMQ context of its own whose I/O
 * thread (every write to every monitor, CURVE's cipher for them, reading
 * the participants' publications) and the proxy thread run at low
 * priority (nice BUS_NICE): when the run wants the CPU they get a tenth of
 * a core, so however many monitors there are and whatever they do, the
 * coupler's loop and the participants are not held up by them; when a core
 * is idle the bus runs at full speed. The loop's side is one copy into an
 * inproc PUB that never blocks (it drops at bus.hwm); when the machine is
 * busy the bus falls behind and drops, not the run (issue 25). Not
 * SCHED_IDLE nor nice 19: on a node whose every core runs the run the bus
 * would get next to nothing and a live page would stand still.
 * ZAP is per context: with CURVE the bus starts a ZAP handler of its own on
 * its context with the run's keys (zap.c cpl_zap_serve).
 *
 * Data flow: publishers (the loop's inproc PUB, the participants' PUBs) ->
 * xsub -> proxy thread: route() -> xpub (monitor stream) | xsnap (snapshot
 * stream) -> the monitors; subscriptions: xpub, xsnap -> forward() -> xsub
 * -> the publishers. */
#include "internal.h"

#include <errno.h>
#include <pthread.h>
#include <stdatomic.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>
#include <stdlib.h>
#include <string.h>
#include <zmq.h>

#define BUS_SMALL_MAX (64 << 10) /* bytes: larger messages go to the snapshot stream */
#define BUS_MAX_PARTS (PROTO_MAX_ARRAYS + 2) /* topic, header, arrays */
#define SNAPSHOT_SUFFIX ".snapshot"
/* ms a monitor socket may go on sending at the end of the run: the last
 * rows (the end of the run) reach a reading monitor; a stalled one costs the
 * teardown at most this. At nice BUS_NICE the bus may be hundreds of rows
 * behind when the loop ends on a loaded machine (a 2000-step stub run at
 * load 9 on 2 cores: 517 rows still queued, lost with 200 ms), so the end
 * gets 2 s: time after the loop, never inside it */
#define BUS_LINGER_MS 2000
/* nice of the bus's threads: CFS weight 110 against 1024 at nice 0, about
 * a tenth of a contended core. Enough for a monitor's traffic (a reading
 * monitor needs a few % of a core) when the run saturates the machine;
 * nice 19 (weight 15) starved it there: a live page stood still, the bus's
 * queue full of old rows (tests/python/test_watch_page.py, stub run on 2
 * cores). What more the bus would want (many stalled monitors, the
 * snapshot fan-out) it gets only from idle cores. */
#define BUS_NICE 10

struct cpl_bus {
  void *ctx; /* the bus's own: its I/O threads at nice BUS_NICE */
  void *xsub, *xpub, *xsnap, *control_thread, *control_main, *pub;
  cpl_zap_handler *zap; /* with CURVE: the ZAP handler of ctx */
  /* topics subscribed on the snapshot stream (XPUB passes the first
   * subscription of a topic and the last unsubscription): 0 = nobody wants
   * snapshots, and the loop need not copy them (cpl_bus_snapshots_wanted) */
  atomic_int snapshot_topics;
  /* the same on the monitor stream: with both 0 nobody listens, and the loop
   * builds no message for the bus (cpl_bus_pub; a paper step's headers and
   * rows: about a tenth of the coupler's time) */
  atomic_int monitor_topics;
  pthread_t thread;
  int started;
};

/* nice BUS_NICE for the calling thread (Linux: nice is per thread, and a
 * thread starts with its creator's); if refused the thread keeps its
 * priority (the bus works, only not behind the run). */
static void low_priority(void) {
  setpriority(PRIO_PROCESS, (id_t)syscall(SYS_gettid), BUS_NICE);
}

/* ZeroMQ starts a context's I/O and reaper threads with its first socket,
 * from the thread that makes it: made here, they inherit BUS_NICE. */
static void *first_socket(void *arg) {
  cpl_bus *b = arg;
  low_priority();
  b->xsub = zmq_socket(b->ctx, ZMQ_XSUB);
  return NULL;
}

static const char *const TERMINATE = "TERMINATE";

/* Forwards one whole message (all its parts) from `from` to `to`; a
 * subscription (first byte 1) or unsubscription (0) counted in *topics. */
static void forward(void *from, void *to, atomic_int *topics) {
  int more = 1, first = 1;
  while (more) {
    zmq_msg_t m;
    zmq_msg_init(&m);
    if (zmq_msg_recv(&m, from, 0) < 0) {
      zmq_msg_close(&m);
      return;
    }
    more = zmq_msg_more(&m);
    const unsigned char *d = zmq_msg_data(&m);
    if (topics && first && zmq_msg_size(&m) > 0 && (d[0] == 0 || d[0] == 1))
      atomic_fetch_add(topics, d[0] == 1 ? 1 : -1);
    first = 0;
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

/* What was published before TERMINATE still goes out (the run's last rows). */
static void drain(cpl_bus *b) {
  zmq_pollitem_t in = {b->xsub, 0, ZMQ_POLLIN, 0};
  while (zmq_poll(&in, 1, 0) > 0) route(b);
}

static void *proxy_thread(void *arg) {
  cpl_bus *b = arg;
  low_priority();
  zmq_pollitem_t items[] = {{b->control_thread, 0, ZMQ_POLLIN, 0},
                            {b->xsub, 0, ZMQ_POLLIN, 0},
                            {b->xpub, 0, ZMQ_POLLIN, 0},
                            {b->xsnap, 0, ZMQ_POLLIN, 0}};
  while (zmq_poll(items, 4, -1) >= 0 || zmq_errno() == EINTR) {
    if (items[0].revents & ZMQ_POLLIN) { /* TERMINATE */
      drain(b);
      break;
    }
    if (items[1].revents & ZMQ_POLLIN) route(b);
    /* subscriptions of either stream go upstream to the publishers */
    if (items[2].revents & ZMQ_POLLIN) forward(b->xpub, b->xsub, &b->monitor_topics);
    if (items[3].revents & ZMQ_POLLIN) forward(b->xsnap, b->xsub, &b->snapshot_topics);
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

cpl_bus *cpl_bus_start(void *run_ctx, cpl_bus_eps *eps, int hwm, int snapshot_hwm,
                       const cpl_zap *zap, proto_err *err) {
  (void)run_ctx; /* the bus's sockets live in its own context */
  cpl_bus *b = calloc(1, sizeof *b);
  if (!b) return NULL;
  b->ctx = zmq_ctx_new();
  if (!b->ctx) {
    free(b);
    proto_fail(err, "bus: cannot make its ZeroMQ context: %s", zmq_strerror(errno));
    return NULL;
  }
  pthread_t maker;
  if (pthread_create(&maker, NULL, first_socket, b) == 0) pthread_join(maker, NULL);
  const char *curve_secret = cpl_zap_secret(zap);
  if (zap && !(b->zap = cpl_zap_serve(zap, b->ctx, err))) {
    cpl_bus_stop(b);
    return NULL;
  }
  void *ctx = b->ctx;
  int linger = 0, out_linger = BUS_LINGER_MS;
  if (!b->xsub) b->xsub = zmq_socket(ctx, ZMQ_XSUB);
  proto_socket_limits(b->xsub);
  b->xpub = zmq_socket(ctx, ZMQ_XPUB);
  b->xsnap = zmq_socket(ctx, ZMQ_XPUB);
  b->control_thread = zmq_socket(ctx, ZMQ_PAIR);
  b->control_main = zmq_socket(ctx, ZMQ_PAIR);
  b->pub = zmq_socket(ctx, ZMQ_PUB);
  void *all[] = {b->xsub, b->xpub, b->xsnap, b->control_thread, b->control_main, b->pub};
  for (int i = 0; i < 6; i++)
    zmq_setsockopt(all[i], ZMQ_LINGER, i == 1 || i == 2 ? &out_linger : &linger, sizeof linger);
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

void *cpl_bus_pub(cpl_bus *b) {
  if (!b) return NULL;
  const int listened = atomic_load_explicit(&b->monitor_topics, memory_order_relaxed) > 0 ||
                       atomic_load_explicit(&b->snapshot_topics, memory_order_relaxed) > 0;
  return listened ? b->pub : NULL;
}

int cpl_bus_snapshots_wanted(cpl_bus *b) {
  return b && atomic_load_explicit(&b->snapshot_topics, memory_order_relaxed) > 0;
}

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
  cpl_zap_handler_stop(b->zap);
  if (b->ctx) zmq_ctx_term(b->ctx);
  free(b);
}
