/* output.c — HDF5 results file: growing time series, string attributes and
 * snapshot arrays (the "output" section of proto.h).
 *
 * Layout choices:
 *   - a series is a 2-D f8 dataset [rows, ncols], chunked, unlimited rows;
 *     appended rows wait in a one-chunk buffer (allocated at creation, so
 *     appending never allocates) and go to disk when the buffer is full, on
 *     proto_h5_flush() and on proto_h5_close();
 *   - strings (attribute "columns", proto_h5_attr_str) are variable-length
 *     UTF-8, which h5py 3 reads as str (fixed-length ones come back as bytes);
 *   - series handles belong to the file: proto_h5_close() frees them.
 * HDF5's automatic error printing is switched off; every failure returns -1
 * with a message "<file>:<object path>: <what> (HDF5: <innermost reason>)". */
#include "proto.h"
#include "h5members.h"

#include <errno.h>
#include <hdf5.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define H5_PATH_CAP 256   /* object paths inside the file */
#define FILE_PATH_CAP 512 /* the file's own path, for messages */

/* bytes: HDF5's metadata cache of a file (its default maximum is 32 MiB) */
#define METADATA_CACHE_MAX ((size_t)2 << 20)
/* bytes: HDF5's free lists, all of one kind and each (H5set_free_list_limits) */
#define FREE_LIST_GLOBAL (1 << 20)
#define FREE_LIST_EACH (256 << 10)

enum {
  /* HDF5 keeps a little bookkeeping per chunk in memory for as long as the
   * file is open: 256-row chunks grew the coupler by 3.8 MB over 10^6 steps,
   * 4096-row ones by 16x less (bench/results/reliability.md, Soak) */
  SERIES_CHUNK_ROWS = 4096,
  SERIES_CHUNK_BYTES = 1 << 20, /* fewer rows per chunk for very wide series */
  SERIES_MAX_COLS = 1 << 16
};

struct proto_series {
  proto_h5 *file;
  char path[H5_PATH_CAP];
  hid_t dset;
  int ncols;
  int64_t rows_on_disk;
  int nbuf;     /* rows waiting in buf */
  int buf_rows; /* capacity of buf in rows (= chunk rows) */
  double *buf;  /* buf_rows x ncols, row-major */
  proto_series *next;
};

struct proto_h5 {
  hid_t file;
  char path[FILE_PATH_CAP];
  proto_series *series; /* owned; freed by proto_h5_close */
};

/* ------------------------------------------------------------- helpers */

static void h5_close_id(hid_t id) {
  if (id < 0) return;
  switch (H5Iget_type(id)) {
    case H5I_FILE: H5Fclose(id); break;
    case H5I_GROUP: H5Gclose(id); break;
    case H5I_DATASET: H5Dclose(id); break;
    case H5I_ATTR: H5Aclose(id); break;
    case H5I_DATATYPE: H5Tclose(id); break;
    case H5I_DATASPACE: H5Sclose(id); break;
    case H5I_GENPROP_LST: H5Pclose(id); break;
    default: break;
  }
}

/* What the error stack says: its innermost description and, when a system
 * call failed (the sec2 driver writes "errno = 28, ..."), that errno. */
typedef struct h5_reason {
  char desc[200];
  int sys_errno;
} h5_reason;

static herr_t innermost_cb(unsigned n, const H5E_error2_t *e, void *data) {
  (void)n;
  h5_reason *r = data;
  /* Walking downward: the last entry visited is the most specific one. */
  if (!e->desc || !e->desc[0]) return 0;
  const char *eq = strstr(e->desc, "errno = ");
  if (eq) {
    r->sys_errno = atoi(eq + 8);
    snprintf(r->desc, sizeof r->desc, "%s", "file write failed");
  } else {
    snprintf(r->desc, sizeof r->desc, "%s", e->desc);
  }
  return 0;
}

/* Fails with "<file>:<obj>: <what>" plus the innermost HDF5 reason and the
 * system error, if any (obj NULL: the file itself). */
static int h5_fail(proto_err *err, const char *file, const char *obj,
                   const char *what) {
  h5_reason r = {"", 0};
  H5Ewalk2(H5E_DEFAULT, H5E_WALK_DOWNWARD, innermost_cb, &r);
  H5Eclear2(H5E_DEFAULT);
  char sys[96] = "";
  if (r.sys_errno > 0)
    snprintf(sys, sizeof sys, ": %s (errno %d)", strerror(r.sys_errno), r.sys_errno);
  return proto_fail(err, "%s%s%s: %s%s%s%s%s", file, obj ? ":" : "",
                    obj ? obj : "", what, sys, r.desc[0] ? " (HDF5: " : "",
                    r.desc, r.desc[0] ? ")" : "");
}

/* "/a//b/" + "c" -> "/a/b/c"; name may be NULL. Empty result is "/". */
static int join_path(char *out, size_t cap, const char *group,
                     const char *name, const char *file, proto_err *err) {
  size_t n = 0;
  const char *parts[2] = {group ? group : "", name ? name : ""};
  for (int k = 0; k < 2; k++) {
    for (const char *p = parts[k]; *p; p++) {
      if (*p == '/') continue;
      if (p == parts[k] || p[-1] == '/' || (k == 1 && p == parts[1])) {
        if (n + 1 >= cap) goto too_long;
        out[n++] = '/';
      }
      if (n + 1 >= cap) goto too_long;
      out[n++] = *p;
    }
  }
  if (n == 0) out[n++] = '/';
  out[n] = '\0';
  return 0;
too_long:
  return proto_fail(err, "%s:%s/%s: path longer than %zu characters", file,
                    parts[0], parts[1], cap - 1);
}

/* Makes every group on `path` ("/a/b/c"); with parents_only the last element
 * is left alone (it is about to become a dataset). */
static int make_groups(proto_h5 *f, const char *path, int parents_only,
                       proto_err *err) {
  char buf[H5_PATH_CAP];
  if (strcmp(path, "/") == 0) return 0; /* the root always exists */
  snprintf(buf, sizeof buf, "%s", path);
  char *end = buf + strlen(buf);
  for (char *p = buf + 1; p <= end; p++) {
    if (*p != '/' && *p != '\0') continue;
    if (*p == '\0' && parents_only) break;
    char c = *p;
    *p = '\0';
    htri_t exists = H5Lexists(f->file, buf, H5P_DEFAULT);
    if (exists < 0) return h5_fail(err, f->path, buf, "cannot look up group");
    hid_t g = exists ? H5Oopen(f->file, buf, H5P_DEFAULT)
                     : H5Gcreate2(f->file, buf, H5P_DEFAULT, H5P_DEFAULT,
                                  H5P_DEFAULT);
    if (g < 0) return h5_fail(err, f->path, buf, "cannot create group");
    H5I_type_t kind = H5Iget_type(g);
    H5Oclose(g);
    if (kind != H5I_GROUP)
      return proto_fail(err, "%s:%s: exists and is not a group", f->path, buf);
    *p = c;
  }
  return 0;
}

/* Variable-length UTF-8 string type (h5py reads it as str). */
static hid_t vlen_str_type(void) {
  hid_t t = H5Tcopy(H5T_C_S1);
  if (t < 0) return t;
  if (H5Tset_size(t, H5T_VARIABLE) < 0 || H5Tset_cset(t, H5T_CSET_UTF8) < 0) {
    H5Tclose(t);
    return H5I_INVALID_HID;
  }
  return t;
}

/* Writes (replacing) attribute name of type over space from data. */
static int write_attr(proto_h5 *f, hid_t obj, const char *obj_path, const char *name,
                      hid_t type, hid_t space, const void *data, proto_err *err) {
  if (type < 0 || space < 0)
    return h5_fail(err, f->path, obj_path, "cannot make attribute type");
  htri_t exists = H5Aexists(obj, name);
  if (exists > 0 && H5Adelete(obj, name) < 0) exists = -1;
  if (exists < 0) return h5_fail(err, f->path, obj_path, "cannot replace attribute");
  hid_t attr = H5Acreate2(obj, name, type, space, H5P_DEFAULT, H5P_DEFAULT);
  int rc = 0;
  if (attr < 0 || H5Awrite(attr, type, data) < 0) {
    char what[96];
    snprintf(what, sizeof what, "cannot write attribute '%.60s'", name);
    rc = h5_fail(err, f->path, obj_path, what);
  }
  h5_close_id(attr);
  return rc;
}

/* Writes (replacing) a string attribute: n < 0 scalar, else a 1-D array. */
static int write_str_attr(proto_h5 *f, hid_t obj, const char *obj_path,
                          const char *name, int n, const char *const *values,
                          proto_err *err) {
  hsize_t dim = n < 0 ? 0 : (hsize_t)n;
  hid_t type = vlen_str_type();
  hid_t space = n < 0 ? H5Screate(H5S_SCALAR) : H5Screate_simple(1, &dim, NULL);
  int rc = write_attr(f, obj, obj_path, name, type, space, (const void *)values, err);
  h5_close_id(space);
  h5_close_id(type);
  return rc;
}

/* ---------------------------------------------------------------- file */

/* Library errors come back as messages, not as stack dumps on stderr; and
 * HDF5 must not close files from an atexit handler: a file whose close
 * failed (a full disk) is left alone at exit rather than closed again by a
 * handler that crashes on it (HDF5 1.10: SIGSEGV in H5F__close_cb). */
static void h5_setup(void) {
  H5dont_atexit(); /* fails harmlessly once the library is initialised */
  H5Eset_auto2(H5E_DEFAULT, NULL, NULL);
  /* HDF5 keeps freed blocks (evicted chunk-index nodes ...) on free lists of
   * up to 16 MiB each kind, which a long run fills: bound them */
  H5set_free_list_limits(FREE_LIST_GLOBAL, FREE_LIST_EACH, FREE_LIST_GLOBAL, FREE_LIST_EACH,
                         FREE_LIST_GLOBAL, FREE_LIST_EACH);
}

static proto_h5 *h5_file(const char *path, int create, int writable,
                         proto_err *err) {
  h5_setup();
  if (!path || !path[0]) {
    proto_fail(err, "HDF5 output: empty file name");
    return NULL;
  }
  proto_h5 *f = calloc(1, sizeof *f);
  if (!f) {
    proto_fail(err, "%s: out of memory", path);
    return NULL;
  }
  snprintf(f->path, sizeof f->path, "%s", path);
  hid_t fapl = H5Pcreate(H5P_FILE_ACCESS);
#if H5_VERSION_GE(1, 10, 7)
  /* Keep locking, but do not fail on file systems without it (NFS...). */
  if (fapl >= 0) H5Pset_file_locking(fapl, 1, 1);
#endif
  /* A long run adds chunk-index nodes to the metadata cache, which HDF5
   * would let grow to 32 MiB: cap it, so that memory stays flat. */
  H5AC_cache_config_t mdc = {.version = H5AC__CURR_CACHE_CONFIG_VERSION};
  if (fapl >= 0 && H5Pget_mdc_config(fapl, &mdc) >= 0) {
    mdc.max_size = METADATA_CACHE_MAX;
    if (mdc.initial_size > mdc.max_size) mdc.initial_size = mdc.max_size;
    if (mdc.min_size > mdc.max_size) mdc.min_size = mdc.max_size;
    H5Pset_mdc_config(fapl, &mdc);
  }
  hid_t use = fapl >= 0 ? fapl : H5P_DEFAULT;
  f->file = create ? H5Fcreate(path, H5F_ACC_TRUNC, H5P_DEFAULT, use)
                   : H5Fopen(path, writable ? H5F_ACC_RDWR : H5F_ACC_RDONLY, use);
  if (f->file < 0) /* read the reason before H5Pclose clears the stack */
    h5_fail(err, path, NULL, create ? "cannot create HDF5 file"
                                    : "cannot open HDF5 file");
  h5_close_id(fapl);
  if (f->file < 0) {
    free(f);
    return NULL;
  }
  return f;
}

proto_h5 *proto_h5_create(const char *path, proto_err *err) {
  return h5_file(path, 1, 1, err);
}

proto_h5 *proto_h5_open(const char *path, int writable, proto_err *err) {
  return h5_file(path, 0, writable, err);
}

int proto_h5_probe(const char *path) {
  h5_setup();
  FILE *fp = fopen(path, "rb");
  if (!fp) return errno == ENOENT ? 0 : 2;
  fclose(fp);
  htri_t is = H5Fis_hdf5(path);
  H5Eclear2(H5E_DEFAULT);
  return is > 0 ? 1 : 2;
}

/* Writes the buffered rows of one series. */
static int series_write(proto_series *s, proto_err *err) {
  if (s->nbuf == 0) return 0;
  const char *file = s->file->path;
  hsize_t dims[2] = {(hsize_t)(s->rows_on_disk + s->nbuf), (hsize_t)s->ncols};
  hsize_t start[2] = {(hsize_t)s->rows_on_disk, 0};
  hsize_t count[2] = {(hsize_t)s->nbuf, (hsize_t)s->ncols};
  int rc = -1;
  hid_t fspace = H5I_INVALID_HID, mspace = H5I_INVALID_HID;
  if (H5Dset_extent(s->dset, dims) < 0) {
    h5_fail(err, file, s->path, "cannot extend series");
    goto done;
  }
  fspace = H5Dget_space(s->dset);
  mspace = H5Screate_simple(2, count, NULL);
  if (fspace < 0 || mspace < 0 ||
      H5Sselect_hyperslab(fspace, H5S_SELECT_SET, start, NULL, count, NULL) < 0 ||
      H5Dwrite(s->dset, H5T_NATIVE_DOUBLE, mspace, fspace, H5P_DEFAULT,
               s->buf) < 0) {
    h5_fail(err, file, s->path, "cannot write series rows");
    goto done;
  }
  s->rows_on_disk += s->nbuf;
  s->nbuf = 0;
  rc = 0;
done:
  h5_close_id(mspace);
  h5_close_id(fspace);
  return rc;
}

int proto_h5_flush(proto_h5 *f, proto_err *err) {
  if (!f) return proto_fail(err, "proto_h5_flush: no file");
  int rc = 0;
  for (proto_series *s = f->series; s; s = s->next)
    if (series_write(s, err) < 0) rc = -1;
  if (rc == 0 && H5Fflush(f->file, H5F_SCOPE_GLOBAL) < 0)
    rc = h5_fail(err, f->path, NULL, "cannot flush");
  H5Eclear2(H5E_DEFAULT);
  return rc;
}

int proto_h5_close(proto_h5 *f, proto_err *err) {
  if (!f) return 0;
  int rc = proto_h5_flush(f, err);
  proto_series *s = f->series;
  while (s) {
    proto_series *next = s->next;
    H5Dclose(s->dset);
    free(s->buf);
    free(s);
    s = next;
  }
  /* after a failed flush the close fails too: keep the first message */
  if (H5Fclose(f->file) < 0 && rc == 0) rc = h5_fail(err, f->path, NULL, "cannot close");
  H5Eclear2(H5E_DEFAULT);
  free(f);
  return rc;
}

/* Opens the object at group ("/" = root) for its attributes: an existing
 * one (group or dataset) as it is, a missing one made a group. */
static hid_t attr_object(proto_h5 *f, const char *group, const char *name, char *path,
                         proto_err *err) {
  if (!f) {
    proto_fail(err, "HDF5 attribute: no file");
    return H5I_INVALID_HID;
  }
  if (join_path(path, H5_PATH_CAP, group, NULL, f->path, err) < 0) return H5I_INVALID_HID;
  if (!name || !name[0]) {
    proto_fail(err, "%s:%s: attribute needs a name", f->path, path);
    return H5I_INVALID_HID;
  }
  htri_t exists = strcmp(path, "/") == 0 ? 1 : H5Lexists(f->file, path, H5P_DEFAULT);
  if (exists <= 0) {
    H5Eclear2(H5E_DEFAULT); /* a missing parent is fine: we make it */
    if (make_groups(f, path, 0, err) < 0) return H5I_INVALID_HID;
  }
  hid_t obj = H5Oopen(f->file, path, H5P_DEFAULT);
  if (obj < 0) h5_fail(err, f->path, path, "cannot open object");
  return obj;
}

int proto_h5_attr_str(proto_h5 *f, const char *group, const char *name,
                      const char *value, proto_err *err) {
  char path[H5_PATH_CAP];
  if (!value) return proto_fail(err, "%s: attribute '%s' without a value",
                                f ? f->path : "HDF5", name ? name : "");
  hid_t obj = attr_object(f, group, name, path, err);
  if (obj < 0) return -1;
  int rc = write_str_attr(f, obj, path, name, -1, &value, err);
  H5Oclose(obj);
  return rc;
}

/* A scalar number attribute stored as type (memory: the same). */
static int attr_scalar(proto_h5 *f, const char *group, const char *name, hid_t type,
                       const void *v, proto_err *err) {
  char path[H5_PATH_CAP];
  hid_t obj = attr_object(f, group, name, path, err);
  if (obj < 0) return -1;
  hid_t space = H5Screate(H5S_SCALAR);
  int rc = write_attr(f, obj, path, name, type, space, v, err);
  h5_close_id(space);
  H5Oclose(obj);
  return rc;
}

int proto_h5_attr_f8(proto_h5 *f, const char *group, const char *name, double v,
                     proto_err *err) {
  return attr_scalar(f, group, name, H5T_IEEE_F64LE, &v, err);
}

int proto_h5_attr_i8(proto_h5 *f, const char *group, const char *name, int64_t v,
                     proto_err *err) {
  return attr_scalar(f, group, name, H5T_STD_I64LE, &v, err);
}

/* -------------------------------------------------------------- series */

/* Checks a series' path and columns; full gets the normalised path. */
static int series_args(proto_h5 *f, const char *path, int ncols,
                       const char *const *columns, char *full, proto_err *err) {
  if (!f) return proto_fail(err, "proto_h5_series: no file");
  if (join_path(full, H5_PATH_CAP, path, NULL, f->path, err) < 0) return -1;
  if (strcmp(full, "/") == 0)
    return proto_fail(err, "%s:%s: a series needs a dataset path", f->path, full);
  if (ncols < 1 || ncols > SERIES_MAX_COLS || !columns)
    return proto_fail(err, "%s:%s: need 1..%d columns with names, got %d", f->path,
                      full, SERIES_MAX_COLS, ncols);
  for (int c = 0; c < ncols; c++)
    if (!columns[c]) return proto_fail(err, "%s:%s: column %d has no name", f->path, full, c);
  return 0;
}

/* A series is written a whole chunk at a time from its own buffer and never
 * read back: HDF5's chunk cache (1 MiB per dataset) would only hold copies
 * of written chunks. Off. */
static hid_t series_access(void) {
  static hid_t dapl = H5I_INVALID_HID;
  if (dapl < 0) {
    dapl = H5Pcreate(H5P_DATASET_ACCESS);
    if (dapl >= 0 && H5Pset_chunk_cache(dapl, H5D_CHUNK_CACHE_NSLOTS_DEFAULT, 0,
                                        H5D_CHUNK_CACHE_W0_DEFAULT) < 0) {
      H5Pclose(dapl);
      dapl = H5I_INVALID_HID;
    }
  }
  return dapl >= 0 ? dapl : H5P_DEFAULT;
}

/* A series handle with its one-chunk row buffer (dataset not yet opened). */
static proto_series *series_alloc(proto_h5 *f, const char *full, int ncols,
                                  proto_err *err) {
  proto_series *s = calloc(1, sizeof *s);
  int rows = SERIES_CHUNK_BYTES / (8 * ncols);
  rows = rows < 1 ? 1 : rows > SERIES_CHUNK_ROWS ? SERIES_CHUNK_ROWS : rows;
  if (s) s->buf = malloc((size_t)rows * (size_t)ncols * sizeof(double));
  if (!s || !s->buf) {
    free(s);
    proto_fail(err, "%s:%s: out of memory", f->path, full);
    return NULL;
  }
  s->file = f;
  s->ncols = ncols;
  s->buf_rows = rows;
  s->dset = H5I_INVALID_HID;
  snprintf(s->path, sizeof s->path, "%s", full);
  return s;
}

static proto_series *series_keep(proto_h5 *f, proto_series *s) {
  s->next = f->series;
  f->series = s;
  return s;
}

static proto_series *series_drop(proto_series *s) {
  h5_close_id(s->dset);
  free(s->buf);
  free(s);
  return NULL;
}

proto_series *proto_h5_series(proto_h5 *f, const char *path, int ncols,
                              const char *const *columns, proto_err *err) {
  char full[H5_PATH_CAP];
  if (series_args(f, path, ncols, columns, full, err) < 0) return NULL;
  if (make_groups(f, full, 1, err) < 0) return NULL;
  htri_t exists = H5Lexists(f->file, full, H5P_DEFAULT);
  if (exists != 0) {
    if (exists < 0) h5_fail(err, f->path, full, "cannot look up series");
    else proto_fail(err, "%s:%s: already exists", f->path, full);
    return NULL;
  }
  proto_series *s = series_alloc(f, full, ncols, err);
  if (!s) return NULL;
  hsize_t dims[2] = {0, (hsize_t)ncols};
  hsize_t maxdims[2] = {H5S_UNLIMITED, (hsize_t)ncols};
  hsize_t chunk[2] = {(hsize_t)s->buf_rows, (hsize_t)ncols};
  hid_t space = H5Screate_simple(2, dims, maxdims);
  hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
  if (space >= 0 && dcpl >= 0 && H5Pset_chunk(dcpl, 2, chunk) >= 0)
    s->dset = H5Dcreate2(f->file, full, H5T_IEEE_F64LE, space, H5P_DEFAULT,
                         dcpl, series_access());
  h5_close_id(dcpl);
  h5_close_id(space);
  if (s->dset < 0) {
    h5_fail(err, f->path, full, "cannot create series");
    return series_drop(s);
  }
  if (write_str_attr(f, s->dset, full, "columns", ncols, columns, err) < 0)
    return series_drop(s);
  return series_keep(f, s);
}

/* Element i of a string attribute (scalar: i = 0) into out; -1 if absent. */
static int read_str_attr(proto_h5 *f, hid_t obj, const char *obj_path,
                         const char *name, int want_n, char **out, int cap,
                         proto_err *err) {
  hid_t attr = H5Aopen(obj, name, H5P_DEFAULT);
  hid_t space = attr >= 0 ? H5Aget_space(attr) : H5I_INVALID_HID;
  hid_t type = vlen_str_type();
  hssize_t n = space >= 0 ? H5Sget_simple_extent_npoints(space) : -1;
  int rc = -1;
  if (attr < 0 || space < 0 || type < 0 || n < 1 || n > cap ||
      (want_n >= 0 && n != want_n)) {
    if (n >= 0 && want_n >= 0 && n != want_n)
      proto_fail(err, "%s:%s: attribute '%s' has %lld entries, expected %d", f->path,
                 obj_path, name, (long long)n, want_n);
    else
      h5_fail(err, f->path, obj_path, "cannot read string attribute");
  } else if (H5Aread(attr, type, out) < 0) {
    h5_fail(err, f->path, obj_path, "cannot read string attribute");
  } else {
    rc = (int)n;
  }
  h5_close_id(type);
  h5_close_id(space);
  h5_close_id(attr);
  return rc;
}

static void free_strs(char **v, int n) {
  for (int i = 0; i < n; i++) H5free_memory(v[i]);
}

/* The columns attribute of an existing series must be `columns`. */
static int same_columns(proto_h5 *f, proto_series *s, const char *const *columns,
                        proto_err *err) {
  char **have = calloc((size_t)s->ncols, sizeof *have);
  if (!have) return proto_fail(err, "%s:%s: out of memory", f->path, s->path);
  int n = read_str_attr(f, s->dset, s->path, "columns", s->ncols, have, s->ncols, err);
  int rc = n < 0 ? -1 : 0;
  for (int c = 0; rc == 0 && c < s->ncols; c++)
    if (strcmp(have[c], columns[c]) != 0)
      rc = proto_fail(err, "%s:%s: column %d is '%s' in the file, '%s' now", f->path,
                      s->path, c, have[c], columns[c]);
  if (n > 0) free_strs(have, n);
  free(have);
  return rc;
}

proto_series *proto_h5_series_resume(proto_h5 *f, const char *path, int ncols,
                                     const char *const *columns, int64_t keep_rows,
                                     proto_err *err) {
  char full[H5_PATH_CAP];
  if (series_args(f, path, ncols, columns, full, err) < 0) return NULL;
  if (H5Lexists(f->file, full, H5P_DEFAULT) <= 0) {
    H5Eclear2(H5E_DEFAULT);
    proto_fail(err, "%s:%s: no such series to continue", f->path, full);
    return NULL;
  }
  proto_series *s = series_alloc(f, full, ncols, err);
  if (!s) return NULL;
  s->dset = H5Dopen2(f->file, full, series_access());
  hid_t space = s->dset >= 0 ? H5Dget_space(s->dset) : H5I_INVALID_HID;
  hsize_t dims[2] = {0, 0};
  int rank = space >= 0 ? H5Sget_simple_extent_dims(space, dims, NULL) : -1;
  h5_close_id(space);
  if (rank != 2 || dims[1] != (hsize_t)ncols) {
    if (rank < 0) h5_fail(err, f->path, full, "cannot open series");
    else proto_fail(err, "%s:%s: is not a series of %d columns", f->path, full, ncols);
    return series_drop(s);
  }
  if (same_columns(f, s, columns, err) < 0) return series_drop(s);
  if ((int64_t)dims[0] < keep_rows) {
    proto_fail(err, "%s:%s: has %lld rows, fewer than the %lld to continue from",
               f->path, full, (long long)dims[0], (long long)keep_rows);
    return series_drop(s);
  }
  dims[0] = (hsize_t)keep_rows;
  if (H5Dset_extent(s->dset, dims) < 0) {
    h5_fail(err, f->path, full, "cannot truncate series");
    return series_drop(s);
  }
  s->rows_on_disk = keep_rows;
  return series_keep(f, s);
}

int proto_series_append(proto_series *s, const double *row, proto_err *err) {
  if (!s || !row) return proto_fail(err, "proto_series_append: no series/row");
  /* Write the full buffer first, so a failed append never keeps its row. */
  if (s->nbuf == s->buf_rows && series_write(s, err) < 0) return -1;
  memcpy(s->buf + (size_t)s->nbuf * (size_t)s->ncols, row,
         (size_t)s->ncols * sizeof(double));
  s->nbuf++;
  return 0;
}

size_t proto_h5_buffer_bytes(const proto_h5 *f) {
  size_t n = 0;
  for (const proto_series *s = f ? f->series : NULL; s; s = s->next)
    n += (size_t)s->buf_rows * (size_t)s->ncols * sizeof(double);
  return n;
}

int64_t proto_series_rows(const proto_series *s) {
  return s ? s->rows_on_disk + s->nbuf : 0;
}

/* -------------------------------------------------------------- arrays */

static hid_t dtype_h5(proto_dtype d, size_t *size) {
  switch (d) {
    case PROTO_F8: *size = 8; return H5T_IEEE_F64LE;
    case PROTO_I4: *size = 4; return H5T_STD_I32LE;
    case PROTO_I8: *size = 8; return H5T_STD_I64LE;
    case PROTO_U1: *size = 1; return H5T_STD_U8LE;
  }
  return H5I_INVALID_HID;
}

int proto_h5_write_array(proto_h5 *f, const char *group, const proto_array *a,
                         proto_err *err) {
  char full[H5_PATH_CAP];
  if (!f || !a) return proto_fail(err, "proto_h5_write_array: no file/array");
  if (!a->name[0])
    return proto_fail(err, "%s:%s: array without a name", f->path,
                      group ? group : "/");
  if (join_path(full, sizeof full, group, a->name, f->path, err) < 0) return -1;
  size_t elsize = 0;
  /* The wire format is little-endian, so the memory type is LE too. */
  hid_t type = dtype_h5(a->dtype, &elsize);
  if (type < 0)
    return proto_fail(err, "%s:%s: unknown dtype %d", f->path, full,
                      (int)a->dtype);
  if (a->ndim < 1 || a->ndim > PROTO_MAX_NDIM)
    return proto_fail(err, "%s:%s: ndim must be 1..%d, got %d", f->path, full,
                      PROTO_MAX_NDIM, a->ndim);
  hsize_t dims[PROTO_MAX_NDIM];
  uint64_t count = 1;
  for (int i = 0; i < a->ndim; i++) {
    if (a->shape[i] < 0 || (a->shape[i] > 0 && count > UINT64_MAX / 16 /
                                                           (uint64_t)a->shape[i]))
      return proto_fail(err, "%s:%s: bad shape[%d] = %lld", f->path, full, i,
                        (long long)a->shape[i]);
    dims[i] = (hsize_t)a->shape[i];
    count *= (uint64_t)a->shape[i];
  }
  if (count * elsize != a->nbytes || (count > 0 && !a->data))
    return proto_fail(err, "%s:%s: shape needs %llu bytes, array has %zu",
                      f->path, full, (unsigned long long)(count * elsize),
                      a->nbytes);

  if (make_groups(f, full, 1, err) < 0) return -1;
  htri_t exists = H5Lexists(f->file, full, H5P_DEFAULT);
  if (exists < 0 || (exists > 0 && H5Ldelete(f->file, full, H5P_DEFAULT) < 0))
    return h5_fail(err, f->path, full, "cannot replace dataset");
  int rc = -1;
  hid_t space = H5Screate_simple(a->ndim, dims, NULL);
  hid_t dset = H5I_INVALID_HID;
  if (space >= 0)
    dset = H5Dcreate2(f->file, full, type, space, H5P_DEFAULT, H5P_DEFAULT,
                      H5P_DEFAULT);
  if (dset < 0) {
    h5_fail(err, f->path, full, "cannot create dataset");
    goto done;
  }
  if (count > 0 &&
      H5Dwrite(dset, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, a->data) < 0) {
    h5_fail(err, f->path, full, "cannot write dataset");
    H5Ldelete(f->file, full, H5P_DEFAULT); /* no half-written dataset left behind */
    H5Eclear2(H5E_DEFAULT);
    goto done;
  }
  rc = 0;
done:
  h5_close_id(dset);
  h5_close_id(space);
  return rc;
}

/* ------------------------------------------------------------- reading */

int proto_h5_exists(proto_h5 *f, const char *path) {
  char full[H5_PATH_CAP];
  if (!f || join_path(full, sizeof full, path, NULL, f->path, NULL) < 0) return 0;
  /* every link on the way must exist for H5Lexists not to fail */
  for (char *p = full + 1; *p; p++) {
    if (*p != '/') continue;
    *p = 0;
    htri_t e = H5Lexists(f->file, full, H5P_DEFAULT);
    *p = '/';
    if (e <= 0) {
      H5Eclear2(H5E_DEFAULT);
      return 0;
    }
  }
  htri_t e = strcmp(full, "/") == 0 ? 1 : H5Lexists(f->file, full, H5P_DEFAULT);
  H5Eclear2(H5E_DEFAULT);
  return e > 0;
}

int proto_h5_unlink(proto_h5 *f, const char *path, proto_err *err) {
  char full[H5_PATH_CAP];
  if (!f) return proto_fail(err, "proto_h5_unlink: no file");
  if (join_path(full, sizeof full, path, NULL, f->path, err) < 0) return -1;
  if (!proto_h5_exists(f, full)) return 0;
  if (H5Ldelete(f->file, full, H5P_DEFAULT) < 0)
    return h5_fail(err, f->path, full, "cannot delete");
  return 0;
}

int proto_h5_list(proto_h5 *f, const char *group,
                  int (*fn)(const char *name, void *ctx), void *ctx, proto_err *err) {
  char full[H5_PATH_CAP];
  if (!f) return proto_fail(err, "proto_h5_list: no file");
  if (join_path(full, sizeof full, group, NULL, f->path, err) < 0) return -1;
  if (!proto_h5_exists(f, full)) return 0;
  hid_t g = H5Gopen2(f->file, full, H5P_DEFAULT);
  if (g < 0) return h5_fail(err, f->path, full, "cannot open group");
  int stop = 0;
  herr_t r = proto_h5_members(g, fn, ctx, &stop);
  H5Gclose(g);
  if (stop < 0) return -1;
  return r < 0 ? h5_fail(err, f->path, full, "cannot list group") : 0;
}
