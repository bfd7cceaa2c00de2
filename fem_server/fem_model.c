/* fem_model.c — model set-up: material, constraints, node adjacency and the
 * assembly of K over the free DOFs in compressed sparse columns (upper
 * triangle, the form CHOLMOD takes with stype = 1). */
#include "fem_server/fem.h"
#include "fem_server/fem_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

int fem_elem_data(fem_model *md, proto_err *err);                /* fem_elem.c */
void fem_elem_stiffness(const fem_model *md, int32_t e, double *Ke); /* fem_elem.c */

int fem_material_check(const fem_material *mat, const char *path, proto_err *err) {
  if (!(mat->E > 0)) return proto_fail(err, "%s.E: must be > 0 (got %g)", path, mat->E);
  if (!(mat->nu > -1 && mat->nu < 0.5))
    return proto_fail(err, "%s.nu: must be in (-1, 0.5) (got %g)", path, mat->nu);
  if (!(mat->density > 0))
    return proto_fail(err, "%s.density: must be > 0 (got %g)", path, mat->density);
  if (!(mat->damping >= 0 && isfinite(mat->damping)))
    return proto_fail(err, "%s.damping: must be >= 0 (got %g)", path, mat->damping);
  return 0;
}

double fem_wave_speed_p(const fem_material *m) {
  return sqrt(m->E * (1 - m->nu) / ((1 + m->nu) * (1 - 2 * m->nu) * m->density));
}

void fem_model_free(fem_model *md) {
  if (!md) return;
  fem_mesh_free(&md->mesh);
  free(md->grad);
  free(md->wdet);
  free(md->mass);
  free(md->fixed);
  free(md->u_fixed);
  free(md->eq);
  free(md->colptr);
  free(md->rowind);
  free(md->kval);
  free(md->n2e_ptr);
  free(md->n2e);
  free(md->node_vol);
  memset(md, 0, sizeof *md);
}

static int build_n2e(fem_model *md, proto_err *err) {
  const fem_mesh *m = &md->mesh;
  const int npe = m->nodes_per_elem;
  size_t tot = (size_t)m->n_elems * npe;
  md->n2e_ptr = calloc((size_t)m->n_nodes + 1, sizeof *md->n2e_ptr);
  md->n2e = malloc(sizeof *md->n2e * tot);
  if (!md->n2e_ptr || !md->n2e) return proto_fail(err, "out of memory (adjacency)");
  for (size_t s = 0; s < tot; s++) md->n2e_ptr[m->conn[s] + 1]++;
  for (int32_t n = 0; n < m->n_nodes; n++) md->n2e_ptr[n + 1] += md->n2e_ptr[n];
  int32_t *fill = malloc(sizeof *fill * (size_t)m->n_nodes);
  if (!fill) return proto_fail(err, "out of memory (adjacency)");
  memcpy(fill, md->n2e_ptr, sizeof *fill * (size_t)m->n_nodes);
  for (size_t s = 0; s < tot; s++) md->n2e[fill[m->conn[s]]++] = (int32_t)s;
  free(fill);
  return 0;
}

int fem_model_init(fem_model *md, fem_mesh *mesh, const fem_material *mat,
                   proto_err *err) {
  memset(md, 0, sizeof *md);
  md->mesh = *mesh;
  memset(mesh, 0, sizeof *mesh);
  md->mat = *mat;
  if (fem_material_check(mat, "material", err) || fem_mesh_check(&md->mesh, err)) return -1;
  md->mu = mat->E / (2 * (1 + mat->nu));
  md->lambda = mat->E * mat->nu / ((1 + mat->nu) * (1 - 2 * mat->nu));
  md->lambda_elem = md->lambda;
  md->n_dof = 3 * md->mesh.n_nodes;
  md->fixed = calloc((size_t)md->n_dof, 1);
  md->u_fixed = calloc((size_t)md->n_dof, sizeof *md->u_fixed);
  if (!md->fixed || !md->u_fixed) return proto_fail(err, "out of memory (model)");
  if (fem_elem_data(md, err) || build_n2e(md, err)) return -1;
  return 0;
}

int fem_model_fix_group(fem_model *md, const char *group, int comp_mask, proto_err *err) {
  int g = fem_mesh_group(&md->mesh, group, err);
  if (g < 0) return -1;
  int32_t *nodes, n;
  if (fem_group_nodes(&md->mesh, g, &nodes, &n, err)) return -1;
  for (int32_t i = 0; i < n; i++)
    for (int d = 0; d < 3; d++)
      if (comp_mask & (1 << d)) {
        md->fixed[3 * (size_t)nodes[i] + d] = 1;
        md->u_fixed[3 * (size_t)nodes[i] + d] = 0;
      }
  free(nodes);
  return 0;
}

void fem_model_fix_node(fem_model *md, int32_t node, int comp_mask, const double *value) {
  for (int d = 0; d < 3; d++)
    if (comp_mask & (1 << d)) {
      md->fixed[3 * (size_t)node + d] = 1;
      md->u_fixed[3 * (size_t)node + d] = value ? value[d] : 0;
    }
}

static int cmp_i32(const void *a, const void *b) {
  int32_t x = *(const int32_t *)a, y = *(const int32_t *)b;
  return (x > y) - (x < y);
}

/* Position of row r in column c (rows sorted), or -1. */
static int64_t csc_find(const fem_model *md, int32_t c, int32_t r) {
  int32_t lo = md->colptr[c], hi = md->colptr[c + 1] - 1;
  while (lo <= hi) {
    int32_t mid = (lo + hi) / 2, v = md->rowind[mid];
    if (v == r) return mid;
    if (v < r) lo = mid + 1;
    else hi = mid - 1;
  }
  return -1;
}

static int csc_fill(fem_model *md, int32_t *nb_ptr, int32_t *nb, int32_t *cnt, proto_err *err);

/* Sparsity: column j (free DOF of node b) holds the free DOFs of every node
 * sharing an element with b whose equation number is <= j. */
static int csc_pattern(fem_model *md, proto_err *err) {
  const fem_mesh *m = &md->mesh;
  const int npe = m->nodes_per_elem;
  int32_t nn = m->n_nodes;
  /* node neighbours (with duplicates, then sorted unique) */
  int32_t *nb_ptr = NULL, *nb = NULL, *cnt = NULL;
  if (md->anp) { /* the nodal pressure couples nodes two elements apart */
    if (fem_anp_neighbours(md, &nb_ptr, &nb, err)) return -1;
    cnt = malloc(sizeof *cnt * ((size_t)nn + 1));
    md->colptr = calloc((size_t)md->n_eq + 1, sizeof *md->colptr);
    if (!cnt || !md->colptr) {
      free(nb_ptr); free(nb); free(cnt);
      return proto_fail(err, "out of memory (pattern)");
    }
    for (int32_t n = 0; n < nn; n++) cnt[n] = nb_ptr[n + 1] - nb_ptr[n];
    return csc_fill(md, nb_ptr, nb, cnt, err);
  }
  nb_ptr = calloc((size_t)nn + 1, sizeof *nb_ptr);
  if (!nb_ptr) return proto_fail(err, "out of memory (pattern)");
  for (int32_t n = 0; n < nn; n++) nb_ptr[n + 1] = nb_ptr[n] + (md->n2e_ptr[n + 1] - md->n2e_ptr[n]) * npe;
  nb = malloc(sizeof *nb * ((size_t)nb_ptr[nn] + 1));
  cnt = calloc((size_t)nn, sizeof *cnt);
  md->colptr = calloc((size_t)md->n_eq + 1, sizeof *md->colptr);
  if (!nb || !cnt || !md->colptr) {
    free(nb_ptr); free(nb); free(cnt);
    return proto_fail(err, "out of memory (pattern)");
  }
  for (int32_t n = 0; n < nn; n++) {
    int32_t k = nb_ptr[n];
    for (int32_t p = md->n2e_ptr[n]; p < md->n2e_ptr[n + 1]; p++) {
      int32_t e = md->n2e[p] / npe;
      for (int a = 0; a < npe; a++) nb[k++] = m->conn[(size_t)e * npe + a];
    }
    qsort(nb + nb_ptr[n], (size_t)(k - nb_ptr[n]), sizeof *nb, cmp_i32);
    int32_t u = nb_ptr[n];
    for (int32_t i = nb_ptr[n]; i < k; i++)
      if (u == nb_ptr[n] || nb[i] != nb[u - 1]) nb[u++] = nb[i];
    cnt[n] = u - nb_ptr[n];
  }
  return csc_fill(md, nb_ptr, nb, cnt, err);
}

/* Column counts, then rows, from sorted node neighbour lists (freed here).
 * Rows come out sorted because equation numbers grow with node index. */
static int csc_fill(fem_model *md, int32_t *nb_ptr, int32_t *nb, int32_t *cnt, proto_err *err) {
  const int32_t nn = md->mesh.n_nodes;
  /* count, then fill (rows sorted because eq numbers grow with node index) */
  for (int pass = 0; pass < 2; pass++) {
    for (int32_t n = 0; n < nn; n++)
      for (int d = 0; d < 3; d++) {
        int32_t j = md->eq[3 * (size_t)n + d];
        if (j < 0) continue;
        int32_t k = pass ? md->colptr[j] : 0;
        for (int32_t i = 0; i < cnt[n]; i++)
          for (int dd = 0; dd < 3; dd++) {
            int32_t r = md->eq[3 * (size_t)nb[nb_ptr[n] + i] + dd];
            if (r < 0 || r > j) continue;
            if (pass) md->rowind[k] = r;
            k++;
          }
        if (!pass) md->colptr[j + 1] = k;
      }
    if (!pass) {
      for (int32_t j = 0; j < md->n_eq; j++) md->colptr[j + 1] += md->colptr[j];
      size_t nnz = (size_t)md->colptr[md->n_eq];
      md->rowind = malloc(sizeof *md->rowind * (nnz + 1));
      md->kval = calloc(nnz + 1, sizeof *md->kval);
      if (!md->rowind || !md->kval) {
        free(nb_ptr); free(nb); free(cnt);
        return proto_fail(err, "out of memory (K with %zu entries)", nnz);
      }
    }
  }
  free(nb_ptr);
  free(nb);
  free(cnt);
  return 0;
}

int fem_model_assemble(fem_model *md, proto_err *err) {
  free(md->eq); free(md->colptr); free(md->rowind); free(md->kval);
  md->colptr = md->rowind = NULL;
  md->kval = NULL;
  md->eq = malloc(sizeof *md->eq * (size_t)md->n_dof);
  if (!md->eq) return proto_fail(err, "out of memory (equations)");
  md->n_eq = 0;
  for (int32_t i = 0; i < md->n_dof; i++) md->eq[i] = md->fixed[i] ? -1 : md->n_eq++;
  if (md->n_eq == 0) return proto_fail(err, "every DOF is fixed: nothing to solve");
  if (csc_pattern(md, err)) return -1;
  const int npe = md->npe, n = 3 * npe;
  double Ke[900];
  for (int32_t e = 0; e < md->mesh.n_elems; e++) {
    fem_elem_stiffness(md, e, Ke);
    const int32_t *c = md->mesh.conn + (size_t)e * npe;
    for (int b = 0; b < n; b++) {
      int32_t col = md->eq[3 * (size_t)c[b / 3] + b % 3];
      if (col < 0) continue;
      for (int a = 0; a < n; a++) {
        int32_t row = md->eq[3 * (size_t)c[a / 3] + a % 3];
        if (row < 0 || row > col) continue;
        int64_t p = csc_find(md, col, row);
        if (p < 0) return proto_fail(err, "internal: K pattern misses (%d, %d)", row, col);
        md->kval[p] += Ke[a * n + b];
      }
    }
  }
  return md->anp ? fem_anp_assemble(md, err) : 0;
}
