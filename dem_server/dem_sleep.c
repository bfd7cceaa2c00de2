/* dem_sleep.c — grains at rest far from every moving mesh sleep ("sleep" in
 * the config; Box2D's sleeping bodies, Chrono's active box around a wheel).
 *
 * A grain sleeps after `time` below `velocity` (|v| and |ω| r) when no moving
 * mesh's box (inflated by `distance`) is near and it touches no mesh: its
 * velocity is set to zero, it is not integrated, its contacts with other
 * sleeping grains are not evaluated (their springs stay as they are) and its
 * plane contacts are frozen. Contacts with awake grains are evaluated as with a
 * fixed grain. It wakes when a touching awake grain is faster than `velocity`
 * or a moving mesh's box comes within `distance`; it then restarts from rest
 * in equilibrium (force −m g: the first half kick leaves it at rest).
 * Decisions use only the state, so results stay bitwise identical for any
 * number of threads. */
#include "dem_server/dem_internal.h"

#include <stdlib.h>
#include <string.h>

int dem_sleep_alloc(const dem_model *m, dem_state *s, proto_err *err) {
  struct dem_work *w = s->work;
  if (!m->sleep.on) return 0;
  w->asleep = calloc((size_t)s->n + 1, 1);
  w->wake = calloc((size_t)s->n + 1, 1);
  w->rest = calloc((size_t)s->n + 1, sizeof(int32_t));
  w->chunk_awake = calloc((size_t)w->nchunk + 1, sizeof(int));
  if (!w->asleep || !w->wake || !w->rest || !w->chunk_awake)
    return proto_fail(err, "out of memory for the sleep state of %d grains", s->n);
  dem_sleep_count(m, s);
  return 0;
}

void dem_sleep_free(struct dem_work *w) {
  free(w->asleep); free(w->wake); free(w->rest); free(w->chunk_awake);
}

/* Within `distance` (+ r, + skin/2: the box is refitted at list rebuilds) of a
 * moving mesh's bounding box. */
static int near_moving_mesh(const dem_model *m, const dem_state *s, int i) {
  const struct dem_work *w = s->work;
  const double *x = &s->x[3 * i], reach = m->sleep.distance + s->radius[i] + 0.5 * m->skin;
  for (int mi = 0; mi < m->n_meshes; mi++) {
    const dem_bvh *b = &w->bvh[mi];
    if (!w->mesh_moving[mi] || b->n_nodes == 0) continue;
    int in = 1;
    for (int k = 0; k < 3 && in; k++) in = x[k] > b->lo[k] - reach && x[k] < b->hi[k] + reach;
    if (in) return 1;
  }
  return 0;
}

static int touches_mesh(const dem_model *m, const struct dem_work *w, int i) {
  for (int k = 0; m->n_meshes > 0 && k < DEM_MESH_SLOTS; k++)
    if (w->mc_key[(size_t)i * DEM_MESH_SLOTS + k]) return 1;
  return 0;
}

void dem_sleep_chunk(const dem_model *m, dem_state *s, int c, int lo, int hi) {
  struct dem_work *w = s->work;
  const double v2max = m->sleep.velocity * m->sleep.velocity, *g = m->gravity;
  const int32_t rest_steps = (int32_t)ceil(m->sleep.time / m->dt - 1e-9);
  int awake = 0;
  for (int i = lo; i < hi; i++) {
    if (w->asleep[i]) {
      if (w->wake[i] || near_moving_mesh(m, s, i)) {
        w->asleep[i] = w->wake[i] = 0;
        w->rest[i] = 0;
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
    if (w->rest[i] >= rest_steps && !touches_mesh(m, w, i) && !near_moving_mesh(m, s, i)) {
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
