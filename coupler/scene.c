/* scene.c — the scene's core keys (docs/architecture.md): name, time, output,
 * bus, coupling, scenario, processes.<name>.exec. The inside of a process
 * section belongs to that participant, which validates it itself
 * (`<exec> --check-config`). */
#include "coupler.h"

#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

static const char *const scheme_names[] = {"serial", "parallel", "implicit", NULL};
static const char *const accel_names[] = {"iqn-ils", "aitken", "constant", NULL};

const char *cpl_scheme_name(cpl_scheme s) {
  return (unsigned)s <= CPL_SCHEME_IMPLICIT ? scheme_names[s] : "?";
}

static int read_time(proto_cfg *root, cpl_scene *s) {
  proto_cfg c;
  if (proto_cfg_child(root, "time", PROTO_REQUIRED, &c) != 0) return -1;
  if (proto_cfg_num(&c, "dt", PROTO_REQUIRED, 1e-12, 1e3, &s->dt) < 0 ||
      proto_cfg_num(&c, "end", PROTO_REQUIRED, 0, 1e9, &s->t_end) < 0)
    return -1;
  if (s->t_end < s->dt)
    return proto_fail(c.err, "time.end: must be at least time.dt (%g), got %g",
                      s->dt, s->t_end);
  double n = floor(s->t_end / s->dt + 0.5);
  if (n > 1e12) return proto_fail(c.err, "time: end/dt = %g steps is too many", n);
  s->n_steps = (int64_t)n;
  return proto_cfg_end(&c);
}

static int read_output(proto_cfg *root, cpl_scene *s) {
  proto_cfg c;
  snprintf(s->output_dir, sizeof s->output_dir, "runs/%s", s->name);
  s->output_every = 100;
  int rc = proto_cfg_child(root, "output", PROTO_OPTIONAL, &c);
  if (rc < 0) return -1;
  if (rc > 0) return 0;
  if (proto_cfg_str(&c, "dir", PROTO_OPTIONAL, s->output_dir,
                    sizeof s->output_dir) < 0 ||
      proto_cfg_int(&c, "every", PROTO_OPTIONAL, 1, INT64_MAX,
                    &s->output_every) < 0)
    return -1;
  return proto_cfg_end(&c);
}

static int bus_endpoint(proto_cfg *c, const char *key, const char *ep) {
  if (ep[0] && strncmp(ep, "tcp://", 6) && strncmp(ep, "ipc://", 6))
    return proto_fail(c->err, "bus.%s: expected a tcp:// or ipc:// endpoint, got '%s'",
                      key, ep);
  if (!strncmp(ep, "tcp://", 6) && !strrchr(ep + 6, ':'))
    return proto_fail(c->err, "bus.%s: expected tcp://HOST:PORT (PORT 0: any free "
                      "port), got '%s'", key, ep);
  return 0;
}

/* The snapshot stream's default endpoint: next to the monitor one (tcp: the
 * same host, any free port; ipc: the same path with "-snapshots"). */
static void default_snapshots(cpl_scene *s) {
  const char *m = s->bus_monitor;
  if (!m[0]) return;
  if (!strncmp(m, "tcp://", 6))
    snprintf(s->bus_snapshots, sizeof s->bus_snapshots, "%.*s:0",
             (int)(strrchr(m + 6, ':') - m), m);
  else
    snprintf(s->bus_snapshots, sizeof s->bus_snapshots, "%.*s-snapshots",
             (int)sizeof s->bus_snapshots - 16, m);
}

static int read_bus(proto_cfg *root, cpl_scene *s) {
  proto_cfg c;
  s->bus_hwm = 1000;
  s->bus_snapshot_hwm = 2;
  int rc = proto_cfg_child(root, "bus", PROTO_OPTIONAL, &c);
  if (rc != 0) return rc < 0 ? -1 : 0;
  if (proto_cfg_str(&c, "monitor", PROTO_OPTIONAL, s->bus_monitor,
                    sizeof s->bus_monitor) < 0 ||
      proto_cfg_str(&c, "snapshots", PROTO_OPTIONAL, s->bus_snapshots,
                    sizeof s->bus_snapshots) < 0 ||
      proto_cfg_int(&c, "hwm", PROTO_OPTIONAL, 1, 1000000, &s->bus_hwm) < 0 ||
      proto_cfg_int(&c, "snapshot_hwm", PROTO_OPTIONAL, 1, 1000, &s->bus_snapshot_hwm) < 0)
    return -1;
  if (bus_endpoint(&c, "monitor", s->bus_monitor) < 0 ||
      bus_endpoint(&c, "snapshots", s->bus_snapshots) < 0)
    return -1;
  if (s->bus_snapshots[0] && !s->bus_monitor[0])
    return proto_fail(c.err, "bus.snapshots: needs bus.monitor");
  if (!s->bus_snapshots[0]) default_snapshots(s);
  return proto_cfg_end(&c);
}

/* checkpoint: {"every": K, "keep": N} (README "Checkpoints and restart"). */
static int read_checkpoint(proto_cfg *root, cpl_scene *s) {
  proto_cfg c;
  s->checkpoint_every = 0;
  s->checkpoint_keep = 3;
  int rc = proto_cfg_child(root, "checkpoint", PROTO_OPTIONAL, &c);
  if (rc != 0) return rc < 0 ? -1 : 0;
  if (proto_cfg_int(&c, "every", PROTO_REQUIRED, 1, INT64_MAX, &s->checkpoint_every) < 0 ||
      proto_cfg_int(&c, "keep", PROTO_OPTIONAL, 1, 1000, &s->checkpoint_keep) < 0)
    return -1;
  return proto_cfg_end(&c);
}

/* notes: free text for the reader of the scene (why its numbers were
 * chosen); the coupler checks only that it is a string. */
static int read_notes(proto_cfg *root, proto_err *err) {
  const cJSON *n = proto_cfg_raw(root, "notes", PROTO_OPTIONAL);
  if (n && !cJSON_IsString(n))
    return proto_fail(err, "notes: expected a string, got %s",
                      cJSON_IsArray(n) ? "an array" : cJSON_IsObject(n) ? "an object"
                                                                         : "a number or literal");
  return 0;
}

/* security: {"curve": true} (README "Security"). */
static int read_security(proto_cfg *root, cpl_scene *s) {
  proto_cfg c;
  s->curve = 0;
  int rc = proto_cfg_child(root, "security", PROTO_OPTIONAL, &c);
  if (rc != 0) return rc < 0 ? -1 : 0;
  if (proto_cfg_bool(&c, "curve", PROTO_OPTIONAL, &s->curve) < 0) return -1;
  return proto_cfg_end(&c);
}

/* coupling.implicit (Degroote et al. 2009; docs/coupling-schemes.md §3). */
static int read_implicit(proto_cfg *parent, cpl_scene *s) {
  cpl_implicit *im = &s->implicit;
  im->tolerance = 1e-6;
  im->max_iterations = 50;
  im->acceleration = CPL_ACCEL_IQN_ILS;
  im->relaxation = 0.5;
  im->reuse = 8;        /* preCICE: 10 */
  im->max_columns = 40; /* preCICE: 100; fewer keep the least squares cheap */
  im->filter = 1e-2;    /* QR2 limit (preCICE's QR3 default) */
  if (!parent) return 0;
  proto_cfg c;
  int rc = proto_cfg_child(parent, "implicit", PROTO_OPTIONAL, &c);
  if (rc != 0) return rc < 0 ? -1 : 0;
  int accel = 0;
  if (proto_cfg_num(&c, "tolerance", PROTO_OPTIONAL, 1e-15, 1, &im->tolerance) < 0 ||
      proto_cfg_int(&c, "max_iterations", PROTO_OPTIONAL, 1, 100000,
                    &im->max_iterations) < 0 ||
      proto_cfg_enum(&c, "acceleration", PROTO_OPTIONAL, accel_names, &accel) < 0 ||
      proto_cfg_num(&c, "relaxation", PROTO_OPTIONAL, 1e-6, 1, &im->relaxation) < 0 ||
      proto_cfg_int(&c, "reuse", PROTO_OPTIONAL, 0, 1000, &im->reuse) < 0 ||
      proto_cfg_int(&c, "max_columns", PROTO_OPTIONAL, 1, 1000, &im->max_columns) < 0 ||
      proto_cfg_num(&c, "filter", PROTO_OPTIONAL, 0, 1, &im->filter) < 0)
    return -1;
  im->acceleration = (cpl_accel_kind)accel;
  return proto_cfg_end(&c);
}

static int read_coupling(proto_cfg *root, cpl_scene *s) {
  proto_cfg c;
  int scheme = 0;
  s->hello_timeout = 10;
  s->heartbeat_timeout = 10;
  s->handshake_timeout = 60;
  s->step_timeout = 60;
  s->sparse = 1;
  snprintf(s->attach_endpoint, sizeof s->attach_endpoint, "tcp://127.0.0.1:0");
  int rc = proto_cfg_child(root, "coupling", PROTO_OPTIONAL, &c);
  if (rc < 0) return -1;
  if (rc > 0) return read_implicit(NULL, s);
  static const char *const transport_names[] = {"auto", "socket", NULL};
  static const char *const affinity_names[] = {"none", "handoff", NULL};
  int transport = CPL_TRANSPORT_AUTO, affinity = CPL_AFFINITY_NONE;
  if (proto_cfg_enum(&c, "scheme", PROTO_OPTIONAL, scheme_names, &scheme) < 0 ||
      proto_cfg_enum(&c, "transport", PROTO_OPTIONAL, transport_names, &transport) < 0 ||
      proto_cfg_enum(&c, "affinity", PROTO_OPTIONAL, affinity_names, &affinity) < 0 ||
      proto_cfg_num(&c, "hello_timeout", PROTO_OPTIONAL, 0.1, 86400,
                    &s->hello_timeout) < 0 ||
      proto_cfg_num(&c, "heartbeat_timeout", PROTO_OPTIONAL, 2 * PROTO_HEARTBEAT_S, 86400,
                    &s->heartbeat_timeout) < 0 ||
      proto_cfg_num(&c, "handshake_timeout", PROTO_OPTIONAL, 0.1, 86400,
                    &s->handshake_timeout) < 0 ||
      proto_cfg_num(&c, "step_timeout", PROTO_OPTIONAL, 0.1, 86400,
                    &s->step_timeout) < 0 ||
      proto_cfg_bool(&c, "sparse", PROTO_OPTIONAL, &s->sparse) < 0 ||
      proto_cfg_str(&c, "attach_endpoint", PROTO_OPTIONAL, s->attach_endpoint,
                    sizeof s->attach_endpoint) < 0 ||
      read_implicit(&c, s) < 0)
    return -1;
  s->scheme = (cpl_scheme)scheme;
  s->transport = transport == CPL_TRANSPORT_SOCKET ? CPL_TRANSPORT_SOCKET : CPL_TRANSPORT_AUTO;
  s->affinity = affinity == CPL_AFFINITY_HANDOFF ? CPL_AFFINITY_HANDOFF : CPL_AFFINITY_NONE;
  const char *ep = s->attach_endpoint;
  if (strncmp(ep, "tcp://", 6) != 0 || !strrchr(ep + 6, ':'))
    return proto_fail(c.err, "coupling.attach_endpoint: expected tcp://HOST:PORT "
                      "(PORT 0: any free port), got '%s'", ep);
  return proto_cfg_end(&c);
}

/* rim_center: [x, y, z] or [x, y, "auto"] (the height from the settled bed). */
static int read_rim_center(proto_cfg *c, cpl_scenario *sc) {
  static const char *const AUTO = "auto";
  const cJSON *node = cJSON_GetObjectItemCaseSensitive(c->obj, "rim_center");
  const cJSON *z = cJSON_IsArray(node) ? cJSON_GetArrayItem(node, 2) : NULL;
  if (!cJSON_IsString(z))
    return proto_cfg_vec(c, "rim_center", PROTO_OPTIONAL, sc->rim_center, 3, 3, NULL);
  char path[PROTO_PATH_CAP];
  proto_cfg_subpath(c, "rim_center", 2, path, sizeof path);
  if (strcmp(z->valuestring, AUTO) != 0)
    return proto_fail(c->err, "%s: expected a number or \"auto\", got \"%s\"", path,
                      z->valuestring);
  /* x, y as numbers: check them through a copy with z = 0 */
  cJSON *copy = cJSON_Duplicate(node, 1);
  cJSON *wrap = cJSON_CreateObject();
  if (!copy || !wrap) {
    cJSON_Delete(copy);
    cJSON_Delete(wrap);
    return proto_fail(c->err, "out of memory");
  }
  cJSON_ReplaceItemInArray(copy, 2, cJSON_CreateNumber(0));
  cJSON_AddItemToObject(wrap, "rim_center", copy);
  proto_cfg sub;
  int rc = proto_cfg_open(&sub, wrap, c->path, c->err);
  if (rc == 0) rc = proto_cfg_vec(&sub, "rim_center", PROTO_REQUIRED, sc->rim_center, 3, 3, NULL);
  cJSON_Delete(wrap);
  proto_cfg_raw(c, "rim_center", PROTO_OPTIONAL); /* used */
  sc->rim_auto = 1;
  return rc;
}

/* The dbp rig's keys (read in every rig, as the load rig's): the carriage,
 * the resistive force's hold and ramp, the running averages' window. */
static int read_dbp(proto_cfg *c, cpl_scenario *sc, double dt) {
  const int dbp = sc->rig == CPL_RIG_DBP;
  sc->carriage_mass = -1;
  sc->dbp_hold = CPL_DBP_HOLD;
  sc->dbp_window = CPL_DBP_WINDOW;
  if (proto_cfg_num(c, "carriage_mass", PROTO_OPTIONAL, 1e-9, 1e9, &sc->carriage_mass) < 0 ||
      proto_cfg_num(c, "dbp_hold", PROTO_OPTIONAL, 0, 1e6, &sc->dbp_hold) < 0 ||
      proto_cfg_num(c, "dbp_force_start", PROTO_OPTIONAL, -1e9, 1e9,
                    &sc->dbp_force_start) < 0 ||
      proto_cfg_num(c, "dbp_force_rate", dbp ? PROTO_REQUIRED : PROTO_OPTIONAL, -1e9, 1e9,
                    &sc->dbp_force_rate) < 0 ||
      proto_cfg_num(c, "dbp_window", PROTO_OPTIONAL, 1e-12, 1e6, &sc->dbp_window) < 0)
    return -1;
  if (sc->carriage_mass < 0) sc->carriage_mass = sc->rig_mass;
  if (!dbp) return 0;
  if (sc->omega == 0)
    return proto_fail(c->err, "%s.omega: the dbp rig turns the wheel at a fixed omega and "
                      "measures the slip 1 - v / (omega radius): omega must not be 0",
                      c->path);
  if (dt > 0 && sc->dbp_window < dt)
    return proto_fail(c->err, "%s.dbp_window: %g s is shorter than the step time.dt = %g s "
                      "(the running averages need at least one step)", c->path,
                      sc->dbp_window, dt);
  return 0;
}

static int read_tire_travel(proto_cfg *c, cpl_scenario *sc, double dt) {
  static const char *const rigs[] = {"kinematic", "load", "dbp", NULL};
  sc->radius = 0.272; /* 165/65 R13 outer radius (seed 000) */
  sc->slip = 0.05;
  sc->auto_gap = CPL_AUTO_GAP;
  sc->rig_mass = -1;
  int rig = CPL_RIG_KINEMATIC;
  if (read_rim_center(c, sc) < 0 ||
      proto_cfg_num(c, "auto_gap", PROTO_OPTIONAL, 0, 10, &sc->auto_gap) < 0 ||
      proto_cfg_enum(c, "rig", PROTO_OPTIONAL, rigs, &rig) < 0 ||
      proto_cfg_num(c, "rig_mass", PROTO_OPTIONAL, 1e-9, 1e9, &sc->rig_mass) < 0 ||
      proto_cfg_num(c, "rig_damping", PROTO_OPTIONAL, 0, 1e12, &sc->rig_damping) < 0 ||
      proto_cfg_num(c, "sinkage_velocity", PROTO_REQUIRED, 0, 1e3,
                    &sc->sinkage_velocity) < 0 ||
      proto_cfg_num(c, "sinkage_force", PROTO_REQUIRED, 0, 1e9,
                    &sc->sinkage_force) < 0 ||
      proto_cfg_num(c, "sinkage_depth", PROTO_OPTIONAL, 1e-9, 10, &sc->sinkage_depth) < 0 ||
      proto_cfg_num_below(c, "slip", PROTO_OPTIONAL, -1, 1, &sc->slip) < 0 ||
      proto_cfg_num(c, "omega", PROTO_REQUIRED, -1e4, 1e4, &sc->omega) < 0 ||
      proto_cfg_num(c, "spin_up", PROTO_OPTIONAL, 0, 1e3, &sc->spin_up) < 0 ||
      proto_cfg_num(c, "radius", PROTO_OPTIONAL, 1e-6, 1e3, &sc->radius) < 0)
    return -1;
  sc->rig = (cpl_rig)rig;
  if (sc->spin_up > 0 && sc->rig != CPL_RIG_KINEMATIC)
    return proto_fail(c->err, "%s.spin_up: %g s needs rig \"kinematic\" (the load and dbp "
                      "rigs start at omega at once)", c->path, sc->spin_up);
  /* the rig keys are read in either mode (a scene switches with one --set) */
  if (sc->rig_mass < 0) {
    if (sc->rig != CPL_RIG_KINEMATIC && !(sc->sinkage_force > 0))
      return proto_fail(c->err, "%s.rig_mass: the default, sinkage_force / %g, needs "
                        "sinkage_force > 0 (got %g); give rig_mass (kg)", c->path,
                        CPL_STANDARD_GRAVITY, sc->sinkage_force);
    sc->rig_mass = sc->sinkage_force / CPL_STANDARD_GRAVITY;
  }
  return read_dbp(c, sc, dt);
}

static int read_indentation(proto_cfg *c, cpl_scenario *sc) {
  static const char *const profiles[] = {"linear", "quadratic",
                                         "load_hold_unload", "sinusoidal",
                                         "force", NULL};
  int p = 0;
  if (proto_cfg_enum(c, "profile", PROTO_REQUIRED, profiles, &p) < 0) return -1;
  sc->profile = (cpl_profile)p;
  proto_need need_ramp = p == CPL_PROFILE_FORCE || p == CPL_PROFILE_SINUSOIDAL
                             ? PROTO_OPTIONAL
                             : PROTO_REQUIRED;
  if (proto_cfg_num(c, "depth", need_ramp, -1, 1, &sc->depth) < 0 ||
      proto_cfg_num(c, "ramp_time", need_ramp, 1e-12, 1e6, &sc->ramp_time) < 0 ||
      proto_cfg_num(c, "hold_time", p == CPL_PROFILE_LOAD_HOLD_UNLOAD
                                        ? PROTO_REQUIRED : PROTO_OPTIONAL,
                    0, 1e6, &sc->hold_time) < 0 ||
      proto_cfg_num(c, "amplitude", p == CPL_PROFILE_SINUSOIDAL
                                        ? PROTO_REQUIRED : PROTO_OPTIONAL,
                    0, 1, &sc->amplitude) < 0 ||
      proto_cfg_num(c, "frequency", p == CPL_PROFILE_SINUSOIDAL
                                        ? PROTO_REQUIRED : PROTO_OPTIONAL,
                    0, 1e9, &sc->frequency) < 0 ||
      proto_cfg_num(c, "road_mass", p == CPL_PROFILE_FORCE
                                        ? PROTO_REQUIRED : PROTO_OPTIONAL,
                    1e-9, 1e9, &sc->road_mass) < 0 ||
      proto_cfg_num(c, "road_force", p == CPL_PROFILE_FORCE
                                         ? PROTO_REQUIRED : PROTO_OPTIONAL,
                    -1e9, 1e9, &sc->road_force) < 0)
    return -1;
  return 0;
}

/* tire_road's own keys (coupler.h): the road plane, the lugs, the penalty. */
static int read_tire_road(proto_cfg *c, cpl_scenario *sc, cpl_scheme scheme) {
  sc->lug_engage = 1e-3;      /* m: a block takes a lug this far above the road */
  sc->lug_tolerance = 7.5e-3; /* m: half the generated tread's 15 mm groove: the inflated
                                 lug tops bulge by several mm (docs/tire-road.md) */
  sc->road_penalty = 1e5;     /* N/m per node: stiff against the tread's nodes at
                                 the coupling steps of the block rates (docs/tire-road.md) */
  if (proto_cfg_num(c, "road_z", PROTO_OPTIONAL, -1e3, 1e3, &sc->road_z) < 0 ||
      proto_cfg_num(c, "lug_engage", PROTO_OPTIONAL, 0, 1, &sc->lug_engage) < 0 ||
      proto_cfg_num(c, "lug_tolerance", PROTO_OPTIONAL, 1e-9, 1, &sc->lug_tolerance) < 0 ||
      proto_cfg_num(c, "road_penalty", PROTO_OPTIONAL, 0, 1e12, &sc->road_penalty) < 0)
    return -1;
  static const char *const faces[] = {"shaped", "flat", NULL};
  int face = 0; /* shaped: the face's own shape under the block's cells */
  if (proto_cfg_enum(c, "lug_face", PROTO_OPTIONAL, faces, &face) < 0) return -1;
  sc->lug_flat = face == 1;
  if (scheme == CPL_SCHEME_IMPLICIT)
    return proto_fail(c->err, "coupling.scheme: 'implicit' does not iterate the lug blocks "
                      "of tire_road yet; use 'serial' or 'parallel'");
  return 0; /* rim_center[2] "auto": the lowest tread node auto_gap above road_z */
}

static int read_scenario(proto_cfg *root, cpl_scene *s) {
  static const char *const kinds[] = {"none", "tire_travel", "indentation", "tire_road",
                                      NULL};
  proto_cfg c;
  cpl_scenario *sc = &s->scenario;
  memset(sc, 0, sizeof *sc);
  int rc = proto_cfg_child(root, "scenario", PROTO_OPTIONAL, &c);
  if (rc != 0) return rc < 0 ? -1 : 0;
  int kind = 0;
  if (proto_cfg_enum(&c, "kind", PROTO_REQUIRED, kinds, &kind) < 0) return -1;
  sc->kind = (cpl_scenario_kind)kind;
  if (cpl_scenario_rolls(sc->kind) && read_tire_travel(&c, sc, s->dt) < 0) return -1;
  if (kind == CPL_SCN_TIRE_ROAD && read_tire_road(&c, sc, s->scheme) < 0) return -1;
  if (kind == CPL_SCN_INDENTATION && read_indentation(&c, sc) < 0) return -1;
  return proto_cfg_end(&c);
}

/* exec: "name_or_path", or ["launcher", "args"..., "participant"]. */
static int read_exec(const cJSON *exec, cpl_process *p, proto_err *err) {
  if (!exec)
    return proto_fail(err, "processes.%s.exec: required key is missing", p->name);
  const cJSON *one = cJSON_IsString(exec) ? exec : NULL;
  int n = one ? 1 : cJSON_IsArray(exec) ? cJSON_GetArraySize(exec) : 0;
  if (n < 1 || n > CPL_MAX_ARGV)
    return proto_fail(err, "processes.%s.exec: expected the name or path of an "
                      "executable, or a list of 1 to %d strings (a launcher "
                      "prefix, then the participant)", p->name, CPL_MAX_ARGV);
  size_t len = 0;
  for (int i = 0; i < n; i++) {
    const cJSON *a = one ? one : cJSON_GetArrayItem(exec, i);
    if (!cJSON_IsString(a) || !a->valuestring[0] ||
        strlen(a->valuestring) >= CPL_PATH_LEN) {
      if (one)
        return proto_fail(err, "processes.%s.exec: expected the name or path "
                          "of an executable", p->name);
      return proto_fail(err, "processes.%s.exec[%d]: expected a non-empty "
                        "string", p->name, i);
    }
    p->argv[i] = a->valuestring;
    if (len < sizeof p->exec)
      len += (size_t)snprintf(p->exec + len, sizeof p->exec - len, "%s%s",
                              i ? " " : "", a->valuestring);
  }
  p->argc = n;
  return 0;
}

static int read_processes(proto_cfg *root, cpl_scene *s) {
  proto_cfg c;
  if (proto_cfg_child(root, "processes", PROTO_REQUIRED, &c) != 0) return -1;
  for (const cJSON *it = c.obj->child; it; it = it->next) {
    for (int i = 0; i < s->nprocs; i++)
      if (strcmp(s->procs[i].name, it->string) == 0)
        return proto_fail(c.err, "processes.%s: duplicate key (each process "
                          "name may appear once)", it->string);
    if (s->nprocs == CPL_MAX_PROCS)
      return proto_fail(c.err, "processes: more than %d processes", CPL_MAX_PROCS);
    /* the name becomes a routing identity, an HDF5 group, a log file name
     * and a bus topic prefix ("<name>.series"): room for the suffix */
    if (proto_name_check_len(it->string, PROTO_NAME_LEN - 16, PROTO_NAME_PLAIN,
                             "processes: process name", c.err) < 0)
      return -1;
    if (strcmp(it->string, CPL_RESERVED_NAME) == 0)
      return proto_fail(c.err, "processes.%s: the name is reserved for the "
                        "coupler's own output and bus topics", it->string);
    cpl_process *p = &s->procs[s->nprocs++];
    memset(p, 0, sizeof *p);
    snprintf(p->name, sizeof p->name, "%s", it->string);
    proto_cfg sec;
    if (proto_cfg_child(&c, it->string, PROTO_REQUIRED, &sec) != 0) return -1;
    p->section = sec.obj;
    if (read_exec(cJSON_GetObjectItemCaseSensitive(sec.obj, "exec"), p, c.err) < 0)
      return -1;
  }
  if (s->nprocs == 0)
    return proto_fail(c.err, "processes: the scene names no process");
  return 0;
}

int cpl_check_roles(const cpl_scene *s, const proto_role *roles, proto_err *err) {
  int count[PROTO_N_ROLES] = {0};
  char have[512] = "";
  size_t len = 0;
  for (int i = 0; i < s->nprocs; i++) {
    count[roles[i]]++;
    if (len < sizeof have)
      len += (size_t)snprintf(have + len, sizeof have - len, "%s%s (%s)",
                              i ? ", " : "", s->procs[i].name,
                              proto_role_name(roles[i]));
  }
  if (count[PROTO_ROLE_FEM] > 1)
    return proto_fail(err, "processes: %d processes of role fem; a scene has "
                      "one coupled surface, so at most one (processes: %s)",
                      count[PROTO_ROLE_FEM], have);
  if (s->scenario.kind == CPL_SCN_TIRE_TRAVEL &&
      !(count[PROTO_ROLE_DEM] && count[PROTO_ROLE_FEM]))
    return proto_fail(err, "scenario.kind: 'tire_travel' needs a process of "
                      "role dem and one of role fem (processes: %s)", have);
  /* tire_road without a lug process: the fem alone, on a road of its own (fem_server's
   * "road": docs/tire-road.md) */
  if (s->scenario.kind == CPL_SCN_TIRE_ROAD &&
      !(count[PROTO_ROLE_FEM] && !count[PROTO_ROLE_DEM] && !count[PROTO_ROLE_BLOCK]))
    return proto_fail(err, "scenario.kind: 'tire_road' needs one process of role fem and "
                      "any of role lug (none: the fem alone, on its own road), and no dem or "
                      "block (processes: %s)", have);
  if (s->scenario.kind != CPL_SCN_TIRE_ROAD && count[PROTO_ROLE_LUG])
    return proto_fail(err, "processes: role lug serves the lugs of scenario.kind "
                      "'tire_road' only (processes: %s)", have);
  if (s->scenario.kind == CPL_SCN_INDENTATION && !count[PROTO_ROLE_BLOCK])
    return proto_fail(err, "scenario.kind: 'indentation' needs a process of "
                      "role block (processes: %s)", have);
  return 0;
}

int cpl_scene_load(cpl_scene *s, const char *path, int nset,
                   char *const *sets, proto_err *err) {
  memset(s, 0, sizeof *s);
  cJSON *root = proto_json_load(path, err);
  return root ? cpl_scene_from_json(s, root, path, nset, sets, err) : -1;
}

int cpl_scene_from_json(cpl_scene *s, cJSON *json, const char *source,
                        int nset, char *const *sets, proto_err *err) {
  memset(s, 0, sizeof *s);
  snprintf(s->source, sizeof s->source, "%s", source);
  s->root = json;
  for (int i = 0; i < nset; i++)
    if (proto_json_set(s->root, sets[i], err) < 0) return -1;
  proto_cfg root;
  if (proto_cfg_open(&root, s->root, "", err) < 0) return -1;
  if (proto_cfg_str(&root, "name", PROTO_REQUIRED, s->name, sizeof s->name) < 0)
    return -1;
  /* the name goes into the run's directory and temporary paths */
  if (proto_name_check_len(s->name, sizeof s->name, PROTO_NAME_DOTTED, "name",
                           err) < 0)
    return -1;
  if (read_time(&root, s) < 0 || read_output(&root, s) < 0 ||
      read_bus(&root, s) < 0 || read_coupling(&root, s) < 0 ||
      read_scenario(&root, s) < 0 || read_checkpoint(&root, s) < 0 ||
      read_security(&root, s) < 0 || read_notes(&root, err) < 0 ||
      read_processes(&root, s) < 0 ||
      proto_cfg_end(&root) < 0)
    return proto_wrap(err, "%s", source);
  return 0;
}

void cpl_scene_free(cpl_scene *s) {
  cJSON_Delete(s->root);
  s->root = NULL;
}

/* ------------------------------------------------------------------ exec */

static int executable(const char *path) {
  struct stat st;
  return stat(path, &st) == 0 && S_ISREG(st.st_mode) && access(path, X_OK) == 0;
}

/* A path with '/' as given (must be executable), else next to the cosim
 * binary, else on PATH (if search_path). 0 found, -1 not found. */
static int find_exec(const char *name, int search_path, char *out, char *self) {
  if (strchr(name, '/')) {
    if (!executable(name) || !realpath(name, out)) return -1;
    return 0;
  }
  char cand[2 * CPL_PATH_LEN];
  ssize_t n = readlink("/proc/self/exe", self, CPL_PATH_LEN - 1);
  if (n > 0) {
    self[n] = 0;
    char *slash = strrchr(self, '/');
    if (slash) *slash = 0;
    snprintf(cand, sizeof cand, "%s/%s", self, name);
    if (executable(cand)) {
      snprintf(out, CPL_PATH_LEN, "%s", cand);
      return 0;
    }
  }
  const char *path = search_path ? getenv("PATH") : NULL;
  while (path && *path) {
    size_t len = strcspn(path, ":");
    snprintf(cand, sizeof cand, "%.*s/%s", (int)len, path, name);
    if (len && executable(cand)) {
      snprintf(out, CPL_PATH_LEN, "%s", cand);
      return 0;
    }
    path += len + (path[len] == ':');
  }
  return -1;
}

int cpl_resolve_exec(cpl_process *p, proto_err *err) {
  char self[CPL_PATH_LEN] = "";
  const char *first = p->argv[0], *last = p->argv[p->argc - 1];
  const char *key = p->argc > 1 ? "exec[0]" : "exec";
  if (find_exec(first, 1, p->resolved, self) < 0) {
    if (strchr(first, '/'))
      return proto_fail(err, "processes.%s.%s: '%s' is not an executable file",
                        p->name, key, first);
    return proto_fail(err, "processes.%s.%s: '%s' not found (looked in %s and on "
                      "PATH)", p->name, key, first, self);
  }
  if (p->argc == 1) {
    snprintf(p->participant, sizeof p->participant, "%s", p->resolved);
    return 0;
  }
  /* behind a launcher: the participant is resolved if it is ours (next to
   * cosim) or a path; otherwise the launcher finds it (e.g. on its PATH) */
  if (find_exec(last, 0, p->participant, self) < 0) {
    if (strchr(last, '/'))
      return proto_fail(err, "processes.%s.exec[%d]: '%s' is not an executable "
                        "file", p->name, p->argc - 1, last);
    snprintf(p->participant, sizeof p->participant, "%s", last);
  }
  return 0;
}

cJSON *cpl_section_for_participant(const cpl_process *p) {
  cJSON *sec = cJSON_Duplicate(p->section, 1);
  if (sec && p->argc > 1)
    cJSON_ReplaceItemInObjectCaseSensitive(sec, "exec",
                                           cJSON_CreateString(p->argv[p->argc - 1]));
  return sec;
}

/* Runs `participant --check-config - --name NAME` (the last element of exec
 * alone: checking a section needs no launcher) with the section on stdin and
 * returns its verdict; its stderr becomes the error message. */
static int check_one(const cpl_process *p, proto_err *err) {
  cJSON *sec = cpl_section_for_participant(p);
  char *text = sec ? cJSON_PrintUnformatted(sec) : NULL;
  cJSON_Delete(sec);
  int in[2], out[2];
  if (!text || pipe(in) < 0 || pipe(out) < 0) {
    free(text);
    return proto_fail(err, "processes.%s: cannot start the check", p->name);
  }
  pid_t pid = fork();
  if (pid == 0) {
    dup2(in[0], 0);
    dup2(out[1], 2);
    dup2(out[1], 1);
    close(in[1]);
    close(out[0]);
    execlp(p->participant, p->participant, "--check-config", "-", "--name",
           p->name, (char *)NULL);
    _exit(127);
  }
  close(in[0]);
  close(out[1]);
  /* The section is small (kilobytes): one write fits in the pipe. */
  ssize_t w = write(in[1], text, strlen(text));
  (void)w;
  close(in[1]);
  free(text);
  char buf[sizeof err->msg] = {0};
  size_t len = 0;
  ssize_t got;
  while ((got = read(out[0], buf + len, sizeof buf - 1 - len)) > 0) len += (size_t)got;
  close(out[0]);
  int status = 0;
  waitpid(pid, &status, 0);
  if (WIFEXITED(status) && WEXITSTATUS(status) == 0) return 0;
  while (len && (buf[len - 1] == '\n' || buf[len - 1] == ' ')) buf[--len] = 0;
  return proto_fail(err, "%s", len ? buf : "check failed with no message");
}

int cpl_check_processes(cpl_scene *s, proto_err *err) {
  for (int i = 0; i < s->nprocs; i++) {
    if (cpl_resolve_exec(&s->procs[i], err) < 0 ||
        check_one(&s->procs[i], err) < 0)
      return proto_wrap(err, "%s", s->source);
  }
  return 0;
}
