/* dem_state.c — the state of a run: allocation, initial checks, and the time
 * step (velocity Verlet, seed 000 eq. 4–5; orientation by quaternion instead
 * of eq. 9's Euler angles, which are singular at sin φ2 = 0). */
#include "dem_server/dem_internal.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int alloc_state(const dem_model *m, dem_state *s, proto_err *err) {
  const size_t n = (size_t)m->n_grains;
  s->n = m->n_grains;
  s->work = calloc(1, sizeof *s->work);
  if (!s->work) return proto_fail(err, "out of memory");
  struct dem_work *w = s->work;
  if (dem_threads_init(m, s, err)) return -1;
  s->x = malloc(3 * n * sizeof(double));
  s->v = malloc(3 * n * sizeof(double));
  s->omega = malloc(3 * n * sizeof(double));
  s->q = malloc(4 * n * sizeof(double));
  s->force = calloc(3 * n, sizeof(double));
  s->torque = calloc(3 * n, sizeof(double));
  s->radius = malloc(n * sizeof(double));
  s->inv_mass = malloc(n * sizeof(double));
  s->inv_inertia = malloc(n * sizeof(double));
  s->material = malloc(n * sizeof(int32_t));
  s->id = malloc(n * sizeof(int32_t));
  s->fix_rotation = malloc(n);
  s->wall_force = calloc(3 * (size_t)(m->n_walls + 1), sizeof(double));
  size_t np = (size_t)m->n_planes * n * 3 + 3;
  w->wall_shear = calloc(np, sizeof(double));
  w->mass = malloc(n * sizeof(double));
  w->inertia = malloc(n * sizeof(double));
  w->chunk = calloc(n / DEM_CHUNK + 1, sizeof(dem_chunk_sum));
  w->wall_part = calloc(3 * (size_t)(m->n_planes + 1) * (n / DEM_CHUNK + 1), sizeof(double));
  if (!s->x || !s->v || !s->omega || !s->q || !s->force || !s->torque || !s->radius ||
      !s->inv_mass || !s->inv_inertia || !s->material || !s->id || !s->fix_rotation ||
      !s->wall_force || !w->wall_shear || !w->wall_part || !w->chunk || !w->mass || !w->inertia)
    return proto_fail(err, "out of memory for %d grains", m->n_grains);
  return 0;
}

/* Overlap of slots i, j as a fraction of the smaller radius; of slot i and
 * plane p (distance of the centre below r) as a fraction of r. */
static double pair_overlap(const dem_state *s, int i, int j) {
  const double d[3] = {s->x[3 * i] - s->x[3 * j], s->x[3 * i + 1] - s->x[3 * j + 1], s->x[3 * i + 2] - s->x[3 * j + 2]};
  const double rmin = s->radius[i] < s->radius[j] ? s->radius[i] : s->radius[j];
  return (s->radius[i] + s->radius[j] - sqrt(dem_dot(d, d))) / rmin;
}

static double plane_distance(const dem_plane *pl, const double *x) {
  const double d[3] = {x[0] - pl->point[0], x[1] - pl->point[1], x[2] - pl->point[2]};
  return dem_dot(d, pl->normal);
}

double dem_worst_overlap(const dem_model *m, const dem_state *s) {
  const struct dem_work *w = s->work;
  double worst = 0;
  for (int i = 0; i < s->n; i++) {
    for (int k = w->nl_start[i]; k < w->nl_start[i + 1]; k++) worst = fmax(worst, pair_overlap(s, i, w->nl_j[k]));
    for (int p = 0; p < m->n_planes; p++)
      worst = fmax(worst, (s->radius[i] - plane_distance(&m->planes[p], &s->x[3 * i])) / s->radius[i]);
  }
  return worst;
}

/* Overlaps beyond the tolerance (overlap_tolerance, or what a bed file saved
 * from a run recorded: a settled bed has its own), grains behind a wall. */
static int check_initial(const dem_model *m, const dem_state *s, proto_err *err) {
  const struct dem_work *w = s->work;
  const double tol = fmax(m->overlap_tolerance, m->bed_max_overlap);
  char why[200];
  snprintf(why, sizeof why, "overlap_tolerance %.3g%s", m->overlap_tolerance,
           m->bed_max_overlap <= 0       ? ""
           : m->cfg.substrate_steps > 0 ? "; the substrate settled alone has a largest overlap of "
                                        : "; the bed file records a largest overlap of ");
  if (m->bed_max_overlap > 0) snprintf(why + strlen(why), sizeof why - strlen(why), "%.6g", m->bed_max_overlap);
  for (int i = 0; i < s->n; i++) {
    for (int k = w->nl_start[i]; k < w->nl_start[i + 1]; k++) {
      const int j = w->nl_j[k];
      const double ratio = pair_overlap(s, i, j);
      if (ratio > tol) {
        int a = s->id[i] < s->id[j] ? s->id[i] : s->id[j], b = s->id[i] ^ s->id[j] ^ a;
        const double rmin = s->radius[i] < s->radius[j] ? s->radius[i] : s->radius[j];
        return proto_fail(err, "%s.particles: grains %d and %d overlap by %.3g m = %.3g of the smaller "
                          "radius (%s)", m->key_path, a, b, ratio * rmin, ratio, why);
      }
    }
    for (int p = 0; p < m->n_planes; p++) {
      const dem_plane *pl = &m->planes[p];
      const double *x = &s->x[3 * i], dist = plane_distance(pl, x), r = s->radius[i];
      if (dist < 0)
        return proto_fail(err, "%s.particles: grain %d at (%g, %g, %g) is outside the domain (behind "
                          "walls[%d])", m->key_path, (int)s->id[i], x[0], x[1], x[2], pl->wall);
      if ((r - dist) / r > tol)
        return proto_fail(err, "%s.particles: grain %d overlaps walls[%d] by %.3g of its radius (%s)",
                          m->key_path, (int)s->id[i], pl->wall, (r - dist) / r, why);
    }
  }
  return 0;
}

void dem_grain_constants(const dem_model *m, dem_state *s, int i, int g) {
  const dem_material *mt = &m->mat[m->material[g]];
  const double r = m->radius[g];
  const double mass = mt->density * (4.0 / 3.0) * M_PI * r * r * r;
  s->radius[i] = r;
  s->inv_mass[i] = 1.0 / mass;
  s->inv_inertia[i] = m->fix_rotation[g] ? 0.0 : 1.0 / (0.4 * mass * r * r); /* solid sphere */
  s->work->mass[i] = mass;
  s->work->inertia[i] = m->fix_rotation[g] ? 0.0 : 0.4 * mass * r * r;
  s->material[i] = m->material[g];
  s->id[i] = g;
  s->fix_rotation[i] = m->fix_rotation[g];
}

int dem_state_set_dt(const dem_model *m, dem_state *s, double coupling_dt, proto_err *err) {
  double dt;
  if (dem_model_dt(m, coupling_dt, &dt, err)) return -1;
  if (!(dt > 0)) /* a model built by hand without its Rayleigh time */
    return proto_fail(err, "%s: time step not set (dt %g s, Rayleigh time %g s)", m->key_path, dt,
                      m->rayleigh_time);
  s->dt = dt;
  return 0;
}

int dem_state_init(const dem_model *m, dem_state *s, double coupling_dt, proto_err *err) {
  memset(s, 0, sizeof *s);
  if (dem_state_set_dt(m, s, coupling_dt, err)) return -1;
  if (alloc_state(m, s, err)) goto fail;
  for (int i = 0; i < s->n; i++) {
    memcpy(&s->x[3 * i], &m->x0[3 * i], 3 * sizeof(double));
    memcpy(&s->v[3 * i], &m->v0[3 * i], 3 * sizeof(double));
    memcpy(&s->omega[3 * i], &m->omega0[3 * i], 3 * sizeof(double));
    s->q[4 * i] = 1; s->q[4 * i + 1] = s->q[4 * i + 2] = s->q[4 * i + 3] = 0;
    dem_grain_constants(m, s, i, i);
    if (m->fix_rotation[i]) memset(&s->omega[3 * i], 0, 3 * sizeof(double));
  }
  /* the model's grains keep their materials (a state import checks the
   * model's fingerprint): one for all, or −1 */
  s->work->grain_law = s->n > 0 ? m->material[0] : -1;
  for (int i = 1; i < s->n && s->work->grain_law >= 0; i++)
    if (m->material[i] != s->work->grain_law) s->work->grain_law = -1;
  if (dem_neigh_alloc(m, s, err) || dem_mesh_alloc(m, s, err) || dem_sleep_alloc(m, s, err) || dem_push_alloc(m, s, err) ||
      dem_neigh_rebuild(m, s, err) ||
      check_initial(m, s, err))
    goto fail;
  dem_compute_forces(m, s, 0);
  for (int i = 0; i < s->n; i++) {
    const double *v = &s->v[3 * i], *o = &s->omega[3 * i];
    double mass = 1.0 / s->inv_mass[i], I = s->inv_inertia[i] > 0 ? 1.0 / s->inv_inertia[i] : 0;
    s->kinetic_energy += 0.5 * mass * dem_dot(v, v) + 0.5 * I * dem_dot(o, o);
  }
  return 0;
fail:
  dem_state_free(s);
  return -1;
}

void dem_state_free(dem_state *s) {
  if (s->work) {
    struct dem_work *w = s->work;
    dem_neigh_free(w);
    dem_mesh_free(NULL, s);
    dem_sleep_free(w);
    dem_push_free(w);
    free(w->wall_shear); free(w->wall_part); free(w->chunk); free(w->mass); free(w->inertia);
    free(w->io_mesh);
    free(w);
  }
  free(s->x); free(s->v); free(s->omega); free(s->q); free(s->force); free(s->torque);
  free(s->radius); free(s->inv_mass); free(s->inv_inertia); free(s->material); free(s->id);
  free(s->fix_rotation); free(s->wall_force);
  memset(s, 0, sizeof *s);
}

/* Where a run went wrong: NaN, grains jumping more than their radius per
 * step, or overlaps beyond max_overlap_ratio (time step too large / too soft). */
static int check_health(const dem_model *m, const dem_state *s, double max_jump, proto_err *err) {
  const struct dem_work *w = s->work;
  if (isfinite(s->kinetic_energy) && max_jump <= 1.0 && s->max_overlap_ratio <= m->max_overlap_ratio)
    return 0;
  for (int i = 0; i < s->n; i++) {
    const double *x = &s->x[3 * i], *v = &s->v[3 * i];
    if (!isfinite(x[0] + x[1] + x[2] + v[0] + v[1] + v[2]))
      return proto_fail(err, "step %lld (t = %.6g s): grain %d has a non-finite position or velocity",
                        (long long)s->step, s->t, (int)s->id[i]);
    if (sqrt(dem_dot(v, v)) * s->dt > s->radius[i])
      return proto_fail(err, "step %lld (t = %.6g s): grain %d at (%g, %g, %g) moves %.3g m per step, "
                        "more than its radius: unstable (dt = %.3g s = %.3g Rayleigh times)",
                        (long long)s->step, s->t, (int)s->id[i], x[0], x[1], x[2],
                        sqrt(dem_dot(v, v)) * s->dt, s->dt, s->dt / m->rayleigh_time);
    if (w->ratio[i] > m->max_overlap_ratio)
      return proto_fail(err, "step %lld (t = %.6g s): grain %d at (%g, %g, %g) overlaps by %.3g of its "
                        "radius (max_overlap_ratio %.3g): unstable or too soft (dt = %.3g s = %.3g "
                        "Rayleigh times)", (long long)s->step, s->t, (int)s->id[i], x[0], x[1], x[2],
                        w->ratio[i], m->max_overlap_ratio, s->dt, s->dt / m->rayleigh_time);
  }
  return proto_fail(err, "step %lld (t = %.6g s): non-finite kinetic energy", (long long)s->step, s->t);
}

/* Velocity Verlet in two fused sweeps over the grains:
 *   1. v += dt/2 (F/m + g), ω += dt/2 T/I, x += dt v, with the checks that
 *      need no extra pass (jump per step, skin);
 *   2. (new forces) q ← rotation by ω^{n+1/2} dt, v += dt/2 (F/m + g),
 *      ω += dt/2 T/I and the kinetic energy, done by dem_compute_forces()
 *      per chunk of grains right after their forces (dem_force.c kick_chunk),
 *      summed per fixed chunk so the total does not depend on the number of
 *      threads. */
int dem_step(const dem_model *m, dem_state *s, proto_err *err) {
  struct dem_work *w = s->work;
  const double dt = s->dt, half = 0.5 * dt, lim2 = 0.25 * m->skin * m->skin;
  const double *g = m->gravity;
  int rebuild = 0, jumped = 0;
  dem_threads_begin(s);
  const int n = w->n_active; /* the awake grains (all unless "sleep": dem_sleep.c) */
  const int nchunk = (n + DEM_CHUNK - 1) / DEM_CHUNK;
  /* the moved grains' sphere box, for the sparse exchange (dem_nodeset.c): min
   * and max are exact in any order, so it does not depend on the threads */
  double blo[3] = {INFINITY, INFINITY, INFINITY}, bhi[3] = {-INFINITY, -INFINITY, -INFINITY};
  double clo[3] = {INFINITY, INFINITY, INFINITY}, chi[3] = {-INFINITY, -INFINITY, -INFINITY}; /* centres: dem_sleep.c */
#pragma omp parallel for schedule(dynamic, 1) reduction(| : rebuild, jumped) reduction(min : blo[:3], clo[:3]) \
    reduction(max : bhi[:3], chi[:3]) num_threads(w->nthreads)
  for (int c = 0; c < nchunk; c++) {
    const int hi = (c + 1) * DEM_CHUNK < n ? (c + 1) * DEM_CHUNK : n;
    for (int i = c * DEM_CHUNK; i < hi; i++) {
      double *x = &s->x[3 * i], *v = &s->v[3 * i], *o = &s->omega[3 * i];
      const double *f = &s->force[3 * i], *t = &s->torque[3 * i], *xr = &w->x_ref[3 * i];
      const double im = s->inv_mass[i], ii = s->inv_inertia[i], r = s->radius[i];
      double d2 = 0;
      for (int a = 0; a < 3; a++) {
        v[a] += half * (f[a] * im + g[a]);
        o[a] += half * t[a] * ii;
        x[a] += dt * v[a];
        d2 += (x[a] - xr[a]) * (x[a] - xr[a]);
        blo[a] = x[a] - r < blo[a] ? x[a] - r : blo[a]; /* as dem_nodeset.c sphere_boxes */
        bhi[a] = x[a] + r > bhi[a] ? x[a] + r : bhi[a];
        clo[a] = x[a] < clo[a] ? x[a] : clo[a];
        chi[a] = x[a] > chi[a] ? x[a] : chi[a];
      }
      rebuild |= d2 > lim2;
      jumped |= !(dem_dot(v, v) * dt * dt <= r * r); /* moved more than its radius, or NaN */
    }
  }
  dem_mesh_move(m, s, dt);
  s->t += dt;
  s->step++;
  memcpy(w->step_box, blo, sizeof blo);
  memcpy(w->step_box + 3, bhi, sizeof bhi);
  memcpy(w->step_cbox, clo, sizeof clo);
  memcpy(w->step_cbox + 3, chi, sizeof chi);
  w->box_all = 1; /* the awake block's box: every grain's without sleep (dem_sleep.c clears it at a wake or sleep) */
  if (jumped) {
    s->kinetic_energy = NAN;
    return check_health(m, s, 2.0, err);
  }
  /* the force rule's book before the list (and pair_ft's index) changes; here,
   * not in dem_neigh_rebuild, which calls nothing of the sleep files (no cycle) */
  if (rebuild) dem_push_fresh(m, s);
  if (rebuild ? dem_neigh_rebuild(m, s, err) : (m->n_meshes > 0 && dem_mesh_lists_check(m, s, err))) return -1;
  if (w->asleep && dem_sleep_guard(m, s, err)) return -1; /* a mesh beyond the region's margin */
  dem_compute_forces(m, s, 1); /* and the second half kick */
  w->sweep_step = s->step;     /* step_box and kick_v2 are this step's */
  dem_threads_end(s);
  if (check_health(m, s, 0.0, err)) return -1;
  return dem_sleep_update(m, s, err); /* wake, region, fall asleep: the awake grains first again */
}

int dem_advance(const dem_model *m, dem_state *s, double duration, proto_err *err) {
  long long n = llround(duration / s->dt);
  for (long long k = 0; k < n; k++)
    if (dem_step(m, s, err)) return -1;
  return 0;
}

void dem_mesh_set_nodes(const dem_model *m, dem_state *s, int mesh, const double *x,
                        const double *v) {
  const dem_mesh *me = &m->meshes[mesh];
  dem_sleep_mesh_jump(m, s, mesh, me->n_nodes, NULL, x, v, NULL); /* the active region's guard */
  memcpy(s->mesh_x[mesh], x, sizeof(double) * 3 * (size_t)me->n_nodes);
  memcpy(s->mesh_v[mesh], v, sizeof(double) * 3 * (size_t)me->n_nodes);
  s->work->mesh_set[mesh] = 1; /* lists: checked at the next step */
  dem_mesh_velocities_changed(m, s, mesh);
  dem_mesh_nodes_set(m, s, mesh);
}

void dem_gather(const dem_state *s, const double *slot_data, int cols, double *out) {
  for (int i = 0; i < s->n; i++)
    for (int k = 0; k < cols; k++) out[(size_t)s->id[i] * cols + k] = slot_data[(size_t)i * cols + k];
}

const char *const DEM_SERIES[DEM_N_SERIES] = {
    [DEM_SERIES_T] = "t",
    [DEM_SERIES_KINETIC] = "kinetic_energy",
    [DEM_SERIES_CONTACTS] = "contacts",
    [DEM_SERIES_MAX_OVERLAP] = "max_overlap_ratio",
    [DEM_SERIES_ELASTIC] = "elastic_energy",
    [DEM_SERIES_COORDINATION] = "coordination"};
const char *const DEM_SNAP[DEM_N_SNAP] = {"x", "v", "omega", "r"};

int dem_ready_declare(const dem_model *m, proto_msg *ready, proto_err *err) {
  if (proto_ready_series(ready, PROTO_A_SERIES, DEM_N_SERIES, DEM_SERIES) < 0 ||
      proto_ready_snapshot(ready, "points", DEM_SNAP[DEM_SNAP_X], NULL, 3, DEM_SNAP + DEM_SNAP_V) < 0)
    return proto_fail(err, "out of memory");
  cJSON *series = cJSON_GetObjectItemCaseSensitive(proto_msg_header(ready), PROTO_H_SERIES);
  cJSON *wf = cJSON_AddArrayToObject(series, DEM_WALL_FORCES);
  if (!wf) return proto_fail(err, "out of memory");
  cJSON_AddItemToArray(wf, cJSON_CreateString("t"));
  for (int w = 0; w < m->n_walls; w++)
    for (int k = 0; k < 3; k++) {
      char name[32];
      snprintf(name, sizeof name, "wall%d_F%c", w, "xyz"[k]);
      cJSON_AddItemToArray(wf, cJSON_CreateString(name));
    }
  return 0;
}

double dem_coordination(const dem_model *m, const dem_state *s) {
  (void)m;
  return s->n ? 2.0 * (double)s->work->pair_contacts / s->n : 0;
}

#define SETTLE_REPORT_EVERY 50 /* steps between progress reports */

int dem_settle(const dem_model *m, dem_state *s, double ke_per_grain, int64_t max_steps,
               dem_progress_fn progress, void *ctx, proto_err *err) {
  for (int64_t k = 0; k < max_steps; k++) {
    if (dem_step(m, s, err)) return proto_wrap(err, "settling the bed");
    if (progress && k % SETTLE_REPORT_EVERY == 0)
      progress(ctx, (double)k / (double)max_steps, "settling the bed");
    if (k > 100 && s->kinetic_energy < ke_per_grain * s->n) break;
  }
  if (progress) progress(ctx, 1.0, "settling the bed");
  return 0;
}
