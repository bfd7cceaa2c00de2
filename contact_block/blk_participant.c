/* blk_participant.c — the contact_block process: the block model behind the
 * participant loop (proto/PROTOCOL.md, role "block"). Each step request
 * carries d_road [1]; the reply carries force [1], a series row and, at
 * output steps, per-element snapshot arrays. Built with BLK_SERVE_LUGS it
 * is `lug_block` (role "lug", scenario tire_road): the same block under one
 * lug of a rolling tyre at a time; a request's header reset: true (a new
 * lug) starts its history afresh, the request carries the face's shape
 * base [M] (each element's offset, blk_state.base), and the reply adds its
 * centre of pressure cop [2] (relative to the grid's centre) and the element
 * forces cell_force [M]; its ready declares the element centres cell_xy. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "contact_block/blk.h"

/* stiffness: tangent dF/dd_road of the step's solve (blk_state.stiffness);
 * slope: (F_n − F_{n−1}) / (d_n − d_{n−1}) between the last two steps (last,
 * so the earlier columns keep their places) */
enum { COL_T, COL_D, COL_F, COL_NC, COL_IT, COL_K, COL_CONV, COL_RES, COL_SLOPE, NCOL };
static const char *const columns[NCOL] = {"t", PROTO_A_D_ROAD, PROTO_A_FORCE, "contacts",
                                          "iterations", "stiffness", "converged",
                                          "residual", "slope"};

enum { SNAP_X, SNAP_FORCE, SNAP_D_RS, SNAP_D_EL, N_SNAP };
static const char *const SNAP[N_SNAP] = {"x", "element_force", "d_rs", "d_el"};

typedef struct server {
  double scalars[BLK_STATE_SCALARS]; /* state_save */
  blk_model model;
  blk_state state;
  int have_model, have_state;
  double row[NCOL];
  double force[1];
  double cop[2];   /* lug_block: centre of pressure (m) */
  int idle;        /* lug_block: it served no lug last step (its state already reset) */
  double *x; /* [M][3] element centres, z = road height */
  double *cell_xy; /* lug_block: [M][2] element centres about the grid's centre */
  double prev[2]; /* force and d_road of the previous step (stiffness column) */
} server;

static int configure(void *user, const proto_run_info *info, const cJSON *section,
                     proto_err *err) {
  server *s = user;
  if (blk_model_from_config(&s->model, section, info->key_path, err)) {
    blk_model_free(&s->model);
    return -1;
  }
  s->have_model = 1;
  const blk_model *m = &s->model;
  if (info->dt > 0 && m->g && !m->solver.quasi_static &&
      fabs(info->dt * m->rate - 1.0) > 1e-6)
    return proto_fail(err, "%s.green: sampling rate %g Hz does not match the coupling "
                      "step time.dt = %g s (need dt = 1/rate = %g s)", info->key_path,
                      m->rate, info->dt, 1.0 / m->rate);
  return 0;
}

static int init(void *user, const proto_msg *welcome, proto_msg *ready, proto_err *err) {
  (void)welcome;
  server *s = user;
  const blk_model *m = &s->model;
  if (blk_state_create(m, &s->state, err)) return -1;
  s->have_state = 1;
  s->x = malloc((size_t)m->M * 3 * sizeof(double));
  if (!s->x) return proto_fail(err, "out of memory");
  for (int e = 0; e < m->M; e++) {
    s->x[3 * e] = (e % m->nx + 0.5) * m->dx;
    s->x[3 * e + 1] = (e / m->nx + 0.5) * m->dy;
    s->x[3 * e + 2] = m->z_road[e];
  }
#ifdef BLK_SERVE_LUGS
  s->cell_xy = malloc((size_t)m->M * 2 * sizeof(double));
  if (!s->cell_xy) return proto_fail(err, "out of memory");
  for (int e = 0; e < m->M; e++) {
    s->cell_xy[2 * e] = s->x[3 * e] - 0.5 * m->nx * m->dx;
    s->cell_xy[2 * e + 1] = s->x[3 * e + 1] - 0.5 * m->ny * m->dy;
  }
  if (proto_msg_add_f8(ready, PROTO_A_CELL_XY, m->M, 2, s->cell_xy))
    return proto_fail(err, "ready: too many arrays");
#endif
  if (proto_ready_series(ready, PROTO_A_SERIES, NCOL, columns) < 0 ||
      proto_ready_snapshot(ready, "points", SNAP[SNAP_X], NULL, 3, SNAP + SNAP_FORCE) < 0)
    return proto_fail(err, "out of memory");
  cJSON *h = proto_msg_header(ready);
  cJSON_AddNumberToObject(h, "elements", m->M);
  cJSON_AddStringToObject(h, "green_model", m->green_model);
  cJSON_AddStringToObject(h, "sampling", m->sampling);
  if (proto_msg_add_prefixed(ready, PROTO_P_MESH, SNAP[SNAP_X], PROTO_F8, m->M, 3, s->x))
    return proto_fail(err, "ready: too many arrays");
  return 0;
}

#ifdef BLK_SERVE_LUGS
#define BLK_ROLE PROTO_ROLE_LUG
#else
#define BLK_ROLE PROTO_ROLE_BLOCK
#endif

/* The centre of the element forces relative to the grid's centre (m); 0
 * without force. */
static void centre_of_pressure(const blk_model *m, const blk_state *st, double cop[2]) {
  double f = 0, fx = 0, fy = 0;
  for (int e = 0; e < m->M; e++) {
    f += st->force[e];
    fx += st->force[e] * ((e % m->nx + 0.5) * m->dx - 0.5 * m->nx * m->dx);
    fy += st->force[e] * ((e / m->nx + 0.5) * m->dy - 0.5 * m->ny * m->dy);
  }
  cop[0] = f != 0 ? fx / f : 0;
  cop[1] = f != 0 ? fy / f : 0;
}

static int step(void *user, proto_peer *peer, const proto_step_info *info,
                const proto_msg *req, proto_msg *reply, proto_err *err) {
  (void)peer;
  server *s = user;
  const blk_model *m = &s->model;
  /* checked against the role table by the participant loop */
  const double *d_road = proto_msg_data(req, PROTO_A_D_ROAD);
  if (BLK_ROLE == PROTO_ROLE_LUG &&
      cJSON_IsTrue(cJSON_GetObjectItemCaseSensitive(req->header, PROTO_H_RESET))) {
    blk_state_reset(m, &s->state); /* a new lug: nothing of the last one's history */
    s->prev[0] = s->prev[1] = 0;
    const double *o = proto_msg_data(req, PROTO_A_ORIGIN);
    if (m->road_world) { /* the road under it, and the snapshot's heights */
      blk_road_world(&s->model, o[0], o[1]);
      for (int e = 0; e < m->M; e++) s->x[3 * e + 2] = m->z_road[e];
    }
  }
  /* a lug block serving no lug: force 0 without a step (the next lug resets it anyway) */
  const int idle = BLK_ROLE == PROTO_ROLE_LUG &&
                   cJSON_IsTrue(cJSON_GetObjectItemCaseSensitive(req->header, PROTO_H_IDLE));
  if (idle && !s->idle) blk_state_reset(m, &s->state); /* once, when it goes idle */
  if (BLK_ROLE == PROTO_ROLE_LUG && !idle) /* the face's shape under the cells */
    memcpy(s->state.base, proto_msg_data(req, PROTO_A_BASE), sizeof(double) * (size_t)m->M);
  if (idle) s->state.d_road = d_road[0];
  else if (blk_step(m, &s->state, d_road[0], err)) return -1;
  s->idle = idle;
  const blk_state *st = &s->state;
  const double dd = st->d_road - s->prev[1];
  s->row[COL_T] = info->t_end;
  s->row[COL_D] = st->d_road;
  s->row[COL_F] = st->total_force;
  s->row[COL_NC] = st->n_contact;
  s->row[COL_IT] = st->iterations;
  s->row[COL_K] = st->stiffness;
  s->row[COL_SLOPE] = dd != 0 ? (st->total_force - s->prev[0]) / dd : 0.0;
  s->row[COL_CONV] = st->converged;
  s->row[COL_RES] = st->residual;
  s->prev[1] = st->d_road;
  s->prev[0] = st->total_force;
  s->force[0] = st->total_force;
  if (proto_msg_add_f8(reply, PROTO_A_FORCE, 1, 0, s->force) ||
      proto_msg_add_f8(reply, PROTO_A_SERIES, NCOL, 0, s->row))
    return proto_fail(err, "done: too many arrays");
  if (BLK_ROLE == PROTO_ROLE_LUG) {
    centre_of_pressure(m, st, s->cop);
    if (proto_msg_add_f8(reply, PROTO_A_COP, 2, 0, s->cop) ||
        proto_msg_add_f8(reply, PROTO_A_CELL_FORCE, m->M, 0, st->force))
      return proto_fail(err, "done: too many arrays");
  }
  if (info->output) {
    /* snapshot arrays ("snap.<name>" → /<name>/steps/<k>/<name>) */
    const double *snap[N_SNAP] = {s->x, st->force, st->d_rs, st->d_el};
    for (int a = 0; a < N_SNAP; a++)
      if (proto_msg_add_prefixed(reply, PROTO_P_SNAP, SNAP[a], PROTO_F8, m->M, a == SNAP_X ? 3 : 0,
                                 snap[a]))
        return proto_fail(err, "done: too many arrays");
  }
  return 0;
}

/* The model's state (blk_state_export) and this server's previous-step
 * values of its stiffness column. */
static int state_save(void *user, proto_msg *state, proto_err *err) {
  server *s = user;
  if (blk_state_export(&s->model, &s->state, s->scalars, state, err)) return -1;
  return proto_msg_add_prefixed(state, PROTO_P_STATE, "server_prev", PROTO_F8, 2, 0,
                                s->prev)
             ? proto_fail(err, "state message full")
             : 0;
}

static int state_load(void *user, const proto_msg *state, proto_err *err) {
  server *s = user;
  return blk_state_import(&s->model, &s->state, state, err) ||
                 proto_state_get(state, "server_prev", PROTO_F8, 2, s->prev, err)
             ? -1
             : 0;
}

static void finish(void *user) {
  server *s = user;
  if (s->have_state) blk_state_free(&s->state);
  if (s->have_model) blk_model_free(&s->model);
  free(s->x);
  free(s->cell_xy);
  memset(s, 0, sizeof *s);
}

int main(int argc, char **argv) {
  static server s;
  const proto_participant_ops ops = {.role = BLK_ROLE, .configure = configure,
                                     .init = init, .step = step, .finish = finish,
                                     .state_save = state_save, .state_load = state_load};
  return proto_participant_main(argc, argv, &ops, &s);
}
