/* The explicit step's team (fem_explicit.c): above FEM_OMP_MIN_ELEMS
 * elements the node update, the element kernel and the node gather run as
 * one OpenMP team per sub-step, and the energies are summed per chunk of
 * FEM_SUM_CHUNK nodes, the chunks in order.
 *
 * 1. A jittered block of 25 272 TET4 (above the threshold), bottom held,
 *    under a body load in a spinning, accelerating frame, undamped, plain
 *    and with ANP: 1, 2 and 3 threads give the same displacement, velocity
 *    and energies bit for bit (3 threads split the 20 chunks unevenly).
 * 2. The same run keeps the leapfrog's discrete energy balance
 *    E - E0 - W = 0 (fem_explicit.c's invariant) to round-off: a chunk left
 *    out of a sum or counted twice breaks it by far more. */
#include "fem_test.h"
#include "fem_server/fem_internal.h"

#include <omp.h>
#include <stdlib.h>
#include <string.h>

enum { N_STEPS = 12 };

typedef struct run {
  double *u, *v, energy, work, kinetic, strain, drift, emax;
} run;

static void block(fem_model *md, int anp) {
  proto_err err;
  fem_mesh m = {0};
  const double L[3] = {0.36, 0.36, 0.26};
  const int n[3] = {18, 18, 13}; /* 6 Kuhn tets per cell: 25 272 elements */
  OK(fem_gen_box(&m, L, n, 0.2, &err));
  fem_material mat = {.E = 2e6, .nu = 0.45, .density = 1100, .damping = 0};
  OK(fem_model_init(md, &m, &mat, &err));
  for (int32_t a = 0; a < md->mesh.n_nodes; a++)
    if (md->mesh.x[3 * (size_t)a + 2] < 1e-9) fem_model_fix_node(md, a, 7, NULL);
  if (anp) OK(fem_model_set_anp(md, &err));
  /* no fem_model_assemble: the explicit step needs no K (ANP's takes seconds here) */
  CHECK(md->mesh.n_elems > FEM_OMP_MIN_ELEMS, "the block (%d elements) must be above the team's "
        "threshold (%d)", (int)md->mesh.n_elems, FEM_OMP_MIN_ELEMS);
}

static run advance(const fem_model *md, double dt_crit, int threads) {
  proto_err err;
  fem_state st;
  OK(fem_state_init(md, &st, &err));
  fem_state_reset(md, &st, NULL);
  st.dt_crit = dt_crit;
  for (int32_t i = 0; i < md->n_dof; i++) /* a body load varying over the block */
    st.b[i] = md->mass[i / 3] * (i % 3 == 2 ? -9.81 : 3 * sin(40 * md->mesh.x[i]));
  omp_set_num_threads(threads);
  run r = {0};
  for (int k = 0; k < N_STEPS; k++) { /* the frame spins up about a tilted axis and accelerates */
    const double s = 1 + 0.1 * k;
    st.frame.omega[0] = 0.6 * s, st.frame.omega[1] = -0.3 * s, st.frame.omega[2] = 1.1 * s;
    st.frame.alpha[0] = 0.6, st.frame.alpha[1] = -0.3, st.frame.alpha[2] = 1.1;
    st.frame.acc[0] = 0.5, st.frame.acc[1] = 0.2, st.frame.acc[2] = -0.1;
    OK(fem_explicit_advance(md, &st, 3 * st.dt_crit, 0.9, 0, &err)); /* 4 sub-steps each */
    r.emax = fmax(r.emax, fabs(st.energy));
    r.drift = fmax(r.drift, fabs(st.energy - st.energy0 - st.work_ext));
  }
  r.u = malloc(sizeof *r.u * (size_t)md->n_dof);
  r.v = malloc(sizeof *r.v * (size_t)md->n_dof);
  memcpy(r.u, st.u, sizeof *r.u * (size_t)md->n_dof);
  memcpy(r.v, st.v, sizeof *r.v * (size_t)md->n_dof);
  r.energy = st.energy, r.work = st.work_ext, r.kinetic = st.kinetic, r.strain = st.strain;
  fem_state_free(&st);
  return r;
}

static int same(const fem_model *md, const run *a, const run *b) {
  const size_t n = sizeof *a->u * (size_t)md->n_dof;
  return memcmp(a->u, b->u, n) == 0 && memcmp(a->v, b->v, n) == 0 && a->energy == b->energy &&
         a->work == b->work && a->kinetic == b->kinetic && a->strain == b->strain;
}

static void case_threads(int anp) {
  fem_model md;
  block(&md, anp);
  proto_err err;
  fem_state st;
  OK(fem_state_init(&md, &st, &err));
  OK(fem_stable_dt(&md, &st, 200, &err));
  run r[3];
  for (int t = 0; t < 3; t++) r[t] = advance(&md, st.dt_crit, t + 1);
  fem_state_free(&st);
  double umax = 0;
  for (int32_t i = 0; i < md.n_dof; i++) umax = fmax(umax, fabs(r[0].u[i]));
  printf("%s: %d elements, %d nodes, %d chunks of %d; after %d coupling steps |u| <= %.3e m, "
         "E = %.6e J, |E - E0 - W| <= %.2e of max |E|\n", anp ? "tet4_anp" : "tet4",
         (int)md.mesh.n_elems, (int)md.mesh.n_nodes, (int)fem_sum_chunks(md.mesh.n_nodes),
         FEM_SUM_CHUNK, N_STEPS, umax, r[0].energy, r[1].drift / r[1].emax);
  CHECK(umax > 1e-6, "the block barely moved (|u| <= %.3e m): the test would show nothing", umax);
  CHECK(same(&md, &r[0], &r[1]), "%s: 2 threads differ from 1 (E %.17g against %.17g)",
        anp ? "ANP" : "TET4", r[1].energy, r[0].energy);
  CHECK(same(&md, &r[0], &r[2]), "%s: 3 threads differ from 1 (E %.17g against %.17g)",
        anp ? "ANP" : "TET4", r[2].energy, r[0].energy);
  CHECK(r[1].drift < 1e-9 * r[1].emax, "%s: discrete energy balance broken with the team: "
        "%.3e of %.3e J", anp ? "ANP" : "TET4", r[1].drift, r[1].emax);
  for (int t = 0; t < 3; t++) free(r[t].u), free(r[t].v);
  fem_model_free(&md);
}

int main(void) {
  case_threads(0);
  case_threads(1);
  return cosim_test_done("test_fem_threads");
}
