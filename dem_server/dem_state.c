/* dem_state.c — the state of a run: allocation, initial checks, and the time
 * step (velocity Verlet, seed 000 eq. 4–5; orientation by quaternion instead
 * of eq. 9's Euler angles, which are singular at sin φ2 = 0). */
#include "dem_server/dem_internal.h"

#include <omp.h>
#include <stdlib.h>
#include <string.h>

static int alloc_state(const dem_model *m, dem_state *s, proto_err *err) {
  const size_t n = (size_t)m->n_grains;
  s->n = m->n_grains;
  s->work = calloc(1, sizeof *s->work);
  if (!s->work) return proto_fail(err, "out of memory");
  struct dem_work *w = s->work;
  /* default: all threads for big scenes; one for small ones, where fork/join
   * costs more than it saves (and a loaded machine makes it far worse) */
  w->nthreads = m->threads > 0 ? m->threads : (m->n_grains >= 4096 ? omp_get_max_threads() : 1);
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
  w->ke_part = calloc(n / DEM_CHUNK + 1, sizeof(double));
  w->wall_part = calloc(3 * (size_t)(m->n_planes + 1) * (n / DEM_CHUNK + 1), sizeof(double));
  w->wall_u = calloc(n, sizeof(double));
  w->wall_contacts = calloc(n, 1);
  size_t cols = 3 * DEM_MESH_SLOTS > 3 * (size_t)m->n_planes ? 3 * DEM_MESH_SLOTS : 3 * (size_t)m->n_planes;
  w->tmp = malloc(cols * n * sizeof(double) + 1); /* widest per-grain record permuted */
  w->itmp = malloc(n * sizeof(int64_t) * DEM_MESH_SLOTS);
  if (!s->x || !s->v || !s->omega || !s->q || !s->force || !s->torque || !s->radius ||
      !s->inv_mass || !s->inv_inertia || !s->material || !s->id || !s->fix_rotation ||
      !s->wall_force || !w->wall_shear || !w->wall_part || !w->ke_part || !w->mass || !w->inertia || !w->wall_u || !w->wall_contacts ||
      !w->tmp || !w->itmp)
    return proto_fail(err, "out of memory for %d grains", m->n_grains);
  return 0;
}

static int check_initial(const dem_model *m, const dem_state *s, proto_err *err) {
  const struct dem_work *w = s->work;
  for (int i = 0; i < s->n; i++) {
    for (int k = w->nl_start[i]; k < w->nl_start[i + 1]; k++) {
      int j = w->nl_j[k];
      double d[3] = {s->x[3 * i] - s->x[3 * j], s->x[3 * i + 1] - s->x[3 * j + 1],
                     s->x[3 * i + 2] - s->x[3 * j + 2]};
      double rmin = s->radius[i] < s->radius[j] ? s->radius[i] : s->radius[j];
      double delta = s->radius[i] + s->radius[j] - sqrt(dem_dot(d, d));
      if (delta > m->overlap_tolerance * rmin) {
        int a = s->id[i] < s->id[j] ? s->id[i] : s->id[j], b = s->id[i] ^ s->id[j] ^ a;
        return proto_fail(err, "%s.particles: grains %d and %d overlap by %.3g m = %.3g of the smaller "
                          "radius (overlap_tolerance %.3g)", m->key_path, a, b, delta, delta / rmin,
                          m->overlap_tolerance);
      }
    }
    for (int p = 0; p < m->n_planes; p++) {
      const dem_plane *pl = &m->planes[p];
      double d[3] = {s->x[3 * i] - pl->point[0], s->x[3 * i + 1] - pl->point[1],
                     s->x[3 * i + 2] - pl->point[2]};
      double dist = dem_dot(d, pl->normal), r = s->radius[i];
      const double *x = &s->x[3 * i];
      if (dist < 0)
        return proto_fail(err, "%s.particles: grain %d at (%g, %g, %g) is outside the domain (behind "
                          "walls[%d])", m->key_path, (int)s->id[i], x[0], x[1], x[2], pl->wall);
      if (r - dist > m->overlap_tolerance * r)
        return proto_fail(err, "%s.particles: grain %d overlaps walls[%d] by %.3g of its radius "
                          "(overlap_tolerance %.3g)", m->key_path, (int)s->id[i], pl->wall, (r - dist) / r,
                          m->overlap_tolerance);
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

int dem_state_init(const dem_model *m, dem_state *s, proto_err *err) {
  memset(s, 0, sizeof *s);
  if (m->dt <= 0) return proto_fail(err, "dem: time step not set");
  if (alloc_state(m, s, err)) goto fail;
  for (int i = 0; i < s->n; i++) {
    memcpy(&s->x[3 * i], &m->x0[3 * i], 3 * sizeof(double));
    memcpy(&s->v[3 * i], &m->v0[3 * i], 3 * sizeof(double));
    memcpy(&s->omega[3 * i], &m->omega0[3 * i], 3 * sizeof(double));
    s->q[4 * i] = 1; s->q[4 * i + 1] = s->q[4 * i + 2] = s->q[4 * i + 3] = 0;
    dem_grain_constants(m, s, i, i);
    if (m->fix_rotation[i]) memset(&s->omega[3 * i], 0, 3 * sizeof(double));
  }
  if (dem_neigh_alloc(m, s, err) || dem_mesh_alloc(m, s, err) || dem_neigh_rebuild(m, s, err) ||
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
    free(w->wall_shear); free(w->wall_part); free(w->ke_part); free(w->mass); free(w->inertia); free(w->wall_u); free(w->wall_contacts);
    free(w->tmp); free(w->itmp); free(w->io_mesh);
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
    if (sqrt(dem_dot(v, v)) * m->dt > s->radius[i])
      return proto_fail(err, "step %lld (t = %.6g s): grain %d at (%g, %g, %g) moves %.3g m per step, "
                        "more than its radius: unstable (dt = %.3g s = %.3g Rayleigh times)",
                        (long long)s->step, s->t, (int)s->id[i], x[0], x[1], x[2],
                        sqrt(dem_dot(v, v)) * m->dt, m->dt, m->dt / m->rayleigh_time);
    if (w->ratio[i] > m->max_overlap_ratio)
      return proto_fail(err, "step %lld (t = %.6g s): grain %d at (%g, %g, %g) overlaps by %.3g of its "
                        "radius (max_overlap_ratio %.3g): unstable or too soft (dt = %.3g s = %.3g "
                        "Rayleigh times)", (long long)s->step, s->t, (int)s->id[i], x[0], x[1], x[2],
                        w->ratio[i], m->max_overlap_ratio, m->dt, m->dt / m->rayleigh_time);
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
  const double dt = m->dt, half = 0.5 * dt, lim2 = 0.25 * m->skin * m->skin;
  const double *g = m->gravity;
  int rebuild = 0, jumped = 0;
#pragma omp parallel for schedule(dynamic, 512) reduction(| : rebuild, jumped) num_threads(w->nthreads)
  for (int i = 0; i < s->n; i++) {
    double *x = &s->x[3 * i], *v = &s->v[3 * i], *o = &s->omega[3 * i];
    const double *f = &s->force[3 * i], *t = &s->torque[3 * i], *xr = &w->x_ref[3 * i];
    const double im = s->inv_mass[i], ii = s->inv_inertia[i], r = s->radius[i];
    double d2 = 0;
    for (int a = 0; a < 3; a++) {
      v[a] += half * (f[a] * im + g[a]);
      o[a] += half * t[a] * ii;
      x[a] += dt * v[a];
      d2 += (x[a] - xr[a]) * (x[a] - xr[a]);
    }
    rebuild |= d2 > lim2;
    jumped |= !(dem_dot(v, v) * dt * dt <= r * r); /* moved more than its radius, or NaN */
  }
  dem_mesh_move(m, s, dt);
  s->t += dt;
  s->step++;
  if (jumped) {
    s->kinetic_energy = NAN;
    return check_health(m, s, 2.0, err);
  }
  if (rebuild && dem_neigh_rebuild(m, s, err)) return -1;
  dem_compute_forces(m, s, 1); /* and the second half kick */
  const int nchunk = (s->n + DEM_CHUNK - 1) / DEM_CHUNK;
  double ke = 0;
  for (int c = 0; c < nchunk; c++) ke += w->ke_part[c];
  s->kinetic_energy = ke;
  return check_health(m, s, 0.0, err);
}

int dem_advance(const dem_model *m, dem_state *s, double duration, proto_err *err) {
  long long n = llround(duration / m->dt);
  for (long long k = 0; k < n; k++)
    if (dem_step(m, s, err)) return -1;
  return 0;
}

void dem_mesh_set_nodes(const dem_model *m, dem_state *s, int mesh, const double *x,
                        const double *v) {
  const dem_mesh *me = &m->meshes[mesh];
  memcpy(s->mesh_x[mesh], x, sizeof(double) * 3 * (size_t)me->n_nodes);
  memcpy(s->mesh_v[mesh], v, sizeof(double) * 3 * (size_t)me->n_nodes);
  dem_bvh_update(&s->work->bvh[mesh], s->mesh_x[mesh], me->tri, me->n_tri);
}

void dem_gather(const dem_state *s, const double *slot_data, int cols, double *out) {
  for (int i = 0; i < s->n; i++)
    for (int k = 0; k < cols; k++) out[(size_t)s->id[i] * cols + k] = slot_data[(size_t)i * cols + k];
}

double dem_coordination(const dem_model *m, const dem_state *s) {
  (void)m;
  int64_t c = 0;
  for (int i = 0; i < s->n; i++) c += s->work->pair_contacts[i];
  return s->n ? 2.0 * (double)c / s->n : 0;
}

int dem_settle(const dem_model *m, dem_state *s, double ke_per_grain, int64_t max_steps,
               proto_err *err) {
  for (int64_t k = 0; k < max_steps; k++) {
    if (dem_step(m, s, err)) return proto_wrap(err, "settling the bed");
    if (k > 100 && s->kinetic_energy < ke_per_grain * s->n) break;
  }
  return 0;
}
