/* blk_state_io.c — the block's whole changing state as named arrays, for the
 * rollback of implicit coupling and for checkpoints (proto.h "state_save"):
 * what blk_state_reset resets — the per-element state, the history of past
 * forces (ring, spectra, the delay lines and windows of the partitioned
 * convolution) and the kept Newton factor of the dense methods (chord steps,
 * the tangent's preconditioner) — so that a restored state gives
 * bit-identical steps. The arrays point into the state (no copies); the
 * caller copies. Everything else in blk_work is per-step scratch. */
#include <stdio.h>
#include <string.h>

#include "contact_block/blk_internal.h"

enum { SC_N, SC_D_ROAD, SC_TOTAL, SC_RESIDUAL, SC_NC, SC_ITER, SC_CONV, SC_CUTS,
       SC_FACT, SC_PUSHED, SC_FACT_VALID, SC_FACT_P, SC_STIFFNESS, SC_PRODUCTS, N_SCALARS };
_Static_assert(N_SCALARS <= BLK_STATE_SCALARS, "blk.h: BLK_STATE_SCALARS too small");

static int add(proto_msg *out, const char *name, proto_dtype dt, int64_t n,
               const void *data) {
  return proto_msg_add_prefixed(out, PROTO_P_STATE, name, dt, n, 0, data);
}

static void level_names(int l, char *fdl, char *win) {
  snprintf(fdl, 16, "fdl%d", l);
  snprintf(win, 16, "win%d", l);
}

int blk_state_export(const blk_model *m, const blk_state *s, double *scalars,
                     proto_msg *out, proto_err *err) {
  const blk_work *w = s->work;
  const blk_history *h = &w->hist;
  const int64_t M = m->M;
  const double sc[N_SCALARS] = {
      (double)s->n, s->d_road, s->total_force, s->residual, s->n_contact,
      s->iterations, s->converged, s->line_search_cuts, s->factorizations,
      (double)h->pushed, w->fact_valid, w->fact_P, s->stiffness, s->products};
  memcpy(scalars, sc, sizeof sc);
  int rc = add(out, "scalars", PROTO_F8, N_SCALARS, scalars) |
           add(out, "d_rs", PROTO_F8, M, s->d_rs) | add(out, "force", PROTO_F8, M, s->force) |
           add(out, "d_el", PROTO_F8, M, s->d_el) |
           add(out, "d_el_old", PROTO_F8, M, s->d_el_old) |
           add(out, "attached", PROTO_I4, M, s->attached);
  if (w->A) /* dense methods: the kept factor */
    rc |= add(out, "fact_act", PROTO_I4, M, w->fact_act) |
          add(out, "fact_sk", PROTO_F8, M, w->fact_sk) |
          add(out, "fact", PROTO_F8, (int64_t)w->fact_P * w->fact_P, w->A);
  if (h->nnz) rc |= add(out, "nnz", PROTO_I4, h->Qh, h->nnz);
  if (h->F_ring) rc |= add(out, "F_ring", PROTO_F8, (int64_t)h->Qh * M, h->F_ring);
  if (h->F_hat) rc |= add(out, "F_hat", PROTO_F8, 2 * (int64_t)h->Qh * h->nq, h->F_hat);
  for (int l = 0; l < h->n_lev; l++) {
    const blk_level *lv = &h->lev[l];
    char fdl[16], win[16];
    level_names(l, fdl, win);
    rc |= add(out, fdl, PROTO_F8, 2 * (int64_t)lv->S * 2 * lv->B * h->nq, lv->fdl) |
          add(out, win, PROTO_F8, 2 * (int64_t)2 * lv->B * h->nq, lv->win);
  }
  return rc ? proto_fail(err, "block state: too many arrays for one message") : 0;
}

int blk_state_import(const blk_model *m, blk_state *s, const proto_msg *in,
                     proto_err *err) {
  blk_work *w = s->work;
  blk_history *h = &w->hist;
  const size_t M = (size_t)m->M;
  double sc[N_SCALARS];
  if (proto_state_get(in, "scalars", PROTO_F8, N_SCALARS, sc, err)) return -1;
  const int fact_P = (int)sc[SC_FACT_P];
  if (fact_P < 0 || (w->A && fact_P > w->A_cap))
    return proto_fail(err, "block state: factor size %d outside [0, %d]", fact_P, w->A_cap);
  if (proto_state_get(in, "d_rs", PROTO_F8, M, s->d_rs, err) ||
      proto_state_get(in, "force", PROTO_F8, M, s->force, err) ||
      proto_state_get(in, "d_el", PROTO_F8, M, s->d_el, err) ||
      proto_state_get(in, "d_el_old", PROTO_F8, M, s->d_el_old, err) ||
      proto_state_get(in, "attached", PROTO_I4, M, s->attached, err) ||
      (w->A && (proto_state_get(in, "fact_act", PROTO_I4, M, w->fact_act, err) ||
                proto_state_get(in, "fact_sk", PROTO_F8, M, w->fact_sk, err) ||
                proto_state_get(in, "fact", PROTO_F8, (size_t)fact_P * fact_P, w->A, err))) ||
      (h->nnz && proto_state_get(in, "nnz", PROTO_I4, (size_t)h->Qh, h->nnz, err)) ||
      (h->F_ring && proto_state_get(in, "F_ring", PROTO_F8, (size_t)h->Qh * M, h->F_ring, err)) ||
      (h->F_hat && proto_state_get(in, "F_hat", PROTO_F8, 2 * (size_t)h->Qh * h->nq, h->F_hat, err)))
    return -1;
  for (int l = 0; l < h->n_lev; l++) {
    blk_level *lv = &h->lev[l];
    char fdl[16], win[16];
    level_names(l, fdl, win);
    if (proto_state_get(in, fdl, PROTO_F8, 2 * (size_t)lv->S * 2 * lv->B * h->nq, lv->fdl, err) ||
        proto_state_get(in, win, PROTO_F8, 2 * (size_t)2 * lv->B * h->nq, lv->win, err))
      return -1;
  }
  s->n = (int64_t)sc[SC_N];
  s->d_road = sc[SC_D_ROAD];
  s->total_force = sc[SC_TOTAL];
  s->residual = sc[SC_RESIDUAL];
  s->n_contact = (int)sc[SC_NC];
  s->iterations = (int)sc[SC_ITER];
  s->converged = (int)sc[SC_CONV];
  s->line_search_cuts = (int)sc[SC_CUTS];
  s->factorizations = (int)sc[SC_FACT];
  h->pushed = (int64_t)sc[SC_PUSHED];
  w->fact_valid = (int)sc[SC_FACT_VALID];
  w->fact_P = fact_P;
  s->stiffness = sc[SC_STIFFNESS];
  s->products = (int)sc[SC_PRODUCTS];
  return 0;
}
