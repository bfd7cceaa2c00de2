/* fuzz_decode — one received message: proto_decode, then the role table's
 * check of it for every role and message kind, and the getters. Input: the
 * frames (topic, header, arrays...) separated by "|#|". Each frame is copied
 * into its own exact-size buffer, so a read past a frame is an ASan error. */
#include "fuzz.h"
#include "proto/proto.h"

#define SEP "|#|"
#define MAX_FRAMES (PROTO_MAX_ARRAYS + 4)

/* Reads every element of every array (what a consumer would do). */
static double touch(const proto_msg *m) {
  double sum = 0;
  for (int i = 0; i < m->narrays; i++) {
    const unsigned char *p = m->arrays[i].data;
    for (size_t b = 0; b < m->arrays[i].nbytes; b++) sum += p[b];
  }
  return sum;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  void *frame[MAX_FRAMES];
  size_t len[MAX_FRAMES];
  int n = fuzz_frames(data, size, SEP, MAX_FRAMES, frame, len);
  proto_msg m = {0};
  proto_err err = {{0}};
  if (proto_decode(&m, n, (const void *const *)frame, len, &err) == 0) {
    volatile double s = touch(&m);
    (void)s;
    for (int r = 0; r < PROTO_N_ROLES; r++)
      for (int k = 0; k < PROTO_N_MSGS; k++) {
        proto_dims d;
        proto_dims_init(&d);
        proto_role_check((proto_role)r, (proto_msg_kind)k, &m, &d, &err);
      }
    int64_t shape[2] = {-1, -1};
    for (int i = 0; i < m.narrays; i++) {
      proto_msg_get(&m, m.arrays[i].name, PROTO_F8, 2, shape, &err);
      proto_msg_get_f8(&m, m.arrays[i].name, -1, 0, &err);
    }
    int64_t v;
    proto_header_int(&m, "iteration", 0, INT32_MAX, 0, &v, &err);
  }
  /* every message is terminal-safe */
  for (const char *c = err.msg; *c; c++)
    if (*c == 0x1b) __builtin_trap();
  proto_msg_free(&m);
  fuzz_frames_free(frame, n);
  return 0;
}
