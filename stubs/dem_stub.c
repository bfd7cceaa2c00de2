/* dem_stub — prescribed grain forces that speak the dem role (PROTOCOL.md):
 * every surface node gets force_per_node, ramped linearly from zero over
 * ramp_time. As the role table says, the reply is the impulse over the step
 * divided by dt: force_per_node times the mean of the ramp over
 * [t_{k-1}, t_k]. It echoes the surface it receives as its snapshot.
 * With bed_top only the nodes below it (z at t_{k-1}) get the force. Sparse
 * exchange (PROTOCOL.md): when the request says sparse it sends the force as
 * (index, force) of the nodes that carry one (dense beyond a third of them);
 * it gives no reach box, so it always gets every node (its snapshot echoes
 * them all). With drag_x each such node also gets -drag_x v_x, v_x its
 * velocity along x over the step (the request's v, constant over the step,
 * so the impulse is exact; not ramped): on fem_stub's wheel, whose nodes
 * move at v_x = V - omega r cos(theta) for a carriage speed V, the traction
 * is linear in the slip s = 1 - V / (omega r), a known force-slip law for
 * the drawbar-pull rig. With step_wall each step also takes that many
 * seconds of wall time (asleep), as a solver's compute would: a run that lasts
 * on any machine, for tests that watch one live.
 * Config: {"exec": "dem_stub", "force_per_node": [fx, fy, fz],
 *          "ramp_time": 0.0, "bed_top": z, "drag_x": c, "step_wall": s}; other keys (a
 * dem_server section) are named in the log and ignored (then the force is
 * zero). */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "stubs/stub.h"

enum { COL_T, COL_FX, COL_FY, COL_FZ, COL_N, NCOL };
static const char *const columns[NCOL] = {"t", "force_x", "force_y", "force_z",
                                          "n_nodes"};
static const char *const SNAP_ATTRS[] = {PROTO_A_NODAL_FORCE};

typedef struct dem_stub {
  double force_per_node[3]; /* N */
  double ramp_time;         /* s */
  double bed_top;           /* m: only nodes below it get the force */
  double drag_x;            /* N s/m per node: -drag_x v_x along x */
  double step_wall;         /* s of wall time each step takes (asleep) */
  int32_t *index;           /* [n] sparse reply: the nodes that carry a force */
  double *rows;             /* [n*3] their forces */
  int64_t n_nodes;
  double *force;
  double series[NCOL];
} dem_stub;

static int configure(void *user, const proto_run_info *info,
                     const cJSON *section, proto_err *err) {
  dem_stub *s = user;
  proto_cfg c;
  char exec[256];
  s->bed_top = INFINITY;
  if (proto_cfg_open(&c, section, info->key_path, err) < 0 ||
      proto_cfg_str(&c, "exec", PROTO_OPTIONAL, exec, sizeof exec) < 0 ||
      proto_cfg_vec(&c, "force_per_node", PROTO_OPTIONAL, s->force_per_node, 3,
                    3, NULL) < 0 ||
      proto_cfg_num(&c, "ramp_time", PROTO_OPTIONAL, 0, 1e9, &s->ramp_time) < 0 ||
      proto_cfg_num(&c, "bed_top", PROTO_OPTIONAL, -1e9, 1e9, &s->bed_top) < 0 ||
      proto_cfg_num(&c, "drag_x", PROTO_OPTIONAL, 0, 1e9, &s->drag_x) < 0 ||
      proto_cfg_num(&c, "step_wall", PROTO_OPTIONAL, 0, 60, &s->step_wall) < 0)
    return -1;
  return stub_cfg_end(&c, "dem_stub");
}

static int init(void *user, const proto_msg *welcome, proto_msg *ready,
                proto_err *err) {
  dem_stub *s = user;
  const proto_array *x0 = proto_msg_find(welcome, PROTO_A_SURFACE_X0);
  if (x0) { /* checked against the role table by the participant loop */
    s->n_nodes = x0->shape[0];
    s->force = calloc((size_t)s->n_nodes * 3, sizeof(double));
    s->index = malloc(sizeof(int32_t) * (size_t)s->n_nodes);
    s->rows = malloc(sizeof(double) * 3 * (size_t)s->n_nodes);
    if (!s->force || !s->index || !s->rows) return proto_fail(err, "out of memory");
  }
  if (proto_ready_series(ready, PROTO_A_SERIES, NCOL, columns) < 0 ||
      (s->n_nodes > 0 &&
       proto_ready_snapshot(ready, "points", PROTO_A_X, NULL, 1, SNAP_ATTRS) < 0))
    return proto_fail(err, "out of memory");
  return 0;
}

/* ∫_0^t min(τ/T, 1) dτ */
static double ramp_integral(double t, double T) {
  if (T <= 0) return t;
  return t <= T ? 0.5 * t * t / T : 0.5 * T + (t - T);
}

static int step(void *user, proto_peer *peer, const proto_step_info *info,
                const proto_msg *req, proto_msg *reply, proto_err *err) {
  (void)peer;
  dem_stub *s = user;
  double ramp = (ramp_integral(info->t_end, s->ramp_time) -
                 ramp_integral(info->t, s->ramp_time)) / info->dt;
  double total[3] = {0, 0, 0};
  if (s->n_nodes > 0) {
    const double *x = proto_msg_data(req, PROTO_A_X), *v = proto_msg_data(req, PROTO_A_V);
    int64_t k = 0;
    for (int64_t i = 0; i < s->n_nodes; i++) {
      const int below = x[3 * i + 2] < s->bed_top;
      for (int a = 0; a < 3; a++)
        s->force[3 * i + a] = below ? ramp * s->force_per_node[a] : 0;
      if (below && s->drag_x > 0) s->force[3 * i] -= s->drag_x * v[3 * i];
      for (int a = 0; a < 3; a++) total[a] += s->force[3 * i + a];
      if (below) { /* rows of +0.0 may be sent too: the coupler expands to +0.0 */
        s->index[k] = (int32_t)i;
        memcpy(&s->rows[3 * k++], &s->force[3 * i], 3 * sizeof(double));
      }
    }
    const int sparse = cJSON_IsTrue(cJSON_GetObjectItemCaseSensitive(req->header, PROTO_H_SPARSE)) &&
                       3 * k <= s->n_nodes;
    if ((sparse ? proto_msg_add_i4(reply, PROTO_A_NODAL_FORCE_INDEX, k, 0, s->index) < 0 ||
                      proto_msg_add_f8(reply, PROTO_A_NODAL_FORCE, k, 3, s->rows) < 0
                : proto_msg_add_f8(reply, PROTO_A_NODAL_FORCE, s->n_nodes, 3, s->force) < 0) ||
        (info->output &&
         (proto_msg_add_prefixed(reply, PROTO_P_SNAP, PROTO_A_X, PROTO_F8,
                                 s->n_nodes, 3, x) < 0 ||
          proto_msg_add_prefixed(reply, PROTO_P_SNAP, PROTO_A_NODAL_FORCE,
                                 PROTO_F8, s->n_nodes, 3, s->force) < 0)))
      return proto_fail(err, "reply full");
  }
  if (s->step_wall > 0) {
    const struct timespec ts = {(time_t)s->step_wall,
                                (long)((s->step_wall - floor(s->step_wall)) * 1e9)};
    nanosleep(&ts, NULL);
  }
  double row[NCOL] = {info->t_end, total[0], total[1], total[2], (double)s->n_nodes};
  memcpy(s->series, row, sizeof row);
  if (proto_msg_add_f8(reply, PROTO_A_SERIES, NCOL, 0, s->series) < 0)
    return proto_fail(err, "reply full");
  return 0;
}

static void finish(void *user) {
  dem_stub *s = user;
  free(s->force);
  free(s->index);
  free(s->rows);
  s->force = NULL;
  s->index = NULL;
  s->rows = NULL;
}

int main(int argc, char **argv) {
  dem_stub s = {0};
  const proto_participant_ops ops = {.role = PROTO_ROLE_DEM,
                                     .configure = configure,
                                     .init = init,
                                     .step = step,
                                     .finish = finish,
                                     .state_save = stub_state_none_save,
                                     .state_load = stub_state_none_load};
  return proto_participant_main(argc, argv, &ops, &s);
}
