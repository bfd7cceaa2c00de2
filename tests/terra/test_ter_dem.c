/* The virtual soil tests (terra/ter_dem.c) on a few hundred grains of the
 * default scene's soil: they run, the signs are physical, the servo holds
 * the normal stress, nothing leaves the box; the scene reader's errors.
 * (The measurements themselves are bench/terra, results in
 * bench/results/terra.md.) */
#include "cosim_test.h"
#include "terra/terra.h"

static const char SCENE[] =
    "{\"processes\": {\"fem\": {\"exec\": \"fem_server\"}, \"soil\": {\"exec\": \"dem_server\","
    " \"materials\": [{\"density\": 2600, \"E\": 5e6, \"nu\": 0.3, \"restitution\": 0.5, \"friction\": 0.6},"
    "                {\"density\": 1100, \"E\": 20e6, \"nu\": 0.45, \"restitution\": 0.5, \"friction\": 0.8}],"
    " \"particles\": {\"generate\": \"bed\", \"scale\": 0.1}, \"threads\": 1,"
    " \"walls\": [{\"type\": \"box\", \"lo\": [0, 0, 0], \"hi\": [1, 1, 1], \"open_top\": true}],"
    " \"surface_material\": 1, \"gravity\": [0, 0, -9.81]}}}";

static void plate(const ter_dem_soil *soil) {
  proto_err err;
  ter_plate_spec sp;
  ter_plate_defaults(&sp);
  sp.width = 0.04;
  sp.container = 0.12;
  sp.depth_factor = 1;
  sp.speed = 0.1;
  sp.z_max = 0.006;
  sp.settle_max_steps = 3000;
  ter_series t;
  OK(ter_plate_test(soil, &sp, stdout, &t, &err));
  int cz = ter_series_col(&t, "z"), cp = ter_series_col(&t, "p"), ci = ter_series_col(&t, "inertial");
  double p_first = 0, p_last = 0, z_last = 0;
  int n = t.n, third = n / 3;
  for (int r = 0; r < n; r++) {
    const double *row = t.row + (size_t)r * t.ncol;
    if (r < third) p_first += row[cp] / third;
    if (r >= n - third) p_last += row[cp] / third;
    z_last = row[cz];
    CHECK(row[cz] > 0 && row[cz] < sp.z_max, "sinkage %g outside (0, z_max)", row[cz]);
    CHECK(isfinite(row[ci]) || row[cp] <= 0, "inertial number not finite at p = %g", row[cp]);
  }
  double grains = 0;
  OK(ter_series_meta_num(&t, "grains", &grains, &err));
  printf("plate: %d rows, %g grains, p %.4g Pa over the first third, %.4g Pa over the last, z to %.2f mm\n",
         n, grains, p_first, p_last, 1e3 * z_last);
  CHECK(n >= 10 && grains > 200, "%d rows, %g grains", n, grains);
  CHECK(p_last > 0 && p_last > p_first, "pressure must rise with sinkage (%.4g -> %.4g Pa)", p_first, p_last);
  ter_series_free(&t);
  /* prepared: settled with the preparation's laws, then again with the
   * scene's (as dem_server settles a prepared bed), then pushed */
  sp.prep = (ter_prep){.on = 1, .friction = 0.3, .rolling = 0};
  sp.z_max = 0.002;
  FILE *log = tmpfile();
  OK(ter_plate_test(soil, &sp, log, &t, &err));
  char line[512];
  int settles = 0;
  rewind(log);
  while (fgets(line, sizeof line, log)) settles += strstr(line, "grains settled in") != NULL;
  fclose(log);
  const char *what = ter_series_get_meta(&t, "preparation");
  CHECK(settles == 2, "a prepared plate bed settles twice (preparation, scene's laws): %d", settles);
  CHECK(what && strstr(what, "friction 0.3"), "prepared plate: preparation meta '%s'", what ? what : "");
  ter_series_free(&t);
  sp.prep.on = 0;
  sp.container = 0.07;
  FAILS_WITH(ter_plate_test(soil, &sp, NULL, &t, &err), "container > 2 width");
}

static void shear(const ter_dem_soil *soil) {
  proto_err err;
  ter_shear_spec sp;
  ter_shear_defaults(&sp);
  sp.length = sp.width = 0.06;
  sp.height = 0.04;
  sp.sigma_n = 4e3;
  sp.speed = 0.05;
  sp.j_max = 0.008;
  sp.dj = 0.5e-3;
  sp.settle_max_steps = 4000;
  ter_series t;
  OK(ter_shear_test(soil, &sp, stdout, &t, &err));
  int ct = ter_series_col(&t, "tau"), cu = ter_series_col(&t, "tau_upper"), cs = ter_series_col(&t, "sigma");
  double tau = 0, tau_up = 0, sig = 0, lost = -1;
  int m = 0;
  for (int r = t.n / 2; r < t.n; r++, m++) {
    tau += t.row[(size_t)r * t.ncol + ct];
    tau_up += t.row[(size_t)r * t.ncol + cu];
    sig += t.row[(size_t)r * t.ncol + cs];
  }
  tau /= m;
  tau_up /= m;
  sig /= m;
  OK(ter_series_meta_num(&t, "lost_grains", &lost, &err));
  printf("shear: %d rows, second half: tau %.4g Pa (upper half %.4g), sigma %.4g Pa, tau/sigma %.3f, "
         "%g grains lost\n", t.n, tau, tau_up, sig, tau / sig, lost);
  /* the plane's normal force is the platen's N (held at sigma_n A) plus the weight above the plane,
   * over the shrinking overlap area: between sigma_n and 2 sigma_n here */
  CHECK(sig > 0.9 * sp.sigma_n && sig < 2 * sp.sigma_n, "normal stress %.4g Pa, target %.4g", sig, sp.sigma_n);
  CHECK(tau / sig > 0.15 && tau / sig < 1.0, "tau/sigma %.3f not a granular friction", tau / sig);
  CHECK(fabs(tau - tau_up) < 0.3 * tau, "the two halves' shear differ: %.4g and %.4g Pa", tau, tau_up);
  CHECK(lost == 0, "%g grains fell out of the box", lost);
  ter_series_free(&t);
  sp.height = 0.02;
  FAILS_WITH(ter_shear_test(soil, &sp, NULL, &t, &err), "below 5 grain diameters");
}

/* ter_solid_fraction against exact volumes: a sphere inside the box, one
 * cut in half by the box's floor, one whose centre lies outside the box's
 * x-y rectangle (not counted). */
static void solid_fraction(void) {
  const double x[9] = {0.5, 0.5, 0.5, 0.2, 0.2, 0.0, 1.5, 0.5, 0.5}, r[3] = {0.1, 0.1, 0.1};
  const double lo[3] = {0, 0, 0}, hi[3] = {1, 1, 1}, v = 4.0 / 3 * M_PI * 1e-3;
  /* tolerance 1e-12: closed-form segment volumes, rounding only */
  CHECK_REL("1 + 1/2 sphere in a 1 m^3 box", ter_solid_fraction(3, x, r, lo, hi), 1.5 * v, 1e-12);
  const double lo2[3] = {0, 0, 0.5}, hi2[3] = {1, 1, 0.6}; /* the upper half of the first sphere */
  CHECK_REL("the upper half of a sphere in a 0.1 m slab", ter_solid_fraction(3, x, r, lo2, hi2), 0.5 * v / 0.1, 1e-12);
}

/* The preparation (ter_prep): settling and consolidating with friction 0
 * packs the shear box denser than the scene's friction 0.6 does (the
 * specimen's solid fraction), and a rolling friction in the preparation of a
 * scene without any is refused by name. */
static void shear_prep(const ter_dem_soil *soil) {
  proto_err err;
  ter_shear_spec sp;
  ter_shear_defaults(&sp);
  sp.length = sp.width = 0.06;
  sp.height = 0.04;
  sp.sigma_n = 4e3;
  sp.speed = 0.05;
  sp.j_max = 0.002;
  sp.dj = 0.5e-3;
  sp.settle_max_steps = 4000;
  double phi[2];
  for (int k = 0; k < 2; k++) {
    sp.prep = (ter_prep){.on = k, .friction = 0, .rolling = 0};
    ter_series t;
    OK(ter_shear_test(soil, &sp, NULL, &t, &err));
    OK(ter_series_meta_num(&t, "solid_fraction", &phi[k], &err));
    const char *what = ter_series_get_meta(&t, "preparation");
    CHECK(what && strstr(what, k ? "friction 0" : "the scene's laws"), "preparation meta '%s'", what ? what : "");
    ter_series_free(&t);
  }
  printf("shear prep: solid fraction %.4f with the scene's friction, %.4f prepared with friction 0\n", phi[0], phi[1]);
  CHECK(phi[0] > 0.45 && phi[1] < 0.75, "solid fractions %.4f, %.4f outside (0.45, 0.75)", phi[0], phi[1]);
  /* margin: 0.01 of solid fraction, ~10 times the seed-to-seed spread of this box's packing */
  CHECK(phi[1] > phi[0] + 0.01, "frictionless preparation not denser: %.4f vs %.4f", phi[1], phi[0]);
  ter_series t;
  sp.prep = (ter_prep){.on = 1, .friction = 0, .rolling = 0.1};
  FAILS_WITH(ter_shear_test(soil, &sp, NULL, &t, &err), "needs a scene with rolling_friction");
}

/* ter_prepare_bed on a small generated bed: saved, counted, packed denser
 * with the frictionless preparation (lower median top for the same grains);
 * a scene whose particles are not a generated bed is refused. */
static void prepared_bed(void) {
  static const char BED[] =
      "{\"processes\": {\"soil\": {\"exec\": \"dem_server\","
      " \"materials\": [{\"density\": 2600, \"E\": 5e6, \"nu\": 0.3, \"restitution\": 0.5, \"friction\": 0.6,"
      "                   \"rolling_friction\": 0.2}],"
      " \"particles\": {\"generate\": \"bed\", \"scale\": 0.02, \"settle_max_steps\": 3000,"
      "                 \"settle_ke_per_grain\": 1e-7}, \"threads\": 1,"
      " \"walls\": [{\"type\": \"box\", \"lo\": [0, 0, 0], \"hi\": [0.1415, 0.1415, 1], \"open_top\": true}],"
      " \"gravity\": [0, 0, -9.81]}}}";
  proto_err err;
  cJSON *scene = proto_json_parse(BED, "bed scene", &err);
  ter_dem_soil soil;
  OK(ter_dem_soil_from_scene(scene, &soil, &err));
  ter_bed_spec sp = {.inset = 0.02, .slabs = 2};
  ter_bed_result res[2];
  const char *path = "test_ter_dem_bed.h5";
  for (int k = 0; k < 2; k++) {
    sp.prep = (ter_prep){.on = k, .friction = 0, .rolling = 0};
    OK(ter_prepare_bed(&soil, &sp, path, NULL, &res[k], &err));
    FILE *f = fopen(path, "rb");
    CHECK(f != NULL, "bed file %s not written", path);
    if (f) fclose(f);
    remove(path);
  }
  printf("bed: %d grains, median top %.4f m with the scene's friction, %.4f m prepared; solid fraction "
         "(lower slab) %.4f, %.4f\n", res[0].grains, res[0].top, res[1].top, res[0].solid_fraction[0],
         res[1].solid_fraction[0]);
  CHECK(res[0].grains == 436 && res[1].grains == 436, "grains %d, %d (21812 x 0.02 = 436)", res[0].grains,
        res[1].grains);
  CHECK(res[1].solid_fraction[0] > res[0].solid_fraction[0], "prepared bed not denser: %.4f vs %.4f",
        res[1].solid_fraction[0], res[0].solid_fraction[0]);
  CHECK(res[1].top < res[0].top, "prepared bed not lower: %.4f vs %.4f m", res[1].top, res[0].top);
  cJSON *parts = cJSON_CreateObject();
  cJSON_AddStringToObject(parts, "file", "none.h5");
  cJSON_ReplaceItemInObjectCaseSensitive((cJSON *)soil.section, "particles", parts);
  FAILS_WITH(ter_prepare_bed(&soil, &sp, path, NULL, &res[0], &err), "must be a generated bed");
  cJSON_Delete(scene);
}

int main(void) {
  proto_err err;
  cJSON *scene = proto_json_parse(SCENE, "scene", &err);
  ter_dem_soil soil;
  OK(ter_dem_soil_from_scene(scene, &soil, &err));
  CHECK(strcmp(soil.path, "processes.soil") == 0 && soil.plate_material == 1 && soil.grain_material == 0,
        "scene reader: %s, plate material %d", soil.path, soil.plate_material);
  plate(&soil);
  shear(&soil);
  shear_prep(&soil);
  solid_fraction();
  prepared_bed();
  cJSON *no_dem = proto_json_parse("{\"processes\": {\"fem\": {\"exec\": \"fem_server\"}}}", "x", &err);
  FAILS_WITH(ter_dem_soil_from_scene(no_dem, &soil, &err), "dem_server");
  cJSON_Delete(no_dem);
  cJSON_Delete(scene);
  return cosim_test_done("test_ter_dem");
}
