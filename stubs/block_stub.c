/* block_stub, lug_stub — a linear spring that speaks the block role, or built
 * with STUB_LUG the lug role (PROTOCOL.md "Role `lug`", scenario tire_road):
 * force = stiffness · max(0, d_road − gap); as a lug its centre of pressure
 * is the face's centre (cop = 0), and having no memory it ignores a request's
 * reset (a new lug); idle requests carry d_road = −1 m and give force 0.
 * As a lug it takes lug_block's grid (nx × ny cells of dx × dy, default one
 * cell of 56 x 112 mm over the generated tread's face), so that it can stand in beside lug_blocks of
 * the same scene; it ignores the face's shape (base) and spreads its force
 * evenly over the cells.
 * Config: {"exec": "block_stub" | "lug_stub", "stiffness": …, "gap": 0,
 * lug: "grid": {nx, ny, dx, dy}}; other keys (a contact_block / lug_block
 * section) are named in the log and ignored. */
#include <stdlib.h>
#include <string.h>

#include "stubs/stub.h"

#ifdef STUB_LUG
#define STUB_NAME "lug_stub"
#define STUB_ROLE PROTO_ROLE_LUG
/* N/m, when standing in for lug_block: about the static stiffness of
 * configs/tire_road.json's block on its 53 x 99 mm face (2.63e6 N/m measured
 * for its 8 x 15 version, tests/e2e/test_tire_road_static.py) */
#define STIFFNESS_DEFAULT 2.6e6
#define STUB_CELLS_MAX 65536 /* cells of its grid: lug_block's largest is 256 x 256 */
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
  int64_t nx, ny; /* lug: its grid */
  double dx, dy;  /* m */
  double *cell_xy, *cell_force; /* lug: [c][2], [c] */
} spring_stub;

#ifdef STUB_LUG
/* The grid of the lug_block it stands in for (only its size is used). */
static int read_grid(spring_stub *s, proto_cfg *c) {
  proto_cfg g;
  s->nx = s->ny = 1, s->dx = 0.056, s->dy = 0.112;
  const int r = proto_cfg_child(c, "grid", PROTO_OPTIONAL, &g);
  if (r != 0) return r < 0 ? -1 : 0;
  if (proto_cfg_int(&g, "nx", PROTO_OPTIONAL, 1, STUB_CELLS_MAX, &s->nx) < 0 ||
      proto_cfg_int(&g, "ny", PROTO_OPTIONAL, 1, STUB_CELLS_MAX, &s->ny) < 0 ||
      proto_cfg_num(&g, "dx", PROTO_OPTIONAL, 1e-9, 1.0, &s->dx) < 0 ||
      proto_cfg_num(&g, "dy", PROTO_OPTIONAL, 1e-9, 1.0, &s->dy) < 0)
    return -1;
  if (s->nx * s->ny > STUB_CELLS_MAX)
    return proto_fail(c->err, "%s.grid: %lld x %lld cells (at most %d)", c->path,
                      (long long)s->nx, (long long)s->ny, STUB_CELLS_MAX);
  return stub_cfg_end(&g, STUB_NAME);
}
#endif

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
#ifdef STUB_LUG
  if (read_grid(s, &c) < 0) return -1;
#endif
  return stub_cfg_end(&c, STUB_NAME);
}

static int init(void *user, const proto_msg *welcome, proto_msg *ready,
                proto_err *err) {
  spring_stub *s = user;
  (void)welcome;
#ifdef STUB_LUG
  const int64_t M = s->nx * s->ny;
  s->cell_xy = malloc(sizeof(double) * 2 * (size_t)M);
  s->cell_force = calloc((size_t)M, sizeof(double));
  if (!s->cell_xy || !s->cell_force) return proto_fail(err, "out of memory");
  for (int64_t e = 0; e < M; e++) { /* lug_block's element centres about the grid's centre */
    s->cell_xy[2 * e] = (double)(e % s->nx) * s->dx + 0.5 * s->dx - 0.5 * (double)s->nx * s->dx;
    s->cell_xy[2 * e + 1] = (double)(e / s->nx) * s->dy + 0.5 * s->dy - 0.5 * (double)s->ny * s->dy;
  }
  if (proto_msg_add_f8(ready, PROTO_A_CELL_XY, M, 2, s->cell_xy) < 0)
    return proto_fail(err, "ready: too many arrays");
#else
  (void)s;
#endif
  if (proto_ready_series(ready, PROTO_A_SERIES, NCOL, columns) < 0)
    return proto_fail(err, "out of memory");
  return 0;
}

/* (d_road[, reset]) -> (force[, cop = 0, cell_force = force / c], series row) */
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
  const int64_t M = s->nx * s->ny;
  for (int64_t e = 0; e < M; e++) s->cell_force[e] = s->force / (double)M;
  if (proto_msg_add_f8(reply, PROTO_A_COP, 2, 0, cop) < 0 ||
      proto_msg_add_f8(reply, PROTO_A_CELL_FORCE, M, 0, s->cell_force) < 0)
    return proto_fail(err, "reply full");
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
  const int rc = proto_participant_main(argc, argv, &ops, &s);
  free(s.cell_xy);
  free(s.cell_force);
  return rc;
}
