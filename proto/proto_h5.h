/* proto_h5.h — proto's output: HDF5 writer and reader, XDMF.
 * Part of proto.h, the one public header: include "proto/proto.h", not this. */
#ifndef COSIM_PROTO_H5_H
#define COSIM_PROTO_H5_H
#ifndef COSIM_PROTO_H
#error "include proto/proto.h, not proto_h5.h"
#endif

/* ------------------------------------------------------------------ output
 *
 * One HDF5 file per run. Time series are 2-D f8 datasets (one row per
 * step, chunked, growing), with the column names in the attribute
 * "columns"; snapshots are groups "<group>/steps/<n>" of arrays. */

typedef struct proto_h5 proto_h5;        /* the file */
typedef struct proto_series proto_series; /* one growing 2-D dataset */

proto_h5 *proto_h5_create(const char *path, proto_err *err);
/* Opens an existing file (writable: to continue it, read-only otherwise). */
proto_h5 *proto_h5_open(const char *path, int writable, proto_err *err);
/* What is at path: 0 nothing, 1 an HDF5 file, 2 anything else (another
 * kind of file, or one that cannot be read). Never changes the file. */
int proto_h5_probe(const char *path);
/* Writes every buffered row and flushes HDF5's caches to the file. Errors
 * name the file, the object and the system error ("No space left on device
 * (errno 28)"); the rows stay buffered, so a later flush may still write
 * them. */
int proto_h5_flush(proto_h5 *f, proto_err *err);
/* Flushes and closes; the handle is freed either way. -1 (err may be NULL)
 * if anything failed. HDF5 never closes a file again at exit. */
int proto_h5_close(proto_h5 *f, proto_err *err);
/* Stores a string attribute (e.g. the config) on an object ("/" = root; a
 * missing one becomes a group): variable-length UTF-8. */
int proto_h5_attr_str(proto_h5 *f, const char *group, const char *name,
                      const char *value, proto_err *err);
/* A number (f8) or an integer (i8) attribute, likewise (one value). */
int proto_h5_attr_f8(proto_h5 *f, const char *group, const char *name, double v,
                     proto_err *err);
int proto_h5_attr_i8(proto_h5 *f, const char *group, const char *name, int64_t v,
                     proto_err *err);
/* "/dem/series" with the given columns; parent groups made as needed. */
proto_series *proto_h5_series(proto_h5 *f, const char *path, int ncols,
                              const char *const *columns, proto_err *err);
/* An existing series, to append to after its first keep_rows rows (the
 * rest is cut off): its columns must be these. */
proto_series *proto_h5_series_resume(proto_h5 *f, const char *path, int ncols,
                                     const char *const *columns, int64_t keep_rows,
                                     proto_err *err);
int proto_series_append(proto_series *s, const double *row, proto_err *err);
int64_t proto_series_rows(const proto_series *s);
/* The most the series' row buffers can hold (bytes): what a flush may
 * have to write besides HDF5's own metadata. */
size_t proto_h5_buffer_bytes(const proto_h5 *f);
/* Writes an array (any dtype/shape of proto_array) as dataset
 * "<group>/<a->name>"; groups made as needed. */
int proto_h5_write_array(proto_h5 *f, const char *group, const proto_array *a,
                         proto_err *err);

/* Continuing a results file (its own writer); every other file is read
 * through the HDF5 input layer below. */
int proto_h5_exists(proto_h5 *f, const char *path); /* 1 if a link is there */
int proto_h5_unlink(proto_h5 *f, const char *path, proto_err *err); /* absent: ok */
/* Calls fn(name, ctx) for each member of group, in name order; fn returns
 * 0 to go on, 1 to stop, -1 to stop with an error (returned). A missing
 * group has no members. */
int proto_h5_list(proto_h5 *f, const char *group,
                  int (*fn)(const char *name, void *ctx), void *ctx, proto_err *err);

/* ------------------------------------------------------------- HDF5 input
 *
 * Reading HDF5 files (roads, springs, Green's functions, saved beds,
 * checkpoints), which may be damaged or hostile. Objects are looked up level
 * by level; a dataset's class must be numeric and its rank and dims are
 * checked against what the reader expects, its element count
 * (overflow-checked) against max_elems, before anything is allocated; its
 * values must be finite (read_f8); an attribute must hold exactly one value.
 * Errors name "<file>:<object>: <what>". */
typedef struct proto_h5in proto_h5in;
#define PROTO_H5IN_MAX_RANK 4

proto_h5in *proto_h5in_open(const char *path, proto_err *err);
void proto_h5in_close(proto_h5in *f); /* NULL is fine */
const char *proto_h5in_path(const proto_h5in *f);
/* 1 if the object (group or dataset, "/a/b") exists, else 0. */
int proto_h5in_exists(proto_h5in *f, const char *obj);
/* The rank of dataset obj, or -1. */
int proto_h5in_rank(proto_h5in *f, const char *obj, proto_err *err);
/* Reads dataset obj of the given rank as doubles (any integer or float
 * type). dims[i] in: the size expected, or -1 for any; out: the size found.
 * *out is malloc'ed (caller frees). */
int proto_h5in_read_f8(proto_h5in *f, const char *obj, int rank, int64_t *dims,
                       int64_t max_elems, double **out, proto_err *err);
/* The same as int32 (integer types only; values beyond int32 saturate: the
 * caller checks the range it needs). */
int proto_h5in_read_i4(proto_h5in *f, const char *obj, int rank, int64_t *dims,
                       int64_t max_elems, int32_t **out, proto_err *err);
/* Attribute `name` of object obj: 0 read, 1 absent (out untouched), -1 bad
 * (not one value, wrong type, not finite). Strings are truncated to cap. */
int proto_h5in_attr_f8(proto_h5in *f, const char *obj, const char *name,
                       double *v, proto_err *err);
int proto_h5in_attr_str(proto_h5in *f, const char *obj, const char *name,
                        char *out, size_t cap, proto_err *err);
/* The same, whole (at most 1 MiB): *out malloc'ed, caller frees. */
int proto_h5in_attr_strdup(proto_h5in *f, const char *obj, const char *name,
                           char **out, proto_err *err);
/* Calls fn(name, ctx) for each member of group, in name order; fn returns
 * 0 to go on, 1 to stop, -1 to stop with an error (returned). A missing
 * group is an error. */
int proto_h5in_list(proto_h5in *f, const char *group,
                    int (*fn)(const char *name, void *ctx), void *ctx, proto_err *err);
/* Reads dataset obj as stored (a checkpoint's state, bit for bit): elements
 * exactly f8, i4, i8 or u1, rank 1 to PROTO_MAX_NDIM, at most max_bytes,
 * values as they are (NaN included: a state may hold "not yet" NaNs).
 * *data is malloc'ed (caller frees); *a describes it (data = *data), named
 * by obj's last element. */
int proto_h5in_read_array(proto_h5in *f, const char *obj, size_t max_bytes,
                          proto_array *a, void **data, proto_err *err);

/* XDMF companion: describes snapshot groups of the HDF5 file so ParaView can
 * open them as a time series. Points (grains) or tetrahedra (a mesh). */
typedef struct proto_xdmf proto_xdmf;
typedef enum { PROTO_XDMF_POINTS, PROTO_XDMF_TET4, PROTO_XDMF_TET10,
               PROTO_XDMF_TRI3 } proto_xdmf_topology;
/* h5_name is the HDF5 file name as seen from the XDMF file (same folder). */
proto_xdmf *proto_xdmf_open(const char *path, const char *h5_name,
                            proto_err *err);
/* One time step. geometry: "<group>/x" dataset path ([n,3]); cells: a
 * dataset path of connectivity ([m,4]/[m,10]/[m,3], i4) or NULL for points;
 * attrs: dataset paths with their names taken from the last path element,
 * node-centred if their first dimension is n, else cell-centred. */
int proto_xdmf_step(proto_xdmf *x, const char *grid_name, double t,
                    proto_xdmf_topology topo, int64_t n_nodes,
                    const char *geometry, int64_t n_cells, const char *cells,
                    int n_attrs, const char *const *attrs,
                    const int64_t *attr_cols /* 1 scalar, 3 vector, 6/9 tensor */,
                    const int64_t *attr_rows);
/* Continues an XDMF file this layer wrote: its grids later than t_keep are
 * dropped (a restart recomputes them). A missing file is created. */
proto_xdmf *proto_xdmf_resume(const char *path, const char *h5_name, double t_keep,
                              proto_err *err);
/* Rewrites the closing tags so the file is valid after every step. */
int proto_xdmf_close(proto_xdmf *x);

#endif
