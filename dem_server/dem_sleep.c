/* dem_sleep.c — the active block: grains at rest outside the region that the
 * moving meshes can reach sleep ("sleep" in the config; Box2D's sleeping
 * bodies, Project Chrono's active box around a wheel).
 *
 * Data flow: the force sweep (dem_force.c) counts each awake grain's steps at
 * rest (dem_sleep_chunk) and marks asleep grains listed with a fast awake one
 * (dem_wake); before the forces the guard moves the region early if a mesh
 * moved farther than its margin allows; at the end of dem_step,
 * dem_sleep_update marks those whose push changed (dem_sleep_push.c, every
 * sleep.test_steps steps), wakes the marked, every DEM_REGION_STEPS steps
 * moves the region with the meshes (wakes the asleep grains it reaches, marks
 * the awake ones in it `near`), every sleep.test_steps steps puts to sleep the
 * grains at rest outside it, then asks dem_neigh.c for a list rebuild when the
 * asleep set changed. dem_neigh.c keeps the awake grains in slots
 * [0, n_active) and the asleep ones after them, so every per-step loop (drift,
 * pairs, walls, meshes, kick) and the partial list rebuild run over the awake
 * block only: an asleep grain costs nothing per step. Its contacts with other
 * asleep grains are not evaluated (springs kept), its plane contacts frozen;
 * its contacts with awake grains are evaluated as with a fixed grain (it
 * pushes back). Decisions use only the state: results are bitwise identical
 * for any number of threads.
 *
 * A grain sleeps when it has been slower than `velocity` (|v| and |ω| r) for
 * `time`, its centre all that time within `displacement` × r of where it
 * was when that time began (at rest, not merely slow), is outside the region
 * and touches no mesh: v = ω = 0, not
 * integrated. It wakes when an awake grain listed with it (within r_i + r_j +
 * skin at the last rebuild) moves faster than `velocity`, or presses into it
 * beyond `overlap` of the smaller radius, or its awake neighbours' push has
 * changed by `force` times its weight since it fell asleep (dem_sleep_push.c),
 * or the region reaches it; it
 * restarts from rest in equilibrium (force −m g: the next half kick leaves it
 * at rest).
 *
 * The region (derivation, also dem_server/README.md): the bounding box of the
 * moving meshes' triangles within the reach of a grain (the grains'
 * occupancy grid, region_update), grown along
 * each axis k by
 *   margin_k = max(distance_k, r_max + 2 skin) + c N dt + v_mesh (N + 1) dt;
 * the reach is the margin with distance 0 (a triangle farther from every
 * grain touches none, nor starts a disturbance that reaches one, before the
 * next update; `distance` widens the box around the triangles that can, as a
 * tyre's stress reaches grains below and beside it, and does not bring in a
 * wheel's triangles above the bed),
 * N = DEM_REGION_STEPS, c = √(E/ρ) of the stiffest, lightest material.
 * Between two updates (N steps) a mesh node moves at most v_mesh N dt (the
 * third term; +1: a grain woken at an update joins at the next step) and a
 * disturbance it starts travels at most c N dt through the grains: the bar
 * wave speed of the grain's solid bounds the speed of any wave in a packing
 * of Hertz contacts, which are softer than the solid (Hertz stiffness
 * 2 Y* √(R* δ) with δ ≪ R*). The first term keeps r_max + skin between the
 * mesh and any asleep grain's surface besides, so a mesh never meets an
 * asleep grain (its candidate list is empty) and a grain woken at the edge is
 * at rest when the disturbance arrives. Grains that move beyond the threshold
 * outside the region wake their neighbours step by step: in explicit DEM a
 * displacement reaches the next grain's force one step later, and the wake
 * reaches every grain listed with a fast one in the same step. The region is
 * kept with a hysteresis of half the reach (moved only when the required box
 * leaves it), so that asleep grains wake in batches, not one at a time.
 * v_mesh is the largest node speed |v| (dem_mesh_velocities_changed).
 *
 * The guard (dem_sleep_guard, in dem_step before the forces): v_mesh is the
 * speed at the update; a mesh that speeds up or is set somewhere else
 * (dem_mesh_set_nodes) between two updates could meet an asleep grain, which
 * has no mesh candidates. So a bound on any node's move since the update
 * accumulates (dem_mesh_move: largest speed x dt; dem_sleep_mesh_jump: the
 * jumps of a set) and the region follows at once when it exceeds the mesh
 * term v_mesh (N + 1) dt of the update, or a mesh that stood still then
 * moves now.
 *
 * Sparse exchange (dem_nodeset.c): region_update skips the triangles not
 * live (not sent); dem_sleep_reach grows the reach box to the grains' box
 * plus the margin without its mesh term and asks the coupler for that term
 * (reach_speed) and the fastest node, so the triangles it looks at and
 * v_mesh are those of the dense exchange; the guard's jumps count only the
 * nodes of triangles whose path meets the grains' reach box
 * (dem_sleep_jump_box), which are sent. */
#include "dem_server/dem_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

int dem_sleep_alloc(const dem_model *m, dem_state *s, proto_err *err) {
  struct dem_work *w = s->work;
  w->n_active = s->n;
  if (!m->sleep.on) return 0;
  for (int i = 0; i < m->n_grains; i++) w->region_rmax = fmax(w->region_rmax, m->radius[i]);
  w->asleep = calloc((size_t)s->n + 1, 1);
  w->wake = calloc((size_t)s->n + 1, 1);
  w->rest = calloc((size_t)s->n + 1, sizeof(int32_t));
  w->near = calloc((size_t)s->n + 1, 1);
  w->rest_x = calloc(3 * (size_t)s->n + 1, sizeof(double));
  w->wake_list = calloc((size_t)s->n + 1, sizeof(int));
  w->occ = calloc(DEM_REGION_OCC_CELLS, 1);
  w->occ_threads_min = DEM_OCC_THREADS_MIN;
  int nodes = 1;
  size_t tris = 0;
  for (int mi = 0; mi < m->n_meshes; mi++) {
    nodes = m->meshes[mi].n_nodes > nodes ? m->meshes[mi].n_nodes : nodes;
    tris += (size_t)m->meshes[mi].n_tri;
  }
  w->cand_box = malloc(6 * sizeof(double) * tris + 1);
  w->jump_pos = malloc(sizeof(int32_t) * (size_t)nodes);
  w->jump_mask = calloc((size_t)nodes, 1);
  if (!w->asleep || !w->wake || !w->rest || !w->near || !w->rest_x || !w->wake_list || !w->jump_pos ||
      !w->jump_mask || !w->occ || !w->cand_box)
    return proto_fail(err, "out of memory for the sleep state of %d grains", s->n);
  return 0;
}

void dem_sleep_free(struct dem_work *w) {
  free(w->asleep); free(w->wake); free(w->rest); free(w->near); free(w->rest_x); free(w->wake_list); free(w->frz_start);
  free(w->jump_pos);
  free(w->jump_mask);
  free(w->occ);
  free(w->cand_box);
}

void dem_sleep_chunk(const dem_model *m, dem_state *s, int lo, int hi) {
  struct dem_work *w = s->work;
  const double v2max = m->sleep.velocity * m->sleep.velocity, d2max = m->sleep.displacement * m->sleep.displacement;
  const int weightless = dem_dot(m->gravity, m->gravity) == 0;
  for (int i = lo; i < hi; i++) {
    const double *v = &s->v[3 * i], *o = &s->omega[3 * i], r = s->radius[i], *f = &s->force[3 * i];
    const double *x = &s->x[3 * i];
    double *x0 = &w->rest_x[3 * i];
    /* slow, and resting on something: a grain without contacts under gravity is falling */
    const int held = weightless || f[0] != 0 || f[1] != 0 || f[2] != 0;
    const int still = held && dem_dot(v, v) < v2max && dem_dot(o, o) * r * r < v2max;
    /* and at rest: within displacement x r of where its steps at rest began
     * (slow is not at rest: a creeping bed moves its grains by far more
     * than a contact's overlap within `time`) */
    const double e0 = x[0] - x0[0], e1 = x[1] - x0[1], e2 = x[2] - x0[2];
    if (still && w->rest[i] > 0 && e0 * e0 + e1 * e1 + e2 * e2 <= d2max * r * r) {
      w->rest[i] = w->rest[i] < INT32_MAX ? w->rest[i] + 1 : INT32_MAX;
    } else { /* a new start here */
      w->rest[i] = still;
      x0[0] = x[0]; x0[1] = x[1]; x0[2] = x[2];
    }
  }
}

void dem_sleep_count(const dem_model *m, dem_state *s) {
  struct dem_work *w = s->work;
  if (!m->sleep.on) return;
  s->sleeping = s->n - w->n_active;
  w->n_wake = 0;
}

/* "state.active": region lo, hi, on; grid lo, size, dims, valid; the guard's
 * move, budget and movers (dem_sleep_guard). */
enum { ACT_REGION_LO = 0, ACT_REGION_HI = 3, ACT_REGION_ON = 6, ACT_GRID_LO = 7, ACT_GRID_SIZE = 10,
       ACT_GRID_DIM = 11, ACT_GRID_OK = 14, ACT_MOVED = 15, ACT_BUDGET = 16, ACT_MOVERS = 17, ACT_N };
_Static_assert(ACT_N <= DEM_IO_ACTIVE, "io_active holds the active block's state");

void dem_sleep_export(const dem_model *m, dem_state *s) {
  struct dem_work *w = s->work;
  if (!m->sleep.on) return;
  double *a = w->io_active;
  memset(a, 0, sizeof w->io_active);
  for (int k = 0; k < 3; k++) {
    a[ACT_REGION_LO + k] = w->region_lo[k];
    a[ACT_REGION_HI + k] = w->region_hi[k];
    a[ACT_GRID_LO + k] = w->cell_lo[k];
    a[ACT_GRID_DIM + k] = w->cell_dim[k];
  }
  a[ACT_REGION_ON] = w->region_on;
  a[ACT_MOVED] = w->region_moved;
  a[ACT_BUDGET] = w->region_budget;
  a[ACT_MOVERS] = w->region_movers;
  a[ACT_GRID_SIZE] = w->cell_size;
  a[ACT_GRID_OK] = w->grid_ok;
}

int dem_sleep_partners(const dem_model *m, dem_state *s, proto_err *err) {
  struct dem_work *w = s->work;
  if (!m->sleep.on) return 0;
  for (int i = w->n_active; i < s->n; i++)
    if (!w->asleep[i])
      return proto_fail(err, "state import: 'state.asleep': awake grain in slot %d after the first asleep one (%d): "
                        "the awake grains come first", i, w->n_active);
  const double *a = w->io_active;
  w->region_on = a[ACT_REGION_ON] != 0;
  w->region_moved = a[ACT_MOVED];
  w->region_budget = a[ACT_BUDGET];
  if (!(a[ACT_MOVERS] >= 0 && a[ACT_MOVERS] < (1 << DEM_MAX_MESHES)) || !(w->region_moved >= 0) ||
      !(w->region_budget >= 0))
    return proto_fail(err, "state import: 'state.active' has a bad region guard (moved %g m, budget %g m, "
                      "movers %g)", w->region_moved, w->region_budget, a[ACT_MOVERS]);
  w->region_movers = (int)a[ACT_MOVERS];
  w->grid_ok = 0;
  w->asleep_box_ok = 0;
  for (int k = 0; k < 3; k++) {
    w->region_lo[k] = a[ACT_REGION_LO + k];
    w->region_hi[k] = a[ACT_REGION_HI + k];
  }
  if (a[ACT_GRID_OK] == 0) return 0; /* the next rebuild is a full one, as it would have been */
  long long cells = 1;
  for (int k = 0; k < 3; k++) {
    if (!(a[ACT_GRID_DIM + k] >= 1 && a[ACT_GRID_DIM + k] <= 1e6) || !isfinite(a[ACT_GRID_LO + k]))
      return proto_fail(err, "state import: 'state.active' has a bad grid (axis %d: %g cells from %g)", k,
                        a[ACT_GRID_DIM + k], a[ACT_GRID_LO + k]);
    w->cell_dim[k] = (int)a[ACT_GRID_DIM + k];
    w->cell_lo[k] = a[ACT_GRID_LO + k];
    cells *= w->cell_dim[k];
  }
  w->cell_size = a[ACT_GRID_SIZE];
  if (!(w->cell_size > 0) || cells > 4LL * s->n + 1000)
    return proto_fail(err, "state import: 'state.active' has a bad grid (%lld cells of %g m)", cells, w->cell_size);
  if (cells + 1 > w->cell_cap) {
    int *cs = realloc(w->cell_start, sizeof(int) * (size_t)(cells + 1));
    if (cs) w->cell_start = cs;
    int *cr = realloc(w->cell_rank, sizeof(int) * (size_t)(cells + 1));
    if (cr) w->cell_rank = cr;
    int *fz = realloc(w->frz_start, sizeof(int) * (size_t)(cells + 1));
    if (fz) w->frz_start = fz;
    if (!cs || !cr || !fz) return proto_fail(err, "state import: out of memory for cells");
    w->cell_cap = (int)cells + 1;
  }
  w->rank_dim[0] = -1; /* ranks to redo */
  return dem_neigh_asleep_cells(m, s, err);
}

static int touches_mesh(const dem_model *m, const struct dem_work *w, int i) {
  for (int k = 0; m->n_meshes > 0 && k < DEM_MESH_SLOTS; k++)
    if (w->mc_key[(size_t)i * DEM_MESH_SLOTS + k]) return 1;
  return 0;
}

/* margin of the region (see the top of the file) along one axis for node
 * speed vmax; with distance 0 it is the reach: how near the grains a triangle
 * must come to touch one, or start a disturbance that reaches one, before the
 * next update. `distance` only widens the box around the triangles within
 * that reach (a wheel's triangles a distance above the bed reach no grain
 * sooner). */
static double region_margin(const dem_model *m, const dem_state *s, double vmax, double distance) {
  double c = 0;
  for (int k = 0; k < m->n_materials; k++) c = fmax(c, sqrt(m->mat[k].E / m->mat[k].density));
  const double N = DEM_REGION_STEPS;
  return fmax(distance, s->work->region_rmax + 2 * m->skin) + c * N * s->dt + vmax * (N + 1) * s->dt;
}

/* Relative slack of the region's reach (dem_sleep_reach): covers the
 * rounding between the margin as one sum (region_margin) and the coupler's
 * box grown in two parts; a larger box selects more nodes, never other bits. */
#define DEM_REACH_SLACK 1e-9

static int in_box(const double *x, double r, const double *lo, const double *hi) {
  return x[0] + r > lo[0] && x[0] - r < hi[0] && x[1] + r > lo[1] && x[1] - r < hi[1] && x[2] + r > lo[2] &&
         x[2] - r < hi[2];
}

/* The box of every grain's centre: the awake ones' and the grid of the last
 * full rebuild, which held the asleep ones (they have not moved since). The
 * awake ones' from the drift's sweep while it is current (its grains, not
 * moved since; min and max are exact in any order: the same box). */
static void grains_box(const dem_state *s, double *lo, double *hi) {
  const struct dem_work *w = s->work;
  const int all = w->grid_ok ? w->n_active : s->n;
  for (int k = 0; k < 3; k++) {
    lo[k] = w->grid_ok ? w->cell_lo[k] : INFINITY;
    hi[k] = w->grid_ok ? w->cell_lo[k] + w->cell_dim[k] * w->cell_size : -INFINITY;
  }
  if (w->grid_ok && dem_sweeps_current(s)) {
    for (int k = 0; k < 3; k++) {
      lo[k] = dem_min(lo[k], w->step_cbox[k]);
      hi[k] = dem_max(hi[k], w->step_cbox[3 + k]);
    }
    return;
  }
  for (int i = 0; i < all; i++)
    for (int k = 0; k < 3; k++) {
      lo[k] = dem_min(lo[k], s->x[3 * i + k]);
      hi[k] = dem_max(hi[k], s->x[3 * i + k]);
    }
}

/* Triangle t of mesh mi (if sent: the sparse exchange's live ones,
 * dem_sleep_reach): its box tlo..thi, and whether it meets glo..ghi. */
static int tri_meets(const dem_model *m, const dem_state *s, int mi, int t, const double *glo, const double *ghi,
                     double *tlo, double *thi) {
  const uint8_t *live = s->mesh_live[mi];
  if (live && !live[t]) return 0;
  const int32_t *tn = &m->meshes[mi].tri[3 * t];
  const double *x = s->mesh_x[mi];
  int meets = 1;
  for (int k = 0; k < 3; k++) {
    const double a = x[3 * tn[0] + k], b = x[3 * tn[1] + k], c = x[3 * tn[2] + k];
    tlo[k] = dem_min(a, dem_min(b, c));
    thi[k] = dem_max(a, dem_max(b, c));
    meets &= thi[k] >= glo[k] && tlo[k] <= ghi[k];
  }
  return meets;
}

/* The region follows the moving meshes; awake grains in it are near, asleep
 * ones in it wake. Only the triangles whose box comes within the reach of a
 * grain count (a wheel's upper half reaches no grain within the next steps):
 * the box grown by the reach must meet the grains' box and an occupied cell
 * of the grains' occupancy grid. By cells, not by the grains' box alone: one
 * grain carried up in a tread's groove, or a heap against a far wall, raised
 * the box's top, and every triangle of the tyre below it counted (the sand
 * scene's region grew to 0.84 m of the 1 m bed). The box test stays: the
 * sparse exchange sends the triangles that pass it (dem_sleep_reach), and the
 * cells, which overhang the box by up to a cell, must not pick another. */
static void region_update(const dem_model *m, dem_state *s) {
  struct dem_work *w = s->work;
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY}, vmax = 0;
  double glo[3], ghi[3];
  int moving = 0;
  for (int mi = 0; mi < m->n_meshes; mi++) {
    if (!w->mesh_moving[mi]) continue;
    vmax = fmax(vmax, w->mesh_vmax[mi]); /* the largest node speed (dem_mesh_velocities_changed) */
    moving = 1;
  }
  double margin[3];
  for (int k = 0; k < 3; k++) margin[k] = moving ? region_margin(m, s, vmax, m->sleep.distance[k]) : 0;
  const double reach = moving ? region_margin(m, s, vmax, 0) : 0;
  /* the guard (dem_sleep_guard): from here, the mesh term of the margin */
  w->region_moved = 0;
  w->region_budget = moving ? vmax * (DEM_REGION_STEPS + 1) * s->dt : 0;
  w->region_movers = 0;
  for (int mi = 0; mi < m->n_meshes; mi++) w->region_movers |= w->mesh_moving[mi] << mi;
  double cbox[6]; /* the grains' centre box, for the occupancy grid */
  if (moving) {
    grains_box(s, glo, ghi);
    memcpy(cbox, glo, sizeof glo);
    memcpy(cbox + 3, ghi, sizeof ghi);
    for (int k = 0; k < 3; k++) { glo[k] -= reach; ghi[k] += reach; }
  }
  /* the candidates: the triangles whose box meets the grains' box grown by
   * the reach (their boxes kept in cand_box); the cells their queries read
   * lie within qlo..qhi */
  double qlo[3] = {INFINITY, INFINITY, INFINITY}, qhi[3] = {-INFINITY, -INFINITY, -INFINITY};
  int nc = 0;
  for (int mi = 0; mi < m->n_meshes && moving; mi++)
    for (int t = 0; w->mesh_moving[mi] && t < m->meshes[mi].n_tri; t++) {
      double *tb = &w->cand_box[6 * nc];
      if (!tri_meets(m, s, mi, t, glo, ghi, tb, tb + 3)) continue;
      nc++;
      for (int k = 0; k < 3; k++) {
        qlo[k] = dem_min(qlo[k], tb[k] - reach); /* as dem_occ_hit grows them */
        qhi[k] = dem_max(qhi[k], tb[3 + k] + reach);
      }
    }
  /* built when a triangle passes the box test: a far mesh costs no O(n) */
  if (nc > 0) dem_occ_build(s, cbox, cbox + 3, reach, m->sleep.wake_velocity, qlo, qhi);
  for (int q = 0; q < nc; q++) {
    const double *tb = &w->cand_box[6 * q];
    if (!dem_occ_hit(w, tb, tb + 3, reach)) continue;
    for (int k = 0; k < 3; k++) {
      lo[k] = dem_min(lo[k], tb[k]);
      hi[k] = dem_max(hi[k], tb[3 + k]);
    }
  }
  int changed = 0;
  if (moving && lo[0] <= hi[0]) { /* some triangle near the grains */
    int inside = w->region_on;
    for (int k = 0; k < 3; k++) {
      lo[k] -= margin[k];
      hi[k] += margin[k];
      inside &= lo[k] >= w->region_lo[k] && hi[k] <= w->region_hi[k];
    }
    if (!inside) { /* moved on: with half the reach of room ahead (hysteresis) */
      for (int k = 0; k < 3; k++) {
        w->region_lo[k] = lo[k] - 0.5 * reach;
        w->region_hi[k] = hi[k] + 0.5 * reach;
      }
      w->region_on = changed = 1;
    }
  }
  w->region_step = s->step;
  const int na = w->n_active;
  if (!w->region_on) { /* nothing moves: no grain is near (fall_asleep adds the fast ones' partners) */
    memset(w->near, 0, (size_t)na);
    return;
  }
#pragma omp parallel for schedule(static) num_threads(w->nthreads) if (na >= w->occ_threads_min)
  for (int i = 0; i < na; i++) w->near[i] = (uint8_t)in_box(&s->x[3 * i], s->radius[i], w->region_lo, w->region_hi);
  for (int i = na; changed && i < s->n; i++)
    if (in_box(&s->x[3 * i], s->radius[i], w->region_lo, w->region_hi)) dem_wake(w, i);
}

/* The grains at rest outside the region fall asleep, in batches: each batch
 * costs a full list rebuild, O(n), so at least 1/16 of all grains (a batch
 * then saves its rebuild within a few dozen steps of the grains it stops). */
static void fall_asleep(const dem_model *m, dem_state *s) {
  struct dem_work *w = s->work;
  const double steps = ceil(m->sleep.time / s->dt - 1e-9); /* `time` may be up to 1e6 s: rest saturates */
  const int32_t rest_steps = steps < INT32_MAX ? (int32_t)steps : INT32_MAX;
  const int na = w->n_active, batch = 1 + s->n / 16;
  int cand = 0;
  for (int i = 0; i < na; i++)
    cand += w->rest[i] >= rest_steps && !w->near[i] && !w->wake[i] && !touches_mesh(m, w, i);
  w->wait_sum += cand;
  w->wait_checks++;
  if (cand < batch && cand < na) return;
  /* not next to a fast grain: it would wake at once, and might touch it in
   * the same step (its reaction then lost) */
  const double v2max = m->sleep.velocity * m->sleep.velocity;
  for (int i = 0; i < na; i++) {
    const int fi = dem_dot(&s->v[3 * i], &s->v[3 * i]) > v2max;
    for (int k = w->nl_start[i]; k < w->nl_start[i + 1]; k++) {
      const int j = w->nl_j[k];
      if (j >= na) break; /* asleep partners end the row */
      if (fi) w->near[j] = 1;
      if (dem_dot(&s->v[3 * j], &s->v[3 * j]) > v2max) w->near[i] = 1;
    }
  }

  for (int i = 0; i < na; i++)
    if (w->rest[i] >= rest_steps && !w->near[i] && !touches_mesh(m, w, i)) { /* near: also fast partners */
      w->asleep[i] = 1;
      dem_push_set(m, s, i, 1);
      memset(&s->v[3 * i], 0, 3 * sizeof(double));
      memset(&s->omega[3 * i], 0, 3 * sizeof(double));
      if (m->n_meshes > 0) { /* no mesh contact (mc_key 0): nothing kept, zero (a wake rebuild skips them) */
        const size_t K = DEM_MESH_SLOTS;
        memset(&w->mc_mesh[K * (size_t)i], 0, K);
        memset(&w->mc_shear[3 * K * (size_t)i], 0, 3 * K * sizeof(double));
        memset(&w->mc_normal[3 * K * (size_t)i], 0, 3 * K * sizeof(double));
      }
      w->compact |= DEM_COMPACT_SLEEP;
    }
}

/* Waking in batches: with each grain woken, the asleep grains within
 * sleep.halo (default one) cells (2 r_max + skin, the cells of the last full
 * rebuild) of it wake too; halo 0 wakes only what a rule or the region wakes.
 * A wake rebuild copies the whole asleep block (O(n), several steps of the
 * awake grains), and a disturbance that spreads into the asleep block wakes
 * one layer of grains after another: without the batch, one wake rebuild per
 * layer, nearly every step at a moving front. A grain woken early is at rest
 * (as one woken in time); it falls asleep again after `time` if nothing
 * reaches it. The set woken does not depend on the order of wake_list. */
static void halo_one(dem_state *s, int j, void *ctx) {
  (void)ctx;
  if (!s->work->wake[j]) dem_wake(s->work, j);
}

static void wake_halo(const dem_model *m, dem_state *s) {
  struct dem_work *w = s->work;
  if (!w->grid_ok || m->sleep.halo <= 0) return;
  const int first = w->n_wake;
  const double h = m->sleep.halo * w->cell_size;
  for (int q = 0; q < first; q++) dem_asleep_near(s, w->wake_list[q], h, halo_one, NULL);
}

void dem_asleep_near(dem_state *s, int i, double h, void (*visit)(dem_state *s, int j, void *ctx), void *ctx) {
  const struct dem_work *w = s->work;
  const double *xi = &s->x[3 * i], h2 = h * h;
  int cc[3];
  for (int k = 0; k < 3; k++) cc[k] = dem_cell_coord(w, xi[k], k);
  for (int z = cc[2] > 0 ? cc[2] - 1 : 0; z <= cc[2] + 1 && z < w->cell_dim[2]; z++)
    for (int y = cc[1] > 0 ? cc[1] - 1 : 0; y <= cc[1] + 1 && y < w->cell_dim[1]; y++)
      for (int x = cc[0] > 0 ? cc[0] - 1 : 0; x <= cc[0] + 1 && x < w->cell_dim[0]; x++) {
        const int r = w->cell_rank[dem_cell_index(w, x, y, z)];
        for (int j = w->frz_start[r]; j < w->frz_start[r + 1]; j++) {
          const double *xj = &s->x[3 * j], d0 = xj[0] - xi[0], d1 = xj[1] - xi[1], d2 = xj[2] - xi[2];
          if (j != i && d0 * d0 + d1 * d1 + d2 * d2 < h2) visit(s, j, ctx);
        }
      }
}

/* The woken grains join the awake block (a wake rebuild, or a full one when
 * grains fell asleep too); each restarts at rest in equilibrium. */
static int wake_woken(const dem_model *m, dem_state *s, proto_err *err) {
  struct dem_work *w = s->work;
  const double *g = m->gravity;
  if (w->n_wake > 0) wake_halo(m, s);
  if (w->n_wake > 0 || w->compact) dem_push_fold(m, s); /* before the flags change */
  for (int q = 0; q < w->n_wake; q++) {
    const int i = w->wake_list[q];
    w->wake[i] = 0;
    if (!w->asleep[i]) continue;
    w->asleep[i] = 0;
    dem_push_set(m, s, i, 0);
    w->rest[i] = 0;
    w->near[i] = 1; /* until the next region update */
    for (int a = 0; a < 3; a++) {
      s->force[3 * i + a] = -g[a] * w->mass[i]; /* at rest in equilibrium */
      s->torque[3 * i + a] = 0;
    }
    w->compact |= DEM_COMPACT_WAKE;
  }
  w->n_wake = 0;
  if (!w->compact) return 0;
  w->asleep_box_ok = 0; /* dem_reach_box */
  w->box_all = 0;       /* the drift's box misses the woken grains, the kick's |v|^2 those put to sleep */
  return dem_neigh_rebuild(m, s, err); /* a wake or full rebuild: clears compact */
}

int dem_sleep_update(const dem_model *m, dem_state *s, proto_err *err) {
  if (!m->sleep.on || s->work->settling) return 0;
  dem_push_gather(m, s); /* this step's forces on the asleep grains */
  if (s->step % DEM_REGION_STEPS == 0) region_update(m, s);
  if (s->step % m->sleep.test_steps == 0) fall_asleep(m, s);
  return wake_woken(m, s, err);
}

void dem_sleep_jump_box(dem_state *s, const double box[6], double dt) {
  struct dem_work *w = s->work;
  memcpy(w->jump_box, box, sizeof w->jump_box);
  w->jump_dt = dt;
  w->jump_on = 1;
}

/* The jump of node a from x0 to x (squared). */
static double jump2(const double *x0, const double *x) {
  const double d0 = x[0] - x0[0], d1 = x[1] - x0[1], d2 = x[2] - x0[2];
  return d0 * d0 + d1 * d1 + d2 * d2;
}

/* The squared jump of the nodes of the triangles that can come into the jump
 * box over the step (every node set: the k rows of idx, or all; new x, v of
 * row pos[node]). Per node once, a bit per side of the box its path
 * [x, x + v dt] reaches (bit 2d: its low end is at most the box's top on
 * axis d; bit 2d+1: its high end at least the bottom); a triangle's path box
 * meets the box iff its nodes' bits together are all six. The ends by
 * dem_min/dem_max, which leave out a NaN end as fmin/fmax do, so a node with a
 * NaN counts as before (per corner, with fmin/fmax: 0.17 ms of a dense paper
 * step). */
static double jump_near(const dem_model *m, const dem_state *s, int mesh, int64_t k, const int32_t *idx,
                        const uint8_t *seen, const int32_t *pos, const double *x, const double *v) {
  const struct dem_work *w = s->work;
  const dem_mesh *me = &m->meshes[mesh];
  const double *x0 = s->mesh_x[mesh], *b = w->jump_box, dt = w->jump_dt;
  uint8_t *mask = w->jump_mask;
  for (int64_t j = 0; j < k; j++) {
    unsigned bits = 0;
    for (int d = 0; d < 3; d++) {
      const double p = x[3 * j + d], q = p + v[3 * j + d] * dt;
      bits |= (dem_min(p, q) <= b[3 + d] ? 1u : 0u) << (2 * d);
      bits |= (dem_max(p, q) >= b[d] ? 2u : 0u) << (2 * d);
    }
    mask[idx ? idx[j] : j] = (uint8_t)bits;
  }
  double worst = 0;
  for (int t = 0; t < me->n_tri; t++) {
    const int32_t *tn = &me->tri[3 * t];
    if (seen && !(seen[tn[0]] & seen[tn[1]] & seen[tn[2]])) continue; /* not sent: cannot meet the box */
    if ((mask[tn[0]] | mask[tn[1]] | mask[tn[2]]) != 63) continue;
    for (int a = 0; a < 3; a++) {
      const double d = jump2(&x0[3 * (size_t)tn[a]], &x[3 * (size_t)(pos ? pos[tn[a]] : tn[a])]);
      worst = d > worst || isnan(d) ? d : worst;
    }
  }
  return worst;
}

void dem_sleep_mesh_jump(const dem_model *m, dem_state *s, int mesh, int64_t k, const int32_t *idx,
                         const double *x, const double *v, const uint8_t *seen) {
  struct dem_work *w = s->work;
  if (!m->sleep.on) return;
  int32_t *pos = w->jump_pos;
  double worst = 0;
  if (w->jump_on) { /* the participant's filter: the same nodes dense or sparse */
    if (idx)
      for (int64_t j = 0; j < k; j++) pos[idx[j]] = (int32_t)j;
    worst = jump_near(m, s, mesh, k, idx, idx ? seen : NULL, idx ? pos : NULL, x, v);
    w->jump_on = 0;
  } else {
    for (int64_t j = 0; j < k; j++) {
      const double d = jump2(&s->mesh_x[mesh][3 * (idx ? (size_t)idx[j] : (size_t)j)], &x[3 * j]);
      worst = d > worst || isnan(d) ? d : worst;
    }
  }
  w->region_moved += isfinite(worst) ? sqrt(worst) : INFINITY; /* NaN: the health check names it */
}

/* Reach of the region (sparse exchange, PROTOCOL.md): every triangle that
 * region_update looks at meets the grains' box (awake centres, the grid of
 * the last full rebuild) grown by the margin; the margin's mesh term is the
 * largest node speed times (N + 1) dt, for the coupler to add (per_speed):
 * the dem does not know the next step's speeds. The rest is added here. */
void dem_sleep_reach(const dem_model *m, const dem_state *s, double box[6], double *per_speed) {
  *per_speed = 0;
  if (!m->sleep.on) return;
  double glo[3], ghi[3];
  grains_box(s, glo, ghi);
  const double grow = region_margin(m, s, 0, 0) * (1 + DEM_REACH_SLACK);
  for (int k = 0; k < 3; k++) {
    box[k] = fmin(box[k], glo[k] - grow);
    box[3 + k] = fmax(box[3 + k], ghi[k] + grow);
  }
  *per_speed = (DEM_REGION_STEPS + 1) * s->dt * (1 + DEM_REACH_SLACK);
}

/* The region's guard. Every step a bound on any mesh node's move since the
 * last region update accumulates (max node speed x dt in dem_mesh_move, the
 * jumps of dem_mesh_set_nodes); while it stays within the margin's mesh term
 * of that update, and no mesh that stood still then moves now, the mesh is
 * farther than the rest of the margin from every asleep grain. Otherwise the
 * region follows now, before the forces: a grain woken here was asleep, at
 * rest and not drifted this step (its half kick from equilibrium is zero), so
 * waking it now is waking it at the end of the last step. */
int dem_sleep_guard(const dem_model *m, dem_state *s, proto_err *err) {
  struct dem_work *w = s->work;
  if (w->n_active == s->n) return 0; /* no asleep grain to miss */
  int movers = 0;
  for (int mi = 0; mi < m->n_meshes; mi++) movers |= w->mesh_moving[mi] << mi;
  if (!movers || ((movers & ~w->region_movers) == 0 && w->region_moved <= w->region_budget)) return 0;
  region_update(m, s);
  w->guard_updates++;
  return wake_woken(m, s, err);
}

void dem_sleep_waiting(const dem_state *s, int64_t *sum, int64_t *checks) {
  *sum = s->work->wait_sum;
  *checks = s->work->wait_checks;
}
