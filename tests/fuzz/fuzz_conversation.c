/* fuzz_conversation — a participant's side of a conversation as the coupler
 * sees it: messages (separated by "|##|", frames within by "|#|") decoded and
 * checked against the role table with one proto_dims that carries what
 * earlier messages bound (n, m, the surface, the declared series). After a
 * message passes, every array the table lists is read in full at the size
 * the dims say, and every declared series row too: a message the check
 * accepts must really hold what it promises. The first byte picks the role. */
#include "fuzz.h"
#include "proto/proto.h"

#define MSG_SEP "|##|"
#define SEP "|#|"
#define MAX_MSGS 16
#define MAX_FRAMES (PROTO_MAX_ARRAYS + 4)

/* Whether the table gives row t its sparse form ("<name>_index" of the same
 * role and message): only then is an index array of that name checked, and
 * only then does a consumer read one (an extra array of that name beside a
 * dense row is not the row's). */
static int has_index_row(const proto_array_spec *tab, int n, const proto_array_spec *t) {
  char iname[PROTO_NAME_LEN + 8];
  snprintf(iname, sizeof iname, "%s%s", t->name, PROTO_SUFFIX_INDEX);
  for (int i = 0; i < n; i++)
    if (tab[i].role == t->role && tab[i].msg == t->msg && tab[i].when == PROTO_WHEN_INDEX &&
        strcmp(tab[i].name, iname) == 0)
      return 1;
  return 0;
}

static double read_checked(proto_role role, proto_msg_kind kind, const proto_msg *m,
                           const proto_dims *d) {
  int n;
  const proto_array_spec *t = proto_role_table(&n);
  double sum = 0;
  for (int i = 0; i < n; i++) {
    if (t[i].role != role || t[i].msg != kind) continue;
    /* a WHEN_SURFACE row without a surface is not checked (nor read by a
     * participant), even if the message holds an array of that name */
    if (t[i].when == PROTO_WHEN_SURFACE && !d->surface) continue;
    const unsigned char *p = proto_msg_data(m, t[i].name);
    if (!p) continue; /* an optional array (an index) not sent */
    /* the sparse form (PROTOCOL.md "Sparse exchange"): k rows, k indices < n */
    const int32_t *idx;
    const int64_t k_rows = t[i].when == PROTO_WHEN_INDEX || !has_index_row(t, n, &t[i])
                               ? -1 : proto_msg_sparse(m, t[i].name, &idx);
    for (int64_t j = 0; j < k_rows; j++)
      if (idx[j] < 0 || idx[j] >= d->nodes) __builtin_trap(); /* checked, so in range */
    int64_t count = 1;
    for (int k = 0; k < t[i].ndim; k++)
      count *= t[i].dims[k] > 0 ? t[i].dims[k]
               : t[i].dims[k] == PROTO_DIM_ROWS ? proto_msg_find(m, t[i].name)->shape[0]
               : t[i].dims[k] == PROTO_DIM_NODES ? (k_rows >= 0 ? k_rows : d->nodes) : d->tris;
    for (int64_t b = 0; b < count * (int64_t)proto_dtype_size(t[i].dtype); b++) sum += p[b];
  }
  if (kind == PROTO_MSG_DONE)
    for (int s = 0; s < d->n_series; s++) {
      char name[PROTO_NAME_LEN + 8];
      snprintf(name, sizeof name, "%s%s", strcmp(d->series[s], PROTO_A_SERIES) ? PROTO_P_SERIES : "",
               d->series[s]);
      const double *row = proto_msg_data(m, name);
      if (!row) __builtin_trap(); /* checked, so it must be there */
      for (int c = 0; c < d->series_cols[s]; c++) sum += row[c];
    }
  return sum;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  if (size < 1) return 0;
  proto_role role = (proto_role)(data[0] % PROTO_N_ROLES);
  const uint8_t *msg[MAX_MSGS];
  size_t mlen[MAX_MSGS];
  int nm = fuzz_split(data + 1, size - 1, MSG_SEP, MAX_MSGS, msg, mlen);
  proto_dims d;
  proto_dims_init(&d);
  proto_err err = {{0}};
  proto_msg m = {0};
  for (int k = 0; k < nm; k++) {
    void *frame[MAX_FRAMES];
    size_t len[MAX_FRAMES];
    int n = fuzz_frames(msg[k], mlen[k], SEP, MAX_FRAMES, frame, len);
    if (proto_decode(&m, n, (const void *const *)frame, len, &err) == 0) {
      int kind = proto_msg_kind_parse(m.type);
      if (kind >= 0 && proto_role_check(role, (proto_msg_kind)kind, &m, &d, &err) == 0) {
        volatile double s = read_checked(role, (proto_msg_kind)kind, &m, &d);
        (void)s;
      }
    }
    proto_msg_free(&m);
    fuzz_frames_free(frame, n);
  }
  return 0;
}
