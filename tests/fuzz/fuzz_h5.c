/* fuzz_h5 — the HDF5 readers (road heights, Green's functions, springs,
 * saved beds with their saved state, checkpoints), structure-aware: the
 * input is a small text that describes a file; the harness writes that file with the HDF5 library and runs the
 * reader on it. Mutating the description reaches every shape, type,
 * attribute and value case of our readers (raw-byte mutations of an HDF5
 * file mostly exercise the HDF5 library's own parser instead).
 *
 *   reader road|green|springs|bed|checkpoint
 *   grid NX NY DX DY                   the block's grid (green, springs)
 *   group PATH
 *   dset PATH TYPE D1 [D2 ...] FILL    TYPE f8 f4 i4 i8 u1 str; FILL
 *                                      const V | ramp A B | col A B | nan |
 *                                      inf | none (not written: fill value)
 *   attr OBJ NAME TYPE N V|TEXT        TYPE f8 i4 str vstr; N values (0 = null
 *                                      dataspace, -1 = scalar)
 *
 * A checkpoint is read against CHECKPOINT_SCENE: the seed's root attribute
 * "config" is that text, so the reader gets past its scene check.
 *
 * Shapes are kept either small (data written) or beyond every reader's
 * limit (not written, so they cost the file nothing): the band in between,
 * legal but larger than the fuzzer's memory limit, is not generated. */
#include <hdf5.h>
#include <math.h>

#include "contact_block/blk.h"
#include "coupler/runner.h"
#include "dem_server/dem.h"
#include "fuzz.h"
#include "green/green.h"

enum { MAX_RANK = 4, MAX_WRITTEN = 1 << 16, MAX_LINE = 512 };
enum { R_ROAD, R_GREEN, R_SPRINGS, R_BED, R_CHECKPOINT, N_READERS };
static const char *const readers[N_READERS] = {"road", "green", "springs", "bed",
                                               "checkpoint"};

/* The scene a checkpoint is read against (two spring blocks; one line, as
 * the seed's config attribute holds it). */
#define CHECKPOINT_SCENE                                                               \
  "{\"name\": \"f\", \"time\": {\"dt\": 1e-05, \"end\": 0.01}, \"output\": "         \
  "{\"dir\": \"f\", \"every\": 10}, \"scenario\": {\"kind\": \"indentation\", "         \
  "\"profile\": \"linear\", \"depth\": 1e-05, \"ramp_time\": 0.01}, \"processes\": "   \
  "{\"left\": {\"exec\": \"block_stub\"}, \"right\": {\"exec\": \"block_stub\"}}}"

static const cpl_scene *checkpoint_scene(void) {
  static cpl_scene s; /* parsed once, kept for the process's life */
  static int state = 0; /* 0 not yet, 1 parsed, -1 failed */
  if (state == 0) {
    proto_err err = {{0}};
    cJSON *root = proto_json_parse(CHECKPOINT_SCENE, "fuzz scene", &err);
    state = root && cpl_scene_from_json(&s, root, "fuzz scene", 0, NULL, &err) == 0 ? 1 : -1;
    if (state < 0) fprintf(stderr, "fuzz_h5: the checkpoint scene: %s\n", err.msg);
  }
  return state > 0 ? &s : NULL;
}

typedef struct grid {
  int nx, ny;
  double dx, dy;
} grid;

static hid_t file_type(const char *t) {
  return !strcmp(t, "f8") ? H5T_IEEE_F64LE : !strcmp(t, "f4") ? H5T_IEEE_F32LE
       : !strcmp(t, "i4") ? H5T_STD_I32LE  : !strcmp(t, "i8") ? H5T_STD_I64LE
       : !strcmp(t, "u1") ? H5T_STD_U8LE   : -1;
}

static double fill_value(const char *mode, double a, double b, uint64_t k,
                         uint64_t last) {
  if (!strcmp(mode, "ramp")) return a + b * (double)k;
  if (!strcmp(mode, "col")) return a + b * (double)(k % (last ? last : 1));
  if (!strcmp(mode, "nan")) return k == 3 ? NAN : a;
  if (!strcmp(mode, "inf")) return k == 1 ? INFINITY : a;
  return a;
}

/* "dset PATH TYPE D1 .. Dr FILL [A [B]]" */
static void make_dataset(hid_t f, char *args) {
  char *path = strtok(args, " "), *type = strtok(NULL, " ");
  if (!path || !type) return;
  hsize_t dims[MAX_RANK];
  int rank = 0;
  char *tok;
  uint64_t n = 1;
  int over = 0;
  while ((tok = strtok(NULL, " ")) && rank < MAX_RANK && (tok[0] >= '0' && tok[0] <= '9')) {
    unsigned long long v = strtoull(tok, NULL, 10);
    dims[rank++] = (hsize_t)v;
    over |= __builtin_mul_overflow(n, (uint64_t)v, &n);
  }
  if (rank == 0 || (dims[0] > 0 && n == 0 && !over)) return;
  const char *mode = tok ? tok : "none";
  char *sa = strtok(NULL, " "), *sb = strtok(NULL, " ");
  double a = sa ? strtod(sa, NULL) : 0, b = sb ? strtod(sb, NULL) : 0;
  int write = strcmp(mode, "none") != 0 && !over && n <= MAX_WRITTEN;
  if (!write && !over && n > 1 && n <= ((uint64_t)1 << 36)) return; /* the band */
  hid_t sp = H5Screate_simple(rank, dims, NULL);
  hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
  if (!write) { /* never allocated: chunked, storage made only when written */
    hsize_t chunk[MAX_RANK];
    for (int i = 0; i < rank; i++) chunk[i] = 1;
    H5Pset_chunk(dcpl, rank, chunk);
  }
  int is_str = !strcmp(type, "str");
  hid_t ft = is_str ? H5Tcopy(H5T_C_S1) : file_type(type);
  if (is_str) H5Tset_size(ft, 8);
  hid_t ds = ft >= 0 ? H5Dcreate2(f, path, ft, sp, H5P_DEFAULT, dcpl, H5P_DEFAULT) : -1;
  if (ds >= 0 && write && n > 0) {
    if (is_str) {
      char *buf = calloc(n, 8);
      for (uint64_t k = 0; buf && k < n; k++) memcpy(buf + 8 * k, "1.5e-3\0", 8);
      H5Dwrite(ds, ft, H5S_ALL, H5S_ALL, H5P_DEFAULT, buf);
      free(buf);
    } else {
      double *buf = malloc(n * sizeof *buf);
      for (uint64_t k = 0; buf && k < n; k++)
        buf[k] = fill_value(mode, a, b, k, dims[rank - 1]);
      if (buf) H5Dwrite(ds, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, buf);
      free(buf);
    }
  }
  if (ds >= 0) H5Dclose(ds);
  if (is_str) H5Tclose(ft);
  H5Pclose(dcpl);
  H5Sclose(sp);
}

/* "attr OBJ NAME TYPE N VALUE" */
static void make_attr(hid_t f, char *args) {
  char *obj = strtok(args, " "), *name = strtok(NULL, " "), *type = strtok(NULL, " ");
  char *sn = strtok(NULL, " "), *value = strtok(NULL, "");
  if (!obj || !name || !type || !sn) return;
  long n = strtol(sn, NULL, 10);
  if (n > 64) n = 64;
  if (!value) value = "0";
  hsize_t dims[1] = {(hsize_t)(n > 0 ? n : 1)};
  hid_t sp = n < 0 ? H5Screate(H5S_SCALAR) : n == 0 ? H5Screate(H5S_NULL)
                                                   : H5Screate_simple(1, dims, NULL);
  hid_t o = H5Oopen(f, obj, H5P_DEFAULT);
  if (o >= 0) {
    if (!strcmp(type, "str") || !strcmp(type, "vstr")) {
      hid_t t = H5Tcopy(H5T_C_S1);
      int vlen = !strcmp(type, "vstr");
      H5Tset_size(t, vlen ? H5T_VARIABLE : strlen(value) + 1);
      hid_t a = H5Acreate2(o, name, t, sp, H5P_DEFAULT, H5P_DEFAULT);
      if (a >= 0 && n != 0) {
        const char *ptrs[64];
        char *fixed = calloc((size_t)dims[0], strlen(value) + 1);
        for (hsize_t i = 0; i < dims[0]; i++) {
          ptrs[i] = value;
          if (fixed) memcpy(fixed + i * (strlen(value) + 1), value, strlen(value));
        }
        if (vlen) H5Awrite(a, t, ptrs);
        else if (fixed) H5Awrite(a, t, fixed);
        free(fixed);
      }
      if (a >= 0) H5Aclose(a);
      H5Tclose(t);
    } else {
      hid_t ft = file_type(type);
      hid_t a = ft >= 0 ? H5Acreate2(o, name, ft, sp, H5P_DEFAULT, H5P_DEFAULT) : -1;
      double v[64];
      for (hsize_t i = 0; i < dims[0]; i++) v[i] = strtod(value, NULL);
      if (a >= 0 && n != 0) H5Awrite(a, H5T_NATIVE_DOUBLE, v);
      if (a >= 0) H5Aclose(a);
    }
    H5Oclose(o);
  }
  H5Sclose(sp);
}

/* Builds the described file; returns the reader, or -1. */
static int build(const char *path, char *text, grid *g) {
  hid_t f = H5Fcreate(path, H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  if (f < 0) return -1;
  int reader = -1;
  for (char *line = text; line && *line;) {
    char *nl = strchr(line, '\n');
    if (nl) *nl = 0;
    char buf[MAX_LINE];
    snprintf(buf, sizeof buf, "%s", line);
    line = nl ? nl + 1 : NULL;
    char *rest = strchr(buf, ' ');
    if (!rest) continue;
    *rest++ = 0;
    if (!strcmp(buf, "reader")) {
      for (int r = 0; r < N_READERS; r++)
        if (!strncmp(rest, readers[r], strlen(readers[r]))) reader = r;
    } else if (!strcmp(buf, "grid")) {
      int nx = 0, ny = 0;
      double dx = 0, dy = 0;
      if (sscanf(rest, "%d %d %lf %lf", &nx, &ny, &dx, &dy) == 4 && nx >= 1 && ny >= 1 &&
          nx <= 64 && ny <= 64 && dx > 0 && dy > 0 && isfinite(dx) && isfinite(dy))
        *g = (grid){nx, ny, dx, dy};
    } else if (!strcmp(buf, "group")) {
      hid_t gr = H5Gcreate2(f, rest, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
      if (gr >= 0) H5Gclose(gr);
    } else if (!strcmp(buf, "dset")) {
      make_dataset(f, rest);
    } else if (!strcmp(buf, "attr")) {
      make_attr(f, rest);
    }
  }
  H5Fclose(f);
  return reader;
}

/* A scene that reads the bed, then its saved state into the fresh state
 * (any overlap accepted: the fuzzed positions must reach the state). */
static void bed_continue(const char *path, proto_err *err) {
  char json[512];
  snprintf(json, sizeof json,
           "{\"materials\":[{\"density\":2600,\"E\":5e6,\"nu\":0.3,\"restitution\":0.5,"
           "\"friction\":0.6}],\"dt\":1e-6,\"overlap_tolerance\":1,\"threads\":1,"
           "\"particles\":{\"file\":\"%s\"}}", path);
  cJSON *j = cJSON_Parse(json);
  dem_model m;
  dem_state s;
  dem_bed_info info;
  if (j && dem_model_from_json(&m, j, "processes.dem", err) == 0) {
    if (dem_state_init(&m, &s, 0, err) == 0) {
      dem_bed_continue(&m, &s, &info, err);
      dem_state_free(&s);
    }
    dem_model_free(&m);
  }
  cJSON_Delete(j);
}

static void run(int reader, const char *path, const grid *g) {
  proto_err err = {{0}};
  if (reader == R_ROAD) {
    grn_surface s;
    if (grn_surface_read_h5(path, &s, &err) == 0) {
      double sum = 0; /* every height must be there */
      for (int64_t i = 0; i < (int64_t)s.Nx * s.Ny; i++) sum += s.z[i];
      if (sum != sum) __builtin_trap(); /* the reader refuses NaN */
      grn_surface_free(&s);
    }
  } else if (reader == R_GREEN || reader == R_SPRINGS) {
    blk_model m;
    if (blk_model_init(&m, g->nx, g->ny, g->dx, g->dy, &err) == 0) {
      if (reader == R_GREEN) blk_green_load(&m, path, &err);
      else blk_springs_load(&m, path, &err);
    }
    blk_model_free(&m);
  } else if (reader == R_BED) {
    dem_model m;
    memset(&m, 0, sizeof m);
    const int loaded = dem_bed_load(&m, path, &err) == 0;
    dem_model_free(&m);
    if (loaded) bed_continue(path, &err); /* its saved state: /state (dem_bed_continue) */
  } else if (reader == R_CHECKPOINT) {
    const cpl_scene *sc = checkpoint_scene();
    cpl_ckpt *c = sc ? cpl_checkpoint_read(path, sc, 0, &err) : NULL;
    if (c && cpl_checkpoint_step(c) < 1) __builtin_trap(); /* the reader refuses it */
    cpl_checkpoint_free(c);
  }
  for (const char *c = err.msg; *c; c++)
    if (*c == 0x1b) __builtin_trap();
  if (getenv("COSIM_FUZZ_VERBOSE")) /* for writing seeds: what the reader said */
    fprintf(stderr, "%s: %s\n", readers[reader], err.msg[0] ? err.msg : "ok");
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  static int quiet = 0;
  if (!quiet) { /* the builder's own failures are expected: keep HDF5 quiet */
    H5Eset_auto2(H5E_DEFAULT, NULL, NULL);
    quiet = 1;
  }
  char *text = fuzz_text(data, size);
  if (!text) return 0;
  const char *dir = access("/dev/shm", W_OK) == 0 ? "/dev/shm" : "/tmp";
  char path[256];
  snprintf(path, sizeof path, "%s/cosim-fuzz-%d.h5", dir, (int)getpid());
  grid g = {4, 3, 1e-3, 1e-3};
  int reader = build(path, text, &g);
  if (reader >= 0) run(reader, path, &g);
  unlink(path); /* nothing left in /dev/shm */
  free(text);
  return 0;
}
