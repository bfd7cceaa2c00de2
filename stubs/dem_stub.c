/* dem_stub — prescribed grain forces that speak the dem role (PROTOCOL.md):
 * every surface node gets force_per_node, ramped linearly from zero over
 * ramp_time. It echoes the surface it receives as its snapshot.
 * Config: {"exec": "dem_stub", "force_per_node": [fx, fy, fz],
 *          "ramp_time": 0.0} */
#include <stdlib.h>
#include <string.h>

#include "proto/proto.h"

typedef struct dem_stub {
  double force_per_node[3]; /* N */
  double ramp_time;         /* s */
  int64_t n_nodes;
  double *force;
  double series[5]; /* t, Fx, Fy, Fz, n_nodes */
} dem_stub;

static int configure(void *user, const proto_run_info *info,
                     const cJSON *section, proto_err *err) {
  dem_stub *s = user;
  proto_cfg c;
  char exec[256];
  if (proto_cfg_open(&c, section, info->key_path, err) < 0 ||
      proto_cfg_str(&c, "exec", PROTO_OPTIONAL, exec, sizeof exec) < 0 ||
      proto_cfg_vec(&c, "force_per_node", PROTO_OPTIONAL, s->force_per_node, 3,
                    3, NULL) < 0 ||
      proto_cfg_num(&c, "ramp_time", PROTO_OPTIONAL, 0, 1e9, &s->ramp_time) < 0)
    return -1;
  return proto_cfg_end(&c);
}

static int init(void *user, const proto_msg *welcome, proto_msg *ready,
                proto_err *err) {
  dem_stub *s = user;
  const proto_array *x0 = proto_msg_find(welcome, "surface_x0");
  if (x0) {
    if (!proto_msg_get_f8(welcome, "surface_x0", -1, 3, err)) return -1;
    s->n_nodes = x0->shape[0];
    s->force = calloc((size_t)s->n_nodes * 3, sizeof(double));
    if (!s->force) return proto_fail(err, "out of memory");
  }
  const char *cols[] = {"t", "force_x", "force_y", "force_z", "n_nodes"};
  const char *attrs[] = {"nodal_force"};
  if (proto_ready_series(ready, "series", 5, cols) < 0 ||
      (s->n_nodes > 0 &&
       proto_ready_snapshot(ready, "points", "x", NULL, 1, attrs) < 0))
    return proto_fail(err, "out of memory");
  return 0;
}

static int step(void *user, proto_peer *peer, const proto_msg *req,
                proto_msg *reply, proto_err *err) {
  (void)peer;
  dem_stub *s = user;
  double t = reply->t;
  double ramp = s->ramp_time > 0 && t < s->ramp_time ? t / s->ramp_time : 1.0;
  double total[3] = {0, 0, 0};
  if (s->n_nodes > 0) {
    const double *x = proto_msg_get_f8(req, "x", s->n_nodes, 3, err);
    if (!x || !proto_msg_get_f8(req, "v", s->n_nodes, 3, err)) return -1;
    for (int64_t i = 0; i < s->n_nodes; i++)
      for (int a = 0; a < 3; a++) {
        s->force[3 * i + a] = ramp * s->force_per_node[a];
        total[a] += s->force[3 * i + a];
      }
    proto_msg_add_f8(reply, "nodal_force", s->n_nodes, 3, s->force);
    const cJSON *out = cJSON_GetObjectItemCaseSensitive(req->header, "output");
    if (cJSON_IsTrue(out)) {
      proto_msg_add_f8(reply, "snap.x", s->n_nodes, 3, x);
      proto_msg_add_f8(reply, "snap.nodal_force", s->n_nodes, 3, s->force);
    }
  }
  double row[5] = {t, total[0], total[1], total[2], (double)s->n_nodes};
  memcpy(s->series, row, sizeof row);
  proto_msg_add_f8(reply, "series", 5, 0, s->series);
  return 0;
}

static void finish(void *user) {
  dem_stub *s = user;
  free(s->force);
  s->force = NULL;
}

int main(int argc, char **argv) {
  dem_stub s = {0};
  proto_participant_ops ops = {"dem", configure, init, step, finish};
  return proto_participant_main(argc, argv, &ops, &s);
}
