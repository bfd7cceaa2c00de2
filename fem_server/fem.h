/* fem.h — the one public header of cosim's FEM part (prefix fem_).
 *
 * Linear-elastic solid of seed 000 §3: Hooke's law (eq. 29), Galerkin
 * discretisation (eq. 31, 33, 34), central differences (eq. 30, 32) with a
 * lumped mass matrix, plus a direct static solve K u0 = b0 (CHOLMOD) and a
 * Jacobi-PCG alternative.
 *
 * Layout (MuJoCo style):
 *   fem_mesh   nodes, tetrahedra (TET4 or TET10, Gmsh node order) and named
 *              surface groups (lists of element faces)
 *   fem_model  the scene, fixed during a run: mesh, material, element data,
 *              lumped mass, constraints, K in compressed sparse columns;
 *              const once fem_model_assemble has built it
 *   fem_state  what changes: displacement u, velocity v, internal force ...,
 *              and the stable time step found for the run (fem_stable_dt)
 *   fem_factor the static solver's own workspace: the kept factorisation and
 *              its scratch, owned by the caller (fem_static_solve)
 * DOF vectors are flat arrays of length 3*n_nodes (node-major: x,y,z).
 * Units SI. Every fallible call takes a proto_err and returns -1 on error.
 */
#ifndef COSIM_FEM_H
#define COSIM_FEM_H

#include <stddef.h>
#include <stdint.h>

#include "proto/proto.h"

/* ------------------------------------------------------------------ mesh */

typedef enum fem_elem_kind { FEM_TET4 = 4, FEM_TET10 = 10, FEM_TET4_ANP = 5 } fem_elem_kind;

/* A named surface: faces of the volume mesh, each as (element, local face).
 * Local face f of a tetrahedron has corners fem_tet_face[f] (outward normal
 * by the right-hand rule for a positively oriented element). */
#define FEM_NAME_LEN 64
typedef struct fem_group {
  char name[FEM_NAME_LEN];
  int32_t n_faces;
  int32_t *face_elem;
  int8_t *face_local;
} fem_group;

typedef struct fem_mesh {
  int32_t n_nodes;
  double *x;              /* [n_nodes*3] rest positions, m */
  int32_t n_elems;
  int nodes_per_elem;     /* 4 or 10 */
  int32_t *conn;          /* [n_elems*nodes_per_elem], Gmsh order */
  int n_groups;
  fem_group *groups;
} fem_mesh;

extern const int fem_tet_face[4][3];   /* corners of local face f */
extern const int fem_tet10_edge[6][2]; /* corners of mid-edge node 4+k */

void fem_mesh_free(fem_mesh *m);
/* Index of a group by name, or -1 (err says which groups exist). */
int fem_mesh_group(const fem_mesh *m, const char *name, proto_err *err);
/* Adds an empty group (faces appended with fem_mesh_group_add_face). */
int fem_mesh_add_group(fem_mesh *m, const char *name, proto_err *err);
int fem_mesh_group_add_face(fem_mesh *m, int g, int32_t elem, int face,
                            proto_err *err);
/* Checks: node indices in range, every node used by some element,
 * every element positively oriented and not degenerate (volume relative to
 * its longest edge cubed above 1e-9). Errors name the element or node. */
int fem_mesh_check(const fem_mesh *m, proto_err *err);
/* TET4 -> TET10: adds one node per edge at the midpoint; if snap != NULL it
 * may move the new node (e.g. onto a curved surface). Groups are kept. */
typedef void (*fem_snap_fn)(void *ctx, const double *xa, const double *xb,
                            double *xmid);
int fem_mesh_to_tet10(fem_mesh *m, fem_snap_fn snap, void *ctx, proto_err *err);
/* Adds a group of all boundary faces that are in none of the listed groups
 * (n_exclude may be 0: then every boundary face). */
int fem_mesh_add_boundary_group(fem_mesh *m, const char *name,
                                const char *const *exclude, int n_exclude,
                                proto_err *err);
/* Unique nodes of a group's faces (corner and mid-edge), sorted; *out is
 * malloc'ed. */
int fem_group_nodes(const fem_mesh *m, int g, int32_t **out, int32_t *n,
                    proto_err *err);

/* Generators. All produce TET4 meshes by splitting a structured hexahedral
 * grid into 6 Kuhn tetrahedra (conforming); call fem_mesh_to_tet10 after.
 * Box [0,Lx]x[0,Ly]x[0,Lz] with nx*ny*nz cells; groups xmin xmax ymin ymax
 * zmin zmax. jitter in [0,0.3): interior nodes moved by up to jitter*h
 * (deterministic), for irregular meshes. */
int fem_gen_box(fem_mesh *m, const double L[3], const int n[3], double jitter,
                proto_err *err);
/* Thick-walled cylinder, axis z, radii a < b, length Lz, angle (rad, up to
 * 2 pi). Cells nr x ntheta x nz. Groups inner outer zmin zmax, and for
 * angle < 2 pi also theta0 (y = 0 plane) and theta1 (end plane). */
int fem_gen_cylinder(fem_mesh *m, double a, double b, double Lz, double angle,
                     const int n[3], proto_err *err);
/* Snaps mid-edge nodes of a cylinder mesh onto the radii a and b. */
void fem_snap_cylinder(void *radii /* double[2] = {a, b} */, const double *xa,
                       const double *xb, double *xmid);

/* Tread band of seed 000 (165/65 R13): axle along y, centre at the origin.
 * Band r in [R_i, R_i + wall], lugs up to R_o = outer_diameter/2 with
 * grooves of groove_depth between them; lugs alternate between the two
 * shoulders. Groups: rim (the band's two side faces, fixed to the rim),
 * inner (inner cylinder, inflation pressure), outer (all other boundary:
 * the surface in contact with the grains). refine scales all cell counts
 * (1 = the paper's resolution, about 24 000 tets). */
typedef struct fem_tread_params {
  double outer_diameter; /* 0.544 */
  double width;          /* 0.165 */
  double wall;           /* 0.016, band thickness below the grooves */
  double groove_depth;   /* 0.015 */
  int lugs;              /* lug pairs around the circumference, 32 */
  double lug_fraction;   /* lug share of the pitch, 0.5 */
  double lug_span;       /* lug length across the width, fraction, 0.6 */
  double refine;         /* 1 */
  double phase;          /* rad: the pattern turned about the axle (0: lug 0 starts at +x) */
} fem_tread_params;
void fem_tread_defaults(fem_tread_params *p);
int fem_gen_tread(fem_mesh *m, const fem_tread_params *p, proto_err *err);
/* Snaps mid-edge nodes of a tread mesh onto its radii (axis y). */
void fem_snap_tread(void *radii /* double[3] = {R_i, R_groove, R_o} */,
                    const double *xa, const double *xb, double *xmid);

/* Gmsh MSH 4.1, ASCII or binary. Volume elements: tet4 (type 4) or tet10
 * (11); surface elements tri3/tri6 (2, 9) in physical groups become fem
 * groups (matched to boundary faces; a triangle that is not a boundary face
 * is an error). Points and lines are ignored; other 3-D types are errors. */
int fem_msh_read(const char *path, fem_mesh *m, proto_err *err);
/* Most elements a mesh may have (generated or read): int32 indices with
 * room for the TET10 nodes. */
#define FEM_MAX_ELEMS ((int64_t)200000000)
/* Largest .msh file read (bytes). */
#define FEM_MSH_MAX_BYTES ((int64_t)16 << 30)
int fem_msh_write(const char *path, const fem_mesh *m, int binary,
                  proto_err *err);

/* -------------------------------------------------------------- material */

typedef struct fem_material {
  double E;       /* Young's modulus, Pa, > 0 */
  double nu;      /* Poisson ratio, (-1, 0.5) */
  double density; /* kg/m^3, > 0 */
  double damping; /* mass-proportional damping alpha, 1/s (C = alpha M) */
} fem_material;
int fem_material_check(const fem_material *mat, const char *path,
                       proto_err *err);
double fem_wave_speed_p(const fem_material *mat); /* sqrt((lambda+2mu)/rho) */

/* ----------------------------------------------------------------- model */

typedef enum fem_solver_kind { FEM_CHOLMOD = 0, FEM_PCG = 1 } fem_solver_kind;

typedef struct fem_model {
  fem_mesh mesh;          /* owned */
  fem_material mat;
  double lambda, mu;      /* Lame parameters, Pa */
  double lambda_elem;     /* lambda used element by element: lambda, or
                             -2mu/3 with ANP (volumetric part nodal) */
  int anp;                /* average nodal pressure TET4 (fem_model_set_anp) */
  double *node_vol;       /* [n_nodes] ANP: V_a = sum_e V_e/4 */
  int npe;                /* nodes per element */
  int nq;                 /* quadrature points per element (1 or 4) */
  double *grad;           /* [n_elems][nq][npe][3] dN/dx at quad points */
  double *wdet;           /* [n_elems][nq] weight * det J (volume share) */
  double *mass;           /* [n_nodes] lumped nodal mass, kg */
  int32_t n_dof;          /* 3*n_nodes */
  uint8_t *fixed;         /* [n_dof] 1 = Dirichlet */
  double *u_fixed;        /* [n_dof] prescribed values on fixed DOFs */
  int32_t n_eq;           /* free DOFs */
  int32_t *eq;            /* [n_dof] equation number or -1 */
  /* K over free DOFs, upper triangle, compressed sparse columns, rows sorted */
  int32_t *colptr;        /* [n_eq+1] */
  int32_t *rowind;        /* [nnz] */
  double *kval;           /* [nnz] */
  int32_t *n2e_ptr;       /* [n_nodes+1] node -> (elem*npe+local) */
  int32_t *n2e;
} fem_model;

/* Takes ownership of *mesh (left zeroed). Checks the mesh and material,
 * builds element data and the lumped mass (row sum for TET4, HRZ for TET10).
 * No constraints yet: call fem_model_fix_* then fem_model_assemble. */
int fem_model_init(fem_model *md, fem_mesh *mesh, const fem_material *mat,
                   proto_err *err);
void fem_model_free(fem_model *md);
/* Fixes components (mask bit 0 = x, 1 = y, 2 = z) of all nodes of a group to
 * zero, or of one node to given values. */
int fem_model_fix_group(fem_model *md, const char *group, int comp_mask,
                        proto_err *err);
void fem_model_fix_node(fem_model *md, int32_t node, int comp_mask,
                        const double *value);
/* Average-nodal-pressure TET4 (Bonet & Burton 1998, linearised): the
 * volumetric strain is averaged at the nodes, theta_a = sum_e V_e/4 tr(eps_e)
 * / V_a, and each element takes the mean of its nodes' theta for the
 * pressure kappa theta; the deviatoric part stays element-wise. Energy
 * sum_e V_e mu dev:dev + sum_a kappa V_a theta_a^2 / 2, so K stays symmetric
 * (it couples nodes two elements apart). Call before fem_model_assemble. */
int fem_model_set_anp(fem_model *md, proto_err *err);
/* Numbers the free DOFs and assembles K (CSC, upper). The last step that
 * writes the model: from here on every call takes it const. A fem_factor of
 * an earlier assembly is stale (fem_static_solve refuses it: free it). */
int fem_model_assemble(fem_model *md, proto_err *err);

/* Scratch of the force kernel, so that the model stays const once built
 * (one per concurrent user of a model: fem_state and the static solver's
 * fem_factor each own one). */
typedef struct fem_work {
  double *elem_force; /* [n_elems*npe*3] element forces before the node gather;
                         ANP: V_e/4 theta_e per element first */
  double *node_theta; /* [n_nodes] ANP: nodal dilatation of the last u */
  double *chunk_sum;  /* [3 * chunks of FEM_SUM_CHUNK nodes] the explicit step's
                         energy sums per chunk (fem_explicit.c) */
} fem_work;
int fem_work_init(const fem_model *md, fem_work *w, proto_err *err);
void fem_work_free(fem_work *w);

/* Internal force f = K u, matrix-free (element kernel + node gather,
 * OpenMP). u and f are full DOF vectors; fixed DOFs are not special here. */
void fem_internal_force(const fem_model *md, fem_work *w, const double *u, double *f);
/* Loads, added into the full DOF vector b. Pressure p (Pa) acts against the
 * outward normal of a group's faces; traction t (Pa, vector) on a group;
 * body acceleration g (m/s^2) with the lumped mass. Consistent nodal loads
 * by face quadrature (curved TRI6 faces included). */
int fem_load_pressure(const fem_model *md, const char *group, double p,
                      double *b, proto_err *err);
int fem_load_traction(const fem_model *md, const char *group, const double t[3],
                      double *b, proto_err *err);
void fem_load_gravity(const fem_model *md, const double g[3], double *b);

/* Element-average strain and stress (Voigt: xx yy zz yz xz xy, engineering
 * shear NOT used: tensor components), [n_elems*6] each; either may be NULL. */
void fem_element_strain_stress(const fem_model *md, fem_work *w, const double *u,
                               double *strain, double *stress);
double fem_strain_energy(const fem_model *md, fem_work *w, const double *u); /* 1/2 u.Ku */

/* ---------------------------------------------------------- static solve */

typedef struct fem_solve_stats {
  double t_assemble, t_analyze, t_factor, t_solve; /* s (wall) */
  int iterations;          /* PCG */
  double residual;         /* ||b - K u||/||b|| over free DOFs */
  double nnz_factor;       /* nnz(L) (CHOLMOD) */
  double memory_peak;      /* bytes, solver's own peak (CHOLMOD / PCG) */
} fem_solve_stats;

/* The static solver's workspace for one assembled model: CHOLMOD's common
 * and kept factorisation, the right-hand-side and PCG scratch, a fem_work
 * (fem_solve.c). Owned by the caller, who starts with NULL. */
typedef struct fem_factor fem_factor;

/* Solves K u = b with u = u_fixed on fixed DOFs (b full; the fixed part of b
 * is ignored). *factor is the caller's workspace: NULL at the first call
 * (created then), kept for later solves of the same assembled model (CHOLMOD
 * reuses its factorisation; a workspace of another model or an earlier
 * assembly is an error); release it with fem_factor_free.
 * PCG: Jacobi, tolerance rtol (<= 0: 1e-10). stats may be NULL. */
int fem_static_solve(const fem_model *md, fem_factor **factor,
                     fem_solver_kind kind, double rtol, const double *b,
                     double *u, fem_solve_stats *stats, proto_err *err);
void fem_factor_free(fem_factor **f);
/* Which BLAS the process uses (from /proc/self/maps), e.g. "openblas". */
const char *fem_blas_name(void);

/* ------------------------------------------------------------- explicit */

/* Motion of the frame the body is solved in (fem_server: the rim frame,
 * x = R(t)(X + u) + c(t)), in FRAME components, held over one advance. All
 * zero = an inertial frame. The body then feels, per unit mass, the
 * fictitious acceleration of a point r = X + u moving with relative velocity
 * w (Goldstein, Classical Mechanics, 3rd ed., §4.10; Meirovitch, Methods of
 * Analytical Dynamics, §1.9):
 *   -[acc + alpha x r + omega x (omega x r) + 2 omega x w]
 *   (origin acceleration, Euler, centrifugal, Coriolis). */
typedef struct fem_frame {
  double omega[3]; /* angular velocity Omega = R^T omega_world, rad/s */
  double alpha[3]; /* angular acceleration dOmega/dt = R^T d(omega_world)/dt */
  double acc[3];   /* acceleration of the origin, R^T d2c/dt2, m/s^2 */
} fem_frame;

/* A flat road under the body, solved in the FEM alone (fem_road.c): the world
 * plane z = height pushes each node i of a surface below it with
 * f_i = k_area a_i depth_i along its normal (a_i the node's share of the
 * surface area; normal only), or with the exact integral of the penalty over
 * the triangles (exact). n = 0: no road. */
typedef struct fem_road {
  int32_t n;            /* surface nodes the road acts on (0: no road) */
  int32_t *node;        /* [n] mesh node of each */
  double *area;         /* [n] a_i, m^2: projected on the road (fem_road_place) */
  int32_t n_tri, *tri;  /* the surface's triangles in road-node numbering */
  double *tri_area;     /* [n_tri*4] area and outward unit normal (frame) of each */
  double *k;            /* [n] k_area a_i, N/m */
  double k_area;        /* penalty per unit area, N/m^3 */
  double height;        /* world z of the plane, m */
  double normal[3], h;  /* the plane in the frame: n . r = h (fem_road_place) */
  double *force;        /* [n_dof] the road's force at the last evaluation (frame) */
  double total;         /* its sum along n (the world +z force), N */
  int32_t contacts;     /* nodes below the plane at the last evaluation */
  int exact;            /* 1: k_area ∫ N_i max(0, depth) over each triangle facing the
                           road (depth linear on it), instead of k_area a_i depth_i */
  double *depth;        /* [n] scratch of the exact quadrature: each node's depth */
} fem_road;

typedef struct fem_state {
  double t;             /* s */
  double *u;            /* [n_dof] displacement at t (rim frame) */
  double *v;            /* [n_dof] velocity at t (relative to the rim) */
  double *v_half;       /* [n_dof] velocity at t - dt/2 (leapfrog) */
  double *fint;         /* [n_dof] K u at t */
  double *b;            /* [n_dof] external force over the coming step */
  double energy0;       /* discrete energy at the start of the run */
  double energy;        /* discrete (shadow) energy, conserved by eq. 32 */
  double work_ext;      /* work of b since the start */
  double work_abs;      /* sum of |work| increments (instability bound) */
  double kinetic, strain; /* 1/2 v.Mv, 1/2 u.Ku at t */
  /* the stable step: a property of the model, found once per run by
   * fem_stable_dt and kept here so that the model stays const (0 until
   * then; fem_state_reset keeps them) */
  double omega_max;     /* sqrt(lambda_max(M^-1 K)), rad/s */
  double dt_crit;       /* 2/omega_max, s */
  double dt_sub;        /* last sub-step used */
  int64_t n_sub;        /* sub-steps taken so far */
  fem_frame frame;      /* frame motion over the coming advance (zeroed by
                           fem_state_init: inertial) */
  double rim_w_prev[3], rim_v_prev[3]; /* fem_frame_from_rim: last call's */
  int rim_has_prev;
  fem_work work;        /* the force kernel's scratch */
  fem_road road;        /* optional road (fem_road_init; zeroed: none), freed with the state */
} fem_state;

/* Columns of fem_server's per-step summary, its "series" dataset (names:
 * fem_participant.c). */
typedef enum fem_series_col {
  FEM_SERIES_T,         /* s, end of the coupling step */
  FEM_SERIES_STRAIN,    /* fem_state.strain, J */
  FEM_SERIES_KINETIC,   /* fem_state.kinetic, J */
  FEM_SERIES_DT_SUB,    /* fem_state.dt_sub, s */
  FEM_SERIES_SUB_STEPS, /* sub-steps in the coupling step (quasi-static: 1) */
  FEM_N_SERIES
} fem_series_col;

int fem_state_init(const fem_model *md, fem_state *st, proto_err *err);
void fem_state_free(fem_state *st);
/* Starts a run at rest in state u (v = 0), computing K u. */
void fem_state_reset(const fem_model *md, fem_state *st, const double *u);

/* Largest eigenvalue of M^-1 K over the free DOFs by power iteration with a
 * Rayleigh quotient (converged to rel. 1e-6 or max_iter); sets
 * st->omega_max and st->dt_crit = 2/omega_max. Call after fem_state_init:
 * it uses st->work as scratch and leaves the rest of st as it was. */
int fem_stable_dt(const fem_model *md, fem_state *st, int max_iter,
                  proto_err *err);

/* Advances st by `span` seconds with central differences (eq. 32, leapfrog
 * form, damping C = alpha M), external force st->b held constant, in the
 * frame st->frame (fictitious forces, fem_explicit.c):
 * n = ceil(span/(safety*st->dt_crit)) equal sub-steps, or a forced dt_sub > 0
 * (span/dt_sub rounded up). Stops with an error naming the limit when the
 * discrete energy exceeds 10x (energy0 + work_abs) or is not finite. */
int fem_explicit_advance(const fem_model *md, fem_state *st, double span,
                         double safety, double dt_sub, proto_err *err);

/* The road (fem_road.c). fem_road_init: over the surface nodes node[n] (mesh
 * indices), triangles tri[n_tri*3] in surface numbering and surface positions
 * x[n*3] (areas and normals of its triangles). fem_road_place: the plane in
 * the frame x = R r + c of the coming step, and the area shares a_i: a third
 * of each triangle facing the road, projected on it. fem_road_force:
 * r->force, total and contacts at displacement u. fem_road_dt: the stable step
 * bound 2 / sqrt(omega_max^2 + max_i k_i / m_i) with the road's stiffness. */
int fem_road_init(const fem_model *md, fem_road *r, const int32_t *node, int32_t n,
                  const int32_t *tri, int32_t n_tri, const double *x, double k_area,
                  double height, proto_err *err);
void fem_road_place(fem_road *r, const double R[9], const double c[3]);
void fem_road_force(const fem_model *md, fem_road *r, const double *u);
double fem_road_dt(const fem_model *md, const fem_road *r, double omega_max);
void fem_road_free(fem_road *r);
/* The load the body puts on its supports (the rim), frame components: the sum
 * over the fixed DOFs of b + road - m a_frame - K u (b: the step's external
 * force; quasi_static: b holds the frame loads and the road's force already). */
void fem_rim_load(const fem_model *md, const fem_state *st, const double *b, int quasi_static,
                  double load[3]);

/* Sets st->frame for the coming step of length span from the rim's motion
 * at its end (world frame, PROTOCOL.md role fem): R (rim -> world, row-major),
 * angular velocity w and origin velocity v. Omega = R^T w; the accelerations
 * are backward differences over the step, alpha = R^T (w - w_prev)/span and
 * acc = R^T (v - v_prev)/span (the previous call's w, v; zero at the first
 * call: the body starts at rest relative to the frame, moving with it). A
 * frame whose velocity jumps between steps (the coupler's piecewise-constant
 * rim velocity) thus gets exactly the velocity change as an impulse spread
 * over one step: first order in span for a smoothly accelerating frame. */
void fem_frame_from_rim(fem_state *st, const double R[9], const double w[3],
                        const double v[3], double span);
/* True if the frame rotates or spins up (the explicit scheme then couples the
 * three components of each node through the Coriolis term). */
int fem_frame_rotating(const fem_frame *fr);
/* Adds the frame's inertial (d'Alembert) loads at displacement u to b:
 * b_a -= m_a [acc + alpha x r_a + Omega x (Omega x r_a)], r_a = X_a + u_a,
 * lumped masses (consistent with the explicit scheme and fem_load_gravity).
 * The Coriolis term is velocity dependent: fem_explicit_advance treats it
 * itself; a steady (quasi-static) state has no relative velocity. */
void fem_load_frame(const fem_model *md, const fem_frame *fr, const double *u,
                    double *b);

/* ---------------------------------------------------------------- config */

typedef enum fem_mesh_source {
  FEM_MESH_FILE = 0, FEM_GEN_BAR, FEM_GEN_SLAB, FEM_GEN_CYLINDER, FEM_GEN_TREAD
} fem_mesh_source;
typedef enum fem_mode { FEM_EXPLICIT = 0, FEM_QUASI_STATIC = 1 } fem_mode;

#define FEM_MAX_FIXED 8
#define FEM_MAX_PRESSURE 4
/* A parsed processes.<name> section (see README.md for the keys). */
typedef struct fem_config {
  char path[256];            /* key path of the section, for errors */
  fem_mesh_source source;
  char mesh_file[512];
  char mesh_write[512];      /* optional: write the mesh used as .msh */
  double size[3];            /* bar/slab box, m */
  int cells[3];              /* bar/slab/cylinder cell counts */
  double jitter;
  double radii[2], length, angle; /* cylinder (angle in rad) */
  fem_tread_params tread;
  fem_elem_kind element;
  fem_material mat;
  int n_fixed;
  char fixed_group[FEM_MAX_FIXED][FEM_NAME_LEN];
  int fixed_mask[FEM_MAX_FIXED];
  int n_pressure;
  char pressure_group[FEM_MAX_PRESSURE][FEM_NAME_LEN];
  double pressure[FEM_MAX_PRESSURE];  /* Pa */
  double gravity[3];         /* world frame, m/s^2 */
  fem_mode mode;
  fem_solver_kind solver;
  double safety;             /* dt = safety * dt_crit */
  double dt_sub;             /* forced sub-step (0 = automatic) */
  int allow_unstable;        /* accept dt_sub > dt_crit (tests) */
  int power_iterations;
  int initial_static;        /* start from K u0 = b0 */
  char surface_group[FEM_NAME_LEN]; /* coupled to the grains */
  int road;                  /* a road solved in the FEM (README "road") */
  double road_z, road_k_area; /* world z of the plane (m), penalty per area (N/m^3) */
  int road_exact;             /* road.quadrature "exact": the penalty integrated (fem_road.c) */
  int reaction;              /* series: the load on the fixed DOFs (the rim) */
  int threads;               /* OpenMP threads; 0 = OpenMP's default (OMP_NUM_THREADS or the cores) */
} fem_config;

void fem_config_defaults(fem_config *c);
/* Reads a section; errors name the key path (path = "processes.fem"). */
int fem_config_read(const cJSON *section, const char *path, fem_config *c,
                    proto_err *err);
/* Builds the mesh (file or generator, TET10 if asked), the model, the
 * constraints and K. On failure nothing is left allocated in md. */
int fem_config_build(const fem_config *c, fem_model *md, proto_err *err);
/* Pressure loads of the config into b (zeroed first). */
int fem_config_loads(const fem_config *c, const fem_model *md, double *b,
                     proto_err *err);

#endif
