/* blk_step.c — one time step of the block model: the per-step contact
 * problem (seed 002 eq. 4–8) by the dense or the matrix-free solver
 * (blk_dense.c, blk_cg.c, which call down into the spring law of
 * blk_spring.c), adhesion with a release force (ch. 5.1), the tangent
 * contact stiffness, then the history term for the next step (eq. 5). Also
 * the state's allocation: nothing is allocated in blk_step. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "contact_block/blk_internal.h"

/* --------------------------------------------------------------- state */

static void *track(blk_work *w, size_t n, size_t size) {
  void *p = calloc(n ? n : 1, size);
  if (p) w->bytes += n * size;
  return p;
}

/* Relative asymmetry of the step's compliance kernel taken as round-off. */
#define BLK_EVEN_TOL 1e-10

/* The solver the model asks for (BLK_AUTO stays: chosen per step, blk_step). */
static int resolve_method(const blk_model *m, int symmetric, blk_method *out,
                          proto_err *err) {
  blk_method me = m->solver.method;
  if (me == BLK_AUTO && !symmetric) me = BLK_NR_PLAIN; /* LU fallback of the primal Newton */
  if ((me == BLK_CG || me == BLK_NR_DUAL || m->rigid) && !symmetric)
    return proto_fail(err, "solver: the dual solvers need a symmetric compliance "
                      "(g(0) even in the offset, reciprocity); this one is not: use "
                      "newton or line_search with compliant springs");
  if (me != BLK_CG && me != BLK_AUTO && m->M > BLK_DENSE_MAX)
    return proto_fail(err, "solver: %d elements exceed the dense limit %d", m->M,
                      BLK_DENSE_MAX);
  *out = me;
  return 0;
}

int blk_state_create(const blk_model *m, blk_state *s, proto_err *err) {
  memset(s, 0, sizeof *s);
  if (blk_model_check(m, err)) return -1;
  const size_t M = (size_t)m->M, no = (size_t)m->nox * m->noy;
  blk_work *w = calloc(1, sizeof *w);
  s->work = w;
  if (!w) return proto_fail(err, "out of memory");
  w->bytes = sizeof *w;
  s->d_rs = track(w, M, sizeof(double));
  s->force = track(w, M, sizeof(double));
  s->d_el = track(w, M, sizeof(double));
  s->d_el_old = track(w, M, sizeof(double));
  s->attached = track(w, M, sizeof(int));
  s->base = track(w, M, sizeof(double));
  w->kern = track(w, no, sizeof(double));
  w->b = track(w, M, sizeof(double));
  w->CF = track(w, M, sizeof(double));
  w->held = track(w, M, sizeof(int));
  if (!s->d_rs || !s->force || !s->d_el || !s->d_el_old || !s->attached || !s->base ||
      !w->kern ||
      !w->b || !w->CF || !w->held)
    return proto_fail(err, "out of memory");
  /* compliance of this step's forces: Δt g(0) (eq. 4) or the static sum */
  const int qs = m->solver.quasi_static || (!m->g && !m->g_time);
  const double scale = qs ? 1.0 : 1.0 / m->rate;
  for (size_t o = 0; o < no; o++)
    w->kern[o] = scale * (qs ? m->g_static[o] : blk_green_at(m, 0, o));
  w->c_self = w->kern[(size_t)(m->ny - 1) * m->nox + (m->nx - 1)];
  /* even, K(Δ) = K(−Δ) (reciprocity), up to the round-off of the closed
   * forms far out (relative to the largest coefficient): then made exactly
   * even, so C is exactly symmetric */
  double kmax = 0, asym = 0;
  for (size_t o = 0; o < no; o++) {
    kmax = fmax(kmax, fabs(w->kern[o]));
    asym = fmax(asym, fabs(w->kern[o] - w->kern[no - 1 - o]));
  }
  w->symmetric = asym <= BLK_EVEN_TOL * kmax;
  for (size_t o = 0; w->symmetric && o < no / 2; o++)
    w->kern[o] = w->kern[no - 1 - o] = 0.5 * (w->kern[o] + w->kern[no - 1 - o]);
  if (resolve_method(m, w->symmetric, &w->method, err)) return -1;
  s->method = w->method;
  /* auto: the dense dual while few elements are in contact (springs only: for
   * rigid contact constrained CG was faster at every size measured) */
  w->auto_dense = w->method == BLK_AUTO && !m->rigid;
  w->A_cap = w->method == BLK_AUTO ? (m->M < BLK_AUTO_DENSE_CAP ? m->M : BLK_AUTO_DENSE_CAP)
                                   : m->M;
  if (blk_fft_init(&w->fft, m, err) || blk_fft_kernel(&w->fft, m, w->kern, 1.0, &w->C_hat, err))
    return -1;
  w->bytes += blk_fft_bytes(&w->fft) + blk_kspec_bytes(&w->fft, &w->C_hat);
  /* matrix-free solver and tangent stiffness vectors */
  double **cg[] = {&w->g, &w->Dk, &w->dF, &w->wC, &w->rho, &w->z, &w->t, &w->q, &w->qc,
                   &w->Fn, &w->dn, &w->un, &w->prec, &w->psi};
  for (size_t i = 0; i < sizeof cg / sizeof *cg; i++)
    if (!(*cg[i] = track(w, M, sizeof(double)))) return proto_fail(err, "out of memory");
  if (w->method != BLK_CG && (w->method != BLK_AUTO || w->auto_dense)) {
    /* dense: the Newton matrix (A_cap × A_cap) and its vectors */
    double **dv[] = {&w->r, &w->delta, &w->d_try, &w->F_try, &w->k_try, &w->sk, &w->y,
                     &w->col_f, &w->fact_sk};
    for (size_t i = 0; i < sizeof dv / sizeof *dv; i++)
      if (!(*dv[i] = track(w, M, sizeof(double)))) return proto_fail(err, "out of memory");
    w->col_idx = track(w, M, sizeof(int));
    w->act = track(w, M, sizeof(int));
    w->piv = track(w, M, sizeof(int));
    w->fact_act = track(w, M, sizeof(int));
    w->A = track(w, (size_t)w->A_cap * w->A_cap, sizeof(double));
    if (!w->col_idx || !w->act || !w->piv || !w->fact_act || !w->A)
      return proto_fail(err, "out of memory (dense %d x %d Newton matrix)", w->A_cap, w->A_cap);
  }
  if (blk_history_init(m, w, &w->hist, err)) return -1;
  w->bytes += w->hist.bytes;
  blk_state_reset(m, s);
  return 0;
}

void blk_state_free(blk_state *s) {
  blk_work *w = s->work;
  if (w) {
    blk_history_free(&w->hist);
    blk_kspec_free(&w->C_hat);
    blk_fft_free(&w->fft);
    double *v[] = {w->kern, w->b, w->CF, w->g, w->Dk, w->dF, w->wC, w->rho, w->z,
                   w->t, w->q, w->qc, w->Fn, w->dn, w->un, w->prec, w->psi, w->r, w->delta,
                   w->d_try, w->F_try, w->k_try, w->sk, w->y, w->col_f, w->fact_sk, w->A};
    for (size_t i = 0; i < sizeof v / sizeof *v; i++) free(v[i]);
    free(w->held);
    free(w->col_idx);
    free(w->act);
    free(w->piv);
    free(w->fact_act);
    free(w);
  }
  free(s->d_rs);
  free(s->force);
  free(s->d_el);
  free(s->d_el_old);
  free(s->attached);
  free(s->base);
  memset(s, 0, sizeof *s);
}

size_t blk_state_bytes(const blk_state *s) { return s->work ? s->work->bytes : 0; }

void blk_state_reset(const blk_model *m, blk_state *s) {
  const size_t M = (size_t)m->M;
  s->n = 0;
  memset(s->d_rs, 0, M * sizeof(double));
  memset(s->force, 0, M * sizeof(double));
  memset(s->d_el, 0, M * sizeof(double));
  memset(s->d_el_old, 0, M * sizeof(double));
  memset(s->attached, 0, M * sizeof(int));
  memset(s->base, 0, M * sizeof(double));
  s->d_road = s->total_force = s->residual = s->stiffness = 0;
  s->n_contact = s->iterations = s->line_search_cuts = s->products = 0;
  s->converged = 1;
  s->factorizations = 0;
  s->work->fact_valid = 0;
  blk_history_reset(m, &s->work->hist);
}

/* ---------------------------------------------------------------- step */

int blk_step(const blk_model *m, blk_state *s, double d_road, proto_err *err) {
  blk_work *w = s->work;
  const int M = m->M;
  if (!isfinite(d_road))
    return proto_fail(err, "step %lld: d_road is not finite", (long long)s->n + 1);
  /* b = d_road + base + z_road − z_free − d_el_old (eq. 6, 4; base: a shaped
   * base, the lug face's, per element; 0 for the thesis' flat block) */
  for (int e = 0; e < M; e++) {
    w->b[e] = d_road + s->base[e] + m->z_road[e] - m->z_free - s->d_el_old[e];
    w->held[e] = s->attached[e];
  }
  if (m->periodic && m->rigid && !m->adhesion) {
    /* the periodic half-space has zero mean displacement (green/periodic.c):
     * hard contact beyond full contact has no equilibrium */
    double mean = 0;
    for (int e = 0; e < M; e++) mean += w->b[e];
    mean /= M;
    if (mean >= 0)
      return proto_fail(err, "step %lld (d_road = %g m): periodic grid, rigid contact: the "
                        "mean overlap %g m is not below full contact (the periodic "
                        "half-space keeps zero mean displacement): no equilibrium",
                        (long long)s->n + 1, d_road, mean);
  }
  int conv = 0, cuts = 0, iters = 0, factored = 0, products = 0;
  double rmax = 0;
  /* adhesion sweeps: solve with the held set fixed, release every held element
   * whose tension exceeds the release force, repeat until none releases */
  blk_method me = w->method;
  if (me == BLK_AUTO) {
    const double P = s->n_contact; /* dense ∝ P³, matrix-free ∝ M log M */
    me = w->auto_dense && P <= w->A_cap && P * P * P <= BLK_AUTO_KAPPA * M * log2(M + 1.0)
             ? BLK_NR_DUAL
             : BLK_CG;
  }
  for (int sweep = 0; sweep <= M; sweep++) {
    switch (me) {
    case BLK_CG: iters += blk_cg_solve(m, s, &conv, &rmax, &products); break;
    case BLK_NR_DUAL:
      iters += blk_dense_dual(m, s, &conv, &rmax, &cuts, &factored);
      if (w->dense_overflow) { /* auto: more free elements than the matrix holds */
        me = BLK_CG;
        iters += blk_cg_solve(m, s, &conv, &rmax, &products);
      }
      break;
    default: iters += blk_dense_newton(m, s, &conv, &rmax, &cuts, &factored);
    }
    if (!m->adhesion) break;
    int released = 0;
    for (int e = 0; e < M; e++)
      if (w->held[e] && s->d_rs[e] < 0 && grn_spring_released(s->force[e], m->release_force)) {
        w->held[e] = 0;
        released++;
      }
    if (!released) break;
  }
  for (int e = 0; e < M; e++)
    if (!isfinite(s->d_rs[e]) || !isfinite(s->force[e]))
      return proto_fail(err, "step %lld (d_road = %g m): element %d (i=%d, j=%d): "
                        "spring compression/force not finite (solver diverged)",
                        (long long)s->n + 1, d_road, e, e % m->nx, e / m->nx);
  for (int e = 0; e < M; e++)
    if (fabs(s->force[e]) > m->solver.max_force)
      return proto_fail(err, "step %lld (d_road = %g m): element %d (i=%d, j=%d): spring "
                        "force %g N exceeds solver.max_force = %g N: runaway (the time "
                        "stepping is unstable; with point-sampled Green's functions use "
                        "ZOH samples, a finer rate or softened springs)",
                        (long long)s->n + 1, d_road, e, e % m->nx, e / m->nx, s->force[e],
                        m->solver.max_force);
  /* final forces of this step, contact flags, layer displacement (eq. 4):
   * every solver leaves w->CF = C F at its final forces */
  double total = 0;
  int nc = 0;
  for (int e = 0; e < M; e++) {
    s->attached[e] = s->force[e] > 0 || (!m->rigid && s->d_rs[e] > 0) ||
                     (m->adhesion && w->held[e] && s->force[e] != 0);
    nc += s->attached[e];
    total += s->force[e];
    s->d_el[e] = s->d_el_old[e] + w->CF[e];
  }
  s->n++;
  s->d_road = d_road;
  s->total_force = total;
  s->n_contact = nc;
  s->iterations = iters;
  s->converged = conv;
  s->residual = rmax;
  s->line_search_cuts = cuts;
  s->factorizations = factored;
  s->method = me;
  s->stiffness = m->solver.tangent ? blk_cg_tangent(m, s, &products) : 0.0;
  s->products = products;
  blk_history_push(m, w, &w->hist, s->force, s->d_el_old);
  return 0;
}
