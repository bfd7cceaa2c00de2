/* proto_msg.h — proto's messages: names, the multipart format, sockets, the clock.
 * Part of proto.h, the one public header: include "proto/proto.h", not this. */
#ifndef COSIM_PROTO_MSG_H
#define COSIM_PROTO_MSG_H
#ifndef COSIM_PROTO_H
#error "include proto/proto.h, not proto_msg.h"
#endif

/* ---------------------------------------------------------------- messages */

typedef enum proto_dtype {
  PROTO_F8 = 0, /* little-endian IEEE double, "f8" */
  PROTO_I4 = 1, /* little-endian int32, "i4" */
  PROTO_I8 = 2, /* little-endian int64, "i8" */
  PROTO_U1 = 3  /* bytes, "u1" */
} proto_dtype;

#define PROTO_MAX_ARRAYS 64
#define PROTO_MAX_NDIM 3
#define PROTO_NAME_LEN 48

/* Names that become HDF5 paths, file names, XDMF text or terminal output
 * (process names, array names, series datasets, snapshot names, message
 * types, topics) follow one grammar, checked here and nowhere else:
 * 1 to PROTO_NAME_LEN - 1 characters; a segment is [A-Za-z0-9_-]+; a plain
 * name is one segment, a dotted name (array names with a prefix such as
 * "series.wall_forces", bus topics "soil.series") segments joined by single
 * dots. So no '/', no empty, "." or ".." segment, no space, quote or control
 * character. `what` names the name in the error ("array name", "process
 * name"); the offending name is quoted sanitised. */
typedef enum { PROTO_NAME_PLAIN = 0, PROTO_NAME_DOTTED = 1 } proto_name_kind;
int proto_name_check(const char *name, proto_name_kind kind, const char *what,
                     proto_err *err);
/* The same grammar for a name stored in cap bytes (a scene's name). */
int proto_name_check_len(const char *name, size_t cap, proto_name_kind kind,
                         const char *what, proto_err *err);

typedef struct proto_array {
  char name[PROTO_NAME_LEN];
  proto_dtype dtype;
  int ndim;
  int64_t shape[PROTO_MAX_NDIM];
  const void *data; /* send: caller's buffer; recv: inside the received frame
                       (8-byte aligned; copied only if the frame was not) */
  size_t nbytes;
} proto_array;

/* One message. `header` holds any header fields beyond the fixed ones
 * (v, type, step, t, arrays); it is owned by the message. */
typedef struct proto_msg {
  char topic[PROTO_NAME_LEN];
  char type[PROTO_NAME_LEN];
  int64_t step;
  double t;
  cJSON *header; /* extra fields; may be NULL */
  int narrays;
  proto_array arrays[PROTO_MAX_ARRAYS];
  struct proto_msg_frames *frames_; /* recv side: the frames the arrays point into */
} proto_msg;

/* Resets a message for building; frees what a previous recv or build owned. */
void proto_msg_reset(proto_msg *m, const char *topic, const char *type,
                     int64_t step, double t);
void proto_msg_free(proto_msg *m);
/* Adds an array that points at the caller's buffer (no copy). The buffer must
 * stay valid and unchanged until the peer has answered (lock-step) — for the
 * bus, proto_publish copies. shape has ndim entries. Returns -1 if full or
 * if the name breaks proto_name_check (dotted), which the receiver enforces. */
int proto_msg_add(proto_msg *m, const char *name, proto_dtype dtype, int ndim,
                  const int64_t *shape, const void *data);
/* Shorthands for the common cases. */
int proto_msg_add_f8(proto_msg *m, const char *name, int64_t rows, int64_t cols,
                     const double *data); /* cols == 0: 1-D [rows] */
int proto_msg_add_i4(proto_msg *m, const char *name, int64_t rows, int64_t cols,
                     const int32_t *data);
/* Extra header fields (created on demand). */
cJSON *proto_msg_header(proto_msg *m);

/* Finds an array by name and checks it: dtype, ndim and each shape entry
 * (an expected entry < 0 means "any"). Returns NULL and fills err with a
 * message naming the message type, the array and what was expected. */
const proto_array *proto_msg_get(const proto_msg *m, const char *name,
                                 proto_dtype dtype, int ndim,
                                 const int64_t *shape, proto_err *err);
/* "[2,3]" (an entry < 0 is shown as "*"), for messages. */
void proto_shape_str(char *out, size_t cap, int ndim, const int64_t *shape);
/* The same for f8 arrays: rows x cols (cols == 0: 1-D; -1: any). */
const double *proto_msg_get_f8(const proto_msg *m, const char *name,
                               int64_t rows, int64_t cols, proto_err *err);
const proto_array *proto_msg_find(const proto_msg *m, const char *name);

/* Sends [topic][header][arrays...] on a ZeroMQ socket (zero-copy for arrays).
 * flags: 0 or ZMQ_DONTWAIT. For ROUTER sockets first send the identity
 * frame with ZMQ_SNDMORE yourself (proto_send_to does that). */
int proto_send(void *socket, const proto_msg *m, int flags, proto_err *err);
int proto_send_to(void *router, const char *identity, const proto_msg *m,
                  proto_err *err);
/* Receives and validates one message: frame count, JSON header, version,
 * dtype names, shapes against byte counts, limits. On any defect returns -1
 * with a message and leaves the socket ready for the next message.
 * `identity` (may be NULL) receives the ROUTER identity frame when the
 * socket is a ROUTER (size PROTO_NAME_LEN). */
int proto_recv(void *socket, proto_msg *m, char *identity, proto_err *err);
/* Decodes already-received frames (used by proto_recv and by tests/fuzzers).
 * frames[i]/sizes[i]: topic, header, arrays. The arrays are not copied:
 * they must outlive m. */
int proto_decode(proto_msg *m, int nframes, const void *const *frames,
                 const size_t *sizes, proto_err *err);

/* Largest array frame accepted (bytes); larger frames are rejected. */
#define PROTO_MAX_FRAME_BYTES ((size_t)1 << 30)
/* Largest header frame accepted (bytes): a welcome carries a config section. */
#define PROTO_MAX_HEADER_BYTES ((size_t)64 << 20)
/* Integer header fields (step, iteration) are within +-2^53: exact doubles. */
#define PROTO_MAX_HEADER_INT 9007199254740992.0
/* Reads an optional integer header field of a received message into *out
 * (def when absent): it must be an integer in [lo, hi]. Errors name the
 * message type and the field. */
int proto_header_int(const proto_msg *m, const char *key, int64_t lo,
                     int64_t hi, int64_t def, int64_t *out, proto_err *err);

/* Sets the input limits of a receiving socket: a peer that sends a frame
 * larger than PROTO_MAX_FRAME_BYTES is disconnected by ZeroMQ before the
 * frame is allocated (proto_recv would refuse it only after). */
int proto_socket_limits(void *socket);
/* Waits up to timeout_ms for the socket to become readable.
 * Returns 1 readable, 0 timeout, -1 interrupted (EINTR). */
int proto_poll_in(void *socket, int timeout_ms);
/* Monotonic wall clock in seconds. */
double proto_now(void);

/* Publishes a copy of the message on a bus socket (PUB), never blocking:
 * a full queue drops the message (slow monitors never slow a run). */
int proto_publish(void *pub, const proto_msg *m);

#endif
