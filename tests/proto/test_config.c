/* Config errors name the key path and what was expected; malformed JSON
 * reports line and column; unknown keys are caught; --set overrides. */
#include <math.h>

#include "cosim_test.h"
#include "proto/proto.h"

static void test_parse_errors(void) {
  proto_err err = {{0}};
  cJSON *j = proto_json_parse("{\n  \"a\": 1,\n  \"b\": [1, 2,, 3]\n}", "scene.json", &err);
  CHECK(j == NULL);
  CHECK_MSG(err, "scene.json:3:");
  CHECK_MSG(err, "malformed JSON");
  j = proto_json_parse("{\"a\": 1", "x.json", &err);
  CHECK(j == NULL);
  CHECK_MSG(err, "x.json:1:");
  CHECK(proto_json_load("/nonexistent/scene.json", &err) == NULL);
  CHECK_MSG(err, "cannot open");
}

static void test_reader(void) {
  proto_err err = {{0}};
  cJSON *j = proto_json_parse(
      "{\"materials\": [{\"E\": 5e6, \"nu\": 0.5}], \"dt\": \"x\", \"n\": 2.5,"
      " \"kind\": \"cube\", \"g\": [0, 0], \"typo\": 1, \"ok\": true}", "s", &err);
  CHECK(j != NULL);
  proto_cfg c, m;
  CHECK(proto_cfg_open(&c, j, "processes.dem", &err) == 0);
  const cJSON *mats = proto_cfg_raw(&c, "materials", PROTO_REQUIRED);
  char path[128];
  proto_cfg_subpath(&c, "materials", 0, path, sizeof path);
  CHECK(proto_cfg_open(&m, cJSON_GetArrayItem(mats, 0), path, &err) == 0);
  double E = 0, nu = 0;
  CHECK(proto_cfg_num(&m, "E", PROTO_REQUIRED, 0, INFINITY, &E) == 0 && E == 5e6);
  CHECK(proto_cfg_num_below(&m, "nu", PROTO_REQUIRED, 0, 0.5, &nu) < 0);
  CHECK_MSG(err, "processes.dem.materials[0].nu: must be in [0, 0.5), got 0.5");
  double dt = 7;
  CHECK(proto_cfg_num(&c, "dt", PROTO_REQUIRED, 0, 1, &dt) < 0);
  CHECK_MSG(err, "processes.dem.dt: expected a number");
  CHECK(dt == 7);
  int64_t n;
  CHECK(proto_cfg_int(&c, "n", PROTO_REQUIRED, 0, 10, &n) < 0);
  CHECK_MSG(err, "processes.dem.n: expected an integer");
  static const char *const kinds[] = {"plane", "box", NULL};
  int kind;
  CHECK(proto_cfg_enum(&c, "kind", PROTO_REQUIRED, kinds, &kind) < 0);
  CHECK_MSG(err, "'cube' is not one of: plane, box");
  double g[3];
  CHECK(proto_cfg_vec(&c, "g", PROTO_REQUIRED, g, 3, 3, NULL) < 0);
  CHECK_MSG(err, "processes.dem.g: expected a list of 3 numbers");
  double missing = 42;
  CHECK(proto_cfg_num(&c, "absent", PROTO_OPTIONAL, 0, 1, &missing) == 0 && missing == 42);
  CHECK(proto_cfg_num(&c, "absent", PROTO_REQUIRED, 0, 1, &missing) < 0);
  CHECK_MSG(err, "processes.dem.absent: required key is missing");
  int ok = 0;
  CHECK(proto_cfg_bool(&c, "ok", PROTO_REQUIRED, &ok) == 0 && ok == 1);
  CHECK(proto_cfg_end(&c) < 0);
  CHECK_MSG(err, "processes.dem.typo: unknown key");
  cJSON_Delete(j);
}

static void test_set(void) {
  proto_err err = {{0}};
  cJSON *j = proto_json_parse("{\"time\": {\"dt\": 1}, \"l\": [{\"a\": 1}]}", "s", &err);
  CHECK(proto_json_set(j, "time.dt=0.5", &err) == 0);
  CHECK(cJSON_GetObjectItem(cJSON_GetObjectItem(j, "time"), "dt")->valuedouble == 0.5);
  CHECK(proto_json_set(j, "processes.dem.exec=dem_stub", &err) == 0);
  const cJSON *e = cJSON_GetObjectItem(cJSON_GetObjectItem(cJSON_GetObjectItem(j, "processes"), "dem"), "exec");
  CHECK(cJSON_IsString(e) && strcmp(e->valuestring, "dem_stub") == 0);
  CHECK(proto_json_set(j, "l[0].a=[1,2]", &err) == 0);
  CHECK(cJSON_IsArray(cJSON_GetObjectItem(cJSON_GetArrayItem(cJSON_GetObjectItem(j, "l"), 0), "a")));
  CHECK(proto_json_set(j, "l[3].a=1", &err) < 0);
  CHECK(proto_json_set(j, "novalue", &err) < 0);
  CHECK_MSG(err, "expected KEY.PATH=VALUE");
  cJSON_Delete(j);
}

int main(void) {
  test_parse_errors();
  test_reader();
  test_set();
  return cosim_test_done("test_config");
}
