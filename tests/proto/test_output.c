/* test_output.c — HDF5 series/arrays/attributes and the XDMF companion file:
 * writes through proto_h5_* / proto_xdmf_*, reads back with the HDF5 API. */
#include "cosim_test.h"
#include "proto/proto.h"

#include <hdf5.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static char dir[64];

static void path_in(char *out, size_t cap, const char *name) {
  snprintf(out, cap, "%s/%s", dir, name);
}

/* Reads a whole dataset as the given memory type; returns its rank. */
static int read_dset(hid_t file, const char *path, hid_t mtype, void *buf,
                     hsize_t *dims) {
  hid_t d = H5Dopen2(file, path, H5P_DEFAULT);
  if (d < 0) return -1;
  hid_t s = H5Dget_space(d);
  int rank = H5Sget_simple_extent_dims(s, dims, NULL);
  if (buf && H5Dread(d, mtype, H5S_ALL, H5S_ALL, H5P_DEFAULT, buf) < 0)
    rank = -1;
  H5Sclose(s);
  H5Dclose(d);
  return rank;
}

/* Reads string attribute element `index` of obj_path into out. */
static int read_str_attr(hid_t file, const char *obj_path, const char *name,
                         int index, char *out, size_t cap) {
  hid_t o = H5Oopen(file, obj_path, H5P_DEFAULT);
  if (o < 0) return -1;
  hid_t a = H5Aopen(o, name, H5P_DEFAULT);
  hid_t s = H5Aget_space(a);
  hssize_t n = H5Sget_simple_extent_npoints(s);
  hid_t t = H5Tcopy(H5T_C_S1);
  H5Tset_size(t, H5T_VARIABLE);
  H5Tset_cset(t, H5T_CSET_UTF8);
  char **v = calloc((size_t)n, sizeof *v);
  int rc = -1;
  if (index < n && H5Aread(a, t, v) >= 0) {
    snprintf(out, cap, "%s", v[index]);
    rc = (int)n;
    H5Dvlen_reclaim(t, s, H5P_DEFAULT, v);
  }
  free(v);
  H5Tclose(t);
  H5Sclose(s);
  H5Aclose(a);
  H5Oclose(o);
  return rc;
}

static void test_write(const char *h5path) {
  proto_err err = {{0}};
  proto_h5 *f = proto_h5_create(h5path, &err);
  CHECK(f != NULL);
  if (!f) return;

  CHECK(proto_h5_attr_str(f, "/", "config", "{\"dt\": 1e-4}", &err) == 0);
  CHECK(proto_h5_attr_str(f, "/dem", "note", "made on demand", &err) == 0);
  CHECK(proto_h5_attr_str(f, "/dem", "note", "replaced", &err) == 0);
  CHECK(proto_h5_attr_f8(f, "/dem", "dx", 2.5e-4, &err) == 0);
  CHECK(proto_h5_attr_i8(f, "/dem", "seed", INT64_C(1) << 40, &err) == 0);
  CHECK(proto_h5_attr_i8(f, "/dem", "seed", 7, &err) == 0); /* replaced */
  CHECK(proto_h5_attr_f8(f, "/dem", "", 1, &err) == -1 && strstr(err.msg, "a name"));

  /* 600 rows cross two buffer boundaries; the rest waits for close. */
  const char *cols[] = {"t", "kinetic_energy", "contacts"};
  proto_series *s = proto_h5_series(f, "/dem/series", 3, cols, &err);
  CHECK(s != NULL);
  for (int i = 0; s && i < 600; i++) {
    double row[3] = {i * 0.5, i * i, -i};
    CHECK(proto_series_append(s, row, &err) == 0);
  }
  CHECK(proto_series_rows(s) == 600);

  /* A second series in a deeper, not yet existing group; flushed mid-way. */
  const char *one[] = {"t"};
  proto_series *s2 = proto_h5_series(f, "coupler/deep/traction", 1, one, &err);
  CHECK(s2 != NULL);
  double v = 1.0;
  CHECK(proto_series_append(s2, &v, &err) == 0);
  CHECK(proto_h5_flush(f, &err) == 0);
  v = 2.0;
  CHECK(proto_series_append(s2, &v, &err) == 0);
  CHECK(proto_series_rows(s2) == 2);

  /* Every dtype, ranks 1..3, parents made as needed. */
  double x[4][3];
  for (int i = 0; i < 12; i++) x[i / 3][i % 3] = i + 0.25;
  int32_t tets[2][2][2] = {{{1, 2}, {3, 4}}, {{5, 6}, {7, -8}}};
  int64_t big[2] = {INT64_C(1) << 40, -3};
  uint8_t bytes[5] = {0, 1, 2, 254, 255};
  proto_array arrs[4] = {
      {.name = "x", .dtype = PROTO_F8, .ndim = 2, .shape = {4, 3}, .data = x,
       .nbytes = sizeof x},
      {.name = "tets", .dtype = PROTO_I4, .ndim = 3, .shape = {2, 2, 2},
       .data = tets, .nbytes = sizeof tets},
      {.name = "ids", .dtype = PROTO_I8, .ndim = 1, .shape = {2}, .data = big,
       .nbytes = sizeof big},
      {.name = "flags", .dtype = PROTO_U1, .ndim = 1, .shape = {5},
       .data = bytes, .nbytes = sizeof bytes},
  };
  for (int i = 0; i < 4; i++)
    CHECK(proto_h5_write_array(f, "/dem/steps/12", &arrs[i], &err) == 0);
  CHECK(proto_h5_write_array(f, "/dem/steps/12", &arrs[0], &err) == 0); /* replace */
  proto_array empty = {.name = "none", .dtype = PROTO_F8, .ndim = 2,
                       .shape = {0, 3}, .data = NULL, .nbytes = 0};
  CHECK(proto_h5_write_array(f, "/dem/steps/12", &empty, &err) == 0);

  /* Errors name the path and leave the file usable. */
  CHECK(proto_h5_series(f, "/dem/series", 3, cols, &err) == NULL);
  CHECK(strstr(err.msg, "/dem/series") && strstr(err.msg, "already exists"));
  proto_array bad = arrs[0];
  bad.nbytes = 8;
  CHECK(proto_h5_write_array(f, "/dem/steps/13", &bad, &err) == -1);
  CHECK(strstr(err.msg, "/dem/steps/13/x") != NULL);
  bad = arrs[0];
  bad.ndim = 4;
  CHECK(proto_h5_write_array(f, "/dem", &bad, &err) == -1);
  CHECK(strstr(err.msg, "ndim") != NULL);
  err.msg[0] = '\0';
  CHECK(proto_h5_write_array(f, "/dem/series/sub", &arrs[0], &err) == -1);
  CHECK(strstr(err.msg, "/dem/series") != NULL);
  CHECK(proto_h5_series(f, "/x", 0, cols, &err) == NULL);

  CHECK(proto_h5_close(f, &err) == 0);

  CHECK(proto_h5_create("/nonexistent-dir/r.h5", &err) == NULL);
  CHECK(strstr(err.msg, "/nonexistent-dir/r.h5") != NULL);
}

static void test_read(const char *h5path) {
  hid_t f = H5Fopen(h5path, H5F_ACC_RDONLY, H5P_DEFAULT);
  CHECK(f >= 0);
  if (f < 0) return;
  char str[128];
  hsize_t dims[3];

  CHECK(read_str_attr(f, "/", "config", 0, str, sizeof str) == 1);
  CHECK(strcmp(str, "{\"dt\": 1e-4}") == 0);
  CHECK(read_str_attr(f, "/dem", "note", 0, str, sizeof str) == 1);
  CHECK(strcmp(str, "replaced") == 0);

  static double rows[600][3];
  CHECK(read_dset(f, "/dem/series", H5T_NATIVE_DOUBLE, rows, dims) == 2);
  CHECK(dims[0] == 600 && dims[1] == 3);
  int ok = 1;
  for (int i = 0; i < 600; i++)
    ok &= rows[i][0] == i * 0.5 && rows[i][1] == i * i && rows[i][2] == -i;
  CHECK(ok);
  CHECK(read_str_attr(f, "/dem/series", "columns", 1, str, sizeof str) == 3);
  CHECK(strcmp(str, "kinetic_energy") == 0);

  double t2[2];
  CHECK(read_dset(f, "/coupler/deep/traction", H5T_NATIVE_DOUBLE, t2, dims) == 2);
  CHECK(dims[0] == 2 && dims[1] == 1 && t2[0] == 1.0 && t2[1] == 2.0);

  double x[4][3];
  CHECK(read_dset(f, "/dem/steps/12/x", H5T_NATIVE_DOUBLE, x, dims) == 2);
  CHECK(dims[0] == 4 && dims[1] == 3 && x[3][2] == 11.25);
  int32_t tets[8];
  CHECK(read_dset(f, "/dem/steps/12/tets", H5T_NATIVE_INT32, tets, dims) == 3);
  CHECK(dims[2] == 2 && tets[7] == -8);
  int64_t big[2];
  CHECK(read_dset(f, "/dem/steps/12/ids", H5T_NATIVE_INT64, big, dims) == 1);
  CHECK(big[0] == INT64_C(1) << 40 && big[1] == -3);
  uint8_t bytes[5];
  CHECK(read_dset(f, "/dem/steps/12/flags", H5T_NATIVE_UINT8, bytes, dims) == 1);
  CHECK(dims[0] == 5 && bytes[4] == 255);
  CHECK(read_dset(f, "/dem/steps/12/none", H5T_NATIVE_DOUBLE, NULL, dims) == 2);
  CHECK(dims[0] == 0 && dims[1] == 3);
  CHECK(H5Lexists(f, "/dem/steps/13", H5P_DEFAULT) == 0);
  H5Fclose(f);
}

static char *slurp(const char *path) {
  FILE *fp = fopen(path, "rb");
  if (!fp) return NULL;
  static char buf[1 << 16];
  size_t n = fread(buf, 1, sizeof buf - 1, fp);
  buf[n] = '\0';
  fclose(fp);
  return buf;
}

static int count(const char *s, const char *what) {
  int n = 0;
  for (const char *p = s; (p = strstr(p, what)); p++) n++;
  return n;
}

static const char TAIL[] = "    </Grid>\n  </Domain>\n</Xdmf>\n";

static int ends_with_tail(const char *s) {
  size_t n = strlen(s), k = strlen(TAIL);
  return n >= k && strcmp(s + n - k, TAIL) == 0;
}

static void test_xdmf(const char *xpath) {
  proto_err err = {{0}};
  proto_xdmf *x = proto_xdmf_open(xpath, "results.h5", &err);
  CHECK(x != NULL);
  if (!x) return;
  const char *s = slurp(xpath);
  CHECK(s && ends_with_tail(s) && count(s, "<Grid ") == 1);

  const char *attrs[] = {"/dem/steps/0/v", "/dem/steps/0/r"};
  int64_t cols[] = {3, 1}, nrows[] = {100, 100};
  CHECK(proto_xdmf_step(x, "grains", 0.0, PROTO_XDMF_POINTS, 100,
                        "/dem/steps/0/x", 0, NULL, 2, attrs, cols, nrows) == 0);
  s = slurp(xpath);
  CHECK(s && ends_with_tail(s) && count(s, "<Grid ") == 2);
  CHECK(strstr(s, "TopologyType=\"Polyvertex\" NumberOfElements=\"100\""));
  CHECK(strstr(s, "Dimensions=\"100 3\" NumberType=\"Float\" Precision=\"8\" "
                  "Format=\"HDF\">results.h5:/dem/steps/0/v</DataItem>"));
  CHECK(strstr(s, "Name=\"r\" AttributeType=\"Scalar\" Center=\"Node\""));

  const char *fattrs[] = {"/fem/steps/1/u", "/fem/steps/1/strain"};
  int64_t fcols[] = {3, 6}, frows[] = {50, 20};
  CHECK(proto_xdmf_step(x, "tread<1>", 1e-3, PROTO_XDMF_TET10, 50,
                        "/fem/steps/1/x", 20, "/fem/steps/1/cells", 2, fattrs,
                        fcols, frows) == 0);
  /* Bad calls fail without touching the file. */
  CHECK(proto_xdmf_step(x, "bad", 0, PROTO_XDMF_TET4, 4, "/x", 1, NULL, 0, NULL,
                        NULL, NULL) == -1);
  CHECK(proto_xdmf_close(x) == 0);
  s = slurp(xpath);
  CHECK(s && ends_with_tail(s) && count(s, "<Grid ") == 3);
  CHECK(count(s, "</Xdmf>") == 1);
  CHECK(strstr(s, "Name=\"tread&lt;1&gt;\""));
  CHECK(strstr(s, "TopologyType=\"Tetrahedron_10\" NumberOfElements=\"20\""));
  CHECK(strstr(s, "Dimensions=\"20 10\" NumberType=\"Int\" Precision=\"4\""));
  CHECK(strstr(s, "Name=\"strain\" AttributeType=\"Tensor6\" Center=\"Cell\""));
  CHECK(strstr(s, "<Time Value=\"0.001\"/>"));

  CHECK(proto_xdmf_open("/nonexistent-dir/r.xdmf", "r.h5", &err) == NULL);
  CHECK(strstr(err.msg, "/nonexistent-dir/r.xdmf") != NULL);
}

typedef struct names {
  int n;
  char name[8][16];
} names;

static int collect(const char *name, void *ctx) {
  names *c = ctx;
  if (c->n == 8) return -1;
  snprintf(c->name[c->n++], sizeof c->name[0], "%s", name);
  return 0;
}

/* What test_write wrote, back through the HDF5 input layer: every dtype
 * bit for bit, the members in name order, attributes; its limits. */
static void test_h5in(const char *h5path) {
  proto_err err = {{0}};
  proto_h5in *f = proto_h5in_open(h5path, &err);
  CHECK(f != NULL);
  if (!f) return;
  names c = {0};
  CHECK(proto_h5in_list(f, "/dem/steps/12", collect, &c, &err) == 0);
  CHECK(c.n == 5 && !strcmp(c.name[0], "flags") && !strcmp(c.name[1], "ids") &&
        !strcmp(c.name[2], "none") && !strcmp(c.name[3], "tets") && !strcmp(c.name[4], "x"));
  static const struct { const char *name; proto_dtype dtype; int ndim; int64_t shape0; size_t nbytes; }
      want[5] = {{"flags", PROTO_U1, 1, 5, 5}, {"ids", PROTO_I8, 1, 2, 16},
                 {"none", PROTO_F8, 2, 0, 0}, {"tets", PROTO_I4, 3, 2, 32},
                 {"x", PROTO_F8, 2, 4, 96}};
  for (int i = 0; i < 5; i++) {
    char obj[64];
    snprintf(obj, sizeof obj, "/dem/steps/12/%s", want[i].name);
    proto_array a;
    void *data = NULL;
    CHECK(proto_h5in_read_array(f, obj, 1 << 20, &a, &data, &err) == 0);
    CHECK(!strcmp(a.name, want[i].name) && a.dtype == want[i].dtype &&
          a.ndim == want[i].ndim && a.shape[0] == want[i].shape0 &&
          a.nbytes == want[i].nbytes && a.data == data);
    free(data);
  }
  proto_array a;
  void *data = NULL;
  CHECK(proto_h5in_read_array(f, "/dem/steps/12/x", 1 << 20, &a, &data, &err) == 0);
  CHECK(data && ((const double *)data)[11] == 11.25 && a.shape[1] == 3);
  free(data);
  CHECK(proto_h5in_read_array(f, "/dem/steps/12/ids", 1 << 20, &a, &data, &err) == 0);
  CHECK(data && ((const int64_t *)data)[0] == INT64_C(1) << 40 && ((const int64_t *)data)[1] == -3);
  free(data);
  CHECK(proto_h5in_read_array(f, "/dem/steps/12/x", 95, &a, &data, &err) == -1);
  CHECK(data == NULL && strstr(err.msg, "/dem/steps/12/x: shape") && strstr(err.msg, "holds more than the 11"));
  CHECK(proto_h5in_read_array(f, "/dem/steps/12", 1 << 20, &a, &data, &err) == -1);
  CHECK(strstr(err.msg, "/dem/steps/12: not a dataset"));
  CHECK(proto_h5in_read_array(f, "/dem/steps/9/x", 1 << 20, &a, &data, &err) == -1);
  CHECK(strstr(err.msg, h5path) && strstr(err.msg, "/dem/steps/9/x: dataset missing"));
  CHECK(proto_h5in_list(f, "/dem/steps/9", collect, &c, &err) == -1);
  CHECK(strstr(err.msg, "/dem/steps/9: group missing"));
  CHECK(proto_h5in_list(f, "/dem/steps/12/x", collect, &c, &err) == -1);
  CHECK(strstr(err.msg, "/dem/steps/12/x: not a group"));
  char *config = NULL;
  CHECK(proto_h5in_attr_strdup(f, "/", "config", &config, &err) == 0);
  CHECK(config && !strcmp(config, "{\"dt\": 1e-4}"));
  free(config);
  CHECK(proto_h5in_attr_strdup(f, "/", "absent", &config, &err) == 1 && config == NULL);
  double v = 0;
  CHECK(proto_h5in_attr_f8(f, "/dem", "dx", &v, &err) == 0 && v == 2.5e-4);
  CHECK(proto_h5in_attr_f8(f, "/dem", "seed", &v, &err) == 0 && v == 7);
  proto_h5in_close(f);
}

int main(void) {
  snprintf(dir, sizeof dir, "/tmp/cosim_test_output_XXXXXX");
  if (!mkdtemp(dir)) {
    perror("mkdtemp");
    return 1;
  }
  char h5path[128], xpath[128];
  path_in(h5path, sizeof h5path, "results.h5");
  path_in(xpath, sizeof xpath, "results.xdmf");
  test_write(h5path);
  test_read(h5path);
  test_h5in(h5path);
  test_xdmf(xpath);
  if (getenv("KEEP_OUTPUT")) {
    printf("%s\n", dir);
  } else {
    unlink(h5path);
    unlink(xpath);
    rmdir(dir);
  }
  return cosim_test_done("test_output");
}
