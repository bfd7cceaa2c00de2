/* dem_internal.h — private to dem_server/: the work struct behind dem_state
 * and small vector/contact helpers shared by the .c files. */
#ifndef COSIM_DEM_INTERNAL_H
#define COSIM_DEM_INTERNAL_H

#include "dem_server/dem.h"
#include <math.h>
#include <omp.h>

/* Binary bounding-volume tree over a mesh's triangles (seed 000 §4.2). Nodes in
 * pre-order (children after parents) so a refit is one reverse sweep. */
typedef struct dem_bvh {
  int n_nodes;
  double *lo, *hi;      /* [n_nodes*3] boxes */
  int32_t *left, *right;/* children; left < 0: leaf holding triangle ~left */
  double area_built;    /* sum of box surface areas right after the build */
} dem_bvh;

/* The effective pair values of materials a and b with the pair's restitution
 * e, friction mu and rolling friction mu_roll (dem_model.c; the config reader
 * dem_config.c calls it). */
void dem_pair_law_set(const dem_material *a, const dem_material *b, double e, double mu, double mu_roll,
                      int clamp, dem_pair_law *l);

/* Grains per chunk: the fixed partition of the slots that the force sums
 * follow (dem_force.c), so results do not depend on the number of threads. */
#define DEM_CHUNK 512
#define DEM_MAX_THREADS 64
#define DEM_TRI_BITS 24 /* triangles per mesh < 2^24 (candidate keys) */

/* Per-chunk totals of a force evaluation, one cache line each. */
typedef struct dem_chunk_sum {
  double u, ke, ratio, v2; /* v2: the largest |v|^2 after the kick */
  int64_t pair_contacts, wall_contacts, mesh_contacts;
  char pad[8];
} dem_chunk_sum;

/* Contact features of a sphere–triangle contact (seed 000 fig. 10). */

enum { DEM_FEAT_VERTEX = 1, DEM_FEAT_EDGE = 2, DEM_FEAT_FACE = 3 }; /* = the feature's node count */

/* Load measurement of "threads": "auto" (dem_threads.c). */
typedef struct dem_thread_probe {
  int on, cores, reserved, cap, up_votes;
  double win_t0, busy0, self0, in_step, step_t0;
} dem_thread_probe;

struct dem_work {
  int nthreads;
  dem_thread_probe probe;
  /* half neighbour list in CSR by slot (j > i, ascending), with per-pair
   * history and the shares that cross into a later chunk (dem_force.c) */
  int *nl_start, *nl_j;
  double *nl_shear, *pair_roll; /* [cap*3]: spring, rolling torque on i (crossing pairs) */
  /* [cap*6] per touching pair crossing into a later chunk: F on i, then
   * (r_j − δ/2) n × F_t (the torque on j is minus that) */
  double *pair_ft;
  uint8_t *pair_touch; /* [cap] 1 = pair touched at the last force evaluation (or
                        * may hold a spring after a rebuild): open pairs whose flag
                        * is 0 have a zero spring, so neither gather nor reset reads them */
  size_t cap, pair_cap; /* capacity of nl_j/nl_shear, of rev_k/pair_ft/pair_touch/pair_roll */
  int *old_start, *old_j; /* the previous list (swapped with nl_* at a rebuild) */
  double *old_shear;
  size_t old_cap;
  int have_old;
  int *rev_start, *rev_k, *rev_fill; /* pairs from earlier chunks in which a slot is j */
  /* The shares of those pairs, stored in reverse-index order (rev_ft[6 q],
   * rev_roll[3 q] for rev_k[q]; zero while the pair is open) so that the
   * partner's sweep reads them in sequence; rev_of[k] = q, or −1 for a pair
   * that is not in the reverse index (dem_neigh_reverse). */
  int *rev_of;
  double *rev_ft, *rev_roll;
  int grain_law; /* the one material of every grain (then every pair has law[grain_law][grain_law]), or −1 (dem_state_init) */
  int *old_of;                       /* new slot -> old slot during a rebuild */
  double *x_ref;                     /* positions at the last rebuild */
  void *perm_tmp[DEM_MAX_THREADS];   /* per-thread scratch of the re-sorting */
  int nchunk;                        /* chunks of DEM_CHUNK slots */
  int **cbuf, *cbuf_cap;             /* [nchunk] a chunk's new rows during a rebuild */
  dem_chunk_sum *chunk;              /* [chunks] */
  int64_t pair_contacts;             /* grain–grain contacts at the last evaluation */
  /* cells */
  int *cell_start, *cell_of, *cell_rank; /* cell_start by Morton rank; rank of each cell */
  int cell_cap, rank_dim[3];
  double cell_lo[3], cell_size;
  int cell_dim[3];
  /* plane walls: per plane p and slot i */
  double *wall_shear;          /* [n_planes][n][3], plane-major: a floor's springs are dense */
  uint64_t *plane_mask;        /* [n] planes within r + skin at the last rebuild */
  uint64_t *plane_touch;       /* [n] planes whose spring may be non-zero (touched last time) */
  double *wall_part;           /* [chunks*n_planes*3] per-chunk wall totals */
  double *mass, *inertia;      /* [n] (inertia 0 for non-rotating grains) */
  /* meshes: contact slots per grain (history carried by feature key, or by
   * normal when a contact moves across an edge onto the next triangle) */
  int64_t *mc_key;  /* [n*K], 0 = free */
  int32_t *mc_tri;  /* [n*K] global triangle: mesh << 24 | tri is not assumed, see mc_mesh */
  int8_t *mc_mesh;  /* [n*K] */
  double *mc_shear, *mc_normal, *mc_zeta, *mc_force; /* [n*K*3] */
  /* [n*K*3] the moment the nodes must take besides the ζ-shares of the force,
   * so that they get exactly minus the grain's moment: the force acts at
   * the grain's contact point, δ/2 off the triangle, and the rolling torque */
  double *mc_couple;
  double *mesh_f, *mesh_t; /* [n*3] force/torque on grain from meshes */
  dem_bvh bvh[DEM_MAX_MESHES];
  /* mesh contact candidates per slot (CSR): key mesh << DEM_TRI_BITS | triangle */
  int *ml_start;
  int32_t *ml_key;
  size_t ml_cap;
  int32_t **ml_cbuf;
  int *ml_cbuf_cap;               /* [nchunk] a chunk's lists during a build */
  double *mesh_xref[DEM_MAX_MESHES]; /* node positions when the lists were built */
  uint8_t *mesh_node_moved[DEM_MAX_MESHES]; /* [nodes] moved more than skin/2 since (dem_mesh_lists_check) */
  int lists_dirty;                /* a mesh started moving: rebuild the lists (and "near") */
  double *ratio; /* [n] max overlap ratio of i's contacts (i's own pairs, walls, meshes) */
  /* sleeping grains, the active block (dem_sleep.c): between steps slots
   * [0, n_active) hold the awake grains and [n_active, n) the asleep ones, so
   * the per-step loops and the list rebuild run over the awake block only */
  uint8_t *asleep, *wake; /* [n] asleep; woken (asleep grain to wake at the end of the step) */
  int32_t *rest;          /* [n] steps at rest */
  double *rest_x;         /* [n,3] where the grain was when its steps at rest began */
  uint8_t *near;          /* [n] inside the region (at its last update): may not sleep */
  int n_active;           /* awake grains = first asleep slot */
  int *wake_list, n_wake; /* asleep grains woken this step (any order: only flags are set from it) */
  int compact;            /* the asleep set changes (DEM_COMPACT_*): list rebuild at the end of the step */
  int64_t full_rebuilds, wake_rebuilds; /* of s->rebuilds (the rest: partial) */
  int64_t wait_sum, wait_checks; /* grains at rest outside the region still awake, summed over the checks (log) */
  int *frz_start;         /* [cell_cap] by Morton rank: the slot ranges of the asleep grains in the
                           * cells of the last full rebuild (partial rebuilds reuse them) */
  int grid_ok;            /* the grid (cell_lo, cell_size, cell_dim) and frz_start are valid */
  double region_lo[3], region_hi[3]; /* the region (box): awake grains in it do not sleep, asleep ones wake */
  int region_on;          /* a region is set (some mesh moved since the first update) */
  int64_t region_step;    /* step of the last region update */
  double region_rmax;     /* the largest grain radius */
  double *cand_box;       /* [6 x the meshes' triangles] region_update's candidate triangles' boxes (lo, hi) */
  uint8_t *occ;           /* [DEM_REGION_OCC_CELLS] the grains' occupancy at the last region update: cell
                           * occ_dim-indexed, 1 where some grain's sphere box meets it (region_update) */
  double occ_lo[3], occ_h; /* its grid: origin and cell side (at least the reach) */
  int occ_threads_min;    /* grains from which the region's passes over all grains use the threads
                           * (DEM_OCC_THREADS_MIN; tests lower it to run that path on small beds) */
  int occ_dim[3];
  double region_moved;    /* bound on any mesh node's move since the last region update (dem_sleep_guard) */
  double region_budget;   /* the margin's mesh term at that update: the region holds while moved <= it */
  int region_movers;      /* bit mi: mesh mi was moving at that update */
  int64_t guard_updates;  /* region updates the guard made between the regular ones */
  double jump_box[6], jump_dt; /* dem_sleep_jump_box: the filter of the next mesh set's jump */
  int jump_on;
  uint8_t *jump_mask;          /* [nodes] jump_near's scratch: the sides of the jump box a node's path reaches */
  int32_t *jump_pos;           /* [largest mesh's nodes] scratch: a node's row in a sparse set */
  double asleep_box[6];        /* dem_reach_box: the asleep grains' sphere boxes (they stand still) */
  /* the awake grains' sphere box and largest |v|^2 as the step's own sweeps
   * left them (dem_step's drift, kick_chunk), valid at step sweep_step (set
   * once dem_step has done both) while the awake set is the drift's (box_all:
   * cleared when grains wake or fall asleep after it, dem_sleep.c); with the
   * asleep grains' box, dem_reach_box and dem_reach_escaped use them without a
   * sweep of their own (dem_nodeset.c) */
  double step_box[6], kick_v2;
  double step_cbox[6];         /* the drift's box of the awake centres (grains_box, dem_sleep.c) */
  int64_t sweep_step;
  int box_all;
  int64_t push_sweep;          /* the book's `now` is of the sweep of this step (dem_sleep_push.c) */
  int asleep_box_ok;           /* valid: cleared when the asleep set changes (dem_sleep.c) */
  /* the force rule (dem_sleep_push.c), by grain id: DEM_PUSH_REC doubles
   * each (base or D of force and torque, the awake neighbours' force and
   * torque at the last gather, state) */
  double *push;
  uint8_t *push_seen;          /* [n] by id: seen by the last gather */
  int *push_list, push_list_n; /* the ids the last gather saw (-1: not known, after an import) */
  uint8_t *push_two;           /* [n] by id: state 2 (a copy of the record's, for the scan) */
  int *push_rows, push_rows_n; /* [2 n] the awake rows with asleep partners: (i, first such k) */
  int64_t push_rows_at;        /* s->rebuilds when push_rows was made (-1: to make) */
  int settling;                /* dem_bed_settle: the sleep rules wait (a settling bed is slow before it is at rest) */
  double io_active[20];   /* dem_state_io.c: the active block's state (region, grid, guard) */
  /* meshes: far from every grain (dem_mesh.c) */
  uint8_t *chunk_mesh;    /* [nchunk] a grain of the chunk has mesh candidates or contacts */
  uint8_t mesh_far[DEM_MAX_MESHES]; /* no candidates: skip the node scan while still far */
  double mesh_gap[DEM_MAX_MESHES];  /* its box's distance to the grains' box at the list build, minus reach */
  double mesh_moved[DEM_MAX_MESHES];/* bound on any node's move since the list build */
  double mesh_vmax[DEM_MAX_MESHES]; /* largest node speed */
  double grains_rmax; /* the awake grains' largest radius at the last list build (the awake set
                      * changes only with one) */
  uint8_t mesh_moving[DEM_MAX_MESHES]; /* some node velocity is not zero */
  uint8_t mesh_set[DEM_MAX_MESHES];    /* nodes set since the last list build */
  int64_t mesh_builds, mesh_clear; /* list builds for a mesh's node moves alone; checks that found
                                    * every moved triangle clear of the grains (dem_mesh_lists_check) */
  /* dem_state_export/import scratch (dem_state_io.c) */
  int64_t io_counters[8];
  int64_t io_model[8]; /* the model's fingerprint by part ("state.model") */
  double io_scalars[8];
  double *io_mesh; /* [3][all mesh nodes][3]: x, v, force */
};

/* Spring of grain slot i on plane p. */
static inline double *dem_wall_shear(const struct dem_work *w, int n, int i, int p) {
  return &w->wall_shear[((size_t)p * n + i) * 3];
}

/* ---- vectors ---- */
static inline double dem_dot(const double *a, const double *b) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
static inline void dem_cross(const double *a, const double *b, double *c) {
  c[0] = a[1] * b[2] - a[2] * b[1];
  c[1] = a[2] * b[0] - a[0] * b[2];
  c[2] = a[0] * b[1] - a[1] * b[0];
}

/* One Hertz–Mindlin contact, LIGGGHTS `model hertz tangential history`
 * (LIGGGHTS 3.8 `src/tangential_model_history.h`; seed 000 eq. 22–27 in LIGGGHTS' form):
 *   n: unit normal towards grain i; delta > 0: overlap; rstar, mstar: eq. 16–17
 *   (walls: r_i, m_i); vc: velocity of i's contact point relative to the other
 *   body's; shear: the tangential spring (eq. 20), updated in place.
 * Out: F (force on i), c = n × F_t, *u = elastic energy ∫F_n dδ = 2/5 kn δ²;
 * returns F_n.
 * Sn = 2Y*√(R*δ), St = 8G*√(R*δ), kn = 4/3 Y*√(R*δ), kt = St,
 * γn = −2√(5/6) β √(Sn m*), γt = −2√(5/6) β √(St m*): one square root for both
 * dampings (l->damp_n = −2√(5/6) β √(2Y*), l->damp_t = −2√(5/6) β √(8G*)). */
static inline __attribute__((always_inline)) double dem_hertz(const dem_pair_law *l, double delta, double rstar,
                               double mstar, const double *n, const double *vc,
                               double dt, double *shear, double *F, double *c, double *u) {
  const double sqrt_rd = sqrt(rstar * delta);
  const double kn = (4.0 / 3.0) * l->Estar * sqrt_rd, kt = 8.0 * l->Gstar * sqrt_rd;
  const double q = sqrt(sqrt_rd * mstar);
  const double gamman = l->damp_n * q, gammat = l->damp_t * q;
  const double vn = dem_dot(vc, n);
  const double Fn0 = kn * delta - gamman * vn; /* eq. 22: damping opposes vn */
  const double Fn = l->clamp && Fn0 < 0 ? 0.0 : Fn0; /* "limit_force": never attractive */
  *u = 0.4 * kn * delta * delta;
  const double vt[3] = {vc[0] - vn * n[0], vc[1] - vn * n[1], vc[2] - vn * n[2]};
  for (int k = 0; k < 3; k++) shear[k] += vt[k] * dt; /* eq. 20 */
  const double rsht = dem_dot(shear, n);               /* project into the tangent plane */
  for (int k = 0; k < 3; k++) shear[k] -= rsht * n[k];
  const double shr2 = dem_dot(shear, shear);
  const double Ft_friction = l->mu * fabs(Fn);
  /* sliding (|kt s| > μ|Fn|): Coulomb, spring reset to −F_t/kt, no damping;
   * sticking: spring + dashpot (eq. 24, 27). Both computed and selected, so
   * that batches of contacts vectorise (dem_force.c); a select is exact. */
  const int slide = kt * kt * shr2 > Ft_friction * Ft_friction, spring = shr2 > 0;
  const int reset = slide & spring;
  const double ratio = Ft_friction / (kt * sqrt(shr2)), ikt = 1.0 / kt;
  double Ft[3];
  for (int k = 0; k < 3; k++) {
    const double e = -kt * shear[k], g = e * ratio;
    Ft[k] = slide ? (spring ? g : 0) : e - gammat * vt[k];
    shear[k] = reset ? -g * ikt : shear[k];
  }
  for (int k = 0; k < 3; k++) F[k] = Fn * n[k] + Ft[k];
  dem_cross(n, Ft, c);
  return Fn;
}

/* q ← exp(ω dt / 2) ⊗ q. For the usual small angles h = |ω| dt/2 < 1e-3,
 * cos h and sin h by their series (truncation below h⁶/720 ≈ 1e-21, and
 * |dq|² = 1 + O(h⁶)): no libm call, no renormalisation in the hot loop —
 * dem_renormalise() runs at neighbour-list rebuilds. */
static inline void dem_rotate_quaternion(double *q, const double *o, double dt) {
  const double w2 = dem_dot(o, o), h2 = 0.25 * w2 * dt * dt;
  double ch, sn; /* cos h, sin(h)/|ω| */
  if (__builtin_expect(h2 < 1e-6, 1)) {
    ch = 1 - h2 * (0.5 - h2 * (1.0 / 24));
    sn = 0.5 * dt * (1 - h2 * (1.0 / 6 - h2 * (1.0 / 120)));
  } else {
    const double wm = sqrt(w2), h = 0.5 * wm * dt;
    ch = cos(h);
    sn = sin(h) / wm;
  }
  const double d1 = o[0] * sn, d2 = o[1] * sn, d3 = o[2] * sn;
  const double q0 = q[0], q1 = q[1], q2 = q[2], q3 = q[3];
  q[0] = ch * q0 - d1 * q1 - d2 * q2 - d3 * q3;
  q[1] = ch * q1 + d1 * q0 + d2 * q3 - d3 * q2;
  q[2] = ch * q2 - d1 * q3 + d2 * q0 + d3 * q1;
  q[3] = ch * q3 + d1 * q2 - d2 * q1 + d3 * q0;
}

/* LIGGGHTS `rolling_friction cdt`: torque −μ_r |F_n| R* ω̂_rel on i. */
static inline void dem_rolling(const dem_pair_law *l, double Fn, double rstar,
                               const double *w_rel, double *torque_i) {
  double wm = sqrt(dem_dot(w_rel, w_rel));
  double s = wm > 0 ? -l->mu_roll * fabs(Fn) * rstar / wm : 0.0;
  for (int k = 0; k < 3; k++) torque_i[k] = s * w_rel[k];
}

/* dem_threads.c: the thread count ("threads": "auto" follows other load) */
int dem_threads_init(const dem_model *m, dem_state *s, proto_err *err);
void dem_threads_begin(dem_state *s);
void dem_threads_end(dem_state *s);
/* dem_sleep.c */
int dem_sleep_alloc(const dem_model *m, dem_state *s, proto_err *err);
void dem_sleep_free(struct dem_work *w);
/* After the kick of awake grains lo..hi−1: their steps at rest. */
void dem_sleep_chunk(const dem_model *m, dem_state *s, int lo, int hi);
/* s->sleeping from the active block (state import: after dem_neigh_reverse,
 * which finds n_active). */
void dem_sleep_count(const dem_model *m, dem_state *s);
/* State import: checks that the awake grains come first and restores the
 * region and the grid of the last full rebuild from io_active. */
int dem_sleep_partners(const dem_model *m, dem_state *s, proto_err *err);
/* State export: the region and the grid into io_active. */
void dem_sleep_export(const dem_model *m, dem_state *s);
#define DEM_IO_ACTIVE 20 /* doubles of "state.active" */
/* A mesh's nodes about to be set to x (k rows, node idx[j] or j if idx is
 * NULL): the largest jump from where they are adds to region_moved. */
void dem_sleep_mesh_jump(const dem_model *m, dem_state *s, int mesh, int64_t k, const int32_t *idx,
                         const double *x, const double *v, const uint8_t *seen);
/* Before the forces of a step: when a mesh moved farther than the region's
 * margin allows since its last update (or started moving), the region
 * follows at once and wakes what it reaches (a wake rebuild). */
int dem_sleep_guard(const dem_model *m, dem_state *s, proto_err *err);
/* End of a step: wake the woken, every DEM_REGION_STEPS steps update the
 * region (wake what it holds), every sleep.test_steps steps (a multiple)
 * test the force rule and put to sleep the grains at rest outside it; then a
 * list rebuild if the asleep set changed. */
int dem_sleep_update(const dem_model *m, dem_state *s, proto_err *err);
/* The step's own sweeps cover every awake grain as they are now: dem_step
 * moved them (the asleep ones stand still) and kicked them last, and nothing
 * has touched x or v since (a wake or sleep after the drift, a state import or
 * a bed's clock reset clears the steps). */
static inline int dem_sweeps_current(const dem_state *s) {
  return s->work->box_all && s->work->sweep_step == s->step;
}
/* The force rule's book holds the last sweep's push (dem_push_fresh). */
static inline int dem_push_current(const struct dem_work *w) { return w->push_sweep == w->sweep_step; }
/* An asleep grain listed with an awake one moving faster than the threshold. */
static inline void dem_wake(struct dem_work *w, int i) {
  if (!__atomic_exchange_n(&w->wake[i], 1, __ATOMIC_RELAXED))
    w->wake_list[__atomic_fetch_add(&w->n_wake, 1, __ATOMIC_RELAXED)] = i;
}
/* The first entry of awake row i that lists an asleep grain (slot >= na):
 * rows ascend in j, so the asleep partners end the row. */
static inline int dem_row_asleep(const struct dem_work *w, int i, int na) {
  int k = w->nl_start[i + 1];
  while (k > w->nl_start[i] && w->nl_j[k - 1] >= na) k--;
  return k;
}
/* The asleep grains j != i whose centres lie within h of grain i's, found in
 * the cells of the last full rebuild around i's (grid_ok; h at most one
 * cell): visit(s, j, ctx) for each, in slot order within each cell. */
void dem_asleep_near(dem_state *s, int i, double h, void (*visit)(dem_state *s, int j, void *ctx), void *ctx);
/* dem_sleep_occ.c: the grains' occupancy (w->occ) on a grid of side at
 * least `reach` over the centre box glo..ghi grown by the largest radius:
 * the cells within qlo..qhi (the candidate triangles' boxes grown by the
 * reach) that some grain's sphere box meets, every grain slower than `vfast`
 * (sleep.wake_velocity) and every asleep one; dem_occ_hit: whether the box
 * lo..hi grown by `reach` (inside qlo..qhi) meets a marked cell. */
void dem_occ_build(const dem_state *s, const double *glo, const double *ghi, double reach, double vfast,
                   const double *qlo, const double *qhi);
int dem_occ_hit(const struct dem_work *w, const double *lo, const double *hi, double reach);
/* dem_sleep_push.c: the force rule (sleep.force) */
/* a grain's record in push: base (or kept change) of force and torque,
 * the awake neighbours' force and torque at the last gather, state */
enum { DEM_PUSH_B = 0, DEM_PUSH_NOW = 6, DEM_PUSH_STATE = 12, DEM_PUSH_REC = 13 };
int dem_push_alloc(const dem_model *m, dem_state *s, proto_err *err);
void dem_push_free(struct dem_work *w);
/* End of a step, before the region: the asleep grains' change of push, and
 * the wake marks of those beyond sleep.force times their weight (gathered
 * only when a test or a base needs it). */
void dem_push_gather(const dem_model *m, dem_state *s);
/* The book's `now` from the last sweep if it was not gathered: before
 * anything reads it or replaces pair_ft (a rebuild, an export). */
void dem_push_fresh(const dem_model *m, dem_state *s);
/* After a state import: push_two from the records; `now` as exported. */
void dem_push_import(const dem_model *m, dem_state *s);
/* Before a rebuild that changes the awake set: D kept for the asleep grains
 * whose awake neighbours change. */
void dem_push_fold(const dem_model *m, dem_state *s);
/* Slot i wakes (asleep 0) or falls asleep (asleep 1). */
void dem_push_set(const dem_model *m, dem_state *s, int i, int asleep);
/* Region update interval (steps): the region's margin covers what moves in it. */
#define DEM_REGION_STEPS 5
/* Cells of the grains' occupancy grid the region's reach test uses (1 byte
 * each): cells of the reach's size over a 1 x 1 x 0.5 m bed with a 4 cm
 * reach are ~8 000; a bed much larger than its reach gets coarser cells
 * (the test stays conservative, only less local). */
#define DEM_REGION_OCC_CELLS (1 << 18)
#define DEM_OCC_BLOCK 64 /* grains per block of the occupancy's cell arithmetic (dem_sleep.c) */
/* Grains from which the region update's passes over every grain (the
 * occupancy, the near flags) are split over the threads: ~25 ns a grain
 * (the deep bed's 87 248: 2.0-2.4 ms an update on one thread, 1.2 on two),
 * so below this a fork (a few us) does not pay. */
#define DEM_OCC_THREADS_MIN 8192
/* w->compact: grains woke (the asleep block keeps its order), or fell asleep (full rebuild) */
/* An awake grain wakes its listed asleep neighbours when faster than this
 * many times the sleep velocity: a hysteresis, so that grains at the edge of
 * the asleep block, moving about the sleep velocity, do not wake and fall
 * asleep again every few steps (each costs a list rebuild). */
#define DEM_WAKE_FACTOR 4.0
#define DEM_COMPACT_WAKE 1
#define DEM_COMPACT_SLEEP 2
/* min and max of boxes, inline: fmin/fmax are library calls (they order
 * NaN), which took 5 % of a step with sleep in the triangle boxes of the
 * region and the BVH refit. The same values for finite numbers (a box's
 * -0 or +0 compares the same); a NaN node or grain stops the run elsewhere. */
static inline double dem_min(double a, double b) { return b < a ? b : a; }
static inline double dem_max(double a, double b) { return b > a ? b : a; }

/* dem_neigh.c */
/* The cell of coordinate x along axis k (clamped to the grid), and a cell's index. */
static inline int dem_cell_coord(const struct dem_work *w, double x, int k) {
  int c = (int)((x - w->cell_lo[k]) / w->cell_size);
  return c < 0 ? 0 : (c >= w->cell_dim[k] ? w->cell_dim[k] - 1 : c);
}
static inline int dem_cell_index(const struct dem_work *w, int x, int y, int z) {
  return (z * w->cell_dim[1] + y) * w->cell_dim[0] + x;
}
/* Morton rank of the cell that holds point x. */
static inline int dem_cell_rank_at(const struct dem_work *w, const double *x) {
  const int cx = dem_cell_coord(w, x[0], 0), cy = dem_cell_coord(w, x[1], 1), cz = dem_cell_coord(w, x[2], 2);
  return w->cell_rank[dem_cell_index(w, cx, cy, cz)];
}
int dem_neigh_alloc(const dem_model *m, dem_state *s, proto_err *err);
void dem_neigh_free(struct dem_work *w);
int dem_neigh_rebuild(const dem_model *m, dem_state *s, proto_err *err);
/* frz_start from the asleep block in the grid cell_lo/size/dim (state import). */
int dem_neigh_asleep_cells(const dem_model *m, dem_state *s, proto_err *err);
/* Room for npairs pairs in the list (keeps its contents). */
int dem_neigh_reserve(const dem_model *m, dem_state *s, int npairs, proto_err *err);
/* The reverse pair index (rev_start, rev_k) of the current list. */
void dem_neigh_reverse(dem_state *s);
/* dem_state.c: the largest overlap (fraction of the smaller radius; walls:
 * of the radius) over the neighbour list and the planes. */
double dem_worst_overlap(const dem_model *m, const dem_state *s);
/* dem_state_io.c: 1 when a state's fingerprint (state.model) gives other
 * meshes than this model's (dem_state_import accepts that only when no grain
 * touches a mesh in it); 0 otherwise or when it has none. */
int dem_state_other_meshes(const dem_model *m, const proto_msg *in);
/* dem_state.c: slot i holds model grain g: radius, mass, inertia, material. */
void dem_grain_constants(const dem_model *m, dem_state *s, int i, int g);
/* dem_mesh.c */
int dem_mesh_alloc(const dem_model *m, dem_state *s, proto_err *err);
void dem_mesh_free(const dem_model *m, dem_state *s);
void dem_mesh_move(const dem_model *m, dem_state *s, double dt);
void dem_mesh_velocities_changed(const dem_model *m, dem_state *s, int mesh);
void dem_mesh_nodes_set(const dem_model *m, dem_state *s, int mesh);
/* Candidate lists: build; rebuild if a node moved more than skin/2 since. */
int dem_mesh_lists(const dem_model *m, dem_state *s, proto_err *err);
/* Only the lists, keeping the rebuild schedule (state import). */
int dem_mesh_lists_build(const dem_model *m, dem_state *s, proto_err *err);
int dem_mesh_lists_check(const dem_model *m, dem_state *s, proto_err *err);
int dem_mesh_grain(const dem_model *m, dem_state *s, int i, double *u);
void dem_mesh_reactions(const dem_model *m, dem_state *s);
int dem_bvh_build(dem_bvh *b, const double *x, const int32_t *tri, int n_tri);
void dem_bvh_refit(dem_bvh *b, const double *x, const int32_t *tri);
void dem_bvh_free(dem_bvh *b);
/* Refit; rebuild when refitting has doubled the total box area. */
void dem_bvh_update(dem_bvh *b, const double *x, const int32_t *tri, int n_tri);
/* Closest point of triangle (a,b,c) to p; zeta: barycentric weights. */
void dem_closest_on_triangle(const double *p, const double *a, const double *b,
                             const double *c, double *q, double *zeta);
/* dem_force.c */
/* Contact forces and torques of the current positions, and the summary
 * (contacts, overlap, elastic energy). kick != 0 (dem_step): then also the
 * second half of the Verlet step of each grain, chunk by chunk while its
 * forces are in cache: q rotated by ω^{n+1/2} dt, v += dt/2 (F/m + g),
 * ω += dt/2 T/I, and the kinetic energy. */
void dem_compute_forces(const dem_model *m, dem_state *s, int kick);

#endif
