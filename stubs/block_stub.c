/* block_stub — a linear spring that speaks the block role (PROTOCOL.md):
 * force = stiffness · max(0, d_road − gap).
 * Config: {"exec": "block_stub", "stiffness": 1e6, "gap": 0} */
#include <string.h>

#include "proto/proto.h"

typedef struct block_stub {
  double stiffness; /* N/m */
  double gap;       /* m */
  double force;
  double series[5]; /* t, d_road, force, points_in_contact, iterations */
} block_stub;

static int configure(void *user, const proto_run_info *info,
                     const cJSON *section, proto_err *err) {
  block_stub *s = user;
  proto_cfg c;
  char exec[256];
  if (proto_cfg_open(&c, section, info->key_path, err) < 0 ||
      proto_cfg_str(&c, "exec", PROTO_OPTIONAL, exec, sizeof exec) < 0 ||
      proto_cfg_num(&c, "stiffness", PROTO_REQUIRED, 0, 1e15, &s->stiffness) < 0 ||
      proto_cfg_num(&c, "gap", PROTO_OPTIONAL, -1, 1, &s->gap) < 0)
    return -1;
  return proto_cfg_end(&c);
}

static int init(void *user, const proto_msg *welcome, proto_msg *ready,
                proto_err *err) {
  (void)user;
  (void)welcome;
  const char *cols[] = {"t", "d_road", "force", "points_in_contact", "iterations"};
  if (proto_ready_series(ready, "series", 5, cols) < 0)
    return proto_fail(err, "out of memory");
  return 0;
}

static int step(void *user, proto_peer *peer, const proto_msg *req,
                proto_msg *reply, proto_err *err) {
  (void)peer;
  block_stub *s = user;
  const double *d = proto_msg_get_f8(req, "d_road", 1, 0, err);
  if (!d) return -1;
  double pen = d[0] - s->gap;
  s->force = pen > 0 ? s->stiffness * pen : 0;
  double row[5] = {reply->t, d[0], s->force, pen > 0 ? 1 : 0, 0};
  memcpy(s->series, row, sizeof row);
  proto_msg_add_f8(reply, "force", 1, 0, &s->force);
  proto_msg_add_f8(reply, "series", 5, 0, s->series);
  return 0;
}

int main(int argc, char **argv) {
  block_stub s = {0};
  proto_participant_ops ops = {"block", configure, init, step, NULL};
  return proto_participant_main(argc, argv, &ops, &s);
}
