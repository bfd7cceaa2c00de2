/* accel.c — acceleration of the implicit scheme's fixed-point iteration
 * x = H(x) in one coupling step (docs/coupling-schemes.md §3):
 *   constant  x ← x + ω r,  r = H(x) − x;
 *   aitken    ω_k = −ω_{k−1} r_{k−1}·(r_k − r_{k−1}) / |r_k − r_{k−1}|²
 *             (Irons & Tuck 1969; the first ω of a step:
 *             sign(ω_prev) min(ω_init, |ω_prev|), as preCICE);
 *   iqn-ils   Degroote et al. 2009, as preCICE implements it: columns
 *             V = [r_k − r_{k−1}, ...], W = [x̃_k − x̃_{k−1}, ...] (newest
 *             first), reused over the last `reuse` steps, scaled per field by
 *             the residual-sum preconditioner, filtered by QR2 (Haelterman
 *             et al. 2016: drop a column whose part orthogonal to the newer
 *             kept ones is below `filter` of its norm); c = argmin |V c + r|
 *             (weighted), x ← x̃ + W c; with no columns yet, x ← x + ω₀ r.
 * The least squares go through the weighted Gram matrix VᵀV, kept per field
 * and updated by one column per iteration: its Cholesky factor, taken newest
 * column first, is the R of the QR of the scaled V, and the QR2 test reads
 * off its diagonal (R_jj² < filter² |v_j|²). Normal equations square the
 * condition number; the filter bounds it, and the iteration checks its own
 * residuals, so a less exact c costs an iteration, not accuracy.
 * Convergence, per field (preCICE's relative and residual-relative
 * measures, either suffices): |r_f| ≤ tol |x̃_f − base_f| (base: the
 * positions at the step start; zero for forces), or |r_f| ≤ tol |r_f,0|, the
 * first non-zero residual of the step — for a field that vanishes (the
 * forces when the grains leave the tread), which the first test cannot pass. */
#include "runner.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

struct cpl_accel {
  cpl_implicit opt;
  int nf;
  int64_t len[CPL_ACCEL_MAX_FIELDS], off[CPL_ACCEL_MAX_FIELDS], N;
  int64_t window;  /* steps begun */
  int iter;        /* iterations in this step */
  double *r, *r_prev, *xt, *xt_prev; /* [N] */
  double sumw[CPL_ACCEL_MAX_FIELDS], w2[CPL_ACCEL_MAX_FIELDS]; /* preconditioner */
  double r0[CPL_ACCEL_MAX_FIELDS]; /* first residual norm of the step, per field */
  int field_ok[CPL_ACCEL_MAX_FIELDS]; /* field passed its test this iteration */
  double omega, omega_last; /* Aitken */
  int converged;   /* the last cpl_accel_next converged */
  /* IQN-ILS columns: slots of storage, `order` newest first */
  int maxc, ncols;
  int *order, *free_slot;
  int64_t *slot_window;
  double *V, *W;     /* [maxc][N] */
  double *G;         /* [nf][maxc][maxc]: per-field Gram matrix by slot */
  double *L, *b, *c, *l; /* Cholesky factor [maxc][maxc], rhs, solution, row */
  int *acc;          /* accepted columns (positions in order) */
};

#define GRAM(a, f, i, j) ((a)->G[((size_t)(f) * (a)->maxc + (size_t)(i)) * (a)->maxc + (size_t)(j)])

cpl_accel *cpl_accel_create(const cpl_implicit *opt, int nf, const int64_t *len,
                            proto_err *err) {
  cpl_accel *a = calloc(1, sizeof *a);
  if (!a || nf > CPL_ACCEL_MAX_FIELDS) {
    free(a);
    proto_fail(err, "out of memory (acceleration)");
    return NULL;
  }
  a->opt = *opt;
  a->nf = nf;
  for (int f = 0; f < nf; f++) {
    a->len[f] = len[f];
    a->off[f] = a->N;
    a->N += len[f];
  }
  size_t n = (size_t)a->N + 1;
  a->maxc = opt->acceleration == CPL_ACCEL_IQN_ILS ? (int)opt->max_columns : 0;
  size_t mc = (size_t)a->maxc + 1;
  a->r = calloc(n, sizeof(double));
  a->r_prev = calloc(n, sizeof(double));
  a->xt = calloc(n, sizeof(double));
  a->xt_prev = calloc(n, sizeof(double));
  a->order = calloc(mc, sizeof(int));
  a->free_slot = calloc(mc, sizeof(int));
  a->slot_window = calloc(mc, sizeof(int64_t));
  a->V = calloc(mc * n, sizeof(double));
  a->W = calloc(mc * n, sizeof(double));
  a->G = calloc((size_t)(nf ? nf : 1) * mc * mc, sizeof(double));
  a->L = calloc(mc * mc, sizeof(double));
  a->b = calloc(mc, sizeof(double));
  a->c = calloc(mc, sizeof(double));
  a->l = calloc(mc, sizeof(double));
  a->acc = calloc(mc, sizeof(int));
  if (!a->r || !a->r_prev || !a->xt || !a->xt_prev || !a->order || !a->free_slot ||
      !a->slot_window || !a->V || !a->W || !a->G || !a->L || !a->b || !a->c || !a->l ||
      !a->acc) {
    cpl_accel_free(a);
    proto_fail(err, "out of memory (acceleration: %d columns of %lld values)", a->maxc,
               (long long)a->N);
    return NULL;
  }
  for (int s = 0; s < a->maxc; s++) a->free_slot[s] = 1;
  a->omega_last = opt->relaxation;
  return a;
}

void cpl_accel_free(cpl_accel *a) {
  if (!a) return;
  free(a->r), free(a->r_prev), free(a->xt), free(a->xt_prev);
  free(a->order), free(a->free_slot), free(a->slot_window);
  free(a->V), free(a->W), free(a->G), free(a->L), free(a->b), free(a->c), free(a->l);
  free(a->acc);
  free(a);
}

int cpl_accel_columns(const cpl_accel *a) { return a ? a->ncols : 0; }

/* weighted dot product Σ_f w_f² (u·v)_f */
static double wdot(const cpl_accel *a, const double *u, const double *v) {
  double s = 0;
  for (int f = 0; f < a->nf; f++) {
    double d = 0;
    for (int64_t j = a->off[f]; j < a->off[f] + a->len[f]; j++) d += u[j] * v[j];
    s += a->w2[f] * d;
  }
  return s;
}

static void drop_column(cpl_accel *a, int pos) {
  a->free_slot[a->order[pos]] = 1;
  memmove(a->order + pos, a->order + pos + 1, sizeof(int) * (size_t)(a->ncols - pos - 1));
  a->ncols--;
}

/* Drops the columns of steps before `oldest`. */
static void drop_before(cpl_accel *a, int64_t oldest) {
  for (int p = a->ncols - 1; p >= 0; p--)
    if (a->slot_window[a->order[p]] < oldest) drop_column(a, p);
}

/* New column (r − r_prev, x̃ − x̃_prev) at the front; the oldest goes when
 * full. Its Gram entries with every kept column, per field. */
static void add_column(cpl_accel *a) {
  if (a->ncols == a->maxc) drop_column(a, a->ncols - 1);
  int s = 0;
  while (!a->free_slot[s]) s++;
  a->free_slot[s] = 0;
  double *v = a->V + (size_t)s * a->N, *w = a->W + (size_t)s * a->N;
  for (int64_t j = 0; j < a->N; j++) {
    v[j] = a->r[j] - a->r_prev[j];
    w[j] = a->xt[j] - a->xt_prev[j];
  }
  memmove(a->order + 1, a->order, sizeof(int) * (size_t)a->ncols);
  a->order[0] = s;
  a->ncols++;
  a->slot_window[s] = a->window;
  for (int p = 0; p < a->ncols; p++) {
    int t = a->order[p];
    const double *u = a->V + (size_t)t * a->N;
    for (int f = 0; f < a->nf; f++) {
      double d = 0;
      for (int64_t j = a->off[f]; j < a->off[f] + a->len[f]; j++) d += v[j] * u[j];
      GRAM(a, f, s, t) = GRAM(a, f, t, s) = d;
    }
  }
}

static double gram(const cpl_accel *a, int s, int t) {
  double g = 0;
  for (int f = 0; f < a->nf; f++) g += a->w2[f] * GRAM(a, f, s, t);
  return g;
}

/* QR2 filter and least squares: x ← x̃ + W c with c = argmin |V c + r|_w. */
static void iqn_step(cpl_accel *a, double *x) {
  const int mc = a->maxc;
  int nacc = 0;
  const double eps2 = a->opt.filter * a->opt.filter;
  for (int p = 0; p < a->ncols;) {
    int s = a->order[p];
    double gss = gram(a, s, s), d = gss;
    for (int q = 0; q < nacc; q++) {
      double v = gram(a, s, a->order[a->acc[q]]);
      for (int o = 0; o < q; o++) v -= a->L[q * mc + o] * a->l[o];
      a->l[q] = v / a->L[q * mc + q];
      d -= a->l[q] * a->l[q];
    }
    if (!(gss > 0) || d <= eps2 * gss) { /* nearly dependent on newer columns */
      drop_column(a, p);
      continue;
    }
    for (int q = 0; q < nacc; q++) a->L[nacc * mc + q] = a->l[q];
    a->L[nacc * mc + nacc] = sqrt(d);
    a->acc[nacc++] = p;
    p++;
  }
  /* L Lᵀ c = −Vᵀ W r */
  for (int q = 0; q < nacc; q++) {
    double v = -wdot(a, a->V + (size_t)a->order[a->acc[q]] * a->N, a->r);
    for (int o = 0; o < q; o++) v -= a->L[q * mc + o] * a->b[o];
    a->b[q] = v / a->L[q * mc + q];
  }
  for (int q = nacc - 1; q >= 0; q--) {
    double v = a->b[q];
    for (int o = q + 1; o < nacc; o++) v -= a->L[o * mc + q] * a->c[o];
    a->c[q] = v / a->L[q * mc + q];
  }
  memcpy(x, a->xt, sizeof(double) * (size_t)a->N);
  for (int q = 0; q < nacc; q++) {
    const double *w = a->W + (size_t)a->order[a->acc[q]] * a->N, cq = a->c[q];
    for (int64_t j = 0; j < a->N; j++) x[j] += cq * w[j];
  }
}

void cpl_accel_begin(cpl_accel *a) {
  a->iter = 0;
  a->converged = 0;
  for (int f = 0; f < a->nf; f++) a->sumw[f] = 0;
  if (a->maxc) drop_before(a, a->window - (a->opt.reuse > 0 ? a->opt.reuse : 1));
}

int cpl_accel_next(cpl_accel *a, double *x, const double *xt,
                   const double *const *base, double *res) {
  double rn[CPL_ACCEL_MAX_FIELDS], total = 0;
  int converged = 1;
  memcpy(a->xt, xt, sizeof(double) * (size_t)a->N);
  for (int f = 0; f < a->nf; f++) {
    double r2 = 0, d2 = 0;
    for (int64_t j = a->off[f]; j < a->off[f] + a->len[f]; j++) {
      double rj = xt[j] - x[j], dj = xt[j] - (base[f] ? base[f][j - a->off[f]] : 0);
      a->r[j] = rj;
      r2 += rj * rj;
      d2 += dj * dj;
    }
    rn[f] = sqrt(r2);
    total += r2;
    /* the first non-zero residual: a field whose first residual was exactly
     * zero (no grain touched the tread for the guess) may get one from the
     * acceleration's coupling of the fields, and must then be measured
     * against it (else its relative residual stays infinite) */
    if (a->iter == 0 || a->r0[f] == 0) a->r0[f] = rn[f];
    const double scale = fmax(sqrt(d2), a->iter > 0 ? a->r0[f] : 0);
    res[f] = scale > 0 ? rn[f] / scale : r2 > 0 ? INFINITY : 0;
    a->field_ok[f] = rn[f] <= a->opt.tolerance * scale;
    if (!a->field_ok[f]) converged = 0;
  }
  a->converged = converged;
  if (converged) return 1;
  /* residual-sum preconditioner: w_f = 1 / Σ_k |r_f,k| / |r_k| over the step */
  total = sqrt(total);
  for (int f = 0; f < a->nf; f++) {
    a->sumw[f] += total > 0 ? rn[f] / total : 0;
    a->w2[f] = a->sumw[f] > 0 ? 1.0 / (a->sumw[f] * a->sumw[f]) : 1.0;
  }
  switch (a->opt.acceleration) {
  case CPL_ACCEL_CONSTANT:
    for (int64_t j = 0; j < a->N; j++) x[j] += a->opt.relaxation * a->r[j];
    break;
  case CPL_ACCEL_AITKEN:
    if (a->iter == 0) {
      double w0 = fmin(a->opt.relaxation, fabs(a->omega_last));
      a->omega = a->omega_last < 0 ? -w0 : w0;
    } else {
      double *dr = a->xt_prev; /* scratch: Aitken keeps no x̃ history */
      for (int64_t j = 0; j < a->N; j++) dr[j] = a->r[j] - a->r_prev[j];
      double num = wdot(a, a->r_prev, dr), den = wdot(a, dr, dr);
      if (den > 0) a->omega = -a->omega * num / den;
    }
    for (int64_t j = 0; j < a->N; j++) x[j] += a->omega * a->r[j];
    break;
  case CPL_ACCEL_IQN_ILS:
    if (a->iter > 0) add_column(a);
    if (a->opt.reuse == 0 && a->iter == 1) drop_before(a, a->window);
    if (a->ncols == 0)
      for (int64_t j = 0; j < a->N; j++) x[j] += a->opt.relaxation * a->r[j];
    else
      iqn_step(a, x);
    memcpy(a->xt_prev, a->xt, sizeof(double) * (size_t)a->N);
    break;
  }
  /* a field that has already converged takes its last output as it is:
   * the others' acceleration must not move it (a force field that is zero
   * because the grains left stays exactly zero, so the impulses balance
   * exactly; columns record the inputs actually used, so IQN stays valid) */
  for (int f = 0; f < a->nf; f++)
    if (a->field_ok[f])
      memcpy(x + a->off[f], xt + a->off[f], sizeof(double) * (size_t)a->len[f]);
  memcpy(a->r_prev, a->r, sizeof(double) * (size_t)a->N);
  a->iter++;
  return 0;
}

void cpl_accel_end(cpl_accel *a) {
  /* IQN-ILS: the last difference pair of a converged step is kept too */
  if (a->opt.acceleration == CPL_ACCEL_IQN_ILS && a->iter > 0 && a->converged)
    add_column(a);
  if (a->opt.acceleration == CPL_ACCEL_AITKEN) a->omega_last = a->omega;
  a->window++;
}

int cpl_accel_state(cpl_accel *a, cpl_stateval *v, int cap) {
  if (!a) return 0;
  const int64_t mc = a->maxc, cols = mc * a->N;
  /* the columns and their Gram entries by slot, which slots are in use and
   * in what order, the steps begun; Aitken's last factor. The rest is
   * rebuilt within each step. */
  const cpl_stateval all[] = {
      {"accel.window", PROTO_I8, &a->window, 1},
      {"accel.ncols", PROTO_I4, &a->ncols, 1},
      {"accel.omega_last", PROTO_F8, &a->omega_last, 1},
      {"accel.order", PROTO_I4, a->order, mc},
      {"accel.free_slot", PROTO_I4, a->free_slot, mc},
      {"accel.slot_window", PROTO_I8, a->slot_window, mc},
      {"accel.V", PROTO_F8, a->V, cols},
      {"accel.W", PROTO_F8, a->W, cols},
      {"accel.G", PROTO_F8, a->G, (int64_t)a->nf * mc * mc},
  };
  int n = (int)(sizeof all / sizeof all[0]);
  if (n > cap) n = cap;
  memcpy(v, all, sizeof(cpl_stateval) * (size_t)n);
  return n;
}
