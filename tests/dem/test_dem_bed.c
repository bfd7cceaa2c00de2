/* A bed saved by dem_bed_save reloads as is: a settled bed has overlaps
 * beyond overlap_tolerance (its weight compresses it), and the file records
 * the largest, which loading accepts. The same grains in a file that does not
 * record it (made by hand), or with a grain moved into another, are refused
 * with a message naming the grains. */
#include "dem_test.h"
#include <hdf5.h>
#include <string.h>
#include <unistd.h>

#define MAT "\"materials\":[{\"density\":2600,\"E\":1e6,\"nu\":0.3,\"restitution\":0.5,\"friction\":0.6}]"
#define BOX "\"walls\":[{\"type\":\"box\",\"lo\":[0,0,0],\"hi\":[0.1414213562,0.1414213562,1],\"open_top\":true}]"

static int load(const char *path, char *msg) {
  char json[1024];
  snprintf(json, sizeof json, "{" MAT "," BOX ",\"dt\":5e-5,\"particles\":{\"file\":\"%s\"}}", path);
  dem_model m;
  dem_state s;
  proto_err err = {{0}};
  cJSON *j = cJSON_Parse(json);
  int rc = dem_model_from_json(&m, j, "processes.dem", &err);
  if (!rc) {
    rc = dem_state_init(&m, &s, 0, &err);
    if (!rc) dem_state_free(&s);
    dem_model_free(&m);
  }
  cJSON_Delete(j);
  snprintf(msg, 1024, "%s", rc ? err.msg : "(accepted)");
  return rc;
}

/* Opens the file for editing a dataset in place. */
static void edit(const char *path, const char *name, void (*fn)(double *), int n, int cols) {
  hid_t f = H5Fopen(path, H5F_ACC_RDWR, H5P_DEFAULT), ds = H5Dopen2(f, name, H5P_DEFAULT);
  double *a = malloc(sizeof(double) * n * cols);
  H5Dread(ds, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, a);
  fn(a);
  H5Dwrite(ds, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, a);
  free(a);
  H5Dclose(ds);
  H5Fclose(f);
}

static void move_grain_0_onto_1(double *x) {
  for (int k = 0; k < 3; k++) x[k] = x[3 + k] + (k == 0 ? 1e-3 : 0);
}

int main(void) {
  dem_model m;
  dem_state s;
  proto_err err;
  scene("{" MAT "," BOX ",\"dt\":5e-5,\"particles\":{\"generate\":\"bed\",\"scale\":0.02,\"seed\":3}}", &m, &s);
  CHECK(dem_settle(&m, &s, 1e-9, 6000, NULL, NULL, &err) == 0, "settling: %s", err.msg);
  char path[] = "/tmp/test_dem_settled_XXXXXX";
  close(mkstemp(path));
  CHECK(dem_bed_save(&m, &s, path, &err) == 0, "save: %s", err.msg);
  const int n = m.n_grains;
  printf("%d grains settled in %lld steps, KE %.3g J, largest overlap %.4g (overlap_tolerance %.3g)\n", n,
         (long long)s.step, s.kinetic_energy, s.max_overlap_ratio, m.overlap_tolerance);
  CHECK(s.max_overlap_ratio > m.overlap_tolerance, "the settled bed has no overlap beyond the tolerance: tests nothing");
  dem_state_free(&s);
  dem_model_free(&m);
  char msg[1024];
  int rc = load(path, msg);
  printf("reload of the saved bed        -> %s\n", msg);
  CHECK(rc == 0, "a saved settled bed is refused: %s", msg);
  /* the same grains, a file without the record: refused as before */
  hid_t f = H5Fopen(path, H5F_ACC_RDWR, H5P_DEFAULT);
  H5Ldelete(f, "max_overlap", H5P_DEFAULT);
  H5Fclose(f);
  rc = load(path, msg);
  printf("same grains, no max_overlap    -> %s\n", msg);
  CHECK(rc != 0 && strstr(msg, "overlap") && strstr(msg, "overlap_tolerance 0.01"), "hand-made file accepted: %s", msg);
  /* a saved bed with a grain moved into another: refused, naming the record */
  char json[512];
  snprintf(json, sizeof json, "{" MAT "," BOX ",\"dt\":5e-5,\"particles\":{\"file\":\"%s\"}}", path);
  scene("{" MAT "," BOX ",\"dt\":5e-5,\"particles\":{\"generate\":\"bed\",\"scale\":0.02,\"seed\":3}}", &m, &s);
  dem_settle(&m, &s, 1e-9, 6000, NULL, NULL, &err);
  dem_bed_save(&m, &s, path, &err);
  dem_state_free(&s);
  dem_model_free(&m);
  edit(path, "x", move_grain_0_onto_1, n, 3);
  rc = load(path, msg);
  printf("saved bed, grain 0 moved       -> %s\n", msg);
  CHECK(rc != 0 && strstr(msg, "grains 0 and 1 overlap") && strstr(msg, "the bed file records"),
        "tampered bed accepted or message unclear: %s", msg);
  unlink(path);
  return cosim_test_done("test_dem_bed");
}
