/* blk_spring.c — the roughness springs as the solvers see them: the law of
 * element e (green's law, green/spring_law.c, on the element's table and
 * scale), its stored energy, its inverse, and the element terms of the
 * convex dual (Legendre transform of the energy). Called by the solvers
 * (blk_dense.c, blk_cg.c) and the model builders (blk_model.c); calls only
 * green. */
#include <math.h>

#include "contact_block/blk_internal.h"

/* Residual of the inverse relative to the force: |F(d) − F| below this is
 * converged (a few ulp of F). */
#define BLK_INVERSE_RES 1e-15
/* Relative Newton step below which the inverse has converged: F(x) is only
 * known to a few ulp, a smaller step is round-off. */
#define BLK_INVERSE_STEP 4e-16
/* Relative width of the bracket of the inverse at which it has converged
 * (about one ulp of d). */
#define BLK_INVERSE_BRACKET 1e-16
/* Newton steps of the warm-started inverse before it falls back to the
 * bracketed one (one or two suffice when the force changed little), and the
 * cap of the bracketed one. */
enum { BLK_INVERSE_WARM_IT = 6, BLK_INVERSE_MAX_IT = 100 };

static grn_spring_table table_of(const blk_model *m, int t) {
  const int K = m->n_knots;
  const grn_spring_table tab = {K, m->spr_d + (size_t)t * K, m->spr_F + (size_t)t * K,
                                m->spr_k + (size_t)t * K};
  return tab;
}

void blk_spring_eval(const blk_model *m, int e, double d, double *F, double *k) {
  if (m->rigid) {
    *F = 0;
    *k = 0;
    return;
  }
  const grn_spring_table t = table_of(m, m->spr_table[e]);
  grn_spring_compressed(&t, m->spr_scale[e], d, F, k);
}

void blk_spring_law(const blk_model *m, const int *held, const double *d, double *F,
                    double *k) {
  for (int e = 0; e < m->M; e++) {
    if (m->rigid) {
      F[e] = 0;
      k[e] = 0;
      continue;
    }
    const grn_spring_table t = table_of(m, m->spr_table[e]);
    grn_spring_force(&t, m->spr_scale[e], d[e], m->adhesion && held[e], &F[e], &k[e]);
  }
}

/* ------------------------------------------------------------ energy */

/* ∫ of the cubic Hermite piece i of table t from its left knot over the
 * fraction x ∈ [0, 1] of the interval. */
static double piece_energy(const blk_model *m, int t, int i, double x) {
  const grn_spring_table tab = table_of(m, t);
  const double *kd = tab.d, *kF = tab.F, *kk = tab.k;
  const double h = kd[i + 1] - kd[i], x2 = x * x, x3 = x2 * x, x4 = x3 * x;
  return h * ((x4 / 2 - x3 + x) * kF[i] + (x4 / 4 - 2 * x3 / 3 + x2 / 2) * h * kk[i] +
              (-x4 / 2 + x3) * kF[i + 1] + (x4 / 4 - x3 / 3) * h * kk[i + 1]);
}

void blk_springs_energies(blk_model *m) {
  const int K = m->n_knots;
  for (int t = 0; t < m->n_tables; t++) {
    double *W = m->spr_W + (size_t)t * K;
    W[0] = 0;
    for (int i = 0; i + 1 < K; i++) W[i + 1] = W[i] + piece_energy(m, t, i, 1.0);
  }
}

/* ∫_0^d F(s) ds of element e (the spring's stored energy W, d ≥ 0): exact
 * integral of the cubic Hermite pieces (knot energies tabulated), linear
 * beyond the last knot. */
double blk_spring_energy(const blk_model *m, int e, double d) {
  if (d <= 0 || m->rigid) return 0;
  const int K = m->n_knots, t = m->spr_table[e];
  const grn_spring_table tab = table_of(m, t);
  const double *kd = tab.d, *kF = tab.F, *kk = tab.k, *W = m->spr_W + (size_t)t * K;
  if (d >= kd[K - 1]) {
    const double s = d - kd[K - 1];
    return m->spr_scale[e] * (W[K - 1] + kF[K - 1] * s + 0.5 * kk[K - 1] * s * s);
  }
  const int i = grn_pchip_interval(K, kd, d);
  return m->spr_scale[e] * (W[i] + piece_energy(m, t, i, (d - kd[i]) / (kd[i + 1] - kd[i])));
}

/* ----------------------------------------------------------- inverse */

/* Newton on scale · F_t(x) = F from *x, the one iteration of both inverses.
 * bracketed: safeguarded in [a, b] (bisection where Newton leaves it), ends
 * converged or after max_it; else (a warm start) gives up, returning 0, on
 * a non-positive slope or step, or after max_it. The root into *x, k at it
 * into *k. */
static int newton_inverse(const grn_spring_table *t, double scale, double F, int bracketed,
                          double a, double b, int max_it, double *x, double *k) {
  double xc = *x, Fx;
  for (int it = 0; it < max_it; it++) {
    grn_spring_compressed(t, scale, xc, &Fx, k);
    const double r = Fx - F;
    if (bracketed) {
      if (r > 0) b = xc; else a = xc;
    }
    if (fabs(r) <= BLK_INVERSE_RES * F || (bracketed && b - a <= BLK_INVERSE_BRACKET * b))
      break;
    double xn;
    if (bracketed) {
      xn = *k > 0 ? xc - r / *k : 0.5 * (a + b);
      if (!(xn > a && xn < b)) xn = 0.5 * (a + b);
    } else {
      if (!(*k > 0)) return 0;
      xn = xc - r / *k;
      if (!(xn > 0)) return 0;
    }
    if (fabs(xn - xc) <= BLK_INVERSE_STEP * xc) { /* below the round-off of F(x) */
      grn_spring_compressed(t, scale, xn, &Fx, k);
      *x = xn;
      return 1;
    }
    xc = xn;
    if (!bracketed && it + 1 == max_it) return 0;
  }
  *x = xc;
  return 1;
}

/* Inverse spring law: the compression d ≥ 0 at which element e carries F ≥ 0
 * (safeguarded Newton on the monotone Hermite piece, in table units). */
double blk_spring_inverse(const blk_model *m, int e, double F) {
  if (F <= 0 || m->rigid) return 0;
  const int K = m->n_knots;
  const grn_spring_table t = table_of(m, m->spr_table[e]);
  const double *kd = t.d, *kF = t.F, *kk = t.k;
  F /= m->spr_scale[e]; /* on the table */
  if (F >= kF[K - 1]) {
    if (kk[K - 1] > 0) return kd[K - 1] + (F - kF[K - 1]) / kk[K - 1];
    return kd[K - 1];
  }
  int lo = 0, hi = K - 1; /* kF[lo] <= F < kF[hi] */
  while (hi - lo > 1) {
    int mid = (lo + hi) / 2;
    if (kF[mid] <= F) lo = mid; else hi = mid;
  }
  const double a = kd[lo], b = kd[hi];
  double x = a + (b - a) * (F - kF[lo]) / (kF[hi] - kF[lo]), k;
  newton_inverse(&t, 1.0, F, 1, a, b, BLK_INVERSE_MAX_IT, &x, &k);
  return x;
}

/* Newton from the previous compression d0 (one or two steps when the force
 * changed little), else the bracketed inverse. k at the result into *k. */
static double inverse_from(const blk_model *m, int e, double F, double d0, double *k) {
  const grn_spring_table t = table_of(m, m->spr_table[e]);
  double x = d0;
  if (d0 > 0 &&
      newton_inverse(&t, m->spr_scale[e], F, 0, 0, 0, BLK_INVERSE_WARM_IT, &x, k))
    return x;
  x = blk_spring_inverse(m, e, F);
  double Fx;
  blk_spring_eval(m, e, x, &Fx, k);
  return x;
}

double blk_spring_inverse_from(const blk_model *m, int e, double F, double d0) {
  if (F <= 0 || m->rigid) return 0;
  double k;
  return inverse_from(m, e, F, d0, &k);
}

/* -------------------------------------------------------------- dual */

double blk_dual_element(const blk_model *m, const blk_work *w, int e, double F,
                        double d_guess, double *d, double *inv_k) {
  if (m->rigid) {
    *d = 0;
    *inv_k = 0;
    return 0;
  }
  const double a = fabs(F);
  double x = 0, kx;
  if (a > 0) { /* warm start only from a compression (d_guess < 0 is a gap) */
    const double d0 = F > 0 ? d_guess : -d_guess;
    x = inverse_from(m, e, a, d0 > 0 ? d0 : 0, &kx);
  } else { /* unloaded: k at the onset d = 0+ */
    const int K = m->n_knots;
    kx = m->spr_scale[e] * m->spr_k[(size_t)m->spr_table[e] * K];
  }
  *inv_k = blk_inverse_stiffness(w, kx);
  *d = F < 0 ? -x : x;
  return a * x - blk_spring_energy(m, e, x); /* Ψ = F d − W(d), Legendre */
}
