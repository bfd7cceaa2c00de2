/* dem_model.c — the DEM scene's physics that the config reader (dem_config.c),
 * the bed builder (dem_bed.c) and the state (dem_state.c) call down to: grain
 * arrays, pair laws and the preparation's override of their friction
 * (dem_prep_laws: dem_bed.c's settling, terra's tests), the Rayleigh time and
 * the step. Calls nothing above it. */
#include "dem_server/dem_internal.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Rayleigh time T_R = pi r sqrt(rho/G) / (0.1631 nu + 0.8766): the fit of the
 * Rayleigh-wave speed c_R/c_S over Poisson's ratio (Y. Li, Y. Xu, C. Thornton
 * 2005; the form LIGGGHTS' `fix check/timestep/gran` reports, docs/dem-bench.md §2). */
#define DEM_RAYLEIGH_FIT_SLOPE 0.1631  /* per unit nu (dimensionless) */
#define DEM_RAYLEIGH_FIT_OFFSET 0.8766 /* the fit's c_R/c_S at nu = 0 (dimensionless) */

/* Relative slack when counting sub-steps: a coupling step that is n DEM steps
 * up to round-off gives n, not n + 1. */
#define DEM_SUBSTEP_ROUNDOFF 1e-12

double dem_rayleigh_time(double r, double density, double E, double nu) {
  double G = E / (2.0 * (1.0 + nu));
  return M_PI * r * sqrt(density / G) / (DEM_RAYLEIGH_FIT_SLOPE * nu + DEM_RAYLEIGH_FIT_OFFSET);
}

/* LIGGGHTS' effective pair values (seed 000 eq. 21, 26; the LIGGGHTS 3.8 source,
 * `src/normal_model_hertz.h`, `src/tangential_model_history.h`) from the
 * two materials and the pair's restitution e, friction μ, rolling friction
 * μ_r. G is taken from each material so a given G overrides E/(2(1+ν)). */
void dem_pair_law_set(const dem_material *a, const dem_material *b, double e, double mu, double mu_roll,
                      int clamp, dem_pair_law *l) {
  l->Estar = 1.0 / ((1 - a->nu * a->nu) / a->E + (1 - b->nu * b->nu) / b->E);
  l->Gstar = 1.0 / ((2 - a->nu) / a->G + (2 - b->nu) / b->G);
  const double le = log(e);
  l->beta = le / sqrt(le * le + M_PI * M_PI);
  l->mu = mu;
  l->damp_n = -2.0 * sqrt(5.0 / 6.0) * l->beta * sqrt(2.0 * l->Estar);
  l->damp_t = -2.0 * sqrt(5.0 / 6.0) * l->beta * sqrt(8.0 * l->Gstar);
  l->mu_roll = mu_roll;
  l->clamp = clamp;
}

int dem_prep_check(const dem_model *m, const dem_prep *p, const char *key, proto_err *err) {
  if (!p->on) return 0;
  if (!(p->friction >= 0 && p->friction <= DEM_PREP_FRICTION_MAX))
    return proto_fail(err, "%s.friction: %g must lie in [0, %g]", key, p->friction, DEM_PREP_FRICTION_MAX);
  if (!(p->rolling >= 0 && p->rolling <= DEM_PREP_FRICTION_MAX))
    return proto_fail(err, "%s.rolling_friction: %g must lie in [0, %g]", key, p->rolling, DEM_PREP_FRICTION_MAX);
  if (p->rolling > 0 && !m->has_rolling)
    return proto_fail(err, "%s.rolling_friction: %g needs a scene with rolling_friction > 0 on some material "
                      "or pair (the DEM keeps rolling state only then)", key, p->rolling);
  return 0;
}

/* Every entry, also those of materials the model does not have: no law a
 * contact can reach keeps the scene's friction. */
void dem_prep_laws(dem_model *m, const dem_prep *p) {
  if (!p->on) return;
  for (int a = 0; a < DEM_MAX_MATERIALS; a++)
    for (int b = 0; b < DEM_MAX_MATERIALS; b++) {
      m->law[a][b].mu = p->friction;
      m->law[a][b].mu_roll = p->rolling;
    }
}

int dem_model_alloc_grains(dem_model *m, int n, proto_err *err) {
  free(m->x0); free(m->v0); free(m->omega0); free(m->radius);
  free(m->material); free(m->fix_rotation);
  m->n_grains = n;
  m->bed_max_overlap = 0; /* new grains: nothing recorded */
  size_t k = n > 0 ? (size_t)n : 1;
  m->x0 = calloc(k * 3, sizeof(double));
  m->v0 = calloc(k * 3, sizeof(double));
  m->omega0 = calloc(k * 3, sizeof(double));
  m->radius = calloc(k, sizeof(double));
  m->material = calloc(k, sizeof(int32_t));
  m->fix_rotation = calloc(k, 1);
  if (!m->x0 || !m->v0 || !m->omega0 || !m->radius || !m->material || !m->fix_rotation)
    return proto_fail(err, "out of memory for %d grains", n);
  return 0;
}

double dem_model_rayleigh(const dem_model *m) {
  double tr = DBL_MAX;
  for (int i = 0; i < m->n_grains; i++) {
    const dem_material *mt = &m->mat[m->material[i]];
    double t = dem_rayleigh_time(m->radius[i], mt->density, mt->E, mt->nu);
    if (t < tr) tr = t;
  }
  return tr;
}

int dem_model_dt(const dem_model *m, double coupling_dt, double *out, proto_err *err) {
  const dem_model_config *ex = &m->cfg;
  double dt = ex->dt_given > 0 ? ex->dt_given : ex->dt_fraction * m->rayleigh_time;
  if (coupling_dt > 0) {
    double nsub = ceil(coupling_dt / dt * (1 - DEM_SUBSTEP_ROUNDOFF));
    dt = coupling_dt / (nsub < 1 ? 1 : nsub);
  }
  double limit = DEM_DT_LIMIT_FRACTION * m->rayleigh_time;
  if (dt > limit && !m->unsafe_dt)
    return proto_fail(err, "%s.%s: dt = %.4g s is above the stability limit %.4g s (%.2f x Rayleigh time "
                      "%.4g s of the smallest grain); lower dt or dt_fraction",
                      m->key_path, ex->dt_given > 0 ? "dt" : "dt_fraction", dt, limit, DEM_DT_LIMIT_FRACTION, m->rayleigh_time);
  *out = dt;
  return 0;
}

int dem_model_set_surface(dem_model *m, int n_nodes, const double *x0, int n_tri,
                          const int32_t *tri, proto_err *err) {
  if (m->n_meshes >= DEM_MAX_MESHES || m->n_walls >= DEM_MAX_WALLS)
    return proto_fail(err, "surface: too many meshes/walls");
  for (int i = 0; i < 3 * n_tri; i++)
    if (tri[i] < 0 || tri[i] >= n_nodes)
      return proto_fail(err, "surface_tri[%d]: node index %d outside [0, %d)", i / 3, (int)tri[i], n_nodes);
  dem_mesh *me = &m->meshes[m->n_meshes];
  memset(me, 0, sizeof *me);
  me->x0 = malloc(sizeof(double) * 3 * (size_t)(n_nodes ? n_nodes : 1));
  me->tri = malloc(sizeof(int32_t) * 3 * (size_t)(n_tri ? n_tri : 1));
  if (!me->x0 || !me->tri) return proto_fail(err, "surface: out of memory");
  memcpy(me->x0, x0, sizeof(double) * 3 * (size_t)n_nodes);
  memcpy(me->tri, tri, sizeof(int32_t) * 3 * (size_t)n_tri);
  me->n_nodes = n_nodes;
  me->n_tri = n_tri;
  me->material = m->surface_material;
  me->coupled = 1;
  me->wall = m->n_walls;
  dem_wall *w = &m->walls[m->n_walls++];
  memset(w, 0, sizeof *w);
  w->kind = DEM_WALL_MESH;
  w->material = me->material;
  w->plane0 = m->n_planes;
  w->mesh = m->n_meshes++;
  return 0;
}

void dem_model_free(dem_model *m) {
  free(m->x0); free(m->v0); free(m->omega0); free(m->radius);
  free(m->material); free(m->fix_rotation);
  for (int i = 0; i < m->n_meshes; i++) { free(m->meshes[i].x0); free(m->meshes[i].tri); }
  memset(m, 0, sizeof *m);
}
