/* dem_force.c — contact forces: grain–grain pairs over the half list, then a
 * per-grain sweep (cross-chunk pair shares, meshes, plane walls, and in
 * dem_step the second half kick), in a fixed order that does not depend on
 * the number of threads, so results are bitwise identical for any number
 * (gravity enters the kick as an acceleration).
 * Grains are in fixed chunks of DEM_CHUNK slots (Morton-sorted, dem_neigh.c):
 * a chunk's rows run in descending slot order and add each pair's share to
 * its partner at once when the partner is in the same chunk (most pairs);
 * shares crossing into a later chunk are stored per pair and summed by the
 * partner's sweep, after a barrier, through the reverse index. A thread owns
 * whole chunks: no two threads write the same grain, no atomics, no
 * per-thread copies.
 * Speed (bench/results/dem.md): touching pairs and wall contacts are gathered
 * into small structure-of-arrays batches and the contact law (then the
 * rolling torque, from the batch's own ω copies) runs over a batch as one
 * branch-free loop that the compiler vectorises (AVX2 clone when
 * the CPU has it; same IEEE operations, so the same results); open pairs cost
 * one distance test (no history read unless they touched last step). */
#include "dem_server/dem_internal.h"

#include <string.h>

/* Touching pairs are evaluated DEM_BATCH at a time, structure of arrays, so
 * the contact law runs as a branch-free loop the compiler vectorises; a row
 * is screened DEM_ROW_BLOCK pairs at a time straight into the batch. */
#define DEM_BATCH 64
#define DEM_ROW_BLOCK 32
/* Rows run in descending slot order and each row's pairs ascending, which
 * the hardware prefetcher does not follow: the springs of the row this many
 * rows on are fetched while a row is screened (their loads were the sweep's
 * hottest cache misses on the sand scene: 14 % of its samples, 2 % after).
 * Fetching the partners' positions and velocities too was slower (stop 59,
 * bench/results/tire_soil.md "The pair sweep's cache misses"). */
#define DEM_ROW_AHEAD 4

typedef struct pair_batch {
  int n, i[DEM_BATCH], j[DEM_BATCH], k[DEM_BATCH];
  /* in: d = x_i − x_j, v_i − v_j, ω_i, ω_j, spring (out: updated) */
  double d[3][DEM_BATCH], dv[3][DEM_BATCH], oi[3][DEM_BATCH], oj[3][DEM_BATCH], sh[3][DEM_BATCH];
  double ri[DEM_BATCH], rj[DEM_BATCH], isum[DEM_BATCH]; /* isum = 1/m_i + 1/m_j */
  double Estar[DEM_BATCH], Gstar[DEM_BATCH], damp_n[DEM_BATCH], damp_t[DEM_BATCH], mu[DEM_BATCH];
  double mu_roll[DEM_BATCH];
  /* out: F on i, (r_i − δ/2) c and (r_j − δ/2) c with c = n × F_t (torques −those
   * on i and j, eq. 7), F_n, elastic energy, R*, overlap ratio, rolling
   * torque on i (dem_rolling; −it on j; set only when the scene has rolling) */
  double F[3][DEM_BATCH], ci[3][DEM_BATCH], cj[3][DEM_BATCH], Fn[DEM_BATCH], up[DEM_BATCH];
  double rstar[DEM_BATCH], rr[DEM_BATCH], roll[3][DEM_BATCH];
} pair_batch;

/* Grain i's running sums over its own pairs (list order). */
typedef struct row_sum {
  int i, cnt;
  double f[3], t[3], u, ratio;
} row_sum;

static void law_set(pair_batch *b, int q, const dem_pair_law *l) {
  b->Estar[q] = l->Estar; b->Gstar[q] = l->Gstar; b->damp_n[q] = l->damp_n; b->damp_t[q] = l->damp_t;
  b->mu[q] = l->mu; b->mu_roll[q] = l->mu_roll;
}

/* Pair k opened: its spring is deleted, and a share it stored for a partner
 * in a later chunk is zeroed (the partner's sweep sums its slot whether the
 * pair touches or not; x − 0 is x). */
static void pair_opened(struct dem_work *w, int k) {
  memset(&w->nl_shear[3 * k], 0, 3 * sizeof(double));
  const int q = w->rev_of[k];
  if (q < 0) return;
  memset(&w->rev_ft[6 * q], 0, 6 * sizeof(double));
  if (w->rev_roll) memset(&w->rev_roll[3 * q], 0, 3 * sizeof(double));
}

/* Appends the touching pairs among k0..k1 of row i (list order; every pair
 * is written, the count advances only when it touches: no branch); open
 * pairs lose their spring (history deleted, as in LIGGGHTS 3.8
 * `src/tangential_model_history.h`) if they touched. */
static void screen_block(const dem_state *s, struct dem_work *w, int i, int k0, int k1,
                         pair_batch *restrict b) {
  const double *restrict x = s->x, *restrict rad = s->radius;
  const int *restrict nl_j = w->nl_j;
  uint8_t *restrict touched = w->pair_touch;
  const double xi0 = x[3 * i], xi1 = x[3 * i + 1], xi2 = x[3 * i + 2], ri = rad[i];
  int q = b->n;
  for (int k = k0; k < k1; k++) {
    const int j = nl_j[k];
    const double d0 = xi0 - x[3 * j], d1 = xi1 - x[3 * j + 1], d2 = xi2 - x[3 * j + 2];
    const double rj = rad[j], rsum = ri + rj, dd = d0 * d0 + d1 * d1 + d2 * d2;
    const int touch = dd < rsum * rsum;
    if ((touch ^ 1) & touched[k]) pair_opened(w, k); /* rare */
    touched[k] = (uint8_t)touch;
    b->j[q] = j; b->k[q] = k;
    b->d[0][q] = d0; b->d[1][q] = d1; b->d[2][q] = d2;
    b->rj[q] = rj;
    q += touch;
  }
  b->n = q;
}

/* screen_block for the asleep partners of awake grain i (the end of its
 * row: slots >= n_active): such a contact is evaluated as with a fixed grain
 * (its share is not added to the asleep one), and the asleep grain is woken
 * when i moves faster than sleep.wake_velocity (default DEM_WAKE_FACTOR × the
 * sleep velocity; listed: within r_i + r_j + skin at the last rebuild, so
 * before they touch) or presses into it beyond
 * sleep.overlap of the smaller radius (a sleeping grain is a fixed one: under
 * a slowly growing load its overlap would grow without bound instead of the
 * load spreading into the bed). */
static void screen_block_asleep(const dem_model *m, const dem_state *s, struct dem_work *w, int i, int k0, int k1,
                                pair_batch *restrict b) {
  const double *restrict x = s->x, *restrict rad = s->radius;
  const double vw = m->sleep.wake_velocity, vs2 = vw * vw, wake_ov = m->sleep.overlap;
  const double xi0 = x[3 * i], xi1 = x[3 * i + 1], xi2 = x[3 * i + 2], ri = rad[i];
  const int fast = dem_dot(&s->v[3 * i], &s->v[3 * i]) > vs2;
  int q = b->n;
  for (int k = k0; k < k1; k++) {
    const int j = w->nl_j[k];
    const double d0 = xi0 - x[3 * j], d1 = xi1 - x[3 * j + 1], d2 = xi2 - x[3 * j + 2];
    const double rj = rad[j], rsum = ri + rj, dd = d0 * d0 + d1 * d1 + d2 * d2;
    const int touch = dd < rsum * rsum;
    if ((touch ^ 1) & w->pair_touch[k]) memset(&w->nl_shear[3 * k], 0, 3 * sizeof(double));
    w->pair_touch[k] = (uint8_t)touch;
    const double rmin = ri < rj ? ri : rj, reach = rsum - wake_ov * rmin; /* overlap > wake_ov rmin */
    if (fast || (touch && reach > 0 && dd < reach * reach)) dem_wake(w, j);
    b->j[q] = j; b->k[q] = k;
    b->d[0][q] = d0; b->d[1][q] = d1; b->d[2][q] = d2;
    b->rj[q] = rj;
    q += touch;
  }
  b->n = q;
}

/* The rest of the inputs of entries q0.. (all of row i). For asleep
 * partners (asleep = 1: the end of an awake row) v_j = ω_j = 0, as dem_sleep.c
 * zeroes them when j falls asleep: the same values, bit for bit (x - 0.0 is
 * x), without loading them (the asleep block lies far from the awake rows in
 * memory: those loads were cache misses). Inlined with a constant asleep. */
static inline __attribute__((always_inline)) void batch_fill(const dem_model *m, const dem_state *s,
                                                              pair_batch *restrict b, int i, int q0, int one_law,
                                                              int asleep) {
  const struct dem_work *w = s->work;
  const double *vi = &s->v[3 * i], *oi = &s->omega[3 * i], ri = s->radius[i], imi = s->inv_mass[i];
  for (int q = q0; q < b->n; q++) {
    const int j = b->j[q], k = b->k[q];
    b->i[q] = i;
    for (int a = 0; a < 3; a++) {
      b->dv[a][q] = vi[a] - (asleep ? 0.0 : s->v[3 * j + a]);
      b->oi[a][q] = oi[a];
      b->oj[a][q] = asleep ? 0.0 : s->omega[3 * j + a];
      b->sh[a][q] = w->nl_shear[3 * k + a];
    }
    b->ri[q] = ri;
    b->isum[q] = imi + s->inv_mass[j];
    if (!one_law) law_set(b, q, &m->law[s->material[i]][s->material[j]]);
  }
}

/* Pair geometry (eq. 10–18) and contact law of a batch, as one branch-free
 * loop the compiler vectorises (IEEE results as in scalar code). */
__attribute__((target_clones("avx2", "default")))
static void batch_hertz(pair_batch *restrict b, double dt, int clamp, int rolling) {
  const int nb = b->n;
  for (int q = 0; q < nb; q++) {
    const double d0 = b->d[0][q], d1 = b->d[1][q], d2 = b->d[2][q];
    const double ri = b->ri[q], rj = b->rj[q], rsum = ri + rj;
    const double dist = sqrt(d0 * d0 + d1 * d1 + d2 * d2);
    const double rinv = 1.0 / dist;
    const int far = dist > 0;                               /* eq. 10: n from j to i */
    const double n0 = far ? d0 * rinv : 0, n1 = far ? d1 * rinv : 0, n2 = far ? d2 * rinv : 1;
    const double delta = rsum - dist;                       /* eq. 18 */
    /* eq. 16–17 with one division: R* = r_i r_j / (r_i + r_j), m* = 1/(1/m_i + 1/m_j) */
    const double isum = b->isum[q], inv_den = 1.0 / (rsum * isum);
    const double rstar = ri * rj * isum * inv_den, mstar = rsum * inv_den;
    /* eq. 11–12: contact points in the middle of the overlap */
    const double cri = ri - 0.5 * delta, crj = rj - 0.5 * delta;
    const double w0 = cri * b->oi[0][q] + crj * b->oj[0][q], w1 = cri * b->oi[1][q] + crj * b->oj[1][q],
                 w2 = cri * b->oi[2][q] + crj * b->oj[2][q];
    const double vc0 = b->dv[0][q] + (n1 * w2 - n2 * w1), vc1 = b->dv[1][q] + (n2 * w0 - n0 * w2),
                 vc2 = b->dv[2][q] + (n0 * w1 - n1 * w0);
    const dem_pair_law l = {.Estar = b->Estar[q], .Gstar = b->Gstar[q], .mu = b->mu[q],
                            .damp_n = b->damp_n[q], .damp_t = b->damp_t[q], .clamp = clamp};
    const double n[3] = {n0, n1, n2}, vc[3] = {vc0, vc1, vc2};
    double sh[3] = {b->sh[0][q], b->sh[1][q], b->sh[2][q]}, F[3], c[3], up;
    const double Fn = dem_hertz(&l, delta, rstar, mstar, n, vc, dt, sh, F, c, &up);
    for (int a = 0; a < 3; a++) {
      b->sh[a][q] = sh[a]; b->F[a][q] = F[a]; b->ci[a][q] = cri * c[a]; b->cj[a][q] = crj * c[a];
    }
    b->Fn[q] = Fn;
    b->up[q] = up;
    b->rstar[q] = rstar;
    b->rr[q] = delta / (ri < rj ? ri : rj);
  }
  if (rolling) /* on ω_i − ω_j as batch_fill copied them (an asleep j's are 0, as stored) */
    for (int q = 0; q < nb; q++) {
      const dem_pair_law l = {.mu_roll = b->mu_roll[q]};
      const double wrel[3] = {b->oi[0][q] - b->oj[0][q], b->oi[1][q] - b->oj[1][q], b->oi[2][q] - b->oj[2][q]};
      double roll[3];
      dem_rolling(&l, b->Fn[q], b->rstar[q], wrel, roll);
      b->roll[0][q] = roll[0]; b->roll[1][q] = roll[1]; b->roll[2][q] = roll[2];
    }
}

/* Grain i's own-pair sums become its force and torque (rows run in
 * descending i, so nothing was added to i yet). */
static inline void row_finish(dem_state *s, const row_sum *r, dem_chunk_sum *sum) {
  double *f = &s->force[3 * r->i], *t = &s->torque[3 * r->i];
  f[0] = r->f[0]; f[1] = r->f[1]; f[2] = r->f[2];
  t[0] = r->t[0]; t[1] = r->t[1]; t[2] = r->t[2];
  s->work->ratio[r->i] = r->ratio;
  sum->u += r->u;
  sum->pair_contacts += r->cnt;
}

/* A row without touching pairs (most grains in flight). */
static inline void row_empty(dem_state *s, int i) {
  double *f = &s->force[3 * i], *t = &s->torque[3 * i];
  f[0] = f[1] = f[2] = t[0] = t[1] = t[2] = 0;
  s->work->ratio[i] = 0;
}

/* Evaluates the batch and sums it in order: torque on i −(r_i − δ/2) n × F_t,
 * on j −(r_j − δ/2) n × F_t; j's share is added at once when j is in this
 * chunk (j < hi; its own sum is in place: rows run in descending i), else
 * stored for the partner's sweep (gather_chunk). The running row sum is in
 * scalars (a struct on the stack costs store-forwarding stalls). */
static void batch_flush(const dem_model *m, dem_state *s, pair_batch *b, row_sum *r, int hi,
                        dem_chunk_sum *sum) {
  struct dem_work *w = s->work;
  double *restrict shear = w->nl_shear, *restrict force = s->force, *restrict torque = s->torque;
  double *restrict pft = w->pair_ft;
  const int rolling = m->has_rolling;
  int ci = r->i, cnt = r->cnt;
  double f0 = r->f[0], f1 = r->f[1], f2 = r->f[2], t0 = r->t[0], t1 = r->t[1], t2 = r->t[2];
  double u = r->u, ratio = r->ratio;
  batch_hertz(b, s->dt, m->limit_force, rolling);
  for (int q = 0; q < b->n; q++) {
    const int i = b->i[q], k = b->k[q], j = b->j[q];
    if (i != ci) {
      if (ci >= 0) row_finish(s, &(row_sum){ci, cnt, {f0, f1, f2}, {t0, t1, t2}, u, ratio}, sum);
      ci = i;
      cnt = 0;
      f0 = f1 = f2 = t0 = t1 = t2 = u = ratio = 0;
    }
    const double F0 = b->F[0][q], F1 = b->F[1][q], F2 = b->F[2][q];
    shear[3 * k] = b->sh[0][q]; shear[3 * k + 1] = b->sh[1][q]; shear[3 * k + 2] = b->sh[2][q];
    f0 += F0; f1 += F1; f2 += F2;
    t0 -= b->ci[0][q]; t1 -= b->ci[1][q]; t2 -= b->ci[2][q];
    double roll[3] = {0, 0, 0};
    const int rolls = rolling && b->mu_roll[q] > 0;
    if (rolls) {
      roll[0] = b->roll[0][q]; roll[1] = b->roll[1][q]; roll[2] = b->roll[2][q];
      t0 += roll[0]; t1 += roll[1]; t2 += roll[2];
    }
    if (j < hi) {
      double *fj = &force[3 * j], *tj = &torque[3 * j];
      fj[0] -= F0; fj[1] -= F1; fj[2] -= F2;
      tj[0] -= b->cj[0][q]; tj[1] -= b->cj[1][q]; tj[2] -= b->cj[2][q];
      if (rolls) { tj[0] -= roll[0]; tj[1] -= roll[1]; tj[2] -= roll[2]; }
    } else { /* an awake partner's share in its reverse slot, an asleep one's by pair (dem_sleep_push.c) */
      const int rq = w->rev_of[k];
      double *p = rq >= 0 ? &w->rev_ft[6 * rq] : &pft[6 * k];
      p[0] = F0; p[1] = F1; p[2] = F2; p[3] = b->cj[0][q]; p[4] = b->cj[1][q]; p[5] = b->cj[2][q];
      if (rolling) memcpy(rq >= 0 ? &w->rev_roll[3 * rq] : &w->pair_roll[3 * k], roll, sizeof roll);
    }
    u += b->up[q];
    cnt++;
    ratio = b->rr[q] > ratio ? b->rr[q] : ratio;
  }
  *r = (row_sum){ci, cnt, {f0, f1, f2}, {t0, t1, t2}, u, ratio};
  b->n = 0;
}

/* Summation order, the same for any number of threads: a grain's force is
 * the sum of its own pairs (j > i, list order), minus the partner shares of
 * the pairs (i', i), i' < i, of its own chunk in descending i', then those of
 * earlier chunks in descending i'; then meshes, planes. Rows lo..hi−1 (one
 * chunk) in descending i. */
static void pair_rows(const dem_model *m, dem_state *s, int lo, int hi, dem_chunk_sum *sum) {
  struct dem_work *w = s->work;
  pair_batch b;
  row_sum r = {.i = -1};
  /* one material for every grain (the meshes' may differ): the law entries are set once */
  const int gl = m->n_materials == 1 ? 0 : w->grain_law, one_law = gl >= 0;
  b.n = 0;
  if (one_law)
    for (int q = 0; q < DEM_BATCH; q++) law_set(&b, q, &m->law[gl][gl]);
  const int na = w->n_active; /* rows of awake grains only; their asleep partners end each row */
  if (hi > na) hi = na;
  for (int i = hi - 1; i >= lo; i--) {
    const int kbeg = w->nl_start[i], kend = w->nl_start[i + 1];
    if (i - DEM_ROW_AHEAD >= lo) { /* the row DEM_ROW_AHEAD on: its pairs' springs and flags */
      const int ka = w->nl_start[i - DEM_ROW_AHEAD], kb = w->nl_start[i - DEM_ROW_AHEAD + 1];
      if (ka < kb) { /* (no pairs at all: the arrays may not exist) */
        __builtin_prefetch(&w->nl_j[ka]);
        __builtin_prefetch(&w->pair_touch[ka], 1);
        for (int k = ka; k < kb; k += 2) __builtin_prefetch(&w->nl_shear[3 * k], 1);
      }
    }
    const int kas = dem_row_asleep(w, i, na);
    int found = 0;
    for (int k0 = kbeg; k0 < kend;) {
      const int lim = k0 < kas ? kas : kend;
      const int k1 = lim - k0 > DEM_ROW_BLOCK ? k0 + DEM_ROW_BLOCK : lim;
      if (b.n + (k1 - k0) > DEM_BATCH) batch_flush(m, s, &b, &r, hi, sum);
      const int q0 = b.n;
      if (k0 < kas) {
        screen_block(s, w, i, k0, k1, &b);
        batch_fill(m, s, &b, i, q0, one_law, 0);
      } else {
        screen_block_asleep(m, s, w, i, k0, k1, &b);
        batch_fill(m, s, &b, i, q0, one_law, 1);
      }
      found += b.n - q0;
      k0 = k1;
    }
    if (!found) row_empty(s, i); /* no share into i is pending */
  }
  batch_flush(m, s, &b, &r, hi, sum);
  if (r.i >= 0) row_finish(s, &r, sum);
}

/* Plane contacts (wall: R* = r_i, m* = m_i, no wall motion), batched like the
 * pairs: a chunk's grains in order, each grain's planes in index order. */
typedef struct wall_batch {
  int n, i[DEM_BATCH], p[DEM_BATCH];
  double delta[DEM_BATCH], r[DEM_BATCH], mass[DEM_BATCH];
  double nrm[3][DEM_BATCH], v[3][DEM_BATCH], o[3][DEM_BATCH], sh[3][DEM_BATCH];
  double Estar[DEM_BATCH], Gstar[DEM_BATCH], damp_n[DEM_BATCH], damp_t[DEM_BATCH], mu[DEM_BATCH];
  double F[3][DEM_BATCH], c[3][DEM_BATCH], Fn[DEM_BATCH], up[DEM_BATCH], cr[DEM_BATCH];
} wall_batch;

__attribute__((target_clones("avx2", "default")))
static void batch_wall_hertz(wall_batch *restrict b, double dt, int clamp) {
  const int nb = b->n;
  for (int q = 0; q < nb; q++) {
    const double delta = b->delta[q], r = b->r[q];
    const double cr = r - 0.5 * delta; /* contact point in the middle of the overlap */
    const double o[3] = {b->o[0][q], b->o[1][q], b->o[2][q]};
    const double n[3] = {b->nrm[0][q], b->nrm[1][q], b->nrm[2][q]};
    double wxn[3], vc[3];
    dem_cross(o, n, wxn);
    for (int a = 0; a < 3; a++) vc[a] = b->v[a][q] - cr * wxn[a];
    const dem_pair_law l = {.Estar = b->Estar[q], .Gstar = b->Gstar[q], .mu = b->mu[q],
                            .damp_n = b->damp_n[q], .damp_t = b->damp_t[q], .clamp = clamp};
    double sh[3] = {b->sh[0][q], b->sh[1][q], b->sh[2][q]}, F[3], c[3], up;
    b->Fn[q] = dem_hertz(&l, delta, r, b->mass[q], n, vc, dt, sh, F, c, &up);
    for (int a = 0; a < 3; a++) { b->sh[a][q] = sh[a]; b->F[a][q] = F[a]; b->c[a][q] = c[a]; }
    b->up[q] = up;
    b->cr[q] = cr;
  }
}

/* Evaluates the batch and adds it to the grains (force/torque hold their
 * pair sums) and to the chunk's plane totals, in batch order. */
static void wall_flush(const dem_model *m, dem_state *s, wall_batch *b, double *part, dem_chunk_sum *sum) {
  struct dem_work *w = s->work;
  batch_wall_hertz(b, s->dt, m->limit_force);
  for (int q = 0; q < b->n; q++) {
    const int i = b->i[q], p = b->p[q];
    double *f = &s->force[3 * i], *t = &s->torque[3 * i];
    double *shear = dem_wall_shear(w, s->n, i, p);
    for (int a = 0; a < 3; a++) {
      shear[a] = b->sh[a][q];
      f[a] += b->F[a][q]; t[a] -= b->cr[q] * b->c[a][q]; part[3 * p + a] += b->F[a][q];
    }
    const dem_pair_law *l = &m->law[s->material[i]][m->planes[p].material];
    if (m->has_rolling && l->mu_roll > 0) {
      double tr[3];
      dem_rolling(l, b->Fn[q], b->r[q], &s->omega[3 * i], tr);
      for (int a = 0; a < 3; a++) t[a] += tr[a];
    }
    sum->u += b->up[q];
    sum->wall_contacts++;
    if (b->delta[q] / b->r[q] > w->ratio[i]) w->ratio[i] = b->delta[q] / b->r[q];
  }
  b->n = 0;
}

static void wall_law_set(wall_batch *b, int q, const dem_pair_law *l) {
  b->Estar[q] = l->Estar; b->Gstar[q] = l->Gstar; b->damp_n[q] = l->damp_n; b->damp_t[q] = l->damp_t;
  b->mu[q] = l->mu;
}

/* Touching planes of grain i into the batch; open ones lose their spring. */
static void plane_screen(const dem_model *m, dem_state *s, int i, wall_batch *b, double *part,
                         dem_chunk_sum *sum) {
  struct dem_work *w = s->work;
  const double r = s->radius[i];
  /* only planes within reach at the last rebuild (dem_neigh.c plane mask) */
  for (uint64_t bits = w->plane_mask[i]; bits; bits &= bits - 1) {
    const int p = __builtin_ctzll(bits);
    const dem_plane *pl = &m->planes[p];
    double *shear = dem_wall_shear(w, s->n, i, p);
    double d[3] = {s->x[3 * i] - pl->point[0], s->x[3 * i + 1] - pl->point[1], s->x[3 * i + 2] - pl->point[2]};
    const double delta = r - dem_dot(d, pl->normal);
    const uint64_t bit = (uint64_t)1 << p;
    if (delta <= 0) { /* contact open: history deleted (zero already unless it touched) */
      if (w->plane_touch[i] & bit) memset(shear, 0, 3 * sizeof(double));
      w->plane_touch[i] &= ~bit;
      continue;
    }
    w->plane_touch[i] |= bit;
    if (b->n == DEM_BATCH) wall_flush(m, s, b, part, sum);
    const int q = b->n++;
    const dem_pair_law *l = &m->law[s->material[i]][pl->material];
    b->i[q] = i; b->p[q] = p;
    b->delta[q] = delta; b->r[q] = r; b->mass[q] = w->mass[i];
    for (int a = 0; a < 3; a++) {
      b->nrm[a][q] = pl->normal[a];
      b->v[a][q] = s->v[3 * i + a];
      b->o[a][q] = s->omega[3 * i + a];
      b->sh[a][q] = shear[a];
    }
    if (m->n_materials > 1) wall_law_set(b, q, l); /* else set once in gather_chunk() */
  }
}

/* Second half of velocity Verlet (seed 000 eq. 4–5) for grains lo..hi−1;
 * returns their kinetic energy (summed in grain order). */
static double kick_chunk(const dem_model *m, dem_state *s, int lo, int hi, double *v2max) {
  const struct dem_work *w = s->work;
  const double dt = s->dt, half = 0.5 * dt, *g = m->gravity;
  double ke = 0, v2m = 0;
  if (m->orientation) /* over the step with the mid-step ω (still ω^{n+1/2} here) */
    for (int i = lo; i < hi; i++)
      if (s->inv_inertia[i] > 0) dem_rotate_quaternion(&s->q[4 * i], &s->omega[3 * i], dt);
  for (int i = lo; i < hi; i++) {
    double *v = &s->v[3 * i], *o = &s->omega[3 * i];
    const double *f = &s->force[3 * i], *t = &s->torque[3 * i];
    const double im = s->inv_mass[i], ii = s->inv_inertia[i];
    for (int a = 0; a < 3; a++) {
      v[a] += half * (f[a] * im + g[a]);
      o[a] += half * t[a] * ii;
    }
    const double v2 = dem_dot(v, v);
    ke += 0.5 * (w->mass[i] * v2 + w->inertia[i] * dem_dot(o, o));
    v2m = v2 > v2m ? v2 : v2m;
  }
  *v2max = v2m;
  return ke;
}

/* Per-grain sum in fixed order (own pairs and same-chunk shares, shares from
 * earlier chunks, planes, meshes); plane-wall totals per chunk (a fixed
 * partition, so the sums do not depend on the number of threads). */
static void gather_chunk(const dem_model *m, dem_state *s, int lo, int hi, double *part, int kick,
                         dem_chunk_sum *sum) {
  struct dem_work *w = s->work;
  wall_batch b;
  b.n = 0;
  if (m->n_materials == 1) /* one law for every contact */
    for (int q = 0; q < DEM_BATCH; q++) wall_law_set(&b, q, &m->law[0][0]);
  if (hi > w->n_active) hi = w->n_active; /* asleep grains: no forces needed */
  const int meshes = m->n_meshes > 0 && w->chunk_mesh[lo / DEM_CHUNK]; /* else no candidates, no contacts */
  for (int i = lo; i < hi; i++) {
    /* shares of pairs (i', i) from earlier chunks, descending i' (reverse
     * index order, their slots in sequence); an open pair's slot holds
     * zeros, and subtracting +0 leaves every value as it was */
    const int q0 = w->rev_start[i], q1 = w->rev_start[i + 1];
    if (q0 < q1) {
      double fx = s->force[3 * i], fy = s->force[3 * i + 1], fz = s->force[3 * i + 2];
      double tx = s->torque[3 * i], ty = s->torque[3 * i + 1], tz = s->torque[3 * i + 2];
      for (int q = q0; q < q1; q++) {
        const double *p = &w->rev_ft[6 * q];
        fx -= p[0]; fy -= p[1]; fz -= p[2]; /* Newton's third law */
        tx -= p[3]; ty -= p[4]; tz -= p[5]; /* −(r_j − δ/2) n × F_t */
        if (m->has_rolling) {
          const double *roll = &w->rev_roll[3 * q];
          tx -= roll[0]; ty -= roll[1]; tz -= roll[2];
        }
      }
      s->force[3 * i] = fx; s->force[3 * i + 1] = fy; s->force[3 * i + 2] = fz;
      s->torque[3 * i] = tx; s->torque[3 * i + 1] = ty; s->torque[3 * i + 2] = tz;
    }
    if (meshes) sum->mesh_contacts += dem_mesh_grain(m, s, i, &sum->u);
    plane_screen(m, s, i, &b, part, sum);
  }
  wall_flush(m, s, &b, part, sum);
  for (int i = lo; i < hi; i++) sum->ratio = w->ratio[i] > sum->ratio ? w->ratio[i] : sum->ratio;
  if (meshes) /* gravity is added as an acceleration in the kick */
    for (int i = lo; i < hi; i++)
      for (int a = 0; a < 3; a++) {
        s->force[3 * i + a] += w->mesh_f[3 * i + a];
        s->torque[3 * i + a] += w->mesh_t[3 * i + a];
      }
  if (kick) sum->ke = kick_chunk(m, s, lo, hi, &sum->v2);
  if (w->asleep && kick && !w->settling) dem_sleep_chunk(m, s, lo, hi);
}

void dem_compute_forces(const dem_model *m, dem_state *s, int kick) {
  struct dem_work *w = s->work;
  /* chunks of awake grains only (dem_sleep.c: the asleep ones come last) */
  const int n = w->n_active, np3 = 3 * m->n_planes, nchunk = (n + DEM_CHUNK - 1) / DEM_CHUNK;
  dem_chunk_sum *cs = w->chunk;
  memset(cs, 0, sizeof(dem_chunk_sum) * (size_t)w->nchunk);
#pragma omp parallel num_threads(w->nthreads)
  {
#pragma omp for schedule(dynamic, 1)
    for (int c = 0; c < nchunk; c++)
      pair_rows(m, s, c * DEM_CHUNK, (c + 1) * DEM_CHUNK < n ? (c + 1) * DEM_CHUNK : n, &cs[c]);
    /* (barrier) every pair's share is in place or stored */
#pragma omp for schedule(dynamic, 1)
    for (int c = 0; c < nchunk; c++) {
      double *part = &w->wall_part[(size_t)c * np3];
      memset(part, 0, sizeof(double) * (size_t)np3);
      gather_chunk(m, s, c * DEM_CHUNK, (c + 1) * DEM_CHUNK < n ? (c + 1) * DEM_CHUNK : n, part, kick, &cs[c]);
    }
  }
  memset(s->wall_force, 0, sizeof(double) * 3 * (size_t)(m->n_walls ? m->n_walls : 1));
  int64_t contacts = 0, pairs = 0;
  double ratio = 0, u = 0, ke = 0, v2 = 0;
  for (int c = 0; c < nchunk; c++) {
    for (int p = 0; p < m->n_planes; p++)
      for (int a = 0; a < 3; a++)
        s->wall_force[3 * m->planes[p].wall + a] -= w->wall_part[(size_t)c * np3 + 3 * p + a];
    contacts += cs[c].pair_contacts + cs[c].wall_contacts + cs[c].mesh_contacts;
    pairs += cs[c].pair_contacts;
    u += cs[c].u;
    ke += cs[c].ke;
    v2 = cs[c].v2 > v2 ? cs[c].v2 : v2;
    ratio = cs[c].ratio > ratio ? cs[c].ratio : ratio;
  }
  if (m->n_meshes > 0) dem_mesh_reactions(m, s);
  if (w->asleep) s->sleeping = s->n - n;
  s->contacts = contacts;
  w->pair_contacts = pairs;
  s->max_overlap_ratio = ratio;
  s->elastic_energy = u;
  if (kick) {
    s->kinetic_energy = ke;
    w->kick_v2 = v2; /* dem_reach_box */
  }
}
