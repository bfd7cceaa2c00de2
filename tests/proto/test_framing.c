/* The decoder rejects every malformed message with a message, never a crash:
 * truncated and oversized frames, frame-count mismatches, bad dtypes and
 * shapes, wrong protocol versions, non-JSON headers. And a round trip over a
 * real socket pair keeps arrays bit-exact. */
#include <stdlib.h>
#include <zmq.h>

#include "cosim_test.h"
#include "proto/proto.h"

static int decode(const char *header, int narr, const size_t *arr_sizes,
                  proto_err *err) {
  static double payload[64];
  const void *frames[8] = {"topic", header};
  size_t sizes[8] = {5, strlen(header)};
  for (int i = 0; i < narr; i++) {
    frames[2 + i] = payload;
    sizes[2 + i] = arr_sizes[i];
  }
  proto_msg m = {0};
  int rc = proto_decode(&m, 2 + narr, frames, sizes, err);
  proto_msg_free(&m);
  return rc;
}

static void test_decoder_rejects(void) {
  proto_err err = {{0}};
  const char *ok = "{\"v\":1,\"type\":\"step\",\"step\":3,\"t\":0.5,"
                   "\"arrays\":[{\"name\":\"x\",\"dtype\":\"f8\",\"shape\":[2,3]}]}";
  size_t good[1] = {48}, truncated[1] = {47}, extra[1] = {56};
  CHECK(decode(ok, 1, good, &err) == 0);
  CHECK(decode(ok, 1, truncated, &err) < 0);
  CHECK_MSG(err, "needs 48 bytes, frame has 47");
  CHECK(decode(ok, 1, extra, &err) < 0);
  CHECK(decode(ok, 0, NULL, &err) < 0);
  CHECK_MSG(err, "1 array(s) but 0 array frame(s)");
  size_t two[2] = {48, 8};
  CHECK(decode(ok, 2, two, &err) < 0);
  CHECK(decode("{\"v\":2,\"type\":\"step\"}", 0, NULL, &err) < 0);
  CHECK_MSG(err, "protocol version mismatch");
  CHECK(decode("not json", 0, NULL, &err) < 0);
  CHECK_MSG(err, "header is not a JSON object");
  CHECK(decode("{\"type\":\"step\"}", 0, NULL, &err) < 0);
  CHECK_MSG(err, "header.v");
  CHECK(decode("{\"v\":1,\"type\":\"s\",\"arrays\":[{\"name\":\"x\",\"dtype\":\"f4\",\"shape\":[1]}]}",
               1, (size_t[]){4}, &err) < 0);
  CHECK_MSG(err, "dtype");
  CHECK(decode("{\"v\":1,\"type\":\"s\",\"arrays\":[{\"name\":\"x\",\"dtype\":\"f8\",\"shape\":[-1]}]}",
               1, (size_t[]){8}, &err) < 0);
  CHECK(decode("{\"v\":1,\"type\":\"s\",\"arrays\":[{\"name\":\"x\",\"dtype\":\"f8\",\"shape\":[1,2,3,4]}]}",
               1, (size_t[]){192}, &err) < 0);
  /* oversized: a shape claiming more than the frame limit */
  CHECK(decode("{\"v\":1,\"type\":\"s\",\"arrays\":[{\"name\":\"x\",\"dtype\":\"f8\",\"shape\":[100000000000]}]}",
               1, (size_t[]){8}, &err) < 0);
  CHECK_MSG(err, "exceeds the limit");
  CHECK(decode("{\"v\":1,\"type\":\"s\",\"arrays\":[{\"name\":\"x\",\"dtype\":\"f8\",\"shape\":[1]},"
               "{\"name\":\"x\",\"dtype\":\"f8\",\"shape\":[1]}]}",
               2, (size_t[]){8, 8}, &err) < 0);
  CHECK_MSG(err, "appears twice");
  CHECK(decode("{\"v\":1,\"type\":\"s\",\"step\":\"x\"}", 0, NULL, &err) < 0);
  CHECK_MSG(err, "header.step");
}

static void test_getters(void) {
  proto_err err = {{0}};
  double x[6] = {1, 2, 3, 4, 5, 6};
  proto_msg m = {0};
  proto_msg_reset(&m, "t", "done", 1, 0);
  proto_msg_add_f8(&m, "x", 2, 3, x);
  CHECK(proto_msg_get_f8(&m, "x", 2, 3, &err) == x);
  CHECK(proto_msg_get_f8(&m, "x", 3, 3, &err) == NULL);
  CHECK_MSG(err, "array 'x' is f8 [2,3], expected f8 [3,3]");
  CHECK(proto_msg_get_f8(&m, "y", 2, 3, &err) == NULL);
  CHECK_MSG(err, "missing array 'y'");
  CHECK(proto_msg_get_f8(&m, "x", -1, 3, &err) == x);
  proto_msg_free(&m);
}

static void test_round_trip(void) {
  void *ctx = zmq_ctx_new();
  void *a = zmq_socket(ctx, ZMQ_PAIR), *b = zmq_socket(ctx, ZMQ_PAIR);
  CHECK(zmq_bind(a, "inproc://rt") == 0);
  CHECK(zmq_connect(b, "inproc://rt") == 0);
  enum { N = 1000 };
  double *x = malloc(sizeof(double) * 3 * N);
  int32_t tri[6] = {0, 1, 2, 2, 1, 3};
  for (int i = 0; i < 3 * N; i++) x[i] = 1.0 / (i + 1);
  proto_msg m = {0}, r = {0};
  proto_err err = {{0}};
  proto_msg_reset(&m, "fem", "done", 7, 0.25);
  cJSON_AddStringToObject(proto_msg_header(&m), "extra", "yes");
  proto_msg_add_f8(&m, "x", N, 3, x);
  proto_msg_add_i4(&m, "tri", 2, 3, tri);
  double one = 3.5;
  proto_msg_add_f8(&m, "s", 1, 0, &one); /* small frame: may arrive unaligned */
  CHECK(proto_send(a, &m, 0, &err) == 0);
  CHECK(proto_recv(b, &r, NULL, &err) == 0);
  CHECK(strcmp(r.topic, "fem") == 0 && strcmp(r.type, "done") == 0);
  CHECK(r.step == 7 && r.t == 0.25 && r.narrays == 3);
  const double *rx = proto_msg_get_f8(&r, "x", N, 3, &err);
  CHECK(rx && memcmp(rx, x, sizeof(double) * 3 * N) == 0);
  const double *rs = proto_msg_get_f8(&r, "s", 1, 0, &err);
  CHECK(rs && *rs == 3.5 && ((uintptr_t)rs % 8) == 0);
  const cJSON *extra = cJSON_GetObjectItem(r.header, "extra");
  CHECK(cJSON_IsString(extra));
  /* a raw, truncated multipart message is rejected and the socket recovers */
  zmq_send(a, "t", 1, ZMQ_SNDMORE);
  const char *h = "{\"v\":1,\"type\":\"x\",\"arrays\":[{\"name\":\"a\",\"dtype\":\"f8\",\"shape\":[4]}]}";
  zmq_send(a, h, strlen(h), ZMQ_SNDMORE);
  zmq_send(a, x, 24, 0);
  CHECK(proto_recv(b, &r, NULL, &err) < 0);
  CHECK_MSG(err, "needs 32 bytes, frame has 24");
  CHECK(proto_send(a, &m, 0, &err) == 0);
  CHECK(proto_recv(b, &r, NULL, &err) == 0 && r.narrays == 3);
  proto_msg_free(&m);
  proto_msg_free(&r);
  free(x);
  zmq_close(a);
  zmq_close(b);
  zmq_ctx_term(ctx);
}

int main(void) {
  test_decoder_rejects();
  test_getters();
  test_round_trip();
  return cosim_test_done("test_framing");
}
