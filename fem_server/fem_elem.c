/* fem_elem.c — TET4/TET10 shape functions, element data, lumped mass,
 * matrix-free internal force, strain/stress and surface loads.
 *
 * Hooke's law (seed 000 eq. 29): sigma = lambda tr(eps) I + 2 mu eps,
 * eps = sym(grad u). Element force f_a = sum_q w_q det J_q sigma_q grad N_a,
 * i.e. the K u of eq. 32 without forming K. */
#include "fem_server/fem.h"
#include "fem_server/fem_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Degree-2 rule: a = (5 + 3 sqrt 5)/20, b = (5 - sqrt 5)/20. */
#define QA 0.5854101966249685
#define QB 0.1381966011250105
const double fem_quad4_pts[4][3] = {{QB, QB, QB}, {QA, QB, QB}, {QB, QA, QB}, {QB, QB, QA}};
const double fem_quad4_w = 1.0 / 24.0;

void fem_shape(int npe, const double rst[3], double *N, double (*dN)[3]) {
  double L[4] = {1 - rst[0] - rst[1] - rst[2], rst[0], rst[1], rst[2]};
  /* dL_i/d(r,s,t) */
  static const double dL[4][3] = {{-1, -1, -1}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  if (npe == 4) {
    for (int a = 0; a < 4; a++) {
      if (N) N[a] = L[a];
      if (dN) memcpy(dN[a], dL[a], sizeof dL[a]);
    }
    return;
  }
  for (int a = 0; a < 4; a++) { /* corners: L (2L - 1) */
    if (N) N[a] = L[a] * (2 * L[a] - 1);
    if (dN)
      for (int d = 0; d < 3; d++) dN[a][d] = (4 * L[a] - 1) * dL[a][d];
  }
  for (int k = 0; k < 6; k++) { /* mid-edge: 4 L_p L_q */
    int p = fem_tet10_edge[k][0], q = fem_tet10_edge[k][1];
    if (N) N[4 + k] = 4 * L[p] * L[q];
    if (dN)
      for (int d = 0; d < 3; d++) dN[4 + k][d] = 4 * (dL[p][d] * L[q] + L[p] * dL[q][d]);
  }
}

/* Gradients dN/dx at one point; returns det J. */
static double point_gradients(const fem_mesh *m, int32_t e, const double rst[3],
                              double *grad /* [npe][3] */) {
  const int npe = m->nodes_per_elem;
  double dN[10][3], J[3][3] = {{0}};
  fem_shape(npe, rst, NULL, dN);
  const int32_t *c = m->conn + (size_t)e * npe;
  for (int a = 0; a < npe; a++) /* J_ij = dx_i / dr_j */
    for (int i = 0; i < 3; i++)
      for (int j = 0; j < 3; j++) J[i][j] += m->x[3 * (size_t)c[a] + i] * dN[a][j];
  double det = J[0][0] * (J[1][1] * J[2][2] - J[1][2] * J[2][1]) -
               J[0][1] * (J[1][0] * J[2][2] - J[1][2] * J[2][0]) +
               J[0][2] * (J[1][0] * J[2][1] - J[1][1] * J[2][0]);
  double inv[3][3]; /* J^-1 */
  inv[0][0] = (J[1][1] * J[2][2] - J[1][2] * J[2][1]) / det;
  inv[0][1] = (J[0][2] * J[2][1] - J[0][1] * J[2][2]) / det;
  inv[0][2] = (J[0][1] * J[1][2] - J[0][2] * J[1][1]) / det;
  inv[1][0] = (J[1][2] * J[2][0] - J[1][0] * J[2][2]) / det;
  inv[1][1] = (J[0][0] * J[2][2] - J[0][2] * J[2][0]) / det;
  inv[1][2] = (J[0][2] * J[1][0] - J[0][0] * J[1][2]) / det;
  inv[2][0] = (J[1][0] * J[2][1] - J[1][1] * J[2][0]) / det;
  inv[2][1] = (J[0][1] * J[2][0] - J[0][0] * J[2][1]) / det;
  inv[2][2] = (J[0][0] * J[1][1] - J[0][1] * J[1][0]) / det;
  for (int a = 0; a < npe; a++) /* dN/dx_i = dN/dr_j (J^-1)_ji */
    for (int i = 0; i < 3; i++)
      grad[3 * a + i] = dN[a][0] * inv[0][i] + dN[a][1] * inv[1][i] + dN[a][2] * inv[2][i];
  return det;
}

int fem_elem_data(fem_model *md, proto_err *err) {
  const fem_mesh *m = &md->mesh;
  const int npe = m->nodes_per_elem, nq = npe == 4 ? 1 : 4;
  md->npe = npe;
  md->nq = nq;
  md->grad = malloc(sizeof *md->grad * (size_t)m->n_elems * nq * npe * 3);
  md->wdet = malloc(sizeof *md->wdet * (size_t)m->n_elems * nq);
  md->mass = calloc((size_t)m->n_nodes, sizeof *md->mass);
  if (!md->grad || !md->wdet || !md->mass) return proto_fail(err, "out of memory (element data)");
  static const double centroid[3] = {0.25, 0.25, 0.25};
  const double rho = md->mat.density;
  for (int32_t e = 0; e < m->n_elems; e++) {
    double vol = 0;
    for (int q = 0; q < nq; q++) {
      const double *rst = nq == 1 ? centroid : fem_quad4_pts[q];
      double w = nq == 1 ? 1.0 / 6.0 : fem_quad4_w;
      double det = point_gradients(m, e, rst, md->grad + ((size_t)e * nq + q) * npe * 3);
      if (!(det > 0))
        return proto_fail(err, "element %d: Jacobian determinant %.3g <= 0 at quadrature point %d "
                          "(inverted or badly curved element)", e, det, q);
      md->wdet[(size_t)e * nq + q] = w * det;
      vol += w * det;
    }
    const int32_t *c = m->conn + (size_t)e * npe;
    if (npe == 4) { /* row sum: rho V / 4 per node */
      for (int a = 0; a < 4; a++) md->mass[c[a]] += rho * vol / 4;
    } else {
      /* HRZ: consistent diagonal (corner m/70, mid-edge 8m/105 for a
       * straight tet) scaled to the element mass -> 1/36 and 4/27. */
      for (int a = 0; a < 4; a++) md->mass[c[a]] += rho * vol / 36;
      for (int a = 4; a < 10; a++) md->mass[c[a]] += rho * vol * 4 / 27;
    }
  }
  return 0;
}

/* Stress from a displacement gradient H_ij = du_i/dx_j (eq. 29). */
static void hooke(double lambda, double mu, const double H[3][3], double S[3][3]) {
  double tr = H[0][0] + H[1][1] + H[2][2];
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++) S[i][j] = mu * (H[i][j] + H[j][i]) + (i == j ? lambda * tr : 0);
}

/* Element force for a fixed element kind: with npe and nq compile-time
 * constants (always inlined below) the loops unroll. */
static inline __attribute__((always_inline)) void
elem_force_k(const fem_model *md, const double *restrict theta, int32_t e, const double *restrict u,
             double *restrict fe, const int npe, const int nq) {
  const int32_t *c = md->mesh.conn + (size_t)e * npe;
  double ue[10][3], f[10][3];
  for (int a = 0; a < npe; a++)
    for (int d = 0; d < 3; d++) {
      ue[a][d] = u[3 * (size_t)c[a] + d];
      f[a][d] = 0;
    }
  for (int q = 0; q < nq; q++) {
    const double *g = md->grad + ((size_t)e * nq + q) * npe * 3;
    double H[3][3] = {{0}}, S[3][3];
    for (int a = 0; a < npe; a++)
      for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) H[i][j] += ue[a][i] * g[3 * a + j];
    const double w = md->wdet[(size_t)e * nq + q];
    double lw = md->lambda_elem * w * (H[0][0] + H[1][1] + H[2][2]);
    const double mw = md->mu * w;
    if (npe == 4 && md->anp) /* ANP: + kappa * mean nodal dilatation */
      lw += w * (md->lambda + 2 * md->mu / 3) * 0.25 *
            (theta[c[0]] + theta[c[1]] + theta[c[2]] + theta[c[3]]);
    for (int i = 0; i < 3; i++) /* w sigma, eq. 29 */
      for (int j = 0; j < 3; j++) S[i][j] = mw * (H[i][j] + H[j][i]) + (i == j ? lw : 0);
    for (int a = 0; a < npe; a++)
      for (int i = 0; i < 3; i++)
        f[a][i] += S[i][0] * g[3 * a] + S[i][1] * g[3 * a + 1] + S[i][2] * g[3 * a + 2];
  }
  for (int a = 0; a < npe; a++)
    for (int d = 0; d < 3; d++) fe[3 * a + d] = f[a][d];
}

static void elem_force(const fem_model *md, const double *theta, int32_t e, const double *u,
                       double *fe) {
  if (md->npe == 4) elem_force_k(md, theta, e, u, fe, 4, 1);
  else elem_force_k(md, theta, e, u, fe, 10, 4);
}

int fem_work_init(const fem_model *md, fem_work *w, proto_err *err) {
  memset(w, 0, sizeof *w);
  w->elem_force = malloc(sizeof *w->elem_force * (size_t)md->mesh.n_elems * md->mesh.nodes_per_elem * 3);
  w->node_theta = calloc((size_t)md->mesh.n_nodes, sizeof *w->node_theta);
  w->chunk_sum = calloc(3 * (size_t)fem_sum_chunks(md->mesh.n_nodes), sizeof *w->chunk_sum);
  if (!w->elem_force || !w->node_theta || !w->chunk_sum) {
    fem_work_free(w);
    return proto_fail(err, "out of memory (force kernel scratch, %d elements)", (int)md->mesh.n_elems);
  }
  return 0;
}

void fem_work_free(fem_work *w) {
  if (!w) return;
  free(w->elem_force);
  free(w->node_theta);
  free(w->chunk_sum);
  memset(w, 0, sizeof *w);
}

/* The team's share of f = K u inside a parallel region (orphaned omp for:
 * the ANP dilatation, the element kernel, the node gather, each ending in the
 * loop's barrier); outside one the calling thread does it all. */
void fem_internal_force_team(const fem_model *md, fem_work *w, const double *u, double *f) {
  if (md->anp) fem_anp_prepare_team(md, w, u); /* nodal dilatation first */
  const int npe = md->npe;
  const int32_t ne = md->mesh.n_elems, nn = md->mesh.n_nodes;
  double *fe = w->elem_force;
  const double *theta = w->node_theta;
  if (npe == 4) {
#pragma omp for schedule(static)
    for (int32_t e = 0; e < ne; e++) elem_force_k(md, theta, e, u, fe + (size_t)e * 12, 4, 1);
  } else {
#pragma omp for schedule(static)
    for (int32_t e = 0; e < ne; e++) elem_force_k(md, theta, e, u, fe + (size_t)e * 30, 10, 4);
  }
  /* gather per node: no write conflicts, no colouring needed */
#pragma omp for schedule(static)
  for (int32_t n = 0; n < nn; n++) {
    double s0 = 0, s1 = 0, s2 = 0;
    for (int32_t p = md->n2e_ptr[n]; p < md->n2e_ptr[n + 1]; p++) {
      const double *q = fe + 3 * (size_t)md->n2e[p];
      s0 += q[0];
      s1 += q[1];
      s2 += q[2];
    }
    f[3 * (size_t)n] = s0;
    f[3 * (size_t)n + 1] = s1;
    f[3 * (size_t)n + 2] = s2;
  }
}

void fem_internal_force(const fem_model *md, fem_work *w, const double *u, double *f) {
#pragma omp parallel if (md->mesh.n_elems > FEM_OMP_MIN_ELEMS)
  fem_internal_force_team(md, w, u, f);
}

/* Element stiffness block K_ab^{ij} (seed 000 eq. 34 with the index typos
 * fixed): sum_q w [mu (g_a . g_b) delta_ij + mu g_a,j g_b,i + lambda g_a,i g_b,j]. */
void fem_elem_stiffness(const fem_model *md, int32_t e, double *Ke /* [3npe]^2 */) {
  const int npe = md->npe, nq = md->nq, n = 3 * npe;
  memset(Ke, 0, sizeof *Ke * n * n);
  for (int q = 0; q < nq; q++) {
    const double *g = md->grad + ((size_t)e * nq + q) * npe * 3;
    double w = md->wdet[(size_t)e * nq + q];
    for (int a = 0; a < npe; a++)
      for (int b = 0; b < npe; b++) {
        const double *ga = g + 3 * a, *gb = g + 3 * b;
        double dot = ga[0] * gb[0] + ga[1] * gb[1] + ga[2] * gb[2];
        for (int i = 0; i < 3; i++)
          for (int j = 0; j < 3; j++)
            Ke[(3 * a + i) * n + 3 * b + j] +=
                w * (md->mu * ((i == j ? dot : 0) + ga[j] * gb[i]) + md->lambda_elem * ga[i] * gb[j]);
      }
  }
}

void fem_element_strain_stress(const fem_model *md, fem_work *w, const double *u, double *strain,
                               double *stress) {
  const int npe = md->npe, nq = md->nq;
  if (md->anp) fem_anp_prepare(md, w, u);
  static const int vi[6] = {0, 1, 2, 1, 0, 0}, vj[6] = {0, 1, 2, 2, 2, 1};
#pragma omp parallel for schedule(static) if (md->mesh.n_elems > FEM_OMP_MIN_ELEMS)
  for (int32_t e = 0; e < md->mesh.n_elems; e++) {
    const int32_t *c = md->mesh.conn + (size_t)e * npe;
    double Hm[3][3] = {{0}}, vol = 0;
    for (int q = 0; q < nq; q++) { /* volume average over the element */
      const double *g = md->grad + ((size_t)e * nq + q) * npe * 3;
      double w = md->wdet[(size_t)e * nq + q];
      vol += w;
      for (int a = 0; a < npe; a++)
        for (int i = 0; i < 3; i++)
          for (int j = 0; j < 3; j++) Hm[i][j] += w * u[3 * (size_t)c[a] + i] * g[3 * a + j];
    }
    double E[3][3], S[3][3];
    for (int i = 0; i < 3; i++)
      for (int j = 0; j < 3; j++) Hm[i][j] /= vol;
    for (int i = 0; i < 3; i++)
      for (int j = 0; j < 3; j++) E[i][j] = 0.5 * (Hm[i][j] + Hm[j][i]);
    hooke(md->lambda_elem, md->mu, Hm, S);
    if (md->anp) { /* + kappa * element mean of the nodal dilatation */
      double p = 0;
      for (int a = 0; a < 4; a++) p += 0.25 * (md->lambda + 2 * md->mu / 3) * w->node_theta[c[a]];
      for (int i = 0; i < 3; i++) S[i][i] += p;
    }
    for (int k = 0; k < 6; k++) {
      if (strain) strain[6 * (size_t)e + k] = E[vi[k]][vj[k]];
      if (stress) stress[6 * (size_t)e + k] = S[vi[k]][vj[k]];
    }
  }
}

double fem_strain_energy(const fem_model *md, fem_work *w, const double *u) {
  double s = 0;
  if (md->anp) fem_anp_prepare(md, w, u); /* sum_e V_e pbar_e theta_e = sum_a kappa V_a theta_a^2 */
  const double *theta = w->node_theta;
  const int npe = md->npe;
#pragma omp parallel for reduction(+ : s) schedule(static) if (md->mesh.n_elems > FEM_OMP_MIN_ELEMS)
  for (int32_t e = 0; e < md->mesh.n_elems; e++) {
    double fe[30];
    elem_force(md, theta, e, u, fe);
    const int32_t *c = md->mesh.conn + (size_t)e * npe;
    for (int a = 0; a < npe; a++)
      for (int d = 0; d < 3; d++) s += 0.5 * fe[3 * a + d] * u[3 * (size_t)c[a] + d];
  }
  return s;
}

/* ------------------------------------------------------------ face loads */

/* 6-point degree-4 rule on the reference triangle (weights sum to 1/2). */
static const double tri6_pts[6][2] = {
    {0.445948490915965, 0.445948490915965}, {0.445948490915965, 0.108103018168070},
    {0.108103018168070, 0.445948490915965}, {0.091576213509771, 0.091576213509771},
    {0.091576213509771, 0.816847572980459}, {0.816847572980459, 0.091576213509771}};
static const double tri6_w[6] = {0.111690794839005, 0.111690794839005, 0.111690794839005,
                                 0.054975871827661, 0.054975871827661, 0.054975871827661};

void fem_face_load(const fem_model *md, int32_t e, int f, const double t_vec[3],
                   double p_normal, double *b) {
  const fem_mesh *m = &md->mesh;
  int32_t fn[6];
  fem_face_nodes(m, e, f, fn);
  const int nf = m->nodes_per_elem == 10 ? 6 : 3;
  for (int q = 0; q < 6; q++) {
    double s = tri6_pts[q][0], t = tri6_pts[q][1], L0 = 1 - s - t;
    double N[6], dNs[6], dNt[6];
    if (nf == 3) {
      N[0] = L0; N[1] = s; N[2] = t;
      dNs[0] = -1; dNs[1] = 1; dNs[2] = 0;
      dNt[0] = -1; dNt[1] = 0; dNt[2] = 1;
    } else { /* TRI6: corners L(2L-1), mids 4 L_p L_q for edges 01 12 20 */
      N[0] = L0 * (2 * L0 - 1); N[1] = s * (2 * s - 1); N[2] = t * (2 * t - 1);
      N[3] = 4 * L0 * s; N[4] = 4 * s * t; N[5] = 4 * t * L0;
      dNs[0] = 1 - 4 * L0; dNs[1] = 4 * s - 1; dNs[2] = 0;
      dNs[3] = 4 * (L0 - s); dNs[4] = 4 * t; dNs[5] = -4 * t;
      dNt[0] = 1 - 4 * L0; dNt[1] = 0; dNt[2] = 4 * t - 1;
      dNt[3] = -4 * s; dNt[4] = 4 * s; dNt[5] = 4 * (L0 - t);
    }
    double xs[3] = {0}, xt[3] = {0};
    for (int a = 0; a < nf; a++)
      for (int d = 0; d < 3; d++) {
        xs[d] += dNs[a] * m->x[3 * (size_t)fn[a] + d];
        xt[d] += dNt[a] * m->x[3 * (size_t)fn[a] + d];
      }
    /* area-weighted outward normal (face corners are ordered outward) */
    double nA[3] = {xs[1] * xt[2] - xs[2] * xt[1], xs[2] * xt[0] - xs[0] * xt[2],
                    xs[0] * xt[1] - xs[1] * xt[0]};
    double dA = sqrt(nA[0] * nA[0] + nA[1] * nA[1] + nA[2] * nA[2]);
    for (int a = 0; a < nf; a++)
      for (int d = 0; d < 3; d++)
        b[3 * (size_t)fn[a] + d] += tri6_w[q] * N[a] * (t_vec[d] * dA + p_normal * nA[d]);
  }
}

int fem_load_pressure(const fem_model *md, const char *group, double p, double *b,
                      proto_err *err) {
  int g = fem_mesh_group(&md->mesh, group, err);
  if (g < 0) return -1;
  static const double zero[3] = {0, 0, 0};
  const fem_group *gr = &md->mesh.groups[g];
  for (int32_t i = 0; i < gr->n_faces; i++) /* pressure pushes against n_out */
    fem_face_load(md, gr->face_elem[i], gr->face_local[i], zero, -p, b);
  return 0;
}

int fem_load_traction(const fem_model *md, const char *group, const double t[3],
                      double *b, proto_err *err) {
  int g = fem_mesh_group(&md->mesh, group, err);
  if (g < 0) return -1;
  const fem_group *gr = &md->mesh.groups[g];
  for (int32_t i = 0; i < gr->n_faces; i++)
    fem_face_load(md, gr->face_elem[i], gr->face_local[i], t, 0, b);
  return 0;
}

void fem_load_gravity(const fem_model *md, const double g[3], double *b) {
  /* lumped: the same M as the explicit scheme, so a static state under
   * gravity is an equilibrium of eq. 32 */
  for (int32_t n = 0; n < md->mesh.n_nodes; n++)
    for (int d = 0; d < 3; d++) b[3 * (size_t)n + d] += md->mass[n] * g[d];
}
