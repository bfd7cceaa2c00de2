/* spring_law.c — the roughness-spring law, the one home of it for green and
 * contact_block: the force of a spring at compression d from its knot table
 * (monotone cubic Hermite, pchip.c; linear beyond the last knot,
 * FORMATS.md), and adhesion as the mirrored branch with a release force
 * (seed 002 ch. 5.1, fig. 13 and 39). */
#include "green/green.h"

void grn_spring_compressed(const grn_spring_table *t, double scale, double d, double *F,
                           double *k) {
  if (d <= 0) { /* not compressed (NaN goes on to the table: stays NaN) */
    *F = 0;
    *k = 0;
    return;
  }
  const int K = t->K;
  if (d >= t->d[K - 1]) { /* linear extension with the last slope */
    *F = t->F[K - 1] + t->k[K - 1] * (d - t->d[K - 1]);
    *k = t->k[K - 1];
  } else {
    *F = grn_pchip_piece(t->d, t->F, t->k, grn_pchip_interval(K, t->d, d), d, k);
    if (*k < 0) *k = 0; /* monotone data: only round-off can make it negative */
  }
  *F *= scale;
  *k *= scale;
}

void grn_spring_force(const grn_spring_table *t, double scale, double d, int held,
                      double *F, double *k) {
  if (d > 0) {
    grn_spring_compressed(t, scale, d, F, k);
  } else if (held) { /* stretched and still attached: F(d) = −F(−d), k(d) = k(−d) */
    grn_spring_compressed(t, scale, -d, F, k);
    *F = -*F;
  } else {
    *F = 0;
    *k = 0;
  }
}

double grn_spring_eval(const grn_springs *sp, int e, double d, int *attached,
                       double *k) {
  const int K = sp->K;
  const grn_spring_table t = {K, sp->d + (size_t)e * K, sp->F + (size_t)e * K,
                              sp->k + (size_t)e * K};
  double f, slope;
  if (d >= 0) {
    *attached = 1;
    grn_spring_compressed(&t, 1.0, d, &f, &slope);
  } else {
    grn_spring_force(&t, 1.0, d, *attached, &f, &slope);
    if (*attached && grn_spring_released(f, sp->release_force)) {
      *attached = 0;
      f = slope = 0;
    }
  }
  if (k) *k = slope;
  return f;
}
