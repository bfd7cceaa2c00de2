/* dem_bed_presettle.c — a generated bed's substrate settled alone before the
 * layers above go on it (dem_bed_presettle, dem.h).
 *
 *   (x0 placed: the substrate on its lattice, the layers above it)
 *     => (x0: the substrate settled at rest, the layers lowered onto it)
 *
 * Opt-in ("particles.substrate.settle_first": true), because it changes the
 * bed: on the sand scene's five beds the layers above a substrate settled
 * first pack looser (solid fraction 0.571 against 0.579 settled with it, and
 * 0.580 on the floor), and the tyre sinks 1.5-2.4 mm deeper, while it saves
 * a fifth of the settling steps (bench/results/sand_calibration.md "The
 * substrate settled first").
 *
 * Why: a substrate placed on its lattice (dem_bed_substrate: a jittered
 * simple cubic packing, 0.5 mm gaps) is metastable. Alone it stands for
 * about 0.05 s, then its columns buckle: its kinetic energy peaks at
 * 0.2-0.3 s. Placed under the layers and settled with them, it collapsed as
 * they landed and kept the whole bed ringing: the sand scene's bed on 0.15 m
 * of 26 mm grains settled in 34 000-39 000 steps of 12.5 us, against
 * 24 500-25 900 without the substrate; a 0.4 x 0.4 m bed of the same kind in
 * 40 100 against 26 700. Settled alone first, at its own Rayleigh step (its
 * grains are 4x the smallest: a 4x longer step, 2 775 grains), the substrate
 * costs seconds, and that 0.4 m bed then settles in 28 100-29 600 steps;
 * the sand scene's in 27 300-28 600.
 *
 * The end test: the substrate's kinetic energy per kilogram below the bed's
 * settle_ke_per_grain per the mean mass of the other grains, i.e. the rms
 * speed the bed's own test stands for (1e-7 J per grain of the sand scene's
 * layers, 2.1 g on average: 9.8 mm/s), after DEM_SETTLE_MIN_TIME; it is a
 * preparation (the bed's settling after it decides when the bed is at rest),
 * so a substrate that stops early only settles longer with the layers. */
#include "dem_server/dem_internal.h"

#include <math.h>
#include <stdlib.h>

static double grain_mass(const dem_model *m, int i) {
  const double r = m->radius[i];
  return m->mat[m->material[i]].density * 4.0 / 3.0 * M_PI * r * r * r;
}

/* The substrate alone (the model's first grains) settled in its own state;
 * its settled positions, in model order, into x (ns x 3). */
static int settle_alone(const dem_model *m, int ns, double ke_per_kg, double *x, int64_t *steps, double *worst,
                        proto_err *err) {
  dem_model sub = *m; /* shares the model's arrays, read only */
  sub.n_grains = ns;
  sub.n_meshes = 0;
  if (m->cfg.prep.on) dem_prep_laws(&sub, &m->cfg.prep);
  sub.rayleigh_time = dem_model_rayleigh(&sub);
  dem_state s = {0};
  if (dem_state_init(&sub, &s, 0, err)) return -1;
  s.work->settling = 1; /* all awake, as dem_bed_settle */
  double mass = 0;
  for (int i = 0; i < ns; i++) mass += grain_mass(m, i);
  /* dem_settle_placed's rules (DEM_SETTLE_MIN_TIME, then the KE test per
   * grain): the test per kilogram times the substrate's mean grain mass */
  const int rc = dem_settle_placed(&sub, &s, ke_per_kg * mass / ns, (int64_t)m->cfg.settle_steps, NULL, NULL, err);
  for (int j = 0; j < s.n && rc == 0; j++)
    for (int c = 0; c < 3; c++) x[3 * s.id[j] + c] = s.x[3 * j + c];
  /* a settled substrate is pressed by its weight: the state built from the
   * model accepts its overlaps, as it accepts a saved bed's */
  if (rc == 0) *worst = dem_worst_overlap(&sub, &s);
  *steps = s.step;
  dem_state_free(&s);
  return rc;
}

int dem_bed_presettle(dem_model *m, proto_err *err) {
  const int ns = m->cfg.substrate_grains, n = m->n_grains;
  if (ns <= 0 || ns >= n || !m->cfg.substrate_first || !(m->cfg.settle_steps > 0)) return 0;
  double mass_above = 0;
  for (int i = ns; i < n; i++) mass_above += grain_mass(m, i);
  const double ke_per_kg = m->cfg.settle_ke / (mass_above / (n - ns));
  double *x = malloc(sizeof *x * 3 * (size_t)ns);
  if (!x) return proto_fail(err, "%s.particles.substrate: out of memory", m->key_path);
  int64_t steps = 0;
  double worst = 0;
  if (settle_alone(m, ns, ke_per_kg, x, &steps, &worst, err)) {
    free(x);
    return proto_wrap(err, "%s.particles.substrate: settling it alone", m->key_path);
  }
  /* the clearance between the settled substrate's highest grain and the
   * lowest grain above (their lattices left none): the layers go down by it */
  double top = -INFINITY, bottom = INFINITY;
  for (int i = 0; i < ns; i++) top = fmax(top, x[3 * i + 2] + m->radius[i]);
  for (int i = ns; i < n; i++) bottom = fmin(bottom, m->x0[3 * i + 2] - m->radius[i]);
  if (!(bottom >= top)) {
    free(x);
    return proto_fail(err, "%s.particles.substrate: settled alone, a grain stands %g m above the lowest grain "
                      "placed on it (settle_max_steps %g may be too few)", m->key_path, top - bottom,
                      m->cfg.settle_steps);
  }
  const double drop = bottom - top;
  for (int i = 0; i < ns; i++)
    for (int c = 0; c < 3; c++) {
      m->x0[3 * i + c] = x[3 * i + c];
      m->v0[3 * i + c] = m->omega0[3 * i + c] = 0;
    }
  for (int i = ns; i < n; i++) m->x0[3 * i + 2] -= drop;
  free(x);
  m->cfg.substrate_steps = steps;
  m->bed_max_overlap = fmax(m->bed_max_overlap, worst);
  return 0;
}
