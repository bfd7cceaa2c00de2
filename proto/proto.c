/* proto.c — the multipart message format (PROTOCOL.md, "Framing"); errors,
 * names and the clock are in error.c, duplicate-key checks in config.c, the
 * shared-memory placement of large arrays (descriptors instead of frames)
 * in shm.c. */
#include "proto.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <zmq.h>

/* ---------------------------------------------------------------- messages */

static const char *const dtype_names[] = {"f8", "i4", "i8", "u1"};
static const size_t dtype_sizes[] = {8, 4, 8, 1};

size_t proto_dtype_size(proto_dtype d) {
  return (unsigned)d <= PROTO_U1 ? dtype_sizes[d] : 0;
}

const char *proto_dtype_name(proto_dtype d) {
  return (unsigned)d <= PROTO_U1 ? dtype_names[d] : "?";
}

/* Received frames, owned by the message; arrays point into them (or into
 * `aligned` copies when a frame's data was not 8-byte aligned). Kept across
 * receives so that a message reused in a loop allocates nothing. */
struct proto_msg_frames {
  int n;
  zmq_msg_t frame[PROTO_MAX_ARRAYS + 2];
  void *aligned[PROTO_MAX_ARRAYS];
  size_t aligned_cap[PROTO_MAX_ARRAYS];
};

static void frames_close(struct proto_msg_frames *f) {
  if (!f) return;
  for (int i = 0; i < f->n; i++) zmq_msg_close(&f->frame[i]);
  f->n = 0;
}

static void frames_free(struct proto_msg_frames *f) {
  if (!f) return;
  frames_close(f);
  for (int i = 0; i < PROTO_MAX_ARRAYS; i++) free(f->aligned[i]);
  free(f);
}

void proto_msg_free(proto_msg *m) {
  cJSON_Delete(m->header);
  m->header = NULL;
  frames_free(m->frames_);
  m->frames_ = NULL;
  m->narrays = 0;
}

void proto_msg_reset(proto_msg *m, const char *topic, const char *type,
                     int64_t step, double t) {
  /* A zero-initialised proto_msg is valid; a reused one releases its
   * frames and header but keeps its buffers. */
  struct proto_msg_frames *keep = m->frames_;
  frames_close(keep);
  cJSON_Delete(m->header);
  m->header = NULL;
  m->narrays = 0;
  snprintf(m->topic, sizeof m->topic, "%s", topic ? topic : "");
  snprintf(m->type, sizeof m->type, "%s", type ? type : "");
  m->step = step;
  m->t = t;
  m->frames_ = keep;
}

cJSON *proto_msg_header(proto_msg *m) {
  if (!m->header) m->header = cJSON_CreateObject();
  return m->header;
}

int proto_msg_add(proto_msg *m, const char *name, proto_dtype dtype, int ndim,
                  const int64_t *shape, const void *data) {
  if (m->narrays >= PROTO_MAX_ARRAYS || ndim < 1 || ndim > PROTO_MAX_NDIM ||
      strlen(name) >= PROTO_NAME_LEN || (unsigned)dtype > PROTO_U1)
    return -1;
  /* names go into the JSON header verbatim, and the receiver holds them to
   * the name grammar: refuse here what it would refuse */
  if (proto_name_check(name, PROTO_NAME_DOTTED, "array name", NULL) < 0) return -1;
  proto_array *a = &m->arrays[m->narrays++];
  memset(a, 0, sizeof *a);
  snprintf(a->name, sizeof a->name, "%s", name);
  a->dtype = dtype;
  a->ndim = ndim;
  size_t count = 1;
  for (int i = 0; i < ndim; i++) {
    a->shape[i] = shape[i];
    count *= (size_t)shape[i];
  }
  a->nbytes = count * dtype_sizes[dtype];
  a->data = data;
  return 0;
}

static int add_2d(proto_msg *m, const char *name, proto_dtype dt, int64_t rows,
                  int64_t cols, const void *data) {
  int64_t shape[2] = {rows, cols};
  return proto_msg_add(m, name, dt, cols > 0 ? 2 : 1, shape, data);
}

int proto_msg_add_f8(proto_msg *m, const char *name, int64_t rows, int64_t cols,
                     const double *data) {
  return add_2d(m, name, PROTO_F8, rows, cols, data);
}

int proto_msg_add_i4(proto_msg *m, const char *name, int64_t rows, int64_t cols,
                     const int32_t *data) {
  return add_2d(m, name, PROTO_I4, rows, cols, data);
}

int proto_msg_add_prefixed(proto_msg *m, const char *prefix, const char *name,
                           proto_dtype dtype, int64_t rows, int64_t cols,
                           const void *data) {
  char full[PROTO_NAME_LEN];
  if (snprintf(full, sizeof full, "%s%s", prefix, name) >= (int)sizeof full)
    return -1;
  return add_2d(m, full, dtype, rows, cols, data);
}

const proto_array *proto_msg_find(const proto_msg *m, const char *name) {
  for (int i = 0; i < m->narrays; i++)
    if (strcmp(m->arrays[i].name, name) == 0) return &m->arrays[i];
  return NULL;
}

void proto_shape_str(char *out, size_t cap, int ndim, const int64_t *shape) {
  size_t len = (size_t)snprintf(out, cap, "[");
  for (int i = 0; i < ndim && len < cap; i++) {
    if (shape[i] < 0)
      len += (size_t)snprintf(out + len, cap - len, "%s*", i ? "," : "");
    else
      len += (size_t)snprintf(out + len, cap - len, "%s%lld", i ? "," : "",
                              (long long)shape[i]);
  }
  if (len < cap) snprintf(out + len, cap - len, "]");
}

const proto_array *proto_msg_get(const proto_msg *m, const char *name,
                                 proto_dtype dtype, int ndim,
                                 const int64_t *shape, proto_err *err) {
  const proto_array *a = proto_msg_find(m, name);
  char want[96], got[96];
  proto_shape_str(want, sizeof want, ndim, shape);
  if (!a) {
    proto_fail(err, "message '%s': missing array '%s' (%s %s)", m->type, name,
               dtype_names[dtype], want);
    return NULL;
  }
  proto_shape_str(got, sizeof got, a->ndim, a->shape);
  int ok = a->dtype == dtype && a->ndim == ndim;
  for (int i = 0; ok && i < ndim; i++)
    if (shape[i] >= 0 && a->shape[i] != shape[i]) ok = 0;
  if (!ok) {
    proto_fail(err, "message '%s': array '%s' is %s %s, expected %s %s",
               m->type, name, dtype_names[a->dtype], got, dtype_names[dtype],
               want);
    return NULL;
  }
  return a;
}

const double *proto_msg_get_f8(const proto_msg *m, const char *name,
                               int64_t rows, int64_t cols, proto_err *err) {
  int64_t shape[2] = {rows, cols};
  const proto_array *a =
      proto_msg_get(m, name, PROTO_F8, cols == 0 ? 1 : 2, shape, err);
  return a ? (const double *)a->data : NULL;
}

/* ------------------------------------------------------------------ encode */

/* Appends to a growing buffer; returns -1 when out of memory. */
typedef struct text_buf {
  char *p;
  size_t len, cap;
} text_buf;

static int tb_printf(text_buf *b, const char *fmt, ...)
    __attribute__((format(printf, 2, 3)));
static int tb_printf(text_buf *b, const char *fmt, ...) {
  while (1) {
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(b->p + b->len, b->cap - b->len, fmt, ap);
    va_end(ap);
    if (n < 0) return -1;
    if ((size_t)n < b->cap - b->len) {
      b->len += (size_t)n;
      return 0;
    }
    char *bigger = realloc(b->p, b->cap * 2 + (size_t)n);
    if (!bigger) return -1;
    b->p = bigger;
    b->cap = b->cap * 2 + (size_t)n;
  }
}

/* A string that needs no escaping printed as is, else through cJSON. */
static int tb_string(text_buf *b, const char *str) {
  int plain = str != NULL;
  for (const unsigned char *c = (const unsigned char *)str; plain && *c; c++)
    plain = *c >= 0x20 && *c != '"' && *c != '\\' && *c < 0x7f;
  if (plain) return tb_printf(b, "\"%s\"", str);
  char *q = cJSON_PrintUnformatted(&(cJSON){.type = cJSON_String, .valuestring = (char *)str});
  int rc = q ? tb_printf(b, "%s", q) : -1;
  free(q);
  return rc;
}

/* A header value: numbers (%.17g: the same double back; not finite: null,
 * as cJSON prints them), booleans, null, plain strings and arrays of these
 * printed here, without cJSON's number round trip and allocations (a step
 * header's dt and reach box every step); anything else through cJSON. */
static int tb_value(text_buf *b, const cJSON *e) {
  if (cJSON_IsNumber(e))
    return isfinite(e->valuedouble) ? tb_printf(b, "%.17g", e->valuedouble) : tb_printf(b, "null");
  if (cJSON_IsBool(e)) return tb_printf(b, "%s", cJSON_IsTrue(e) ? "true" : "false");
  if (cJSON_IsNull(e)) return tb_printf(b, "null");
  if (cJSON_IsString(e)) return tb_string(b, e->valuestring);
  if (cJSON_IsArray(e)) {
    int rc = tb_printf(b, "[");
    for (const cJSON *c = e->child; rc == 0 && c; c = c->next) {
      if (c != e->child) rc = tb_printf(b, ",");
      if (rc == 0) rc = tb_value(b, c);
    }
    return rc == 0 ? tb_printf(b, "]") : rc;
  }
  char *q = cJSON_PrintUnformatted(e);
  int rc = q ? tb_printf(b, "%s", q) : -1;
  free(q);
  return rc;
}

/* The header's fixed fields are printed directly (a cJSON round trip per
 * message was most of the cost of a small exchange); extra fields are
 * spliced in from the cJSON object. Array names are checked plain by
 * proto_msg_add, so they need no escaping; the fixed fields take precedence
 * over extras of the same name. */
/* pl (may be NULL): the arrays placed in a shared-memory segment get their
 * descriptor [message number, offset]; a new segment's descriptor goes in
 * the header (proto_shm.h). */
static char *header_json(const proto_msg *m, const proto_shm *w,
                         const proto_shm_place *pl) {
  text_buf b = {malloc(512), 0, 512};
  if (!b.p) return NULL;
  int rc = tb_printf(&b, "{\"v\":%d,\"type\":\"%s\",\"step\":%lld,\"t\":%.17g,"
                     "\"arrays\":[", PROTO_VERSION, m->type, (long long)m->step,
                     m->t);
  for (int i = 0; rc == 0 && i < m->narrays; i++) {
    const proto_array *a = &m->arrays[i];
    rc = tb_printf(&b, "%s{\"name\":\"%s\",\"dtype\":\"%s\",\"shape\":[",
                   i ? "," : "", a->name, dtype_names[a->dtype]);
    for (int d = 0; rc == 0 && d < a->ndim; d++)
      rc = tb_printf(&b, "%s%lld", d ? "," : "", (long long)a->shape[d]);
    if (rc == 0) rc = tb_printf(&b, "]");
    if (rc == 0 && pl && pl->offset[i] >= 0)
      rc = tb_printf(&b, ",\"%s\":[%llu,%lld]", PROTO_A_SHM,
                     (unsigned long long)pl->seq, (long long)pl->offset[i]);
    if (rc == 0) rc = tb_printf(&b, "}");
  }
  if (rc == 0) rc = tb_printf(&b, "]");
  const int announce = pl && pl->announce;
  if (rc == 0 && announce) {
    char *desc = proto_shm_descriptor_json(w);
    rc = desc ? tb_printf(&b, ",\"%s\":%s", PROTO_H_SHM_SEGMENT, desc) : -1;
    free(desc);
  }
  for (const cJSON *e = m->header ? m->header->child : NULL; rc == 0 && e;
       e = e->next) {
    static const char *const fixed[] = {"v", "type", "step", "t", "arrays"};
    int skip = announce && strcmp(e->string, PROTO_H_SHM_SEGMENT) == 0;
    for (int k = 0; k < 5; k++) skip |= strcmp(e->string, fixed[k]) == 0;
    if (skip) continue;
    rc = tb_printf(&b, ",");
    if (rc == 0) rc = tb_string(&b, e->string);
    if (rc == 0) rc = tb_printf(&b, ":");
    if (rc == 0) rc = tb_value(&b, e);
  }
  if (rc == 0) rc = tb_printf(&b, "}");
  if (rc < 0) {
    free(b.p);
    return NULL;
  }
  return b.p;
}

static int send_frame(void *s, const void *data, size_t n, int more, int copy,
                      int flags, proto_err *err) {
  zmq_msg_t f;
  int rc;
  if (copy || n == 0) {
    rc = zmq_msg_init_size(&f, n);
    if (rc == 0 && n) memcpy(zmq_msg_data(&f), data, n);
  } else {
    /* Zero-copy: the lock-step protocol guarantees the buffer outlives the
     * transfer (the peer answers only after it has the whole message). */
    rc = zmq_msg_init_data(&f, (void *)data, n, NULL, NULL);
  }
  if (rc != 0) return proto_fail(err, "zmq_msg_init: %s", zmq_strerror(errno));
  if (zmq_msg_send(&f, s, (more ? ZMQ_SNDMORE : 0) | flags) < 0) {
    int e = errno;
    zmq_msg_close(&f);
    return proto_fail(err, "send failed: %s", zmq_strerror(e));
  }
  return 0;
}

/* The frames of m with its encoded header; arrays placed in a segment (pl)
 * travel as empty frames. */
static int send_frames(void *s, const proto_msg *m, const char *hdr,
                       const proto_shm_place *pl, int flags, int copy, proto_err *err) {
  int rc = send_frame(s, m->topic, strlen(m->topic), 1, 1, flags, err);
  if (rc == 0) rc = send_frame(s, hdr, strlen(hdr), m->narrays > 0, 1, flags, err);
  for (int i = 0; rc == 0 && i < m->narrays; i++) {
    const int in_shm = pl && pl->offset[i] >= 0;
    rc = send_frame(s, m->arrays[i].data, in_shm ? 0 : m->arrays[i].nbytes,
                    i + 1 < m->narrays, copy, flags, err);
  }
  return rc;
}

static int send_msg(void *s, const proto_msg *m, int flags, int copy, proto_err *err) {
  char *hdr = header_json(m, NULL, NULL);
  if (!hdr) return proto_fail(err, "cannot encode header of '%s'", m->type);
  int rc = send_frames(s, m, hdr, NULL, flags, copy, err);
  free(hdr);
  return rc;
}

int proto_send(void *socket, const proto_msg *m, int flags, proto_err *err) {
  return send_msg(socket, m, flags, 0, err);
}

/* w (may be NULL): arrays of PROTO_SHM_MIN_BYTES or more go into its
 * segment and travel as an empty frame plus their descriptor; a ringing
 * writer posts the whole message there instead (shm.c). */
int proto_send_via(void *socket, const char *identity, const proto_msg *m,
                   int flags, proto_shm *w, proto_err *err) {
  proto_shm_place pl;
  if (w && proto_shm_place_msg(w, m, &pl, err) < 0)
    return identity ? proto_wrap(err, "to '%s'", identity) : -1;
  const proto_shm_place *placed = w && pl.seq ? &pl : NULL;
  char *hdr = header_json(m, w, placed);
  if (!hdr) return proto_fail(err, "cannot encode header of '%s'", m->type);
  int rc = 0;
  if (placed && proto_shm_post(w, placed, m, hdr)) {
    free(hdr);
    return 0;
  }
  if (identity) rc = send_frame(socket, identity, strlen(identity), 1, 1, flags, err);
  if (rc == 0) rc = send_frames(socket, m, hdr, placed, flags, 0, err);
  free(hdr);
  if (rc < 0) return identity ? proto_wrap(err, "to '%s'", identity) : -1;
  return 0;
}

int proto_send_to(void *router, const char *identity, const proto_msg *m,
                  proto_err *err) {
  return proto_send_via(router, identity, m, 0, NULL, err);
}

int proto_publish(void *pub, const proto_msg *m) {
  /* Copies: queued bus messages may outlive the caller's buffers. PUB drops
   * at the high-water mark instead of blocking. */
  return send_msg(pub, m, ZMQ_DONTWAIT, 1, NULL);
}

/* ------------------------------------------------------------------ decode */

static int parse_dtype(const char *s) {
  for (int i = 0; i < 4; i++)
    if (strcmp(s, dtype_names[i]) == 0) return i;
  return -1;
}

/* An array's spec; with "shm" its bytes are in rd's segment (shm.c), its
 * frame empty. */
static int decode_array_spec(proto_array *a, const cJSON *spec, int idx,
                             size_t frame_bytes, proto_shm *rd, proto_err *err) {
  if (!cJSON_IsObject(spec))
    return proto_fail(err, "arrays[%d]: expected an object {name, dtype, shape}",
                      idx);
  const cJSON *name = cJSON_GetObjectItemCaseSensitive(spec, "name");
  const cJSON *dtype = cJSON_GetObjectItemCaseSensitive(spec, "dtype");
  const cJSON *shape = cJSON_GetObjectItemCaseSensitive(spec, "shape");
  char what[32];
  snprintf(what, sizeof what, "arrays[%d].name", idx);
  if (!cJSON_IsString(name))
    return proto_fail(err, "%s: expected a string", what);
  if (proto_name_check(name->valuestring, PROTO_NAME_DOTTED, what, err) < 0)
    return -1;
  int dt = cJSON_IsString(dtype) ? parse_dtype(dtype->valuestring) : -1;
  if (dt < 0)
    return proto_fail(err, "arrays[%d].dtype: expected one of f8, i4, i8, u1",
                      idx);
  int ndim = cJSON_IsArray(shape) ? cJSON_GetArraySize(shape) : -1;
  if (ndim < 1 || ndim > PROTO_MAX_NDIM)
    return proto_fail(err, "arrays[%d].shape: expected 1..%d dimensions", idx,
                      PROTO_MAX_NDIM);
  memset(a, 0, sizeof *a);
  snprintf(a->name, sizeof a->name, "%s", name->valuestring);
  a->dtype = (proto_dtype)dt;
  a->ndim = ndim;
  /* each dim <= 1e12 and the byte count compared in double (exact to 2^53,
   * and the product of three dims <= 1e36 cannot overflow it) before any
   * conversion to an integer type */
  double count = 1;
  for (int d = 0; d < ndim; d++) {
    const cJSON *e = cJSON_GetArrayItem(shape, d);
    if (!cJSON_IsNumber(e) || !(e->valuedouble >= 0 && e->valuedouble <= 1e12) ||
        e->valuedouble != floor(e->valuedouble))
      return proto_fail(err, "arrays[%d].shape[%d]: expected a count in [0, 1e12]",
                        idx, d);
    a->shape[d] = (int64_t)e->valuedouble;
    count *= e->valuedouble;
  }
  double bytes = count * (double)dtype_sizes[dt];
  if (bytes > (double)PROTO_MAX_FRAME_BYTES)
    return proto_fail(err, "array '%s': %.0f bytes exceeds the limit of %zu",
                      a->name, bytes, PROTO_MAX_FRAME_BYTES);
  a->nbytes = (size_t)bytes;
  const cJSON *shm = cJSON_GetObjectItemCaseSensitive(spec, PROTO_A_SHM);
  if (shm) return proto_shm_resolve(rd, a, shm, frame_bytes, err);
  if (a->nbytes != frame_bytes)
    return proto_fail(err,
                      "array '%s' (%s, shape product %.0f) needs %zu bytes, "
                      "frame has %zu",
                      a->name, dtype_names[dt], count, a->nbytes, frame_bytes);
  return 0;
}

/* An optional number field of the header: absent -> def; it must be finite
 * and, if integral, an integer within +-PROTO_MAX_HEADER_INT. */
static int header_number(const cJSON *h, const char *key, int integral,
                         double def, double *out, proto_err *err) {
  const cJSON *v = cJSON_GetObjectItemCaseSensitive(h, key);
  *out = def;
  if (!v) return 0;
  double x = cJSON_IsNumber(v) ? v->valuedouble : NAN;
  if (!isfinite(x))
    return proto_fail(err, "header.%s: expected a finite number", key);
  if (integral && (x != floor(x) || fabs(x) > PROTO_MAX_HEADER_INT))
    return proto_fail(err, "header.%s: expected an integer, got %.17g", key, x);
  *out = x;
  return 0;
}

int proto_header_int(const proto_msg *m, const char *key, int64_t lo,
                     int64_t hi, int64_t def, int64_t *out, proto_err *err) {
  double x;
  if (header_number(m->header, key, 1, (double)def, &x, err) < 0 ||
      x < (double)lo || x > (double)hi)
    return proto_fail(err, "message '%s': header field '%s' must be an integer "
                      "in [%lld, %lld]", m->type, key, (long long)lo,
                      (long long)hi);
  *out = (int64_t)x;
  return 0;
}

/* Parses exactly len bytes as one JSON value (trailing whitespace only). */
static cJSON *parse_exact(const char *text, size_t len) {
  const char *end = NULL;
  cJSON *h = cJSON_ParseWithLengthOpts(text, len, &end, 0);
  if (!h) return NULL;
  for (const char *p = end; p && p < text + len; p++)
    if (*p != ' ' && *p != '\t' && *p != '\n' && *p != '\r') {
      cJSON_Delete(h);
      return NULL;
    }
  return h;
}

static int decode_header(proto_msg *m, const char *text, size_t len,
                         const cJSON **specs, proto_err *err) {
  if (len > PROTO_MAX_HEADER_BYTES)
    return proto_fail(err, "header of %zu bytes exceeds the limit of %zu", len,
                      PROTO_MAX_HEADER_BYTES);
  cJSON *h = parse_exact(text, len);
  if (!h || !cJSON_IsObject(h)) {
    cJSON_Delete(h);
    return proto_fail(err, "header is not a JSON object");
  }
  m->header = h;
  if (proto_json_check_unique(h, "header", err) < 0) return -1;
  const cJSON *v = cJSON_GetObjectItemCaseSensitive(h, "v");
  const cJSON *type = cJSON_GetObjectItemCaseSensitive(h, "type");
  if (!cJSON_IsNumber(v))
    return proto_fail(err, "header.v: expected the protocol version number");
  if (v->valuedouble != PROTO_VERSION)
    return proto_fail(err, "protocol version mismatch: peer speaks v%g, this "
                      "build speaks v%d (the version is the integer %d)",
                      v->valuedouble, PROTO_VERSION, PROTO_VERSION);
  if (!cJSON_IsString(type))
    return proto_fail(err, "header.type: expected a string");
  if (proto_name_check(type->valuestring, PROTO_NAME_PLAIN, "header.type", err) < 0)
    return -1;
  snprintf(m->type, sizeof m->type, "%s", type->valuestring);
  double step, t;
  if (header_number(h, "step", 1, 0, &step, err) < 0 ||
      header_number(h, "t", 0, 0, &t, err) < 0)
    return -1;
  m->step = (int64_t)step;
  m->t = t;
  *specs = cJSON_GetObjectItemCaseSensitive(h, "arrays");
  if (*specs && !cJSON_IsArray(*specs))
    return proto_fail(err, "header.arrays: expected a list");
  return 0;
}

int proto_decode(proto_msg *m, int nframes, const void *const *frames,
                 const size_t *sizes, proto_err *err) {
  return proto_decode_via(m, nframes, frames, sizes, NULL, err);
}

int proto_decode_via(proto_msg *m, int nframes, const void *const *frames,
                     const size_t *sizes, proto_shm *rd, proto_err *err) {
  proto_msg_reset(m, "", "", 0, 0);
  if (nframes < 2) return proto_fail(err, "message has %d frame(s), need at "
                                     "least topic and header", nframes);
  if (sizes[0] >= PROTO_NAME_LEN)
    return proto_fail(err, "topic longer than %d bytes", PROTO_NAME_LEN - 1);
  memcpy(m->topic, frames[0], sizes[0]);
  m->topic[sizes[0]] = 0;
  /* the topic is a sender's name or "<name>.<what>" (or empty); an
   * embedded NUL or a stray character is a defect, not a shorter name */
  if (sizes[0] > 0 && (strlen(m->topic) != sizes[0] ||
                       proto_name_check(m->topic, PROTO_NAME_DOTTED, "topic", err) < 0)) {
    if (strlen(m->topic) != sizes[0]) proto_fail(err, "topic contains a NUL byte");
    m->topic[0] = 0;
    goto fail;
  }
  const cJSON *specs = NULL;
  if (decode_header(m, frames[1], sizes[1], &specs, err) < 0) goto fail;
  /* a new segment of the sender's comes before the arrays that lie in it */
  const cJSON *seg = cJSON_GetObjectItemCaseSensitive(m->header, PROTO_H_SHM_SEGMENT);
  if (seg && rd && proto_shm_attach(rd, seg, err) < 0) goto fail;
  int n = specs ? cJSON_GetArraySize(specs) : 0;
  if (n > PROTO_MAX_ARRAYS) {
    proto_fail(err, "%d arrays, at most %d allowed", n, PROTO_MAX_ARRAYS);
    goto fail;
  }
  if (n != nframes - 2) {
    proto_fail(err, "header lists %d array(s) but %d array frame(s) arrived",
               n, nframes - 2);
    goto fail;
  }
  for (int i = 0; i < n; i++) {
    proto_array *a = &m->arrays[i];
    if (decode_array_spec(a, cJSON_GetArrayItem(specs, i), i, sizes[i + 2], rd,
                          err) < 0)
      goto fail;
    for (int j = 0; j < i; j++)
      if (strcmp(m->arrays[j].name, a->name) == 0) {
        proto_fail(err, "array '%s' appears twice", a->name);
        goto fail;
      }
    if (!a->data) a->data = frames[i + 2]; /* else: in the segment (shm.c) */
    m->narrays = i + 1;
  }
  return 0;
fail:
  proto_wrap(err, "bad '%s' message (topic '%s')",
             m->type[0] ? m->type : "?", m->topic);
  cJSON_Delete(m->header);
  m->header = NULL;
  m->narrays = 0;
  return -1;
}

/* Receives every remaining frame of the current message into f. */
static int recv_frames(void *s, struct proto_msg_frames *f, proto_err *err) {
  int more = 1, too_many = 0;
  while (more) {
    zmq_msg_t tmp, *dst = f->n < PROTO_MAX_ARRAYS + 2 ? &f->frame[f->n] : &tmp;
    zmq_msg_init(dst);
    if (zmq_msg_recv(dst, s, 0) < 0) {
      int e = errno;
      zmq_msg_close(dst);
      return proto_fail(err, "receive failed: %s", zmq_strerror(e));
    }
    more = zmq_msg_more(dst);
    if (dst == &tmp) {
      zmq_msg_close(&tmp);
      too_many = 1;
    } else {
      f->n++;
    }
  }
  if (too_many)
    return proto_fail(err, "message has more than %d frames",
                      PROTO_MAX_ARRAYS + 2);
  return 0;
}

int proto_recv(void *socket, proto_msg *m, char *identity, proto_err *err) {
  return proto_recv_via(socket, m, identity, NULL, NULL, err);
}

int proto_recv_via(void *socket, proto_msg *m, char *identity,
                   proto_shm_lookup reader_of, void *ctx, proto_err *err) {
  proto_msg_reset(m, "", "", 0, 0);
  struct proto_msg_frames *f = m->frames_;
  m->frames_ = NULL;
  if (!f) f = calloc(1, sizeof *f);
  if (!f) return proto_fail(err, "out of memory");
  int rc = recv_frames(socket, f, err);
  int first = 0;
  if (rc == 0 && identity) {
    size_t n = zmq_msg_size(&f->frame[0]);
    if (n >= PROTO_NAME_LEN) n = PROTO_NAME_LEN - 1;
    memcpy(identity, zmq_msg_data(&f->frame[0]), n);
    identity[n] = 0;
    first = 1;
  }
  if (rc == 0) {
    const void *data[PROTO_MAX_ARRAYS + 2];
    size_t size[PROTO_MAX_ARRAYS + 2];
    int nf = f->n - first;
    for (int i = 0; i < nf; i++) {
      zmq_msg_t *fr = &f->frame[i + first];
      data[i] = zmq_msg_data(fr);
      size[i] = zmq_msg_size(fr);
      /* Small frames may sit unaligned inside zmq_msg_t: copy those. */
      if (i >= 2 && ((uintptr_t)data[i] % 8) != 0 && size[i] > 0) {
        if (f->aligned_cap[i - 2] < size[i]) {
          free(f->aligned[i - 2]);
          f->aligned[i - 2] = malloc(size[i]);
          f->aligned_cap[i - 2] = f->aligned[i - 2] ? size[i] : 0;
        }
        if (!f->aligned[i - 2]) {
          rc = proto_fail(err, "out of memory");
          break;
        }
        memcpy(f->aligned[i - 2], data[i], size[i]);
        data[i] = f->aligned[i - 2];
      }
    }
    proto_shm *rd = reader_of ? reader_of(ctx, identity ? identity : "") : NULL;
    if (rc == 0) rc = proto_decode_via(m, nf, data, size, rd, err);
  }
  m->frames_ = f; /* kept even on error: its buffers serve the next receive */
  if (rc < 0) {
    frames_close(f);
    return -1;
  }
  return 0;
}

int proto_shm_take(proto_shm *rd, proto_msg *m, proto_err *err) {
  const void *data[PROTO_MAX_ARRAYS + 2];
  size_t size[PROTO_MAX_ARRAYS + 2];
  int n = proto_shm_frames(rd, data, size, err);
  return n < 0 ? -1 : proto_decode_via(m, n, data, size, rd, err);
}

int proto_recv_found(void *socket, int found, proto_shm *const *rds, proto_msg *m,
                     char *identity, proto_shm_lookup reader_of, void *ctx, proto_err *err) {
  if (found >= 2) return proto_shm_take(rds[found - 2], m, err);
  return proto_recv_via(socket, m, identity, reader_of, ctx, err);
}

int proto_socket_limits(void *socket) {
  int64_t max = (int64_t)(PROTO_MAX_FRAME_BYTES > PROTO_MAX_HEADER_BYTES
                              ? PROTO_MAX_FRAME_BYTES : PROTO_MAX_HEADER_BYTES);
  return zmq_setsockopt(socket, ZMQ_MAXMSGSIZE, &max, sizeof max);
}

int proto_poll_in(void *socket, int timeout_ms) {
  zmq_pollitem_t item = {socket, 0, ZMQ_POLLIN, 0};
  int rc = zmq_poll(&item, 1, timeout_ms);
  if (rc < 0) return -1;
  return rc > 0 ? 1 : 0;
}

double proto_bell_slice(double waited_s) {
  return waited_s < PROTO_BELL_IDLE_S ? PROTO_BELL_SLICE_S : PROTO_BELL_SLICE_IDLE_S;
}

int proto_wait_in(void *socket, proto_shm *const *rds, int n, int timeout_ms, double since) {
  int first = -1;
  for (int i = 0; i < n; i++)
    if (proto_shm_attached(rds[i]) && first < 0) first = i;
  if (first < 0) return proto_poll_in(socket, timeout_ms);
  const double start = proto_now(), until = start + 1e-3 * timeout_ms;
  if (since <= 0 || since > start) since = start;
  while (1) {
    for (int i = 0; i < n; i++)
      if (proto_shm_pending(rds[i])) return 2 + i;
    const double left = until - proto_now();
    /* sleep on the first reader's bell (a futex waits on one word), then
     * look at the socket. The bell comes first: a process that just woke its
     * peer should be asleep before the peer needs the core */
    const double slice = proto_bell_slice(proto_now() - since);
    if (left > 0) proto_shm_wait(rds[first], (int)(1e6 * (left < slice ? left : slice)) + 1);
    for (int i = 0; i < n; i++)
      if (proto_shm_pending(rds[i])) return 2 + i;
    int r = proto_poll_in(socket, 0);
    if (r != 0 || left <= 0) return r;
  }
}
