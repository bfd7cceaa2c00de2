/* fuzz_msh — the Gmsh MSH 4.1 reader (ASCII and binary) on any bytes, and
 * the mesh checks after it. */
#include "fem_server/fem.h"
#include "fuzz.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  const char *path = fuzz_file(data, size, ".msh");
  if (!path) return 0;
  fem_mesh m;
  proto_err err = {{0}};
  if (fem_msh_read(path, &m, &err) == 0) fem_mesh_free(&m);
  return 0;
}
