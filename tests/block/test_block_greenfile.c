/* cosim_green writes rectangular elements and contact_block reads them
 * (issue 14; green/FORMATS.md, one writer, one reader): `cosim_green green
 * --model love|layer --elements 6x4 --size 1.5e-3x1e-3` gives the same
 * coefficients as the library computes in-process, a block of other element
 * sizes refuses the file, and a quasi-static step runs on the layer file. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "blk_test.h"
#include "contact_block/blk.h"
#include "green/green.h"

static proto_err err;

enum { NX = 6, NY = 4 };
static const double DX = 1.5e-3, DY = 1e-3;

static void make(const char *model, const char *path) {
  char cmd[1024];
  snprintf(cmd, sizeof cmd, "%s green --model %s --elements %dx%d --size %gx%g --E 1e7 "
           "--nu 0.3 --thickness 0.01 --out %s 2>/dev/null", COSIM_GREEN_EXE, model, NX, NY,
           DX, DY, path);
  CHECK(system(cmd) == 0, "%s failed", cmd);
}

int main(void) {
  const grn_grid g = {NX, NY, DX, DY};
  const int nk = (2 * NX - 1) * (2 * NY - 1);
  static double ref[(2 * NX - 1) * (2 * NY - 1)];
  const char *models[] = {"love", "layer"};
  for (int k = 0; k < 2; k++) {
    const char *path = k ? "/tmp/blk_test_green_layer.h5" : "/tmp/blk_test_green_love.h5";
    make(models[k], path);
    if (k == 0) grn_static_love(&g, 1e7, 0.3, ref);
    else OK(grn_static_layer(&g, 0.01, 1e7, 0.3, 0, ref, &err));
    blk_model m;
    OK(blk_model_init(&m, NX, NY, DX, DY, &err));
    OK(blk_green_load(&m, path, &err));
    double d = 0;
    for (int o = 0; o < nk; o++) d = fmax(d, fabs(m.g_static[o] - ref[o]));
    printf("%s file, %d x %d elements of %g x %g m: max difference to the library %.1e m/N\n",
           models[k], NX, NY, DX, DY, d);
    CHECK(d == 0.0, "%s: file differs from the library by %g", models[k], d);
    if (k == 1) { /* a quasi-static step on the layer */
      OK(blk_road_paraboloid(&m, 0.05, &err));
      OK(blk_springs_rigid(&m, &err));
      m.solver.quasi_static = 1;
      blk_state s;
      OK(blk_state_create(&m, &s, &err));
      OK(blk_step(&m, &s, 2e-5, &err));
      printf("layer, quasi-static step: F %.4g N, %d in contact\n", s.total_force, s.n_contact);
      CHECK(s.converged && s.total_force > 0, "layer step: F %g", s.total_force);
      blk_state_free(&s);
    }
    blk_model_free(&m);
    /* square elements of the same grid refuse the rectangular file */
    OK(blk_model_init(&m, NX, NY, DX, DX, &err));
    CHECK(blk_green_load(&m, path, &err) == -1 && strstr(err.msg, "grid.dx"),
          "square block loaded a rectangular file (%s)", err.msg);
    blk_model_free(&m);
    remove(path);
  }
  return cosim_test_done("test_block_greenfile");
}
