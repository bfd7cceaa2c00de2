/* The role table (proto/roles.c): every role's arrays checked by name, dtype
 * and shape with symbolic dims (n, m) bound by the first array that has
 * them; messages that lack an array or carry a wrong shape are refused with
 * the array, the expected shape and its meaning; "with a surface" arrays
 * only when the conversation has a surface; the JSON form lists them. */
#include "proto/proto.h"
#include "cosim_test.h"

int main(void) {
  proto_err err = {{0}};
  double x0[4][3] = {{0}}, f[4][3] = {{0}}, R[9] = {0}, c[3] = {0};
  int32_t tri[2][3] = {{0, 1, 2}, {1, 3, 2}};
  proto_msg m = {0};

  /* fem ready binds n = 4, m = 2 */
  proto_dims d;
  proto_dims_init(&d);
  proto_msg_reset(&m, "fem", "ready", 0, 0);
  proto_msg_add_f8(&m, PROTO_A_SURFACE_X0, 4, 3, &x0[0][0]);
  CHECK(proto_role_check(PROTO_ROLE_FEM, PROTO_MSG_READY, &m, &d, &err) < 0);
  CHECK_MSG(err, "missing array 'surface_tri': expected i4 [m, 3]");
  proto_msg_add_i4(&m, PROTO_A_SURFACE_TRI, 2, 3, &tri[0][0]);
  proto_dims_init(&d);
  CHECK(proto_role_check(PROTO_ROLE_FEM, PROTO_MSG_READY, &m, &d, &err) == 0);
  CHECK(d.nodes == 4 && d.tris == 2);

  /* a step request with a wrong shape names the bound size */
  proto_msg_reset(&m, "fem", "step", 3, 0);
  proto_msg_add_f8(&m, PROTO_A_NODAL_FORCE, 3, 3, &f[0][0]);
  proto_msg_add_f8(&m, PROTO_A_RIM_R, 3, 3, R);
  proto_msg_add_f8(&m, PROTO_A_RIM_C, 3, 0, c);
  proto_msg_add_f8(&m, PROTO_A_RIM_OMEGA, 3, 0, c);
  proto_msg_add_f8(&m, PROTO_A_RIM_V, 3, 0, c);
  CHECK(proto_role_check(PROTO_ROLE_FEM, PROTO_MSG_STEP, &m, &d, &err) < 0);
  CHECK_MSG(err, "array 'nodal_force': expected f8 [n=4, 3]");
  CHECK_MSG(err, "got f8 [3, 3]");
  CHECK_MSG(err, "impulse");
  proto_msg_reset(&m, "fem", "step", 3, 0);
  proto_msg_add_f8(&m, PROTO_A_NODAL_FORCE, 4, 3, &f[0][0]);
  proto_msg_add_f8(&m, PROTO_A_RIM_R, 9, 0, R); /* flat instead of [3,3] */
  proto_msg_add_f8(&m, PROTO_A_RIM_C, 3, 0, c);
  proto_msg_add_f8(&m, PROTO_A_RIM_OMEGA, 3, 0, c);
  proto_msg_add_f8(&m, PROTO_A_RIM_V, 3, 0, c);
  CHECK(proto_role_check(PROTO_ROLE_FEM, PROTO_MSG_STEP, &m, &d, &err) < 0);
  CHECK_MSG(err, "'rim_R': expected f8 [3, 3]");

  /* dem without a surface: x, v, nodal_force are not due */
  proto_dims_init(&d);
  proto_msg_reset(&m, "dem", "welcome", 0, 0);
  CHECK(proto_role_check(PROTO_ROLE_DEM, PROTO_MSG_WELCOME, &m, &d, &err) == 0 && !d.surface);
  proto_msg_reset(&m, "dem", "done", 1, 0);
  CHECK(proto_role_check(PROTO_ROLE_DEM, PROTO_MSG_DONE, &m, &d, &err) == 0);
  /* with a surface they are */
  proto_msg_reset(&m, "dem", "welcome", 0, 0);
  proto_msg_add_f8(&m, PROTO_A_SURFACE_X0, 4, 3, &x0[0][0]);
  proto_msg_add_i4(&m, PROTO_A_SURFACE_TRI, 2, 3, &tri[0][0]);
  CHECK(proto_role_check(PROTO_ROLE_DEM, PROTO_MSG_WELCOME, &m, &d, &err) == 0 && d.surface);
  proto_msg_reset(&m, "dem", "done", 1, 0);
  CHECK(proto_role_check(PROTO_ROLE_DEM, PROTO_MSG_DONE, &m, &d, &err) < 0);
  CHECK_MSG(err, "done (role dem): missing array 'nodal_force': expected f8 [n=4, 3]");
  /* an i4 where f8 is due */
  proto_msg_reset(&m, "block", "done", 1, 0);
  int32_t one = 1;
  proto_msg_add_i4(&m, PROTO_A_FORCE, 1, 0, &one);
  proto_dims_init(&d);
  CHECK(proto_role_check(PROTO_ROLE_BLOCK, PROTO_MSG_DONE, &m, &d, &err) < 0);
  CHECK_MSG(err, "'force': expected f8 [1]");

  /* names and JSON */
  CHECK(proto_role_parse("fem") == PROTO_ROLE_FEM && proto_role_parse("blob") < 0);
  CHECK(proto_msg_kind_parse("checkpoint") == PROTO_MSG_CHECKPOINT);
  cJSON *j = proto_role_table_json();
  const cJSON *roles = cJSON_GetObjectItem(j, "roles");
  const cJSON *dem_done = cJSON_GetObjectItem(cJSON_GetObjectItem(roles, "dem"), "done");
  const cJSON *nf = cJSON_GetArrayItem(dem_done, 0);
  CHECK(nf && strcmp(cJSON_GetObjectItem(nf, "name")->valuestring, PROTO_A_NODAL_FORCE) == 0);
  CHECK(strcmp(cJSON_GetArrayItem(cJSON_GetObjectItem(nf, "shape"), 0)->valuestring, "n") == 0);
  CHECK(strcmp(cJSON_GetObjectItem(nf, "when")->valuestring, "with_surface") == 0);
  cJSON_Delete(j);

  /* state arrays: by name, dtype and size */
  double u[3] = {1, 2, 3}, back[3];
  proto_msg_reset(&m, "p", "state", 0, 0);
  CHECK(proto_msg_add_prefixed(&m, PROTO_P_STATE, "u", PROTO_F8, 3, 0, u) == 0);
  CHECK(proto_state_get(&m, "u", PROTO_F8, 3, back, &err) == 0 && back[2] == 3);
  CHECK(proto_state_get(&m, "u", PROTO_F8, 4, back, &err) < 0);
  CHECK_MSG(err, "state: array 'state.u' is f8 with 24 bytes, expected f8 with 32 bytes");
  CHECK(proto_state_get(&m, "w", PROTO_F8, 3, back, &err) < 0);
  CHECK_MSG(err, "missing array 'state.w'");
  proto_msg_free(&m);
  return cosim_test_done("test_roles");
}
