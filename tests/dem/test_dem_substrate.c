/* A substrate under the paper's bed (particles.substrate, dem_bed_substrate):
 * its grains are placed as the bottom layer, full lattice levels of the
 * footprint, below every grain of the three layers, which keep their count,
 * sizes and places (lifted by the substrate's levels); after settling the
 * layer on it (the 15.6 mm grains, wider than its lattice windows) is still
 * above it. (The 6.9 and 7.8 mm grains are not checked: they pass the 15.6 mm
 * layer's own lattice windows and wall strip in a box this small, with or
 * without a substrate.) Bad substrate keys are refused, naming the key. */
#include "dem_test.h"

#define MAT "\"materials\":[{\"density\":2600,\"E\":1e6,\"nu\":0.3,\"restitution\":0.5,\"friction\":0.6}]"
#define BOX "\"walls\":[{\"type\":\"box\",\"lo\":[0,0,0],\"hi\":[0.1414213562,0.1414213562,2],\"open_top\":true}]"
#define BED(SUB) "{" MAT "," BOX ",\"dt\":5e-5,\"particles\":{\"generate\":\"bed\",\"scale\":0.02,\"seed\":3" SUB "}}"

int main(void) {
  dem_model m0, m;
  dem_state s0, s;
  proto_err err;
  scene(BED(""), &m0, &s0);
  /* 26 mm grains on a 0.1414 m footprint: pitch 0.0265 m (gap 0.5 mm), 5 x 5 per level, 3 levels in 0.1 m;
   * 4.5 mm strips at the walls and 11.5 mm lattice windows, narrower than the 15.6 mm grains above */
  scene(BED(",\"substrate\":{\"diameter\":0.026,\"depth\":0.1}"), &m, &s);
  const double a = 0.026 + 0.5e-3;
  const int per_level = (int)floor(0.1414213562 / a), levels = (int)floor(0.1 / a);
  const int n_sub = per_level * per_level * levels;
  printf("%d grains without the substrate, %d with it (%d levels of %d x %d)\n", m0.n_grains, m.n_grains, levels,
         per_level, per_level);
  CHECK(levels == 3 && per_level == 5, "the test's arithmetic: %d levels of %d", levels, per_level);
  CHECK(m.n_grains == m0.n_grains + n_sub, "%d grains, expected %d + %d", m.n_grains, m0.n_grains, n_sub);
  double sub_top = 0, fine_low = INFINITY;
  int bad_size = 0;
  for (int i = 0; i < m.n_grains; i++) {
    const double d = 2 * m.radius[i], z = m.x0[3 * i + 2];
    if (i < n_sub) {
      bad_size += fabs(d - 0.026) > 1e-15;
      sub_top = fmax(sub_top, z + m.radius[i]);
    } else {
      fine_low = fmin(fine_low, z - m.radius[i]);
      /* the paper's layers as without the substrate, lifted by the substrate's levels */
      const int k = i - n_sub;
      bad_size += m.radius[i] != m0.radius[k];
      bad_size += fabs(z - (m0.x0[3 * k + 2] + levels * a)) > 1e-12;
    }
  }
  printf("substrate placed up to z = %.4f m, the paper's layers from %.4f m\n", sub_top, fine_low);
  CHECK(bad_size == 0, "%d grains not where or as large as they should be", bad_size);
  CHECK(sub_top <= fine_low, "substrate top %.4f above the layers' bottom %.4f", sub_top, fine_low);
  CHECK(dem_settle_placed(&m, &s, 1e-9, 8000, NULL, NULL, &err) == 0, "settling: %s", err.msg);
  double sub_mean = 0, fine_min = INFINITY;
  for (int i = 0; i < s.n; i++) {
    if (i < n_sub) sub_mean += s.x[3 * i + 2] / n_sub;
    else if (m.radius[i] == 0.5 * 15.6e-3) fine_min = fmin(fine_min, s.x[3 * i + 2]);
  }
  printf("settled in %lld steps: coarse centres at %.4f m on average, the lowest 15.6 mm grain's %.4f m\n",
         (long long)s.step, sub_mean, fine_min);
  CHECK(fine_min > sub_mean, "a 15.6 mm grain sank into the substrate (%.4f below %.4f)", fine_min, sub_mean);
  dem_state_free(&s);
  dem_model_free(&m);
  dem_state_free(&s0);
  dem_model_free(&m0);

  expect_error("no diameter", BED(",\"substrate\":{\"depth\":0.1}"), "processes.dem.particles.substrate.diameter");
  expect_error("depth below one level", BED(",\"substrate\":{\"diameter\":0.026,\"depth\":0.02}"),
               "processes.dem.particles.substrate.depth: 0.02 m holds no level");
  expect_error("grains wider than the box", BED(",\"substrate\":{\"diameter\":0.2,\"depth\":1}"),
               "processes.dem.particles.substrate.diameter");
  expect_error("spread of half the diameter", BED(",\"substrate\":{\"diameter\":0.03,\"spread\":0.015,\"depth\":0.1}"),
               "processes.dem.particles.substrate.spread");
  expect_error("unknown key", BED(",\"substrate\":{\"diameter\":0.03,\"depth\":0.1,\"levels\":2}"), "levels");
  expect_error("not an object", BED(",\"substrate\":0.03"), "processes.dem.particles.substrate: expected an object");
  return cosim_test_done("test_dem_substrate");
}
