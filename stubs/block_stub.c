/* block_stub, lug_stub — a linear spring that speaks the block role, or built
 * with STUB_LUG the lug role (PROTOCOL.md "Role `lug`", scenario tire_road):
 * force = stiffness · max(0, d_road − gap); as a lug its centre of pressure
 * is the face's centre (cop = 0), and having no memory it ignores a request's
 * reset (a new lug); idle requests carry d_road = −1 m and give force 0.
 * Config: {"exec": "block_stub" | "lug_stub", "stiffness": …, "gap": 0}; other
 * keys (a contact_block / lug_block section) are named in the log and ignored. */
#include <string.h>

#include "stubs/stub.h"

#ifdef STUB_LUG
#define STUB_NAME "lug_stub"
#define STUB_ROLE PROTO_ROLE_LUG
/* N/m, when standing in for lug_block: about the static stiffness of
 * configs/tire_road.json's block on its 53 x 99 mm face (2.63e6 N/m measured
 * for its 8 x 15 version, tests/e2e/test_tire_road_static.py) */
#define STIFFNESS_DEFAULT 2.6e6
enum { COL_T, COL_D, COL_F, COL_RESET, NCOL };
static const char *const columns[NCOL] = {"t", PROTO_A_D_ROAD, PROTO_A_FORCE, "reset"};
#else
#define STUB_NAME "block_stub"
#define STUB_ROLE PROTO_ROLE_BLOCK
#define STIFFNESS_DEFAULT 1e6 /* N/m, when standing in for contact_block */
enum { COL_T, COL_D, COL_F, COL_NC, COL_IT, NCOL };
static const char *const columns[NCOL] = {"t", PROTO_A_D_ROAD, PROTO_A_FORCE,
                                          "points_in_contact", "iterations"};
#endif
static const char *const STATE_FORCE = "force";

typedef struct spring_stub {
  double stiffness; /* N/m */
  double gap;       /* m */
  double force;
  double series[NCOL];
} spring_stub;

static int configure(void *user, const proto_run_info *info,
                     const cJSON *section, proto_err *err) {
  spring_stub *s = user;
  proto_cfg c;
  char exec[256];
  s->stiffness = STIFFNESS_DEFAULT;
  if (proto_cfg_open(&c, section, info->key_path, err) < 0 ||
      proto_cfg_str(&c, "exec", PROTO_OPTIONAL, exec, sizeof exec) < 0 ||
      proto_cfg_num(&c, "stiffness", PROTO_OPTIONAL, 0, 1e15, &s->stiffness) < 0 ||
      proto_cfg_num(&c, "gap", PROTO_OPTIONAL, -1, 1, &s->gap) < 0)
    return -1;
  return stub_cfg_end(&c, STUB_NAME);
}

static int init(void *user, const proto_msg *welcome, proto_msg *ready,
                proto_err *err) {
  (void)user;
  (void)welcome;
  if (proto_ready_series(ready, PROTO_A_SERIES, NCOL, columns) < 0)
    return proto_fail(err, "out of memory");
  return 0;
}

/* (d_road[, reset]) -> (force[, cop = 0], series row) */
static int step(void *user, proto_peer *peer, const proto_step_info *info,
                const proto_msg *req, proto_msg *reply, proto_err *err) {
  (void)peer;
  spring_stub *s = user;
  const double d = *(const double *)proto_msg_data(req, PROTO_A_D_ROAD);
  const double pen = d - s->gap;
  s->force = pen > 0 ? s->stiffness * pen : 0;
#ifdef STUB_LUG
  static const double cop[2] = {0, 0};
  const int reset = cJSON_IsTrue(cJSON_GetObjectItemCaseSensitive(req->header, PROTO_H_RESET));
  const double row[NCOL] = {info->t_end, d, s->force, reset};
  if (proto_msg_add_f8(reply, PROTO_A_COP, 2, 0, cop) < 0) return proto_fail(err, "reply full");
#else
  const double row[NCOL] = {info->t_end, d, s->force, pen > 0 ? 1 : 0, 0};
#endif
  memcpy(s->series, row, sizeof row);
  if (proto_msg_add_f8(reply, PROTO_A_FORCE, 1, 0, &s->force) < 0 ||
      proto_msg_add_f8(reply, PROTO_A_SERIES, NCOL, 0, s->series) < 0)
    return proto_fail(err, "reply full");
  return 0;
}

/* The spring has no memory; the last force is its whole state. */
static int state_save(void *user, proto_msg *state, proto_err *err) {
  spring_stub *s = user;
  return proto_msg_add_prefixed(state, PROTO_P_STATE, STATE_FORCE, PROTO_F8, 1,
                                0, &s->force) < 0
             ? proto_fail(err, "state message full")
             : 0;
}

static int state_load(void *user, const proto_msg *state, proto_err *err) {
  spring_stub *s = user;
  return proto_state_get(state, STATE_FORCE, PROTO_F8, 1, &s->force, err);
}

int main(int argc, char **argv) {
  spring_stub s = {0};
  const proto_participant_ops ops = {.role = STUB_ROLE,
                                     .configure = configure,
                                     .init = init,
                                     .step = step,
                                     .state_save = state_save,
                                     .state_load = state_load};
  return proto_participant_main(argc, argv, &ops, &s);
}
