/* loop.c — the coupling schemes over the schedule (PROTOCOL.md "Schemes";
 * docs/coupling-schemes.md; Gatzhammer 2014; Degroote et al. 2009):
 *   serial    the stages in order, each committed before the next (the
 *             grains' forces of step k reach the tread in step k);
 *   parallel  one stage, every process at once on the last committed fields
 *             (the tread gets the grains' forces one step late: Jacobi);
 *   implicit  the parallel stage repeated until the interface fields stop
 *             changing, accelerated (IQN-ILS, Aitken or constant), the
 *             processes rolled back between repeats.
 * (implicit.c). The orchestrator: per step the scheme's exchange and
 * scenario stages, then record (record.c), timing and checkpoint; the
 * stages only call down (runner.h). */
#include "runner.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int one_step(cpl_runner *r, int64_t k, int output) {
  switch (r->scene->scheme) {
  case CPL_SCHEME_IMPLICIT:
    return cpl_implicit_step(r, k, output);
  case CPL_SCHEME_SERIAL:
  case CPL_SCHEME_PARALLEL:
    r->data.iterations = r->data.converged = 1;
    return cpl_run_stages(r, 0, cpl_last_stage(r), k, 0, output, 1, 1);
  }
  return -1;
}

int cpl_scheme_init(cpl_runner *r) {
  return r->scene->scheme == CPL_SCHEME_IMPLICIT ? cpl_implicit_init(r) : 0;
}

/* The orchestrator: per step the scheme's exchange and scenario stages
 * (schedule.c, scenario_step.c), then record, timing and checkpoint. */
int cpl_step_loop(cpl_runner *r) {
  const cpl_scene *s = r->scene;
  cpl_inputs_current(r);
  double last_shown = proto_now(), start = proto_now();
  for (int64_t k = r->k0 + 1; k <= s->n_steps; k++) {
    int output = (k % s->output_every == 0) || k == s->n_steps;
    double t_step = proto_now();
    r->t_blocked = 0;
    int rc = one_step(r, k, output);
    if (rc == 0) r->data.road.force_last = r->data.fields[CPL_F_ROAD_FORCE].cur[0];
    double t_rec = proto_now();
    if (rc == 0) rc = cpl_record(r, k, output);
    double now = proto_now();
    if (rc == 0) rc = cpl_timing_step(r, k, now - t_step, now - t_rec);
    if (rc == 0 && s->checkpoint_every && k % s->checkpoint_every == 0)
      rc = cpl_checkpoint_write(r, k);
    if (rc < 0) {
      proto_err ignore;
      if (!cpl_output_io_failed(r->out)) cpl_output_flush(r->out, &ignore);
      return proto_wrap(&r->err, "step %lld (t = %g s)", (long long)k,
                        (double)(k - 1) * s->dt);
    }
    if (now - last_shown > 0.5 || k == s->n_steps) {
      double rate = (double)(k - r->k0) / fmax(now - start, 1e-9);
      cpl_progress(r, k, rate, k == s->n_steps);
      last_shown = now;
    }
  }
  if (r->data.steps_unconverged)
    fprintf(stderr, "cosim: warning: %lld of %lld steps did not reach "
            "coupling.implicit.tolerance %g within max_iterations %lld "
            "(see /coupler/series)\n", (long long)r->data.steps_unconverged,
            (long long)s->n_steps, s->implicit.tolerance,
            (long long)s->implicit.max_iterations);
  return 0;
}
