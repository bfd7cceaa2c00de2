/* The shared-memory data plane (proto_shm.h): arrays sent through a writer's
 * segment arrive bit-exact over a real socket pair, as descriptors and empty
 * frames; the two buffers alternate (the previous message stays readable
 * while the next arrives); an array computed in the next buffer is sent
 * without a copy; a message too large for the segment announces a larger
 * one; and every malformed or oversized descriptor is refused with a
 * message that names the defect. Segments are memfds: no name in /dev/shm.
 * The doorbell: a ringing writer posts whole messages in the segment (no
 * socket message), a reader in another process sleeping on the bell wakes
 * for it, a message that announces a new segment still takes the socket,
 * and a reader that finds two posts where lock-step allows one refuses. */
#include <dirent.h>
#include <sys/wait.h>
#include <unistd.h>
#include <stdio.h>
#include <stdlib.h>
#include <zmq.h>

#include "cosim_test.h"
#include "proto/proto.h"

#define N_NODES 1000 /* 24 000 bytes per [n,3] array: above PROTO_SHM_MIN_BYTES */

static proto_shm *the_reader(void *ctx, const char *identity) {
  (void)identity;
  return ctx;
}

/* x [rows,3] (in the segment when large) and rim_R (a small frame); with
 * announce the writer's descriptor; with note a header field of that name. */
static int send_x(void *s, proto_shm *w, const double *x, int64_t rows, int announce,
                  const char *note, proto_err *err) {
  proto_msg m = {0};
  /* static: proto_send_via sends arrays zero-copy (they must outlive the send) */
  static const double rim[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  proto_msg_reset(&m, "tyre", "done", 7, 0.25);
  proto_msg_add_f8(&m, "x", rows, 3, x);
  proto_msg_add_f8(&m, "rim_R", 3, 3, rim);
  if (announce) proto_shm_announce(w, proto_msg_header(&m));
  if (note) cJSON_AddStringToObject(proto_msg_header(&m), "note", note);
  int rc = proto_send_via(s, NULL, &m, 0, w, err);
  proto_msg_free(&m);
  return rc;
}

/* Two PAIR sockets over inproc, a writer and a reader. */
typedef struct pair {
  void *ctx, *a, *b;
  proto_shm *w, *rd;
} pair;

static void pair_open(pair *p, const char *endpoint) {
  proto_err err = {{0}};
  p->ctx = zmq_ctx_new();
  p->a = zmq_socket(p->ctx, ZMQ_PAIR);
  p->b = zmq_socket(p->ctx, ZMQ_PAIR);
  CHECK(zmq_bind(p->a, endpoint) == 0 && zmq_connect(p->b, endpoint) == 0);
  p->w = proto_shm_writer(PROTO_SHM_INITIAL_BYTES, &err);
  p->rd = proto_shm_reader();
  CHECK(p->w && p->rd, "writer and reader: %s", err.msg);
}

static void pair_close(pair *p) {
  proto_shm_free(p->w);
  proto_shm_free(p->rd);
  zmq_close(p->a), zmq_close(p->b);
  zmq_ctx_term(p->ctx);
}

static int same_bits(const void *a, const void *b, size_t n) { return memcmp(a, b, n) == 0; }

/* How many entries of /dev/shm name a cosim segment. */
static int dev_shm_entries(void) {
  DIR *d = opendir("/dev/shm");
  int n = 0;
  if (!d) return 0;
  for (struct dirent *e; (e = readdir(d));) n += strstr(e->d_name, "cosim") != NULL;
  closedir(d);
  return n;
}

static int mapped_memfds(void) {
  FILE *f = fopen("/proc/self/maps", "r");
  char line[512];
  int n = 0;
  while (f && fgets(line, sizeof line, f)) n += strstr(line, "memfd:cosim-shm") != NULL;
  if (f) fclose(f);
  return n;
}

static void test_round_trip(void) {
  proto_err err = {{0}};
  int shm_before = dev_shm_entries();
  pair P;
  pair_open(&P, "inproc://shm");
  void *a = P.a, *b = P.b;
  proto_shm *w = P.w, *rd = P.rd;
  static double x1[3 * N_NODES], x2[3 * N_NODES];
  for (int i = 0; i < 3 * N_NODES; i++) x1[i] = 0.1 * i, x2[i] = -1.0 / (i + 1);

  /* 1: the first message announces the segment; x by shm, rim_R as a frame */
  proto_msg m1 = {0}, m2 = {0}, m3 = {0};
  CHECK(send_x(a, w, x1, N_NODES, 1, NULL, &err) == 0, "%s", err.msg);
  CHECK(proto_recv_via(b, &m1, NULL, the_reader, rd, &err) == 0, "%s", err.msg);
  CHECK(proto_shm_attached(rd));
  const proto_array *ax = proto_msg_find(&m1, "x");
  CHECK(ax && ax->nbytes == sizeof x1 && same_bits(ax->data, x1, sizeof x1));
  CHECK(ax && ax->data != (const void *)x1);
  const double *rim = proto_msg_get_f8(&m1, "rim_R", 3, 3, &err);
  CHECK(rim && rim[0] == 1 && rim[4] == 1);
  uint64_t copied, in_place;
  proto_shm_counts(w, &copied, &in_place);
  CHECK(copied == sizeof x1 && in_place == 0, "copied %llu", (unsigned long long)copied);
  CHECK(mapped_memfds() >= 2, "the writer's and the reader's mappings are memfds");

  /* 2: the other buffer; message 1 is still intact while 2 is read */
  CHECK(send_x(a, w, x2, N_NODES, 0, NULL, &err) == 0, "%s", err.msg);
  CHECK(proto_recv_via(b, &m2, NULL, the_reader, rd, &err) == 0, "%s", err.msg);
  const proto_array *ax2 = proto_msg_find(&m2, "x");
  CHECK(ax2 && same_bits(ax2->data, x2, sizeof x2));
  CHECK(same_bits(proto_msg_find(&m1, "x")->data, x1, sizeof x1), "double buffered");
  CHECK(ax2 && ax2->data != proto_msg_find(&m1, "x")->data);

  /* 3: zero copy: computed in the next buffer, sent without a copy */
  double *next = proto_shm_next(w, sizeof x1);
  CHECK(next != NULL);
  for (int i = 0; i < 3 * N_NODES; i++) next[i] = x1[i] + 1;
  CHECK(send_x(a, w, next, N_NODES, 0, NULL, &err) == 0, "%s", err.msg);
  CHECK(proto_recv_via(b, &m3, NULL, the_reader, rd, &err) == 0, "%s", err.msg);
  proto_shm_counts(w, &copied, &in_place);
  CHECK(copied == 2 * sizeof x1 && in_place == 1, "in place: %llu", (unsigned long long)in_place);
  const double *got = proto_msg_get_f8(&m3, "x", N_NODES, 3, &err);
  CHECK(got && got[3] == x1[3] + 1 && got == proto_msg_find(&m1, "x")->data);

  /* 4: a message larger than the segment: a new one, announced in it; the
   * message before (old segment) stays readable */
  const int64_t big = 40000; /* 960 000 bytes */
  double *xb = malloc(sizeof(double) * 3 * (size_t)big);
  for (int64_t i = 0; i < 3 * big; i++) xb[i] = (double)i * 1e-3;
  proto_msg m4 = {0};
  CHECK(send_x(a, w, xb, big, 0, NULL, &err) == 0, "%s", err.msg);
  CHECK(proto_recv_via(b, &m4, NULL, the_reader, rd, &err) == 0, "%s", err.msg);
  const double *g4 = proto_msg_get_f8(&m4, "x", big, 3, &err);
  CHECK(g4 && same_bits(g4, xb, sizeof(double) * 3 * (size_t)big));
  CHECK(proto_msg_get_f8(&m3, "x", N_NODES, 3, &err)[3] == x1[3] + 1);

  /* 5: without a reader a descriptor is refused */
  CHECK(send_x(a, w, x1, N_NODES, 0, NULL, &err) == 0, "%s", err.msg);
  proto_msg m5 = {0};
  CHECK(proto_recv(b, &m5, NULL, &err) < 0);
  CHECK_MSG(err, "in shared memory, but this sender announced no segment");
  CHECK(dev_shm_entries() == shm_before, "nothing in /dev/shm");
  proto_msg_free(&m1), proto_msg_free(&m2), proto_msg_free(&m3), proto_msg_free(&m4);
  proto_msg_free(&m5);
  free(xb);
  pair_close(&P);
}

/* One crafted message through proto_decode_via; 0 or -1 with err. */
static int decode(proto_shm *rd, const char *header, size_t frame_bytes, proto_err *err) {
  static double payload[8];
  const void *frames[3] = {"tyre", header, payload};
  size_t sizes[3] = {4, strlen(header), frame_bytes};
  proto_msg m = {0};
  int rc = proto_decode_via(&m, 3, frames, sizes, rd, err);
  if (rc == 0) { /* what a consumer does: read it all */
    volatile unsigned char sum = 0;
    for (size_t i = 0; i < m.arrays[0].nbytes; i++) sum += ((const unsigned char *)m.arrays[0].data)[i];
  }
  proto_msg_free(&m);
  return rc;
}

static void test_descriptors_refused(void) {
  proto_err err = {{0}};
  proto_shm *w = proto_shm_writer(PROTO_SHM_INITIAL_BYTES, &err);
  proto_shm *rd = proto_shm_reader();
  char *desc = proto_shm_descriptor_json(w);
  cJSON *d = cJSON_Parse(desc);
  CHECK(proto_shm_attach(rd, d, &err) == 0, "%s", err.msg);
  /* message 1 in buffer 1: a real one to point at */
  static double x[3 * N_NODES];
  proto_msg m = {0};
  proto_msg_reset(&m, "tyre", "done", 1, 0);
  proto_msg_add_f8(&m, "x", N_NODES, 3, x);
  proto_shm_place pl;
  CHECK(proto_shm_place_msg(w, &m, &pl, &err) == 0 && pl.seq == 1 && pl.offset[0] == 0);
  proto_msg_free(&m);
  char h[512];
#define HDR(shape, shm) \
  (snprintf(h, sizeof h, "{\"v\":1,\"type\":\"done\",\"arrays\":[{\"name\":\"x\"," \
            "\"dtype\":\"f8\",\"shape\":" shape ",\"shm\":" shm "}]}"), h)
  CHECK(decode(rd, HDR("[1000,3]", "[1,0]"), 0, &err) == 0, "%s", err.msg);
  CHECK(decode(NULL, HDR("[1000,3]", "[1,0]"), 0, &err) < 0);
  CHECK_MSG(err, "announced no segment");
  CHECK(decode(rd, HDR("[1000,3]", "[1,0]"), 8, &err) < 0);
  CHECK_MSG(err, "its frame has 8 bytes (expected none)");
  CHECK(decode(rd, HDR("[1000,3]", "[1,4]"), 0, &err) < 0);
  CHECK_MSG(err, "offset 4 is not a multiple of 8");
  CHECK(decode(rd, HDR("[1000,3]", "[1,65536]"), 0, &err) < 0);
  CHECK_MSG(err, "exceed the segment's buffer of 65536 bytes");
  CHECK(decode(rd, HDR("[3000,3]", "[1,0]"), 0, &err) < 0); /* 72 000 > 65 536 */
  CHECK_MSG(err, "72000 bytes at offset 0 exceed");
  CHECK(decode(rd, HDR("[1000,3]", "[1,1e300]"), 0, &err) < 0);
  CHECK_MSG(err, "expected [message number >= 1, byte offset >= 0]");
  CHECK(decode(rd, HDR("[1000,3]", "[2,0]"), 0, &err) < 0);
  CHECK_MSG(err, "buffer 0 holds message 0, the descriptor names message 2");
  CHECK(decode(rd, HDR("[1000,3]", "[3,0]"), 0, &err) < 0);
  CHECK_MSG(err, "buffer 1 holds message 1, the descriptor names message 3");
  CHECK(decode(rd, HDR("[1000,3]", "[0,0]"), 0, &err) < 0);
  CHECK(decode(rd, HDR("[1000,3]", "\"0\""), 0, &err) < 0);
  CHECK(decode(rd, HDR("[1000,3]", "[1,0,0]"), 0, &err) < 0);
  CHECK_MSG(err, "shm: expected [message number");

  /* segment descriptors: each field checked before anything is opened */
  struct { const char *key; double value; const char *msg; } bad[] = {
      {"pid", 0, "shm_segment.pid: expected an integer"},
      {"fd", -1, "shm_segment.fd: expected an integer"},
      {"fd", 999999, "cannot open the peer's segment"},
      {"bytes", 1e18, "shm_segment.bytes: expected an integer"},
      {"buffer_bytes", 8192, "is not a header page and two buffers"},
      {"buffer_bytes", 4097, "is not a header page and two buffers"},
      {"buffer_bytes", 1e15, "shm_segment.buffer_bytes: expected an integer"},
  };
  for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
    cJSON *c = cJSON_Duplicate(d, 1);
    cJSON_ReplaceItemInObjectCaseSensitive(c, bad[i].key, cJSON_CreateNumber(bad[i].value));
    CHECK(proto_shm_attach(rd, c, &err) < 0, "%s = %g", bad[i].key, bad[i].value);
    CHECK_MSG(err, bad[i].msg);
    cJSON_Delete(c);
  }
  cJSON *c = cJSON_Duplicate(d, 1);
  cJSON_ReplaceItemInObjectCaseSensitive(c, "nonce", cJSON_CreateString("00112233445566778899aabbccddeeff"));
  CHECK(proto_shm_attach(rd, c, &err) < 0);
  CHECK_MSG(err, "is not the one its descriptor names");
  cJSON_ReplaceItemInObjectCaseSensitive(c, "nonce", cJSON_CreateString("xyz"));
  CHECK(proto_shm_attach(rd, c, &err) < 0);
  CHECK_MSG(err, "shm_segment.nonce: expected 32 hex digits");
  cJSON_Delete(c);
  /* a descriptor naming another file of ours (stdin: not a sealed memfd) */
  c = cJSON_Duplicate(d, 1);
  cJSON_ReplaceItemInObjectCaseSensitive(c, "fd", cJSON_CreateNumber(0));
  CHECK(proto_shm_attach(rd, c, &err) < 0);
  cJSON_Delete(c);
  CHECK(proto_shm_attach(rd, cJSON_GetObjectItem(d, "pid"), &err) < 0);
  CHECK_MSG(err, "shm_segment: expected an object");
  /* after all the refusals the reader still reads the segment it had */
  CHECK(decode(rd, HDR("[1000,3]", "[1,0]"), 0, &err) == 0, "%s", err.msg);
  /* a header announcing a bad segment fails the message */
  snprintf(h, sizeof h, "{\"v\":1,\"type\":\"done\",\"shm_segment\":{\"pid\":1},\"arrays\":"
           "[{\"name\":\"x\",\"dtype\":\"f8\",\"shape\":[1]}]}");
  CHECK(decode(rd, h, 8, &err) < 0);
  CHECK_MSG(err, "shm_segment.fd");
#undef HDR
  cJSON_Delete(d);
  free(desc);
  proto_shm_free(w);
  proto_shm_free(rd);
}

static void test_doorbell(void) {
  proto_err err = {{0}};
  pair P;
  pair_open(&P, "inproc://bell");
  void *a = P.a, *b = P.b;
  proto_shm *w = P.w, *rd = P.rd;
  static double x1[3 * N_NODES], x2[3 * N_NODES];
  for (int i = 0; i < 3 * N_NODES; i++) x1[i] = 0.5 * i, x2[i] = 1.0 / (i + 3);
  proto_msg m1 = {0}, m2 = {0}, m3 = {0}, m4 = {0}, m5 = {0};

  /* 1: before ringing, the announcing message takes the socket */
  CHECK(send_x(a, w, x1, N_NODES, 1, NULL, &err) == 0, "%s", err.msg);
  CHECK(!proto_shm_pending(rd));
  CHECK(proto_recv_via(b, &m1, NULL, the_reader, rd, &err) == 0, "%s", err.msg);
  CHECK(!proto_shm_pending(rd), "nothing posted before the writer rings");

  /* 2: ringing: posted whole, nothing on the socket, the same bits */
  proto_shm_ring(w);
  CHECK(proto_shm_rings(w));
  CHECK(send_x(a, w, x2, N_NODES, 0, "two", &err) == 0, "%s", err.msg);
  CHECK(proto_poll_in(b, 0) == 0, "no socket message for a posted one");
  CHECK(proto_shm_pending(rd) && proto_wait_in(b, &rd, 1, 0, 0) == 2);
  CHECK(proto_shm_take(rd, &m2, &err) == 0, "%s", err.msg);
  CHECK(strcmp(m2.type, "done") == 0 && strcmp(m2.topic, "tyre") == 0 && m2.step == 7 &&
        m2.t == 0.25);
  const cJSON *note = cJSON_GetObjectItemCaseSensitive(m2.header, "note");
  CHECK(cJSON_IsString(note) && strcmp(note->valuestring, "two") == 0);
  const proto_array *ax = proto_msg_find(&m2, "x");
  CHECK(ax && same_bits(ax->data, x2, sizeof x2));
  const double *rim = proto_msg_get_f8(&m2, "rim_R", 3, 3, &err);
  CHECK(rim && rim[0] == 1 && rim[4] == 1 && rim[1] == 0, "the small frame posted too");
  CHECK(same_bits(proto_msg_find(&m1, "x")->data, x1, sizeof x1), "message 1 intact");
  CHECK(!proto_shm_pending(rd));
  CHECK(proto_shm_take(rd, &m3, &err) < 0);
  CHECK_MSG(err, "no message posted");

  /* 2b: an array below PROTO_SHM_MIN_BYTES written into the next buffer
   * (proto_peer_reply_buffer's way; fem_server's x, v of a small surface) is
   * posted intact: it keeps its place, and the frames go after it (laid from
   * the buffer's start, they overwrote it: a slab scene's non-finite grains) */
  enum { SMALL = 100 }; /* 2400 bytes */
  double *in_buf = proto_shm_next(w, sizeof(double) * 3 * SMALL);
  CHECK(in_buf != NULL);
  double want_small[3 * SMALL];
  for (int i = 0; i < 3 * SMALL; i++) in_buf[i] = want_small[i] = 7.0 + 1.0 / (i + 1);
  CHECK(send_x(a, w, in_buf, SMALL, 0, "small", &err) == 0, "%s", err.msg);
  proto_msg ms = {0};
  CHECK(proto_shm_take(rd, &ms, &err) == 0, "%s", err.msg);
  const proto_array *as = proto_msg_find(&ms, "x");
  CHECK(as && as->nbytes == sizeof want_small && same_bits(as->data, want_small, sizeof want_small),
        "a small array written in the buffer arrives intact");
  const cJSON *ns = cJSON_GetObjectItemCaseSensitive(ms.header, "note");
  CHECK(cJSON_IsString(ns) && strcmp(ns->valuestring, "small") == 0, "and its header too");
  proto_msg_free(&ms);

  /* 3: a reader in another process, asleep on the bell, wakes for a post */
  fflush(stdout);
  pid_t child = fork();
  if (child == 0) {
    proto_msg mc = {0};
    proto_err e = {{0}};
    /* one wait of 20 s: back well before it, the futex woke it (not a
     * timeout followed by a look) */
    const double t0 = proto_now();
    int woke = proto_shm_wait(rd, 20000000) && proto_now() - t0 < 10;
    int ok = woke && proto_shm_take(rd, &mc, &e) == 0 &&
             same_bits(proto_msg_find(&mc, "x")->data, x1, sizeof x1);
    _exit(ok ? 0 : 1);
  }
  CHECK(child > 0);
  usleep(50000);
  CHECK(send_x(a, w, x1, N_NODES, 0, "three", &err) == 0, "%s", err.msg);
  int status = -1;
  CHECK(waitpid(child, &status, 0) == child && WIFEXITED(status) &&
        WEXITSTATUS(status) == 0, "the child woke on the bell and read the post");
  CHECK(proto_shm_take(rd, &m3, &err) == 0, "%s", err.msg); /* ours, too */

  /* 4: a message larger than the segment: announced, so on the socket; the
   * next one is posted in the new segment */
  const int64_t big = 40000;
  double *xb = malloc(sizeof(double) * 3 * (size_t)big);
  for (int64_t i = 0; i < 3 * big; i++) xb[i] = (double)i * 1e-3;
  CHECK(send_x(a, w, xb, big, 0, "four", &err) == 0, "%s", err.msg);
  CHECK(!proto_shm_pending(rd) && proto_poll_in(b, 100) == 1);
  CHECK(proto_recv_via(b, &m4, NULL, the_reader, rd, &err) == 0, "%s", err.msg);
  CHECK(same_bits(proto_msg_find(&m4, "x")->data, xb, sizeof(double) * 3 * (size_t)big));
  CHECK(send_x(a, w, xb, big, 0, "five", &err) == 0, "%s", err.msg);
  CHECK(proto_shm_take(rd, &m5, &err) == 0, "%s", err.msg);
  CHECK(same_bits(proto_msg_find(&m5, "x")->data, xb, sizeof(double) * 3 * (size_t)big));
  uint64_t sent, posted;
  proto_shm_bells(w, &sent, &posted);
  CHECK(sent == 6 && posted == 4, "sent %llu, posted %llu", (unsigned long long)sent,
        (unsigned long long)posted);

  /* 5: two posts where lock-step allows one: refused, named */
  CHECK(send_x(a, w, x1, N_NODES, 0, "six", &err) == 0, "%s", err.msg);
  CHECK(send_x(a, w, x2, N_NODES, 0, "seven", &err) == 0, "%s", err.msg);
  CHECK(proto_shm_take(rd, &m3, &err) < 0);
  CHECK_MSG(err, "posted 2 messages");
  proto_msg_free(&m1), proto_msg_free(&m2), proto_msg_free(&m3), proto_msg_free(&m4);
  proto_msg_free(&m5);
  free(xb);
  pair_close(&P);
}

/* The bell's slice: PROTO_BELL_SLICE_S while a wait is younger than
 * PROTO_BELL_IDLE_S, then PROTO_BELL_SLICE_IDLE_S; never shorter for a longer
 * wait, and a socket message after an idle wait waits at most 5 % of it. */
static void test_slices(void) {
  CHECK(proto_bell_slice(0) == PROTO_BELL_SLICE_S);
  CHECK(proto_bell_slice(-1) == PROTO_BELL_SLICE_S, "a clock that went back: the short slice");
  CHECK(proto_bell_slice(0.999 * PROTO_BELL_IDLE_S) == PROTO_BELL_SLICE_S);
  CHECK(proto_bell_slice(PROTO_BELL_IDLE_S) == PROTO_BELL_SLICE_IDLE_S);
  CHECK(proto_bell_slice(1e9) == PROTO_BELL_SLICE_IDLE_S);
  int monotone = 1;
  for (int i = 0; i < 1000; i++)
    monotone &= proto_bell_slice(0.01 * (i + 1)) >= proto_bell_slice(0.01 * i);
  CHECK(monotone);
  CHECK(PROTO_BELL_SLICE_IDLE_S <= 0.05 * PROTO_BELL_IDLE_S + 1e-12);
  /* idle for a minute: about 4 wake-ups a second, not 50 */
  CHECK(1.0 / proto_bell_slice(60.0) <= 4.0 + 1e-9);
}

int main(void) {
  test_slices();
  test_round_trip();
  test_doorbell();
  test_descriptors_refused();
  return cosim_test_done("test_shm");
}
