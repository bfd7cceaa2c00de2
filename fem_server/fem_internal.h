/* fem_internal.h — helpers shared by the fem_server sources (not public). */
#ifndef COSIM_FEM_INTERNAL_H
#define COSIM_FEM_INTERNAL_H

#include "fem_server/fem.h"

/* Below this many elements the OpenMP fork/join costs more than it saves
 * (and spins on a shared machine). */
#define FEM_OMP_MIN_ELEMS 20000
/* Nodes per partial sum of the explicit step's energies (fem_explicit.c): the
 * chunks' sums are added in chunk order, so the energies do not depend on the
 * number of threads. 256 nodes: a chunk's work (5-10 us) dwarfs its sum's. */
#define FEM_SUM_CHUNK 256
static inline int32_t fem_sum_chunks(int32_t n_nodes) {
  return (n_nodes + FEM_SUM_CHUNK - 1) / FEM_SUM_CHUNK;
}
/* One past the last node of chunk c. */
static inline int32_t fem_chunk_end(int32_t c, int32_t n_nodes) {
  return (c + 1) * FEM_SUM_CHUNK < n_nodes ? (c + 1) * FEM_SUM_CHUNK : n_nodes;
}

/* Index of the mid-edge node between local corners a and b (TET10). */
int fem_edge_mid(int a, int b);
/* Nodes of local face f of element e: 3 corners, then (TET10) the mid-edge
 * nodes (c0,c1), (c1,c2), (c2,c0) — Gmsh TRI6 order. */
void fem_face_nodes(const fem_mesh *m, int32_t e, int f, int32_t out[6]);
/* 6 x signed volume of the tetrahedron x0..x3. */
double fem_tet_volume6(const double *x0, const double *x1, const double *x2,
                       const double *x3);

/* Boundary faces (faces of exactly one element), sorted by corner set. */
typedef struct fem_face_index {
  struct face_key *keys;
  size_t n;
} fem_face_index;
fem_face_index *fem_face_index_build(const fem_mesh *m, proto_err *err);
void fem_face_index_free(fem_face_index *ix);
/* Finds the boundary face with these corners (any order); -1 if none. */
int fem_face_index_find(const fem_face_index *ix, const int32_t corners[3],
                        int32_t *elem, int *local);

/* Shape functions of the reference tetrahedron (barycentric L0 = 1-r-s-t,
 * L1 = r, L2 = s, L3 = t): values N[npe] and derivatives dN[npe][3] wrt
 * (r, s, t). */
void fem_shape(int npe, const double rst[3], double *N, double (*dN)[3]);
/* 4-point rule (degree 2) on the reference tet: points and weights (sum 1/6). */
extern const double fem_quad4_pts[4][3];
extern const double fem_quad4_w;

/* Triangle face loads: f_a += integral of N_a * traction(n) dA over face,
 * with traction = t_vec + p_normal * n_out (n_out outward unit normal). */
void fem_face_load(const fem_model *md, int32_t e, int f, const double t_vec[3],
                   double p_normal, double *b);

/* c = a x b */
static inline void fem_cross(const double a[3], const double b[3], double c[3]) {
  c[0] = a[1] * b[2] - a[2] * b[1];
  c[1] = a[2] * b[0] - a[0] * b[2];
  c[2] = a[0] * b[1] - a[1] * b[0];
}
/* Frame acceleration of a point r at rest in the frame (fem_frame.c):
 * acc + alpha x r + Omega x (Omega x r). The body force is -m times it. */
void fem_frame_point_acc(const fem_frame *fr, const double r[3], double a[3]);

/* ANP (fem_anp.c): nodal dilatation of u into w->node_theta (w->elem_force
 * as scratch), which the element kernel then reads for the volumetric part. */
void fem_anp_prepare(const fem_model *md, fem_work *w, const double *u);
/* The same, and fem_internal_force, as a team's share inside an enclosing
 * parallel region (orphaned omp for; outside one the caller does it all). */
void fem_anp_prepare_team(const fem_model *md, fem_work *w, const double *u);
void fem_internal_force_team(const fem_model *md, fem_work *w, const double *u, double *f);
int fem_anp_assemble(fem_model *md, proto_err *err);
/* 2-ring node neighbours for the ANP pattern: nb[ptr[n]..ptr[n+1]) sorted. */
int fem_anp_neighbours(const fem_model *md, int32_t **ptr, int32_t **nb, proto_err *err);

#endif
