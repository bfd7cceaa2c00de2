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

/* ------------------------------------------------------- duplicate keys */

/* Key path buffer shared down the recursion (appends, then restores). */
typedef struct path_buf {
  char s[PROTO_PATH_CAP];
  size_t len;
} path_buf;

static size_t path_push_key(path_buf *p, const char *key) {
  size_t old = p->len;
  if (p->len < sizeof p->s)
    p->len += (size_t)snprintf(p->s + p->len, sizeof p->s - p->len, "%s%s",
                               p->len ? "." : "", key);
  if (p->len >= sizeof p->s) p->len = sizeof p->s - 1;
  return old;
}

static size_t path_push_index(path_buf *p, int i) {
  size_t old = p->len;
  if (p->len < sizeof p->s)
    p->len += (size_t)snprintf(p->s + p->len, sizeof p->s - p->len, "[%d]", i);
  if (p->len >= sizeof p->s) p->len = sizeof p->s - 1;
  return old;
}

static void path_pop(path_buf *p, size_t old) {
  p->len = old;
  p->s[old] = 0;
}

typedef struct key_ref {
  const char *key;
  int index; /* position in the object */
} key_ref;

static int key_ref_cmp(const void *a, const void *b) {
  const key_ref *x = a, *y = b;
  int c = strcmp(x->key, y->key);
  return c ? c : (x->index > y->index) - (x->index < y->index);
}

/* Objects up to this many keys are compared pairwise, larger ones sorted
 * (a 100 000-key object must not take 10^10 comparisons). */
enum { PAIRWISE_MAX_KEYS = 16 };

/* The duplicate of obj whose second occurrence comes first in the text:
 * its key and how often it is given; NULL if every key is unique. */
static const char *first_duplicate(const cJSON *obj, int n, int *times,
                                   int *oom) {
  const char *dup = NULL;
  *times = 0;
  *oom = 0;
  if (n <= PAIRWISE_MAX_KEYS) {
    for (const cJSON *a = obj->child; a && !dup; a = a->next)
      for (const cJSON *b = obj->child; b != a; b = b->next)
        if (strcmp(a->string, b->string) == 0) {
          dup = a->string;
          break;
        }
    for (const cJSON *a = obj->child; dup && a; a = a->next)
      *times += strcmp(a->string, dup) == 0;
    return dup;
  }
  key_ref *refs = malloc(sizeof *refs * (size_t)n);
  if (!refs) {
    *oom = 1;
    return NULL;
  }
  int i = 0;
  for (const cJSON *a = obj->child; a; a = a->next, i++)
    refs[i] = (key_ref){a->string, i};
  qsort(refs, (size_t)n, sizeof *refs, key_ref_cmp);
  int best_second = n;
  for (int g = 0; g < n;) {
    int e = g + 1;
    while (e < n && strcmp(refs[e].key, refs[g].key) == 0) e++;
    if (e - g > 1 && refs[g + 1].index < best_second) {
      best_second = refs[g + 1].index;
      dup = refs[g].key;
      *times = e - g;
    }
    g = e;
  }
  free(refs);
  return dup;
}

static int unique_walk(const cJSON *node, path_buf *p, proto_err *err) {
  if (cJSON_IsObject(node)) {
    int n = 0;
    for (const cJSON *c = node->child; c; c = c->next) n++;
    int times, oom;
    const char *dup = n > 1 ? first_duplicate(node, n, &times, &oom) : NULL;
    if (n > 1 && oom) return proto_fail(err, "%s: out of memory", p->s);
    if (dup) {
      path_push_key(p, dup);
      return proto_fail(err, "%s: duplicate key (given %d times; a key may "
                        "appear once in an object)", p->s, times);
    }
    for (const cJSON *c = node->child; c; c = c->next) {
      if (!cJSON_IsObject(c) && !cJSON_IsArray(c)) continue;
      size_t old = path_push_key(p, c->string);
      if (unique_walk(c, p, err) < 0) return -1;
      path_pop(p, old);
    }
  } else if (cJSON_IsArray(node)) {
    int i = 0;
    for (const cJSON *c = node->child; c; c = c->next, i++) {
      if (!cJSON_IsObject(c) && !cJSON_IsArray(c)) continue;
      size_t old = path_push_index(p, i);
      if (unique_walk(c, p, err) < 0) return -1;
      path_pop(p, old);
    }
  }
  return 0;
}

int proto_json_check_unique(const cJSON *node, const char *path,
                            proto_err *err) {
  path_buf p;
  p.len = (size_t)snprintf(p.s, sizeof p.s, "%s", path ? path : "");
  if (p.len >= sizeof p.s) p.len = sizeof p.s - 1;
  return unique_walk(node, &p, err);
}

/* ------------------------------------------------------------- JSON text */

cJSON *proto_json_parse(const char *text, const char *source_name,
                        proto_err *err) {
  const char *end = NULL;
  const char *src = source_name ? source_name : "<json>";
  cJSON *root = cJSON_ParseWithOpts(text, &end, 1);
  if (root) {
    if (proto_json_check_unique(root, "", err) == 0) return root;
    cJSON_Delete(root);
    proto_wrap(err, "%s", src);
    return NULL;
  }
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
  proto_fail(err, "%s:%d:%d: malformed JSON near '%s'", src, line, col,
             *near ? near : "<end of input>");
  return NULL;
}

/* Reads a whole file ("-": stdin) of at most PROTO_MAX_JSON_BYTES. */
static char *read_file(const char *path, proto_err *err) {
  int is_stdin = strcmp(path, "-") == 0;
  FILE *f = is_stdin ? stdin : fopen(path, "rb");
  if (!f) {
    proto_fail(err, "%s: cannot open: %s", path, strerror(errno));
    return NULL;
  }
  size_t cap = 4096, len = 0;
  char *buf = malloc(cap);
  int too_big = 0;
  while (buf) {
    size_t got = fread(buf + len, 1, cap - len - 1, f);
    len += got;
    if (len + 1 < cap) break;
    if (cap > PROTO_MAX_JSON_BYTES) {
      too_big = 1;
      break;
    }
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
  if (!is_stdin) fclose(f);
  if (!buf || bad || too_big) {
    free(buf);
    if (too_big)
      proto_fail(err, "%s: larger than %zu bytes (not a scene?)", path,
                 (size_t)PROTO_MAX_JSON_BYTES);
    else
      proto_fail(err, "%s: read failed", path);
    return NULL;
  }
  buf[len] = 0;
  if (strlen(buf) != len) {
    free(buf);
    proto_fail(err, "%s: contains a NUL byte (not a JSON text file)", path);
    return NULL;
  }
  return buf;
}

cJSON *proto_json_load(const char *path, proto_err *err) {
  char *text = read_file(path, err);
  if (!text) return NULL;
  cJSON *root = proto_json_parse(text, strcmp(path, "-") ? path : "<stdin>", err);
  free(text);
  return root;
}

/* ------------------------------------------------------------------ --set */

/* Where an assignment's key path leads: the container and the key (object)
 * or index (list) of the value to set. Missing object keys on the way are
 * created as objects. */
typedef struct set_target {
  cJSON *parent;
  char key[PROTO_NAME_LEN * 2];
  int index; /* >= 0: list element */
} set_target;

static int set_walk(cJSON *root, const char *assignment, const char *path,
                    set_target *t, proto_err *err) {
  cJSON *node = root;
  const char *p = path;
  while (1) {
    size_t k = strcspn(p, ".[");
    if (k == 0 || k >= sizeof t->key)
      return proto_fail(err, "--set '%s': bad key path", assignment);
    if (!cJSON_IsObject(node))
      return proto_fail(err, "--set '%s': '%.*s' is not inside an object",
                        assignment, (int)k, p);
    memcpy(t->key, p, k);
    t->key[k] = 0;
    t->index = -1;
    t->parent = node;
    p += k;
    if (*p == 0) return 0;
    cJSON *child = cJSON_GetObjectItemCaseSensitive(node, t->key);
    if (!child) child = cJSON_AddObjectToObject(node, t->key);
    if (!child) return proto_fail(err, "--set '%s': out of memory", assignment);
    while (*p == '[') {
      char *close;
      errno = 0;
      long idx = strtol(p + 1, &close, 10);
      if (close == p + 1 || *close != ']' || errno || !cJSON_IsArray(child) ||
          idx < 0 || idx >= cJSON_GetArraySize(child))
        return proto_fail(err, "--set '%s': index out of range or not a list",
                          assignment);
      p = close + 1;
      if (*p == 0) {
        t->parent = child;
        t->index = (int)idx;
        return 0;
      }
      child = cJSON_GetArrayItem(child, (int)idx);
    }
    if (*p != '.')
      return proto_fail(err, "--set '%s': bad key path", assignment);
    p++;
    node = child;
  }
}

int proto_json_set(cJSON *root, const char *assignment, proto_err *err) {
  const char *eq = strchr(assignment, '=');
  int json_only = eq && eq > assignment && eq[-1] == ':';
  size_t plen = eq ? (size_t)(eq - assignment) - (size_t)json_only : 0;
  if (!eq || plen == 0)
    return proto_fail(err, "--set '%s': expected KEY.PATH=VALUE or "
                      "KEY.PATH:=JSON", assignment);
  char path[PROTO_PATH_CAP];
  if (plen >= sizeof path) return proto_fail(err, "--set: key path too long");
  memcpy(path, assignment, plen);
  path[plen] = 0;
  set_target t;
  if (set_walk(root, assignment, path, &t, err) < 0) return -1;
  const cJSON *old = t.index >= 0 ? cJSON_GetArrayItem(t.parent, t.index)
                                  : cJSON_GetObjectItemCaseSensitive(t.parent, t.key);
  const char *text = eq + 1;
  cJSON *value = cJSON_ParseWithOpts(text, NULL, 1);
  /* where the scene has a string, only a "quoted" JSON string is JSON */
  if (value && !json_only && cJSON_IsString(old) && !cJSON_IsString(value)) {
    cJSON_Delete(value);
    value = NULL;
  }
  if (value && proto_json_check_unique(value, path, err) < 0) {
    cJSON_Delete(value);
    return proto_wrap(err, "--set '%s'", assignment);
  }
  if (!value && json_only)
    return proto_fail(err, "--set '%s': '%s' is not one JSON value (KEY=VALUE "
                      "sets a string)", assignment, text);
  if (!value) value = cJSON_CreateString(text);
  if (!value) return proto_fail(err, "--set '%s': out of memory", assignment);
  int ok = t.index >= 0 ? cJSON_ReplaceItemInArray(t.parent, t.index, value)
           : old        ? cJSON_ReplaceItemInObjectCaseSensitive(t.parent, t.key, value)
                        : cJSON_AddItemToObject(t.parent, t.key, value);
  if (!ok) {
    cJSON_Delete(value);
    return proto_fail(err, "--set '%s': cannot set the value", assignment);
  }
  return 0;
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

/* What a JSON value is, for "expected X, got Y". */
static const char *json_kind(const cJSON *v) {
  return cJSON_IsString(v) ? "a string" : cJSON_IsNumber(v) ? "a number"
       : cJSON_IsBool(v)   ? "a boolean" : cJSON_IsNull(v) ? "null"
       : cJSON_IsArray(v)  ? "a list" : cJSON_IsObject(v) ? "an object"
                           : "an invalid value";
}

static int type_error(proto_cfg *c, const char *key, const char *what,
                      const cJSON *got) {
  char p[320];
  key_path(c, key, p, sizeof p);
  if (cJSON_IsNumber(got) && strcmp(what, "a string") == 0)
    return proto_fail(c->err, "%s: expected a string, got the number %.17g "
                      "(in JSON, quote it)", p, got->valuedouble);
  if (cJSON_IsNumber(got))
    return proto_fail(c->err, "%s: expected %s, got %.17g", p, what,
                      got->valuedouble);
  return proto_fail(c->err, "%s: expected %s, got %s", p, what, json_kind(got));
}

int proto_cfg_child(proto_cfg *parent, const char *key, proto_need need,
                    proto_cfg *child) {
  int rc;
  const cJSON *node = lookup(parent, key, need, &rc);
  memset(child, 0, sizeof *child);
  child->err = parent->err;
  key_path(parent, key, child->path, sizeof child->path);
  if (!node) return rc < 0 ? -1 : 1;
  if (!cJSON_IsObject(node)) return type_error(parent, key, "an object", node);
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
    return type_error(c, key, "a number", node);
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
    return type_error(c, key, "an integer", node);
  if (v < (double)lo || v > (double)hi) {
    char p[320];
    key_path(c, key, p, sizeof p);
    return proto_fail(c->err, "%s: must be in [%lld, %lld], got %.0f", p,
                      (long long)lo, (long long)hi, v);
  }
  *out = (int64_t)v;
  return 0;
}

int proto_cfg_threads(proto_cfg *c, const char *key, int64_t *out) {
  const cJSON *t = proto_cfg_raw(c, key, PROTO_OPTIONAL);
  if (!t) return 0;
  if (cJSON_IsString(t) && !strcmp(t->valuestring, "auto")) {
    *out = 0;
    return 0;
  }
  if (cJSON_IsNumber(t) && t->valuedouble >= 0 && t->valuedouble <= 1024 && t->valuedouble == floor(t->valuedouble)) {
    *out = (int64_t)t->valuedouble;
    return 0;
  }
  char p[320];
  key_path(c, key, p, sizeof p);
  return proto_fail(c->err, "%s: expected \"auto\" or a number of threads in [0, 1024] (0 = auto)", p);
}

int proto_cfg_bool(proto_cfg *c, const char *key, proto_need need, int *out) {
  int rc;
  const cJSON *node = lookup(c, key, need, &rc);
  if (!node) return rc;
  if (!cJSON_IsBool(node)) return type_error(c, key, "true or false", node);
  *out = cJSON_IsTrue(node);
  return 0;
}

int proto_cfg_str(proto_cfg *c, const char *key, proto_need need, char *out,
                  size_t cap) {
  int rc;
  const cJSON *node = lookup(c, key, need, &rc);
  if (!node) return rc;
  if (!cJSON_IsString(node)) return type_error(c, key, "a string", node);
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
    return type_error(c, key, what, node);
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
