/* dem_nodeset.c — the dem's side of the sparse exchange (PROTOCOL.md "Sparse
 * exchange"). Data flow, per coupling step:
 *   done of step k: the grains (s->x, radius, v) -> the reach box R of step
 *     k+1 (dem_reach_box), in the done header; the nodal force rows that are
 *     not zero -> (index, force) (proto_sparse_rows).
 *   step k+1: the coupler sends x, v of the nodes of every triangle whose box
 *     over the step meets R (proto_reach_nodes) -> those nodes set, the
 *     others left standing, the triangles with a node left out marked not live
 *     (dem_mesh_set_nodes_sparse; dem_mesh.c skips them) -> after every
 *     sub-step, every grain sphere still inside R (dem_reach_escaped).
 *
 * Why this gives the dense exchange's bits. A grain i touches a triangle only
 * if the triangle comes within r_i of its centre, so only if the triangle meets
 * the sphere's box [x_i - r_i, x_i + r_i]. While every sphere box lies inside R
 * (checked at every force evaluation, the end of every sub-step), a triangle
 * that touches a grain meets R at that moment; its nodes move on the segments
 * x -> x + v dt during the step, so the triangle stays inside the box of those
 * six end points, which then meets R: the coupler sent all three nodes, the
 * triangle is live and its positions are this step's, as in the dense
 * exchange. A triangle not live does not meet R, so no grain touches it in
 * either exchange; it only takes up room in the candidate lists (which are
 * valid for either: dem_mesh_lists_check compares node positions with those of
 * the build, stale ones included, and builds them again when a moved
 * triangle comes near a grain; a stale node joining the set far from the
 * grains keeps them). The contacts, forces and so every result are the same
 * bit for bit; a force row not sent is +0.0 in the dense reply too.
 *
 * The margin of R. The coupler sends the surface's exact path over the step
 * (x, x + v dt), so R need not grow by the surface's speed times dt (that is
 * the growth a node set taken from the dem's own copy of the surface would
 * need, and such a set goes stale for nodes not sent for a while: the dem
 * cannot know where they are). R has to grow only by how far a grain moves
 * within one coupling step, and that is not known beforehand: a grain of speed
 * v_max at t_k moves about v_max dt; we allow for its speed doubling within
 * the step (a grain hit by the tread) and add the neighbour skin:
 *   delta = skin + 2 v_max dt.
 * The margin decides only how often the check could fail, not whether the
 * result is exact: a grain that leaves R stops the step with an error naming
 * it (and coupling.sparse false as the way round).
 *
 * With sleep the active region (dem_sleep.c) also looks at the surface: R
 * grows to cover it and the coupler sends the fastest node (dem_sleep_reach,
 * reach_speed); the grains are then checked against their own box, computed
 * again at the start of the step (the state the done reported it from). */
#include "dem_server/dem_internal.h"

#include <string.h>

void dem_mesh_set_nodes_sparse(const dem_model *m, dem_state *s, int mesh, int64_t k,
                               const int32_t *idx, const double *x, const double *v,
                               uint8_t *node_seen, uint8_t *live) {
  const dem_mesh *me = &m->meshes[mesh];
  double *mx = s->mesh_x[mesh], *mv = s->mesh_v[mesh];
  memset(node_seen, 0, (size_t)me->n_nodes);
  for (int64_t j = 0; j < k; j++) node_seen[idx[j]] = 1;
  dem_sleep_mesh_jump(m, s, mesh, k, idx, x, v, node_seen); /* the active region's guard, before the copy */
  memset(mv, 0, sizeof(double) * 3 * (size_t)me->n_nodes); /* the others stand still */
  for (int64_t j = 0; j < k; j++) {
    const size_t a = (size_t)idx[j];
    memcpy(&mx[3 * a], &x[3 * j], 3 * sizeof(double));
    memcpy(&mv[3 * a], &v[3 * j], 3 * sizeof(double));
  }
  for (int t = 0; t < me->n_tri; t++) {
    const int32_t *tn = &me->tri[3 * t];
    live[t] = node_seen[tn[0]] & node_seen[tn[1]] & node_seen[tn[2]];
  }
  s->mesh_live[mesh] = live;
  s->work->mesh_set[mesh] = 1; /* lists: checked at the next step */
  dem_mesh_velocities_changed(m, s, mesh);
  dem_mesh_nodes_set(m, s, mesh); /* as dem_mesh_set_nodes */
}

/* Sphere boxes of slots lo..hi−1 into box; returns the largest |v|². */
static double sphere_boxes(const dem_state *s, int lo, int hi, double box[6]) {
  double v2 = 0;
  for (int i = lo; i < hi; i++) { /* comparisons, not fmin/fmax: no NaN here (dem_step) */
    const double *x = &s->x[3 * i], *v = &s->v[3 * i], r = s->radius[i], w2 = dem_dot(v, v);
    for (int d = 0; d < 3; d++) {
      const double l = x[d] - r, h = x[d] + r;
      box[d] = l < box[d] ? l : box[d];
      box[3 + d] = h > box[3 + d] ? h : box[3 + d];
    }
    v2 = w2 > v2 ? w2 : v2;
  }
  return v2;
}

/* box grown to hold other too (min/max: exact in any order) */
static void box_union(double box[6], const double other[6]) {
  for (int d = 0; d < 3; d++) {
    box[d] = other[d] < box[d] ? other[d] : box[d];
    box[3 + d] = other[3 + d] > box[3 + d] ? other[3 + d] : box[3 + d];
  }
}

/* With sleep, the asleep grains' sphere box into box, kept until the asleep
 * set changes; without, box unchanged. */
static void with_asleep(const dem_state *s, double box[6]) {
  struct dem_work *w = s->work;
  if (!w->asleep || w->n_active == s->n) return;
  if (!w->asleep_box_ok) {
    for (int d = 0; d < 3; d++) w->asleep_box[d] = INFINITY, w->asleep_box[3 + d] = -INFINITY;
    sphere_boxes(s, w->n_active, s->n, w->asleep_box);
    w->asleep_box_ok = 1;
  }
  box_union(box, w->asleep_box);
}

void dem_reach_box(const dem_model *m, const dem_state *s, double dt, double box[6]) {
  struct dem_work *w = s->work;
  for (int d = 0; d < 3; d++) box[d] = INFINITY, box[3 + d] = -INFINITY;
  double v2;
  with_asleep(s, box); /* they stand still: |v| 0 */
  if (dem_sweeps_current(s)) { /* the same min, max and |v|^2 as the sweep below */
    box_union(box, w->step_box);
    v2 = w->kick_v2;
  } else {
    v2 = sphere_boxes(s, 0, w->n_active, box);
  }
  const double delta = m->skin + 2 * sqrt(v2) * dt; /* the margin derived above */
  for (int d = 0; d < 3; d++) {
    if (s->n == 0) box[d] = box[3 + d] = 0; /* no grain: a point box, reached by nothing */
    box[d] -= delta;
    box[3 + d] += delta;
  }
}

int dem_reach_escaped(const dem_state *s, const double box[6]) {
  int out = 0;
  if (dem_sweeps_current(s)) { /* every sphere box inside: their union is */
    double u[6];
    memcpy(u, s->work->step_box, sizeof u);
    with_asleep(s, u);
    if (u[0] >= box[0] && u[1] >= box[1] && u[2] >= box[2] && u[3] <= box[3] && u[4] <= box[4] &&
        u[5] <= box[5])
      return -1;
  }
  for (int i = 0; i < s->n; i++) { /* branch-free sweep; the slot only when one is out */
    const double *x = &s->x[3 * i], r = s->radius[i];
    out |= !(x[0] - r >= box[0]) | !(x[0] + r <= box[3]) | !(x[1] - r >= box[1]) |
           !(x[1] + r <= box[4]) | !(x[2] - r >= box[2]) | !(x[2] + r <= box[5]); /* also NaN */
  }
  for (int i = 0; out && i < s->n; i++) {
    const double *x = &s->x[3 * i], r = s->radius[i];
    for (int d = 0; d < 3; d++)
      if (!(x[d] - r >= box[d] && x[d] + r <= box[3 + d])) return i;
  }
  return -1;
}
