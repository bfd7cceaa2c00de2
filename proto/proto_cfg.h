/* proto_cfg.h — proto's config: JSON loading, --set overrides, the key reader.
 * Part of proto.h, the one public header: include "proto/proto.h", not this. */
#ifndef COSIM_PROTO_CFG_H
#define COSIM_PROTO_CFG_H
#ifndef COSIM_PROTO_H
#error "include proto/proto.h, not proto_cfg.h"
#endif

/* ------------------------------------------------------------------ config */

#define PROTO_PATH_CAP 256 /* key paths in messages ("processes.dem.walls[2].n") */
/* Largest JSON text read (a scene, a section on stdin). */
#define PROTO_MAX_JSON_BYTES ((size_t)256 << 20)

/* Parses JSON text; malformed input reports line and column:
 * "scene.json:12:5: malformed JSON near '...'". A key given twice in any
 * object (cJSON would keep both silently) is an error naming its path:
 * "scene.json: processes.dem.materials[1].E: duplicate key (given 2
 * times)". Returns NULL on error. */
cJSON *proto_json_parse(const char *text, const char *source_name,
                        proto_err *err);
cJSON *proto_json_load(const char *path, proto_err *err); /* "-": stdin */
/* The duplicate-key check alone, on a parsed tree (path: its key path, may
 * be "" for the root). Received headers get it too (proto_decode). */
int proto_json_check_unique(const cJSON *node, const char *path,
                            proto_err *err);
/* Applies one --set override (README "--set"). Two forms:
 *   KEY.PATH=VALUE   VALUE is text. It stays a string when it is not as a
 *                    whole one JSON value ("output.dir=2024/run1" is the
 *                    string "2024/run1"), and when the scene has a string at
 *                    KEY.PATH (then "output.dir=2024" is the string "2024";
 *                    only a "quoted" VALUE is read as a JSON string there).
 *                    Otherwise a number, true, false, null, a "quoted
 *                    string", {...} or [...] is that JSON value.
 *   KEY.PATH:=JSON   VALUE must be one JSON value, of any type.
 * Missing object keys on the path are created; an index [i] must exist.
 * A value that the key's reader does not accept is reported by the reader
 * (e.g. "output.dir: expected a string, got a number"). */
int proto_json_set(cJSON *root, const char *assignment, proto_err *err);

/* Key reader: wraps an object and its path; every getter marks the key as
 * used, and proto_cfg_end() reports any key nobody asked for (typos).
 * All getters return 0 on success (value stored) or -1 with err naming the
 * path and what was expected. A missing optional key leaves *out as the
 * default given. */
typedef struct proto_cfg {
  const cJSON *obj;
  char path[PROTO_PATH_CAP];
  uint64_t used; /* bitmask over the object's first 64 keys */
  proto_err *err;
} proto_cfg;

typedef enum { PROTO_OPTIONAL = 0, PROTO_REQUIRED = 1 } proto_need;

/* Starts reading obj (must be an object) at path; fails if it is not. */
int proto_cfg_open(proto_cfg *c, const cJSON *obj, const char *path,
                   proto_err *err);
/* Opens a child object: key missing and optional -> returns 1, c->obj NULL. */
int proto_cfg_child(proto_cfg *parent, const char *key, proto_need need,
                    proto_cfg *child);
int proto_cfg_num(proto_cfg *c, const char *key, proto_need need, double lo,
                  double hi, double *out); /* lo <= v <= hi */
/* Like proto_cfg_num but the upper bound is exclusive: lo <= v < hi. */
int proto_cfg_num_below(proto_cfg *c, const char *key, proto_need need,
                        double lo, double hi, double *out);
int proto_cfg_int(proto_cfg *c, const char *key, proto_need need, int64_t lo,
                  int64_t hi, int64_t *out);
int proto_cfg_bool(proto_cfg *c, const char *key, proto_need need, int *out);
/* An optional thread count: "auto" or 0 (*out = 0), or 1..1024; missing:
 * *out unchanged. */
int proto_cfg_threads(proto_cfg *c, const char *key, int64_t *out);
/* Copies a string (cap bytes incl. NUL). */
int proto_cfg_str(proto_cfg *c, const char *key, proto_need need, char *out,
                  size_t cap);
/* A string that must be one of the NULL-terminated `choices`; *out = index. */
int proto_cfg_enum(proto_cfg *c, const char *key, proto_need need,
                   const char *const *choices, int *out);
/* A numeric array of exactly n entries (n < 0: any length up to cap);
 * *count gets the length (may be NULL). */
int proto_cfg_vec(proto_cfg *c, const char *key, proto_need need, double *out,
                  int n, int cap, int *count);
/* The raw node for custom reading (arrays of objects...); marks it used.
 * Returns NULL if missing (error only if required). */
const cJSON *proto_cfg_raw(proto_cfg *c, const char *key, proto_need need);
/* Path of an element, "parent.key[3]", for errors in custom readers. */
void proto_cfg_subpath(const proto_cfg *c, const char *key, int index,
                       char *out, size_t cap);
/* Reports the first unknown key: "<path>.<key>: unknown key". */
int proto_cfg_end(proto_cfg *c);
/* The keys nobody asked for, comma-separated into out; returns how many.
 * For stubs, which accept the section of the solver they stand in for. */
int proto_cfg_unused(const proto_cfg *c, char *out, size_t cap);

#endif
