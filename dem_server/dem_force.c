/* dem_force.c — contact forces: grain–grain pairs over the half list (each
 * pair written once, into its own slot), then a per-grain gather in fixed
 * order so results are bitwise identical for any number of threads; plane
 * walls and meshes are added in the same per-grain sweep (gravity enters
 * the kick as an acceleration). */
#include "dem_server/dem_internal.h"

#include <string.h>

static void pair_forces(const dem_model *m, dem_state *s) {
  struct dem_work *w = s->work;
  const double dt = m->dt;
#pragma omp parallel for schedule(dynamic, 256) num_threads(w->nthreads)
  for (int i = 0; i < s->n; i++) {
    const double *xi = &s->x[3 * i], *vi = &s->v[3 * i], *oi = &s->omega[3 * i];
    const double ri = s->radius[i];
    double u = 0, ratio = 0;
    double fi[3] = {0, 0, 0}, ti[3] = {0, 0, 0}; /* grain i's own pairs, in list order */
    int cnt = 0;
    for (int k = w->nl_start[i]; k < w->nl_start[i + 1]; k++) {
      const int j = w->nl_j[k];
      double *F = &w->pair_f[3 * k], *c = &w->pair_c[4 * k], *shear = &w->nl_shear[3 * k];
      double d[3] = {xi[0] - s->x[3 * j], xi[1] - s->x[3 * j + 1], xi[2] - s->x[3 * j + 2]};
      const double rj = s->radius[j], rsum = ri + rj, dist2 = dem_dot(d, d);
      if (m->has_rolling) memset(&w->pair_roll[3 * k], 0, 3 * sizeof(double));
      if (dist2 >= rsum * rsum) { /* contact open: history deleted (notes §1.1) */
        memset(F, 0, 3 * sizeof(double)); memset(c, 0, 4 * sizeof(double));
        if (shear[0] != 0 || shear[1] != 0 || shear[2] != 0) memset(shear, 0, 3 * sizeof(double));
        continue;
      }
      const double dist = sqrt(dist2);
      double n[3] = {0, 0, 1}; /* eq. 10: from j to i */
      if (dist > 0) {
        const double rinv = 1.0 / dist;
        for (int a = 0; a < 3; a++) n[a] = d[a] * rinv;
      }
      const double delta = rsum - dist;                                /* eq. 18 */
      /* eq. 16–17 with one division: R* = r_i r_j / (r_i + r_j), m* = 1/(1/m_i + 1/m_j) */
      const double isum = s->inv_mass[i] + s->inv_mass[j], inv_den = 1.0 / (rsum * isum);
      const double rstar = ri * rj * isum * inv_den, mstar = rsum * inv_den;
      /* eq. 11–12: relative velocity of the contact points, which LIGGGHTS puts
       * in the middle of the overlap: i at −(r_i − δ/2) n, j at +(r_j − δ/2) n */
      const double cri = ri - 0.5 * delta, crj = rj - 0.5 * delta;
      double wsum[3], nxw[3], vc[3];
      for (int a = 0; a < 3; a++) wsum[a] = cri * oi[a] + crj * s->omega[3 * j + a];
      dem_cross(n, wsum, nxw);
      for (int a = 0; a < 3; a++) vc[a] = vi[a] - s->v[3 * j + a] + nxw[a];
      const dem_pair_law *l = &m->law[s->material[i]][s->material[j]];
      double up;
      const double Fn = dem_hertz(l, delta, rstar, mstar, n, vc, dt, shear, F, c, &up);
      c[3] = 0.5 * delta;
      /* torque on i: −(r_i − δ/2) n × F_t; j's share is summed in gather() */
      for (int a = 0; a < 3; a++) { fi[a] += F[a]; ti[a] -= cri * c[a]; }
      if (m->has_rolling && l->mu_roll > 0) {
        double wrel[3] = {oi[0] - s->omega[3 * j], oi[1] - s->omega[3 * j + 1], oi[2] - s->omega[3 * j + 2]};
        dem_rolling(l, Fn, rstar, wrel, &w->pair_roll[3 * k]);
        for (int a = 0; a < 3; a++) ti[a] += w->pair_roll[3 * k + a];
      }
      u += up;
      cnt++;
      const double rr = delta / (ri < rj ? ri : rj);
      if (rr > ratio) ratio = rr;
    }
    memcpy(&s->force[3 * i], fi, sizeof fi);
    memcpy(&s->torque[3 * i], ti, sizeof ti);
    w->pair_u[i] = u;
    w->pair_contacts[i] = cnt;
    w->ratio[i] = ratio;
  }
}

/* Plane contacts of grain i (wall: R* = r_i, m* = m_i, no wall motion). */
static void plane_forces(const dem_model *m, dem_state *s, int i, double *f, double *t,
                         double *part) {
  struct dem_work *w = s->work;
  const double r = s->radius[i], mass = w->mass[i];
  /* only planes within reach at the last rebuild (dem_neigh.c plane mask) */
  for (uint64_t bits = w->plane_mask[i]; bits; bits &= bits - 1) {
    const int p = __builtin_ctzll(bits);
    const dem_plane *pl = &m->planes[p];
    const size_t idx = ((size_t)i * m->n_planes + p) * 3;
    double *shear = &w->wall_shear[idx];
    double d[3] = {s->x[3 * i] - pl->point[0], s->x[3 * i + 1] - pl->point[1], s->x[3 * i + 2] - pl->point[2]};
    const double delta = r - dem_dot(d, pl->normal);
    if (delta <= 0) { /* contact open: history deleted */
      if (shear[0] != 0 || shear[1] != 0 || shear[2] != 0) memset(shear, 0, 3 * sizeof(double));
      continue;
    }
    double wxn[3], vc[3], c[3], F[3];
    const double cr = r - 0.5 * delta; /* contact point in the middle of the overlap */
    dem_cross(&s->omega[3 * i], pl->normal, wxn);
    for (int a = 0; a < 3; a++) vc[a] = s->v[3 * i + a] - cr * wxn[a];
    const dem_pair_law *l = &m->law[s->material[i]][pl->material];
    double up;
    const double Fn = dem_hertz(l, delta, r, mass, pl->normal, vc, m->dt, shear, F, c, &up);
    for (int a = 0; a < 3; a++) { f[a] += F[a]; t[a] -= cr * c[a]; part[3 * p + a] += F[a]; }
    if (m->has_rolling && l->mu_roll > 0) {
      double tr[3];
      dem_rolling(l, Fn, r, &s->omega[3 * i], tr);
      for (int a = 0; a < 3; a++) t[a] += tr[a];
    }
    w->wall_u[i] += up;
    w->wall_contacts[i]++;
    if (delta / r > w->ratio[i]) w->ratio[i] = delta / r;
  }
}

/* Per-grain sum in fixed order; plane-wall totals per chunk of grains (a
 * fixed partition, so the sums do not depend on the number of threads). */
static void gather_grain(const dem_model *m, dem_state *s, int i, double *part) {
  struct dem_work *w = s->work;
  const double *pf = w->pair_f, *pc = w->pair_c;
  /* torque −(r − δ/2) (n × F_t) with this grain's own radius for both kinds
   * of pairs: the force on j is −F_t at lever +(r_j − δ/2) n */
  const double ri = s->radius[i];
  /* own pairs were summed by pair_forces() into force/torque */
  double fx = s->force[3 * i], fy = s->force[3 * i + 1], fz = s->force[3 * i + 2];
  double tx = s->torque[3 * i], ty = s->torque[3 * i + 1], tz = s->torque[3 * i + 2];
  const int q0 = w->rev_start[i], q1 = w->rev_start[i + 1];
  for (int q = q0; q < q1; q++) {
    const int k = w->rev_k[q];
    const double cr = ri - pc[4 * k + 3];
    fx -= pf[3 * k]; fy -= pf[3 * k + 1]; fz -= pf[3 * k + 2]; /* Newton's third law */
    tx -= cr * pc[4 * k]; ty -= cr * pc[4 * k + 1]; tz -= cr * pc[4 * k + 2];
  }
  double f[3] = {fx, fy, fz}, t[3] = {tx, ty, tz};
  if (m->has_rolling)
    for (int q = q0; q < q1; q++)
      for (int a = 0; a < 3; a++) t[a] -= w->pair_roll[3 * w->rev_k[q] + a];
  plane_forces(m, s, i, f, t, part);
  if (m->n_meshes > 0)
    for (int a = 0; a < 3; a++) { f[a] += w->mesh_f[3 * i + a]; t[a] += w->mesh_t[3 * i + a]; }
  for (int a = 0; a < 3; a++) { /* gravity is added as an acceleration in the kick */
    s->force[3 * i + a] = f[a];
    s->torque[3 * i + a] = t[a];
  }
}

static void gather(const dem_model *m, dem_state *s) {
  struct dem_work *w = s->work;
  const int np3 = 3 * m->n_planes, nchunk = (s->n + DEM_CHUNK - 1) / DEM_CHUNK;
#pragma omp parallel for schedule(dynamic, 1) num_threads(w->nthreads)
  for (int c = 0; c < nchunk; c++) {
    double *part = &w->wall_part[(size_t)c * np3];
    memset(part, 0, sizeof(double) * (size_t)np3);
    const int end = (c + 1) * DEM_CHUNK < s->n ? (c + 1) * DEM_CHUNK : s->n;
    for (int i = c * DEM_CHUNK; i < end; i++) gather_grain(m, s, i, part);
  }
  for (int c = 0; c < nchunk; c++)
    for (int p = 0; p < m->n_planes; p++)
      for (int a = 0; a < 3; a++)
        s->wall_force[3 * m->planes[p].wall + a] -= w->wall_part[(size_t)c * np3 + 3 * p + a];
}

void dem_compute_forces(const dem_model *m, dem_state *s) {
  struct dem_work *w = s->work;
  memset(w->wall_u, 0, sizeof(double) * (size_t)s->n);
  memset(w->wall_contacts, 0, (size_t)s->n);
  memset(s->wall_force, 0, sizeof(double) * 3 * (size_t)(m->n_walls ? m->n_walls : 1));
  pair_forces(m, s);
  dem_mesh_forces(m, s);
  gather(m, s);
  int64_t contacts = 0;
  double ratio = 0, u = 0;
  for (int i = 0; i < s->n; i++) {
    contacts += w->pair_contacts[i] + w->wall_contacts[i];
    if (w->ratio[i] > ratio) ratio = w->ratio[i];
    u += w->pair_u[i] + w->wall_u[i];
  }
  s->contacts = contacts;
  s->max_overlap_ratio = ratio;
  s->elastic_energy = u;
}
