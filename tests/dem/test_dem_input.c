/* Bad input gives a clear error naming the key (and a non-zero status from
 * the library call): overlapping grains, radius <= 0, nu >= 0.5, grains
 * outside the domain, dt above the stability limit, unknown keys, types.
 * And the step rule (dem_state_init / dem_state_set_dt): dt_fraction × T_R
 * split into equal sub-steps of a coupling step, refused above the limit. */
#include "dem_test.h"
#include <math.h>
#include <string.h>

#define MAT "\"materials\":[{\"density\":2600,\"E\":1e7,\"nu\":0.3,\"restitution\":0.5,\"friction\":0.5}]"
#define BOX "\"walls\":[{\"type\":\"box\",\"lo\":[0,0,0],\"hi\":[0.1,0.1,0.1]}]"
#define P(x, y, z, r) "{\"x\":[" #x "," #y "," #z "],\"r\":" #r "}"

/* The step is the state's: without a coupling step dt_fraction × T_R (T_R of
 * docs/dem-bench.md §2 computed here), with one the fewest equal sub-steps not longer than
 * that; a coupling step may change it; a step above the limit is refused,
 * naming the key, and leaves the state's step as it was. */
static void check_step_rule(void) {
  dem_model m;
  dem_state s;
  proto_err err = {{0}};
  cJSON *j = cJSON_Parse("{" MAT ",\"dt_fraction\":0.1,\"particles\":[" P(0, 0, 0, 0.005) "]}");
  CHECK(dem_model_from_json(&m, j, "processes.dem", &err) == 0, "%s", err.msg);
  cJSON_Delete(j);
  const double G = 1e7 / (2 * 1.3), tr = M_PI * 0.005 * sqrt(2600 / G) / (0.1631 * 0.3 + 0.8766);
  const double own = 0.1 * tr; /* 4.4e-5 s */
  CHECK(dem_state_init(&m, &s, 0, &err) == 0, "%s", err.msg);
  CHECK_REL("dt without a coupling step", s.dt, own, 1e-14);
  dem_state_free(&s);
  const double coupling[3] = {1e-4, 4 * own, 1e-5}; /* 3 sub-steps, exactly 4, one shorter step */
  const double nsub[3] = {3, 4, 1};
  CHECK(dem_state_init(&m, &s, coupling[0], &err) == 0, "%s", err.msg);
  for (int k = 0; k < 3; k++) {
    CHECK(k == 0 || dem_state_set_dt(&m, &s, coupling[k], &err) == 0, "%s", err.msg);
    printf("coupling step %.4g s: dt = %.6g s (%.0f sub-steps)\n", coupling[k], s.dt, coupling[k] / s.dt);
    CHECK_REL("dt = coupling step / sub-steps", s.dt, coupling[k] / nsub[k], 1e-14);
  }
  m.cfg.dt_given = 0.6 * tr; /* a model edited by hand: refused, the state keeps its step */
  CHECK(dem_state_set_dt(&m, &s, 0, &err) != 0, "dt above the limit accepted");
  CHECK_MSG(err, "processes.dem.dt: dt = ");
  CHECK_MSG(err, "above the stability limit");
  CHECK(s.dt == coupling[2] / nsub[2], "a refused step changed the state's dt to %g", s.dt);
  dem_state_free(&s);
  m.cfg.dt_given = 0;
  m.rayleigh_time = 0; /* grains replaced without their Rayleigh time */
  CHECK(dem_state_init(&m, &s, 0, &err) != 0, "a zero step accepted");
  CHECK_MSG(err, "processes.dem: time step not set");
  dem_model_free(&m);
}

int main(void) {
  check_step_rule();
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
