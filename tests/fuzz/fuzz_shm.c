/* fuzz_shm — one received message whose arrays may lie in shared memory:
 * proto_decode_via with a reader mapped to a real segment (two buffers of
 * PROTO_SHM_INITIAL_BYTES, message 1 written in buffer 1), then every byte
 * of every array is read. Input: frames (topic, header, arrays...) separated
 * by "|#|", as fuzz_decode. A descriptor that points outside the buffer, a
 * stale message number or a bad shm_segment must be refused, never read.
 * Input that starts with "#post#": the rest overwrites the buffer of a
 * message just posted through the doorbell (its frame table and frames),
 * which proto_shm_take must then refuse or decode within the buffer. */
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

#define POST_PREFIX "#post#"

static proto_shm *post_writer, *post_reader;

static void read_all(const proto_msg *m) {
  volatile double sum = 0;
  for (int i = 0; i < m->narrays; i++) {
    const unsigned char *p = m->arrays[i].data;
    for (size_t b = 0; b < m->arrays[i].nbytes; b++) sum += p[b];
  }
  (void)sum;
}

/* A posted message whose buffer the input then overwrites. */
static void posted(const uint8_t *data, size_t size) {
  proto_err err = {{0}};
  if (!post_reader) {
    post_writer = proto_shm_writer(PROTO_SHM_INITIAL_BYTES, &err);
    post_reader = proto_shm_reader();
    /* the descriptor as a welcome carries it (announced: messages may be posted) */
    cJSON *h = cJSON_CreateObject();
    if (!post_writer || !h || proto_shm_announce(post_writer, h) < 0 ||
        proto_shm_attach(post_reader,
                         cJSON_GetObjectItemCaseSensitive(h, PROTO_H_SHM_SEGMENT), &err) < 0)
      __builtin_trap();
    cJSON_Delete(h);
    proto_shm_ring(post_writer);
  }
  if (size > PROTO_SHM_INITIAL_BYTES) size = PROTO_SHM_INITIAL_BYTES;
  unsigned char *buf = proto_shm_next(post_writer, PROTO_SHM_INITIAL_BYTES);
  static double f[3 * 100];
  proto_msg m = {0};
  proto_msg_reset(&m, "dem", "done", 1, 0);
  /* small frames only: the frame table lies at the buffer's start, where
   * the input lands (arrays in the segment are the other mode's) */
  proto_msg_add_f8(&m, "nodal_force", 100, 3, f);
  proto_msg_add_f8(&m, "torque", 1, 3, f);
  /* no socket: a post that fails would have to be sent, and that must not happen */
  if (!buf || proto_send_via(NULL, NULL, &m, 0, post_writer, &err) < 0) __builtin_trap();
  memcpy(buf, data, size);
  proto_msg got = {0};
  if (proto_shm_take(post_reader, &got, &err) == 0) read_all(&got);
  for (const char *c = err.msg; *c; c++)
    if (*c == 0x1b) __builtin_trap();
  proto_msg_free(&got);
  proto_msg_free(&m);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  if (size >= strlen(POST_PREFIX) && memcmp(data, POST_PREFIX, strlen(POST_PREFIX)) == 0) {
    posted(data + strlen(POST_PREFIX), size - strlen(POST_PREFIX));
    return 0;
  }
  setup();
  void *frame[MAX_FRAMES];
  size_t len[MAX_FRAMES];
  int n = fuzz_frames(data, size, SEP, MAX_FRAMES, frame, len);
  proto_msg m = {0};
  proto_err err = {{0}};
  if (proto_decode_via(&m, n, (const void *const *)frame, len, reader, &err) == 0) {
    read_all(&m); /* every byte read (the mapping's bounds) */
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
