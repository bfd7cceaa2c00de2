/* The tread generator: the paper's resolution gives about 24 000 tets; the
 * groups rim / inner / outer partition the boundary (each boundary face in
 * exactly one), the boundary is closed (area vectors sum to zero), the
 * volume matches the polygonal ring + lugs exactly (TET4) and the circular
 * one closely (TET10 with snapped mid-edge nodes), and MSH round trips. */
#include "fem_test.h"

#include <string.h>
#include <unistd.h>

static double mesh_volume(const fem_model *md) {
  double v = 0;
  for (int32_t q = 0; q < md->mesh.n_elems * md->nq; q++) v += md->wdet[q];
  return v;
}

int main(void) {
  proto_err err;
  fem_tread_params p;
  fem_tread_defaults(&p);
  fem_mesh m;
  OK(fem_gen_tread(&m, &p, &err));
  printf("tread refine 1: %d nodes, %d tets\n", m.n_nodes, m.n_elems);
  CHECK(m.n_elems > 20000 && m.n_elems < 28000, "tet count %d not about 24 000", m.n_elems);
  /* groups partition the boundary and the boundary is closed */
  int64_t faces = 0;
  double area[3] = {0, 0, 0};
  for (int g = 0; g < m.n_groups; g++) {
    faces += m.groups[g].n_faces;
    printf("  group %-6s %6d faces\n", m.groups[g].name, m.groups[g].n_faces);
    CHECK(m.groups[g].n_faces > 0, "group %s empty", m.groups[g].name);
    for (int32_t i = 0; i < m.groups[g].n_faces; i++) {
      const int *fc = fem_tet_face[m.groups[g].face_local[i]];
      const int32_t *c = m.conn + 4 * m.groups[g].face_elem[i];
      const double *a = m.x + 3 * c[fc[0]], *b = m.x + 3 * c[fc[1]], *d = m.x + 3 * c[fc[2]];
      double u[3], v[3];
      for (int k = 0; k < 3; k++) { u[k] = b[k] - a[k]; v[k] = d[k] - a[k]; }
      area[0] += 0.5 * (u[1] * v[2] - u[2] * v[1]);
      area[1] += 0.5 * (u[2] * v[0] - u[0] * v[2]);
      area[2] += 0.5 * (u[0] * v[1] - u[1] * v[0]);
    }
  }
  fem_mesh all = {0};
  all.n_nodes = m.n_nodes; all.x = m.x; all.n_elems = m.n_elems; all.nodes_per_elem = 4; all.conn = m.conn;
  OK(fem_mesh_add_boundary_group(&all, "all", NULL, 0, &err));
  printf("  boundary faces %d, in groups %lld; sum of area vectors (%.1e, %.1e, %.1e) m^2\n",
         all.groups[0].n_faces, (long long)faces, area[0], area[1], area[2]);
  CHECK(all.groups[0].n_faces == faces, "groups do not partition the boundary");
  CHECK(fabs(area[0]) + fabs(area[1]) + fabs(area[2]) < 1e-12, "boundary not closed");
  free(all.groups[0].face_elem);
  free(all.groups[0].face_local);
  free(all.groups);

  /* volume: polygonal ring (n_theta = 4 * lugs cells) + lug cells */
  const double ro = p.outer_diameter / 2, rg = ro - p.groove_depth, ri = rg - p.wall;
  const int nth = 4 * p.lugs, ny = 12, span = 7; /* lug_span 0.6 * 12 cells */
  const double poly = 0.5 * nth * sin(2 * M_PI / nth);
  double v_exact = poly * (rg * rg - ri * ri) * p.width +
                   poly * (ro * ro - rg * rg) * p.width * (2.0 / 4.0) * span / ny;
  double v_circ = M_PI * (rg * rg - ri * ri) * p.width + M_PI * (ro * ro - rg * rg) * p.width * 0.5 * span / ny;
  char path[128];
  snprintf(path, sizeof path, "/tmp/test_fem_tread_%d.msh", (int)getpid());
  OK(fem_msh_write(path, &m, 1, &err));
  fem_material mat = {20e6, 0.45, 1100, 0};
  fem_model md;
  OK(fem_model_init(&md, &m, &mat, &err));
  double v4 = mesh_volume(&md);
  printf("TET4 volume %.8e m^3, polygonal exact %.8e (rel %.1e)\n", v4, v_exact, v4 / v_exact - 1);
  CHECK(fabs(v4 / v_exact - 1) < 1e-12, "TET4 volume %.10e vs %.10e", v4, v_exact);
  double mass = 0;
  for (int32_t i = 0; i < md.mesh.n_nodes; i++) mass += md.mass[i];
  CHECK(fabs(mass / (mat.density * v4) - 1) < 1e-12, "lumped mass %.6e vs rho V %.6e", mass, mat.density * v4);
  fem_model_free(&md);

  fem_mesh r;
  OK(fem_msh_read(path, &r, &err));
  unlink(path);
  CHECK(r.n_elems == 23808 && r.n_groups == 3, "binary MSH round trip of the tread: %d elements, %d groups", r.n_elems, r.n_groups);
  double radii[3] = {ri, rg, ro};
  OK(fem_mesh_to_tet10(&r, fem_snap_tread, radii, &err));
  OK(fem_model_init(&md, &r, &mat, &err));
  double v10 = mesh_volume(&md);
  mass = 0;
  int negative = 0;
  for (int32_t i = 0; i < md.mesh.n_nodes; i++) {
    mass += md.mass[i];
    negative += md.mass[i] <= 0;
  }
  printf("TET10 volume %.8e m^3, circular %.8e (rel %.1e; TET4 %.1e); HRZ mass %.6e kg, %d non-positive\n",
         v10, v_circ, v10 / v_circ - 1, v4 / v_circ - 1, mass, negative);
  CHECK(fabs(v10 / v_circ - 1) < 0.1 * fabs(v4 / v_circ - 1), "TET10 curved volume not closer to the circle");
  CHECK(negative == 0 && fabs(mass / (mat.density * v10) - 1) < 1e-12, "HRZ lumped mass");
  fem_model_free(&md);
  fem_mesh_free(&m);
  return cosim_test_done("test_fem_tread");
}
