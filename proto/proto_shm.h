/* proto_shm.h — proto's shared-memory data plane (PROTOCOL.md "Shared memory"):
 * a message's large arrays travel in a segment mapped by both processes,
 * the ZeroMQ message carries only their descriptors (the doorbell).
 * Part of proto.h, the one public header: include "proto/proto.h", not this.
 *
 * One segment per direction of a conversation, owned by its writer: an
 * anonymous memfd (memfd_create, sealed against shrinking and growing), which
 * the reader opens read-only through /proc/<writer pid>/fd/<fd>. No name ever
 * exists in /dev/shm or the run directory, so a process that dies leaves
 * nothing behind: the pages go when the last mapping does. Two buffers per
 * segment (double buffering): message number s (s = 1, 2, ... per writer)
 * lies in buffer s mod 2, so the reader may keep the previous message while
 * the writer fills the next one. The writer publishes each buffer with a
 * release store of s into the segment header before the ZeroMQ send; the
 * reader's acquire load after the receive must find that s (C11
 * <stdatomic.h>), or the message is refused. A segment that is too small for
 * a message is replaced by a larger one, announced in that message.
 *
 * The doorbell: once its reader maps the segment, a writer that rings
 * (proto_shm_ring) posts each whole message in it (topic, header and small
 * frames after the arrays), bumps the header's bell word and wakes the
 * reader with a futex: no ZeroMQ message at all, one wake-up instead of
 * libzmq's four thread hops. Messages that announce a segment, or do not
 * fit, still travel on the socket. */
#ifndef COSIM_PROTO_SHM_H
#define COSIM_PROTO_SHM_H
#ifndef COSIM_PROTO_H
#error "include proto/proto.h, not proto_shm.h"
#endif

typedef struct proto_shm proto_shm; /* one direction: a writer or a reader */

/* Arrays smaller than this travel as frames: a frame of one page costs the
 * socket no more than its descriptor does (bytes). */
#define PROTO_SHM_MIN_BYTES 4096
/* A new segment's buffer (bytes, each of the two): the first message that
 * needs more replaces it with one of 5/4 of what it needs. */
#define PROTO_SHM_INITIAL_BYTES ((size_t)64 << 10)
/* The largest buffer a writer makes and a reader accepts (bytes): what does
 * not fit travels as frames (the largest frame is PROTO_MAX_FRAME_BYTES). */
#define PROTO_SHM_MAX_BUFFER_BYTES ((size_t)1 << 30)

/* Waiting for a posted message, the socket is looked at between futex
 * waits (slices): a heartbeat, or a control message that takes the socket
 * (stop, a segment announced), waits at most a slice. Each slice costs a
 * wake-up, and a process woken while it waits takes a core from a peer that
 * computes. So a wait that has lasted PROTO_BELL_IDLE_S is an idle process
 * and sleeps in longer slices: the waits of the coupled loop (milliseconds)
 * and of a short init keep 20 ms, while a participant idle for minutes (the
 * tread while the grains settle a bed) wakes 4 times a second, not 50; a
 * socket message then waits at most 5 % of the wait before it. With several
 * readers the futex sleeps on the first: a message posted in another is
 * taken when the first's comes or the slice ends, which costs nothing when
 * (as in a stage) every reply is needed before the coupler goes on. */
#define PROTO_BELL_SLICE_S 20e-3     /* s: the slice of a wait younger than PROTO_BELL_IDLE_S */
#define PROTO_BELL_IDLE_S 5.0        /* s: a wait this long is an idle process */
#define PROTO_BELL_SLICE_IDLE_S 0.25 /* s: its slice (4 wake-ups a second) */

/* Header fields (PROTOCOL.md "Shared memory"). */
#define PROTO_H_HOST "host"           /* hello: {name, boot_id}: it can map segments */
#define PROTO_H_SHM_SEGMENT "shm_segment" /* welcome, ready, any later message: a writer's segment */
#define PROTO_H_TRANSPORT "transport" /* ready: "shm" or "socket" */
#define PROTO_H_SHM_ERROR "shm_error" /* ready: why a participant keeps the socket */
#define PROTO_A_SHM "shm"             /* array spec: [message number, byte offset] */

/* A writer with a segment of two buffers of buffer_bytes each. */
proto_shm *proto_shm_writer(size_t buffer_bytes, proto_err *err);
/* A reader with no segment yet (proto_shm_attach, or a message's
 * shm_segment, maps one). */
proto_shm *proto_shm_reader(void);
/* Unmaps and closes; NULL is fine. Messages read from a reader must be
 * freed (or no longer read) before it is. */
void proto_shm_free(proto_shm *s);
/* Adds the writer's segment descriptor to a header (welcome, ready). */
int proto_shm_announce(proto_shm *w, cJSON *header);
/* Maps the segment a descriptor names (checked: fields, size, seals, magic,
 * the writer's random nonce). On failure the reader is unchanged. */
int proto_shm_attach(proto_shm *rd, const cJSON *desc, proto_err *err);
int proto_shm_attached(const proto_shm *rd);
/* This host: "<hostname> <boot id>" (PROTO_H_HOST's two fields), for the
 * "same host?" test of the handshake. */
int proto_shm_host(char *name, size_t name_cap, char *boot_id, size_t boot_cap);
/* Zero copy: the place in the buffer the writer's next message will use,
 * nbytes long (8-byte aligned), or NULL if the current segment is smaller.
 * An array added from there is sent without a copy. */
void *proto_shm_next(proto_shm *w, size_t nbytes);
/* Bytes the writer copied into its segment, and arrays it placed without a
 * copy, since it was made (tests, timing). */
void proto_shm_counts(const proto_shm *w, uint64_t *copied_bytes, uint64_t *in_place);

/* The doorbell (PROTOCOL.md "Shared memory"). A writer rings once its
 * reader is known to map its segment; from then on proto_send_via posts
 * every message it can in the segment instead of sending it. */
void proto_shm_ring(proto_shm *w);
int proto_shm_rings(const proto_shm *w);
/* Writer: messages sent through it (proto_send_via), and how many of them
 * were posted whole (the rest went on the socket). */
void proto_shm_bells(const proto_shm *w, uint64_t *sent, uint64_t *posted);
/* Reader: 1 if a posted message waits to be taken. */
int proto_shm_pending(const proto_shm *rd);
/* Reader: sleeps until a message is posted or timeout_us passes (a futex
 * on the bell word); 1 if one is pending. */
int proto_shm_wait(const proto_shm *rd, int timeout_us);
/* Reader: the posted message into m (decoded and checked as a received
 * one: proto_decode_via); -1 with err naming the defect. */
int proto_shm_take(proto_shm *rd, proto_msg *m, proto_err *err);
/* The bell's slice (s) after waiting waited_s (see PROTO_BELL_SLICE_S). */
double proto_bell_slice(double waited_s);
/* Waits up to timeout_ms for the socket (1) or a message posted in readers
 * rds[i] (2 + i); 0 on timeout, -1 on a poll error. NULL readers are
 * skipped. since: when the caller's wait began (proto_now(); 0: at this
 * call), which sets the bell's slices (proto_bell_slice). */
int proto_wait_in(void *socket, proto_shm *const *rds, int n, int timeout_ms, double since);

/* proto_send / proto_send_to through a writer (NULL: plain frames).
 * identity: the ROUTER identity, or NULL on a DEALER. */
int proto_send_via(void *socket, const char *identity, const proto_msg *m,
                   int flags, proto_shm *w, proto_err *err);
/* proto_recv with the readers of its senders: reader_of(ctx, identity)
 * gives the reader for a sender (identity "" on a DEALER) or NULL, when a
 * descriptor is then refused. reader_of NULL: no reader. */
typedef proto_shm *(*proto_shm_lookup)(void *ctx, const char *identity);
int proto_recv_via(void *socket, proto_msg *m, char *identity,
                   proto_shm_lookup reader_of, void *ctx, proto_err *err);
/* Receives what proto_wait_in found (found >= 1, its return value): the
 * message posted in rds[found - 2], or the socket's (proto_recv_via: identity,
 * reader_of and ctx as there; identity is left as it is for a posted one). */
int proto_recv_found(void *socket, int found, proto_shm *const *rds, proto_msg *m,
                     char *identity, proto_shm_lookup reader_of, void *ctx, proto_err *err);
/* proto_decode with a reader (NULL: descriptors are refused). */
int proto_decode_via(proto_msg *m, int nframes, const void *const *frames,
                     const size_t *sizes, proto_shm *rd, proto_err *err);

/* internal to proto (proto.c ↔ shm.c) */
typedef struct proto_shm_place {
  int64_t offset[PROTO_MAX_ARRAYS]; /* < 0: as a frame */
  uint64_t seq;                     /* the message number; 0: no array placed */
  size_t end;                       /* bytes of the buffer the placed arrays take */
  int announce;                     /* a new segment: its descriptor in the header */
} proto_shm_place;
int proto_shm_place_msg(proto_shm *w, const proto_msg *m, proto_shm_place *pl,
                        proto_err *err);
char *proto_shm_descriptor_json(const proto_shm *w); /* malloc'd */
/* The frames of the posted message (pointing into the segment, checked to
 * lie in its buffer): their count, or -1 with err; proto_shm_take decodes
 * them. data and size hold PROTO_MAX_ARRAYS + 2. */
int proto_shm_frames(proto_shm *rd, const void **data, size_t *size, proto_err *err);
/* 1: posted whole (the bell rung), 0: send it on the socket */
int proto_shm_post(proto_shm *w, const proto_shm_place *pl, const proto_msg *m,
                   const char *header);
int proto_shm_resolve(proto_shm *rd, proto_array *a, const cJSON *desc,
                      size_t frame_bytes, proto_err *err);

#endif
