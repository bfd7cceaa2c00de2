/* The road solved in the FEM alone (fem_road.c) against springs in series:
 * a bar (nu = 0, so the fixed top adds no lateral stress and the stress is
 * uniaxial and uniform, which TET4 represents exactly) hangs from its top,
 * its bottom face A on a road raised by delta into it. The penalty per unit
 * area k and the bar's E A / H act in series:
 *   F = A delta / (1/k + H/E),
 * reached by the quasi-static fixed point (K u = f_road(u), contraction k H/E)
 * and by the damped explicit scheme at rest; the load on the fixed top (the
 * rim's, fem_rim_load) is F too, and each bottom node carries k a_i depth.
 * The exact quadrature (road.quadrature "exact") on the bottom tilted so that
 * the road's edge crosses its triangles: depth = alpha (x0 - x) for x < x0,
 * F = k L_y alpha x0^2 / 2 and its moment about x = 0, k L_y alpha x0^3 / 6,
 * to round-off; the nodal form is above it (Jensen). */
#include "fem_test.h"

#include <stdlib.h>
#include <string.h>

enum { NX = 2, NY = 2, NZ = 5 };
static const double L[3] = {0.02, 0.02, 0.1}; /* m: the bar */
static const double E = 1e6, DELTA = 1e-3;    /* Pa; m: the road's rise into the bottom */
static const double K_AREA = 5e6;             /* N/m^3: k H / E = 0.5 */

/* The bottom face (group zmin) as road surface: nodes and triangles. */
static void bottom(const fem_mesh *m, int32_t **node, int32_t *n, int32_t **tri, int32_t *nt) {
  proto_err err;
  const int g = fem_mesh_group(m, "zmin", &err);
  const fem_group *gr = &m->groups[g];
  int32_t *local = malloc(sizeof *local * (size_t)m->n_nodes);
  *node = malloc(sizeof **node * 3 * (size_t)gr->n_faces);
  *tri = malloc(sizeof **tri * 3 * (size_t)gr->n_faces);
  *n = 0;
  *nt = gr->n_faces;
  for (int32_t i = 0; i < m->n_nodes; i++) local[i] = -1;
  for (int32_t f = 0; f < gr->n_faces; f++)
    for (int a = 0; a < 3; a++) {
      const int32_t v = m->conn[4 * (size_t)gr->face_elem[f] + fem_tet_face[gr->face_local[f]][a]];
      if (local[v] < 0) local[v] = (*n)++, (*node)[local[v]] = v;
      (*tri)[3 * f + a] = local[v];
    }
  free(local);
}

int main(void) {
  proto_err err;
  fem_mesh mesh;
  const int cells[3] = {NX, NY, NZ};
  OK(fem_gen_box(&mesh, L, cells, 0, &err));
  const fem_material mat = {E, 0.0, 1000, 500};
  fem_model md;
  OK(fem_model_init(&md, &mesh, &mat, &err));
  OK(fem_model_fix_group(&md, "zmax", 7, &err));
  OK(fem_model_assemble(&md, &err));
  int32_t *node, n, *tri, nt;
  bottom(&md.mesh, &node, &n, &tri, &nt);
  double *x = malloc(sizeof *x * 3 * (size_t)n);
  for (int32_t i = 0; i < n; i++)
    for (int d = 0; d < 3; d++) x[3 * i + d] = md.mesh.x[3 * (size_t)node[i] + d];
  const double A = L[0] * L[1], F_exact = A * DELTA / (1 / K_AREA + L[2] / E);

  /* quasi-static: the lagged fixed point */
  fem_state st;
  OK(fem_state_init(&md, &st, &err));
  OK(fem_road_init(&md, &st.road, node, n, tri, nt, x, K_AREA, DELTA, &err));
  double area = 0;
  for (int32_t i = 0; i < n; i++) area += st.road.area[i];
  CHECK_REL("the bottom's projected area", area, A, 1e-14);
  fem_factor *fac = NULL;
  double *b = calloc((size_t)md.n_dof, sizeof *b);
  int it;
  for (it = 0; it < 200; it++) {
    fem_road_force(&md, &st.road, st.u);
    const double before = st.road.total;
    memcpy(b, st.road.force, sizeof *b * (size_t)md.n_dof);
    OK(fem_static_solve(&md, &fac, FEM_CHOLMOD, 0, b, st.u, NULL, &err));
    fem_road_force(&md, &st.road, st.u);
    if (fabs(st.road.total - before) <= 1e-15 * F_exact) break;
  }
  fem_internal_force(&md, &st.work, st.u, st.fint);
  double load[3];
  fem_rim_load(&md, &st, b, 1, load);
  printf("quasi-static: %d iterations, road %.15g N, rim %.15g N, exact %.15g N\n", it,
         st.road.total, load[2], F_exact);
  CHECK_REL("quasi-static road force against springs in series", st.road.total, F_exact, 1e-12);
  CHECK_REL("quasi-static rim load", load[2], F_exact, 1e-12);
  CHECK(st.road.contacts == n, "every bottom node touches (%d of %d)", st.road.contacts, n);
  double worst = 0; /* each node: k a_i depth_i, depth the same everywhere */
  const double depth = F_exact / (K_AREA * A);
  for (int32_t i = 0; i < n; i++)
    worst = fmax(worst, fabs(st.road.force[3 * (size_t)node[i] + 2] - K_AREA * st.road.area[i] * depth));
  CHECK_SMALL("nodal forces k a_i depth", worst, 1e-12 * F_exact);

  /* explicit, damped, from rest: the same rest state */
  fem_state ex;
  OK(fem_state_init(&md, &ex, &err));
  OK(fem_road_init(&md, &ex.road, node, n, tri, nt, x, K_AREA, DELTA, &err));
  OK(fem_stable_dt(&md, &ex, 300, &err));
  const double bare = ex.dt_crit;
  ex.dt_crit = fem_road_dt(&md, &ex.road, ex.omega_max);
  CHECK(ex.dt_crit < bare, "the road lowers the stable step (%g < %g s)", ex.dt_crit, bare);
  memset(ex.b, 0, sizeof *ex.b * (size_t)md.n_dof);
  for (int k = 0; k < 400; k++) OK(fem_explicit_advance(&md, &ex, 1e-3, 0.9, 0, &err));
  fem_rim_load(&md, &ex, ex.b, 0, load);
  printf("explicit at t = %.3g s: road %.15g N, rim %.15g N, energy %.6g J, work %.6g J\n",
         ex.t, ex.road.total, load[2], ex.energy, ex.work_ext);
  CHECK_REL("explicit road force at rest", ex.road.total, F_exact, 1e-9);
  CHECK_REL("explicit rim load at rest", load[2], F_exact, 1e-9);

  /* exact quadrature: the bottom tilted, the road's edge at x0 inside its triangles */
  const double x_edge = 0.75 * L[0], alpha = DELTA / x_edge;
  double F_nodes = 0;
  for (int exact = 0; exact < 2; exact++) {
    fem_state q;
    OK(fem_state_init(&md, &q, &err));
    OK(fem_road_init(&md, &q.road, node, n, tri, nt, x, K_AREA, 0.0, &err));
    q.road.exact = exact;
    for (int32_t i = 0; i < n; i++) /* z = alpha (x - x0): depth alpha (x0 - x) */
      q.u[3 * (size_t)node[i] + 2] = alpha * (x[3 * i] - x_edge) - x[3 * i + 2];
    fem_road_force(&md, &q.road, q.u);
    double moment = 0;
    for (int32_t i = 0; i < n; i++) moment += q.road.force[3 * (size_t)node[i] + 2] * x[3 * i];
    const double F_int = K_AREA * L[1] * alpha * x_edge * x_edge / 2;
    const double M_int = K_AREA * L[1] * alpha * x_edge * x_edge * x_edge / 6;
    printf("tilted bottom, %s: road %.15g N (integral %.15g), moment %.15g N m (%.15g)\n",
           exact ? "exact" : "nodes", q.road.total, F_int, moment, M_int);
    if (exact) {
      CHECK_REL("exact quadrature: the penalty's integral", q.road.total, F_int, 1e-13);
      CHECK_REL("exact quadrature: its moment", moment, M_int, 1e-13);
      CHECK(F_nodes > q.road.total, "the nodal form is above the integral (%.6g > %.6g N)",
            F_nodes, q.road.total);
    }
    F_nodes = q.road.total;
    fem_state_free(&q);
  }

  fem_factor_free(&fac);
  fem_state_free(&st);
  fem_state_free(&ex);
  fem_model_free(&md);
  free(node), free(tri), free(x), free(b);
  return cosim_test_done("test_fem_road");
}
