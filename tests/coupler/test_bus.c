/* test_bus.c — the monitor bus and CURVE for big messages (issue 25).
 *
 * Data flow: a run's CURVE keys (zap.c) in a private temp dir -> (1) a
 * CURVE ROUTER (the control socket's set-up) and a DEALER with a process's
 * key file exchange messages of 0.54 MB arrays (a 150 x 150 surface) and an
 * odd-sized u1 array both ways over tcp -> compared bit for bit; (2) the bus
 * with the same keys (its own context and ZAP handler): a participant's PUB
 * (process key) publishes a big snapshot, the coupler's inproc PUB a series
 * row -> a monitor with the monitor key receives both from the two streams,
 * bit for bit; a monitor with keys of its own receives nothing; (3) the bus's
 * proxy and I/O threads run at nice 10 (bus.c BUS_NICE), the caller's
 * threads keep their priority; (4) the bus says snapshots are wanted
 * exactly while a monitor subscribes on the snapshot stream.
 * Correctness only: what CURVE costs is bench/reliability/bench_curve.py. */
#include <dirent.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <unistd.h>
#include <zmq.h>

#include "coupler/internal.h"
#include "cosim_test.h"

#define N_NODES (150 * 150) /* the bench's big surface: 0.54 MB per [n,3] f8 array */
#define ODD_BYTES 1000003   /* not a multiple of 8, nor of any cipher block */
#define WAIT_MS 10000       /* ms: a handshake and delivery on a loaded machine */
#define QUIET_MS 500        /* ms an impostor is watched for receiving anything */
#define BUS_NICE 10         /* bus.c: the bus's threads, behind the run's */

static void fill(double *x, size_t n, double seed) {
  for (size_t i = 0; i < n; i++) x[i] = seed + 1e-3 * (double)i + 1.0 / (double)(i + 3);
}

static void client_keys(void *s, const char *file) {
  proto_err err = {{0}};
  proto_curve k;
  OK(proto_curve_read(file, &k, &err));
  OK(proto_curve_client(s, &k, &err));
}

/* Receives one message within WAIT_MS; 0 on success. */
static int recv_within(void *s, proto_msg *m, char *identity) {
  proto_err err = {{0}};
  if (proto_poll_in(s, WAIT_MS) <= 0) return -1;
  if (proto_recv(s, m, identity, &err) < 0) {
    fprintf(stderr, "recv: %s\n", err.msg);
    return -1;
  }
  return 0;
}

static int same_array(const proto_msg *m, const char *name, const void *want, size_t bytes) {
  const proto_array *a = proto_msg_find(m, name);
  return a && a->nbytes == bytes && memcmp(a->data, want, bytes) == 0;
}

/* 1. CURVE on the control socket's pattern, big frames, both ways. */
static void control_round_trip(void *ctx, const cpl_zap *zap, const char *key_file) {
  proto_err err = {{0}};
  void *router = zmq_socket(ctx, ZMQ_ROUTER);
  int linger = 0;
  zmq_setsockopt(router, ZMQ_LINGER, &linger, sizeof linger);
  proto_socket_limits(router);
  OK(proto_curve_server(router, cpl_zap_secret(zap), CPL_ZAP_CONTROL, &err));
  CHECK(zmq_bind(router, "tcp://127.0.0.1:0") == 0);
  char ep[256];
  size_t len = sizeof ep;
  zmq_getsockopt(router, ZMQ_LAST_ENDPOINT, ep, &len);
  void *peer_ctx = zmq_ctx_new(); /* another context: as another process */
  void *dealer = zmq_socket(peer_ctx, ZMQ_DEALER);
  zmq_setsockopt(dealer, ZMQ_LINGER, &linger, sizeof linger);
  zmq_setsockopt(dealer, ZMQ_IDENTITY, "fem", 3);
  client_keys(dealer, key_file);
  CHECK(zmq_connect(dealer, ep) == 0);

  double *x = malloc(N_NODES * 3 * sizeof *x), *v = malloc(N_NODES * 3 * sizeof *v);
  unsigned char *odd = malloc(ODD_BYTES);
  fill(x, N_NODES * 3, 1.0);
  fill(v, N_NODES * 3, -2.0);
  for (size_t i = 0; i < ODD_BYTES; i++) odd[i] = (unsigned char)(i * 131u + 7u);
  const int64_t odd_shape[1] = {ODD_BYTES};
  proto_msg m = {0}, got = {0};
  proto_msg_reset(&m, "fem", "done", 7, 0.007);
  proto_msg_add_f8(&m, "x", N_NODES, 3, x);
  proto_msg_add_f8(&m, "v", N_NODES, 3, v);
  proto_msg_add(&m, "odd", PROTO_U1, 1, odd_shape, odd);
  OK(proto_send(dealer, &m, 0, &err));
  char who[PROTO_NAME_LEN] = "";
  CHECK(recv_within(router, &got, who) == 0, "the coupler got the participant's message");
  CHECK(strcmp(who, "fem") == 0, "from 'fem' (got '%s')", who);
  CHECK(got.step == 7 && same_array(&got, "x", x, N_NODES * 3 * sizeof *x) &&
            same_array(&got, "v", v, N_NODES * 3 * sizeof *v) && same_array(&got, "odd", odd, ODD_BYTES),
        "participant -> coupler over CURVE: every array bit for bit");
  /* and back: the coupler's request (zero-copy send) */
  fill(x, N_NODES * 3, 5.0);
  proto_msg_reset(&m, "fem", "step", 8, 0.008);
  proto_msg_add_f8(&m, "nodal_force", N_NODES, 3, x);
  proto_msg_add(&m, "odd", PROTO_U1, 1, odd_shape, odd);
  OK(proto_send_to(router, "fem", &m, &err));
  CHECK(recv_within(dealer, &got, NULL) == 0, "the participant got the coupler's message");
  CHECK(got.step == 8 && same_array(&got, "nodal_force", x, N_NODES * 3 * sizeof *x) &&
            same_array(&got, "odd", odd, ODD_BYTES),
        "coupler -> participant over CURVE: every array bit for bit");
  proto_msg_free(&m);
  proto_msg_free(&got);
  free(x);
  free(v);
  free(odd);
  zmq_close(dealer);
  zmq_ctx_term(peer_ctx);
  zmq_close(router);
}

/* A monitor with the keys of key_file, or (own_keys) with the coupler's
 * public key from it but a client pair of its own, which no run allowed. */
static void *monitor_sub(void *ctx, const cpl_bus_eps *eps, const char *key_file,
                         int own_keys) {
  proto_err err = {{0}};
  void *sub = zmq_socket(ctx, ZMQ_SUB);
  int linger = 0;
  zmq_setsockopt(sub, ZMQ_LINGER, &linger, sizeof linger);
  proto_socket_limits(sub);
  proto_curve k;
  OK(proto_curve_read(key_file, &k, &err));
  if (own_keys) OK(proto_curve_keypair(k.public_key, k.secret_key, &err));
  OK(proto_curve_client(sub, &k, &err));
  zmq_setsockopt(sub, ZMQ_SUBSCRIBE, "", 0);
  CHECK(zmq_connect(sub, eps->monitor) == 0 && zmq_connect(sub, eps->snapshots) == 0);
  return sub;
}

/* 2. The bus over CURVE: its own context and ZAP handler. The publishers
 * repeat until the monitor has both messages (a subscription reaches a PUB
 * some time after the connect: ZeroMQ's late joiner). */
static void bus_round_trip(void *ctx, const cpl_zap *zap, const char *dir,
                           const char *proc_key, const char *monitor_key) {
  proto_err err = {{0}};
  cpl_bus_eps eps = {{0}, {0}, {0}};
  snprintf(eps.inner, sizeof eps.inner, "ipc://%s/bus", dir);
  snprintf(eps.monitor, sizeof eps.monitor, "ipc://%s/monitor", dir);
  snprintf(eps.snapshots, sizeof eps.snapshots, "ipc://%s/snapshots", dir);
  cpl_bus *bus = cpl_bus_start(ctx, &eps, 1000, 2, zap, &err);
  CHECK(bus != NULL, "bus started: %s", err.msg);
  if (!bus) return;
  void *peer_ctx = zmq_ctx_new();
  void *pub = zmq_socket(peer_ctx, ZMQ_PUB);
  int linger = 0;
  zmq_setsockopt(pub, ZMQ_LINGER, &linger, sizeof linger);
  client_keys(pub, proc_key);
  CHECK(zmq_connect(pub, eps.inner) == 0);
  void *mon = monitor_sub(peer_ctx, &eps, monitor_key, 0);
  void *impostor = monitor_sub(peer_ctx, &eps, monitor_key, 1);

  double *snap = malloc(N_NODES * 3 * sizeof *snap), row[4] = {0.5, 1.5, -2.5, 1e300};
  fill(snap, N_NODES * 3, 3.0);
  proto_msg s = {0}, r = {0}, got = {0};
  proto_msg_reset(&s, "fem.snapshot", "snapshot", 12, 0.012);
  proto_msg_add_f8(&s, "snap.x", N_NODES, 3, snap);
  proto_msg_reset(&r, "coupler.series", "series", 12, 0.012);
  proto_msg_add_f8(&r, "series", 4, 0, row);
  int have_snap = 0, have_row = 0, good_snap = 0, good_row = 0;
  double until = proto_now() + WAIT_MS / 1e3;
  while ((!have_snap || !have_row) && proto_now() < until) {
    proto_publish(pub, &s);                /* a participant's, over ipc + CURVE */
    proto_publish(cpl_bus_pub(bus), &r);   /* the coupler's own, inproc */
    while (proto_poll_in(mon, 50) > 0 && proto_recv(mon, &got, NULL, &err) == 0) {
      if (strcmp(got.topic, "fem.snapshot") == 0) {
        have_snap = 1;
        good_snap = same_array(&got, "snap.x", snap, N_NODES * 3 * sizeof *snap);
      } else if (strcmp(got.topic, "coupler.series") == 0) {
        have_row = 1;
        good_row = same_array(&got, "series", row, sizeof row);
      }
    }
  }
  CHECK(have_snap && good_snap, "a 0.54 MB snapshot through the bus, bit for bit (got %d)",
        have_snap);
  CHECK(have_row && good_row, "the coupler's series row through the bus (got %d)", have_row);
  CHECK(proto_poll_in(impostor, QUIET_MS) == 0,
        "a monitor with a key not of this run receives nothing");
  proto_msg_free(&s);
  proto_msg_free(&r);
  proto_msg_free(&got);
  free(snap);
  zmq_close(impostor);
  zmq_close(mon);
  zmq_close(pub);
  zmq_ctx_term(peer_ctx);
  cpl_bus_stop(bus);
}

#ifdef __linux__
/* Threads of this process at nice `nice`: field 19 of /proc/self/task/TID/stat. */
static int threads_at_nice(int nice) {
  DIR *d = opendir("/proc/self/task");
  int n = 0;
  struct dirent *e;
  while (d && (e = readdir(d))) {
    if (e->d_name[0] == '.') continue;
    char path[300], buf[1024];
    snprintf(path, sizeof path, "/proc/self/task/%s/stat", e->d_name);
    FILE *f = fopen(path, "r");
    size_t len = f ? fread(buf, 1, sizeof buf - 1, f) : 0;
    if (f) fclose(f);
    buf[len] = 0;
    char *p = strrchr(buf, ')'); /* field 2 ends here; fields 3.. follow */
    int field = 2;
    for (; p && *p && field < 19; p++)
      if (*p == ' ') field++;
    if (p && atoi(p) == nice) n++;
  }
  if (d) closedir(d);
  return n;
}

/* 3. The bus's threads run behind the run's; the caller's keep their nice. */
static void low_priority(void *ctx, const char *dir) {
  proto_err err = {{0}};
  int mine = getpriority(PRIO_PROCESS, 0);
  if (mine >= BUS_NICE) {
    printf("SKIP the priority check: this test already runs at nice %d\n", mine);
    return;
  }
  int before = threads_at_nice(BUS_NICE);
  cpl_bus_eps eps = {{0}, {0}, {0}};
  snprintf(eps.inner, sizeof eps.inner, "ipc://%s/bus2", dir);
  snprintf(eps.monitor, sizeof eps.monitor, "ipc://%s/monitor2", dir);
  snprintf(eps.snapshots, sizeof eps.snapshots, "ipc://%s/snapshots2", dir);
  cpl_bus *bus = cpl_bus_start(ctx, &eps, 1000, 2, NULL, &err);
  CHECK(bus != NULL, "bus started: %s", err.msg);
  int during = 0;
  for (int i = 0; i < 100 && (during = threads_at_nice(BUS_NICE)) < before + 2; i++)
    usleep(10000);
  CHECK(before == 0, "no thread at nice %d before the bus (%d)", BUS_NICE, before);
  /* the proxy thread and the bus context's I/O thread (and its reaper) */
  CHECK(during >= before + 2, "the bus's proxy and I/O threads at nice %d (%d threads)",
        BUS_NICE, during);
  CHECK(getpriority(PRIO_PROCESS, 0) == mine, "the caller keeps its nice %d (%d)", mine,
        getpriority(PRIO_PROCESS, 0));
  cpl_bus_stop(bus);
}
#endif

/* 4. The loop copies snapshots onto the bus only while a monitor subscribes
 * to the snapshot stream: wanted follows the subscriptions. */
static int wanted_within(cpl_bus *bus, int want) {
  double until = proto_now() + WAIT_MS / 1e3;
  while (cpl_bus_snapshots_wanted(bus) != want && proto_now() < until) usleep(5000);
  return cpl_bus_snapshots_wanted(bus) == want;
}

static void snapshots_wanted(void *ctx, const char *dir) {
  proto_err err = {{0}};
  cpl_bus_eps eps = {{0}, {0}, {0}};
  snprintf(eps.inner, sizeof eps.inner, "ipc://%s/bus3", dir);
  snprintf(eps.monitor, sizeof eps.monitor, "ipc://%s/monitor3", dir);
  snprintf(eps.snapshots, sizeof eps.snapshots, "ipc://%s/snapshots3", dir);
  cpl_bus *bus = cpl_bus_start(ctx, &eps, 1000, 2, NULL, &err);
  CHECK(bus != NULL, "bus started: %s", err.msg);
  if (!bus) return;
  CHECK(!cpl_bus_snapshots_wanted(bus), "no snapshots wanted without a monitor");
  void *peer_ctx = zmq_ctx_new();
  int linger = 0;
  void *series_only = zmq_socket(peer_ctx, ZMQ_SUB); /* everything on the monitor stream */
  zmq_setsockopt(series_only, ZMQ_LINGER, &linger, sizeof linger);
  zmq_setsockopt(series_only, ZMQ_SUBSCRIBE, "", 0);
  zmq_connect(series_only, eps.monitor);
  void *a = zmq_socket(peer_ctx, ZMQ_SUB), *b = zmq_socket(peer_ctx, ZMQ_SUB);
  zmq_setsockopt(a, ZMQ_LINGER, &linger, sizeof linger);
  zmq_setsockopt(b, ZMQ_LINGER, &linger, sizeof linger);
  zmq_setsockopt(a, ZMQ_SUBSCRIBE, "fem.", 4);
  zmq_setsockopt(b, ZMQ_SUBSCRIBE, "", 0);
  zmq_connect(a, eps.snapshots);
  usleep(200000); /* the monitor stream's subscription has arrived by now */
  CHECK(wanted_within(bus, 1), "a subscriber on the snapshot stream: snapshots wanted");
  zmq_connect(b, eps.snapshots);
  zmq_close(a);
  usleep(200000);
  CHECK(wanted_within(bus, 1), "one of two snapshot subscribers gone: still wanted");
  zmq_close(b);
  CHECK(wanted_within(bus, 0), "the last snapshot subscriber gone: not wanted (%d)",
        cpl_bus_snapshots_wanted(bus));
  /* and the monitor stream's subscriber never counted */
  CHECK(!cpl_bus_snapshots_wanted(bus), "a monitor-stream subscriber wants no snapshots");
  zmq_close(series_only);
  zmq_ctx_term(peer_ctx);
  cpl_bus_stop(bus);
}

int main(void) {
  proto_err err = {{0}};
  if (!zmq_has("curve")) {
    printf("SKIP: this libzmq has no CURVE\n");
    return 77;
  }
  char dir[] = "/tmp/cosim-test-bus-XXXXXX";
  if (!mkdtemp(dir)) return 1;
  cpl_scene scene;
  memset(&scene, 0, sizeof scene);
  scene.nprocs = 1;
  snprintf(scene.procs[0].name, sizeof scene.procs[0].name, "fem");
  void *ctx = zmq_ctx_new();
  cpl_zap *zap = cpl_zap_start(ctx, dir, &scene, &err);
  CHECK(zap != NULL, "keys and ZAP handler: %s", err.msg);
  if (!zap) return cosim_test_done("test_bus");
  char proc_key[CPL_PATH_LEN], monitor_key[CPL_PATH_LEN];
  snprintf(proc_key, sizeof proc_key, "%s", cpl_zap_key_file(zap, 0));
  snprintf(monitor_key, sizeof monitor_key, "%s", cpl_zap_monitor_file(zap));
  control_round_trip(ctx, zap, proc_key);
  bus_round_trip(ctx, zap, dir, proc_key, monitor_key);
#ifdef __linux__
  low_priority(ctx, dir);
#endif
  snapshots_wanted(ctx, dir);
  cpl_zap_stop(zap);
  zmq_ctx_term(ctx);
  char cmd[64 + sizeof dir];
  snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
  if (system(cmd) != 0) fprintf(stderr, "could not remove %s\n", dir);
  return cosim_test_done("test_bus");
}
