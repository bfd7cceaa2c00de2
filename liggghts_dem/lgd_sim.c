/* lgd_sim.c — LIGGGHTS driven through its library interface as cosim's DEM:
 * start-up from a dem_model, the coupling step with sub-steps (the coupled
 * surface moved node by node, nodal forces by eq. 42 from each sub-step's
 * contacts), summaries, gathers to rank 0. All functions are collective. */
#include "liggghts_dem/lgd_internal.h"

#include <liggghts/library.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define LGD_SCREEN_MAX (1L << 20) /* bytes of LIGGGHTS screen kept (the end of a run) */
#define LGD_SETTLE_CHUNK 50       /* steps between kinetic-energy checks while settling */
#define LGD_SETTLE_MIN 100        /* dem_settle's minimum before the check counts */
#define LGD_SNAP_COLS 10          /* gathered per grain: tag, x, v, omega */
static const char RUN_ONE[] = "run 1 pre no post no";
_Static_assert(LGD_SHIM_TIMERS == LGD_LIG_TIMERS, "the shim's timer order is lgd_timing.lig's");

struct lgd_sim {
  const dem_model *m;
  MPI_Comm comm;
  int rank, nproc;
  void *lmp;
  int ntypes, n_grains;   /* rank 0's: only rank 0 has the grains */
  double *estar;          /* Y* per type pair */
  int surface;            /* coupled mesh, -1 if none */
  int n_nodes;
  lgd_topo topo;
  uint8_t *edge_on, *corner_on;
  double *node_x, *node_v, *nodal_local;
  double *wall_local, *mesh_acc;
  lgd_rows rows;
  lgd_out out;
  double t, coupling_dt, dt; /* dt: the DEM step, the one LIGGGHTS integrates with */
  int mesh_tri[DEM_MAX_MESHES];
  int plane_axis[DEM_MAX_PLANES];
  int32_t *near;          /* (grain index, plane) pairs within r + skin of a plane */
  int near_n, near_cap, near_valid;
  int frozen_activity;
  lgd_timing time;
  double *gsend, *grecv;
  int gsend_cap, *counts, *displs;
  double *ckpt_ft;        /* checkpoint: forces, torques [n_grains*3] each (lgd_save, resume) */
};

/* Every rank learns whether any failed; the first failing rank's message wins. */
static int agree(MPI_Comm comm, int rc, proto_err *err) {
  int rank, size, first;
  MPI_Comm_rank(comm, &rank);
  MPI_Comm_size(comm, &size);
  int mine = rc < 0 ? rank : size;
  MPI_Allreduce(&mine, &first, 1, MPI_INT, MPI_MIN, comm);
  if (first == size) return 0;
  MPI_Bcast(err->msg, (int)sizeof err->msg, MPI_CHAR, first, comm);
  return -1;
}

const lgd_out *lgd_result(const lgd_sim *s) { return &s->out; }
const lgd_timing *lgd_time(const lgd_sim *s) { return &s->time; }

double lgd_dt(const lgd_sim *s) { return s->dt; }

int lgd_mesh_triangles(const lgd_sim *s, int mesh) {
  return mesh >= 0 && mesh < s->m->n_meshes ? s->mesh_tri[mesh] : -1;
}

/* ------------------------------------------------------------ start-up */

static int alloc_sim(lgd_sim *s, proto_err *err) {
  const dem_model *m = s->m;
  s->surface = -1;
  for (int k = 0; k < m->n_meshes; k++)
    if (m->meshes[k].coupled) s->surface = k;
  if (s->rank == 0) {
    s->ntypes = lgd_n_types(m);
    s->n_grains = m->n_grains;
  }
  MPI_Bcast(&s->ntypes, 1, MPI_INT, 0, s->comm);
  MPI_Bcast(&s->n_grains, 1, MPI_INT, 0, s->comm);
  for (int p = 0; p < m->n_planes; p++) s->plane_axis[p] = lgd_plane_axis(&m->planes[p]);
  s->estar = lgd_estar_table(m, s->ntypes);
  s->wall_local = calloc(3 * (size_t)m->n_walls + 1, sizeof(double));
  s->mesh_acc = calloc(3 * (size_t)m->n_meshes + 1, sizeof(double));
  s->out.wall_force = calloc(3 * (size_t)m->n_walls + 1, sizeof(double));
  s->counts = calloc((size_t)s->nproc, sizeof(int));
  s->displs = calloc((size_t)s->nproc, sizeof(int));
  if (!s->estar || !s->wall_local || !s->mesh_acc || !s->out.wall_force || !s->counts || !s->displs)
    return proto_fail(err, "out of memory");
  if (s->surface < 0) return 0;
  const dem_mesh *me = &m->meshes[s->surface];
  const size_t n3 = 3 * (size_t)me->n_nodes, t3 = 3 * (size_t)me->n_tri;
  s->n_nodes = me->n_nodes;
  s->node_x = malloc(sizeof(double) * n3);
  s->node_v = calloc(n3, sizeof(double));
  s->nodal_local = calloc(n3, sizeof(double));
  s->out.nodal_force = calloc(n3, sizeof(double));
  s->edge_on = malloc(t3);
  s->corner_on = malloc(t3);
  if (!s->node_x || !s->node_v || !s->nodal_local || !s->out.nodal_force || !s->edge_on || !s->corner_on)
    return proto_fail(err, "out of memory for the surface (%d nodes)", me->n_nodes);
  memcpy(s->node_x, me->x0, sizeof(double) * n3);
  /* LIGGGHTS drops or mangles flat triangles, and the activity rule needs
   * their normals: refuse them by index */
  for (int t = 0; t < me->n_tri; t++) {
    const double *a = &me->x0[3 * me->tri[3 * t]], *b = &me->x0[3 * me->tri[3 * t + 1]],
                 *c = &me->x0[3 * me->tri[3 * t + 2]];
    const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    const double n[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
    const double area2 = n[0] * n[0] + n[1] * n[1] + n[2] * n[2];
    const double scale = (u[0] * u[0] + u[1] * u[1] + u[2] * u[2]) * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    if (!(area2 > 1e-24 * scale) || scale == 0)
      return proto_fail(err, "surface_tri[%d]: the triangle (nodes %d, %d, %d) has no area", t, (int)me->tri[3 * t],
                        (int)me->tri[3 * t + 1], (int)me->tri[3 * t + 2]);
  }
  return lgd_topo_build(&s->topo, me->n_nodes, me->n_tri, me->tri, err);
}

/* Rank 0 writes the input files into a fresh directory and builds the
 * commands; every rank receives the commands. */
static int make_script(lgd_sim *s, const lgd_options *o, char *dir, size_t dircap, char **text,
                       proto_err *err) {
  int rc = 0;
  long len = 0;
  lgd_script sc = {0};
  dir[0] = 0;
  if (s->rank == 0) {
    const char *base = o && o->tmp_dir ? o->tmp_dir : getenv("TMPDIR");
    snprintf(dir, dircap, "%s/cosim-lgd-XXXXXX", base && base[0] ? base : "/tmp");
    if (!mkdtemp(dir)) {
      rc = proto_fail(err, "%s: cannot create a directory for the LIGGGHTS input", dir);
      dir[0] = 0;
    } else {
      rc = lgd_script_build(s->m, dir, o ? o->face_tolerance : 0, s->dt,
                            o && o->resume ? o->resume->restart : NULL,
                            o && o->resume ? o->resume->surface_x : NULL, &sc, err);
      len = rc ? 0 : (long)sc.len;
    }
  }
  if (agree(s->comm, rc, err)) {
    lgd_script_free(&sc);
    return -1;
  }
  MPI_Bcast(&len, 1, MPI_LONG, 0, s->comm);
  *text = s->rank == 0 ? sc.text : malloc((size_t)len + 1);
  if (s->rank != 0 && *text) (*text)[len] = 0;
  rc = agree(s->comm, *text ? 0 : proto_fail(err, "out of memory"), err);
  if (!rc) MPI_Bcast(*text, (int)len + 1, MPI_CHAR, 0, s->comm);
  return rc;
}

static void remove_inputs(const char *dir) {
  char p[700];
  snprintf(p, sizeof p, "%s/grains.data", dir);
  unlink(p);
  for (int k = 0; k < DEM_MAX_MESHES; k++) {
    snprintf(p, sizeof p, "%s/mesh%d.stl", dir, k);
    unlink(p);
  }
  rmdir(dir);
}

/* This rank's grains' kinetic energy (translation + rotation). */
static double local_kinetic_energy(lgd_sim *s) {
  const int n = *(int *)lammps_extract_global(s->lmp, "nlocal");
  double **v = lammps_extract_atom(s->lmp, "v"), **w = lammps_extract_atom(s->lmp, "omega");
  double *mass = lammps_extract_atom(s->lmp, "rmass"), *r = lammps_extract_atom(s->lmp, "radius");
  double ke = 0;
  for (int i = 0; i < n; i++) /* solid spheres, I = 2/5 m r²; grains that do not rotate have ω = 0 */
    ke += 0.5 * mass[i] * (v[i][0] * v[i][0] + v[i][1] * v[i][1] + v[i][2] * v[i][2]) +
          0.2 * mass[i] * r[i] * r[i] * (w[i][0] * w[i][0] + w[i][1] * w[i][1] + w[i][2] * w[i][2]);
  return ke;
}

/* dem_settle's rule (KE per grain below settle_ke_per_grain after at least
 * 100 steps, or settle_max_steps), checked every LGD_SETTLE_CHUNK steps. */
static void settle(lgd_sim *s) {
  const dem_model *m = s->m;
  const int64_t max = (int64_t)m->cfg.settle_steps;
  int64_t done = 0;
  double ke = 0, t0 = MPI_Wtime();
  while (done < max) {
    char cmd[64];
    const int64_t chunk = max - done < LGD_SETTLE_CHUNK ? max - done : LGD_SETTLE_CHUNK;
    snprintf(cmd, sizeof cmd, "run %lld pre no post no", (long long)chunk);
    lammps_command(s->lmp, cmd);
    done += chunk;
    const double mine = local_kinetic_energy(s);
    MPI_Allreduce(&mine, &ke, 1, MPI_DOUBLE, MPI_SUM, s->comm);
    if (done > LGD_SETTLE_MIN && ke < m->cfg.settle_ke * s->n_grains) break;
  }
  if (s->rank == 0)
    fprintf(stderr, "liggghts_dem: bed of %d grains settled in %lld steps (%.1f s), KE %.3g J\n",
            s->n_grains, (long long)done, MPI_Wtime() - t0, ke);
}

/* The settled bed through dem_server's writer (one owner of the bed format). */
static int save_bed(lgd_sim *s, proto_err *err) {
  const dem_model *m = s->m;
  const size_t n = (size_t)s->n_grains;
  double *buf = s->rank == 0 ? malloc(sizeof(double) * 9 * n) : NULL;
  int32_t *id = s->rank == 0 ? malloc(sizeof(int32_t) * n) : NULL;
  int rc = agree(s->comm, s->rank == 0 && (!buf || !id) ? proto_fail(err, "out of memory") : 0, err);
  if (!rc) rc = lgd_gather(s, buf, buf ? buf + 3 * n : NULL, buf ? buf + 6 * n : NULL, err);
  if (!rc && s->rank == 0) {
    for (size_t i = 0; i < n; i++) id[i] = (int32_t)i;
    dem_state st = {.n = s->n_grains, .x = buf, .v = buf + 3 * n, .omega = buf + 6 * n,
                    .radius = m->radius, .material = m->material, .id = id};
    rc = dem_bed_save(m, &st, m->cfg.save_bed, err);
    if (rc) proto_wrap(err, "%s.particles.save", m->key_path);
  }
  free(buf);
  free(id);
  return agree(s->comm, rc, err);
}

/* After LIGGGHTS read its restart file (grains and the tangential history of
 * every contact: pairs, plane walls, mesh triangles): the sim's clock, and
 * the coupled surface where it was after the last DEM step (positions,
 * velocities, activity), which a second set-up run puts into the initial
 * forces, as the step that wrote the checkpoint left them. Set-up runs do not
 * change the tangential history (LIGGGHTS' `shearupdate` is off in set-up). */
static void set_forces(lgd_sim *s, const double *f, const double *torque);
static int gather_atoms(lgd_sim *s, const char *const names[3], double *out[3], proto_err *err);
static int resume_surface(lgd_sim *s, const lgd_resume *r, proto_err *err);
static int resume(lgd_sim *s, const lgd_resume *r, proto_err *err) {
  s->t = r->t;
  const size_t n3 = 3 * (size_t)s->n_grains;
  int rc = s->rank == 0 && (!r->force || !r->torque) ? proto_fail(err, "checkpoint: no grain forces in it") : 0;
  if (!rc && !(s->ckpt_ft = malloc(sizeof(double) * 2 * n3)))
    rc = proto_fail(err, "out of memory for the forces of %d grains", s->n_grains);
  if (agree(s->comm, rc, err)) return -1;
  if (s->rank == 0) {
    memcpy(s->ckpt_ft, r->force, sizeof(double) * n3);
    memcpy(s->ckpt_ft + n3, r->torque, sizeof(double) * n3);
  }
  MPI_Bcast(s->ckpt_ft, 2 * (int)n3, MPI_DOUBLE, 0, s->comm);
  rc = resume_surface(s, r, err);
  if (agree(s->comm, rc, err)) return -1;
  set_forces(s, s->ckpt_ft, s->ckpt_ft + n3);
  return 0;
}

static int resume_surface(lgd_sim *s, const lgd_resume *r, proto_err *err) {
  if (s->surface < 0) return 0;
  const size_t n3 = 3 * (size_t)s->n_nodes;
  if (!r->surface_x || !r->surface_v) return proto_fail(err, "checkpoint: no coupled surface in it");
  memcpy(s->node_x, r->surface_x, sizeof(double) * n3);
  memcpy(s->node_v, r->surface_v, sizeof(double) * n3);
  char sid[LGD_ID_LEN];
  snprintf(sid, sizeof sid, LGD_FIX_MESH, s->surface);
  if (!s->frozen_activity) lgd_topo_activity(&s->topo, s->node_x, s->edge_on, s->corner_on);
  if (lgd_shim_mesh_set(s->lmp, sid, s->m->meshes[s->surface].tri, s->node_x, s->node_v,
                        s->frozen_activity ? NULL : s->edge_on, s->frozen_activity ? NULL : s->corner_on))
    return proto_fail(err, "LIGGGHTS mesh %s not found", sid);
  lammps_command(s->lmp, "run 0 post no");
  return 0;
}

/* Velocity Verlet starts a step from the last step's forces, which LIGGGHTS
 * computed at the half-step velocities (damping), while a set-up run computes
 * them at the full-step ones: the checkpoint carries the step's forces and
 * torques, and they replace the set-up's (ft: [n_grains*3] each, config
 * order, every rank). */
static void set_forces(lgd_sim *s, const double *f, const double *torque) {
  const int n = *(int *)lammps_extract_global(s->lmp, "nlocal");
  double **pf = lammps_extract_atom(s->lmp, "f"), **pt = lammps_extract_atom(s->lmp, "torque");
  const int *tag = lammps_extract_atom(s->lmp, "id");
  for (int i = 0; i < n; i++)
    for (int d = 0; d < 3; d++) {
      pf[i][d] = f[3 * (size_t)(tag[i] - 1) + d]; /* atom tags are model order + 1 */
      pt[i][d] = torque[3 * (size_t)(tag[i] - 1) + d];
    }
}

int lgd_save(lgd_sim *s, const char *path, lgd_resume *r, proto_err *err) {
  const dem_model *m = s->m;
  int rc = 0;
  for (int k = 0; k < m->n_meshes && !rc; k++) {
    const double *u = m->meshes[k].velocity;
    if (!m->meshes[k].coupled && (u[0] != 0 || u[1] != 0 || u[2] != 0))
      rc = proto_fail(err, "%s.walls[%d].velocity: liggghts_dem cannot checkpoint a mesh wall that "
                      "LIGGGHTS moves (fix move/mesh is not restored)", m->key_path, m->meshes[k].wall);
  }
  const size_t n3 = 3 * (size_t)s->n_grains;
  if (!rc && !s->ckpt_ft && !(s->ckpt_ft = malloc(sizeof(double) * 2 * n3)))
    rc = proto_fail(err, "out of memory for the forces of %d grains", s->n_grains);
  if (agree(s->comm, rc, err)) return -1;
  static const char *const ft[3] = {"f", "torque", NULL};
  double *out[3] = {s->ckpt_ft, s->ckpt_ft + n3, NULL};
  if (gather_atoms(s, ft, out, err)) return -1;
  MPI_Bcast(s->ckpt_ft, 2 * (int)n3, MPI_DOUBLE, 0, s->comm);
  char cmd[700];
  if (s->rank == 0) snprintf(cmd, sizeof cmd, "write_restart %s", path);
  MPI_Bcast(cmd, (int)sizeof cmd, MPI_CHAR, 0, s->comm);
  lgd_shim_restart_sizes(s->lmp); /* else read_restart overruns its buffer (lgd_shim.cpp) */
  lammps_command(s->lmp, cmd); /* one file, written by rank 0 */
  /* write_restart re-exchanges the grains and rebuilds the ghosts (LAMMPS'
   * WriteRestart::command), which the neighbour lists of a `run 1 pre no`
   * would not see: a set-up run rebuilds them, and the step's forces are put
   * back (set_forces), as a resumed sim does */
  lammps_command(s->lmp, "run 0 post no");
  s->near_valid = 0; /* the set-up may have sorted the grains */
  set_forces(s, s->ckpt_ft, s->ckpt_ft + 3 * (size_t)s->n_grains);
  *r = (lgd_resume){.restart = path, .t = s->t, .coupling_dt = s->coupling_dt,
                    .surface_x = s->surface >= 0 ? s->node_x : NULL,
                    .surface_v = s->surface >= 0 ? s->node_v : NULL,
                    .force = s->rank == 0 ? s->ckpt_ft : NULL,
                    .torque = s->rank == 0 ? s->ckpt_ft + 3 * (size_t)s->n_grains : NULL};
  return 0;
}

int lgd_open(lgd_sim **out, MPI_Comm comm, const dem_model *m, double coupling_dt, const lgd_options *o,
             proto_err *err) {
  *out = NULL;
  lgd_sim *s = calloc(1, sizeof *s);
  int rc = s ? 0 : proto_fail(err, "out of memory");
  if (agree(comm, rc, err)) return -1;
  s->m = m;
  MPI_Comm_dup(comm, &s->comm);
  MPI_Comm_rank(s->comm, &s->rank);
  MPI_Comm_size(s->comm, &s->nproc);
  s->coupling_dt = 0; /* the first lgd_step re-splits its step: the same dt, no change */
  s->frozen_activity = o ? o->frozen_activity : 0;
  rc = dem_model_dt(m, coupling_dt, &s->dt, err);
  if (!rc) rc = lgd_check_model(m, err);
  if (!rc) rc = alloc_sim(s, err);
  char dir[600], *text = NULL;
  if (agree(s->comm, rc, err) || make_script(s, o, dir, sizeof dir, &text, err)) {
    if (s->rank == 0 && dir[0]) remove_inputs(dir);
    free(text);
    lgd_close(s);
    return -1;
  }
  char *args[] = {"liggghts", "-screen", (char *)(o && o->screen ? o->screen : "/dev/null"), "-log", "none"};
  lammps_open(5, args, s->comm, &s->lmp);
  for (char *line = text, *nl; line && *line; line = nl ? nl + 1 : NULL) {
    nl = strchr(line, '\n');
    if (nl) *nl = 0;
    lammps_command(s->lmp, line); /* an input error ends the process (LIGGGHTS' Error::all) */
  }
  free(text);
  if (s->surface >= 0) {
    char id[LGD_ID_LEN];
    snprintf(id, sizeof id, LGD_FIX_MESH, s->surface);
    rc = lgd_shim_mesh_enable_motion(s->lmp, id);
  }
  lammps_command(s->lmp, "run 0 post no"); /* set-up: neighbour lists, initial forces */
  if (s->rank == 0) remove_inputs(dir);
  if (!rc && o && o->resume) rc = resume(s, o->resume, err);
  for (int k = 0; k < m->n_meshes && !rc; k++) {
    char id[LGD_ID_LEN];
    snprintf(id, sizeof id, LGD_FIX_MESH, k);
    s->mesh_tri[k] = lgd_shim_mesh_size(s->lmp, id);
    if (s->mesh_tri[k] != m->meshes[k].n_tri) /* LIGGGHTS drops degenerate triangles */
      rc = proto_fail(err, "%s: LIGGGHTS kept %d of the %d triangles of mesh %d (degenerate or "
                      "duplicate triangles are dropped; the nodal forces need them all)",
                      m->key_path, s->mesh_tri[k], m->meshes[k].n_tri, k);
  }
  const int64_t natoms = *(int64_t *)lammps_extract_global(s->lmp, "natoms");
  if (!rc && natoms != s->n_grains)
    rc = proto_fail(err, "%s.particles: LIGGGHTS holds %lld of the %d grains", m->key_path,
                    (long long)natoms, s->n_grains);
  const int fresh = !(o && (o->resume || o->skip_settle));
  if (!rc && fresh && m->cfg.settle_steps > 0) settle(s);
  if (!rc && fresh && m->cfg.save_bed[0]) rc = save_bed(s, err);
  if (agree(s->comm, rc, err)) {
    lgd_close(s);
    return -1;
  }
  *out = s;
  return 0;
}

void lgd_close(lgd_sim *s) {
  if (!s) return;
  if (s->lmp) lammps_close(s->lmp);
  lgd_topo_free(&s->topo);
  free(s->estar); free(s->wall_local); free(s->mesh_acc); free(s->out.wall_force);
  free(s->out.nodal_force); free(s->node_x); free(s->node_v); free(s->nodal_local);
  free(s->edge_on); free(s->corner_on); free(s->rows.v); free(s->gsend); free(s->grecv);
  free(s->counts); free(s->displs); free(s->near); free(s->ckpt_ft);
  if (s->comm != MPI_COMM_NULL && s->comm) MPI_Comm_free(&s->comm);
  free(s);
}

/* ------------------------------------------------------------ stepping */

/* Barycentric weights of p (a point of triangle abc, as LIGGGHTS' contact
 * points are) — seed 000 eq. 42 distributes the force by them. Rounding can
 * leave a weight a hair below 0 on an edge: clamped, renormalised. */
static void barycentric(const double *p, const double *a, const double *b, const double *c, double *w) {
  double e0[3], e1[3], e2[3];
  for (int k = 0; k < 3; k++) { e0[k] = b[k] - a[k]; e1[k] = c[k] - a[k]; e2[k] = p[k] - a[k]; }
  const double d00 = e0[0] * e0[0] + e0[1] * e0[1] + e0[2] * e0[2];
  const double d01 = e0[0] * e1[0] + e0[1] * e1[1] + e0[2] * e1[2];
  const double d11 = e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2];
  const double d20 = e2[0] * e0[0] + e2[1] * e0[1] + e2[2] * e0[2];
  const double d21 = e2[0] * e1[0] + e2[1] * e1[1] + e2[2] * e1[2];
  const double den = d00 * d11 - d01 * d01;
  w[1] = (d11 * d20 - d01 * d21) / den;
  w[2] = (d00 * d21 - d01 * d20) / den;
  w[0] = 1.0 - w[1] - w[2];
  double sum = 0;
  for (int k = 0; k < 3; k++) sum += w[k] = w[k] > 0 ? w[k] : 0;
  for (int k = 0; k < 3; k++) w[k] /= sum;
}

/* This sub-step's contacts on the coupled surface onto its nodes (local). */
static int add_nodal(lgd_sim *s, proto_err *err) {
  char id[LGD_ID_LEN];
  snprintf(id, sizeof id, LGD_FIX_MESH, s->surface);
  s->rows.n = 0;
  if (lgd_shim_mesh_contacts(s->lmp, id, &s->rows)) return proto_fail(err, "mesh contacts: out of memory");
  const int32_t *tri = s->m->meshes[s->surface].tri;
  for (int r = 0; r < s->rows.n; r++) {
    const double *row = &s->rows.v[LGD_ROW_LEN * (size_t)r];
    const int32_t *tn = &tri[3 * (int)row[LGD_ROW_TRI]];
    double w[3];
    barycentric(&row[LGD_ROW_CP], &s->node_x[3 * tn[0]], &s->node_x[3 * tn[1]], &s->node_x[3 * tn[2]], w);
    for (int a = 0; a < 3; a++)
      for (int d = 0; d < 3; d++) s->nodal_local[3 * tn[a] + d] -= w[a] * row[LGD_ROW_F + d];
  }
  return 0;
}

/* The grains within r + skin of each plane, listed again whenever LIGGGHTS
 * rebuilt its neighbour lists (only then do grain indices change, and until
 * then no grain moves more than skin/2). */
static int list_near_planes(lgd_sim *s, proto_err *err) {
  const dem_model *m = s->m;
  const int n = *(int *)lammps_extract_global(s->lmp, "nlocal");
  double **x = lammps_extract_atom(s->lmp, "x"), *r = lammps_extract_atom(s->lmp, "radius");
  s->near_n = 0;
  for (int i = 0; i < n; i++)
    for (int p = 0; p < m->n_planes; p++) {
      const int d = s->plane_axis[p];
      if (fabs(x[i][d] - m->planes[p].point[d]) - r[i] >= m->skin) continue;
      if (s->near_n == s->near_cap) {
        const int cap = s->near_cap ? 2 * s->near_cap : 4096;
        int32_t *t = realloc(s->near, sizeof(int32_t) * 2 * (size_t)cap);
        if (!t) return proto_fail(err, "out of memory");
        s->near = t;
        s->near_cap = cap;
      }
      s->near[2 * s->near_n] = i;
      s->near[2 * s->near_n++ + 1] = p;
    }
  s->near_valid = 1;
  return 0;
}

/* Plane walls of this sub-step: the force each puts on this rank's grains
 * (`store_force`, a per-grain array), and the contact statistics (LIGGGHTS'
 * planes act on both sides). */
static int add_planes(lgd_sim *s, lgd_stats *st, proto_err *err) {
  const dem_model *m = s->m;
  if (m->n_planes == 0) return 0;
  double **f[DEM_MAX_PLANES];
  for (int p = 0; p < m->n_planes; p++) {
    char id[LGD_ID_LEN + 8];
    snprintf(id, sizeof id, "force_" LGD_FIX_PLANE, p);
    if (!(f[p] = lammps_extract_fix(s->lmp, id, 1, 2, 0, 0))) return proto_fail(err, "LIGGGHTS fix %s not found", id);
  }
  if ((!s->near_valid || *(int *)lammps_extract_global(s->lmp, "ago") == 0) && list_near_planes(s, err)) return -1;
  double **x = lammps_extract_atom(s->lmp, "x"), *r = lammps_extract_atom(s->lmp, "radius");
  int *type = lammps_extract_atom(s->lmp, "type");
  for (int k = 0; k < s->near_n; k++) {
    const int i = s->near[2 * k], p = s->near[2 * k + 1], d = s->plane_axis[p];
    const double gap = fabs(x[i][d] - m->planes[p].point[d]) - r[i];
    if (gap >= 0) continue;
    double *wf = &s->wall_local[3 * m->planes[p].wall];
    for (int c = 0; c < 3; c++) wf[c] -= f[p][i][c];
    const int wt = lgd_type(m, m->planes[p].material, 0);
    lgd_stats_add(st, -gap, r[i], r[i], s->estar[(wt - 1) * s->ntypes + type[i] - 1], 1.0);
  }
  return 0;
}

/* Meshes of this sub-step: the stress module's total (the same on every rank). */
static int add_meshes(lgd_sim *s, proto_err *err) {
  for (int k = 0; k < s->m->n_meshes; k++) {
    char id[LGD_ID_LEN];
    double f[3];
    snprintf(id, sizeof id, LGD_FIX_MESH, k);
    if (lgd_shim_mesh_force(s->lmp, id, f)) return proto_fail(err, "LIGGGHTS mesh %s not found", id);
    for (int d = 0; d < 3; d++) s->mesh_acc[3 * k + d] += f[d];
  }
  return 0;
}

/* Mesh-contact statistics of the last sub-step (all meshes). */
static int mesh_stats(lgd_sim *s, lgd_stats *st, proto_err *err) {
  for (int k = 0; k < s->m->n_meshes; k++) {
    char id[LGD_ID_LEN];
    snprintf(id, sizeof id, LGD_FIX_MESH, k);
    s->rows.n = 0;
    if (lgd_shim_mesh_contacts(s->lmp, id, &s->rows)) return proto_fail(err, "mesh contacts: out of memory");
    const int wt = lgd_type(s->m, s->m->meshes[k].material, 0);
    for (int r = 0; r < s->rows.n; r++) {
      const double *row = &s->rows.v[LGD_ROW_LEN * (size_t)r];
      const double rad = row[LGD_ROW_R];
      lgd_stats_add(st, rad - row[LGD_ROW_DIST], rad, rad,
                    s->estar[(wt - 1) * s->ntypes + (int)row[LGD_ROW_TYPE] - 1], 1.0);
    }
  }
  return 0;
}

/* dem_server's health checks on this rank's grains, at the end of the step. */
static int check_grains(lgd_sim *s, proto_err *err) {
  const dem_model *m = s->m;
  const int n = *(int *)lammps_extract_global(s->lmp, "nlocal");
  double **x = lammps_extract_atom(s->lmp, "x"), **v = lammps_extract_atom(s->lmp, "v");
  double *r = lammps_extract_atom(s->lmp, "radius");
  int *tag = lammps_extract_atom(s->lmp, "id");
  const double dt2 = s->dt * s->dt;
  for (int i = 0; i < n; i++) {
    const double *p = x[i], *u = v[i], v2 = u[0] * u[0] + u[1] * u[1] + u[2] * u[2];
    if (__builtin_expect(!(v2 * dt2 <= r[i] * r[i]) || !isfinite(p[0] + p[1] + p[2]), 0)) {
      const double speed = sqrt(v2);
      if (!isfinite(p[0] + p[1] + p[2] + speed))
        return proto_fail(err, "t = %.6g s: grain %d has a non-finite position or velocity", s->t, tag[i] - 1);
      return proto_fail(err, "t = %.6g s: grain %d at (%g, %g, %g) moves %.3g m per step, more than its "
                        "radius: unstable (dt = %.3g s = %.3g Rayleigh times)", s->t, tag[i] - 1, p[0], p[1],
                        p[2], speed * s->dt, s->dt, s->dt / m->rayleigh_time);
    }
  }
  return 0;
}

static int change_dt(lgd_sim *s, double coupling_dt, proto_err *err) {
  double dt;
  if (dem_model_dt(s->m, coupling_dt, &dt, err)) return -1;
  s->coupling_dt = coupling_dt;
  if (dt == s->dt) return 0;
  char cmd[64];
  snprintf(cmd, sizeof cmd, "timestep %.17g", dt);
  lammps_command(s->lmp, cmd);
  /* `run N pre no` keeps the integrators' old dt: one set-up run makes them
   * take the new one (docs/liggghts.md §3) */
  lammps_command(s->lmp, "run 0 post no");
  s->dt = dt;
  return 0;
}

int lgd_step(lgd_sim *s, double dt, const double *x, const double *v, proto_err *err) {
  const dem_model *m = s->m;
  lgd_timing *tm = &s->time;
  const double t_start = MPI_Wtime();
  double t0;
  int rc = 0;
  if (!(dt > 0)) rc = proto_fail(err, "coupling dt must be > 0 (got %g)", dt);
  else if (s->surface >= 0 && (!x || !v)) rc = proto_fail(err, "the coupled surface needs node positions and velocities");
  else if (fabs(dt - s->coupling_dt) > 1e-12 * dt) rc = change_dt(s, dt, err);
  if (agree(s->comm, rc, err)) return -1;
  const long long nsub = llround(dt / s->dt) < 1 ? 1 : llround(dt / s->dt);
  memset(s->wall_local, 0, sizeof(double) * 3 * (size_t)m->n_walls);
  memset(s->mesh_acc, 0, sizeof(double) * 3 * (size_t)m->n_meshes);
  char sid[LGD_ID_LEN];
  if (s->surface >= 0) {
    const size_t n3 = 3 * (size_t)s->n_nodes;
    memcpy(s->node_x, x, sizeof(double) * n3);
    memcpy(s->node_v, v, sizeof(double) * n3);
    memset(s->nodal_local, 0, sizeof(double) * n3);
    snprintf(sid, sizeof sid, LGD_FIX_MESH, s->surface);
  }
  lgd_stats st = {0};
  for (long long k = 0; k < nsub && !rc; k++) {
    t0 = MPI_Wtime();
    if (s->surface >= 0) {
      /* the surface moves with its node velocities through the step, and the
       * forces of each sub-step see it where it is (dem_mesh_move) */
      for (size_t a = 0; a < 3 * (size_t)s->n_nodes; a++) s->node_x[a] += s->node_v[a] * s->dt;
      /* LIGGGHTS decided edge/corner activity once, on the initial shape:
       * re-decide it by its own rule on this shape (lgd_topo.c) */
      if (!s->frozen_activity) lgd_topo_activity(&s->topo, s->node_x, s->edge_on, s->corner_on);
      if (lgd_shim_mesh_set(s->lmp, sid, m->meshes[s->surface].tri, s->node_x, s->node_v,
                            s->frozen_activity ? NULL : s->edge_on, s->frozen_activity ? NULL : s->corner_on))
        rc = proto_fail(err, "LIGGGHTS mesh %s not found", sid);
    }
    tm->surface += MPI_Wtime() - t0;
    t0 = MPI_Wtime();
    lammps_command(s->lmp, RUN_ONE);
    tm->run += MPI_Wtime() - t0;
    lgd_shim_timer_add(s->lmp, tm->lig);
    t0 = MPI_Wtime();
    if (!rc && s->surface >= 0) rc = add_nodal(s, err);
    if (!rc) {
      memset(&st, 0, sizeof st); /* statistics: the last sub-step's */
      rc = add_planes(s, &st, err);
      if (!rc) rc = add_meshes(s, err);
    }
    tm->forces += MPI_Wtime() - t0;
  }
  t0 = MPI_Wtime();
  s->t += dt;
  if (!rc) rc = mesh_stats(s, &st, err);
  if (!rc) lgd_shim_pair_stats(s->lmp, s->estar, s->ntypes, &st);
  if (!rc) rc = check_grains(s, err);
  if (agree(s->comm, rc, err)) return -1;
  double sums[4] = {local_kinetic_energy(s), st.contacts, st.energy, st.pair_contacts}, tot[4];
  double ratio = st.max_ratio;
  MPI_Allreduce(sums, tot, 4, MPI_DOUBLE, MPI_SUM, s->comm);
  MPI_Allreduce(&st.max_ratio, &ratio, 1, MPI_DOUBLE, MPI_MAX, s->comm);
  double *row = s->out.series;
  row[DEM_SERIES_T] = s->t;
  row[DEM_SERIES_KINETIC] = tot[0];
  row[DEM_SERIES_CONTACTS] = round(tot[1]);
  row[DEM_SERIES_MAX_OVERLAP] = ratio;
  row[DEM_SERIES_ELASTIC] = tot[2];
  row[DEM_SERIES_COORDINATION] = 2.0 * round(tot[3]) / s->n_grains;
  s->out.substeps = nsub;
  MPI_Reduce(s->rank == 0 ? MPI_IN_PLACE : s->wall_local, s->wall_local, 3 * m->n_walls, MPI_DOUBLE,
             MPI_SUM, 0, s->comm);
  if (s->surface >= 0)
    MPI_Reduce(s->rank == 0 ? MPI_IN_PLACE : s->nodal_local, s->nodal_local, 3 * s->n_nodes, MPI_DOUBLE,
               MPI_SUM, 0, s->comm);
  if (s->rank == 0) { /* impulse over the coupling step / Δt = mean over the sub-steps */
    for (int w = 0; w < 3 * m->n_walls; w++) s->out.wall_force[w] = s->wall_local[w] / (double)nsub;
    for (int k = 0; k < m->n_meshes; k++)
      for (int d = 0; d < 3; d++) s->out.wall_force[3 * m->meshes[k].wall + d] += s->mesh_acc[3 * k + d] / (double)nsub;
    for (int a = 0; a < 3 * s->n_nodes; a++) s->out.nodal_force[a] = s->nodal_local[a] / (double)nsub;
    lgd_shim_screen_trim(s->lmp, LGD_SCREEN_MAX);
  }
  tm->summary += MPI_Wtime() - t0;
  tm->total += MPI_Wtime() - t_start;
  tm->steps++;
  tm->substeps += nsub;
  if (!isfinite(tot[0]))
    rc = proto_fail(err, "t = %.6g s: non-finite kinetic energy", s->t);
  else if (ratio > m->max_overlap_ratio)
    rc = proto_fail(err, "t = %.6g s: a contact overlaps by %.3g of the grain radius (max_overlap_ratio %.3g): "
                    "unstable or too soft (dt = %.3g s = %.3g Rayleigh times)", s->t, ratio,
                    m->max_overlap_ratio, s->dt, s->dt / m->rayleigh_time);
  return rc; /* the same on every rank: computed from reduced values */
}

/* ------------------------------------------------------------- gathers */

int lgd_mesh_activity(lgd_sim *s, int mesh, uint8_t *edge_active, uint8_t *corner_active, proto_err *err) {
  const int nt = mesh >= 0 && mesh < s->m->n_meshes ? s->m->meshes[mesh].n_tri : 0;
  char id[LGD_ID_LEN];
  snprintf(id, sizeof id, LGD_FIX_MESH, mesh);
  memset(edge_active, 0, 3 * (size_t)nt);
  memset(corner_active, 0, 3 * (size_t)nt);
  int rc = nt > 0 && lgd_shim_mesh_flags(s->lmp, id, edge_active, corner_active) == 0
               ? 0 : proto_fail(err, "mesh %d: no such LIGGGHTS mesh", mesh);
  if (agree(s->comm, rc, err)) return -1;
  MPI_Allreduce(MPI_IN_PLACE, edge_active, 3 * nt, MPI_UINT8_T, MPI_MAX, s->comm);
  MPI_Allreduce(MPI_IN_PLACE, corner_active, 3 * nt, MPI_UINT8_T, MPI_MAX, s->comm);
  for (int k = 0; k < 3 * nt; k++) {
    edge_active[k] = edge_active[k] > 1;
    corner_active[k] = corner_active[k] > 1;
  }
  return 0;
}

/* Three per-grain vectors of LIGGGHTS (names[k], NULL = none) in config
 * order into out[k] on rank 0 ([n_grains*3]; NULL allowed). */
static int gather_atoms(lgd_sim *s, const char *const names[3], double *out[3], proto_err *err) {
  const int n = *(int *)lammps_extract_global(s->lmp, "nlocal");
  int rc = 0;
  if (n * LGD_SNAP_COLS > s->gsend_cap) {
    free(s->gsend);
    s->gsend_cap = n * LGD_SNAP_COLS + 1024;
    s->gsend = malloc(sizeof(double) * (size_t)s->gsend_cap);
    if (!s->gsend) { s->gsend_cap = 0; rc = proto_fail(err, "out of memory"); }
  }
  const size_t ng = (size_t)s->n_grains;
  if (s->rank == 0 && !s->grecv && !(s->grecv = malloc(sizeof(double) * LGD_SNAP_COLS * ng)))
    rc = proto_fail(err, "out of memory for %zu grains", ng);
  if (agree(s->comm, rc, err)) return -1;
  double **p[3];
  for (int k = 0; k < 3; k++) p[k] = names[k] ? lammps_extract_atom(s->lmp, (char *)names[k]) : NULL;
  int *tag = lammps_extract_atom(s->lmp, "id");
  for (int i = 0; i < n; i++) {
    double *row = &s->gsend[LGD_SNAP_COLS * (size_t)i];
    row[0] = tag[i];
    for (int k = 0; k < 3; k++)
      for (int d = 0; d < 3; d++) row[1 + 3 * k + d] = p[k] ? p[k][i][d] : 0;
  }
  const int mine = n * LGD_SNAP_COLS;
  MPI_Gather(&mine, 1, MPI_INT, s->counts, 1, MPI_INT, 0, s->comm);
  int total = 0;
  for (int p = 0; s->rank == 0 && p < s->nproc; p++) { s->displs[p] = total; total += s->counts[p]; }
  MPI_Gatherv(s->gsend, mine, MPI_DOUBLE, s->grecv, s->counts, s->displs, MPI_DOUBLE, 0, s->comm);
  if (s->rank == 0) {
    if (total != LGD_SNAP_COLS * (int)ng) rc = proto_fail(err, "gathered %d grains, expected %zu", total / LGD_SNAP_COLS, ng);
    for (int r = 0; r < total / LGD_SNAP_COLS && !rc; r++) {
      const double *row = &s->grecv[LGD_SNAP_COLS * (size_t)r];
      const size_t g = (size_t)row[0] - 1; /* atom tags are model order + 1 */
      for (int k = 0; k < 3; k++)
        for (int d = 0; d < 3 && out[k]; d++) out[k][3 * g + d] = row[1 + 3 * k + d];
    }
  }
  return agree(s->comm, rc, err);
}

int lgd_gather(lgd_sim *s, double *x, double *v, double *omega, proto_err *err) {
  static const char *const names[3] = {"x", "v", "omega"};
  double *out[3] = {x, v, omega};
  return gather_atoms(s, names, out, err);
}
