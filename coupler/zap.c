/* zap.c — security.curve (README "Security"; CurveZMQ, ZeroMQ RFC 26): the
 * run's CURVE keys and the ZAP handler (RFC 27) that decides who may
 * connect. The coupler's key pair serves every socket it binds; each process
 * of the scene gets its own client pair and monitors one more; a client key
 * file (0600, in the run's private 0700 directory) holds what a client
 * needs. The handler lets in exactly those keys: the processes' on the
 * control socket and the bus's publishing side, theirs and the monitors' on
 * the monitor streams. A client without an allowed key never completes its
 * handshake: it gets nothing and can send nothing. ZAP is per ZeroMQ
 * context: the bus runs its own context (bus.c: its threads at nice 10,
 * behind the run's), so cpl_zap_serve starts one more handler there, with a copy of
 * the same keys. */
#include "internal.h"

#include <errno.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <zmq.h>

#define ZAP_ENDPOINT "inproc://zeromq.zap.01" /* fixed by RFC 27 */
#define ZAP_VERSION "1.0"
#define ZAP_FRAMES 7   /* version, id, domain, address, identity, mechanism, key */
#define RAW_KEY 32     /* bytes of a binary CURVE key */
#define FRAME_CAP 256
#define REFUSALS_SHOWN 5 /* refused clients named on stderr; then only counted */

/* One ZAP handler: a REP on ZAP_ENDPOINT of one context, in its own
 * thread, with its own copy of the allowed keys (a context of the bus's
 * has its own: ZAP is per context). */
struct cpl_zap_handler {
  int nkeys;                              /* processes, then the monitor key */
  uint8_t allowed[CPL_MAX_PROCS + 1][RAW_KEY];
  void *rep, *control_thread, *control_main;
  pthread_t thread;
  int started;
  int refused;
};

struct cpl_zap {
  char secret[PROTO_KEY_LEN], public_key[PROTO_KEY_LEN];
  int nkeys;                              /* processes, then the monitor key */
  uint8_t allowed[CPL_MAX_PROCS + 1][RAW_KEY];
  char files[CPL_MAX_PROCS + 1][CPL_PATH_LEN];
  cpl_zap_handler *handler;               /* the one of the coupler's context */
};

/* Is this a client key the domain lets in? Monitors (the last key) only on
 * the monitor streams. */
static int allowed(const cpl_zap_handler *z, const char *domain, const uint8_t *key) {
  int monitor_ok = strcmp(domain, CPL_ZAP_MONITOR) == 0;
  for (int i = 0; i < z->nkeys; i++) {
    if (i == z->nkeys - 1 && !monitor_ok) break;
    if (memcmp(z->allowed[i], key, RAW_KEY) == 0) return 1;
  }
  return 0;
}

/* Prints a peer address without anything a terminal would act on. */
static void printable(char *s) {
  for (; *s; s++)
    if (*s < 0x20 || *s > 0x7e) *s = '?';
}

static void answer(cpl_zap_handler *z) {
  char f[ZAP_FRAMES][FRAME_CAP];
  size_t len[ZAP_FRAMES];
  int n = 0, more = 1;
  while (more) {
    zmq_msg_t m;
    zmq_msg_init(&m);
    if (zmq_msg_recv(&m, z->rep, 0) < 0) {
      zmq_msg_close(&m);
      return;
    }
    if (n < ZAP_FRAMES) {
      len[n] = zmq_msg_size(&m) < FRAME_CAP - 1 ? zmq_msg_size(&m) : FRAME_CAP - 1;
      memcpy(f[n], zmq_msg_data(&m), len[n]);
      f[n][len[n]] = 0;
      n++;
    }
    more = zmq_msg_more(&m);
    zmq_msg_close(&m);
  }
  int ok = n == ZAP_FRAMES && strcmp(f[5], "CURVE") == 0 && len[6] == RAW_KEY &&
           allowed(z, f[2], (const uint8_t *)f[6]);
  if (!ok && z->refused++ < REFUSALS_SHOWN) {
    char addr[FRAME_CAP];
    snprintf(addr, sizeof addr, "%s", n > 3 ? f[3] : "?");
    printable(addr);
    fprintf(stderr, "cosim: refused a connection from %s (%s): its CURVE key is not "
            "one of this run's\n", addr[0] ? addr : "a local process",
            n > 2 && strcmp(f[2], CPL_ZAP_MONITOR) == 0 ? "monitor bus" : "control or bus");
  }
  const char *status = ok ? "200" : "400", *text = ok ? "OK" : "key not allowed";
  zmq_send(z->rep, ZAP_VERSION, strlen(ZAP_VERSION), ZMQ_SNDMORE);
  zmq_send(z->rep, f[1], n > 1 ? len[1] : 0, ZMQ_SNDMORE);
  zmq_send(z->rep, status, strlen(status), ZMQ_SNDMORE);
  zmq_send(z->rep, text, strlen(text), ZMQ_SNDMORE);
  zmq_send(z->rep, "", 0, ZMQ_SNDMORE); /* user id */
  zmq_send(z->rep, "", 0, 0);           /* metadata */
}

static void *zap_thread(void *arg) {
  cpl_zap_handler *z = arg;
  zmq_pollitem_t items[] = {{z->control_thread, 0, ZMQ_POLLIN, 0}, {z->rep, 0, ZMQ_POLLIN, 0}};
  while (zmq_poll(items, 2, -1) >= 0 || zmq_errno() == EINTR) {
    if (items[0].revents & ZMQ_POLLIN) break;
    if (items[1].revents & ZMQ_POLLIN) answer(z);
  }
  return NULL;
}

/* A client pair; its key file goes to path. */
static int client(cpl_zap *z, const char *path, proto_err *err) {
  proto_curve k;
  memcpy(k.server_public, z->public_key, PROTO_KEY_LEN);
  if (proto_curve_keypair(k.public_key, k.secret_key, err) < 0 ||
      proto_curve_write(path, &k, err) < 0)
    return -1;
  zmq_z85_decode(z->allowed[z->nkeys], k.public_key);
  snprintf(z->files[z->nkeys++], CPL_PATH_LEN, "%s", path);
  return 0;
}

cpl_zap_handler *cpl_zap_serve(const cpl_zap *keys, void *ctx, proto_err *err) {
  cpl_zap_handler *z = calloc(1, sizeof *z);
  if (!z) {
    proto_fail(err, "security.curve: out of memory");
    return NULL;
  }
  z->nkeys = keys->nkeys;
  memcpy(z->allowed, keys->allowed, sizeof z->allowed);
  char ctl[64];
  snprintf(ctl, sizeof ctl, "inproc://cosim-zap-control-%p", (void *)z);
  z->rep = zmq_socket(ctx, ZMQ_REP);
  z->control_thread = zmq_socket(ctx, ZMQ_PAIR);
  z->control_main = zmq_socket(ctx, ZMQ_PAIR);
  int linger = 0, rc = 0;
  void *all[] = {z->rep, z->control_thread, z->control_main};
  for (int i = 0; i < 3; i++) zmq_setsockopt(all[i], ZMQ_LINGER, &linger, sizeof linger);
  if (zmq_bind(z->rep, ZAP_ENDPOINT) != 0 || zmq_bind(z->control_thread, ctl) != 0 ||
      zmq_connect(z->control_main, ctl) != 0)
    rc = proto_fail(err, "security.curve: cannot start the ZAP handler: %s",
                    zmq_strerror(zmq_errno()));
  if (rc == 0 && pthread_create(&z->thread, NULL, zap_thread, z) != 0)
    rc = proto_fail(err, "security.curve: cannot start the ZAP thread");
  z->started = rc == 0;
  if (rc < 0) {
    cpl_zap_handler_stop(z);
    return NULL;
  }
  return z;
}

void cpl_zap_handler_stop(cpl_zap_handler *z) {
  if (!z) return;
  if (z->started) {
    zmq_send(z->control_main, "", 0, 0);
    pthread_join(z->thread, NULL);
  }
  zmq_close(z->control_main);
  zmq_close(z->control_thread);
  zmq_close(z->rep);
  if (z->refused > REFUSALS_SHOWN)
    fprintf(stderr, "cosim: refused %d connections without an allowed CURVE key\n",
            z->refused);
  free(z);
}

cpl_zap *cpl_zap_start(void *ctx, const char *dir, const cpl_scene *s, proto_err *err) {
  cpl_zap *z = calloc(1, sizeof *z);
  if (!z) return NULL;
  char path[2 * CPL_PATH_LEN];
  int rc = proto_curve_keypair(z->public_key, z->secret, err);
  for (int i = 0; rc == 0 && i < s->nprocs; i++) {
    snprintf(path, sizeof path, "%s/%s.key", dir, s->procs[i].name);
    rc = client(z, path, err);
  }
  snprintf(path, sizeof path, "%s/monitor.key", dir);
  if (rc == 0) rc = client(z, path, err);
  if (rc == 0 && !(z->handler = cpl_zap_serve(z, ctx, err))) rc = -1;
  if (rc < 0) {
    cpl_zap_stop(z);
    return NULL;
  }
  return z;
}

const char *cpl_zap_secret(const cpl_zap *z) { return z ? z->secret : NULL; }
const char *cpl_zap_public(const cpl_zap *z) { return z ? z->public_key : ""; }
const char *cpl_zap_key_file(const cpl_zap *z, int proc) {
  return z && proc < z->nkeys - 1 ? z->files[proc] : NULL;
}
const char *cpl_zap_monitor_file(const cpl_zap *z) {
  return z && z->nkeys ? z->files[z->nkeys - 1] : "";
}

void cpl_zap_stop(cpl_zap *z) {
  if (!z) return;
  cpl_zap_handler_stop(z->handler);
  for (int i = 0; i < z->nkeys; i++) unlink(z->files[i]);
  free(z);
}
