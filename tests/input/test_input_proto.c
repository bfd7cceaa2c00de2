/* Hostile input at proto's level (issue 11): every defect is refused with a
 * message that names it, never silently accepted.
 *   - a key given twice in any JSON object (scene, nested, list element,
 *     a received header) is "duplicate", with its path;
 *   - --set KEY=VALUE keeps strings that look like numbers as strings where
 *     the scene has a string, and "2024/run1" is never the number 2024;
 *   - the protocol version is the integer 1 (1.9 is not 1);
 *   - names from the wire follow one grammar (no '/', '..', control chars);
 *   - a done without a declared series row is refused;
 *   - every error message is terminal-safe (no escape sequences). */
#include <math.h>
#include <stdlib.h>

#include "cosim_test.h"
#include "proto/proto.h"

static const cJSON *at(const cJSON *o, const char *a, const char *b) {
  const cJSON *x = cJSON_GetObjectItemCaseSensitive(o, a);
  return b ? cJSON_GetObjectItemCaseSensitive(x, b) : x;
}

static void test_duplicates(void) {
  proto_err err = {{0}};
  CHECK(proto_json_parse("{\"a\": 1, \"a\": 2}", "s.json", &err) == NULL);
  CHECK_MSG(err, "s.json: a: duplicate key (given 2 times");
  CHECK(proto_json_parse("{\"p\": {\"b\": {\"x\": 1}, \"b\": {}, \"b\": 3}}", "s.json",
                         &err) == NULL);
  CHECK_MSG(err, "p.b: duplicate key (given 3 times");
  CHECK(proto_json_parse("{\"m\": [{\"E\": 1}, {\"E\": 1, \"nu\": 0, \"E\": 2}]}", "s.json",
                         &err) == NULL);
  CHECK_MSG(err, "m[1].E: duplicate key");
  /* deep inside lists of lists */
  CHECK(proto_json_parse("{\"a\": [[{\"q\": [{\"k\": 1, \"k\": 1}]}]]}", "s", &err) == NULL);
  CHECK_MSG(err, "a[0][0].q[0].k: duplicate key");
  /* a large object is sorted, not compared pairwise; the first duplicate in
   * the text is the one named */
  size_t cap = 1 << 20, len = 0;
  char *big = malloc(cap);
  len += (size_t)snprintf(big + len, cap - len, "{");
  for (int i = 0; i < 20000; i++)
    len += (size_t)snprintf(big + len, cap - len, "\"k%d\": %d, ", i, i);
  len += (size_t)snprintf(big + len, cap - len, "\"k17\": 0, \"k3\": 0}");
  CHECK(proto_json_parse(big, "big", &err) == NULL);
  CHECK_MSG(err, "k17: duplicate key (given 2 times");
  free(big);
  cJSON *ok = proto_json_parse("{\"a\": {\"x\": 1}, \"b\": {\"x\": 1}, \"l\": [{\"x\": 1}, {\"x\": 2}]}",
                               "s", &err);
  CHECK(ok != NULL); /* the same key in different objects is fine */
  cJSON_Delete(ok);
}

static void test_set(void) {
  proto_err err = {{0}};
  cJSON *j = proto_json_parse("{\"output\": {\"dir\": \"runs/a\", \"every\": 10}, "
                              "\"time\": {\"dt\": 1e-3}, \"l\": [1, \"s\"]}", "s", &err);
  /* not one JSON value as a whole: a string, whatever its first characters */
  CHECK(proto_json_set(j, "output.dir=2024/run1", &err) == 0);
  CHECK(cJSON_IsString(at(j, "output", "dir")) &&
        strcmp(at(j, "output", "dir")->valuestring, "2024/run1") == 0);
  /* looks like a number, but the scene has a string there: stays a string */
  CHECK(proto_json_set(j, "output.dir=2024", &err) == 0);
  CHECK(cJSON_IsString(at(j, "output", "dir")) &&
        strcmp(at(j, "output", "dir")->valuestring, "2024") == 0);
  CHECK(proto_json_set(j, "output.dir=true", &err) == 0);
  CHECK(cJSON_IsString(at(j, "output", "dir")));
  CHECK(proto_json_set(j, "output.dir=\"q\"", &err) == 0); /* quoted: JSON string */
  CHECK(strcmp(at(j, "output", "dir")->valuestring, "q") == 0);
  /* a number where the scene has a number */
  CHECK(proto_json_set(j, "output.every=20", &err) == 0);
  CHECK(cJSON_IsNumber(at(j, "output", "every")) && at(j, "output", "every")->valuedouble == 20);
  CHECK(proto_json_set(j, "time.dt=1e-3x", &err) == 0); /* not JSON: a string, */
  CHECK(cJSON_IsString(at(j, "time", "dt")));           /* which its reader refuses */
  /* a new key: JSON if it is one whole JSON value */
  CHECK(proto_json_set(j, "extra.n=7", &err) == 0);
  CHECK(cJSON_IsNumber(at(j, "extra", "n")));
  CHECK(proto_json_set(j, "extra.s=7 days", &err) == 0);
  CHECK(cJSON_IsString(at(j, "extra", "s")));
  CHECK(proto_json_set(j, "extra.q=\"7\"", &err) == 0);
  CHECK(cJSON_IsString(at(j, "extra", "q")) && strcmp(at(j, "extra", "q")->valuestring, "7") == 0);
  /* := forces JSON, and must be JSON */
  CHECK(proto_json_set(j, "output.dir:=5", &err) == 0);
  CHECK(cJSON_IsNumber(at(j, "output", "dir")));
  CHECK(proto_json_set(j, "output.dir:=2024/run1", &err) < 0);
  CHECK_MSG(err, "is not one JSON value");
  CHECK(proto_json_set(j, "extra.o:={\"a\": 1, \"a\": 2}", &err) < 0);
  CHECK_MSG(err, "extra.o.a: duplicate key");
  /* list elements */
  CHECK(proto_json_set(j, "l[1]=x", &err) == 0);
  CHECK(cJSON_IsString(cJSON_GetArrayItem(at(j, "l", NULL), 1)));
  CHECK(proto_json_set(j, "l[2]=x", &err) < 0);
  CHECK_MSG(err, "index out of range");
  CHECK(proto_json_set(j, "l[x]=1", &err) < 0);
  CHECK(proto_json_set(j, "l[0]junk=1", &err) < 0);
  CHECK_MSG(err, "bad key path");
  CHECK(proto_json_set(j, "a..b=1", &err) < 0);
  CHECK(proto_json_set(j, ":=1", &err) < 0);
  CHECK(proto_json_set(j, "=1", &err) < 0);
  cJSON_Delete(j);
  /* the reader names the key and what it got */
  j = proto_json_parse("{\"dir\": 2024}", "s", &err);
  proto_cfg c;
  char dir[64];
  CHECK(proto_cfg_open(&c, j, "output", &err) == 0);
  CHECK(proto_cfg_str(&c, "dir", PROTO_REQUIRED, dir, sizeof dir) < 0);
  CHECK_MSG(err, "output.dir: expected a string, got the number 2024");
  cJSON_Delete(j);
}

static int decode1(const char *topic, const char *header, proto_err *err) {
  const void *frames[2] = {topic, header};
  size_t sizes[2] = {strlen(topic), strlen(header)};
  proto_msg m = {0};
  int rc = proto_decode(&m, 2, frames, sizes, err);
  proto_msg_free(&m);
  return rc;
}

static void test_header(void) {
  proto_err err = {{0}};
  CHECK(decode1("p", "{\"v\":1,\"type\":\"hello\"}", &err) == 0);
  CHECK(decode1("p", "{\"v\":1.9,\"type\":\"hello\"}", &err) < 0);
  CHECK_MSG(err, "peer speaks v1.9");
  CHECK(decode1("p", "{\"v\":1.0000001,\"type\":\"hello\"}", &err) < 0);
  CHECK(decode1("p", "{\"v\":1,\"v\":2,\"type\":\"hello\"}", &err) < 0);
  CHECK_MSG(err, "header.v: duplicate key");
  CHECK(decode1("p", "{\"v\":1,\"type\":\"hello\",\"config\":{\"a\":1,\"a\":2}}", &err) < 0);
  CHECK_MSG(err, "header.config.a: duplicate key");
  CHECK(decode1("p", "{\"v\":1,\"type\":\"hello\"} trailing", &err) < 0);
  CHECK_MSG(err, "not a JSON object");
  CHECK(decode1("p", "{\"v\":1,\"type\":\"hello\"}  \n", &err) == 0);
  CHECK(decode1("p", "{\"v\":1,\"type\":\"step\",\"step\":1e300}", &err) < 0);
  CHECK_MSG(err, "header.step: expected an integer");
  CHECK(decode1("p", "{\"v\":1,\"type\":\"step\",\"step\":2.5}", &err) < 0);
  CHECK(decode1("p", "{\"v\":1,\"type\":\"step\",\"t\":1e999}", &err) < 0);
  CHECK_MSG(err, "header.t: expected a finite number");
  CHECK(decode1("p", "{\"v\":1,\"type\":\"../x\"}", &err) < 0);
  CHECK_MSG(err, "header.type '../x'");
  CHECK(decode1("a/b", "{\"v\":1,\"type\":\"hello\"}", &err) < 0);
  CHECK_MSG(err, "topic 'a/b': contains '/'");
  CHECK(decode1("", "{\"v\":1,\"type\":\"hello\"}", &err) == 0);
  CHECK(decode1("soil.series", "{\"v\":1,\"type\":\"series\"}", &err) == 0);
  /* the shape check converts nothing before the range check */
  const void *frames[3] = {"p", "{\"v\":1,\"type\":\"s\",\"arrays\":[{\"name\":\"x\","
                                "\"dtype\":\"f8\",\"shape\":[1e300]}]}", "12345678"};
  size_t sizes[3] = {1, strlen(frames[1]), 8};
  proto_msg m = {0};
  CHECK(proto_decode(&m, 3, frames, sizes, &err) < 0);
  CHECK_MSG(err, "arrays[0].shape[0]: expected a count");
  const char *bad_names[] = {"../../coupler/series", "series/x", "snap..x", ".x", "x.",
                             "a b", "x\x1b[31m", ""};
  for (size_t i = 0; i < sizeof bad_names / sizeof *bad_names; i++) {
    char h[256];
    snprintf(h, sizeof h, "{\"v\":1,\"type\":\"done\",\"arrays\":[{\"name\":\"%s\","
             "\"dtype\":\"u1\",\"shape\":[1]}]}", bad_names[i]);
    frames[1] = h;
    sizes[1] = strlen(h);
    sizes[2] = 1;
    CHECK(proto_decode(&m, 3, frames, sizes, &err) < 0);
    CHECK_MSG(err, "arrays[0].name");
    CHECK(strchr(err.msg, 0x1b) == NULL);
  }
  proto_msg_free(&m);
  /* integer header fields, read safely */
  proto_msg s = {0};
  frames[1] = "{\"v\":1,\"type\":\"done\",\"iteration\":1e300}";
  sizes[1] = strlen(frames[1]);
  CHECK(proto_decode(&s, 2, frames, sizes, &err) == 0);
  int64_t it = 0;
  CHECK(proto_header_int(&s, "iteration", 0, INT32_MAX, 0, &it, &err) < 0);
  CHECK_MSG(err, "header field 'iteration' must be an integer");
  CHECK(proto_header_int(&s, "absent", 0, 5, 3, &it, &err) == 0 && it == 3);
  proto_msg_free(&s);
}

static void test_names(void) {
  proto_err err = {{0}};
  CHECK(proto_name_check("soil", PROTO_NAME_PLAIN, "n", &err) == 0);
  CHECK(proto_name_check("tread-block_2", PROTO_NAME_PLAIN, "n", &err) == 0);
  CHECK(proto_name_check("series.wall_forces", PROTO_NAME_DOTTED, "n", &err) == 0);
  CHECK(proto_name_check("series.wall_forces", PROTO_NAME_PLAIN, "n", &err) < 0);
  CHECK(proto_name_check("..", PROTO_NAME_DOTTED, "n", &err) < 0);
  CHECK_MSG(err, "empty segment");
  CHECK(proto_name_check("a\nb", PROTO_NAME_PLAIN, "n", &err) < 0);
  CHECK(strchr(err.msg, '\n') == NULL || strstr(err.msg, "a?b")); /* sanitised */
  char longname[80];
  memset(longname, 'a', sizeof longname - 1);
  longname[sizeof longname - 1] = 0;
  CHECK(proto_name_check(longname, PROTO_NAME_PLAIN, "n", &err) < 0);
  CHECK_MSG(err, "longer than the limit");
  /* every message is terminal-safe, whatever went into it */
  proto_fail(&err, "peer says: %s", "\x1b]0;owned\x07\x1b[2J\x9b" "1m\xc2\x9b ok \xc3\xa9\n");
  CHECK(strcmp(err.msg, "peer says: ?]0;owned??[2J?1m?? ok \xc3\xa9\n") == 0);
  proto_wrap(&err, "from '%s'", "x\x1b");
  CHECK(strchr(err.msg, 0x1b) == NULL);
}

static void add_row(proto_msg *m, const char *name, int n, const double *row) {
  proto_msg_add_f8(m, name, n, 0, row);
}

static void test_series(void) {
  proto_err err = {{0}};
  proto_dims d;
  proto_dims_init(&d);
  proto_msg ready = {0}, done = {0};
  proto_msg_reset(&ready, "b", "ready", 0, 0);
  const char *cols[] = {"t", PROTO_A_FORCE}, *wf[] = {"t", "Fx"};
  proto_ready_series(&ready, PROTO_A_SERIES, 2, cols);
  proto_ready_series(&ready, "wall_forces", 2, wf);
  CHECK(proto_role_check(PROTO_ROLE_BLOCK, PROTO_MSG_READY, &ready, &d, &err) == 0);
  CHECK(d.n_series == 2);
  double row[2] = {0, 1}, f[1] = {1};
  proto_msg_reset(&done, "b", "done", 1, 0);
  proto_msg_add_f8(&done, PROTO_A_FORCE, 1, 0, f);
  add_row(&done, PROTO_A_SERIES, 2, row);
  add_row(&done, PROTO_P_SERIES "wall_forces", 2, row);
  CHECK(proto_role_check(PROTO_ROLE_BLOCK, PROTO_MSG_DONE, &done, &d, &err) == 0);
  /* a done without its series row */
  proto_msg_reset(&done, "b", "done", 1, 0);
  proto_msg_add_f8(&done, PROTO_A_FORCE, 1, 0, f);
  add_row(&done, PROTO_P_SERIES "wall_forces", 2, row);
  CHECK(proto_role_check(PROTO_ROLE_BLOCK, PROTO_MSG_DONE, &done, &d, &err) < 0);
  CHECK_MSG(err, "missing array 'series' (f8 [2]): ready declared the series dataset 'series'");
  /* a row of the wrong width */
  proto_msg_reset(&done, "b", "done", 1, 0);
  proto_msg_add_f8(&done, PROTO_A_FORCE, 1, 0, f);
  add_row(&done, PROTO_A_SERIES, 1, row);
  add_row(&done, PROTO_P_SERIES "wall_forces", 2, row);
  CHECK(proto_role_check(PROTO_ROLE_BLOCK, PROTO_MSG_DONE, &done, &d, &err) < 0);
  CHECK_MSG(err, "wrong shape or dtype of array 'series'");
  /* an undeclared dataset, and the declared one under a second name */
  const char *extra[] = {PROTO_P_SERIES "other", PROTO_P_SERIES PROTO_A_SERIES};
  for (int i = 0; i < 2; i++) {
    proto_msg_reset(&done, "b", "done", 1, 0);
    proto_msg_add_f8(&done, PROTO_A_FORCE, 1, 0, f);
    add_row(&done, PROTO_A_SERIES, 2, row);
    add_row(&done, PROTO_P_SERIES "wall_forces", 2, row);
    add_row(&done, extra[i], 2, row);
    CHECK(proto_role_check(PROTO_ROLE_BLOCK, PROTO_MSG_DONE, &done, &d, &err) < 0);
    CHECK_MSG(err, "belongs to no series dataset declared");
  }
  /* declarations: names that would become paths, bad columns, limits */
  const char *bad_ready[] = {
      "{\"../../coupler/series\": [\"t\"]}", "{\"a/b\": [\"t\"]}", "{\"..\": [\"t\"]}",
      "{\"s\": []}", "{\"s\": [\"t\", 5]}", "{\"s\": [\"\\u001b[2J\"]}", "{\"s\": \"t\"}",
      "[1]", "{\"a\":[\"t\"],\"b\":[\"t\"],\"c\":[\"t\"],\"d\":[\"t\"],\"e\":[\"t\"],"
      "\"f\":[\"t\"],\"g\":[\"t\"],\"h\":[\"t\"],\"i\":[\"t\"]}"};
  const char *why[] = {"ready.series: dataset '../../coupler/series'", "contains '/'",
                       "ready.series: dataset '..'", "1 to 64 column names",
                       "ready.series.s[1]", "ready.series.s[0]", "ready.series.s:",
                       "expected an object", "more than 8 datasets"};
  for (size_t i = 0; i < sizeof bad_ready / sizeof *bad_ready; i++) {
    proto_msg_reset(&ready, "b", "ready", 0, 0);
    cJSON_AddItemToObject(proto_msg_header(&ready), "series", cJSON_Parse(bad_ready[i]));
    CHECK(proto_role_check(PROTO_ROLE_BLOCK, PROTO_MSG_READY, &ready, &d, &err) < 0);
    CHECK_MSG(err, why[i]);
  }
  const char *bad_snap[] = {"{\"kind\":\"points\",\"geometry\":\"../x\"}",
                            "{\"kind\":\"points\",\"geometry\":\"x\",\"cells\":\"a/b\"}",
                            "{\"kind\":\"points\",\"geometry\":\"x\",\"attributes\":[\"<y>\"]}",
                            "{\"kind\":\"points\",\"geometry\":5}"};
  for (size_t i = 0; i < sizeof bad_snap / sizeof *bad_snap; i++) {
    proto_msg_reset(&ready, "b", "ready", 0, 0);
    cJSON_AddItemToObject(proto_msg_header(&ready), "snapshot", cJSON_Parse(bad_snap[i]));
    CHECK(proto_role_check(PROTO_ROLE_BLOCK, PROTO_MSG_READY, &ready, &d, &err) < 0);
    CHECK_MSG(err, "ready.snapshot.");
  }
  proto_msg_free(&ready);
  proto_msg_free(&done);
}

int main(void) {
  test_duplicates();
  test_set();
  test_header();
  test_names();
  test_series();
  return cosim_test_done("test_input_proto");
}
