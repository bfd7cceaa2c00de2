/* blk_server.c — the contact_block process: the block model behind the
 * participant loop (proto/PROTOCOL.md, role "block"). Each step request
 * carries d_road [1]; the reply carries force [1], a series row and, at
 * output steps, per-element snapshot arrays. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "contact_block/blk.h"

/* stiffness: tangent dF/dd_road of the step's solve (blk_state.stiffness);
 * slope: (F_n − F_{n−1}) / (d_n − d_{n−1}) between the last two steps (last,
 * so the earlier columns keep their places) */
enum { COL_T, COL_D, COL_F, COL_NC, COL_IT, COL_K, COL_CONV, COL_RES, COL_SLOPE, NCOL };
static const char *const columns[NCOL] = {"t", "d_road", "force", "contacts",
                                          "iterations", "stiffness", "converged",
                                          "residual", "slope"};

typedef struct server {
  blk_model model;
  blk_state state;
  int have_model, have_state;
  double row[NCOL];
  double force[1];
  double *x; /* [M][3] element centres, z = road height */
  double prev_force, prev_d;
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
  const char *attrs[] = {"element_force", "d_rs", "d_el"};
  if (proto_ready_series(ready, "series", NCOL, columns) < 0 ||
      proto_ready_snapshot(ready, "points", "x", NULL, 3, attrs) < 0)
    return proto_fail(err, "out of memory");
  cJSON *h = proto_msg_header(ready);
  cJSON_AddNumberToObject(h, "elements", m->M);
  cJSON_AddStringToObject(h, "green_model", m->green_model);
  cJSON_AddStringToObject(h, "sampling", m->sampling);
  if (proto_msg_add_f8(ready, "x", m->M, 3, s->x))
    return proto_fail(err, "ready: too many arrays");
  return 0;
}

static int step(void *user, proto_peer *peer, const proto_msg *req, proto_msg *reply,
                proto_err *err) {
  (void)peer;
  server *s = user;
  const blk_model *m = &s->model;
  const double *d_road = proto_msg_get_f8(req, "d_road", 1, 0, err);
  if (!d_road) return -1;
  if (blk_step(m, &s->state, d_road[0], err)) return -1;
  const blk_state *st = &s->state;
  const double dd = st->d_road - s->prev_d;
  const cJSON *jdt = req->header ? cJSON_GetObjectItem(req->header, "dt") : NULL;
  s->row[COL_T] = req->t + (cJSON_IsNumber(jdt) ? jdt->valuedouble : 0.0);
  s->row[COL_D] = st->d_road;
  s->row[COL_F] = st->total_force;
  s->row[COL_NC] = st->n_contact;
  s->row[COL_IT] = st->iterations;
  s->row[COL_K] = st->stiffness;
  s->row[COL_SLOPE] = dd != 0 ? (st->total_force - s->prev_force) / dd : 0.0;
  s->row[COL_CONV] = st->converged;
  s->row[COL_RES] = st->residual;
  s->prev_d = st->d_road;
  s->prev_force = st->total_force;
  s->force[0] = st->total_force;
  if (proto_msg_add_f8(reply, "force", 1, 0, s->force) ||
      proto_msg_add_f8(reply, "series", NCOL, 0, s->row))
    return proto_fail(err, "done: too many arrays");
  const cJSON *out = req->header ? cJSON_GetObjectItem(req->header, "output") : NULL;
  if (cJSON_IsTrue(out)) {
    /* snapshot arrays ("snap.<name>" → /<name>/steps/<k>/<name>) */
    if (proto_msg_add_f8(reply, "snap.x", m->M, 3, s->x) ||
        proto_msg_add_f8(reply, "snap.element_force", m->M, 0, st->force) ||
        proto_msg_add_f8(reply, "snap.d_rs", m->M, 0, st->d_rs) ||
        proto_msg_add_f8(reply, "snap.d_el", m->M, 0, st->d_el))
      return proto_fail(err, "done: too many arrays");
  }
  return 0;
}

static void finish(void *user) {
  server *s = user;
  if (s->have_state) blk_state_free(&s->state);
  if (s->have_model) blk_model_free(&s->model);
  free(s->x);
  memset(s, 0, sizeof *s);
}

int main(int argc, char **argv) {
  static server s;
  const proto_participant_ops ops = {.role = "block", .configure = configure,
                                     .init = init, .step = step, .finish = finish};
  return proto_participant_main(argc, argv, &ops, &s);
}
