/* A substrate under the paper's bed (particles.substrate, dem_bed_substrate):
 * its grains are placed as the bottom layer, full lattice levels of the
 * footprint, below every grain of the three layers, which keep their count,
 * sizes and places (lifted by the substrate's levels); after settling the
 * layer on it (the 15.6 mm grains, wider than its lattice windows) is still
 * above it. (The 6.9 and 7.8 mm grains are not checked: they pass the 15.6 mm
 * layer's own lattice windows and wall strip in a box this small, with or
 * without a substrate.) A bed that settles (settle_max_steps) with
 * settle_first has its substrate settled alone first (dem_bed_presettle): the substrate then
 * stands at rest on the floor (the floor carries its weight: static
 * equilibrium, not the routine's own test), lower than its lattice, and the
 * layers are the placed ones moved straight down by one drop onto its
 * highest grain. Bad substrate keys are refused, naming the key. */
#include "dem_test.h"

#define MAT "\"materials\":[{\"density\":2600,\"E\":1e6,\"nu\":0.3,\"restitution\":0.5,\"friction\":0.6}]"
#define BOX "\"walls\":[{\"type\":\"box\",\"lo\":[0,0,0],\"hi\":[0.1414213562,0.1414213562,2],\"open_top\":true}]"
#define BED(SUB) "{" MAT "," BOX ",\"dt\":5e-5,\"particles\":{\"generate\":\"bed\",\"scale\":0.02,\"seed\":3" SUB "}}"
/* the same with frictionless walls (material 1, pair friction 0): the floor then carries the whole weight of
 * grains at rest (with wall friction the walls carry a part, Janssen's, which a state built from positions
 * has lost with the springs) */
#define MAT_SMOOTH_WALLS                                                                                         \
  "\"materials\":[{\"density\":2600,\"E\":1e6,\"nu\":0.3,\"restitution\":0.5,\"friction\":0.6},"              \
  "{\"density\":2600,\"E\":1e6,\"nu\":0.3,\"restitution\":0.5,\"friction\":0}],"                                \
  "\"pairs\":[{\"materials\":[0,1],\"friction\":0}]"
#define SMOOTH_BOX \
  "\"walls\":[{\"type\":\"box\",\"material\":1,\"lo\":[0,0,0],\"hi\":[0.1414213562,0.1414213562,2],\"open_top\":true}]"
#define SMOOTH_BED(SUB) \
  "{" MAT_SMOOTH_WALLS "," SMOOTH_BOX ",\"dt\":5e-5,\"particles\":{\"generate\":\"bed\",\"scale\":0.02,\"seed\":3" SUB "}}"
#define SUB26 ",\"substrate\":{\"diameter\":0.026,\"depth\":0.1}"
#define SUB26_FIRST ",\"substrate\":{\"diameter\":0.026,\"depth\":0.1,\"settle_first\":true}"
#define SETTLES ",\"settle_ke_per_grain\":1e-7,\"settle_max_steps\":40000"

/* The substrate settled alone (dem_bed_presettle) against the placed bed p. */
static void presettled(const dem_model *p, int n_sub) {
  dem_model m;
  dem_state s;
  scene(SMOOTH_BED(SUB26_FIRST SETTLES), &m, &s);
  CHECK(m.n_grains == p->n_grains && m.cfg.substrate_grains == n_sub, "%d grains (%d of the substrate)", m.n_grains,
        m.cfg.substrate_grains);
  CHECK(m.cfg.substrate_steps >= (int64_t)(DEM_SETTLE_MIN_TIME / 5e-5) && m.cfg.substrate_steps < 40000,
        "settled alone in %lld steps (at least 0.1 s, and its test before the limit)",
        (long long)m.cfg.substrate_steps);
  double weight = 0, top = 0, top_placed = 0, low = INFINITY, drop = NAN;
  int moved = 0, not_rigid = 0;
  for (int i = 0; i < m.n_grains; i++) {
    const double *x = &m.x0[3 * i], *x0 = &p->x0[3 * i], r = m.radius[i];
    if (i < n_sub) {
      weight += 2600 * 4.0 / 3.0 * M_PI * r * r * r * 9.81;
      top = fmax(top, x[2] + r);
      top_placed = fmax(top_placed, x0[2] + r);
      moved += fabs(x[2] - x0[2]) > 1e-4;
      continue;
    }
    low = fmin(low, x[2] - r);
    if (isnan(drop)) drop = x0[2] - x[2];
    not_rigid += x[0] != x0[0] || x[1] != x0[1] || fabs(x0[2] - x[2] - drop) > 1e-12;
  }
  const double fz = -s.wall_force[2];
  printf("substrate settled alone in %lld steps: %d of %d grains moved > 0.1 mm, top %.4f m (placed %.4f); "
         "the floor carries %.4f N of its %.4f N; the layers %.4f m lower, from %.4f m\n",
         (long long)m.cfg.substrate_steps, moved, n_sub, top, top_placed, fz, weight, drop, low);
  CHECK(moved > n_sub / 2 && top < top_placed, "the substrate did not settle (%d moved, top %.4f)", moved, top);
  CHECK(fabs(fz - weight) < 0.01 * weight, "floor %.4f N against the substrate's weight %.4f N", fz, weight);
  CHECK(not_rigid == 0 && drop > 0, "%d grains of the layers not moved as one (drop %g)", not_rigid, drop);
  CHECK(fabs(low - top) < 1e-12, "the layers start at %.6f m, the substrate's top is %.6f m", low, top);
  /* and the bed settles on it as before: the 15.6 mm layer stays above it */
  proto_err err;
  CHECK(dem_settle_placed(&m, &s, 1e-9, 8000, NULL, NULL, &err) == 0, "settling: %s", err.msg);
  double sub_mean = 0, fine_min = INFINITY;
  for (int i = 0; i < s.n; i++) {
    if (s.id[i] < n_sub) sub_mean += s.x[3 * i + 2] / n_sub;
    else if (s.radius[i] == 0.5 * 15.6e-3) fine_min = fmin(fine_min, s.x[3 * i + 2]);
  }
  CHECK(fine_min > sub_mean, "a 15.6 mm grain sank into the presettled substrate (%.4f below %.4f)", fine_min,
        sub_mean);
  dem_state_free(&s);
  dem_model_free(&m);
}

int main(void) {
  dem_model m0, m;
  dem_state s0, s;
  proto_err err;
  scene(BED(""), &m0, &s0);
  /* 26 mm grains on a 0.1414 m footprint: pitch 0.0265 m (gap 0.5 mm), 5 x 5 per level, 3 levels in 0.1 m;
   * 4.5 mm strips at the walls and 11.5 mm lattice windows, narrower than the 15.6 mm grains above */
  scene(BED(SUB26), &m, &s);
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
  CHECK(m.cfg.substrate_grains == n_sub && m.cfg.substrate_steps == 0, "a bed that does not settle: %d, %lld",
        m.cfg.substrate_grains, (long long)m.cfg.substrate_steps);
  {
    /* settle_first off (the default), or a bed that does not settle: the substrate stays as placed */
    dem_model mk;
    dem_state sk;
    scene(BED(SUB26 SETTLES), &mk, &sk);
    int same = mk.n_grains == m.n_grains && mk.cfg.substrate_steps == 0;
    for (int i = 0; same && i < 3 * m.n_grains; i++) same = mk.x0[i] == m.x0[i];
    CHECK(same, "a settling bed without settle_first is not the placed bed");
    dem_state_free(&sk);
    dem_model_free(&mk);
    scene(BED(SUB26_FIRST), &mk, &sk);
    same = mk.cfg.substrate_steps == 0;
    for (int i = 0; same && i < 3 * m.n_grains; i++) same = mk.x0[i] == m.x0[i];
    CHECK(same, "a bed that does not settle had its substrate settled");
    dem_state_free(&sk);
    dem_model_free(&mk);
  }
  presettled(&m, n_sub);
  CHECK(dem_settle_placed(&m, &s, 1e-9, 8000, NULL, NULL, &err) == 0, "settling: %s", err.msg);
  double sub_mean = 0, fine_min = INFINITY;
  for (int i = 0; i < s.n; i++) {
    if (s.id[i] < n_sub) sub_mean += s.x[3 * i + 2] / n_sub; /* slots are reordered: the model's index */
    else if (s.radius[i] == 0.5 * 15.6e-3) fine_min = fmin(fine_min, s.x[3 * i + 2]);
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
  expect_error("settle_first not a boolean", BED(",\"substrate\":{\"diameter\":0.026,\"depth\":0.1,\"settle_first\":2}"),
               "processes.dem.particles.substrate.settle_first");
  return cosim_test_done("test_dem_substrate");
}
