/* fem_participant.c — the FEM participant of fem_server (role "fem", PROTOCOL.md).
 *
 * The tread is solved in the rim's frame (docs/architecture.md): x = R(t)(X + u) + c(t).
 * Each coupling step: nodal forces (world; a sparse nodal_force, PROTOCOL.md
 * "Sparse exchange", is expanded first) are rotated into the rim frame,
 * added to the inflation pressure and gravity (rotated likewise), the tread
 * is advanced by sub-cycled central differences (or re-solved statically
 * with the kept factor in quasi_static mode), and the surface nodes go back
 * in the world frame: v = R v_rel + omega x (x - c) + v_c. The rim frame's
 * inertial forces (origin acceleration, Euler, centrifugal, Coriolis) act on
 * the tread (fem_frame.c, fem_explicit.c); the frame's accelerations are
 * backward differences of consecutive steps' rim_omega and rim_v. */
#include "fem_server/fem.h"

#include <math.h>
#ifdef _OPENMP
#include <omp.h>
#endif
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* snapshot arrays (snap.<name>) and the mesh arrays written once (mesh.<name>) */
enum { SNAP_X, SNAP_U, SNAP_V, SNAP_STRAIN, SNAP_STRESS, SNAP_ROAD, N_SNAP };
static const char *const SNAP[N_SNAP] = {"x", "u", "v", "strain", "stress", "road_force"};
static const char *const MESH_X0 = "x0", *const MESH_CELLS = "cells";
/* with a road: the surface it acts on, written once (results.h5 /<name>/mesh/) */
static const char *const MESH_SURF_NODE = "surface_node", *const MESH_SURF_TRI = "surface_tri",
                  *const MESH_SURF_X0 = "surface_x0", *const MESH_ROAD_AREA = "road_area";
/* the series' optional columns: the road's (fem_road.c), the rim's load */
enum { N_ROAD_COLS = 2, N_REACTION_COLS = 3, MAX_SERIES = FEM_N_SERIES + N_ROAD_COLS + N_REACTION_COLS };
/* state arrays (state.<name>) */
static const char *const ST_U = "u", *const ST_V = "v", *const ST_V_HALF = "v_half",
                  *const ST_FINT = "fint", *const ST_SCALARS = "scalars";
#define ST_RIM_PREV "rim_prev" /* a literal: optional, found by its full name */
/* rim_prev: the rim's w[3], v[3] of the last step and whether there was one
 * (fem_frame_from_rim: the frame's acceleration is their difference) */
enum { N_RIM_PREV = 7 };

typedef struct server {
  fem_config cfg;
  fem_model md;         /* built by configure, const from then on */
  fem_state st;
  fem_factor *factor;   /* static solver's kept factorisation (NULL before the first solve) */
  double span;          /* coupling step, s */
  double *b_static;     /* [n_dof] pressure loads (rim frame) */
  double *b_qs;         /* [n_dof] quasi-static right-hand side */
  double *u_prev;       /* [n_dof] quasi-static: previous solution */
  int32_t n_surf, n_tri;
  int32_t *surf_node;   /* [n_surf] mesh node of each surface node */
  int32_t *surf_tri;    /* [n_tri*3] */
  double *surf_x0;      /* [n_surf*3] rim frame, after the static solve */
  double *x_out, *v_out; /* [n_surf*3] world */
  double *f_dense;       /* [n_surf*3] a sparse nodal_force expanded */
  double series[MAX_SERIES];
  int n_series;         /* FEM_N_SERIES, + the road's, + the reaction's columns */
  double scalars[8];    /* state_save: the scalar part of fem_state */
  double rim_prev[N_RIM_PREV]; /* state_save: the rim of the last step */
  /* snapshots */
  int32_t *cells;       /* [n_elems*npe] VTK order */
  double *mesh_x0, *snap_x, *snap_v, *strain, *stress, *voigt;
  double *snap_road;    /* [n_nodes*3] with a road: its force on each node, world */
} server;

/* ------------------------------------------------------------- configure */

static int configure(void *user, const proto_run_info *info, const cJSON *section,
                     proto_err *err) {
  server *s = user;
  if (fem_config_read(section, info->key_path, &s->cfg, err)) return -1;
#ifdef _OPENMP
  if (s->cfg.threads > 0) omp_set_num_threads(s->cfg.threads); /* results do not depend on it */
  fprintf(stderr, "%s: %d OpenMP threads (threads %s)\n", info->key_path, omp_get_max_threads(),
          s->cfg.threads > 0 ? "set" : "auto");
#endif
  if (fem_config_build(&s->cfg, &s->md, err)) return -1;
  s->span = info->dt;
  if (s->cfg.dt_sub > 0 && info->dt > 0 && s->cfg.dt_sub > info->dt)
    return proto_fail(err, "%s.dt_sub: %g s exceeds the coupling step %g s", info->key_path,
                      s->cfg.dt_sub, info->dt);
  return 0;
}

/* -------------------------------------------------------------- surface */

/* Surface triangles of the coupled group; TET10 faces split into 4. */
static int build_surface(server *s, proto_err *err) {
  const fem_mesh *m = &s->md.mesh;
  int g = fem_mesh_group(m, s->cfg.surface_group, err);
  if (g < 0) return -1;
  const fem_group *gr = &m->groups[g];
  int split = m->nodes_per_elem == 10 ? 4 : 1;
  int32_t *local = malloc(sizeof *local * (size_t)m->n_nodes);
  s->surf_tri = malloc(sizeof *s->surf_tri * 3 * (size_t)gr->n_faces * split);
  s->surf_node = malloc(sizeof *s->surf_node * 6 * (size_t)gr->n_faces);
  if (!local || !s->surf_tri || !s->surf_node) {
    free(local);
    return proto_fail(err, "out of memory (surface)");
  }
  for (int32_t i = 0; i < m->n_nodes; i++) local[i] = -1;
  static const int sub[4][3] = {{0, 3, 5}, {3, 1, 4}, {5, 4, 2}, {3, 4, 5}};
  for (int32_t f = 0; f < gr->n_faces; f++) {
    int32_t fn[6];
    const int8_t lf = gr->face_local[f];
    const int32_t e = gr->face_elem[f];
    const int *fc = fem_tet_face[lf];
    const int32_t *c = m->conn + (size_t)e * m->nodes_per_elem;
    for (int a = 0; a < 3; a++) fn[a] = c[fc[a]];
    if (split == 4)
      for (int a = 0; a < 3; a++) { /* mid-edge node between fc[a], fc[a+1] */
        int p = fc[a], q = fc[(a + 1) % 3], k;
        for (k = 0; k < 6; k++)
          if ((fem_tet10_edge[k][0] == p && fem_tet10_edge[k][1] == q) ||
              (fem_tet10_edge[k][0] == q && fem_tet10_edge[k][1] == p))
            break;
        fn[3 + a] = c[4 + k];
      }
    for (int a = 0; a < 3 * (split == 4 ? 2 : 1); a++)
      if (local[fn[a]] < 0) {
        local[fn[a]] = s->n_surf;
        s->surf_node[s->n_surf++] = fn[a];
      }
    for (int t = 0; t < split; t++)
      for (int a = 0; a < 3; a++)
        s->surf_tri[3 * ((size_t)s->n_tri + t) + a] = local[fn[split == 4 ? sub[t][a] : a]];
    s->n_tri += split;
  }
  free(local);
  size_t n3 = 3 * (size_t)s->n_surf;
  s->surf_x0 = malloc(sizeof *s->surf_x0 * n3);
  s->x_out = malloc(sizeof *s->x_out * n3);
  s->v_out = malloc(sizeof *s->v_out * n3);
  s->f_dense = malloc(sizeof *s->f_dense * (n3 + 1));
  if (!s->surf_x0 || !s->x_out || !s->v_out || !s->f_dense) return proto_fail(err, "out of memory (surface)");
  for (int32_t i = 0; i < s->n_surf; i++)
    for (int d = 0; d < 3; d++)
      s->surf_x0[3 * i + d] = m->x[3 * (size_t)s->surf_node[i] + d] + s->st.u[3 * (size_t)s->surf_node[i] + d];
  return 0;
}

static int alloc_snapshots(server *s, proto_err *err) {
  const fem_mesh *m = &s->md.mesh;
  size_t nn3 = 3 * (size_t)m->n_nodes, ne6 = 6 * (size_t)m->n_elems;
  const int npe = m->nodes_per_elem;
  s->cells = malloc(sizeof *s->cells * (size_t)m->n_elems * npe);
  s->mesh_x0 = malloc(sizeof(double) * nn3);
  s->snap_x = malloc(sizeof(double) * nn3);
  s->snap_v = malloc(sizeof(double) * nn3);
  s->strain = malloc(sizeof(double) * ne6);
  s->stress = malloc(sizeof(double) * ne6);
  s->voigt = malloc(sizeof(double) * ne6);
  if (s->cfg.road && !(s->snap_road = calloc(nn3, sizeof(double))))
    return proto_fail(err, "out of memory (snapshots)");
  if (!s->cells || !s->mesh_x0 || !s->snap_x || !s->snap_v || !s->strain || !s->stress || !s->voigt)
    return proto_fail(err, "out of memory (snapshots)");
  memcpy(s->mesh_x0, m->x, sizeof(double) * nn3);
  /* Gmsh TET10 has edges (2,3) then (1,3); VTK/XDMF the other way round */
  for (int32_t e = 0; e < m->n_elems; e++)
    for (int a = 0; a < npe; a++) {
      int src = npe == 10 && a == 8 ? 9 : npe == 10 && a == 9 ? 8 : a;
      s->cells[(size_t)e * npe + a] = m->conn[(size_t)e * npe + src];
    }
  return 0;
}

/* ------------------------------------------------------------------ init */

static int init(void *user, const proto_msg *welcome, proto_msg *ready, proto_err *err) {
  (void)welcome;
  server *s = user;
  const fem_model *md = &s->md;
  const char *path = s->cfg.path;
  size_t nd = (size_t)md->n_dof;
  s->b_static = calloc(nd, sizeof *s->b_static);
  s->b_qs = calloc(nd, sizeof *s->b_qs);
  s->u_prev = calloc(nd, sizeof *s->u_prev);
  if (!s->b_static || !s->b_qs || !s->u_prev) return proto_fail(err, "out of memory");
  if (fem_state_init(md, &s->st, err) || fem_config_loads(&s->cfg, md, s->b_static, err)) return -1;
  double *u0 = s->u_prev; /* R(0) = I: gravity in the rim frame = world */
  memcpy(s->b_qs, s->b_static, sizeof *s->b_qs * nd);
  fem_load_gravity(md, s->cfg.gravity, s->b_qs);
  if (s->cfg.initial_static || s->cfg.mode == FEM_QUASI_STATIC) {
    fem_solve_stats ss;
    if (fem_static_solve(md, &s->factor, s->cfg.solver, 1e-10, s->b_qs, u0, &ss, err))
      return proto_wrap(err, "%s: initial static solve", path);
    fprintf(stderr, "%s: static solve K u0 = b0: %d equations, %s (BLAS: %s), analyze %.3f s, "
            "factor %.3f s, solve %.3f s, %d iterations, residual %.1e\n", path, md->n_eq,
            s->cfg.solver == FEM_CHOLMOD ? "CHOLMOD" : "PCG", fem_blas_name(), ss.t_analyze,
            ss.t_factor, ss.t_solve, ss.iterations, ss.residual);
  }
  fem_state_reset(md, &s->st, u0);
  if (build_surface(s, err) || alloc_snapshots(s, err)) return -1;
  if (s->cfg.road &&
      fem_road_init(md, &s->st.road, s->surf_node, s->n_surf, s->surf_tri, s->n_tri, s->surf_x0,
                    s->cfg.road_k_area, s->cfg.road_z, err))
    return proto_wrap(err, "%s.road", path);
  s->st.road.exact = s->cfg.road_exact;
  if (s->cfg.mode == FEM_EXPLICIT) {
    if (fem_stable_dt(md, &s->st, s->cfg.power_iterations, err)) return -1;
    if (s->cfg.road) { /* the road's stiffness lowers the stable step */
      const double bare = s->st.dt_crit;
      s->st.dt_crit = fem_road_dt(md, &s->st.road, s->st.omega_max);
      fprintf(stderr, "%s.road: stable step %.4g s without the road, %.4g s with its penalty "
              "(k_area %.4g N/m^3 on %d nodes)\n", path, bare, s->st.dt_crit, s->cfg.road_k_area,
              s->st.road.n);
    }
    double dt = s->cfg.dt_sub > 0 ? s->cfg.dt_sub : s->cfg.safety * s->st.dt_crit;
    if (s->cfg.dt_sub > s->st.dt_crit && !s->cfg.allow_unstable)
      return proto_fail(err, "%s.dt_sub: %.4g s exceeds the stable limit dt_crit = 2/omega_max = "
                        "%.4g s (set allow_unstable to force it)", path, s->cfg.dt_sub, s->st.dt_crit);
    fprintf(stderr, "%s: %d nodes, %d %s elements; stable step dt_crit = 2/omega_max = %.4g s "
            "(power iteration), sub-step %.4g s (safety %.2f), %lld sub-steps per coupling step "
            "of %.4g s\n", path, md->mesh.n_nodes, md->mesh.n_elems,
            md->npe == 10 ? "tet10" : "tet4", s->st.dt_crit, dt, s->cfg.safety,
            s->span > 0 ? (long long)((s->span / dt) + 0.999999) : 0LL, s->span);
  }

  const char *cols[MAX_SERIES] = {
      [FEM_SERIES_T] = "t", [FEM_SERIES_STRAIN] = "strain_energy",
      [FEM_SERIES_KINETIC] = "kinetic_energy", [FEM_SERIES_DT_SUB] = "dt_sub",
      [FEM_SERIES_SUB_STEPS] = "sub_steps"};
  s->n_series = FEM_N_SERIES;
  if (s->cfg.road) cols[s->n_series++] = "road_force", cols[s->n_series++] = "road_contacts";
  if (s->cfg.reaction)
    cols[s->n_series++] = "reaction_x", cols[s->n_series++] = "reaction_y",
    cols[s->n_series++] = "reaction_z";
  if (proto_ready_series(ready, PROTO_A_SERIES, s->n_series, cols) < 0 ||
      proto_ready_snapshot(ready, md->npe == 10 ? "tet10" : "tet4", SNAP[SNAP_X], MESH_CELLS,
                           s->cfg.road ? 5 : 4, SNAP + SNAP_U) < 0)
    return proto_fail(err, "out of memory");
  cJSON *h = proto_msg_header(ready);
  cJSON_AddBoolToObject(h, PROTO_H_SPARSE, 1); /* nodal_force may come sparse */
  cJSON *info = cJSON_AddObjectToObject(h, "fem");
  cJSON_AddNumberToObject(info, "dt_crit", s->st.dt_crit);
  cJSON_AddNumberToObject(info, "nodes", md->mesh.n_nodes);
  cJSON_AddNumberToObject(info, "elements", md->mesh.n_elems);
  cJSON_AddNumberToObject(info, "equations", md->n_eq);
  if (proto_msg_add_f8(ready, PROTO_A_SURFACE_X0, s->n_surf, 3, s->surf_x0) ||
      proto_msg_add_i4(ready, PROTO_A_SURFACE_TRI, s->n_tri, 3, s->surf_tri) ||
      proto_msg_add_prefixed(ready, PROTO_P_MESH, MESH_X0, PROTO_F8, md->mesh.n_nodes, 3,
                             s->mesh_x0) ||
      proto_msg_add_prefixed(ready, PROTO_P_MESH, MESH_CELLS, PROTO_I4, md->mesh.n_elems,
                             md->npe, s->cells))
    return proto_fail(err, "ready message full");
  if (s->cfg.road &&
      (proto_msg_add_prefixed(ready, PROTO_P_MESH, MESH_SURF_NODE, PROTO_I4, s->n_surf, 0,
                              s->surf_node) ||
       proto_msg_add_prefixed(ready, PROTO_P_MESH, MESH_SURF_TRI, PROTO_I4, s->n_tri, 3,
                              s->surf_tri) ||
       proto_msg_add_prefixed(ready, PROTO_P_MESH, MESH_SURF_X0, PROTO_F8, s->n_surf, 3,
                              s->surf_x0) ||
       proto_msg_add_prefixed(ready, PROTO_P_MESH, MESH_ROAD_AREA, PROTO_F8, s->n_surf, 0,
                              s->st.road.area)))
    return proto_fail(err, "ready message full");
  return 0;
}

/* ------------------------------------------------------------------ step */

/* y = R x (row-major R) and y = R^T x */
static void rot(const double *R, const double *x, double *y) {
  for (int a = 0; a < 3; a++) y[a] = R[3 * a] * x[0] + R[3 * a + 1] * x[1] + R[3 * a + 2] * x[2];
}
static void rot_t(const double *R, const double *x, double *y) {
  for (int a = 0; a < 3; a++) y[a] = R[a] * x[0] + R[3 + a] * x[1] + R[6 + a] * x[2];
}

/* World position and velocity of node n. */
static void to_world(const server *s, const double *R, const double *c, const double *w,
                     const double *vc, int32_t n, double *x, double *v) {
  double X[3], r[3], vr[3];
  for (int d = 0; d < 3; d++) X[d] = s->md.mesh.x[3 * (size_t)n + d] + s->st.u[3 * (size_t)n + d];
  rot(R, X, r);
  rot(R, s->st.v + 3 * (size_t)n, vr);
  double wr[3] = {w[1] * r[2] - w[2] * r[1], w[2] * r[0] - w[0] * r[2], w[0] * r[1] - w[1] * r[0]};
  for (int d = 0; d < 3; d++) {
    x[d] = c[d] + r[d];
    v[d] = vc[d] + wr[d] + vr[d];
  }
}

static int step(void *user, proto_peer *peer, const proto_step_info *info,
                const proto_msg *req, proto_msg *reply, proto_err *err) {
  server *s = user;
  const fem_model *md = &s->md;
  /* checked against the role table by the participant loop */
  const double *f = proto_msg_dense(req, PROTO_A_NODAL_FORCE, s->n_surf, 3, s->f_dense);
  const double *R = proto_msg_data(req, PROTO_A_RIM_R);
  const double *c = proto_msg_data(req, PROTO_A_RIM_C);
  const double *w = proto_msg_data(req, PROTO_A_RIM_OMEGA);
  const double *vc = proto_msg_data(req, PROTO_A_RIM_V);
  const double span = info->dt;
  fem_frame_from_rim(&s->st, R, w, vc, span);
  if (s->cfg.road) fem_road_place(&s->st.road, R, c);
  /* external force in the rim frame: pressure + R^T g m + R^T f, constant
   * over the coupling step (the role table: f is the step's mean force) */
  double g[3];
  rot_t(R, s->cfg.gravity, g);
  double *b = s->cfg.mode == FEM_EXPLICIT ? s->st.b : s->b_qs;
  const int64_t bad = proto_first_nonfinite(f, 3 * (int64_t)s->n_surf);
  if (bad >= 0) {
    const int node = (int)(bad / 3);
    return proto_fail(err, "nodal_force[%d] (surface node %d) is not finite", node, node);
  }
  memcpy(b, s->b_static, sizeof *b * (size_t)md->n_dof);
  fem_load_gravity(md, g, b);
  for (int32_t i = 0; i < s->n_surf; i++) {
    double fr[3];
    rot_t(R, f + 3 * (size_t)i, fr);
    for (int d = 0; d < 3; d++) b[3 * (size_t)s->surf_node[i] + d] += fr[d];
  }
  if (s->cfg.mode == FEM_EXPLICIT) {
    if (fem_explicit_advance(md, &s->st, span, s->cfg.safety, s->cfg.dt_sub, err)) return -1;
  } else { /* quasi-static: K u = b with the kept factor; steady in the rim
              frame, so no Coriolis; frame loads at the previous u (lag) */
    fem_load_frame(md, &s->st.frame, s->st.u, b);
    if (s->cfg.road) { /* the road's force at the previous u, lagged like the frame loads */
      fem_road_force(md, &s->st.road, s->st.u);
      for (int32_t i = 0; i < md->n_dof; i++) b[i] += s->st.road.force[i];
    }
    memcpy(s->u_prev, s->st.u, sizeof *s->u_prev * (size_t)md->n_dof);
    if (fem_static_solve(md, &s->factor, s->cfg.solver, 1e-10, b, s->st.u, NULL, err)) return -1;
    for (int32_t i = 0; i < md->n_dof; i++) s->st.v[i] = (s->st.u[i] - s->u_prev[i]) / span;
    fem_internal_force(md, &s->st.work, s->st.u, s->st.fint);
    double se = 0, ke = 0;
    for (int32_t i = 0; i < md->n_dof; i++) {
      se += 0.5 * s->st.u[i] * s->st.fint[i];
      ke += 0.5 * md->mass[i / 3] * s->st.v[i] * s->st.v[i];
    }
    s->st.strain = se;
    s->st.kinetic = ke;
    s->st.t += span;
    s->st.dt_sub = span;
  }
  /* x, v straight into the segment the reply is posted in (zero copy), when
   * the arrays travel by shared memory; else into our own arrays */
  const size_t n3 = 3 * (size_t)s->n_surf;
  double *xo = proto_peer_reply_buffer(peer, 2 * n3 * sizeof(double));
  double *vo = xo ? xo + n3 : s->v_out;
  if (!xo) xo = s->x_out;
  for (int32_t i = 0; i < s->n_surf; i++)
    to_world(s, R, c, w, vc, s->surf_node[i], xo + 3 * (size_t)i, vo + 3 * (size_t)i);
  s->series[FEM_SERIES_T] = info->t_end;
  s->series[FEM_SERIES_STRAIN] = s->st.strain;
  s->series[FEM_SERIES_KINETIC] = s->st.kinetic;
  s->series[FEM_SERIES_DT_SUB] = s->st.dt_sub;
  s->series[FEM_SERIES_SUB_STEPS] =
      s->cfg.mode == FEM_EXPLICIT ? (double)(int64_t)(span / s->st.dt_sub + 0.5) : 1;
  int col = FEM_N_SERIES;
  if (s->cfg.road) { /* explicit: at the step's end; quasi-static: the lagged force */
    s->series[col++] = s->st.road.total;
    s->series[col++] = s->st.road.contacts;
  }
  if (s->cfg.reaction) { /* the tread's load on the rim, world frame */
    double load[3], world[3];
    fem_rim_load(md, &s->st, b, s->cfg.mode == FEM_QUASI_STATIC, load);
    rot(R, load, world);
    for (int d = 0; d < 3; d++) s->series[col++] = world[d];
  }
  if (proto_msg_add_f8(reply, PROTO_A_X, s->n_surf, 3, xo) ||
      proto_msg_add_f8(reply, PROTO_A_V, s->n_surf, 3, vo) ||
      proto_msg_add_f8(reply, PROTO_A_SERIES, s->n_series, 0, s->series))
    return proto_fail(err, "reply full");
  if (info->output) {
    const int32_t nn = md->mesh.n_nodes, ne = md->mesh.n_elems;
    for (int32_t n = 0; n < nn; n++)
      to_world(s, R, c, w, vc, n, s->snap_x + 3 * (size_t)n, s->snap_v + 3 * (size_t)n);
    fem_element_strain_stress(md, &s->st.work, s->st.u, s->voigt, NULL);
    /* XDMF Tensor6 order: xx xy xz yy yz zz (ours: xx yy zz yz xz xy) */
    static const int perm[6] = {0, 5, 4, 1, 3, 2};
    for (int32_t e = 0; e < ne; e++)
      for (int k = 0; k < 6; k++) s->strain[6 * (size_t)e + k] = s->voigt[6 * (size_t)e + perm[k]];
    fem_element_strain_stress(md, &s->st.work, s->st.u, NULL, s->voigt);
    for (int32_t e = 0; e < ne; e++)
      for (int k = 0; k < 6; k++) s->stress[6 * (size_t)e + k] = s->voigt[6 * (size_t)e + perm[k]];
    if (s->cfg.road)
      for (int32_t i = 0; i < s->st.road.n; i++) {
        const size_t n3 = 3 * (size_t)s->st.road.node[i];
        rot(R, s->st.road.force + n3, s->snap_road + n3);
      }
    const double *snap[N_SNAP] = {s->snap_x, s->st.u, s->snap_v, s->strain, s->stress,
                                  s->snap_road};
    const int64_t rows[N_SNAP] = {nn, nn, nn, ne, ne, nn}, cols[N_SNAP] = {3, 3, 3, 6, 6, 3};
    for (int a = 0; a < N_SNAP - !s->cfg.road; a++)
      if (proto_msg_add_prefixed(reply, PROTO_P_SNAP, SNAP[a], PROTO_F8, rows[a], cols[a], snap[a]))
        return proto_fail(err, "reply full");
  }
  return 0;
}

/* ----------------------------------------------------------------- state */

/* The whole changing state (rollback of the implicit scheme, checkpoints):
 * u, v, v_half, K u, the scalars of fem_state and the rim's w, v of the last
 * step (the frame's acceleration over the next is the difference: without
 * them a restart, and every iteration after an implicit step's first, saw
 * none). st.b is rebuilt by every step from its request; quasi-static mode
 * changes only u and v. */
static int state_save(void *user, proto_msg *state, proto_err *err) {
  server *s = user;
  const fem_state *st = &s->st;
  const int64_t nd = s->md.n_dof;
  const double sc[8] = {st->t, st->energy, st->work_ext, st->work_abs, st->kinetic,
                        st->strain, st->dt_sub, (double)st->n_sub};
  memcpy(s->scalars, sc, sizeof sc);
  memcpy(s->rim_prev, st->rim_w_prev, sizeof st->rim_w_prev);
  memcpy(s->rim_prev + 3, st->rim_v_prev, sizeof st->rim_v_prev);
  s->rim_prev[6] = st->rim_has_prev;
  if (proto_msg_add_prefixed(state, PROTO_P_STATE, ST_U, PROTO_F8, nd, 0, st->u) ||
      proto_msg_add_prefixed(state, PROTO_P_STATE, ST_V, PROTO_F8, nd, 0, st->v) ||
      proto_msg_add_prefixed(state, PROTO_P_STATE, ST_V_HALF, PROTO_F8, nd, 0, st->v_half) ||
      proto_msg_add_prefixed(state, PROTO_P_STATE, ST_FINT, PROTO_F8, nd, 0, st->fint) ||
      proto_msg_add_prefixed(state, PROTO_P_STATE, ST_SCALARS, PROTO_F8, 8, 0, s->scalars) ||
      proto_msg_add_prefixed(state, PROTO_P_STATE, ST_RIM_PREV, PROTO_F8, N_RIM_PREV, 0,
                             s->rim_prev))
    return proto_fail(err, "state message full");
  return 0;
}

static int state_load(void *user, const proto_msg *state, proto_err *err) {
  server *s = user;
  fem_state *st = &s->st;
  const size_t nd = (size_t)s->md.n_dof;
  double sc[8];
  if (proto_state_get(state, ST_U, PROTO_F8, nd, st->u, err) ||
      proto_state_get(state, ST_V, PROTO_F8, nd, st->v, err) ||
      proto_state_get(state, ST_V_HALF, PROTO_F8, nd, st->v_half, err) ||
      proto_state_get(state, ST_FINT, PROTO_F8, nd, st->fint, err) ||
      proto_state_get(state, ST_SCALARS, PROTO_F8, 8, sc, err))
    return -1;
  st->t = sc[0];
  st->energy = sc[1];
  st->work_ext = sc[2];
  st->work_abs = sc[3];
  st->kinetic = sc[4];
  st->strain = sc[5];
  st->dt_sub = sc[6];
  st->n_sub = (int64_t)sc[7];
  /* a checkpoint written before rim_prev was saved: no last step, as then */
  double rp[N_RIM_PREV] = {0};
  if (proto_msg_find(state, PROTO_P_STATE ST_RIM_PREV) &&
      proto_state_get(state, ST_RIM_PREV, PROTO_F8, N_RIM_PREV, rp, err))
    return -1;
  memcpy(st->rim_w_prev, rp, sizeof st->rim_w_prev);
  memcpy(st->rim_v_prev, rp + 3, sizeof st->rim_v_prev);
  st->rim_has_prev = rp[6] != 0;
  return 0;
}

static void finish(void *user) {
  server *s = user;
  fem_state_free(&s->st);
  fem_factor_free(&s->factor);
  fem_model_free(&s->md);
  free(s->b_static); free(s->b_qs); free(s->u_prev);
  free(s->surf_node); free(s->surf_tri); free(s->surf_x0);
  free(s->x_out); free(s->v_out); free(s->f_dense);
  free(s->cells); free(s->mesh_x0); free(s->snap_x); free(s->snap_v);
  free(s->strain); free(s->stress); free(s->voigt); free(s->snap_road);
  memset(s, 0, sizeof *s);
}

int main(int argc, char **argv) {
  static server s;
  static const proto_participant_ops ops = {.role = PROTO_ROLE_FEM,
                                            .configure = configure,
                                            .init = init,
                                            .step = step,
                                            .finish = finish,
                                            .state_save = state_save,
                                            .state_load = state_load};
  return proto_participant_main(argc, argv, &ops, &s);
}
