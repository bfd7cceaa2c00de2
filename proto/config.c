/* config.c — JSON loading with line/column errors, --set overrides, and the
 * key reader that names the key path in every error and rejects unknown
 * keys (typos). */
#include "proto.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ------------------------------------------------------------- JSON text */

cJSON *proto_json_parse(const char *text, const char *source_name,
                        proto_err *err) {
  const char *end = NULL;
  cJSON *root = cJSON_ParseWithOpts(text, &end, 1);
  if (root) return root;
  if (!end) end = cJSON_GetErrorPtr();
  if (!end) end = text;
  int line = 1, col = 1;
  for (const char *p = text; *p && p < end; p++) {
    if (*p == '\n') {
      line++;
      col = 1;
    } else {
      col++;
    }
  }
  char near[24] = {0};
  for (int i = 0; i < 20 && end[i] && end[i] != '\n'; i++) near[i] = end[i];
  proto_fail(err, "%s:%d:%d: malformed JSON near '%s'",
             source_name ? source_name : "<json>", line, col,
             *near ? near : "<end of input>");
  return NULL;
}

static char *read_file(const char *path, proto_err *err) {
  FILE *f = fopen(path, "rb");
  if (!f) {
    proto_fail(err, "%s: cannot open: %s", path, strerror(errno));
    return NULL;
  }
  size_t cap = 4096, len = 0;
  char *buf = malloc(cap);
  while (buf) {
    size_t got = fread(buf + len, 1, cap - len - 1, f);
    len += got;
    if (len + 1 < cap) break;
    char *bigger = realloc(buf, cap * 2);
    if (!bigger) {
      free(buf);
      buf = NULL;
      break;
    }
    buf = bigger;
    cap *= 2;
  }
  int bad = ferror(f);
  fclose(f);
  if (!buf || bad) {
    free(buf);
    proto_fail(err, "%s: read failed", path);
    return NULL;
  }
  buf[len] = 0;
  return buf;
}

cJSON *proto_json_load(const char *path, proto_err *err) {
  char *text = read_file(path, err);
  if (!text) return NULL;
  cJSON *root = proto_json_parse(text, path, err);
  free(text);
  return root;
}

/* Splits "a.b[2].c" into steps; walks/creates objects; sets the last one. */
int proto_json_set(cJSON *root, const char *assignment, proto_err *err) {
  const char *eq = strchr(assignment, '=');
  if (!eq || eq == assignment)
    return proto_fail(err, "--set '%s': expected KEY.PATH=VALUE", assignment);
  char path[256];
  size_t plen = (size_t)(eq - assignment);
  if (plen >= sizeof path) return proto_fail(err, "--set: key path too long");
  memcpy(path, assignment, plen);
  path[plen] = 0;
  cJSON *value = cJSON_Parse(eq + 1);
  if (!value) value = cJSON_CreateString(eq + 1);
  cJSON *node = root;
  char *p = path;
  while (1) {
    char key[128];
    size_t k = strcspn(p, ".[");
    if (k == 0 || k >= sizeof key) {
      cJSON_Delete(value);
      return proto_fail(err, "--set '%s': bad key path", assignment);
    }
    memcpy(key, p, k);
    key[k] = 0;
    p += k;
    if (!cJSON_IsObject(node)) {
      cJSON_Delete(value);
      return proto_fail(err, "--set '%s': '%s' is not inside an object",
                        assignment, key);
    }
    cJSON *child = cJSON_GetObjectItemCaseSensitive(node, key);
    int last = (*p == 0);
    if (last) {
      if (child)
        cJSON_ReplaceItemInObjectCaseSensitive(node, key, value);
      else
        cJSON_AddItemToObject(node, key, value);
      return 0;
    }
    if (!child) child = cJSON_AddObjectToObject(node, key);
    while (*p == '[') {
      char *close;
      long idx = strtol(p + 1, &close, 10);
      if (*close != ']' || !cJSON_IsArray(child) || idx < 0 ||
          idx >= cJSON_GetArraySize(child)) {
        cJSON_Delete(value);
        return proto_fail(err, "--set '%s': index out of range or not a list",
                          assignment);
      }
      p = close + 1;
      if (*p == 0) {
        cJSON_ReplaceItemInArray(child, (int)idx, value);
        return 0;
      }
      child = cJSON_GetArrayItem(child, (int)idx);
    }
    if (*p == '.') p++;
    node = child;
  }
}

/* ------------------------------------------------------------- key reader */

int proto_cfg_open(proto_cfg *c, const cJSON *obj, const char *path,
                   proto_err *err) {
  memset(c, 0, sizeof *c);
  c->obj = obj;
  c->err = err;
  snprintf(c->path, sizeof c->path, "%s", path ? path : "");
  if (!cJSON_IsObject(obj))
    return proto_fail(err, "%s: expected an object", c->path[0] ? c->path : "config");
  return 0;
}

static void key_path(const proto_cfg *c, const char *key, char *out,
                     size_t cap) {
  if (c->path[0])
    snprintf(out, cap, "%s.%s", c->path, key);
  else
    snprintf(out, cap, "%s", key);
}

void proto_cfg_subpath(const proto_cfg *c, const char *key, int index,
                       char *out, size_t cap) {
  char base[320];
  key_path(c, key, base, sizeof base);
  if (index >= 0)
    snprintf(out, cap, "%s[%d]", base, index);
  else
    snprintf(out, cap, "%s", base);
}

/* Finds key and marks it used. Missing + required -> error. */
static const cJSON *lookup(proto_cfg *c, const char *key, proto_need need,
                           int *rc) {
  *rc = 0;
  int i = 0;
  for (const cJSON *it = c->obj ? c->obj->child : NULL; it; it = it->next, i++) {
    if (it->string && strcmp(it->string, key) == 0) {
      if (i < 64) c->used |= (uint64_t)1 << i;
      return it;
    }
  }
  if (need == PROTO_REQUIRED) {
    char p[320];
    key_path(c, key, p, sizeof p);
    *rc = proto_fail(c->err, "%s: required key is missing", p);
  }
  return NULL;
}

static int type_error(proto_cfg *c, const char *key, const char *what) {
  char p[320];
  key_path(c, key, p, sizeof p);
  return proto_fail(c->err, "%s: expected %s", p, what);
}

int proto_cfg_child(proto_cfg *parent, const char *key, proto_need need,
                    proto_cfg *child) {
  int rc;
  const cJSON *node = lookup(parent, key, need, &rc);
  memset(child, 0, sizeof *child);
  child->err = parent->err;
  key_path(parent, key, child->path, sizeof child->path);
  if (!node) return rc < 0 ? -1 : 1;
  if (!cJSON_IsObject(node)) return type_error(parent, key, "an object");
  child->obj = node;
  return 0;
}

/* Reads a finite number: 0 found, 1 missing (optional), -1 error. */
static int get_number(proto_cfg *c, const char *key, proto_need need,
                      double *v) {
  int rc;
  const cJSON *node = lookup(c, key, need, &rc);
  if (!node) return rc < 0 ? -1 : 1;
  if (!cJSON_IsNumber(node) || !isfinite(node->valuedouble))
    return type_error(c, key, "a number");
  *v = node->valuedouble;
  return 0;
}

static int range_error(proto_cfg *c, const char *key, double lo, double hi,
                       char close, double v) {
  char p[320];
  key_path(c, key, p, sizeof p);
  return proto_fail(c->err, "%s: must be in [%g, %g%c, got %g", p, lo, hi,
                    close, v);
}

int proto_cfg_num(proto_cfg *c, const char *key, proto_need need, double lo,
                  double hi, double *out) {
  double v;
  int rc = get_number(c, key, need, &v);
  if (rc != 0) return rc < 0 ? -1 : 0;
  if (v < lo || v > hi) return range_error(c, key, lo, hi, ']', v);
  *out = v;
  return 0;
}

int proto_cfg_num_below(proto_cfg *c, const char *key, proto_need need,
                        double lo, double hi, double *out) {
  double v;
  int rc = get_number(c, key, need, &v);
  if (rc != 0) return rc < 0 ? -1 : 0;
  if (v < lo || v >= hi) return range_error(c, key, lo, hi, ')', v);
  *out = v;
  return 0;
}

int proto_cfg_int(proto_cfg *c, const char *key, proto_need need, int64_t lo,
                  int64_t hi, int64_t *out) {
  int rc;
  const cJSON *node = lookup(c, key, need, &rc);
  if (!node) return rc;
  double v = node->valuedouble;
  if (!cJSON_IsNumber(node) || v != floor(v) || fabs(v) > 9e15)
    return type_error(c, key, "an integer");
  if (v < (double)lo || v > (double)hi) {
    char p[320];
    key_path(c, key, p, sizeof p);
    return proto_fail(c->err, "%s: must be in [%lld, %lld], got %.0f", p,
                      (long long)lo, (long long)hi, v);
  }
  *out = (int64_t)v;
  return 0;
}

int proto_cfg_bool(proto_cfg *c, const char *key, proto_need need, int *out) {
  int rc;
  const cJSON *node = lookup(c, key, need, &rc);
  if (!node) return rc;
  if (!cJSON_IsBool(node)) return type_error(c, key, "true or false");
  *out = cJSON_IsTrue(node);
  return 0;
}

int proto_cfg_str(proto_cfg *c, const char *key, proto_need need, char *out,
                  size_t cap) {
  int rc;
  const cJSON *node = lookup(c, key, need, &rc);
  if (!node) return rc;
  if (!cJSON_IsString(node)) return type_error(c, key, "a string");
  if (strlen(node->valuestring) >= cap) {
    char p[320];
    key_path(c, key, p, sizeof p);
    return proto_fail(c->err, "%s: longer than %zu characters", p, cap - 1);
  }
  snprintf(out, cap, "%s", node->valuestring);
  return 0;
}

int proto_cfg_enum(proto_cfg *c, const char *key, proto_need need,
                   const char *const *choices, int *out) {
  char s[128];
  int rc = proto_cfg_str(c, key, need, s, sizeof s);
  if (rc != 0 || !lookup(c, key, PROTO_OPTIONAL, &rc)) return rc;
  char list[512] = {0};
  size_t len = 0;
  for (int i = 0; choices[i]; i++) {
    if (strcmp(s, choices[i]) == 0) {
      *out = i;
      return 0;
    }
    len += (size_t)snprintf(list + len, sizeof list - len, "%s%s",
                            i ? ", " : "", choices[i]);
    if (len >= sizeof list) break;
  }
  char p[320];
  key_path(c, key, p, sizeof p);
  return proto_fail(c->err, "%s: '%s' is not one of: %s", p, s, list);
}

int proto_cfg_vec(proto_cfg *c, const char *key, proto_need need, double *out,
                  int n, int cap, int *count) {
  int rc;
  const cJSON *node = lookup(c, key, need, &rc);
  if (!node) return rc;
  int len = cJSON_IsArray(node) ? cJSON_GetArraySize(node) : -1;
  char what[64];
  if (n >= 0)
    snprintf(what, sizeof what, "a list of %d numbers", n);
  else
    snprintf(what, sizeof what, "a list of at most %d numbers", cap);
  if (len < 0 || (n >= 0 && len != n) || (n < 0 && len > cap))
    return type_error(c, key, what);
  int i = 0;
  for (const cJSON *e = node->child; e; e = e->next, i++) {
    if (!cJSON_IsNumber(e) || !isfinite(e->valuedouble)) {
      char p[320];
      key_path(c, key, p, sizeof p);
      return proto_fail(c->err, "%s[%d]: expected a number", p, i);
    }
    out[i] = e->valuedouble;
  }
  if (count) *count = len;
  return 0;
}

const cJSON *proto_cfg_raw(proto_cfg *c, const char *key, proto_need need) {
  int rc;
  return lookup(c, key, need, &rc);
}

int proto_cfg_end(proto_cfg *c) {
  int i = 0;
  for (const cJSON *it = c->obj ? c->obj->child : NULL; it; it = it->next, i++) {
    if (i >= 64 || !(c->used & ((uint64_t)1 << i))) {
      char p[320];
      key_path(c, it->string ? it->string : "?", p, sizeof p);
      return proto_fail(c->err, "%s: unknown key", p);
    }
  }
  return 0;
}

int proto_cfg_unused(const proto_cfg *c, char *out, size_t cap) {
  int i = 0, n = 0;
  size_t len = 0;
  if (cap) out[0] = 0;
  for (const cJSON *it = c->obj ? c->obj->child : NULL; it; it = it->next, i++) {
    if (i < 64 && (c->used & ((uint64_t)1 << i))) continue;
    if (len < cap)
      len += (size_t)snprintf(out + len, cap - len, "%s%s", n ? ", " : "",
                              it->string ? it->string : "?");
    n++;
  }
  return n;
}
