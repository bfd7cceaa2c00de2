/* fem_anp.c — average nodal pressure TET4 (Bonet & Burton 1998, Commun.
 * Numer. Meth. Eng. 14:437, linearised), the second cure for volumetric
 * locking at nu -> 0.5 besides TET10.
 *
 *   theta_e = tr eps_e,  V_a = sum_{e ni a} V_e/4,
 *   theta_a = sum_{e ni a} (V_e/4) theta_e / V_a,
 *   sigma_e = 2 mu dev eps_e + kappa (1/4 sum_{a in e} theta_a) I.
 *
 * This is the gradient of W = sum_e V_e mu dev:dev + sum_a kappa V_a
 * theta_a^2/2, so the assembled K = K_dev + sum_a kappa V_a h_a h_a^T with
 * h_a = d theta_a / du (support: the patch of node a) is symmetric and equal
 * to what the matrix-free force applies. */
#include "fem_server/fem.h"
#include "fem_server/fem_internal.h"

#include <stdlib.h>
#include <string.h>

int fem_model_set_anp(fem_model *md, proto_err *err) {
  if (md->npe != 4) return proto_fail(err, "average nodal pressure is a TET4 formulation");
  free(md->node_vol);
  md->node_vol = calloc((size_t)md->mesh.n_nodes, sizeof *md->node_vol);
  if (!md->node_vol) return proto_fail(err, "out of memory (ANP)");
  for (int32_t e = 0; e < md->mesh.n_elems; e++)
    for (int a = 0; a < 4; a++) md->node_vol[md->mesh.conn[4 * (size_t)e + a]] += 0.25 * md->wdet[e];
  md->anp = 1;
  md->lambda_elem = -2 * md->mu / 3; /* element part: 2 mu dev eps */
  return 0;
}

static double elem_dilatation(const fem_model *md, int32_t e, const double *u) {
  const int32_t *c = md->mesh.conn + 4 * (size_t)e;
  const double *g = md->grad + 12 * (size_t)e;
  double th = 0;
  for (int a = 0; a < 4; a++)
    for (int d = 0; d < 3; d++) th += g[3 * a + d] * u[3 * (size_t)c[a] + d];
  return th;
}

/* Inside a parallel region the team shares the two loops (orphaned omp
 * for); outside one the calling thread runs them. */
void fem_anp_prepare_team(const fem_model *md, fem_work *w, const double *u) {
  const int32_t nn = md->mesh.n_nodes, ne = md->mesh.n_elems;
  double *ew = w->elem_force; /* scratch: V_e/4 theta_e per element */
#pragma omp for schedule(static)
  for (int32_t e = 0; e < ne; e++) ew[e] = 0.25 * md->wdet[e] * elem_dilatation(md, e, u);
#pragma omp for schedule(static)
  for (int32_t n = 0; n < nn; n++) {
    double s = 0;
    for (int32_t p = md->n2e_ptr[n]; p < md->n2e_ptr[n + 1]; p++) s += ew[md->n2e[p] / 4];
    w->node_theta[n] = s / md->node_vol[n];
  }
}

void fem_anp_prepare(const fem_model *md, fem_work *w, const double *u) {
#pragma omp parallel if (md->mesh.n_elems > FEM_OMP_MIN_ELEMS)
  fem_anp_prepare_team(md, w, u);
}

static int cmp_i32(const void *a, const void *b) {
  int32_t x = *(const int32_t *)a, y = *(const int32_t *)b;
  return (x > y) - (x < y);
}

int fem_anp_neighbours(const fem_model *md, int32_t **ptr_out, int32_t **nb_out, proto_err *err) {
  const int32_t nn = md->mesh.n_nodes;
  const int32_t *conn = md->mesh.conn;
  /* 1-ring first */
  int32_t *p1 = calloc((size_t)nn + 1, sizeof *p1);
  if (!p1) return proto_fail(err, "out of memory (ANP pattern)");
  for (int32_t n = 0; n < nn; n++) p1[n + 1] = p1[n] + 4 * (md->n2e_ptr[n + 1] - md->n2e_ptr[n]);
  int32_t *r1 = malloc(sizeof *r1 * ((size_t)p1[nn] + 1));
  int32_t *c1 = malloc(sizeof *c1 * (size_t)nn);
  if (!r1 || !c1) {
    free(p1); free(r1); free(c1);
    return proto_fail(err, "out of memory (ANP pattern)");
  }
  for (int32_t n = 0; n < nn; n++) {
    int32_t k = p1[n];
    for (int32_t p = md->n2e_ptr[n]; p < md->n2e_ptr[n + 1]; p++)
      for (int a = 0; a < 4; a++) r1[k++] = conn[4 * (size_t)(md->n2e[p] / 4) + a];
    qsort(r1 + p1[n], (size_t)(k - p1[n]), sizeof *r1, cmp_i32);
    int32_t u = p1[n];
    for (int32_t i = p1[n]; i < k; i++)
      if (u == p1[n] || r1[i] != r1[u - 1]) r1[u++] = r1[i];
    c1[n] = u - p1[n];
  }
  /* 2-ring: union of the 1-rings of the 1-ring */
  int32_t *p2 = calloc((size_t)nn + 1, sizeof *p2);
  size_t cap = 0;
  for (int32_t n = 0; n < nn; n++) {
    size_t s = 0;
    for (int32_t i = 0; i < c1[n]; i++) s += (size_t)c1[r1[p1[n] + i]];
    cap = s > cap ? s : cap;
  }
  int32_t *tmp = malloc(sizeof *tmp * (cap + 1));
  size_t total_cap = 0;
  int32_t *r2 = NULL;
  int rc = (p2 && tmp) ? 0 : proto_fail(err, "out of memory (ANP pattern)");
  for (int32_t n = 0; n < nn && rc == 0; n++) {
    size_t k = 0;
    for (int32_t i = 0; i < c1[n]; i++) {
      int32_t m = r1[p1[n] + i];
      memcpy(tmp + k, r1 + p1[m], sizeof *tmp * (size_t)c1[m]);
      k += (size_t)c1[m];
    }
    qsort(tmp, k, sizeof *tmp, cmp_i32);
    size_t u = 0;
    for (size_t i = 0; i < k; i++)
      if (u == 0 || tmp[i] != tmp[u - 1]) tmp[u++] = tmp[i];
    if ((size_t)p2[n] + u > total_cap) {
      total_cap = 2 * ((size_t)p2[n] + u) + 1024;
      int32_t *r = realloc(r2, sizeof *r * total_cap);
      if (!r) { rc = proto_fail(err, "out of memory (ANP pattern)"); break; }
      r2 = r;
    }
    memcpy(r2 + p2[n], tmp, sizeof *tmp * u);
    p2[n + 1] = p2[n] + (int32_t)u;
  }
  free(p1); free(r1); free(c1); free(tmp);
  if (rc) {
    free(p2); free(r2);
    return -1;
  }
  *ptr_out = p2;
  *nb_out = r2;
  return 0;
}

/* Position of row r in column c of the CSC pattern, or -1. */
static int64_t find(const fem_model *md, int32_t c, int32_t r) {
  int32_t lo = md->colptr[c], hi = md->colptr[c + 1] - 1;
  while (lo <= hi) {
    int32_t mid = (lo + hi) / 2;
    if (md->rowind[mid] == r) return mid;
    if (md->rowind[mid] < r) lo = mid + 1;
    else hi = mid - 1;
  }
  return -1;
}

/* K_vol = sum_a kappa V_a h_a h_a^T, h_a over the DOFs of the patch of a:
 * h_a[b, d] = sum_{e ni a, b in e} (V_e/4) g_b,d(e) / V_a. */
int fem_anp_assemble(fem_model *md, proto_err *err) {
  const double kappa = md->lambda + 2 * md->mu / 3;
  int32_t cap = 0;
  for (int32_t n = 0; n < md->mesh.n_nodes; n++)
    if (md->n2e_ptr[n + 1] - md->n2e_ptr[n] > cap) cap = md->n2e_ptr[n + 1] - md->n2e_ptr[n];
  int32_t *dof = malloc(sizeof *dof * 12 * ((size_t)cap + 1));
  double *h = malloc(sizeof *h * 12 * ((size_t)cap + 1));
  if (!dof || !h) {
    free(dof); free(h);
    return proto_fail(err, "out of memory (ANP assembly)");
  }
  int rc = 0;
  for (int32_t a = 0; a < md->mesh.n_nodes && rc == 0; a++) {
    int k = 0; /* (dof, value) pairs, duplicates merged below by the sum into K */
    for (int32_t p = md->n2e_ptr[a]; p < md->n2e_ptr[a + 1]; p++) {
      int32_t e = md->n2e[p] / 4;
      const double *g = md->grad + 12 * (size_t)e;
      double wv = 0.25 * md->wdet[e] / md->node_vol[a];
      for (int b = 0; b < 4; b++)
        for (int d = 0; d < 3; d++) {
          dof[k] = md->eq[3 * (size_t)md->mesh.conn[4 * (size_t)e + b] + d];
          h[k++] = wv * g[3 * b + d];
        }
    }
    double s = kappa * md->node_vol[a];
    for (int i = 0; i < k && rc == 0; i++)
      for (int j = 0; j < k; j++) {
        int32_t r = dof[i], c = dof[j];
        if (r < 0 || c < 0 || r > c) continue;
        int64_t q = find(md, c, r);
        if (q < 0) {
          rc = proto_fail(err, "internal: ANP pattern misses (%d, %d)", r, c);
          break;
        }
        md->kval[q] += s * h[i] * h[j];
      }
  }
  free(dof);
  free(h);
  return rc;
}
