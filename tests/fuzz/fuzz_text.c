/* fuzz_text — the plain-text inputs of cosim_green: a road height grid
 * (grn_surface_read_text) and a material table (grn_material_load). The
 * first byte picks the reader, the rest is the file. */
#include "fuzz.h"
#include "green/green.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  if (size < 1) return 0;
  const char *path = fuzz_file(data + 1, size - 1, ".txt");
  if (!path) return 0;
  proto_err err = {{0}};
  if (data[0] % 2 == 0) {
    grn_surface s;
    if (grn_surface_read_text(path, 0, 0, &s, &err) == 0) grn_surface_free(&s);
  } else {
    grn_material m;
    grn_material_default(&m);
    if (grn_material_load(&m, path, &err) == 0) grn_material_check(&m, &err);
  }
  if (getenv("COSIM_FUZZ_VERBOSE")) fprintf(stderr, "%s\n", err.msg[0] ? err.msg : "ok");
  return 0;
}
