/* fuzz_shm — one received message whose arrays may lie in shared memory:
 * proto_decode_via with a reader mapped to a real segment (two buffers of
 * PROTO_SHM_INITIAL_BYTES, message 1 written in buffer 1), then every byte
 * of every array is read. Input: frames (topic, header, arrays...) separated
 * by "|#|", as fuzz_decode. A descriptor that points outside the buffer, a
 * stale message number or a bad shm_segment must be refused, never read. */
#include "fuzz.h"
#include "proto/proto.h"

#define SEP "|#|"
#define MAX_FRAMES (PROTO_MAX_ARRAYS + 4)

static proto_shm *writer, *reader;

static void setup(void) {
  if (reader) return;
  proto_err err;
  writer = proto_shm_writer(PROTO_SHM_INITIAL_BYTES, &err);
  reader = proto_shm_reader();
  char *desc = writer ? proto_shm_descriptor_json(writer) : NULL;
  cJSON *d = desc ? cJSON_Parse(desc) : NULL;
  if (!d || proto_shm_attach(reader, d, &err) < 0) __builtin_trap();
  static double x[3000];
  proto_msg m = {0};
  proto_msg_reset(&m, "dem", "done", 1, 0);
  proto_msg_add_f8(&m, "nodal_force", 1000, 3, x);
  proto_shm_place pl;
  if (proto_shm_place_msg(writer, &m, &pl, &err) < 0 || pl.seq != 1) __builtin_trap();
  proto_msg_free(&m);
  cJSON_Delete(d);
  free(desc);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  setup();
  void *frame[MAX_FRAMES];
  size_t len[MAX_FRAMES];
  int n = fuzz_frames(data, size, SEP, MAX_FRAMES, frame, len);
  proto_msg m = {0};
  proto_err err = {{0}};
  if (proto_decode_via(&m, n, (const void *const *)frame, len, reader, &err) == 0) {
    volatile double sum = 0;
    for (int i = 0; i < m.narrays; i++) {
      const unsigned char *p = m.arrays[i].data;
      for (size_t b = 0; b < m.arrays[i].nbytes; b++) sum += p[b];
    }
    (void)sum; /* every byte read (the mapping's bounds); the value itself is not wanted */
    for (int r = 0; r < PROTO_N_ROLES; r++) {
      proto_dims d;
      proto_dims_init(&d);
      proto_role_check((proto_role)r, PROTO_MSG_DONE, &m, &d, &err);
    }
  }
  for (const char *c = err.msg; *c; c++)
    if (*c == 0x1b) __builtin_trap();
  proto_msg_free(&m);
  fuzz_frames_free(frame, n);
  return 0;
}
