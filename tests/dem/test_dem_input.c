/* Bad input gives a clear error naming the key (and a non-zero status from
 * the library call): overlapping grains, radius <= 0, nu >= 0.5, grains
 * outside the domain, dt above the stability limit, unknown keys, types. */
#include "dem_test.h"
#include <string.h>

#define MAT "\"materials\":[{\"density\":2600,\"E\":1e7,\"nu\":0.3,\"restitution\":0.5,\"friction\":0.5}]"
#define BOX "\"walls\":[{\"type\":\"box\",\"lo\":[0,0,0],\"hi\":[0.1,0.1,0.1]}]"
#define P(x, y, z, r) "{\"x\":[" #x "," #y "," #z "],\"r\":" #r "}"

static void expect_error(const char *name, const char *json, const char *want) {
  dem_model m;
  dem_state s;
  proto_err err = {{0}};
  cJSON *j = cJSON_Parse(json);
  if (!j) { fprintf(stderr, "bad JSON in %s\n", name); exit(2); }
  int rc = dem_model_from_json(&m, j, "processes.dem", &err);
  if (rc == 0) {
    rc = dem_state_init(&m, &s, 0, &err);
    if (rc == 0) dem_state_free(&s);
    dem_model_free(&m);
  }
  cJSON_Delete(j);
  printf("%-28s -> %s\n", name, rc ? err.msg : "(accepted)");
  CHECK(rc != 0, "%s: accepted", name);
  CHECK(rc == 0 || strstr(err.msg, want), "%s: message lacks '%s'", name, want);
}

int main(void) {
  expect_error("overlapping grains", "{" MAT "," BOX ",\"particles\":[" P(0.05, 0.05, 0.05, 0.01) ","
               P(0.065, 0.05, 0.05, 0.01) "]}", "grains 0 and 1 overlap");
  expect_error("radius 0", "{" MAT ",\"particles\":[" P(0, 0, 0, 0.01) "," P(1, 0, 0, 0) "]}",
               "processes.dem.particles[1].r: radius must be > 0");
  expect_error("negative radius", "{" MAT ",\"particles\":[" P(0, 0, 0, -0.01) "]}",
               "processes.dem.particles[0].r");
  expect_error("nu = 0.5", "{\"materials\":[{\"density\":2600,\"E\":1e7,\"nu\":0.5,\"restitution\":0.5,"
               "\"friction\":0.5}],\"particles\":[" P(0, 0, 0, 0.01) "]}", "processes.dem.materials[0].nu");
  expect_error("grain outside the box", "{" MAT "," BOX ",\"particles\":[" P(0.05, 0.05, 0.05, 0.01) ","
               P(0.05, 0.05, 0.2, 0.01) "]}", "grain 1 at (0.05, 0.05, 0.2) is outside the domain");
  expect_error("grain behind a plane", "{" MAT ",\"walls\":[{\"type\":\"plane\",\"point\":[0,0,0],"
               "\"normal\":[0,0,1]}],\"particles\":[" P(0, 0, -1, 0.01) "]}", "outside the domain");
  expect_error("dt above the limit", "{" MAT ",\"dt\":1e-3,\"particles\":[" P(0, 0, 0, 0.005) "]}",
               "above the stability limit");
  expect_error("dt_fraction above the limit", "{" MAT ",\"dt_fraction\":0.8,\"particles\":["
               P(0, 0, 0, 0.005) "]}", "stability limit");
  expect_error("unknown key", "{" MAT ",\"gravty\":[0,0,-9.81],\"particles\":[" P(0, 0, 0, 0.01) "]}",
               "processes.dem.gravty: unknown key");
  expect_error("wrong type", "{" MAT ",\"particles\":[{\"x\":[0,0],\"r\":0.01}]}",
               "processes.dem.particles[0].x");
  expect_error("material index", "{" MAT ",\"particles\":[{\"x\":[0,0,0],\"r\":0.01,\"material\":3}]}",
               "processes.dem.particles[0].material");
  expect_error("missing materials", "{\"particles\":[" P(0, 0, 0, 0.01) "]}", "processes.dem.materials");
  expect_error("unknown wall type", "{" MAT ",\"walls\":[{\"type\":\"cone\"}],\"particles\":["
               P(0, 0, 0, 0.01) "]}", "processes.dem.walls[0].type");
  expect_error("missing bed file", "{" MAT ",\"particles\":{\"file\":\"/nonexistent/bed.h5\"}}",
               "processes.dem.particles.file");
  expect_error("pair: material index", "{" MAT ",\"pairs\":[{\"materials\":[0,1],\"friction\":0.3}],"
               "\"particles\":[" P(0, 0, 0, 0.01) "]}", "processes.dem.pairs[0].materials[1]: 1 is not a material index");
  expect_error("pair: given twice", "{\"materials\":[{\"density\":2600,\"E\":1e7,\"nu\":0.3,\"restitution\":0.5,"
               "\"friction\":0.5},{\"density\":2600,\"E\":1e7,\"nu\":0.3,\"restitution\":0.5,\"friction\":0.5}],"
               "\"pairs\":[{\"materials\":[0,1],\"friction\":0.3},{\"materials\":[1,0],\"restitution\":0.3}],"
               "\"particles\":[" P(0, 0, 0, 0.01) "]}", "processes.dem.pairs[1].materials: pair [1, 0] given twice");
  expect_error("pair: restitution 0", "{" MAT ",\"pairs\":[{\"materials\":[0,0],\"restitution\":0}],"
               "\"particles\":[" P(0, 0, 0, 0.01) "]}", "processes.dem.pairs[0].restitution");
  expect_error("pair: unknown key", "{" MAT ",\"pairs\":[{\"materials\":[0,0],\"frictoin\":0.2}],"
               "\"particles\":[" P(0, 0, 0, 0.01) "]}", "processes.dem.pairs[0].frictoin: unknown key");
  expect_error("sleep: bad value", "{" MAT ",\"sleep\":{\"velocity\":-1},\"particles\":[" P(0, 0, 0, 0.01) "]}",
               "processes.dem.sleep.velocity");
  expect_error("threads: bad value", "{" MAT ",\"threads\":\"many\",\"particles\":[" P(0, 0, 0, 0.01) "]}",
               "processes.dem.threads: expected \"auto\"");
  /* and a good one is accepted, with exec ignored */
  {
    dem_model m;
    proto_err err;
    cJSON *j = cJSON_Parse("{\"exec\":\"dem_server\"," MAT ",\"particles\":[" P(0, 0, 0, 0.01) "]}");
    int rc = dem_model_from_json(&m, j, "processes.dem", &err);
    CHECK(rc == 0, "good config refused: %s", err.msg);
    if (!rc) dem_model_free(&m);
    cJSON_Delete(j);
  }
  return cosim_test_done("test_dem_input");
}
