/* fem_msh.c — Gmsh MSH 4.1 reader and writer, ASCII and binary.
 *
 * Reads $MeshFormat, $PhysicalNames, $Entities, $Nodes, $Elements (other
 * sections are skipped). Elements carry only their entity tag; the entity's
 * physical tags name the groups. Binary: counts and tags size_t, block
 * headers int, coordinates double, little-endian (checked by the int 1 after
 * the format line).
 *
 * The reader takes any bytes: every count is checked against the bytes left
 * in the file before anything is allocated (a count of items needs at least
 * that many items' bytes), node tags are looked up in a sorted table (no
 * array sized by the file's maxTag), each section may appear once, and every
 * error names the file, the section and the line (ASCII) or byte offset. */
#include "fem_server/fem.h"
#include "fem_server/fem_internal.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum {
  MSH_SECTION_LEN = 64,
  MSH_MAX_PHYS_PER_ENTITY = 8, /* physical tags kept per entity (more are read, ignored) */
  MSH_MAX_GROUPS = 1024,       /* surface groups built from physical tags */
  MSH_MAX_PARAM_DIM = 3        /* parametric coordinates per node: dim <= 3 */
};

typedef struct rd {
  const char *buf, *p, *end;
  int binary;
  const char *path;
  char section[MSH_SECTION_LEN];
  proto_err *err;
  int failed;
} rd;

static int rfail(rd *r, const char *what) {
  if (!r->failed) {
    long line = 1;
    for (const char *q = r->buf; q < r->p && q < r->end; q++) line += *q == '\n';
    if (r->binary)
      proto_fail(r->err, "%s: section $%s: %s (at byte %ld)", r->path, r->section, what,
                 (long)(r->p - r->buf));
    else
      proto_fail(r->err, "%s:%ld: section $%s: %s", r->path, line, r->section, what);
  }
  r->failed = 1;
  return -1;
}

static void skip_ws(rd *r) {
  while (r->p < r->end && (*r->p == ' ' || *r->p == '\n' || *r->p == '\r' || *r->p == '\t')) r->p++;
}

/* The buffer ends with a NUL (slurp), so strtoll/strtod stop there. */
static int64_t ascii_int(rd *r) {
  if (r->failed) return 0;
  skip_ws(r);
  if (r->p >= r->end) return rfail(r, "unexpected end of file"), 0;
  char *e;
  errno = 0;
  long long v = strtoll(r->p, &e, 10);
  if (e == r->p || errno) return rfail(r, "expected an integer"), 0;
  r->p = e;
  return v;
}

static int64_t rd_size(rd *r) {
  if (!r->binary) return ascii_int(r);
  if (r->failed) return 0;
  if (r->end - r->p < 8) return rfail(r, "truncated (size_t)"), 0;
  uint64_t v;
  memcpy(&v, r->p, 8);
  r->p += 8;
  if (v > (uint64_t)INT32_MAX * 16) return rfail(r, "implausible count/tag"), 0;
  return (int64_t)v;
}

static int64_t rd_int(rd *r) {
  if (!r->binary) return ascii_int(r);
  if (r->failed) return 0;
  if (r->end - r->p < 4) return rfail(r, "truncated (int)"), 0;
  int32_t v;
  memcpy(&v, r->p, 4);
  r->p += 4;
  return v;
}

static double rd_dbl(rd *r) {
  if (r->failed) return 0;
  double v;
  if (r->binary) {
    if (r->end - r->p < 8) return rfail(r, "truncated (double)"), 0;
    memcpy(&v, r->p, 8);
    r->p += 8;
  } else {
    skip_ws(r);
    char *e;
    v = strtod(r->p, &e);
    if (e == r->p || e > r->end) return rfail(r, "expected a number"), 0;
    r->p = e;
  }
  if (!isfinite(v)) return rfail(r, "a coordinate is not a finite number"), 0;
  return v;
}

/* A count of items of `fields` numbers each (bytes: their binary size) must
 * fit in what is left of the file: ASCII needs at least a character and a
 * separator per number. Checked before anything is allocated for them. */
static int fits(rd *r, int64_t count, int fields, int bytes, const char *what) {
  if (r->failed) return -1;
  const int64_t left = r->end - r->p, per = r->binary ? bytes : 2 * fields;
  if (count < 0 || (per > 0 && count > left / per)) {
    char msg[160];
    snprintf(msg, sizeof msg, "%s: count %lld does not fit in the %lld bytes left", what,
             (long long)count, (long long)left);
    return rfail(r, msg);
  }
  return 0;
}

/* After a section's data: expect "$End<section>". */
static int expect_end(rd *r) {
  if (r->failed) return -1;
  skip_ws(r);
  char tag[MSH_SECTION_LEN + 8];
  snprintf(tag, sizeof tag, "$End%s", r->section);
  size_t n = strlen(tag);
  if ((size_t)(r->end - r->p) < n || memcmp(r->p, tag, n) != 0)
    return rfail(r, "data does not end where the counts say (missing $End or wrong counts)");
  r->p += n;
  return 0;
}

static int nodes_of_type(int64_t type) {
  switch (type) {
  case 15: return 1;
  case 1: return 2;
  case 8: return 3;
  case 2: return 3;
  case 9: return 6;
  case 4: return 4;
  case 11: return 10;
  default: return -1;
  }
}

typedef struct phys_name { int dim, tag; char name[FEM_NAME_LEN]; } phys_name;
typedef struct entity { int dim, tag, nphys; int phys[MSH_MAX_PHYS_PER_ENTITY]; } entity;
typedef struct tri_rec { int32_t c[3]; int entity; } tri_rec;
typedef struct node_tag { int64_t tag; int32_t index; } node_tag;

typedef struct msh_data {
  phys_name *names; int n_names;
  entity *ents; int n_ents;
  node_tag *tags; int64_t n_tags; /* sorted by tag */
  tri_rec *tris; size_t n_tris;
  int npe;
  size_t n_tets;
  unsigned seen; /* sections read (each may appear once) */
} msh_data;

static int read_physical_names(rd *r, msh_data *d) {
  int64_t n = ascii_int(r); /* always ASCII, also in a binary file */
  if (r->failed) return -1;
  if (n < 0 || n > (r->end - r->p) / 6) /* "0 0 \"\"" at least */
    return rfail(r, "the count of physical names does not fit in the file");
  d->names = calloc((size_t)n + 1, sizeof *d->names);
  if (!d->names) return rfail(r, "out of memory");
  for (int64_t i = 0; i < n && !r->failed; i++) {
    phys_name *q = &d->names[i];
    q->dim = (int)ascii_int(r);
    q->tag = (int)ascii_int(r);
    skip_ws(r);
    if (r->failed) return -1;
    if (r->p >= r->end || *r->p != '"') return rfail(r, "expected a quoted name");
    const char *s = ++r->p;
    while (r->p < r->end && *r->p != '"' && *r->p != '\n') r->p++;
    if (r->p >= r->end || *r->p != '"') return rfail(r, "unterminated name");
    if (r->p - s >= FEM_NAME_LEN || memchr(s, 0, (size_t)(r->p - s)))
      return rfail(r, "physical name longer than 63 bytes or with a NUL byte");
    snprintf(q->name, sizeof q->name, "%.*s", (int)(r->p - s), s);
    r->p++;
    d->n_names++;
  }
  return expect_end(r);
}

static int read_entities(rd *r, msh_data *d) {
  int64_t cnt[4], tot = 0;
  for (int k = 0; k < 4; k++) {
    cnt[k] = rd_size(r);
    /* a point entity has at least a tag, 3 coordinates and a tag count */
    if (fits(r, cnt[k], 5, 4 + 3 * 8 + 8, "entities") < 0) return -1;
    tot += cnt[k];
  }
  if (fits(r, tot, 5, 4 + 3 * 8 + 8, "entities") < 0) return -1;
  d->ents = calloc((size_t)tot + 1, sizeof *d->ents);
  if (!d->ents) return rfail(r, "out of memory");
  for (int dim = 0; dim < 4; dim++)
    for (int64_t i = 0; i < cnt[dim] && !r->failed; i++) {
      entity *en = &d->ents[d->n_ents++];
      en->dim = dim;
      en->tag = (int)rd_int(r);
      for (int k = 0; k < (dim == 0 ? 3 : 6); k++) rd_dbl(r);
      int64_t np = rd_size(r);
      if (fits(r, np, 1, 4, "physical tags of an entity") < 0) return -1;
      for (int64_t k = 0; k < np && !r->failed; k++) {
        int t = (int)rd_int(r);
        if (k < MSH_MAX_PHYS_PER_ENTITY) en->phys[en->nphys++] = t;
      }
      if (dim > 0) {
        int64_t nb = rd_size(r);
        if (fits(r, nb, 1, 4, "bounding entities") < 0) return -1;
        for (int64_t k = 0; k < nb && !r->failed; k++) rd_int(r);
      }
    }
  return expect_end(r);
}

static int tag_cmp(const void *a, const void *b) {
  const node_tag *x = a, *y = b;
  return (x->tag > y->tag) - (x->tag < y->tag);
}

static int read_nodes(rd *r, msh_data *d, fem_mesh *m) {
  int64_t nblocks = rd_size(r), nnodes = rd_size(r);
  rd_size(r); /* minNodeTag, maxNodeTag: the tags themselves are checked */
  rd_size(r);
  if (r->failed) return -1;
  if (nnodes <= 0 || nnodes > INT32_MAX / 3) return rfail(r, "bad node count");
  /* a node: its tag and 3 coordinates; a block: 3 ints and a count */
  if (fits(r, nnodes, 4, 8 + 3 * 8, "nodes") < 0 || fits(r, nblocks, 4, 3 * 4 + 8, "node blocks") < 0)
    return -1;
  m->x = malloc(sizeof *m->x * 3 * (size_t)nnodes);
  d->tags = malloc(sizeof *d->tags * (size_t)nnodes);
  if (!m->x || !d->tags) return rfail(r, "out of memory");
  int64_t k = 0;
  for (int64_t b = 0; b < nblocks && !r->failed; b++) {
    int64_t dim = rd_int(r);
    rd_int(r);
    int64_t param = rd_int(r);
    int64_t nb = rd_size(r);
    if (r->failed) return -1;
    if (param && (dim < 0 || dim > MSH_MAX_PARAM_DIM))
      return rfail(r, "parametric node block of entity dimension outside 0..3");
    if (nb < 0 || nb > nnodes - k) return rfail(r, "node block larger than the node count");
    for (int64_t i = 0; i < nb && !r->failed; i++) {
      int64_t tag = rd_size(r);
      if (!r->failed && tag < 1) return rfail(r, "node tag < 1");
      d->tags[k + i] = (node_tag){tag, (int32_t)(k + i)};
    }
    for (int64_t i = 0; i < nb && !r->failed; i++) {
      for (int c = 0; c < 3; c++) m->x[3 * (k + i) + c] = rd_dbl(r);
      for (int64_t c = 0; param && c < dim; c++) rd_dbl(r);
    }
    k += nb;
  }
  if (r->failed) return -1;
  if (k != nnodes) return rfail(r, "fewer nodes than the header says");
  qsort(d->tags, (size_t)nnodes, sizeof *d->tags, tag_cmp);
  for (int64_t i = 1; i < nnodes; i++)
    if (d->tags[i].tag == d->tags[i - 1].tag) {
      char msg[64];
      snprintf(msg, sizeof msg, "duplicate node tag %lld", (long long)d->tags[i].tag);
      return rfail(r, msg);
    }
  d->n_tags = nnodes;
  m->n_nodes = (int32_t)nnodes;
  return expect_end(r);
}

static int node_index(rd *r, const msh_data *d, int64_t tag, int32_t *out) {
  const node_tag key = {tag, 0};
  const node_tag *hit = bsearch(&key, d->tags, (size_t)d->n_tags, sizeof key, tag_cmp);
  if (!hit) {
    char msg[80];
    snprintf(msg, sizeof msg, "element refers to unknown node tag %lld", (long long)tag);
    return rfail(r, msg);
  }
  *out = hit->index;
  return 0;
}

/* Grows *p (elements of size sz) to hold at least n; doubles. */
static int grow(rd *r, void **p, size_t *cap, size_t n, size_t sz) {
  if (n <= *cap) return 0;
  size_t want = 2 * n;
  void *q = realloc(*p, want * sz);
  if (!q) return rfail(r, "out of memory");
  *p = q;
  *cap = want;
  return 0;
}

static int read_elements(rd *r, msh_data *d, fem_mesh *m) {
  if (!d->tags) return rfail(r, "$Elements before $Nodes");
  int64_t nblocks = rd_size(r), nelem = rd_size(r);
  rd_size(r);
  rd_size(r);
  if (r->failed) return -1;
  if (fits(r, nblocks, 4, 3 * 4 + 8, "element blocks") < 0 ||
      fits(r, nelem, 2, 2 * 8, "elements") < 0)
    return -1;
  size_t cap_tet = 0, cap_tri = 0;
  int64_t total = 0;
  for (int64_t b = 0; b < nblocks && !r->failed; b++) {
    int64_t dim = rd_int(r), etag = rd_int(r), type = rd_int(r);
    int64_t nb = rd_size(r);
    if (r->failed) break;
    int nn = nodes_of_type(type);
    if (nn < 0 || (dim == 3 && type != 4 && type != 11) || (dim == 2 && type != 2 && type != 9)) {
      char msg[200];
      snprintf(msg, sizeof msg, "unsupported element type %lld in entity (dim %lld, tag %lld): "
               "supported are tet4 (4), tet10 (11), tri3 (2), tri6 (9), points and lines",
               (long long)type, (long long)dim, (long long)etag);
      return rfail(r, msg);
    }
    if (nb < 0 || nb > nelem - total) return rfail(r, "element blocks hold more elements than the header says");
    if (fits(r, nb, 1 + nn, 8 * (1 + nn), "elements of a block") < 0) return -1;
    total += nb;
    int ent = -1;
    for (int q = 0; q < d->n_ents; q++)
      if (d->ents[q].dim == dim && d->ents[q].tag == etag) ent = q;
    if (dim == 3) {
      int npe = type == 4 ? 4 : 10;
      if (d->npe && d->npe != npe) return rfail(r, "mixed tet4 and tet10 volume elements");
      d->npe = npe;
      if (d->n_tets + (size_t)nb > (size_t)FEM_MAX_ELEMS) return rfail(r, "more elements than a mesh may have");
      if (grow(r, (void **)&m->conn, &cap_tet, d->n_tets + (size_t)nb, sizeof(int32_t) * (size_t)npe))
        return -1;
    }
    if (dim == 2 && grow(r, (void **)&d->tris, &cap_tri, d->n_tris + (size_t)nb, sizeof *d->tris))
      return -1;
    for (int64_t i = 0; i < nb && !r->failed; i++) {
      rd_size(r); /* element tag */
      int32_t idx[10];
      for (int a = 0; a < nn && !r->failed; a++) {
        int64_t t = rd_size(r);
        if (!r->failed && dim >= 2 && node_index(r, d, t, &idx[a])) return -1;
      }
      if (r->failed) break;
      if (dim == 3) {
        memcpy(m->conn + d->n_tets * d->npe, idx, sizeof(int32_t) * d->npe);
        d->n_tets++;
      } else if (dim == 2) {
        tri_rec *t = &d->tris[d->n_tris++];
        memcpy(t->c, idx, sizeof t->c);
        t->entity = ent;
      }
    }
  }
  m->n_elems = (int32_t)d->n_tets;
  m->nodes_per_elem = d->npe;
  return expect_end(r);
}

static const char *phys_name_of(const msh_data *d, int tag, char *buf, size_t cap) {
  for (int i = 0; i < d->n_names; i++)
    if (d->names[i].dim == 2 && d->names[i].tag == tag) return d->names[i].name;
  snprintf(buf, cap, "physical_%d", tag);
  return buf;
}

static int build_groups(rd *r, msh_data *d, fem_mesh *m) {
  fem_face_index *ix = fem_face_index_build(m, r->err);
  if (!ix) return -1;
  int rc = 0;
  for (size_t t = 0; t < d->n_tris && rc == 0; t++) {
    const entity *en = d->tris[t].entity >= 0 ? &d->ents[d->tris[t].entity] : NULL;
    if (!en || en->nphys == 0) continue;
    int32_t e;
    int loc;
    if (fem_face_index_find(ix, d->tris[t].c, &e, &loc)) {
      rc = proto_fail(r->err, "%s: surface triangle (nodes %d %d %d) of physical group %d is not a "
                      "boundary face of the volume mesh", r->path, d->tris[t].c[0] + 1,
                      d->tris[t].c[1] + 1, d->tris[t].c[2] + 1, en->phys[0]);
      break;
    }
    for (int q = 0; q < en->nphys && rc == 0; q++) {
      char buf[32];
      const char *name = phys_name_of(d, en->phys[q], buf, sizeof buf);
      int g = -1;
      for (int k = 0; k < m->n_groups; k++)
        if (strcmp(m->groups[k].name, name) == 0) g = k;
      if (g < 0 && m->n_groups == MSH_MAX_GROUPS)
        rc = proto_fail(r->err, "%s: more than %d physical surface groups", r->path,
                        MSH_MAX_GROUPS);
      else if (g < 0 && (g = fem_mesh_add_group(m, name, r->err)) < 0)
        rc = -1;
      if (rc == 0) rc = fem_mesh_group_add_face(m, g, e, loc, r->err);
    }
  }
  fem_face_index_free(ix);
  return rc;
}

static const char *find_bytes(const char *p, const char *end, const char *s) {
  size_t n = strlen(s);
  for (; p + n <= end; p++)
    if (*p == *s && memcmp(p, s, n) == 0) return p;
  return NULL;
}

/* Whole file, NUL-terminated; at most FEM_MSH_MAX_BYTES. */
static char *slurp(const char *path, size_t *n, proto_err *err) {
  FILE *f = fopen(path, "rb");
  if (!f) {
    proto_fail(err, "%s: cannot open (%s)", path, strerror(errno));
    return NULL;
  }
  long sz = fseek(f, 0, SEEK_END) == 0 ? ftell(f) : -1;
  if (sz > FEM_MSH_MAX_BYTES) {
    fclose(f);
    proto_fail(err, "%s: %ld bytes, more than the %lld a mesh may have", path, sz,
               (long long)FEM_MSH_MAX_BYTES);
    return NULL;
  }
  char *b = sz >= 0 && fseek(f, 0, SEEK_SET) == 0 ? malloc((size_t)sz + 1) : NULL;
  if (!b || fread(b, 1, (size_t)sz, f) != (size_t)sz) {
    free(b);
    fclose(f);
    proto_fail(err, "%s: read error (not a regular file?)", path);
    return NULL;
  }
  fclose(f);
  b[sz] = 0;
  *n = (size_t)sz;
  return b;
}

/* The sections the reader knows, and the bit of each in msh_data.seen. */
static const char *const known_sections[] = {"MeshFormat", "PhysicalNames", "Entities",
                                             "Nodes", "Elements", NULL};

static int read_format(rd *r) {
  double ver = rd_dbl(r);
  int64_t ft = ascii_int(r), ds = ascii_int(r);
  if (r->failed) return -1;
  if (ver < 4.1 || ver >= 5)
    return rfail(r, "only MSH version 4.1 is supported (use Mesh.MshFileVersion = 4.1)");
  if (ds != 8) return rfail(r, "data size must be 8");
  if (ft != 0 && ft != 1) return rfail(r, "file type must be 0 (ASCII) or 1 (binary)");
  r->binary = ft == 1;
  if (r->binary) {
    if (r->p < r->end && *r->p == '\n') r->p++;
    if (rd_int(r) != 1) return r->failed ? -1 : rfail(r, "binary file of other endianness");
  }
  return expect_end(r);
}

int fem_msh_read(const char *path, fem_mesh *m, proto_err *err) {
  memset(m, 0, sizeof *m);
  size_t n;
  char *buf = slurp(path, &n, err);
  if (!buf) return -1;
  rd r = {.buf = buf, .p = buf, .end = buf + n, .path = path, .section = "MeshFormat",
          .err = err};
  msh_data d;
  memset(&d, 0, sizeof d);
  int rc = 0;
  while (rc == 0) {
    skip_ws(&r);
    if (r.p >= r.end) break;
    if (*r.p != '$') {
      rc = rfail(&r, "expected a section header ($Name)");
      break;
    }
    int len = 0;
    const char *s = ++r.p;
    while (r.p < r.end && *r.p != '\n' && *r.p != '\r' && len < MSH_SECTION_LEN - 1) len++, r.p++;
    snprintf(r.section, sizeof r.section, "%.*s", len, s);
    int which = -1;
    for (int k = 0; known_sections[k]; k++)
      if (strcmp(r.section, known_sections[k]) == 0) which = k;
    if (which >= 0 && (d.seen & (1u << which))) {
      rc = rfail(&r, "the section appears twice");
      break;
    }
    if (which >= 0) d.seen |= 1u << which;
    if (which > 0 && r.binary && r.p < r.end && *r.p == '\n') r.p++;
    if (which == 0) rc = read_format(&r);
    else if (!(d.seen & 1u)) rc = rfail(&r, "file does not start with $MeshFormat (not a Gmsh mesh?)");
    else if (which == 1) rc = read_physical_names(&r, &d);
    else if (which == 2) rc = read_entities(&r, &d);
    else if (which == 3) rc = read_nodes(&r, &d, m);
    else if (which == 4) rc = read_elements(&r, &d, m);
    else { /* skip unknown section */
      char tag[MSH_SECTION_LEN + 8];
      snprintf(tag, sizeof tag, "\n$End%s", r.section);
      const char *q = find_bytes(r.p, r.end, tag);
      if (!q) rc = rfail(&r, "unterminated section");
      else r.p = q + strlen(tag);
    }
  }
  if (rc == 0 && !(d.seen & 1u)) rc = proto_fail(err, "%s: empty or not a Gmsh mesh", path);
  if (rc == 0 && m->n_elems == 0)
    rc = proto_fail(err, "%s: no volume elements (tet4/tet10) found", path);
  if (rc == 0) rc = fem_mesh_check(m, err);
  if (rc == 0) rc = build_groups(&r, &d, m);
  if (rc) fem_mesh_free(m);
  free(d.names);
  free(d.ents);
  free(d.tags);
  free(d.tris);
  free(buf);
  if (rc && err && strncmp(err->msg, path, strlen(path)) != 0) proto_wrap(err, "%s", path);
  return rc;
}

/* ---------------------------------------------------------------- writer */

typedef struct wr { FILE *f; int binary; } wr;

static void w_size(wr *w, int64_t v) {
  if (w->binary) { uint64_t u = (uint64_t)v; fwrite(&u, 8, 1, w->f); }
  else fprintf(w->f, "%lld ", (long long)v);
}
static void w_int(wr *w, int v) {
  if (w->binary) { int32_t i = v; fwrite(&i, 4, 1, w->f); }
  else fprintf(w->f, "%d ", v);
}
static void w_dbl(wr *w, double v) {
  if (w->binary) fwrite(&v, 8, 1, w->f);
  else fprintf(w->f, "%.17g ", v);
}
static void w_nl(wr *w) { if (!w->binary) fputc('\n', w->f); }

int fem_msh_write(const char *path, const fem_mesh *m, int binary, proto_err *err) {
  FILE *f = fopen(path, "wb");
  if (!f) return proto_fail(err, "%s: cannot create (%s)", path, strerror(errno));
  wr w = {f, binary};
  fprintf(f, "$MeshFormat\n4.1 %d 8\n", binary ? 1 : 0);
  if (binary) { int32_t one = 1; fwrite(&one, 4, 1, f); fputc('\n', f); }
  fprintf(f, "$EndMeshFormat\n$PhysicalNames\n%d\n3 1 \"volume\"\n", m->n_groups + 1);
  for (int g = 0; g < m->n_groups; g++) fprintf(f, "2 %d \"%s\"\n", g + 2, m->groups[g].name);
  fprintf(f, "$EndPhysicalNames\n$Entities\n");
  w_size(&w, 0); w_size(&w, 0); w_size(&w, m->n_groups); w_size(&w, 1); w_nl(&w);
  for (int g = 0; g <= m->n_groups; g++) { /* surfaces 1..G, then volume 1 */
    w_int(&w, g < m->n_groups ? g + 1 : 1);
    for (int k = 0; k < 6; k++) w_dbl(&w, 0);
    w_size(&w, 1);
    w_int(&w, g < m->n_groups ? g + 2 : 1);
    w_size(&w, 0);
    w_nl(&w);
  }
  if (binary) fputc('\n', f);
  fprintf(f, "$EndEntities\n$Nodes\n");
  w_size(&w, 1); w_size(&w, m->n_nodes); w_size(&w, 1); w_size(&w, m->n_nodes); w_nl(&w);
  w_int(&w, 3); w_int(&w, 1); w_int(&w, 0); w_size(&w, m->n_nodes); w_nl(&w);
  for (int32_t i = 0; i < m->n_nodes; i++) { w_size(&w, i + 1); w_nl(&w); }
  for (int32_t i = 0; i < m->n_nodes; i++) {
    for (int d = 0; d < 3; d++) w_dbl(&w, m->x[3 * (size_t)i + d]);
    w_nl(&w);
  }
  if (binary) fputc('\n', f);
  fprintf(f, "$EndNodes\n$Elements\n");
  int64_t n_faces = 0;
  for (int g = 0; g < m->n_groups; g++) n_faces += m->groups[g].n_faces;
  int64_t total = n_faces + m->n_elems, tag = 1;
  w_size(&w, m->n_groups + 1); w_size(&w, total); w_size(&w, 1); w_size(&w, total); w_nl(&w);
  const int tri6 = m->nodes_per_elem == 10, nf = tri6 ? 6 : 3;
  for (int g = 0; g < m->n_groups; g++) {
    w_int(&w, 2); w_int(&w, g + 1); w_int(&w, tri6 ? 9 : 2); w_size(&w, m->groups[g].n_faces); w_nl(&w);
    for (int32_t i = 0; i < m->groups[g].n_faces; i++) {
      int32_t fn[6];
      fem_face_nodes(m, m->groups[g].face_elem[i], m->groups[g].face_local[i], fn);
      w_size(&w, tag++);
      for (int a = 0; a < nf; a++) w_size(&w, fn[a] + 1);
      w_nl(&w);
    }
  }
  w_int(&w, 3); w_int(&w, 1); w_int(&w, tri6 ? 11 : 4); w_size(&w, m->n_elems); w_nl(&w);
  for (int32_t e = 0; e < m->n_elems; e++) {
    w_size(&w, tag++);
    for (int a = 0; a < m->nodes_per_elem; a++) w_size(&w, m->conn[(size_t)e * m->nodes_per_elem + a] + 1);
    w_nl(&w);
  }
  if (binary) fputc('\n', f);
  fprintf(f, "$EndElements\n");
  int bad = ferror(f);
  if (fclose(f) || bad) return proto_fail(err, "%s: write error", path);
  return 0;
}
