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
 * a message is replaced by a larger one, announced in that message. */
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
/* proto_decode with a reader (NULL: descriptors are refused). */
int proto_decode_via(proto_msg *m, int nframes, const void *const *frames,
                     const size_t *sizes, proto_shm *rd, proto_err *err);

/* internal to proto (proto.c ↔ shm.c) */
typedef struct proto_shm_place {
  int64_t offset[PROTO_MAX_ARRAYS]; /* < 0: as a frame */
  uint64_t seq;                     /* the message number; 0: no array placed */
  int announce;                     /* a new segment: its descriptor in the header */
} proto_shm_place;
int proto_shm_place_msg(proto_shm *w, const proto_msg *m, proto_shm_place *pl,
                        proto_err *err);
char *proto_shm_descriptor_json(const proto_shm *w); /* malloc'd */
int proto_shm_resolve(proto_shm *rd, proto_array *a, const cJSON *desc,
                      size_t frame_bytes, proto_err *err);

#endif
