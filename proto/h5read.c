/* h5read.c — reading HDF5 files made elsewhere (roads, springs, Green's
 * functions, saved beds: the "HDF5 input" section of proto.h). A file may be
 * damaged or hostile: every object is looked up level by level, every
 * dataset's class, rank and dims are checked against what the reader
 * expects and its element count (overflow-checked) against a limit before
 * anything is allocated, values must be finite, attributes must hold one
 * value, and every error names "<file>:<object>". HDF5's own error printing
 * is off while a file is open. */
#include "proto.h"
#include "h5members.h"

#include <hdf5.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Longest fixed-length string attribute read (bytes). */
#define H5IN_MAX_STRING ((size_t)1 << 20)

struct proto_h5in {
  hid_t file;
  char path[PROTO_PATH_CAP * 2];
  H5E_auto2_t saved_fn; /* HDF5's error printer, restored on close */
  void *saved_data;
};

proto_h5in *proto_h5in_open(const char *path, proto_err *err) {
  proto_h5in *f = calloc(1, sizeof *f);
  if (!f) {
    proto_fail(err, "%s: out of memory", path);
    return NULL;
  }
  snprintf(f->path, sizeof f->path, "%s", path);
  H5Eget_auto2(H5E_DEFAULT, &f->saved_fn, &f->saved_data);
  H5Eset_auto2(H5E_DEFAULT, NULL, NULL);
  f->file = H5Fis_hdf5(path) > 0 ? H5Fopen(path, H5F_ACC_RDONLY, H5P_DEFAULT) : -1;
  if (f->file < 0) {
    proto_fail(err, "%s: cannot open as HDF5 (missing, unreadable or not an "
               "HDF5 file)", path);
    proto_h5in_close(f);
    return NULL;
  }
  return f;
}

void proto_h5in_close(proto_h5in *f) {
  if (!f) return;
  if (f->file >= 0) H5Fclose(f->file);
  H5Eclear2(H5E_DEFAULT);
  H5Eset_auto2(H5E_DEFAULT, f->saved_fn, f->saved_data);
  free(f);
}

const char *proto_h5in_path(const proto_h5in *f) { return f->path; }

int proto_h5in_exists(proto_h5in *f, const char *obj) {
  /* H5Lexists fails (rather than says no) when a parent is missing: walk */
  char part[PROTO_PATH_CAP];
  size_t n = strlen(obj);
  if (n == 0 || n >= sizeof part) return 0;
  if (strcmp(obj, "/") == 0) return 1;
  for (size_t i = 1; i <= n; i++) {
    if (obj[i] != '/' && obj[i] != 0) continue;
    memcpy(part, obj, i);
    part[i] = 0;
    if (H5Lexists(f->file, part, H5P_DEFAULT) <= 0) return 0;
    if (H5Oexists_by_name(f->file, part, H5P_DEFAULT) <= 0) return 0;
  }
  return 1;
}

/* What a dataset's elements must be. */
typedef enum { H5IN_NUMBERS, H5IN_INTEGERS } h5in_kind;

/* Opens a dataset and checks its class (numeric) and rank (-1: any of 1 to
 * PROTO_MAX_NDIM); dims out. */
static hid_t open_dataset(proto_h5in *f, const char *obj, int rank,
                          hsize_t *dims, h5in_kind kind, proto_err *err) {
  if (!proto_h5in_exists(f, obj)) {
    proto_fail(err, "%s:%s: dataset missing", f->path, obj);
    return -1;
  }
  hid_t ds = H5Dopen2(f->file, obj, H5P_DEFAULT);
  if (ds < 0) {
    proto_fail(err, "%s:%s: not a dataset", f->path, obj);
    return -1;
  }
  hid_t type = H5Dget_type(ds), space = H5Dget_space(ds);
  H5T_class_t cls = type >= 0 ? H5Tget_class(type) : H5T_NO_CLASS;
  int r = space >= 0 && H5Sget_simple_extent_type(space) == H5S_SIMPLE
              ? H5Sget_simple_extent_ndims(space) : -1;
  int rc = 0;
  if (cls != H5T_INTEGER && (kind == H5IN_INTEGERS || cls != H5T_FLOAT))
    rc = proto_fail(err, "%s:%s: expected %s, got another HDF5 type", f->path, obj,
                    kind == H5IN_INTEGERS ? "integers" : "numbers (integer or float)");
  else if (rank < 0 && (r < 1 || r > PROTO_MAX_NDIM))
    rc = proto_fail(err, "%s:%s: has %d dimension(s), expected 1 to %d", f->path, obj,
                    r, PROTO_MAX_NDIM);
  else if (rank >= 0 && r != rank)
    rc = proto_fail(err, "%s:%s: has %d dimension(s), expected %d", f->path, obj,
                    r, rank);
  else if (H5Sget_simple_extent_dims(space, dims, NULL) != r)
    rc = proto_fail(err, "%s:%s: cannot read its dimensions", f->path, obj);
  if (type >= 0) H5Tclose(type);
  if (space >= 0) H5Sclose(space);
  if (rc < 0) {
    H5Dclose(ds);
    return -1;
  }
  return ds;
}

/* Checks hdims against want (-1: any), the product against max_elems. */
static int check_dims(proto_h5in *f, const char *obj, int rank,
                      const hsize_t *hdims, int64_t *want, int64_t max_elems,
                      int64_t *count, proto_err *err) {
  int64_t got[PROTO_H5IN_MAX_RANK];
  uint64_t n = 1;
  int over = 0;
  for (int i = 0; i < rank; i++) {
    got[i] = hdims[i] > (hsize_t)INT64_MAX ? INT64_MAX : (int64_t)hdims[i];
    over |= __builtin_mul_overflow(n, (uint64_t)hdims[i], &n);
  }
  for (int i = 0; i < rank; i++)
    if (want[i] >= 0 && want[i] != got[i]) {
      char w[96], g[96];
      proto_shape_str(w, sizeof w, rank, want);
      proto_shape_str(g, sizeof g, rank, got);
      return proto_fail(err, "%s:%s: shape %s, expected %s", f->path, obj, g, w);
    }
  if (over || n > (uint64_t)max_elems) {
    char g[96];
    proto_shape_str(g, sizeof g, rank, got);
    return proto_fail(err, "%s:%s: shape %s holds more than the %lld elements "
                      "this reader accepts", f->path, obj, g, (long long)max_elems);
  }
  for (int i = 0; i < rank; i++) want[i] = got[i];
  *count = (int64_t)n;
  return 0;
}

/* Index of flat element k in dims, "[i][j]", for messages. */
static void index_str(int rank, const int64_t *dims, int64_t k, char *out,
                      size_t cap) {
  int64_t idx[PROTO_H5IN_MAX_RANK];
  for (int i = rank - 1; i >= 0; i--) {
    idx[i] = dims[i] > 0 ? k % dims[i] : 0;
    k = dims[i] > 0 ? k / dims[i] : 0;
  }
  size_t len = 0;
  out[0] = 0;
  for (int i = 0; i < rank && len < cap; i++)
    len += (size_t)snprintf(out + len, cap - len, "[%lld]", (long long)idx[i]);
}

static int read_any(proto_h5in *f, const char *obj, int rank, int64_t *dims,
                    int64_t max_elems, int integer, void **out, proto_err *err) {
  *out = NULL;
  if (rank < 1 || rank > PROTO_H5IN_MAX_RANK)
    return proto_fail(err, "%s:%s: rank %d not supported", f->path, obj, rank);
  hsize_t hdims[PROTO_H5IN_MAX_RANK];
  hid_t ds = open_dataset(f, obj, rank, hdims, integer ? H5IN_INTEGERS : H5IN_NUMBERS, err);
  if (ds < 0) return -1;
  int64_t count = 0;
  int rc = check_dims(f, obj, rank, hdims, dims, max_elems, &count, err);
  size_t elem = integer ? sizeof(int32_t) : sizeof(double);
  void *buf = rc == 0 ? malloc((size_t)(count ? count : 1) * elem) : NULL;
  if (rc == 0 && !buf)
    rc = proto_fail(err, "%s:%s: out of memory for %lld elements", f->path, obj,
                    (long long)count);
  if (rc == 0 && count > 0 &&
      H5Dread(ds, integer ? H5T_NATIVE_INT32 : H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL,
              H5P_DEFAULT, buf) < 0)
    rc = proto_fail(err, "%s:%s: cannot read (damaged, or values out of range "
                    "of %s)", f->path, obj, integer ? "int32" : "double");
  const int64_t k = rc == 0 && !integer ? proto_first_nonfinite(buf, count) : -1;
  if (k >= 0) {
    char at[96];
    index_str(rank, dims, k, at, sizeof at);
    rc = proto_fail(err, "%s:%s: element %s is %g (values must be finite)",
                    f->path, obj, at, ((const double *)buf)[k]);
  }
  H5Dclose(ds);
  if (rc < 0) {
    free(buf);
    return -1;
  }
  *out = buf;
  return 0;
}

int proto_h5in_read_f8(proto_h5in *f, const char *obj, int rank, int64_t *dims,
                       int64_t max_elems, double **out, proto_err *err) {
  return read_any(f, obj, rank, dims, max_elems, 0, (void **)out, err);
}

int proto_h5in_read_i4(proto_h5in *f, const char *obj, int rank, int64_t *dims,
                       int64_t max_elems, int32_t **out, proto_err *err) {
  return read_any(f, obj, rank, dims, max_elems, 1, (void **)out, err);
}

typedef struct list_ctx {
  int (*fn)(const char *name, void *ctx);
  void *ctx;
  int stop;
} list_ctx;

static herr_t list_cb(hid_t g, const char *name, const H5L_info_t *info, void *data) {
  (void)g, (void)info;
  list_ctx *c = data;
  c->stop = c->fn(name, c->ctx);
  return c->stop ? 1 : 0;
}

herr_t proto_h5_members(hid_t g, int (*fn)(const char *name, void *ctx), void *ctx,
                        int *fn_rc) {
  list_ctx c = {fn, ctx, 0};
  herr_t r = H5Literate(g, H5_INDEX_NAME, H5_ITER_INC, NULL, list_cb, &c);
  *fn_rc = c.stop;
  return r;
}

int proto_h5in_list(proto_h5in *f, const char *group,
                    int (*fn)(const char *name, void *ctx), void *ctx, proto_err *err) {
  if (!proto_h5in_exists(f, group))
    return proto_fail(err, "%s:%s: group missing", f->path, group);
  hid_t g = H5Gopen2(f->file, group, H5P_DEFAULT);
  if (g < 0) return proto_fail(err, "%s:%s: not a group", f->path, group);
  int stop = 0;
  herr_t r = proto_h5_members(g, fn, ctx, &stop);
  H5Gclose(g);
  if (stop < 0) return -1;
  return r < 0 ? proto_fail(err, "%s:%s: cannot list its members (damaged)", f->path, group)
               : 0;
}

/* The proto dtype a stored type is exactly (class, size and sign; the byte
 * order HDF5 converts): -1 if none. */
static int stored_dtype(hid_t type, proto_dtype *d, hid_t *mem) {
  H5T_class_t cls = H5Tget_class(type);
  size_t size = H5Tget_size(type);
  H5T_sign_t sign = cls == H5T_INTEGER ? H5Tget_sign(type) : H5T_SGN_ERROR;
  if (cls == H5T_FLOAT && size == 8) *d = PROTO_F8, *mem = H5T_IEEE_F64LE;
  else if (sign == H5T_SGN_2 && size == 4) *d = PROTO_I4, *mem = H5T_STD_I32LE;
  else if (sign == H5T_SGN_2 && size == 8) *d = PROTO_I8, *mem = H5T_STD_I64LE;
  else if (sign == H5T_SGN_NONE && size == 1) *d = PROTO_U1, *mem = H5T_STD_U8LE;
  else return -1;
  /* a float must also be IEEE binary64 (its precision and exponent) */
  if (cls == H5T_FLOAT && (H5Tget_precision(type) != 64 || H5Tget_ebias(type) != 1023))
    return -1;
  return 0;
}

int proto_h5in_read_array(proto_h5in *f, const char *obj, size_t max_bytes,
                          proto_array *a, void **data, proto_err *err) {
  memset(a, 0, sizeof *a);
  *data = NULL;
  hsize_t hdims[PROTO_MAX_NDIM];
  hid_t ds = open_dataset(f, obj, -1, hdims, H5IN_NUMBERS, err);
  if (ds < 0) return -1;
  hid_t type = H5Dget_type(ds), mem = -1;
  int rc = type >= 0 && stored_dtype(type, &a->dtype, &mem) == 0 ? 0
         : proto_fail(err, "%s:%s: expected f8, i4, i8 or u1 elements, got another "
                      "HDF5 type", f->path, obj);
  if (type >= 0) H5Tclose(type);
  hid_t space = H5Dget_space(ds); /* open_dataset checked it: 1 to PROTO_MAX_NDIM */
  int rank = space >= 0 ? H5Sget_simple_extent_ndims(space) : -1;
  if (space >= 0) H5Sclose(space);
  if (rc == 0 && (rank < 1 || rank > PROTO_MAX_NDIM))
    rc = proto_fail(err, "%s:%s: cannot read its dimensions", f->path, obj);
  size_t el = rc == 0 ? proto_dtype_size(a->dtype) : 1;
  int64_t count = 0, want[PROTO_MAX_NDIM] = {-1, -1, -1};
  if (rc == 0)
    rc = check_dims(f, obj, rank, hdims, want, (int64_t)(max_bytes / el), &count, err);
  if (rc == 0) {
    a->ndim = rank;
    memcpy(a->shape, want, sizeof a->shape);
    a->nbytes = (size_t)count * el;
    const char *slash = strrchr(obj, '/');
    snprintf(a->name, sizeof a->name, "%s", slash ? slash + 1 : obj);
    *data = malloc(a->nbytes ? a->nbytes : 1);
    if (!*data)
      rc = proto_fail(err, "%s:%s: out of memory for %zu bytes", f->path, obj, a->nbytes);
  }
  if (rc == 0 && count > 0 && H5Dread(ds, mem, H5S_ALL, H5S_ALL, H5P_DEFAULT, *data) < 0)
    rc = proto_fail(err, "%s:%s: cannot read (damaged)", f->path, obj);
  H5Dclose(ds);
  if (rc < 0) {
    free(*data);
    *data = NULL;
    return -1;
  }
  a->data = *data;
  return 0;
}

int proto_h5in_rank(proto_h5in *f, const char *obj, proto_err *err) {
  if (!proto_h5in_exists(f, obj))
    return proto_fail(err, "%s:%s: dataset missing", f->path, obj);
  hid_t ds = H5Dopen2(f->file, obj, H5P_DEFAULT);
  if (ds < 0) return proto_fail(err, "%s:%s: not a dataset", f->path, obj);
  hid_t space = H5Dget_space(ds);
  int r = space >= 0 && H5Sget_simple_extent_type(space) == H5S_SIMPLE
              ? H5Sget_simple_extent_ndims(space) : -1;
  if (space >= 0) H5Sclose(space);
  H5Dclose(ds);
  return r < 0 ? proto_fail(err, "%s:%s: not an array", f->path, obj) : r;
}

/* Opens attribute name of obj holding exactly one value; 1 if absent. */
static int open_attr(proto_h5in *f, const char *obj, const char *name, hid_t *a,
                     H5T_class_t *cls, hid_t *type, proto_err *err) {
  if (!proto_h5in_exists(f, obj) ||
      H5Aexists_by_name(f->file, obj, name, H5P_DEFAULT) <= 0)
    return 1;
  *a = H5Aopen_by_name(f->file, obj, name, H5P_DEFAULT, H5P_DEFAULT);
  if (*a < 0) return proto_fail(err, "%s:%s: cannot open attribute %s", f->path, obj, name);
  hid_t space = H5Aget_space(*a);
  hssize_t npoints = space >= 0 ? H5Sget_simple_extent_npoints(space) : -1;
  H5S_class_t sc = space >= 0 ? H5Sget_simple_extent_type(space) : H5S_NO_CLASS;
  if (space >= 0) H5Sclose(space);
  *type = H5Aget_type(*a);
  *cls = *type >= 0 ? H5Tget_class(*type) : H5T_NO_CLASS;
  if (sc == H5S_NULL || npoints != 1) {
    if (*type >= 0) H5Tclose(*type);
    H5Aclose(*a);
    return proto_fail(err, "%s:%s: attribute %s must hold one value (it holds %lld)",
                      f->path, obj, name, (long long)(sc == H5S_NULL ? 0 : npoints));
  }
  return 0;
}

int proto_h5in_attr_f8(proto_h5in *f, const char *obj, const char *name,
                       double *v, proto_err *err) {
  hid_t a, type;
  H5T_class_t cls;
  int rc = open_attr(f, obj, name, &a, &cls, &type, err);
  if (rc != 0) return rc;
  double x = 0;
  if (cls != H5T_INTEGER && cls != H5T_FLOAT)
    rc = proto_fail(err, "%s:%s: attribute %s must be a number", f->path, obj, name);
  else if (H5Aread(a, H5T_NATIVE_DOUBLE, &x) < 0)
    rc = proto_fail(err, "%s:%s: cannot read attribute %s", f->path, obj, name);
  else if (!isfinite(x))
    rc = proto_fail(err, "%s:%s: attribute %s is %g (must be finite)", f->path, obj,
                    name, x);
  H5Tclose(type);
  H5Aclose(a);
  if (rc == 0) *v = x;
  return rc;
}

int proto_h5in_attr_strdup(proto_h5in *f, const char *obj, const char *name,
                           char **out, proto_err *err) {
  *out = NULL;
  hid_t a, type;
  H5T_class_t cls;
  int rc = open_attr(f, obj, name, &a, &cls, &type, err);
  if (rc != 0) return rc;
  hid_t mem = H5Tcopy(H5T_C_S1);
  char *s = NULL;
  /* HDF5 converts no text between ASCII and UTF-8: read it as it is stored */
  if (cls == H5T_STRING) H5Tset_cset(mem, H5Tget_cset(type));
  int vlen = cls == H5T_STRING && H5Tis_variable_str(type) > 0;
  size_t size = cls == H5T_STRING && !vlen ? H5Tget_size(type) : 0;
  if (cls != H5T_STRING) {
    rc = proto_fail(err, "%s:%s: attribute %s must be a string", f->path, obj, name);
  } else if (vlen) {
    H5Tset_size(mem, H5T_VARIABLE);
    if (H5Aread(a, mem, &s) < 0 || !s)
      rc = proto_fail(err, "%s:%s: cannot read attribute %s", f->path, obj, name);
    else if (strlen(s) > H5IN_MAX_STRING)
      rc = proto_fail(err, "%s:%s: attribute %s: a string of %zu bytes (at most %zu)",
                      f->path, obj, name, strlen(s), H5IN_MAX_STRING);
    else if (!(*out = strdup(s)))
      rc = proto_fail(err, "%s:%s: out of memory", f->path, obj);
    if (s) H5free_memory(s);
  } else if (size == 0 || size > H5IN_MAX_STRING) {
    rc = proto_fail(err, "%s:%s: attribute %s: a string of %zu bytes (at most %zu)",
                    f->path, obj, name, size, H5IN_MAX_STRING);
  } else {
    s = calloc(size + 1, 1);
    H5Tset_size(mem, size + 1);
    if (!s || H5Aread(a, mem, s) < 0) {
      rc = proto_fail(err, "%s:%s: cannot read attribute %s", f->path, obj, name);
      free(s);
    } else {
      *out = s;
    }
  }
  H5Tclose(mem);
  H5Tclose(type);
  H5Aclose(a);
  return rc;
}

int proto_h5in_attr_str(proto_h5in *f, const char *obj, const char *name,
                        char *out, size_t cap, proto_err *err) {
  char *s = NULL;
  int rc = proto_h5in_attr_strdup(f, obj, name, &s, err);
  if (rc == 0) snprintf(out, cap, "%s", s);
  free(s);
  return rc;
}
