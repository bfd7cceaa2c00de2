/* checkpoint.c — checkpoints and restart (README "Checkpoints and restart";
 * Veen & Hoekstra 2020: MUSCLE3's coordinated checkpoints at window
 * boundaries). After step k (k a multiple of checkpoint.every) the coupler
 * asks every participant for its state (the `checkpoint` message; the reply
 * `state` carries the arrays its state_save makes, the same ones rollback
 * uses) and writes them with its own state — the fields it holds between
 * the processes, the scenario's rim and road, its counters, the implicit
 * scheme's carried impulse defect and the accelerator's history — to
 * output.dir/checkpoint_<k>.h5 through proto's HDF5 layer (written under a
 * temporary name, then renamed: a checkpoint file is always whole). A
 * restart reads it, checks that the scene continues it, and after the
 * handshake sends each participant its state (`restore`); the run then goes
 * on from step k + 1, bit for bit as if it had never stopped.
 *
 * File layout: root attributes "cosim" (CKPT_MAGIC) and "config" (the scene
 * as run); /coupler/<name> one dataset per piece of the coupler's state
 * (step first); /participants/<name>/state.<x> with attribute "role". */
#include "runner.h"

#include <dirent.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define CKPT_MAGIC "cosim checkpoint 1"
#define CKPT_PREFIX "checkpoint_"
#define CKPT_SUFFIX ".h5"
#define CKPT_TMP ".tmp"
#define CKPT_LATEST "latest"
#define MAX_VALS 64
#define G_COUPLER "/coupler"
#define G_PARTS "/participants"
#define A_MAGIC "cosim"
#define A_CONFIG "config"
#define A_ROLE "role"
#define V_STEP "step"

/* Scene keys a restart may change: they do not decide the results. */
static const char *const FREE_KEYS[] = {
    "name", "time.end", "output", "bus", "checkpoint", "security",
    "coupling.hello_timeout", "coupling.heartbeat_timeout", "coupling.handshake_timeout",
    "coupling.step_timeout", "coupling.attach_endpoint", NULL};

/* Scene keys a branch (--branch) may change besides: the coupling scheme.
 * The scheme's own coupler state (the implicit scheme's carried defect, its
 * accelerator's history) is then not taken from the checkpoint: it starts as
 * at step 0. The participants' states do not depend on the scheme. */
static const char *const BRANCH_KEYS[] = {"coupling.scheme", "coupling.implicit", NULL};
static const char *const SCHEME_VALS[] = {"implicit.", "accel.", NULL};

typedef struct ckpt_array {
  proto_array a;
  void *data;
} ckpt_array;

typedef struct ckpt_part {
  char name[PROTO_NAME_LEN];
  char role[PROTO_NAME_LEN];
  int n;
  ckpt_array arrays[PROTO_MAX_ARRAYS];
} ckpt_part;

struct cpl_ckpt {
  char path[CPL_PATH_LEN];
  int64_t step;
  int branch;       /* --branch: a new run from this state (its own results.h5) */
  int other_scheme; /* a branch under another scheme (BRANCH_KEYS differ) */
  cJSON *config;
  int nparts;
  ckpt_part parts[CPL_MAX_PROCS];
  int nvals;
  ckpt_array vals[MAX_VALS];
};

/* -------------------------------------------------------- the coupler */

/* Every piece of the coupler's state that carries over a step boundary. */
static int coupler_state(cpl_runner *r, int64_t *step, double *wall, int64_t *unconv,
                         cpl_stateval *v) {
  static const char *const field_keys[CPL_N_FIELDS] = {
      "field.surface.x", "field.surface.v", "field.surface.force", "field.rim.R",
      "field.rim.c", "field.rim.omega", "field.rim.v", "field.road.d", "field.road.force",
      "field.lug.d", "field.lug.force", "field.lug.cop", "field.lug.origin",
      "field.lug.base", "field.lug.cell_force"};
  int n = 0;
  v[n++] = (cpl_stateval){V_STEP, PROTO_I8, step, 1};
  v[n++] = (cpl_stateval){"wall_s", PROTO_F8, wall, 1};
  v[n++] = (cpl_stateval){"steps_unconverged", PROTO_I8, unconv, 1};
  for (int f = 0; f < CPL_N_FIELDS; f++)
    v[n++] = (cpl_stateval){field_keys[f], PROTO_F8, r->data.fields[f].cur, r->data.fields[f].len};
  _Static_assert(sizeof(int) == 4, "int flags are stored as i4");
  v[n++] = (cpl_stateval){"rim.travelling", PROTO_I4, &r->data.rim.travelling, 1};
  v[n++] = (cpl_stateval){"rim.angle", PROTO_F8, &r->data.rim.angle, 1};
  v[n++] = (cpl_stateval){"rim.c", PROTO_F8, r->data.rim.c, 3};
  v[n++] = (cpl_stateval){"rim.v", PROTO_F8, r->data.rim.v, 3};
  v[n++] = (cpl_stateval){"rim.w", PROTO_F8, r->data.rim.w, 3};
  v[n++] = (cpl_stateval){"rim.R", PROTO_F8, r->data.rim.R, 9};
  v[n++] = (cpl_stateval){"rim.c0", PROTO_F8, r->data.rim.c0, 3};
  v[n++] = (cpl_stateval){"rim.z_touch", PROTO_F8, &r->data.rim.z_touch, 1};
  v[n++] = (cpl_stateval){"rim.z_fit", PROTO_F8, &r->data.rim.z_fit, 1};
  v[n++] = (cpl_stateval){"rim.fit", PROTO_F8, r->data.rim.fit, 5};
  v[n++] = (cpl_stateval){"rim.stiffness", PROTO_F8, &r->data.rim.stiffness, 1};
  v[n++] = (cpl_stateval){"rim.mass", PROTO_F8, &r->data.rim.mass, 1};
  v[n++] = (cpl_stateval){"rim.damping", PROTO_F8, &r->data.rim.damping, 1};
  v[n++] = (cpl_stateval){"rim.travel_time", PROTO_F8, &r->data.rim.travel_time, 1};
  v[n++] = (cpl_stateval){"rim.resistive_force", PROTO_F8, &r->data.rim.resistive_force, 1};
  v[n++] = (cpl_stateval){"rim.avg_bins", PROTO_F8, &r->data.rim.avg_bins[0][0],
                          CPL_DBP_BINS * CPL_DBP_NAVG};
  v[n++] = (cpl_stateval){"rim.avg_part", PROTO_F8, r->data.rim.avg_part, CPL_DBP_NAVG};
  v[n++] = (cpl_stateval){"rim.avg_n", PROTO_I8, r->data.rim.avg_n, 4};
  v[n++] = (cpl_stateval){"lug.slot", PROTO_I4, r->data.lug.lug, CPL_MAX_PROCS};
  v[n++] = (cpl_stateval){"lug.handovers", PROTO_I8, &r->data.lug.handovers, 1};
  v[n++] = (cpl_stateval){"road.d", PROTO_F8, &r->data.road.d, 1};
  v[n++] = (cpl_stateval){"road.v", PROTO_F8, &r->data.road.v, 1};
  v[n++] = (cpl_stateval){"road.a", PROTO_F8, &r->data.road.a, 1};
  v[n++] = (cpl_stateval){"road.force_last", PROTO_F8, &r->data.road.force_last, 1};
  if (r->data.carry) /* implicit: the impulse defect carried into the next step */
    v[n++] = (cpl_stateval){"implicit.carry", PROTO_F8, r->data.carry, 3 * r->plan->surf.n_nodes};
  return n + cpl_accel_state(r->accel, v + n, MAX_VALS - n);
}

/* ------------------------------------------------------------ writing */

static void file_path(char *out, size_t cap, const char *dir, int64_t k, const char *tail) {
  snprintf(out, cap, "%s/%s%lld%s%s", dir, CKPT_PREFIX, (long long)k, CKPT_SUFFIX, tail);
}

/* checkpoint_<k>.h5 → k; -1 for other names. */
static int64_t step_of(const char *name) {
  size_t np = strlen(CKPT_PREFIX), ns = strlen(CKPT_SUFFIX), n = strlen(name);
  if (n <= np + ns || strncmp(name, CKPT_PREFIX, np) || strcmp(name + n - ns, CKPT_SUFFIX))
    return -1;
  int64_t k = 0;
  for (size_t i = np; i < n - ns; i++) {
    if (name[i] < '0' || name[i] > '9' || k > INT64_MAX / 10 - 9) return -1;
    k = 10 * k + (name[i] - '0');
  }
  return k;
}

static int newest_first(const void *a, const void *b) {
  const int64_t x = *(const int64_t *)a, y = *(const int64_t *)b;
  return (x < y) - (x > y);
}

#define LIST_CAP 4096

/* The steps of the checkpoints in dir, newest first. */
static int list_steps(const char *dir, int64_t *steps) {
  DIR *d = opendir(dir);
  int n = 0;
  for (struct dirent *e; d && (e = readdir(d));) {
    int64_t k = step_of(e->d_name);
    if (k >= 0 && n < LIST_CAP) steps[n++] = k;
  }
  if (d) closedir(d);
  qsort(steps, (size_t)n, sizeof *steps, newest_first);
  return n;
}


static void prune(const char *dir, int64_t keep) {
  static int64_t steps[LIST_CAP];
  int n = list_steps(dir, steps);
  char path[CPL_PATH_LEN + 64];
  for (int i = (int)keep; i < n; i++) {
    file_path(path, sizeof path, dir, steps[i], "");
    unlink(path);
  }
}

int cpl_checkpoint_clear(const char *dir, proto_err *err) {
  static int64_t steps[LIST_CAP];
  int n = list_steps(dir, steps);
  char path[CPL_PATH_LEN + 64];
  for (int i = 0; i < n; i++) {
    file_path(path, sizeof path, dir, steps[i], "");
    if (unlink(path) != 0 && errno != ENOENT)
      return proto_fail(err, "cannot remove the old checkpoint %s: %s", path, strerror(errno));
  }
  return 0;
}

/* Asks every participant for its state after step k; the replies land in
 * their reply slots. */
static int gather_states(cpl_runner *r, int64_t k) {
  const double t = (double)k * r->scene->dt;
  proto_msg req = {0};
  int rc = 0;
  for (int i = 0; i < r->n && rc == 0; i++) {
    proto_msg_reset(&req, r->peers[i].proc->name, proto_msg_type(PROTO_MSG_CHECKPOINT), k, t);
    rc = cpl_send(r, i, &req);
  }
  proto_msg_free(&req);
  int got[CPL_MAX_PROCS] = {0};
  for (int left = r->n; rc == 0 && left > 0; left--) {
    int from = -1;
    if (cpl_receive(r, -1, r->scene->step_timeout, "step_timeout", NULL, &from) < 0) return -1;
    const proto_msg *m = &r->peers[from].reply;
    r->failed_peer = from;
    if (got[from]++ || strcmp(m->type, proto_msg_type(PROTO_MSG_STATE)) || m->step != k)
      return proto_fail(&r->err, "participant '%s': expected 'state' for step %lld, got "
                        "'%s' for step %lld", r->peers[from].proc->name, (long long)k,
                        m->type, (long long)m->step);
    for (int a = 0; a < m->narrays; a++)
      if (strncmp(m->arrays[a].name, PROTO_P_STATE, strlen(PROTO_P_STATE)) != 0)
        return proto_fail(&r->err, "participant '%s': its state carries '%s'; state "
                          "arrays are named %s<x>", r->peers[from].proc->name,
                          m->arrays[a].name, PROTO_P_STATE);
    r->failed_peer = -1;
  }
  return rc;
}

static int write_file(cpl_runner *r, int64_t k, const char *path) {
  proto_err *err = &r->err;
  proto_h5 *f = proto_h5_create(path, err);
  if (!f) return -1;
  char *config = cJSON_Print(r->scene->root);
  int rc = config ? 0 : proto_fail(err, "out of memory");
  if (rc == 0) rc = proto_h5_attr_str(f, "/", A_MAGIC, CKPT_MAGIC, err);
  if (rc == 0) rc = proto_h5_attr_str(f, "/", A_CONFIG, config, err);
  free(config);
  char group[CPL_PATH_LEN];
  for (int i = 0; i < r->n && rc == 0; i++) {
    const proto_msg *m = &r->peers[i].reply;
    snprintf(group, sizeof group, "%s/%s", G_PARTS, r->peers[i].proc->name);
    rc = proto_h5_attr_str(f, group, A_ROLE, proto_role_name(r->peers[i].role), err);
    for (int a = 0; a < m->narrays && rc == 0; a++)
      rc = proto_h5_write_array(f, group, &m->arrays[a], err);
  }
  int64_t step = k, unconv = r->data.steps_unconverged;
  double wall = proto_now() - r->wall_start;
  cpl_stateval v[MAX_VALS];
  int nv = coupler_state(r, &step, &wall, &unconv, v);
  for (int i = 0; i < nv && rc == 0; i++) {
    proto_array a = {.dtype = v[i].dtype, .ndim = 1, .shape = {v[i].count}, .data = v[i].data,
                     .nbytes = (size_t)v[i].count * proto_dtype_size(v[i].dtype)};
    snprintf(a.name, sizeof a.name, "%s", v[i].name);
    rc = proto_h5_write_array(f, G_COUPLER, &a, err);
  }
  if (proto_h5_close(f, rc < 0 ? NULL : err) < 0) rc = -1;
  return rc;
}

/* (every participant's state, the coupler's) -> (checkpoint_<k>.h5) */
int cpl_checkpoint_write(cpl_runner *r, int64_t k) {
  const cpl_scene *s = r->scene;
  /* the results hold every row up to step k before the checkpoint exists */
  if (cpl_output_flush(r->out, &r->err) < 0 || gather_states(r, k) < 0) return -1;
  char tmp[CPL_PATH_LEN + 64], final[CPL_PATH_LEN + 64];
  file_path(tmp, sizeof tmp, s->output_dir, k, CKPT_TMP);
  file_path(final, sizeof final, s->output_dir, k, "");
  if (write_file(r, k, tmp) < 0 || rename(tmp, final) != 0) {
    if (strstr(r->err.msg, tmp) == NULL) /* rename failed */
      proto_fail(&r->err, "cannot rename %s: %s (errno %d)", tmp, strerror(errno), errno);
    unlink(tmp); /* frees what it took, for the results' last flush */
    r->exit_code = CPL_EXIT_OUTPUT;
    return proto_wrap(&r->err, "checkpoint of step %lld", (long long)k);
  }
  prune(s->output_dir, s->checkpoint_keep);
  return 0;
}

/* ------------------------------------------------------------ reading */

void cpl_checkpoint_free(cpl_ckpt *c) {
  if (!c) return;
  for (int i = 0; i < c->nparts; i++)
    for (int a = 0; a < c->parts[i].n; a++) free(c->parts[i].arrays[a].data);
  for (int i = 0; i < c->nvals; i++) free(c->vals[i].data);
  cJSON_Delete(c->config);
  free(c);
}

int64_t cpl_checkpoint_step(const cpl_ckpt *c) { return c->step; }

typedef struct read_ctx {
  proto_h5in *f;
  cpl_ckpt *c;
  ckpt_part *part; /* reading one participant's arrays, else NULL */
  proto_err *err;
} read_ctx;

/* One dataset <group>/<name> as stored. Its name goes into a restore
 * message: the names' grammar, and at most what a message frame holds. */
static int read_one(read_ctx *x, const char *group, const char *name, ckpt_array *dst) {
  char path[CPL_PATH_LEN + PROTO_NAME_LEN];
  snprintf(path, sizeof path, "%s/%s", group, name);
  if (proto_name_check(name, PROTO_NAME_DOTTED, "array name", x->err) < 0)
    return proto_wrap(x->err, "%s:%s", x->c->path, group);
  return proto_h5in_read_array(x->f, path, PROTO_MAX_FRAME_BYTES, &dst->a, &dst->data,
                               x->err);
}

static int read_val(const char *name, void *ctx) {
  read_ctx *x = ctx;
  if (x->c->nvals == MAX_VALS)
    return proto_fail(x->err, "%s:%s: more than %d coupler arrays", x->c->path,
                      G_COUPLER, MAX_VALS);
  return read_one(x, G_COUPLER, name, &x->c->vals[x->c->nvals++]) < 0 ? -1 : 0;
}

static int read_state_array(const char *name, void *ctx) {
  read_ctx *x = ctx;
  ckpt_part *p = x->part;
  char group[CPL_PATH_LEN];
  snprintf(group, sizeof group, "%s/%s", G_PARTS, p->name);
  if (p->n == PROTO_MAX_ARRAYS)
    return proto_fail(x->err, "%s:%s: more than %d state arrays", x->c->path, group,
                      PROTO_MAX_ARRAYS);
  if (strncmp(name, PROTO_P_STATE, strlen(PROTO_P_STATE)) != 0)
    return proto_fail(x->err, "%s:%s/%s: state arrays are named %s<x>", x->c->path,
                      group, name, PROTO_P_STATE);
  return read_one(x, group, name, &p->arrays[p->n++]) < 0 ? -1 : 0;
}

static int read_part(const char *name, void *ctx) {
  read_ctx *x = ctx;
  cpl_ckpt *c = x->c;
  if (c->nparts == CPL_MAX_PROCS)
    return proto_fail(x->err, "%s:%s: more than %d participants", c->path, G_PARTS,
                      CPL_MAX_PROCS);
  if (proto_name_check(name, PROTO_NAME_PLAIN, "process name", x->err) < 0)
    return proto_wrap(x->err, "%s:%s", c->path, G_PARTS);
  ckpt_part *p = &c->parts[c->nparts++];
  snprintf(p->name, sizeof p->name, "%s", name);
  char group[CPL_PATH_LEN];
  snprintf(group, sizeof group, "%s/%s", G_PARTS, name);
  int rc = proto_h5in_attr_str(x->f, group, A_ROLE, p->role, sizeof p->role, x->err);
  if (rc == 1)
    return proto_fail(x->err, "%s:%s: attribute %s missing", c->path, group, A_ROLE);
  if (rc < 0) return -1;
  x->part = p;
  rc = proto_h5in_list(x->f, group, read_state_array, x, x->err);
  x->part = NULL;
  return rc < 0 ? -1 : 0;
}

static const ckpt_array *find_val(const cpl_ckpt *c, const char *name) {
  for (int i = 0; i < c->nvals; i++)
    if (strcmp(c->vals[i].a.name, name) == 0) return &c->vals[i];
  return NULL;
}

/* Appends ".key" or "[i]" to a key path. */
static size_t push(char *path, size_t cap, const char *key, int index) {
  size_t len = strlen(path);
  if (key) snprintf(path + len, cap - len, "%s%s", len ? "." : "", key);
  else snprintf(path + len, cap - len, "[%d]", index);
  return len;
}

/* 1 if a and b differ; path gets the first difference's key path. */
static int json_diff(const cJSON *a, const cJSON *b, char *path, size_t cap) {
  if (cJSON_IsObject(a) && cJSON_IsObject(b)) {
    for (int pass = 0; pass < 2; pass++)
      for (const cJSON *x = (pass ? b : a)->child; x; x = x->next) {
        const cJSON *y = cJSON_GetObjectItemCaseSensitive(pass ? a : b, x->string);
        size_t len = push(path, cap, x->string, 0);
        if (!y || (!pass && json_diff(x, y, path, cap))) return 1;
        path[len] = 0;
      }
    return 0;
  }
  if (cJSON_IsArray(a) && cJSON_IsArray(b) && cJSON_GetArraySize(a) == cJSON_GetArraySize(b)) {
    int i = 0;
    for (const cJSON *x = a->child, *y = b->child; x; x = x->next, y = y->next, i++) {
      size_t len = push(path, cap, NULL, i);
      if (json_diff(x, y, path, cap)) return 1;
      path[len] = 0;
    }
    return 0;
  }
  return !cJSON_Compare(a, b, 1);
}

/* Deletes a.b.c from a copy of the scene. */
static void drop_key(cJSON *root, const char *dotted) {
  char key[CPL_PATH_LEN];
  snprintf(key, sizeof key, "%s", dotted);
  cJSON *o = root;
  char *part = key, *dot;
  while (o && (dot = strchr(part, '.'))) {
    *dot = 0;
    o = cJSON_GetObjectItemCaseSensitive(o, part);
    part = dot + 1;
  }
  if (cJSON_IsObject(o)) cJSON_DeleteItemFromObjectCaseSensitive(o, part);
}

/* processes.<name>.exec as its participant alone (the last element of a
 * launcher list): the launcher in front of it may change on a restart, e.g.
 * `mpirun -np N` to resume liggghts_dem on another rank count (its state is
 * LIGGGHTS' restart file, which any rank count reads); the participant may
 * not. */
static void drop_launchers(cJSON *root) {
  cJSON *procs = cJSON_GetObjectItemCaseSensitive(root, "processes");
  for (cJSON *p = cJSON_IsObject(procs) ? procs->child : NULL; p; p = p->next) {
    const cJSON *exec = cJSON_GetObjectItemCaseSensitive(p, "exec");
    const int n = cJSON_IsArray(exec) ? cJSON_GetArraySize(exec) : 0;
    const cJSON *last = n > 0 ? cJSON_GetArrayItem(exec, n - 1) : NULL;
    if (cJSON_IsString(last))
      cJSON_ReplaceItemInObjectCaseSensitive(p, "exec", cJSON_CreateString(last->valuestring));
  }
}

/* The scene with the keys that may change left out. */
static cJSON *comparable(const cJSON *scene) {
  cJSON *c = cJSON_Duplicate(scene, 1);
  for (int i = 0; FREE_KEYS[i]; i++) drop_key(c, FREE_KEYS[i]);
  drop_launchers(c);
  return c;
}

/* The scene must continue the checkpointed one: equal in every key that
 * decides the results (a branch: but the scheme, and then other_scheme
 * says whether the scheme differs). */
static int same_scene(cpl_ckpt *c, const cpl_scene *s, int branch, proto_err *err) {
  cJSON *was = comparable(c->config), *now = comparable(s->root);
  char path[CPL_PATH_LEN] = "";
  int differ = !was || !now || json_diff(was, now, path, sizeof path);
  if (differ && branch && was && now) {
    for (int i = 0; BRANCH_KEYS[i]; i++) {
      drop_key(was, BRANCH_KEYS[i]);
      drop_key(now, BRANCH_KEYS[i]);
    }
    path[0] = 0;
    c->other_scheme = 1;
    differ = json_diff(was, now, path, sizeof path);
  }
  cJSON_Delete(was);
  cJSON_Delete(now);
  const char *what = branch ? "branch" : "restart";
  if (differ)
    return proto_fail(err, "--%s %s: the scene differs from the checkpointed one "
                      "at '%s'; a %s continues the same scene (it may change "
                      "time.end, output, bus, checkpoint, security, the "
                      "coupling deadlines and the launcher in front of a "
                      "participant's exec, e.g. mpirun -np N%s)", what, c->path,
                      path[0] ? path : "(root)", what,
                      branch ? "; a branch also coupling.scheme and coupling.implicit" : "");
  if (c->nparts != s->nprocs)
    return proto_fail(err, "--%s %s: the checkpoint holds %d participants, the "
                      "scene has %d processes", what, c->path, c->nparts, s->nprocs);
  return 0;
}

static int latest(const char *dir, char *out, size_t cap, proto_err *err) {
  static int64_t steps[LIST_CAP];
  if (list_steps(dir, steps) < 1)
    return proto_fail(err, "--restart %s: no %s<step>%s in %s", CKPT_LATEST, CKPT_PREFIX,
                      CKPT_SUFFIX, dir);
  file_path(out, cap, dir, steps[0], "");
  return 0;
}

/* The root attributes: the magic, then the scene as run. */
static int read_header(proto_h5in *f, cpl_ckpt *c, proto_err *err) {
  char magic[sizeof CKPT_MAGIC + 1] = "", *config = NULL;
  int rc = proto_h5in_attr_str(f, "/", A_MAGIC, magic, sizeof magic, err);
  if (rc == 1 || (rc == 0 && strcmp(magic, CKPT_MAGIC) != 0))
    return proto_fail(err, "%s: not a cosim checkpoint (its root attribute %s is not "
                      "'%s')", c->path, A_MAGIC, CKPT_MAGIC);
  if (rc == 0) rc = proto_h5in_attr_strdup(f, "/", A_CONFIG, &config, err);
  if (rc == 1) rc = proto_fail(err, "%s:/: attribute %s missing", c->path, A_CONFIG);
  if (rc == 0) c->config = proto_json_parse(config, c->path, err);
  free(config);
  return rc == 0 && c->config ? 0 : -1;
}

/* /coupler/step: one i8, the step the checkpoint was made after (>= 1). */
static int read_step(cpl_ckpt *c, proto_err *err) {
  const ckpt_array *st = find_val(c, V_STEP);
  if (!st || st->a.dtype != PROTO_I8 || st->a.nbytes != sizeof(int64_t))
    return proto_fail(err, "%s:%s/%s: %s; expected one i8 (the step)", c->path, G_COUPLER,
                      V_STEP, st ? "another type or size" : "dataset missing");
  memcpy(&c->step, st->data, sizeof c->step);
  if (c->step < 1)
    return proto_fail(err, "%s:%s/%s: step %lld (a checkpoint is made after a step >= 1)",
                      c->path, G_COUPLER, V_STEP, (long long)c->step);
  return 0;
}

cpl_ckpt *cpl_checkpoint_read(const char *path, const cpl_scene *s, int branch,
                               proto_err *err) {
  cpl_ckpt *c = calloc(1, sizeof *c);
  if (!c) {
    proto_fail(err, "out of memory");
    return NULL;
  }
  int rc = strcmp(path, CKPT_LATEST) == 0 ? latest(s->output_dir, c->path, sizeof c->path, err)
                                          : (snprintf(c->path, sizeof c->path, "%s", path), 0);
  proto_h5in *f = rc == 0 ? proto_h5in_open(c->path, err) : NULL;
  rc = f ? read_header(f, c, err) : -1;
  read_ctx x = {f, c, NULL, err};
  if (rc == 0) rc = proto_h5in_list(f, G_COUPLER, read_val, &x, err);
  if (rc == 0) rc = proto_h5in_list(f, G_PARTS, read_part, &x, err);
  if (rc == 0) rc = read_step(c, err);
  c->branch = branch;
  if (rc == 0) rc = same_scene(c, s, branch, err);
  proto_h5in_close(f);
  if (rc < 0) {
    cpl_checkpoint_free(c);
    return NULL;
  }
  return c;
}

/* ---------------------------------------------------------- restoring */

static const ckpt_part *find_part(const cpl_ckpt *c, const char *name) {
  for (int i = 0; i < c->nparts; i++)
    if (strcmp(c->parts[i].name, name) == 0) return &c->parts[i];
  return NULL;
}

static int restore_participants(cpl_runner *r) {
  const cpl_ckpt *c = r->ckpt;
  const double t = (double)c->step * r->scene->dt;
  proto_msg m = {0};
  int rc = 0;
  for (int i = 0; i < r->n && rc == 0; i++) {
    const cpl_peer *p = &r->peers[i];
    const ckpt_part *cp = find_part(c, p->proc->name);
    r->failed_peer = i;
    if (!cp)
      rc = proto_fail(&r->err, "--restart %s: no state of participant '%s'", c->path,
                      p->proc->name);
    else if (strcmp(cp->role, proto_role_name(p->role)) != 0)
      rc = proto_fail(&r->err, "--restart %s: participant '%s' was of role %s, now %s",
                      c->path, p->proc->name, cp->role, proto_role_name(p->role));
    if (rc < 0) break;
    r->failed_peer = -1;
    proto_msg_reset(&m, p->proc->name, proto_msg_type(PROTO_MSG_RESTORE), c->step, t);
    for (int a = 0; a < cp->n; a++) m.arrays[m.narrays++] = cp->arrays[a].a;
    rc = cpl_send(r, i, &m);
    m.narrays = 0; /* the arrays belong to the checkpoint */
  }
  proto_msg_free(&m);
  for (int left = r->n; rc == 0 && left > 0; left--) {
    int from = -1;
    if (cpl_receive(r, -1, r->scene->step_timeout, "step_timeout", NULL, &from) < 0)
      return proto_wrap(&r->err, "--restart %s", c->path);
    const proto_msg *got = &r->peers[from].reply;
    if (strcmp(got->type, proto_msg_type(PROTO_MSG_RESTORED)) != 0 || got->step != c->step) {
      r->failed_peer = from;
      return proto_fail(&r->err, "participant '%s': expected 'restored' for step %lld, "
                        "got '%s'", r->peers[from].proc->name, (long long)c->step,
                        got->type);
    }
  }
  return rc;
}

static int scheme_value(const char *name) {
  for (int i = 0; SCHEME_VALS[i]; i++)
    if (strncmp(name, SCHEME_VALS[i], strlen(SCHEME_VALS[i])) == 0) return 1;
  return 0;
}

/* The coupler's state from the checkpoint: every piece this run carries
 * must be there, of its type and size; apply: copied in. */
static int coupler_values(cpl_runner *r, int apply) {
  const cpl_ckpt *c = r->ckpt;
  int64_t step = 0, unconv = 0;
  double wall = 0;
  cpl_stateval v[MAX_VALS];
  int nv = coupler_state(r, &step, &wall, &unconv, v);
  for (int i = 0; i < nv; i++) {
    if (c->other_scheme && scheme_value(v[i].name)) continue; /* starts as at step 0 */
    const ckpt_array *a = find_val(c, v[i].name);
    size_t want = (size_t)v[i].count * proto_dtype_size(v[i].dtype);
    if (!a || a->a.dtype != v[i].dtype || a->a.nbytes != want)
      return proto_fail(&r->err, "--%s %s:%s/%s: %s there, %s of %zu bytes here "
                        "(another scene, surface or scheme?)", c->branch ? "branch" : "restart",
                        c->path, G_COUPLER, v[i].name, a ? "different" : "missing",
                        proto_dtype_name(v[i].dtype), want);
    if (apply && want) memcpy(v[i].data, a->data, want);
  }
  if (apply && !c->branch) { /* a branch is a new run: its counters start at 0 */
    r->data.steps_unconverged = unconv;
    r->wall_start = proto_now() - wall;
  }
  return 0;
}

int cpl_checkpoint_restore(cpl_runner *r) {
  /* the coupler's own state first: nothing is sent for a checkpoint that
   * does not fit */
  if (coupler_values(r, 0) < 0 || restore_participants(r) < 0) return -1;
  return coupler_values(r, 1);
}
