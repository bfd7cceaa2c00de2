/* Self-affine surfaces: PSD slope -2(1+H) within 5 %, rms as requested,
 * seed reproducibility, down-sampling to the element maximum, readers and
 * their errors (NaN in a height map). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cosim_test.h"
#include "green/green.h"

int main(void) {
  proto_err err;
  const double Hs[3] = {0.3, 0.6, 0.9};
  for (int k = 0; k < 3; k++) {
    grn_surface_params p = {512, 512, 1e-5, 1e-5, Hs[k], 5e-5, 8e-5, 1.28e-3, 42 + k};
    grn_surface s;
    CHECK(grn_surface_generate(&p, &s, &err) == 0, "%s", err.msg);
    double slope = grn_surface_psd_slope(&s, 2 * M_PI / p.lambda_long, 2 * M_PI / p.lambda_short, &err);
    char what[64];
    snprintf(what, sizeof what, "PSD slope, H = %.1f", Hs[k]);
    CHECK_REL(what, slope, -2 * (1 + Hs[k]), 0.05);
    CHECK_REL("rms", grn_surface_rms(&s), p.rms, 1e-9);
    grn_surface s2;
    CHECK(grn_surface_generate(&p, &s2, &err) == 0, "%s", err.msg);
    CHECK(memcmp(s.z, s2.z, 512 * 512 * sizeof(double)) == 0, "same seed, same surface");
    grn_surface_free(&s2);
    if (k == 0) {
      double zr[16];
      CHECK(grn_surface_downsample_max(&s, 4, 4, zr, &err) == 0, "%s", err.msg);
      double m = -1;
      for (int j = 0; j < 128; j++)
        for (int i = 128; i < 256; i++) m = fmax(m, s.z[j * 512 + i]);
      CHECK(zr[1] == m, "element (1,0) takes its highest point");
      CHECK(grn_surface_downsample_max(&s, 3, 3, zr, &err) == -1, "indivisible grid");
      /* HDF5 round trip */
      CHECK(grn_surface_write_h5("test_green_road.h5", &s, &p, &err) == 0, "%s", err.msg);
      grn_surface r;
      CHECK(grn_surface_read_h5("test_green_road.h5", &r, &err) == 0, "%s", err.msg);
      CHECK(r.Nx == 512 && r.dx == 1e-5 && memcmp(r.z, s.z, 512 * 512 * 8) == 0, "h5 round trip");
      r.z[7 * 512 + 3] = NAN;
      CHECK(grn_surface_write_h5("test_green_nan.h5", &r, NULL, &err) == 0, "%s", err.msg);
      grn_surface_free(&r);
      CHECK(grn_surface_read_h5("test_green_nan.h5", &r, &err) == -1 && strstr(err.msg, "[7][3]"),
            "NaN in HDF5 height map: %s", err.msg);
      printf("error message: %s\n", err.msg);
    }
    grn_surface_free(&s);
  }
  /* text grid */
  FILE *f = fopen("test_green_road.txt", "w");
  fprintf(f, "# dx = 2e-5\n# dy = 3e-5\n1e-6 2e-6 3e-6\n4e-6 5e-6 6e-6\n");
  fclose(f);
  grn_surface t;
  CHECK(grn_surface_read_text("test_green_road.txt", 0, 0, &t, &err) == 0, "%s", err.msg);
  CHECK(t.Nx == 3 && t.Ny == 2 && t.dx == 2e-5 && t.dy == 3e-5 && t.z[4] == 5e-6, "text grid");
  grn_surface_free(&t);
  f = fopen("test_green_nan.txt", "w");
  fprintf(f, "1e-6 2e-6 3e-6\n4e-6 nan 6e-6\n");
  fclose(f);
  CHECK(grn_surface_read_text("test_green_nan.txt", 1e-5, 1e-5, &t, &err) == -1 &&
            strstr(err.msg, ":2: column 2"), "NaN in text height map: %s", err.msg);
  printf("error message: %s\n", err.msg);
  /* bad generator parameters name the key */
  grn_surface_params bad = {64, 64, 1e-5, 1e-5, 1.2, 1e-4, 1e-4, 1e-3, 1};
  CHECK(grn_surface_generate(&bad, &t, &err) == -1 && strstr(err.msg, "hurst"), "bad hurst: %s", err.msg);
  remove("test_green_road.h5");
  remove("test_green_nan.h5");
  remove("test_green_road.txt");
  remove("test_green_nan.txt");
  return cosim_test_done("test_green_surface");
}
