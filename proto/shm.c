/* shm.c — the shared-memory data plane (proto_shm.h; PROTOCOL.md "Shared
 * memory"). Send side: (a message's arrays, a writer) -> (the arrays in the
 * writer's next buffer, copied unless already there; the buffer's message
 * number published with a release store; an offset per array for the
 * header). Receive side: (a descriptor, a reader's mapping) -> (the array
 * pointing into the read-only mapping, after an acquire load of the
 * buffer's message number and bounds checks). Doorbell: (a whole message,
 * a ringing writer) -> (its frames after the arrays, a frame table, the bell
 * word bumped and woken by a futex); (a reader's bell) -> (the frames,
 * bounds-checked, for proto_decode_via). Segments are memfds: no name in
 * /dev/shm, nothing left when a process dies. */
#define _GNU_SOURCE
#include "proto.h"

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <limits.h>
#include <linux/futex.h>
#include <sys/mman.h>
#include <sys/random.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <time.h>
#include <unistd.h>

#define SHM_MAGIC 0x314d48534d534f43ULL /* "COSMSHM1" read little-endian */
#define SHM_VERSION 2u /* 2: the doorbell (bell, post_seq, post_off) */
#define SHM_PAGE ((size_t)4096)      /* buffers start on pages */
#define SHM_HEAD_BYTES SHM_PAGE      /* the header page */
#define SHM_ALIGN ((size_t)64)       /* arrays start on cache lines */
#define SHM_NONCE_BYTES 16           /* 128 random bits: this segment, not another process's fd */
#define SHM_MAX_FD 1048576.0         /* a descriptor's fd number: below the kernel's nr_open limit */
#define SHM_MAX_PID 4194304.0        /* PID_MAX_LIMIT on 64-bit Linux */

/* Both sides of one host share these 64-bit counters: they must be
 * lock-free (address-free) to work across processes. */
_Static_assert(ATOMIC_LLONG_LOCK_FREE == 2 && ATOMIC_LONG_LOCK_FREE == 2,
               "64-bit atomics must be lock-free for a segment shared by processes");

typedef struct seg_head {
  uint64_t magic;
  uint32_t version, head_bytes;
  uint64_t buffer_bytes;
  uint64_t writer_pid;
  unsigned char nonce[SHM_NONCE_BYTES];
  _Atomic uint64_t seq[2]; /* the message number each buffer holds (0: none) */
  /* the doorbell: whole messages posted in the segment (PROTOCOL.md) */
  _Atomic uint32_t bell;      /* messages posted so far: the futex word */
  uint32_t pad;
  _Atomic uint64_t post_seq;  /* the number of the last message posted */
  uint64_t post_off[2];       /* per buffer: its posted message's frame table */
} seg_head;

/* A posted message's frame table, at post_off in its buffer: topic, header
 * and the array frames (empty for arrays placed in the segment), each
 * frame 8-byte aligned inside the same buffer. */
typedef struct post_table {
  uint64_t nframes;
  uint64_t off[PROTO_MAX_ARRAYS + 2], len[PROTO_MAX_ARRAYS + 2];
} post_table;

typedef struct seg {
  unsigned char *base; /* the mapping, NULL if none */
  size_t bytes, buffer_bytes;
  int fd;              /* writer: its memfd; reader: -1 */
  unsigned char nonce[SHM_NONCE_BYTES];
} seg;

struct proto_shm {
  int writer;
  seg cur;
  seg prev;      /* reader: the segment before the last one announced (its
                    last message may still be held by the reader) */
  uint64_t seq;  /* writer: the last message number placed */
  int announced; /* writer: cur's descriptor went out */
  int ring;      /* writer: whole messages are posted (the reader maps cur) */
  uint32_t rung; /* reader: the bells of cur taken */
  uint64_t copied, in_place;
  uint64_t sent, posted; /* writer: messages sent through it, and posted whole */
};

static size_t round_up(size_t n, size_t to) { return (n + to - 1) / to * to; }

static seg_head *head_of(const seg *s) { return (seg_head *)(void *)s->base; }

static unsigned char *buffer_of(const seg *s, int b) {
  return s->base + SHM_HEAD_BYTES + (size_t)b * s->buffer_bytes;
}

static void seg_drop(seg *s) {
  if (s->base) munmap(s->base, s->bytes);
  if (s->fd >= 0) close(s->fd);
  memset(s, 0, sizeof *s);
  s->fd = -1;
}

static int random_bytes(unsigned char *out, size_t n) {
  size_t got = 0;
  while (got < n) {
    ssize_t r = getrandom(out + got, n - got, 0);
    if (r < 0 && errno == EINTR) continue;
    if (r <= 0) return -1;
    got += (size_t)r;
  }
  return 0;
}

/* A new sealed memfd of two buffers, mapped read-write. */
static int seg_make(seg *s, size_t buffer_bytes, proto_err *err) {
  memset(s, 0, sizeof *s);
  s->fd = -1;
  s->buffer_bytes = round_up(buffer_bytes ? buffer_bytes : SHM_PAGE, SHM_PAGE);
  s->bytes = SHM_HEAD_BYTES + 2 * s->buffer_bytes;
  int fd = memfd_create("cosim-shm", MFD_CLOEXEC | MFD_ALLOW_SEALING);
  if (fd < 0) return proto_fail(err, "memfd_create: %s", strerror(errno));
  const char *what = NULL;
  if (ftruncate(fd, (off_t)s->bytes) < 0) what = "ftruncate";
  /* sealed: the reader may trust the size it checked (no SIGBUS later) */
  else if (fcntl(fd, F_ADD_SEALS, F_SEAL_SHRINK | F_SEAL_GROW | F_SEAL_SEAL) < 0)
    what = "sealing";
  else if (random_bytes(s->nonce, sizeof s->nonce) < 0) what = "getrandom";
  void *p = what ? MAP_FAILED
                 : mmap(NULL, s->bytes, PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
  if (p == MAP_FAILED) {
    int e = errno;
    close(fd);
    return proto_fail(err, "shared-memory segment of %zu bytes: %s failed: %s", s->bytes,
                      what ? what : "mmap", strerror(e));
  }
  s->base = p;
  s->fd = fd;
  seg_head *h = head_of(s);
  h->magic = SHM_MAGIC;
  h->version = SHM_VERSION;
  h->head_bytes = (uint32_t)SHM_HEAD_BYTES;
  h->buffer_bytes = s->buffer_bytes;
  h->writer_pid = (uint64_t)getpid();
  memcpy(h->nonce, s->nonce, sizeof s->nonce);
  atomic_init(&h->seq[0], 0);
  atomic_init(&h->seq[1], 0);
  atomic_init(&h->bell, 0);
  atomic_init(&h->post_seq, 0);
  return 0;
}

proto_shm *proto_shm_writer(size_t buffer_bytes, proto_err *err) {
  if (buffer_bytes > PROTO_SHM_MAX_BUFFER_BYTES) {
    proto_fail(err, "shared-memory buffer of %zu bytes exceeds the limit of %zu",
               buffer_bytes, PROTO_SHM_MAX_BUFFER_BYTES);
    return NULL;
  }
  proto_shm *w = calloc(1, sizeof *w);
  if (!w) {
    proto_fail(err, "out of memory");
    return NULL;
  }
  w->writer = 1;
  w->prev.fd = -1;
  if (seg_make(&w->cur, buffer_bytes, err) < 0) {
    free(w);
    return NULL;
  }
  return w;
}

proto_shm *proto_shm_reader(void) {
  proto_shm *r = calloc(1, sizeof *r);
  if (r) r->cur.fd = r->prev.fd = -1;
  return r;
}

void proto_shm_free(proto_shm *s) {
  if (!s) return;
  seg_drop(&s->cur);
  seg_drop(&s->prev);
  free(s);
}

int proto_shm_attached(const proto_shm *rd) { return rd && rd->cur.base; }

void proto_shm_bells(const proto_shm *w, uint64_t *sent, uint64_t *posted) {
  *sent = w && w->writer ? w->sent : 0;
  *posted = w && w->writer ? w->posted : 0;
}

void proto_shm_counts(const proto_shm *w, uint64_t *copied_bytes, uint64_t *in_place) {
  if (copied_bytes) *copied_bytes = w ? w->copied : 0;
  if (in_place) *in_place = w ? w->in_place : 0;
}

/* ------------------------------------------------------------ descriptors */

char *proto_shm_descriptor_json(const proto_shm *w) {
  char hex[2 * SHM_NONCE_BYTES + 1];
  for (int i = 0; i < SHM_NONCE_BYTES; i++) snprintf(hex + 2 * i, 3, "%02x", w->cur.nonce[i]);
  char *out = malloc(256);
  if (out)
    snprintf(out, 256, "{\"pid\":%d,\"fd\":%d,\"bytes\":%zu,\"buffer_bytes\":%zu,"
             "\"nonce\":\"%s\"}", (int)getpid(), w->cur.fd, w->cur.bytes,
             w->cur.buffer_bytes, hex);
  return out;
}

int proto_shm_announce(proto_shm *w, cJSON *header) {
  char *text = w && w->writer ? proto_shm_descriptor_json(w) : NULL;
  cJSON *d = text ? cJSON_Parse(text) : NULL;
  free(text);
  if (!d || !cJSON_AddItemToObject(header, PROTO_H_SHM_SEGMENT, d)) {
    cJSON_Delete(d);
    return -1;
  }
  w->announced = 1;
  return 0;
}

/* An integer field of a descriptor in [lo, hi]. */
static int desc_int(const cJSON *d, const char *key, double lo, double hi, double *out,
                    proto_err *err) {
  const cJSON *v = cJSON_GetObjectItemCaseSensitive(d, key);
  double x = cJSON_IsNumber(v) ? v->valuedouble : NAN;
  if (!(x >= lo && x <= hi) || x != floor(x))
    return proto_fail(err, "%s.%s: expected an integer in [%.0f, %.0f]",
                      PROTO_H_SHM_SEGMENT, key, lo, hi);
  *out = x;
  return 0;
}

static int parse_nonce(const cJSON *d, unsigned char *out, proto_err *err) {
  const cJSON *v = cJSON_GetObjectItemCaseSensitive(d, "nonce");
  const char *s = cJSON_IsString(v) ? v->valuestring : "";
  if (strlen(s) != 2 * SHM_NONCE_BYTES)
    return proto_fail(err, "%s.nonce: expected %d hex digits", PROTO_H_SHM_SEGMENT,
                      2 * SHM_NONCE_BYTES);
  for (int i = 0; i < SHM_NONCE_BYTES; i++) {
    unsigned v8 = 0;
    for (int k = 0; k < 2; k++) {
      char c = s[2 * i + k];
      int d4 = c >= '0' && c <= '9' ? c - '0' : c >= 'a' && c <= 'f' ? c - 'a' + 10 : -1;
      if (d4 < 0)
        return proto_fail(err, "%s.nonce: expected lower-case hex digits",
                          PROTO_H_SHM_SEGMENT);
      v8 = 16 * v8 + (unsigned)d4;
    }
    out[i] = (unsigned char)v8;
  }
  return 0;
}

int proto_shm_attach(proto_shm *rd, const cJSON *d, proto_err *err) {
  if (!rd || rd->writer) return proto_fail(err, "shared memory: not a reader");
  if (!cJSON_IsObject(d))
    return proto_fail(err, "%s: expected an object {pid, fd, bytes, buffer_bytes, nonce}",
                      PROTO_H_SHM_SEGMENT);
  double pid, fdn, bytes, bb;
  seg s = {0};
  s.fd = -1;
  if (desc_int(d, "pid", 1, SHM_MAX_PID, &pid, err) < 0 ||
      desc_int(d, "fd", 0, SHM_MAX_FD, &fdn, err) < 0 ||
      desc_int(d, "buffer_bytes", (double)SHM_PAGE, (double)PROTO_SHM_MAX_BUFFER_BYTES, &bb,
                err) < 0 ||
      desc_int(d, "bytes", (double)(SHM_HEAD_BYTES + 2 * SHM_PAGE),
               (double)(SHM_HEAD_BYTES + 2 * PROTO_SHM_MAX_BUFFER_BYTES), &bytes, err) < 0 ||
      parse_nonce(d, s.nonce, err) < 0)
    return -1;
  if ((size_t)bb % SHM_PAGE != 0 || bytes != (double)SHM_HEAD_BYTES + 2 * bb)
    return proto_fail(err, "%s: bytes %.0f is not a header page and two buffers of %.0f "
                      "bytes (a multiple of %zu)", PROTO_H_SHM_SEGMENT, bytes, bb, SHM_PAGE);
  s.bytes = (size_t)bytes;
  s.buffer_bytes = (size_t)bb;
  char path[64];
  snprintf(path, sizeof path, "/proc/%d/fd/%d", (int)pid, (int)fdn);
  int fd = open(path, O_RDONLY | O_CLOEXEC | O_NONBLOCK); /* never wait on a FIFO */
  if (fd < 0)
    return proto_fail(err, "cannot open the peer's segment %s: %s (another host, another "
                      "pid namespace, or no access)", path, strerror(errno));
  struct stat st;
  const char *bad = NULL;
  int seals = fcntl(fd, F_GET_SEALS);
  if (fstat(fd, &st) < 0 || !S_ISREG(st.st_mode)) bad = "not a memory file";
  else if ((size_t)st.st_size != s.bytes) bad = "its size differs from the descriptor's";
  else if (seals < 0 || !(seals & F_SEAL_SHRINK) || !(seals & F_SEAL_GROW))
    bad = "not sealed against resizing";
  void *p = bad ? MAP_FAILED : mmap(NULL, s.bytes, PROT_READ, MAP_SHARED, fd, 0);
  int e = errno;
  close(fd);
  if (p == MAP_FAILED)
    return proto_fail(err, "the peer's segment %s: %s", path, bad ? bad : strerror(e));
  s.base = p;
  const seg_head *h = head_of(&s);
  if (h->magic != SHM_MAGIC || h->version != SHM_VERSION || h->head_bytes != SHM_HEAD_BYTES ||
      h->buffer_bytes != s.buffer_bytes || h->writer_pid != (uint64_t)pid ||
      memcmp(h->nonce, s.nonce, sizeof s.nonce) != 0) {
    munmap(p, s.bytes);
    return proto_fail(err, "the peer's segment %s is not the one its descriptor names "
                      "(magic, version, sizes, pid or nonce differ)", path);
  }
  seg_drop(&rd->prev);
  rd->prev = rd->cur;
  rd->cur = s;
  rd->rung = atomic_load_explicit(&head_of(&rd->cur)->bell, memory_order_acquire);
  return 0;
}

int proto_shm_host(char *name, size_t name_cap, char *boot_id, size_t boot_cap) {
  if (gethostname(name, name_cap) != 0) return -1;
  name[name_cap - 1] = 0;
  FILE *f = fopen("/proc/sys/kernel/random/boot_id", "r");
  if (!f) return -1;
  char *got = fgets(boot_id, (int)boot_cap, f);
  fclose(f);
  if (!got) return -1;
  boot_id[strcspn(boot_id, "\r\n")] = 0;
  return boot_id[0] ? 0 : -1;
}

/* ------------------------------------------------------------------ send */

void *proto_shm_next(proto_shm *w, size_t nbytes) {
  if (!w || !w->writer || nbytes > w->cur.buffer_bytes) return NULL;
  return buffer_of(&w->cur, (int)((w->seq + 1) & 1));
}

static int eligible(const proto_array *a) { return a->nbytes >= PROTO_SHM_MIN_BYTES; }

/* Offsets for the arrays of m in a buffer of bb bytes at buf: those already
 * inside it keep their place, whatever their size (a small one written there
 * by proto_peer_reply_buffer is placed too: left as a frame, the post would lay
 * its frames from the buffer's start over it before copying it), the rest of
 * the eligible ones follow them. Returns the bytes needed; arrays that do not
 * fit get -1 when `fit` (else all are placed). */
static size_t layout(const proto_msg *m, const unsigned char *buf, size_t bb, int fit,
                     const uint8_t *keep, int64_t *off) {
  size_t end = 0;
  for (int i = 0; i < m->narrays; i++) {
    const proto_array *a = &m->arrays[i];
    off[i] = -1;
    const unsigned char *d = a->data;
    if (!a->nbytes || !buf || d < buf || d >= buf + bb) continue;
    size_t o = (size_t)(d - buf);
    if (o % 8 == 0 && a->nbytes <= bb - o) {
      off[i] = (int64_t)o;
      if (o + a->nbytes > end) end = o + a->nbytes;
    }
  }
  for (int i = 0; i < m->narrays; i++) { /* keep: placed in the old buffer, which goes */
    const proto_array *a = &m->arrays[i];
    if (!(eligible(a) || (keep && keep[i])) || off[i] >= 0) continue;
    size_t o = round_up(end, SHM_ALIGN);
    if (fit && (o > bb || a->nbytes > bb - o)) continue;
    off[i] = (int64_t)o;
    end = o + a->nbytes;
  }
  return end;
}

/* Room a posted message takes after its arrays besides its small frames:
 * the frame table, the topic and the header (bytes). A header that does not
 * fit sends that message on the socket instead. */
#define SHM_POST_RESERVE (sizeof(post_table) + (size_t)16384)

/* The bytes a whole message needs after its arrays: its small frames (each
 * rounded to 8) and the reserve. */
static size_t post_extra(const proto_msg *m) {
  size_t n = SHM_POST_RESERVE;
  for (int i = 0; i < m->narrays; i++)
    if (!eligible(&m->arrays[i])) n += round_up(m->arrays[i].nbytes, 8);
  return n;
}

int proto_shm_place_msg(proto_shm *w, const proto_msg *m, proto_shm_place *pl,
                        proto_err *err) {
  (void)err;
  pl->seq = 0;
  pl->announce = 0;
  pl->end = 0;
  for (int i = 0; i < m->narrays; i++) pl->offset[i] = -1;
  int any = 0;
  for (int i = 0; i < m->narrays; i++) any |= eligible(&m->arrays[i]);
  if (!w || !w->writer) return 0;
  w->sent++;
  if (!any && !w->ring) return 0;
  /* a ringing writer numbers every message: each may be posted whole */
  const size_t extra = w->ring ? post_extra(m) : 0;
  const uint64_t seq = w->seq + 1;
  const int b = (int)(seq & 1);
  size_t need = layout(m, buffer_of(&w->cur, b), w->cur.buffer_bytes, 0, NULL, pl->offset);
  seg old = {0};
  old.fd = -1;
  if (need + extra > w->cur.buffer_bytes) {
    /* a larger segment, announced in this message; the old one stays mapped
     * here until the copies below are done (arrays may point into it) */
    uint8_t keep[PROTO_MAX_ARRAYS]; /* in the old buffer: copied out of it, whatever their size */
    for (int i = 0; i < m->narrays; i++) keep[i] = pl->offset[i] >= 0;
    size_t all = layout(m, NULL, 0, 0, keep, pl->offset) + extra;
    size_t want = all + all / 4;
    if (want > PROTO_SHM_MAX_BUFFER_BYTES) want = PROTO_SHM_MAX_BUFFER_BYTES;
    seg fresh;
    proto_err ignore;
    if (seg_make(&fresh, want, &ignore) == 0) {
      old = w->cur;
      w->cur = fresh;
      w->announced = 0;
    }
    need = layout(m, buffer_of(&w->cur, b), w->cur.buffer_bytes, 1, keep, pl->offset);
  }
  unsigned char *buf = buffer_of(&w->cur, b);
  int placed = 0;
  for (int i = 0; i < m->narrays; i++) {
    if (pl->offset[i] < 0) continue;
    const proto_array *a = &m->arrays[i];
    unsigned char *dst = buf + pl->offset[i];
    if (dst != (const unsigned char *)a->data) {
      memcpy(dst, a->data, a->nbytes);
      w->copied += a->nbytes;
    } else {
      w->in_place++;
    }
    placed++;
  }
  seg_drop(&old);
  if (!placed && !w->ring) return 0;
  pl->end = placed ? need : 0;
  /* release: every byte written above is visible to whoever acquires seq */
  atomic_store_explicit(&head_of(&w->cur)->seq[b], seq, memory_order_release);
  w->seq = seq;
  pl->seq = seq;
  pl->announce = !w->announced;
  w->announced = 1;
  return 0;
}

/* -------------------------------------------------------------- doorbell */

void proto_shm_ring(proto_shm *w) {
  if (w && w->writer) w->ring = 1;
}

int proto_shm_rings(const proto_shm *w) { return w && w->writer && w->ring; }

static long futex(_Atomic uint32_t *word, int op, uint32_t val, const struct timespec *ts) {
  return syscall(SYS_futex, (uint32_t *)(void *)word, op, val, ts, NULL, 0);
}

int proto_shm_post(proto_shm *w, const proto_shm_place *pl, const proto_msg *m,
                   const char *header) {
  if (!proto_shm_rings(w) || !pl->seq || pl->announce) return 0;
  const int b = (int)(pl->seq & 1);
  const size_t bb = w->cur.buffer_bytes;
  unsigned char *buf = buffer_of(&w->cur, b);
  const size_t table_at = round_up(pl->end, SHM_ALIGN);
  post_table t = {.nframes = (uint64_t)m->narrays + 2};
  const void *src[PROTO_MAX_ARRAYS + 2] = {m->topic, header};
  t.len[0] = strlen(m->topic);
  t.len[1] = strlen(header);
  for (int i = 0; i < m->narrays; i++) {
    src[i + 2] = m->arrays[i].data;
    t.len[i + 2] = pl->offset[i] >= 0 ? 0 : m->arrays[i].nbytes;
  }
  size_t at = table_at + sizeof t;
  for (uint64_t f = 0; f < t.nframes; f++) {
    at = round_up(at, 8);
    if (at > bb || t.len[f] > bb - at) return 0; /* does not fit: the socket */
    t.off[f] = at;
    at += t.len[f];
  }
  if (table_at > bb || sizeof t > bb - table_at) return 0;
  for (uint64_t f = 0; f < t.nframes; f++)
    if (t.len[f]) memcpy(buf + t.off[f], src[f], t.len[f]);
  memcpy(buf + table_at, &t, sizeof t);
  seg_head *h = head_of(&w->cur);
  h->post_off[b] = table_at;
  atomic_store_explicit(&h->post_seq, pl->seq, memory_order_relaxed);
  /* release: the table, the frames and post_seq before the bell */
  atomic_fetch_add_explicit(&h->bell, 1, memory_order_release);
  futex(&h->bell, FUTEX_WAKE, INT_MAX, NULL);
  w->posted++;
  return 1;
}

int proto_shm_pending(const proto_shm *rd) {
  return rd && !rd->writer && rd->cur.base &&
         atomic_load_explicit(&head_of(&rd->cur)->bell, memory_order_acquire) != rd->rung;
}

int proto_shm_wait(const proto_shm *rd, int timeout_us) {
  if (!rd || rd->writer || !rd->cur.base) return 0;
  if (proto_shm_pending(rd)) return 1;
  if (timeout_us <= 0) return 0;
  struct timespec ts = {timeout_us / 1000000, (long)(timeout_us % 1000000) * 1000};
  /* returns at once when the bell is no longer what we last took */
  futex(&head_of(&rd->cur)->bell, FUTEX_WAIT, rd->rung, &ts);
  return proto_shm_pending(rd);
}

int proto_shm_frames(proto_shm *rd, const void **data, size_t *size, proto_err *err) {
  if (!proto_shm_pending(rd)) return proto_fail(err, "no message posted in the segment");
  seg_head *h = head_of(&rd->cur);
  const uint32_t bell = atomic_load_explicit(&h->bell, memory_order_acquire);
  if (bell != rd->rung + 1u)
    return proto_fail(err, "the sender posted %u messages in its segment since the last "
                      "one read (expected one: lock-step)", bell - rd->rung);
  rd->rung = bell;
  const uint64_t seq = atomic_load_explicit(&h->post_seq, memory_order_relaxed);
  const int b = (int)(seq & 1);
  const size_t bb = rd->cur.buffer_bytes;
  const uint64_t at = h->post_off[b];
  if (seq == 0 || atomic_load_explicit(&h->seq[b], memory_order_acquire) != seq)
    return proto_fail(err, "posted message %llu is not the one its buffer %d holds",
                      (unsigned long long)seq, b);
  post_table t; /* a copy: the writer's memory is not ours to trust twice */
  if (at % 8 != 0 || at > bb || sizeof t > bb - at)
    return proto_fail(err, "posted message %llu: frame table at offset %llu is outside "
                      "the buffer of %zu bytes", (unsigned long long)seq,
                      (unsigned long long)at, bb);
  const unsigned char *buf = buffer_of(&rd->cur, b);
  memcpy(&t, buf + at, sizeof t);
  if (t.nframes < 2 || t.nframes > PROTO_MAX_ARRAYS + 2)
    return proto_fail(err, "posted message %llu: %llu frames (expected 2 to %d)",
                      (unsigned long long)seq, (unsigned long long)t.nframes,
                      PROTO_MAX_ARRAYS + 2);
  for (uint64_t f = 0; f < t.nframes; f++) {
    if (t.off[f] > bb || t.len[f] > bb - t.off[f] || (f >= 2 && t.len[f] && t.off[f] % 8))
      return proto_fail(err, "posted message %llu: frame %llu (%llu bytes at %llu) is "
                        "outside the buffer of %zu bytes or not 8-byte aligned",
                        (unsigned long long)seq, (unsigned long long)f,
                        (unsigned long long)t.len[f], (unsigned long long)t.off[f], bb);
    data[f] = buf + t.off[f];
    size[f] = (size_t)t.len[f];
  }
  return (int)t.nframes;
}

/* --------------------------------------------------------------- receive */

int proto_shm_resolve(proto_shm *rd, proto_array *a, const cJSON *desc, size_t frame_bytes,
                      proto_err *err) {
  if (!proto_shm_attached(rd))
    return proto_fail(err, "array '%s' is in shared memory, but this sender announced no "
                      "segment that was mapped (%s)", a->name, PROTO_H_SHM_SEGMENT);
  const cJSON *s = cJSON_IsArray(desc) && cJSON_GetArraySize(desc) == 2
                       ? cJSON_GetArrayItem(desc, 0) : NULL;
  const cJSON *o = s ? s->next : NULL;
  double seq = cJSON_IsNumber(s) ? s->valuedouble : NAN;
  double off = cJSON_IsNumber(o) ? o->valuedouble : NAN;
  if (!(seq >= 1 && seq <= PROTO_MAX_HEADER_INT) || seq != floor(seq) ||
      !(off >= 0 && off <= PROTO_MAX_HEADER_INT) || off != floor(off))
    return proto_fail(err, "array '%s': %s: expected [message number >= 1, byte offset "
                      ">= 0] (integers)", a->name, PROTO_A_SHM);
  if (frame_bytes != 0)
    return proto_fail(err, "array '%s' is in shared memory, but its frame has %zu bytes "
                      "(expected none)", a->name, frame_bytes);
  const size_t bb = rd->cur.buffer_bytes;
  if ((uint64_t)off % 8 != 0)
    return proto_fail(err, "array '%s': shared-memory offset %.0f is not a multiple of 8",
                      a->name, off);
  if (off > (double)bb || a->nbytes > bb - (size_t)off)
    return proto_fail(err, "array '%s': %zu bytes at offset %.0f exceed the segment's "
                      "buffer of %zu bytes", a->name, a->nbytes, off, bb);
  const int b = (int)((uint64_t)seq & 1);
  /* acquire: pairs with the writer's release store before its send */
  uint64_t have = atomic_load_explicit(&head_of(&rd->cur)->seq[b], memory_order_acquire);
  if (have != (uint64_t)seq)
    return proto_fail(err, "array '%s': shared-memory buffer %d holds message %llu, the "
                      "descriptor names message %.0f (overwritten, or never written)",
                      a->name, b, (unsigned long long)have, seq);
  a->data = buffer_of(&rd->cur, b) + (size_t)off;
  return 0;
}
