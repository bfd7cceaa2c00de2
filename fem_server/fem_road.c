/* fem_road.c — a flat road under the body, solved in the FEM alone: a penalty
 * per unit area on the nodes of a surface, normal only (no friction).
 *
 * The road is the world plane z = height. In the rim frame (x = R r + c) it
 * is n . r = h with n = R^T e_z (the third row of R) and h = height - c_z, so
 * node i (r_i = X_i + u_i) is depth_i = h - n . r_i below it and gets
 *   f_i = k_area a_i max(0, depth_i) n,
 * a_i its share of the surface's area projected on the road: a third of each
 * triangle it has, times the cosine max(0, -n_t . n) of the triangle's outward
 * normal n_t against the road's (fem_road_place; n_t and the areas of the
 * positions given to fem_road_init). A face turned to the road thus carries
 * its footprint, k_area times its area times its mean depth (the coupler's
 * lug faces weigh the nodes with the same thirds, docs/tire-road.md), and
 * the side walls of lugs and grooves carry nothing. The force is a
 * function of u: the explicit scheme evaluates it at u_n with K u_n and counts
 * it as external work (fem_explicit.c), which keeps the energy balance exact;
 * its stiffness k_i adds at most max k_i / m_i to omega_max^2 (fem_road_dt).
 *
 * quadrature "exact": f_i = k_area ∫ N_i max(0, depth) dA over each triangle
 * facing the road (its projected area, depth linear on it: the penalty of
 * the surface's interpolated shape, as a lug block integrates it over its
 * cells), in closed form (tri_wet). The nodal form lumps the same integral
 * on the nodes and, max(0, .) being convex, is never below it (Jensen); the
 * two agree where a triangle is wholly in the road. The row sums of the
 * exact form's stiffness are the k_i, so fem_road_dt holds for both. */
#include "fem_server/fem.h"
#include "fem_server/fem_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

void fem_road_free(fem_road *r) {
  free(r->node);
  free(r->k);
  free(r->area);
  free(r->force);
  free(r->tri);
  free(r->tri_area);
  free(r->depth);
  memset(r, 0, sizeof *r);
}

/* (surface nodes, triangles, positions) -> (road: nodes, area shares, k_i) */
int fem_road_init(const fem_model *md, fem_road *r, const int32_t *node, int32_t n,
                  const int32_t *tri, int32_t n_tri, const double *x, double k_area,
                  double height, proto_err *err) {
  memset(r, 0, sizeof *r);
  if (!(k_area > 0) || n < 1) return proto_fail(err, "road: needs k_area > 0 and a surface");
  r->node = malloc(sizeof *r->node * (size_t)n);
  r->k = malloc(sizeof *r->k * (size_t)n);
  r->area = calloc((size_t)n, sizeof *r->area);
  r->force = calloc((size_t)md->n_dof, sizeof *r->force);
  r->tri = malloc(sizeof *r->tri * 3 * (size_t)(n_tri > 0 ? n_tri : 1));
  r->tri_area = malloc(sizeof *r->tri_area * 4 * (size_t)(n_tri > 0 ? n_tri : 1));
  r->depth = malloc(sizeof *r->depth * (size_t)n);
  if (!r->node || !r->k || !r->area || !r->force || !r->tri || !r->tri_area || !r->depth) {
    fem_road_free(r);
    return proto_fail(err, "out of memory (road)");
  }
  r->n = n;
  r->n_tri = n_tri;
  r->k_area = k_area;
  r->height = height;
  memcpy(r->node, node, sizeof *r->node * (size_t)n);
  memcpy(r->tri, tri, sizeof *r->tri * 3 * (size_t)n_tri);
  for (int32_t t = 0; t < n_tri; t++) { /* area and outward unit normal of each triangle */
    const int32_t *v = &tri[3 * (size_t)t];
    const double *a = &x[3 * (size_t)v[0]], *b = &x[3 * (size_t)v[1]], *q = &x[3 * (size_t)v[2]];
    const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    const double w[3] = {q[0] - a[0], q[1] - a[1], q[2] - a[2]};
    double nt[3];
    fem_cross(u, w, nt);
    const double len = sqrt(nt[0] * nt[0] + nt[1] * nt[1] + nt[2] * nt[2]), A = 0.5 * len;
    r->tri_area[4 * (size_t)t] = A;
    for (int d = 0; d < 3; d++) r->tri_area[4 * (size_t)t + 1 + d] = len > 0 ? nt[d] / len : 0;
  }
  const double up[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1}, origin[3] = {0, 0, 0};
  fem_road_place(r, up, origin); /* the identity frame until the first step */
  return 0;
}

/* (the frame of the coming step) -> (the plane n . r = h, the area shares a_i, k_i) */
void fem_road_place(fem_road *r, const double R[9], const double c[3]) {
  for (int d = 0; d < 3; d++) r->normal[d] = R[6 + d];
  r->h = r->height - c[2];
  memset(r->area, 0, sizeof *r->area * (size_t)r->n);
  for (int32_t t = 0; t < r->n_tri; t++) {
    const double *g = &r->tri_area[4 * (size_t)t];
    const double facing = -(g[1] * r->normal[0] + g[2] * r->normal[1] + g[3] * r->normal[2]);
    if (!(facing > 0)) continue;
    for (int k = 0; k < 3; k++) r->area[r->tri[3 * (size_t)t + k]] += g[0] * facing / 3;
  }
  for (int32_t i = 0; i < r->n; i++) r->k[i] = r->k_area * r->area[i];
}

/* out[k] = ∫ N_k max(0, g) dA over a triangle of area A whose depth g is
 * linear with the corner values g[0..2]. ∫ φψ dA = A/12 (Σ φ_i ψ_i + Σφ Σψ)
 * for linear φ, ψ on a triangle; with one corner o on its own side of g = 0
 * the part on o's side is the triangle (o, p_a, p_b), p_a = o + t_a (a − o),
 * t_a = g_o / (g_o − g_a), of area t_a t_b A, where g is (g_o, 0, 0) and N_o,
 * N_a, N_b are (1, 1 − t_a, 1 − t_b), (0, t_a, 0), (0, 0, t_b). */
static void tri_wet(const double g[3], double A, double out[3]) {
  const int wet = (g[0] > 0) + (g[1] > 0) + (g[2] > 0);
  const double sum = g[0] + g[1] + g[2];
  for (int k = 0; k < 3; k++) out[k] = wet == 3 ? A / 12 * (g[k] + sum) : 0;
  if (wet == 0 || wet == 3) return;
  int o = 0; /* the corner alone on its side: the wet one of one, the dry one of two */
  for (int k = 0; k < 3; k++)
    if ((g[k] > 0) == (wet == 1)) o = k;
  const int a = (o + 1) % 3, b = (o + 2) % 3;
  const double ta = g[o] / (g[o] - g[a]), tb = g[o] / (g[o] - g[b]);
  const double c = ta * tb * A * g[o] / 12; /* ∫ N_k g over (o, p_a, p_b) = c (N_k(o) + Σ N_k) */
  double part[3];
  part[o] = c * (4 - ta - tb), part[a] = c * ta, part[b] = c * tb;
  for (int k = 0; k < 3; k++) /* one wet: that part; two: the whole minus the dry part */
    out[k] = wet == 1 ? part[k] : A / 12 * (g[k] + sum) - part[k];
}

/* (u) -> (r->force at the road's nodes, its world z sum and contacts) */
void fem_road_force(const fem_model *md, fem_road *r, const double *u) {
  double total = 0;
  int32_t on = 0;
  for (int32_t i = 0; i < r->n; i++) {
    const size_t i0 = 3 * (size_t)r->node[i];
    double nr = 0;
    for (int d = 0; d < 3; d++) nr += r->normal[d] * (md->mesh.x[i0 + d] + u[i0 + d]);
    const double depth = r->h - nr, f = depth > 0 ? r->k[i] * depth : 0;
    r->depth[i] = depth;
    for (int d = 0; d < 3; d++) r->force[i0 + d] = r->exact ? 0 : f * r->normal[d];
    total += f;
    on += depth > 0;
  }
  r->contacts = on;
  if (!r->exact) {
    r->total = total;
    return;
  }
  total = 0;
  for (int32_t t = 0; t < r->n_tri; t++) { /* each triangle facing the road, its wet part */
    const int32_t *v = &r->tri[3 * (size_t)t];
    const double *gt = &r->tri_area[4 * (size_t)t];
    const double facing = -(gt[1] * r->normal[0] + gt[2] * r->normal[1] + gt[3] * r->normal[2]);
    const double g[3] = {r->depth[v[0]], r->depth[v[1]], r->depth[v[2]]};
    if (!(facing > 0) || !(g[0] > 0 || g[1] > 0 || g[2] > 0)) continue;
    double w[3];
    tri_wet(g, gt[0] * facing, w);
    for (int k = 0; k < 3; k++) {
      const double f = r->k_area * w[k];
      for (int d = 0; d < 3; d++) r->force[3 * (size_t)r->node[v[k]] + d] += f * r->normal[d];
      total += f;
    }
  }
  r->total = total;
}

double fem_road_dt(const fem_model *md, const fem_road *r, double omega_max) {
  /* Gershgorin: K + diag(k) has lambda_max(M^-1 .) <= omega_max^2 + max k/m, k_i at most
   * k_area times the node's whole share (every triangle facing the road) */
  double *share = r->force; /* scratch: zero before the first fem_road_force */
  for (int32_t t = 0; t < r->n_tri; t++)
    for (int k = 0; k < 3; k++) share[r->tri[3 * (size_t)t + k]] += r->tri_area[4 * (size_t)t] / 3;
  double w2 = 0;
  for (int32_t i = 0; i < r->n; i++) {
    w2 = fmax(w2, r->k_area * share[i] / md->mass[r->node[i]]);
    share[i] = 0;
  }
  return 2.0 / sqrt(omega_max * omega_max + w2);
}

void fem_rim_load(const fem_model *md, const fem_state *st, const double *b, int quasi_static,
                  double load[3]) {
  const int frame_in_b = quasi_static, road_in_b = quasi_static;
  load[0] = load[1] = load[2] = 0;
  for (int32_t a = 0; a < md->mesh.n_nodes; a++) {
    const size_t i0 = 3 * (size_t)a;
    if (!md->fixed[i0] && !md->fixed[i0 + 1] && !md->fixed[i0 + 2]) continue;
    double acc[3] = {0, 0, 0}, r[3];
    if (!frame_in_b) {
      for (int d = 0; d < 3; d++) r[d] = md->mesh.x[i0 + d] + st->u[i0 + d];
      fem_frame_point_acc(&st->frame, r, acc);
    }
    for (int d = 0; d < 3; d++) {
      if (!md->fixed[i0 + d]) continue;
      const double road = st->road.n && !road_in_b ? st->road.force[i0 + d] : 0;
      load[d] += b[i0 + d] + road - md->mass[a] * acc[d] - st->fint[i0 + d];
    }
  }
}
