/* dem_sleep_push.c — the force rule of sleep: an asleep grain wakes when the
 * push of its awake neighbours has changed, since it fell asleep, by more
 * than `force` times its weight, or their torque on it by more than that
 * weight at its radius (sleep.force; 0: off).
 *
 * Data flow: (pair_ft of the awake–asleep contacts, pair_touch, pair_roll)
 * => (push: per asleep grain the change D of force and torque, wake marks),
 * at the end of a step (dem_sleep_update) when the test or a base needs it,
 * else when something reads it (dem_push_fresh); at a change of the awake set
 * (dem_push_fold, before the rebuild) the D of each asleep grain whose awake
 * neighbours change is kept across it.
 *
 * Why: an asleep grain is a fixed one. Its contacts with other asleep grains
 * are not evaluated and stay as they were (neither moves), so the force and
 * torque it would feel now differ from those it felt at rest (about zero
 * net) by exactly the change in what its awake neighbours exert on it:
 *   D_j = Σ_{i awake} F_ij(now) − Σ_{i awake} F_ij(reference),
 * where a contact's reference is its value when it joined the awake set (at
 * the same positions, so the same force: a woken grain restarts at rest where
 * it slept) or zero for a contact made since; the same for the torque. A
 * real grain under that imbalance accelerates at |D|/m (or spins up: a
 * sphere rolls at the torque its tangential forces leave, and an asleep one
 * does not, as if it had an infinite rolling resistance); asleep, it does
 * not move and the load passes into the frozen bed as into a rigid one
 * (bench/results/tire_soil.md, stop 38: a tyre's bed 3-10 mm stiffer). The
 * overlap rule (sleep.overlap of the smaller radius, dem_force.c) waits for
 * a contact to reach an absolute overlap, about the contact force under a
 * tyre; this rule sees a grain's load grow from its own rest, wherever the
 * bed's static overlaps lie.
 *
 * Book-keeping, by grain id (ids do not move when slots are permuted),
 * DEM_PUSH_REC doubles each in `push`: [DEM_PUSH_B..+5] the base B of force
 * and torque with D = now − B (state 1) or D itself (state 2: the awake set
 * changed; the base is taken at the next gather that sees the grain,
 * B = now − D, so D goes on where it was); [DEM_PUSH_NOW..+5] `now`, the
 * awake neighbours' force and torque at the last gather (zero for a grain it
 * did not see); [DEM_PUSH_STATE] the state, 0 for an awake grain or an
 * asleep one no awake neighbour has touched (B = 0: every such contact is
 * new). A grain falling asleep starts in state 2 with D = 0. A grain that
 * loses every awake contact is not tested until one touches it again (D
 * counts from its last base, which is right then); a neighbour leaving fast
 * wakes it by the velocity rule. The gather is serial, in slot order (over
 * the awake rows with asleep partners, kept from one rebuild to the next):
 * the same bits for any number of threads. */
#include "dem_server/dem_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

int dem_push_alloc(const dem_model *m, dem_state *s, proto_err *err) {
  struct dem_work *w = s->work;
  if (!m->sleep.on) return 0;
  w->push = calloc(DEM_PUSH_REC * (size_t)s->n + 1, sizeof(double));
  w->push_seen = calloc((size_t)s->n + 1, 1);
  w->push_list = malloc(sizeof(int) * ((size_t)s->n + 1));
  w->push_two = calloc((size_t)s->n + 1, 1);
  w->push_rows = malloc(sizeof(int) * (2 * (size_t)s->n + 2));
  w->push_list_n = 0;
  w->push_sweep = w->sweep_step;
  w->push_rows_at = -1;
  if (!w->push || !w->push_seen || !w->push_list || !w->push_two || !w->push_rows)
    return proto_fail(err, "out of memory for the sleep push state of %d grains", s->n);
  return 0;
}

/* The rule is on: sleep on and sleep.force > 0 (the one test of every entry
 * point below; w->push exists then). */
static int rule_on(const dem_model *m) { return m->sleep.on && m->sleep.force > 0; }

void dem_push_free(struct dem_work *w) {
  free(w->push); free(w->push_seen); free(w->push_list); free(w->push_two); free(w->push_rows);
}

/* A grain's state, and its copy in push_two (what base_due reads). */
static void set_state(struct dem_work *w, int id, int state) {
  w->push[DEM_PUSH_REC * id + DEM_PUSH_STATE] = state;
  w->push_two[id] = state == 2;
}

void dem_push_import(const dem_model *m, dem_state *s) {
  struct dem_work *w = s->work;
  if (!rule_on(m)) return;
  for (int id = 0; id < s->n; id++) w->push_two[id] = w->push[DEM_PUSH_REC * id + DEM_PUSH_STATE] == 2;
  w->push_list_n = -1; /* `now` is cleared whole at the next gather */
  w->push_sweep = w->sweep_step; /* as the exporter left it, up to date (dem_state_export) */
  w->push_rows_at = -1;
}

/* The awake rows that end in asleep partners, as (i, the first such k), in
 * slot order. nl_j and n_active change only at a rebuild (s->rebuilds), so
 * the list is kept until the next: on the deep bed about one awake row in
 * five has one. */
static void boundary_rows(dem_state *s) {
  struct dem_work *w = s->work;
  if (w->push_rows_at == s->rebuilds) return;
  const int na = w->n_active;
  int nr = 0;
  for (int i = 0; i < na; i++) {
    const int kas = dem_row_asleep(w, i, na);
    if (kas == w->nl_start[i + 1]) continue;
    w->push_rows[2 * nr] = i;
    w->push_rows[2 * nr + 1] = kas;
    nr++;
  }
  w->push_rows_n = nr;
  w->push_rows_at = s->rebuilds;
}

/* The asleep neighbours' forces from the last sweep (the share of an
 * awake–asleep pair k is stored in pair_ft, not added: dem_force.c), the base
 * of the grains in state 2 it sees, and with `test` the test. */
static void gather(const dem_model *m, dem_state *s, int test) {
  struct dem_work *w = s->work;
  double *p = w->push;
  if (w->push_list_n < 0) { /* after a state import: where the last gather wrote is not known */
    for (int id = 0; id < s->n; id++) memset(&p[DEM_PUSH_REC * id + DEM_PUSH_NOW], 0, 6 * sizeof(double));
    memset(w->push_seen, 0, (size_t)s->n);
  } else
    for (int q = 0; q < w->push_list_n; q++) {
      const int id = w->push_list[q];
      memset(&p[DEM_PUSH_REC * id + DEM_PUSH_NOW], 0, 6 * sizeof(double));
      w->push_seen[id] = 0;
    }
  int nl = 0;
  boundary_rows(s);
  for (int r = 0; r < w->push_rows_n; r++) { /* rows in slot order */
    const int i = w->push_rows[2 * r], kas = w->push_rows[2 * r + 1];
    for (int k = w->nl_start[i + 1] - 1; k >= kas; k--) {
      if (!w->pair_touch[k]) continue;
      const int j = w->nl_j[k], id = s->id[j];
      double *now = &p[DEM_PUSH_REC * id + DEM_PUSH_NOW];
      const double *f = &w->pair_ft[6 * (size_t)k]; /* force on i, torque share of j: on j −f, −c */
      if (!w->push_seen[id]) {
        w->push_seen[id] = 1;
        w->push_list[nl] = j; /* slots until the test below; ids after it */
        nl++;
      }
      for (int a = 0; a < 6; a++) now[a] -= f[a]; /* as gather_chunk adds it to an awake j */
      if (m->has_rolling) /* rolling resistance's torque on j */
        for (int a = 0; a < 3; a++) now[3 + a] -= w->pair_roll[3 * (size_t)k + a];
    }
  }
  const double g = sqrt(dem_dot(m->gravity, m->gravity)), fw = m->sleep.force * g;
  for (int q = 0; q < nl; q++) {
    const int j = w->push_list[q], id = s->id[j];
    double *b = &p[DEM_PUSH_REC * id + DEM_PUSH_B];
    const double *now = &p[DEM_PUSH_REC * id + DEM_PUSH_NOW];
    if (b[DEM_PUSH_STATE] == 2) /* the base from D kept across a change of the awake set */
      for (int a = 0; a < 6; a++) b[a] = now[a] - b[a];
    set_state(w, id, 1);
    w->push_list[q] = id;
    if (!test) continue;
    double df = 0, dt = 0;
    for (int a = 0; a < 3; a++) {
      df += (now[a] - b[a]) * (now[a] - b[a]);
      dt += (now[3 + a] - b[3 + a]) * (now[3 + a] - b[3 + a]);
    }
    const double lim = fw * w->mass[j], tlim = lim * s->radius[j]; /* torque: the weight at the radius */
    if (df > lim * lim || dt > tlim * tlim) dem_wake(w, j);
  }
  w->push_list_n = nl;
  w->push_sweep = w->sweep_step;
}

/* Whether a gather now would take a base: an awake grain touches an asleep
 * one in state 2. Reads a byte per touching awake–asleep pair, where the
 * gather writes a record. */
static int base_due(dem_state *s) {
  const struct dem_work *w = s->work;
  boundary_rows(s);
  for (int r = 0; r < w->push_rows_n; r++) {
    const int i = w->push_rows[2 * r];
    for (int k = w->push_rows[2 * r + 1]; k < w->nl_start[i + 1]; k++)
      if (w->pair_touch[k] && w->push_two[s->id[w->nl_j[k]]]) return 1;
  }
  return 0;
}

/* End of a step. `now` is read by three things only: the test (every
 * `test_steps` steps, with the grains falling asleep and the region: their
 * wakes share one rebuild, each one a copy of the asleep block), the base of
 * a grain in state 2 (that of the first sum that sees it after a fold) and
 * dem_push_fold. So the gather runs for the first two, and the fold (or a
 * rebuild, an export: anything that reads `now` or replaces pair_ft) brings
 * it up to date first through dem_push_fresh, from the same pair_ft: the
 * same bits as a gather at every step, which cost 3.7 % of the deep bed's
 * run in one thread (bench/results/tire_soil.md, stop 42). */
void dem_push_gather(const dem_model *m, dem_state *s) {
  struct dem_work *w = s->work;
  if (!rule_on(m) || w->n_active == s->n) return;
  const int test = s->step % m->sleep.test_steps == 0;
  if (test || base_due(s)) gather(m, s, test);
}

void dem_push_fresh(const dem_model *m, dem_state *s) {
  struct dem_work *w = s->work;
  if (!rule_on(m) || w->n_active == s->n || dem_push_current(w)) return;
  gather(m, s, 0);
}

/* Asleep grain j keeps its D across a change of its awake neighbours. */
static void fold_one(struct dem_work *w, int id) {
  double *b = &w->push[DEM_PUSH_REC * id];
  if (b[DEM_PUSH_STATE] != 1) return;
  for (int a = 0; a < 6; a++) b[a] = b[DEM_PUSH_NOW + a] - b[a];
  set_state(w, id, 2);
}

/* dem_asleep_near's visit: j folds if it touches grain *ctx and is not
 * woken itself. */
static void fold_touching(dem_state *s, int j, void *ctx) {
  const int i = *(const int *)ctx;
  const double *xi = &s->x[3 * i], *xj = &s->x[3 * j], rs = s->radius[i] + s->radius[j];
  const double d0 = xj[0] - xi[0], d1 = xj[1] - xi[1], d2 = xj[2] - xi[2];
  if (!s->work->wake[j] && d0 * d0 + d1 * d1 + d2 * d2 < rs * rs) fold_one(s->work, s->id[j]);
}

/* Before a rebuild that changes the awake set (slots as before it: the
 * grains falling asleep are flagged asleep among the awake ones, the woken
 * listed in wake_list, halo included): the asleep grains that touch one of
 * them keep their D (state 1 -> 2), as their set of awake neighbours
 * changes; the others keep their base, exact. Only those: a fold takes the
 * next base from the next gather, so the change over that one step is not
 * counted (at every wake near a grain it would add up). The woken grains'
 * asleep partners are found in the cells of the last full rebuild (every
 * contact lies within one cell); without that grid, every asleep grain folds. */
void dem_push_fold(const dem_model *m, dem_state *s) {
  struct dem_work *w = s->work;
  if (!rule_on(m)) return;
  dem_push_fresh(m, s); /* `now` of the last sweep */
  const int na = w->n_active;
  for (int i = 0; i < na; i++) { /* falling asleep: their asleep partners end their rows */
    if (!w->asleep[i]) continue;
    for (int k = dem_row_asleep(w, i, na); k < w->nl_start[i + 1]; k++)
      if (w->pair_touch[k]) fold_one(w, s->id[w->nl_j[k]]);
  }
  if (w->n_wake == 0) return;
  if (!w->grid_ok) {
    for (int j = na; j < s->n; j++) fold_one(w, s->id[j]);
    return;
  }
  for (int q = 0; q < w->n_wake; q++) {
    int i = w->wake_list[q];
    if (w->asleep[i]) dem_asleep_near(s, i, 2 * w->region_rmax, fold_touching, &i);
  }
}

/* Grain in slot i wakes (state 0, no base) or falls asleep (state 2, D = 0). */
void dem_push_set(const dem_model *m, dem_state *s, int i, int asleep) {
  if (!rule_on(m)) return;
  memset(&s->work->push[DEM_PUSH_REC * s->id[i]], 0, 6 * sizeof(double));
  set_state(s->work, s->id[i], asleep ? 2 : 0);
}
