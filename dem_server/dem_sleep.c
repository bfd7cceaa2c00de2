/* dem_sleep.c — grains at rest far from every moving mesh sleep ("sleep" in
 * the config; Box2D's sleeping bodies, Chrono's active box around a wheel).
 *
 * A grain sleeps after `time` below `velocity` (|v| and |ω| r) when no moving
 * mesh is within `distance` (see dem_sleep_near) and it touches no mesh: its
 * velocity is set to zero, it is not integrated, its contacts with other
 * sleeping grains are not evaluated (their springs stay as they are) and its
 * plane contacts are frozen. Contacts with awake grains are evaluated as with
 * a fixed grain (an awake grain pressing slowly on a sleeping one meets a
 * wall). It wakes when a touching awake grain is faster than `velocity` or a
 * moving mesh comes within `distance`; it then restarts from rest in
 * equilibrium (force −m g: the first half kick leaves it at rest).
 * Decisions use only the state, so results stay bitwise identical for any
 * number of threads. */
#include "dem_server/dem_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

int dem_sleep_alloc(const dem_model *m, dem_state *s, proto_err *err) {
  struct dem_work *w = s->work;
  if (!m->sleep.on) return 0;
  w->asleep = calloc((size_t)s->n + 1, 1);
  w->wake = calloc((size_t)s->n + 1, 1);
  w->rest = calloc((size_t)s->n + 1, sizeof(int32_t));
  w->chunk_awake = calloc((size_t)w->nchunk + 1, sizeof(int));
  w->near = calloc((size_t)s->n + 1, 1);
  w->chunk_frozen = calloc((size_t)w->nchunk + 1, 1);
  w->row_frozen = calloc((size_t)s->n + 1, 1);
  w->prow_start = calloc((size_t)s->n + 1, sizeof(int));
  if (!w->asleep || !w->wake || !w->rest || !w->chunk_awake || !w->near || !w->chunk_frozen || !w->row_frozen ||
      !w->prow_start)
    return proto_fail(err, "out of memory for the sleep state of %d grains", s->n);
  dem_sleep_count(m, s);
  return 0;
}

void dem_sleep_free(struct dem_work *w) {
  free(w->asleep); free(w->wake); free(w->rest); free(w->chunk_awake); free(w->near); free(w->chunk_frozen);
  free(w->row_frozen); free(w->prow_start); free(w->prow);
  free(w->ng_start); free(w->ng_of); free(w->ng_x);
}

/* ---- nearness to moving meshes ----
 * Refreshed whenever the mesh candidate lists are rebuilt (dem_mesh_lists:
 * before any grain or node has moved skin/2 since the last time): points of
 * the moving meshes h = distance/2 apart at most (nodes, and grids on long
 * triangles) binned on a grid, and each grain marked near if a point lies
 * within distance + h + skin + r (every point of the surface is within h of
 * one): near means within `distance` of the surface, or somewhat farther. */
static int grow_int(int **p, int *cap, int need) {
  if (need <= *cap) return 0;
  int *q = realloc(*p, sizeof(int) * (size_t)need);
  if (!q) return -1;
  *p = q;
  *cap = need;
  return 0;
}

static int node_cell(const struct dem_work *w, const double *x, int *c) {
  for (int k = 0; k < 3; k++) {
    c[k] = (int)floor((x[k] - w->ng_lo[k]) / w->ng_size);
    if (c[k] < 0 || c[k] >= w->ng_dim[k]) return -1;
  }
  return (c[2] * w->ng_dim[1] + c[1]) * w->ng_dim[0] + c[0];
}

/* Points of the moving meshes no farther than h from any point of them: the
 * nodes, and barycentric grids on triangles longer than h (into ng_x).
 * Returns the count, −1 when out of memory. */
static int mesh_samples(const dem_model *m, dem_state *s, double h) {
  struct dem_work *w = s->work;
  int total = 0;
  for (int pass = 0; pass < 2; pass++) {
    int q = 0;
    for (int mi = 0; mi < m->n_meshes; mi++) {
      if (!w->mesh_moving[mi]) continue;
      const dem_mesh *me = &m->meshes[mi];
      const double *x = s->mesh_x[mi];
      for (int a = 0; a < me->n_nodes; a++, q++)
        if (pass) memcpy(&w->ng_x[3 * (size_t)q], &x[3 * a], 3 * sizeof(double));
      for (int t = 0; t < me->n_tri; t++) {
        const double *p[3] = {&x[3 * me->tri[3 * t]], &x[3 * me->tri[3 * t + 1]], &x[3 * me->tri[3 * t + 2]]};
        double edge = 0;
        for (int e = 0; e < 3; e++) {
          const double d[3] = {p[e][0] - p[(e + 1) % 3][0], p[e][1] - p[(e + 1) % 3][1], p[e][2] - p[(e + 1) % 3][2]};
          edge = fmax(edge, sqrt(dem_dot(d, d)));
        }
        const int sub = (int)ceil(edge / h);
        for (int i = 0; sub > 1 && i <= sub; i++)
          for (int j = 0; i + j <= sub; j++) {
            if ((i == 0 || i == sub) && (j == 0 || j == sub || i + j == sub)) continue; /* corners: nodes */
            if (pass) {
              const double u = (double)i / sub, v = (double)j / sub;
              for (int k = 0; k < 3; k++)
                w->ng_x[3 * (size_t)q + k] = (1 - u - v) * p[0][k] + u * p[1][k] + v * p[2][k];
            }
            q++;
          }
      }
    }
    if (!pass) {
      total = q;
      if (total > w->ng_xcap) {
        double *nx = realloc(w->ng_x, sizeof(double) * 3 * (size_t)total);
        if (!nx) return -1;
        w->ng_x = nx;
        w->ng_xcap = total;
      }
    }
  }
  return total;
}

int dem_sleep_near(const dem_model *m, dem_state *s, proto_err *err) {
  struct dem_work *w = s->work;
  if (!m->sleep.on) return 0;
  memset(w->near, 0, (size_t)s->n);
  double rmax = 0, rmin = 1e300;
  for (int i = 0; i < s->n; i++) { rmax = fmax(rmax, s->radius[i]); rmin = fmin(rmin, s->radius[i]); }
  const double h = fmax(0.5 * m->sleep.distance, rmin); /* sample spacing */
  const int total = mesh_samples(m, s, h);
  if (total < 0) return proto_fail(err, "out of memory for the sleep grid");
  if (total == 0) return 0;
  double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
  for (int q = 0; q < total; q++)
    for (int k = 0; k < 3; k++) { lo[k] = fmin(lo[k], w->ng_x[3 * q + k]); hi[k] = fmax(hi[k], w->ng_x[3 * q + k]); }
  const double slack = m->sleep.distance + h + m->skin;
  w->ng_size = slack + rmax;
  long long cells = 1;
  for (int k = 0; k < 3; k++) {
    w->ng_lo[k] = lo[k] - w->ng_size;
    w->ng_dim[k] = (int)((hi[k] - lo[k]) / w->ng_size) + 3;
    cells *= w->ng_dim[k];
  }
  if (cells > 64LL * total + 4096) return proto_fail(err, "sleep: mesh grid of %lld cells", cells);
  if (grow_int(&w->ng_start, &w->ng_cap, (int)cells + 1) || grow_int(&w->ng_of, &w->ng_ncap, 2 * total))
    return proto_fail(err, "out of memory for the sleep grid");
  /* counting sort of the samples by cell (ng_of: cell, then sorted index) */
  int *cell = w->ng_of, *order = w->ng_of + total, c[3];
  memset(w->ng_start, 0, sizeof(int) * (size_t)(cells + 1));
  for (int q = 0; q < total; q++) w->ng_start[(cell[q] = node_cell(w, &w->ng_x[3 * q], c)) + 1]++;
  for (long long k = 0; k < cells; k++) w->ng_start[k + 1] += w->ng_start[k];
  for (int q = 0; q < total; q++) order[w->ng_start[cell[q]]++] = q;
  for (long long k = cells; k > 0; k--) w->ng_start[k] = w->ng_start[k - 1];
  w->ng_start[0] = 0;
  /* grains: a sample in the 27 cells around within reach */
#pragma omp parallel for schedule(dynamic, 512) num_threads(w->nthreads)
  for (int i = 0; i < s->n; i++) {
    const double *x = &s->x[3 * i], reach = slack + s->radius[i];
    int g[3];
    for (int k = 0; k < 3; k++) g[k] = (int)floor((x[k] - w->ng_lo[k]) / w->ng_size);
    int near = 0;
    for (int dz = -1; dz <= 1 && !near; dz++)
      for (int dy = -1; dy <= 1 && !near; dy++)
        for (int dx = -1; dx <= 1 && !near; dx++) {
          const int cx = g[0] + dx, cy = g[1] + dy, cz = g[2] + dz;
          if (cx < 0 || cy < 0 || cz < 0 || cx >= w->ng_dim[0] || cy >= w->ng_dim[1] || cz >= w->ng_dim[2]) continue;
          const int cl = (cz * w->ng_dim[1] + cy) * w->ng_dim[0] + cx;
          for (int k = w->ng_start[cl]; k < w->ng_start[cl + 1] && !near; k++) {
            const double *p = &w->ng_x[3 * (size_t)order[k]];
            const double d[3] = {p[0] - x[0], p[1] - x[1], p[2] - x[2]};
            near = dem_dot(d, d) < reach * reach;
          }
        }
    w->near[i] = (uint8_t)near;
  }
  return 0;
}

static int touches_mesh(const dem_model *m, const struct dem_work *w, int i) {
  for (int k = 0; m->n_meshes > 0 && k < DEM_MESH_SLOTS; k++)
    if (w->mc_key[(size_t)i * DEM_MESH_SLOTS + k]) return 1;
  return 0;
}

/* Grain i woke: its row and the rows that pair with it are live again, and
 * their chunks. Other threads may clear the same flags: atomic stores, read
 * after the step's barriers. */
static void unfreeze(struct dem_work *w, int i) {
  w->row_frozen[i] = 0;
  __atomic_store_n(&w->chunk_frozen[i / DEM_CHUNK], 0, __ATOMIC_RELAXED);
  for (int q = w->prow_start[i]; q < w->prow_start[i + 1]; q++) {
    const int row = w->prow[q];
    __atomic_store_n(&w->row_frozen[row], 0, __ATOMIC_RELAXED);
    __atomic_store_n(&w->chunk_frozen[row / DEM_CHUNK], 0, __ATOMIC_RELAXED);
  }
}

/* The rows in which each slot is a partner (after a list rebuild). */
int dem_sleep_partners(const dem_model *m, dem_state *s, proto_err *err) {
  struct dem_work *w = s->work;
  if (!m->sleep.on) return 0;
  const int n = s->n, np = w->nl_start[n];
  if (np > w->prow_cap) {
    int *p = realloc(w->prow, sizeof(int) * ((size_t)np + (size_t)np / 4 + 64));
    if (!p) return proto_fail(err, "out of memory for the sleep index");
    w->prow = p;
    w->prow_cap = np + np / 4 + 64;
  }
  memset(w->prow_start, 0, sizeof(int) * (size_t)(n + 1));
  for (int k = 0; k < np; k++) w->prow_start[w->nl_j[k] + 1]++;
  for (int i = 0; i < n; i++) w->prow_start[i + 1] += w->prow_start[i];
  for (int i = 0; i < n; i++)
    for (int k = w->nl_start[i]; k < w->nl_start[i + 1]; k++) w->prow[w->prow_start[w->nl_j[k]]++] = i;
  for (int i = n; i > 0; i--) w->prow_start[i] = w->prow_start[i - 1];
  w->prow_start[0] = 0;
  memset(w->row_frozen, 0, (size_t)n); /* found again at the next step */
  memset(w->chunk_frozen, 0, (size_t)w->nchunk);
  return 0;
}

void dem_sleep_chunk(const dem_model *m, dem_state *s, int c, int lo, int hi) {
  struct dem_work *w = s->work;
  const double v2max = m->sleep.velocity * m->sleep.velocity, *g = m->gravity;
  const int32_t rest_steps = (int32_t)ceil(m->sleep.time / s->dt - 1e-9);
  int awake = 0;
  for (int i = lo; i < hi; i++) {
    if (w->asleep[i]) {
      if (w->wake[i] || w->near[i]) {
        w->asleep[i] = w->wake[i] = 0;
        w->rest[i] = 0;
        unfreeze(w, i);
        for (int a = 0; a < 3; a++) {
          s->force[3 * i + a] = -g[a] * w->mass[i]; /* at rest in equilibrium */
          s->torque[3 * i + a] = 0;
        }
        awake++;
      }
      continue;
    }
    w->wake[i] = 0;
    const double *v = &s->v[3 * i], *o = &s->omega[3 * i], r = s->radius[i];
    const int still = dem_dot(v, v) < v2max && dem_dot(o, o) * r * r < v2max;
    w->rest[i] = still ? w->rest[i] + 1 : 0;
    if (w->rest[i] >= rest_steps && !touches_mesh(m, w, i) && !w->near[i]) {
      w->asleep[i] = 1;
      memset(&s->v[3 * i], 0, 3 * sizeof(double));
      memset(&s->omega[3 * i], 0, 3 * sizeof(double));
    } else {
      awake++;
    }
  }
  w->chunk_awake[c] = awake;
}

void dem_sleep_count(const dem_model *m, dem_state *s) {
  struct dem_work *w = s->work;
  if (!m->sleep.on) return;
  int64_t sleeping = 0;
  for (int c = 0; c < w->nchunk; c++) {
    const int lo = c * DEM_CHUNK, hi = (c + 1) * DEM_CHUNK < s->n ? (c + 1) * DEM_CHUNK : s->n;
    int awake = 0;
    for (int i = lo; i < hi; i++) awake += !w->asleep[i];
    w->chunk_awake[c] = awake;
    sleeping += hi - lo - awake;
  }
  s->sleeping = sleeping;
}
