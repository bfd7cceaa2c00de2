/* run.c — one coupled run: the lock on output.dir, a private run directory,
 * keys and sockets (free ports where asked: port 0; CURVE with
 * security.curve), bus, starting the participants, handshake (each process
 * says its role), results.h5 (only once every participant has passed its
 * handshake), a restart's checkpoint, the schedule, the loop (loop.c), and
 * a teardown that leaves no process behind whatever happened. */
#include "runner.h"

#include <errno.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zmq.h>

volatile int cpl_interrupted = 0;

static void on_signal(int sig) { cpl_interrupted = sig; }

/* ---------------------------------------------------------------- setup */

static int last_endpoint(void *socket, char *out, size_t cap) {
  size_t len = cap;
  return zmq_getsockopt(socket, ZMQ_LAST_ENDPOINT, out, &len);
}

/* tcp://HOST:PORT → tcp://HOST:0 (the bus's inner side, any free port). */
static void host_any_port(const char *ep, char *out, size_t cap) {
  const char *colon = strrchr(ep, ':');
  snprintf(out, cap, "%.*s:0", (int)(colon - ep), ep);
}

/* The private run directory (mode 0700): ipc endpoints, key files. */
static int make_run_dir(cpl_runner *r) {
  snprintf(r->run_dir, sizeof r->run_dir, "/tmp/cosim-%s-XXXXXX", r->scene->name);
  if (mkdtemp(r->run_dir)) return 0;
  r->run_dir[0] = 0;
  return proto_fail(&r->err, "cannot create a run directory: %s", strerror(errno));
}

static int setup_sockets(cpl_runner *r) {
  cpl_scene *s = r->scene;
  cpl_bus_eps *eps = &r->bus_eps;
  if (make_run_dir(r) < 0) return -1;
  r->ctx = zmq_ctx_new();
  if (s->curve) { /* the ZAP handler first: it must answer the first handshake */
    r->zap = cpl_zap_start(r->ctx, r->run_dir, s, &r->err);
    if (!r->zap) return -1;
  }
  r->router = zmq_socket(r->ctx, ZMQ_ROUTER);
  proto_socket_limits(r->router);
  int on = 1, linger = 0;
  zmq_setsockopt(r->router, ZMQ_ROUTER_MANDATORY, &on, sizeof on);
  zmq_setsockopt(r->router, ZMQ_LINGER, &linger, sizeof linger);
  if (r->zap &&
      proto_curve_server(r->router, cpl_zap_secret(r->zap), CPL_ZAP_CONTROL, &r->err) < 0)
    return -1;
  /* the bus's publishing side takes no outside publisher: ipc in the
   * private directory, or (other hosts) tcp with CURVE */
  if (r->opts->attach) {
    snprintf(r->ctl_endpoint, sizeof r->ctl_endpoint, "%s", s->attach_endpoint);
    if (r->zap) host_any_port(s->attach_endpoint, eps->inner, sizeof eps->inner);
  } else {
    snprintf(r->ctl_endpoint, sizeof r->ctl_endpoint, "ipc://%s/control", r->run_dir);
  }
  if (!eps->inner[0]) snprintf(eps->inner, sizeof eps->inner, "ipc://%s/bus", r->run_dir);
  if (zmq_bind(r->router, r->ctl_endpoint) != 0)
    return proto_fail(&r->err, "cannot bind %s%s: %s", r->ctl_endpoint,
                      r->opts->attach ? " (coupling.attach_endpoint)" : "",
                      zmq_strerror(errno));
  last_endpoint(r->router, r->ctl_endpoint, sizeof r->ctl_endpoint);
  if (s->bus_monitor[0]) {
    snprintf(eps->monitor, sizeof eps->monitor, "%s", s->bus_monitor);
    snprintf(eps->snapshots, sizeof eps->snapshots, "%s", s->bus_snapshots);
    r->bus = cpl_bus_start(r->ctx, eps, (int)s->bus_hwm, (int)s->bus_snapshot_hwm,
                           r->zap, &r->err);
    if (!r->bus) return -1;
  } else {
    eps->inner[0] = 0;
  }
  return 0;
}

/* output.dir/endpoints.json: where the control socket and the monitor bus
 * actually are (ports chosen at bind); with CURVE, the coupler's public key
 * and the monitors' key file. */
static int write_endpoints(cpl_runner *r) {
  const cpl_bus_eps *eps = &r->bus_eps;
  cJSON *o = cJSON_CreateObject();
  cJSON_AddStringToObject(o, "control", r->ctl_endpoint);
  cJSON_AddStringToObject(o, "bus_monitor", eps->monitor);
  cJSON_AddStringToObject(o, "bus_snapshots", eps->snapshots);
  cJSON_AddStringToObject(o, "bus_inner", eps->inner);
  cJSON_AddNumberToObject(o, "pid", (double)getpid());
  if (r->zap) {
    cJSON_AddStringToObject(o, "curve_server_public", cpl_zap_public(r->zap));
    cJSON_AddStringToObject(o, "monitor_key_file", cpl_zap_monitor_file(r->zap));
  }
  char *text = cJSON_Print(o);
  cJSON_Delete(o);
  char path[CPL_PATH_LEN + 32];
  snprintf(path, sizeof path, "%s/%s", r->scene->output_dir, CPL_ENDPOINTS_FILE);
  FILE *f = text ? fopen(path, "w") : NULL;
  int rc = f && fprintf(f, "%s\n", text) > 0 ? 0 : -1;
  if (f && fclose(f) != 0) rc = -1;
  free(text);
  if (rc < 0) {
    r->exit_code = CPL_EXIT_OUTPUT;
    return proto_fail(&r->err, "cannot write %s: %s (errno %d)", path, strerror(errno), errno);
  }
  if (eps->monitor[0] && !r->opts->quiet)
    printf("cosim: monitor bus at %s, snapshots at %s (also in %s)\n", eps->monitor,
           eps->snapshots, path);
  fflush(stdout);
  return 0;
}

static int start_children(cpl_runner *r) {
  char logs[CPL_PATH_LEN + 8];
  snprintf(logs, sizeof logs, "%s/logs", r->scene->output_dir);
  mkdir(logs, 0755);
  for (int i = 0; i < r->n; i++) {
    cpl_process *p = r->peers[i].proc;
    if (cpl_resolve_exec(p, &r->err) < 0) return -1;
    const char *argv[CPL_MAX_ARGV];
    for (int a = 0; a < p->argc; a++) argv[a] = p->argv[a];
    argv[0] = p->resolved;
    argv[p->argc - 1] = p->participant;
    char log[2 * CPL_PATH_LEN];
    snprintf(log, sizeof log, "%s/%s.log", logs, p->name);
    if (cpl_spawn(&r->children[r->nchildren], p->name, p->argc, argv,
                  r->ctl_endpoint, log, cpl_zap_key_file(r->zap, i), &r->affinity,
                  &r->err) < 0)
      return -1;
    r->nchildren++;
  }
  return 0;
}

/* How to start each participant by hand (--attach), with its key file. */
static void print_attach(const cpl_runner *r) {
  fprintf(stderr, "cosim: waiting %g s (coupling.hello_timeout) for participants; "
          "start each with\n", r->scene->hello_timeout);
  for (int i = 0; i < r->n; i++) {
    const char *key = cpl_zap_key_file(r->zap, i);
    fprintf(stderr, "  %s%s%s%s --endpoint %s --name %s\n", key ? PROTO_ENV_CURVE "=" : "",
            key ? key : "", key ? " " : "", r->peers[i].proc->exec, r->ctl_endpoint,
            r->peers[i].proc->name);
  }
  if (r->zap)
    fprintf(stderr, "cosim: CURVE: the coupler's public key is %s; each participant "
            "needs its key file (copy it to the participant's host, mode 0600; "
            "it is removed when the run ends). Monitors: %s\n",
            cpl_zap_public(r->zap), cpl_zap_monitor_file(r->zap));
}

static int wait_hellos(cpl_runner *r) {
  if (r->opts->attach) print_attach(r);
  int missing = r->n;
  const double until = cpl_watch(r) + r->scene->hello_timeout;
  proto_msg m = {0};
  while (missing > 0) {
    int from = -1;
    double left = until - cpl_watch(r);
    if (cpl_receive(r, -1, left > 0 ? left : 0, "hello_timeout", &m, &from) < 0) {
      if (strstr(r->err.msg, "did not answer")) {
        char names[256] = {0};
        for (int i = 0; i < r->n; i++)
          if (!r->peers[i].connected) {
            strncat(names, " ", sizeof names - strlen(names) - 1);
            strncat(names, r->peers[i].proc->name, sizeof names - strlen(names) - 1);
            if (r->failed_peer < 0) r->failed_peer = i;
          }
        proto_fail(&r->err, "no hello within %g s (coupling.hello_timeout) from:%s",
                   r->scene->hello_timeout, names);
      }
      proto_msg_free(&m);
      return -1;
    }
    if (cpl_take_hello(r, from, &m) < 0) {
      proto_msg_free(&m);
      return -1;
    }
    missing--;
  }
  proto_msg_free(&m);
  proto_role roles[CPL_MAX_PROCS];
  r->draft->fem = -1;
  for (int i = 0; i < r->n; i++) {
    roles[i] = r->peers[i].role;
    r->peers[i].rank = r->draft->n_of_role[roles[i]]++;
    if (roles[i] == PROTO_ROLE_FEM) r->draft->fem = i;
  }
  return cpl_check_roles(r->scene, roles, &r->err);
}

static void fill_run_header(cpl_runner *r, proto_msg *w, const cpl_process *p) {
  cpl_scene *s = r->scene;
  cJSON *h = proto_msg_header(w);
  cJSON_AddItemToObject(h, PROTO_H_CONFIG, cpl_section_for_participant(p));
  cJSON *run = cJSON_AddObjectToObject(h, PROTO_H_RUN);
  cJSON_AddStringToObject(run, "name", s->name);
  cJSON_AddNumberToObject(run, PROTO_H_DT, s->dt);
  cJSON_AddNumberToObject(run, "t_end", s->t_end);
  cJSON_AddNumberToObject(run, "n_steps", (double)s->n_steps);
  cJSON_AddNumberToObject(run, "output_every", (double)s->output_every);
  cJSON_AddStringToObject(run, "output_dir", s->output_dir);
  cJSON_AddStringToObject(run, "bus", r->bus_eps.inner);
  cJSON_AddNumberToObject(run, "deadline_s", s->step_timeout);
  cJSON_AddStringToObject(run, "scheme", cpl_scheme_name(s->scheme));
  cJSON_AddBoolToObject(run, PROTO_H_ROLLBACK, s->scheme == CPL_SCHEME_IMPLICIT);
  cJSON_AddNumberToObject(run, PROTO_H_RESTART_STEP, (double)r->k0);
  /* a launched participant watches its launcher instead (0: no limit); one
   * started by hand waits for others' steps too: be generous before giving
   * up (implicit: every iteration of a step) */
  double per_step = s->step_timeout * (r->n + 1) *
                    (s->scheme == CPL_SCHEME_IMPLICIT ? (double)s->implicit.max_iterations : 1);
  cJSON_AddNumberToObject(run, "idle_timeout_s",
                          r->opts->attach ? per_step + s->handshake_timeout : 0);
}

/* Keeps the fem's surface for the coupling (world = rim frame at t = 0). */
static int take_surface(cpl_runner *r, const proto_msg *ready) {
  const proto_array *x0 = proto_msg_find(ready, PROTO_A_SURFACE_X0);
  const proto_array *tri = proto_msg_find(ready, PROTO_A_SURFACE_TRI);
  cpl_surface *s = &r->draft->surf;
  s->n_nodes = x0->shape[0];
  s->n_tris = tri->shape[0];
  size_t nb = (size_t)s->n_nodes * 3 * sizeof(double);
  s->x0 = malloc(nb + 1);
  s->tri = malloc(tri->nbytes + 1);
  if (!s->x0 || !s->tri) return proto_fail(&r->err, "out of memory for the surface");
  memcpy(s->x0, x0->data, nb);
  memcpy(s->tri, tri->data, tri->nbytes);
  const int32_t *t = s->tri;
  for (int64_t i = 0; i < 3 * s->n_tris; i++)
    if (t[i] < 0 || t[i] >= s->n_nodes)
      return proto_fail(&r->err, "participant '%s': surface_tri refers to node %d "
                        "of %lld", r->peers[r->plan->fem].proc->name, t[i],
                        (long long)s->n_nodes);
  return 0;
}

/* The transport (PROTOCOL.md "Shared memory"): a participant on this host
 * (its hello's host and boot id) is offered our segment in its welcome,
 * unless coupling.transport is "socket"; we make a reader for the segment
 * its ready announces. Anything that fails keeps the socket, and says why. */
static void shm_offer(cpl_runner *r, cpl_peer *p, proto_msg *w) {
  if (r->scene->transport == CPL_TRANSPORT_SOCKET) {
    snprintf(p->shm_why, sizeof p->shm_why, "coupling.transport is \"socket\"");
    return;
  }
  if (!p->same_host) {
    snprintf(p->shm_why, sizeof p->shm_why, "another host, or a participant that "
             "cannot map segments (its hello has no matching host)");
    return;
  }
  proto_err why = {{0}};
  p->shm_out = proto_shm_writer(PROTO_SHM_INITIAL_BYTES, &why);
  p->shm_in = p->shm_out ? proto_shm_reader() : NULL;
  if (!p->shm_in || proto_shm_announce(p->shm_out, proto_msg_header(w)) < 0) {
    snprintf(p->shm_why, sizeof p->shm_why, "%s", why.msg[0] ? why.msg : "out of memory");
    proto_shm_free(p->shm_out);
    proto_shm_free(p->shm_in);
    p->shm_out = p->shm_in = NULL;
  }
}

/* The ready's answer to the offer: shm when it took it and its segment is
 * mapped (cpl_receive mapped the one the ready announced), else the socket. */
static void shm_settle(cpl_peer *p) {
  const cJSON *t = cJSON_GetObjectItemCaseSensitive(p->reply.header, PROTO_H_TRANSPORT);
  const cJSON *e = cJSON_GetObjectItemCaseSensitive(p->reply.header, PROTO_H_SHM_ERROR);
  p->shm_on = p->shm_out && proto_shm_attached(p->shm_in) && cJSON_IsString(t) &&
              strcmp(t->valuestring, "shm") == 0;
  if (p->shm_on) { /* it maps our segment: post whole messages there */
    proto_shm_ring(p->shm_out);
    return;
  }
  if (p->shm_out) {
    char text[sizeof p->shm_why];
    cpl_printable(text, sizeof text, cJSON_IsString(e) ? e->valuestring
                                     : "it did not take the offer");
    snprintf(p->shm_why, sizeof p->shm_why, "%s", text);
  }
  proto_shm_free(p->shm_out);
  proto_shm_free(p->shm_in);
  p->shm_out = p->shm_in = NULL;
}

static int welcome_one(cpl_runner *r, int i) {
  cpl_peer *p = &r->peers[i];
  proto_msg w = {0};
  proto_msg_reset(&w, p->proc->name, proto_msg_type(PROTO_MSG_WELCOME), 0, 0);
  fill_run_header(r, &w, p->proc);
  shm_offer(r, p, &w);
  if (p->role == PROTO_ROLE_DEM && r->plan->surf.n_nodes > 0) {
    proto_msg_add_f8(&w, PROTO_A_SURFACE_X0, r->plan->surf.n_nodes, 3,
                     r->data.fields[CPL_F_SURF_X].cur);
    proto_msg_add_i4(&w, PROTO_A_SURFACE_TRI, r->plan->surf.n_tris, 3, r->plan->surf.tri);
  }
  /* the coupler's copy of the conversation's dims (n, m; surface or not) */
  int rc = proto_role_check(p->role, PROTO_MSG_WELCOME, &w, &p->dims, &r->err);
  if (rc == 0) rc = cpl_send(r, i, &w);
  proto_msg_free(&w);
  int from;
  if (rc == 0)
    rc = cpl_receive(r, i, r->scene->handshake_timeout, "handshake_timeout", &p->reply,
                     &from);
  p->initialized = rc == 0;
  if (rc == 0 && p->shown >= 0 && r->opts->progress && !r->opts->quiet)
    fprintf(stderr, "\r  %s: ready%*s\n", p->proc->name, 40, "");
  if (rc == 0 && strcmp(p->reply.type, proto_msg_type(PROTO_MSG_READY)) != 0)
    rc = proto_fail(&r->err, "participant '%s': expected 'ready', got '%s'",
                    p->proc->name, p->reply.type);
  if (rc == 0 &&
      proto_role_check(p->role, PROTO_MSG_READY, &p->reply, &p->dims, &r->err) < 0)
    rc = proto_wrap(&r->err, "participant '%s'", p->proc->name);
  p->rollback = cJSON_IsTrue(cJSON_GetObjectItemCaseSensitive(p->reply.header,
                                                              PROTO_H_ROLLBACK));
  if (rc == 0) shm_settle(p);
  if (rc == 0 && i == r->plan->fem) rc = take_surface(r, &p->reply);
  if (rc < 0 && r->failed_peer < 0) r->failed_peer = i;
  return rc;
}

/* rim_center [x, y, "auto"]: the lowest tread node auto_gap above the
 * highest bed_top the dem processes report after settling (where the parked
 * tread, lowered, would first touch one of their grains). */
static int place_rim(cpl_runner *r) {
  const cpl_scenario *sc = &r->scene->scenario;
  double top = -INFINITY;
  for (int i = 0; i < r->n; i++) {
    if (r->peers[i].role != PROTO_ROLE_DEM) continue;
    const cJSON *t = cJSON_GetObjectItemCaseSensitive(r->peers[i].reply.header, PROTO_H_BED_TOP);
    if (!cJSON_IsNumber(t) || !isfinite(t->valuedouble)) {
      r->failed_peer = i;
      return proto_fail(&r->err, "scenario.rim_center[2]: \"auto\" needs the settled bed's "
                        "top from every dem process, and participant '%s' (%s) reported no "
                        "%s in its ready (no grains under the tread's footprint, or a dem "
                        "that does not measure it); give the height as a number",
                        r->peers[i].proc->name, r->peers[i].proc->exec, PROTO_H_BED_TOP);
    }
    top = fmax(top, t->valuedouble);
  }
  cpl_rim_place(&r->data.rim, r->plan->surf.x0, r->plan->surf.n_nodes, top + sc->auto_gap);
  if (!r->opts->quiet)
    fprintf(stderr, "cosim: rim_center \"auto\": bed top %.10g m, rim height %.10g m (lowest "
            "tread node %g m above the bed)\n", top, r->data.rim.c[2], sc->auto_gap);
  cpl_fields_from_rim(r);
  return 0;
}

/* The fem first (its surface goes to the dem processes), then the rest;
 * an "auto" rim waits parked above everything until the beds are settled. */
static int welcome_all(cpl_runner *r) {
  const int rim_auto = r->scene->scenario.kind == CPL_SCN_TIRE_TRAVEL &&
                       r->scene->scenario.rim_auto && r->plan->fem >= 0;
  if (r->plan->fem >= 0 && welcome_one(r, r->plan->fem) < 0) return -1;
  for (int i = 0; i < r->n; i++) /* their grids go onto the lug faces */
    if (r->peers[i].role == PROTO_ROLE_LUG && welcome_one(r, i) < 0) return -1;
  if (cpl_lugs_setup(r) < 0) return -1;
  if (cpl_fields_init(r, r->plan->surf.n_nodes, &r->err) < 0) return -1;
  const cpl_scenario *sc = &r->scene->scenario;
  if (sc->kind == CPL_SCN_TIRE_ROAD && sc->rim_auto) /* above the road plane */
    cpl_rim_place(&r->data.rim, r->plan->surf.x0, r->plan->surf.n_nodes,
                  sc->road_z + sc->auto_gap);
  if (rim_auto) /* out of the way while the beds settle */
    cpl_rim_place(&r->data.rim, r->plan->surf.x0, r->plan->surf.n_nodes, CPL_AUTO_PARK_Z);
  cpl_fields_from_rim(r);
  for (int i = 0; i < r->n; i++)
    if (i != r->plan->fem && r->peers[i].role != PROTO_ROLE_LUG && welcome_one(r, i) < 0)
      return -1;
  return rim_auto ? place_rim(r) : 0;
}

/* The implicit scheme repeats steps: every process must roll back. */
static int check_rollback(cpl_runner *r) {
  if (r->scene->scheme != CPL_SCHEME_IMPLICIT) return 0;
  for (int i = 0; i < r->n; i++)
    if (!r->peers[i].rollback)
      return proto_fail(&r->err, "coupling.scheme: 'implicit' repeats steps, "
                        "but participant '%s' (%s) cannot roll back (its ready "
                        "says rollback: false; it has no state_save/state_load)",
                        r->peers[i].proc->name, r->peers[i].proc->exec);
  return 0;
}

/* results.h5, once every participant has passed its handshake (README
 * "Output"): a new file, or the one a restart continues; the participants'
 * datasets from their ready messages; the endpoints; a reserve for closing
 * it on a full disk. */
static int open_output(cpl_runner *r) {
  cpl_scene *s = r->scene;
  const int continues = r->ckpt && !r->opts->branch; /* a branch starts new results */
  if (!continues && cpl_checkpoint_clear(s->output_dir, &r->err) < 0) return -1;
  r->out = cpl_output_open(s, continues ? r->k0 : -1, &r->err);
  int rc = r->out ? 0 : -1;
  for (int i = 0; i < r->n && rc == 0; i++)
    if (cpl_output_participant(r->out, r->peers[i].proc->name, &r->peers[i].reply,
                               &r->err) < 0) {
      if (!cpl_output_io_failed(r->out)) r->failed_peer = i;
      rc = proto_wrap(&r->err, "participant '%s'", r->peers[i].proc->name);
    }
  if (rc == 0) rc = cpl_output_endpoints(r->out, r->ctl_endpoint, r->bus_eps.monitor, &r->err);
  if (rc == 0) rc = cpl_output_flush(r->out, &r->err);
  if (rc == 0)
    rc = cpl_reserve_make(s->output_dir, cpl_output_pending_bytes(r->out), &r->err);
  if (rc < 0 && r->failed_peer < 0) r->exit_code = CPL_EXIT_OUTPUT;
  return rc;
}

/* A restart restores the coupler and every participant before results.h5
 * is touched: a checkpoint that does not fit this run, or a state a
 * participant refuses, leaves the earlier results as they were. The ready
 * messages open_output declares the datasets from are kept aside meanwhile
 * (the replies to `restore` land in the same slots). */
static int restore(cpl_runner *r) {
  if (!r->ckpt) return 0;
  proto_msg *ready = calloc((size_t)r->n, sizeof *ready);
  if (!ready) return proto_fail(&r->err, "out of memory");
  for (int i = 0; i < r->n; i++) {
    ready[i] = r->peers[i].reply;
    memset(&r->peers[i].reply, 0, sizeof r->peers[i].reply);
  }
  int rc = cpl_checkpoint_restore(r);
  for (int i = 0; i < r->n; i++) {
    proto_msg_free(&r->peers[i].reply);
    r->peers[i].reply = ready[i];
  }
  free(ready);
  return rc;
}

/* --------------------------------------------------------------- teardown */

static void say_stop(cpl_runner *r) {
  proto_msg m = {0}, reply = {0};
  for (int i = 0; i < r->n; i++) {
    if (r->peers[i].stopped || !r->peers[i].connected) continue;
    proto_msg_reset(&m, r->peers[i].proc->name, proto_msg_type(PROTO_MSG_STOP), 0, 0);
    proto_err ignore;
    if (proto_send_to(r->router, r->peers[i].proc->name, &m, &ignore) == 0) {
      /* wait briefly for the bye; the process table is the final judge */
      double until = proto_now() + 2.0;
      proto_shm *bell = r->peers[i].shm_on ? r->peers[i].shm_in : NULL;
      int got;
      while (proto_now() < until && (got = proto_wait_in(r->router, &bell, 1, 100, 0)) > 0) {
        char id[PROTO_NAME_LEN];
        snprintf(id, sizeof id, "%s", r->peers[i].proc->name); /* posted: from it */
        if (proto_recv_found(r->router, got, &bell, &reply, id, NULL, NULL, &ignore) == 0 &&
            strcmp(id, r->peers[i].proc->name) == 0 &&
            strcmp(reply.type, proto_msg_type(PROTO_MSG_BYE)) == 0)
          break;
      }
    }
    r->peers[i].stopped = 1;
  }
  proto_msg_free(&m);
  proto_msg_free(&reply);
}

static void remove_run_dir(cpl_runner *r) {
  if (!r->run_dir[0]) return;
  static const char *const files[] = {"control", "bus"};
  char path[CPL_PATH_LEN + 16];
  for (int i = 0; i < 2; i++) {
    snprintf(path, sizeof path, "%s/%s", r->run_dir, files[i]);
    unlink(path);
  }
  rmdir(r->run_dir);
}

static void teardown(cpl_runner *r, int ok) {
  if (ok) say_stop(r);
  cpl_stop_all(r->children, r->nchildren, ok ? 3.0 : 0.5);
  for (int i = 0; i < r->n; i++) proto_msg_free(&r->peers[i].reply);
  proto_msg_free(&r->inbox);
  for (int i = 0; i < r->n; i++) { /* after every message that may point into them */
    proto_shm_bells(r->peers[i].shm_out, &r->peers[i].shm_sent, &r->peers[i].shm_posted);
    proto_shm_free(r->peers[i].shm_out);
    proto_shm_free(r->peers[i].shm_in);
    r->peers[i].shm_out = r->peers[i].shm_in = NULL;
  }
  cpl_bus_stop(r->bus);
  if (r->router) zmq_close(r->router);
  cpl_zap_stop(r->zap); /* removes the key files */
  if (r->ctx) zmq_ctx_term(r->ctx);
  remove_run_dir(r);
  free(r->plan->surf.x0);
  free(r->plan->surf.tri);
  cpl_fields_free(r);
  cpl_accel_free(r->accel);
  free(r->data.xi), free(r->data.xt), free(r->data.x_start), free(r->data.v_dem), free(r->data.f_fem),
      free(r->data.carry);
  cpl_checkpoint_free(r->ckpt);
}

static void install_signals(void) {
  struct sigaction sa;
  memset(&sa, 0, sizeof sa);
  sa.sa_handler = on_signal;
  sigaction(SIGINT, &sa, NULL);
  sigaction(SIGTERM, &sa, NULL);
  sigaction(SIGHUP, &sa, NULL);
  signal(SIGPIPE, SIG_IGN);
}

/* A branch writes a new run: not into the directory of the checkpoint it
 * starts from, whose run (and checkpoints) it would replace. */
static int branch_target(const char *ckpt, const char *output_dir, proto_err *err) {
  if (strcmp(ckpt, "latest") == 0)
    return proto_fail(err, "--branch latest: a branch needs the checkpoint's file "
                      "(latest is in output.dir, which the branch writes anew)");
  char dir[CPL_PATH_LEN];
  snprintf(dir, sizeof dir, "%s", ckpt);
  char *slash = strrchr(dir, '/');
  if (slash) *slash = 0;
  else snprintf(dir, sizeof dir, ".");
  struct stat a, b;
  if (stat(dir[0] ? dir : "/", &a) == 0 && stat(output_dir, &b) == 0 && a.st_dev == b.st_dev &&
      a.st_ino == b.st_ino)
    return proto_fail(err, "--branch %s: output.dir '%s' is the checkpoint's own "
                      "directory; a branch is a new run: give it another output.dir",
                      ckpt, output_dir);
  return 0;
}

/* Before anything in output.dir is touched: its lock, the kept-results
 * rule, the checkpoint to continue from (a bad one: exit 1, nothing
 * started). */
static int claim_output_dir(cpl_runner *r) {
  cpl_scene *s = r->scene;
  r->lock_fd = cpl_outdir_lock(s->output_dir, &r->err);
  if (r->lock_fd < 0) return -1;
  if (r->opts->branch && branch_target(r->opts->restart, s->output_dir, &r->err) < 0)
    return -1;
  if (r->opts->restart) {
    r->ckpt = cpl_checkpoint_read(r->opts->restart, s, r->opts->branch, &r->err);
    if (!r->ckpt) return -1;
    r->k0 = cpl_checkpoint_step(r->ckpt);
    if (r->k0 >= s->n_steps)
      return proto_fail(&r->err, "--restart: the checkpoint is of step %lld, but the "
                        "scene ends at step %lld (time.end = %g s)", (long long)r->k0,
                        (long long)s->n_steps, s->t_end);
  }
  return cpl_outdir_results(s->output_dir, r->ckpt && !r->opts->branch, r->opts->overwrite,
                            &r->err);
}

static int prepare(cpl_runner *r) {
  int nrows;
  const proto_array_spec *table = proto_role_table(&nrows);
  int rc = cpl_contract_build(&r->draft->contract, table, nrows, &r->err);
  if (rc == 0 && !r->opts->attach)
    for (int i = 0; i < r->n && rc == 0; i++)
      rc = cpl_resolve_exec(&r->scene->procs[i], &r->err);
  if (rc == 0) rc = claim_output_dir(r);
  if (rc == 0) rc = setup_sockets(r);
  if (rc == 0) rc = write_endpoints(r);
  if (rc == 0) cpl_affinity_plan(r->scene, r->opts->attach, &r->affinity);
  if (rc == 0 && !r->opts->attach) rc = start_children(r);
  if (rc == 0) rc = wait_hellos(r);
  if (rc == 0) rc = welcome_all(r);
  if (rc == 0) rc = check_rollback(r);
  if (rc == 0) rc = cpl_scheme_init(r);
  if (rc == 0) rc = restore(r);
  if (rc == 0) rc = open_output(r);
  if (rc == 0) {
    cpl_schedule_build(r->draft, r->peers, r->n, r->scene->scheme);
    r->draft = NULL; /* sealed: from here on the plan is read-only */
    if (!r->opts->quiet) cpl_schedule_print(r, stdout);
    fflush(stdout);
    r->timing = cpl_timing_create(r);
    if (!r->timing) rc = proto_fail(&r->err, "out of memory (timing)");
  }
  return rc;
}

/* The results are closed complete even on a full disk: after a write error
 * the reserve is freed first. */
static int close_output(cpl_runner *r, int *exit_code) {
  cpl_scene *s = r->scene;
  if (!r->out) return 0;
  int failed = cpl_output_io_failed(r->out);
  cpl_reserve_release(s->output_dir);
  proto_err err = {{0}};
  int rc = cpl_output_close(r->out, &err);
  r->out = NULL;
  if (rc < 0 && !failed) {
    fprintf(stderr, "cosim: output error: %s\n", err.msg);
    *exit_code = CPL_EXIT_OUTPUT;
  }
  return rc;
}

int cpl_run(cpl_scene *s, const cpl_run_opts *opts) {
  cpl_runner *r = calloc(1, sizeof *r);
  cpl_plan *plan = calloc(1, sizeof *plan);
  if (!r || !plan) {
    free(r);
    free(plan);
    return CPL_EXIT_OUTPUT;
  }
  r->plan = r->draft = plan;
  r->scene = s;
  r->opts = opts;
  r->failed_peer = -1;
  plan->fem = -1;
  r->lock_fd = -1;
  r->n = s->nprocs;
  r->watch_wall = proto_now();
  for (int i = 0; i < r->n; i++) r->peers[i].proc = &s->procs[i];
  install_signals();
  cpl_rim_init(&r->data.rim, &s->scenario);
  r->data.road.a = s->scenario.kind == CPL_SCN_INDENTATION && s->scenario.profile == CPL_PROFILE_FORCE
                  ? s->scenario.road_force / s->scenario.road_mass
                  : 0;
  r->wall_start = proto_now();
  int rc = prepare(r);
  if (rc == 0) cpl_affinity_pin_self(&r->affinity); /* the children keep every core */
  if (rc == 0) rc = cpl_step_loop(r);
  int exit_code = 0;
  if (rc < 0) {
    exit_code = cpl_interrupted        ? CPL_EXIT_INTERRUPTED
                : r->out && cpl_output_io_failed(r->out) ? CPL_EXIT_OUTPUT
                : r->exit_code         ? r->exit_code
                : r->failed_peer >= 0  ? CPL_EXIT_PARTICIPANT
                                       : CPL_EXIT_USAGE;
    char msg[sizeof r->err.msg]; /* parts of it may come from the wire or a log */
    cpl_printable(msg, sizeof msg, r->err.msg);
    fprintf(stderr, "\ncosim: run '%s' failed: %s%s\n", s->name,
            exit_code == CPL_EXIT_OUTPUT ? "output error: " : "", msg);
    if (r->failed_peer >= 0 && exit_code == CPL_EXIT_PARTICIPANT)
      fprintf(stderr, "cosim: failed participant: %s\n",
                r->peers[r->failed_peer].proc->name);
  }
  teardown(r, rc == 0);
  char summary[2048] = {0};
  int had_output = r->out != NULL;
  if (r->out) cpl_output_summary(r->out, summary, sizeof summary);
  close_output(r, &exit_code);
  cpl_outdir_unlock(r->lock_fd);
  if (exit_code == 0) {
    printf("cosim: run '%s' finished: %lld steps, t = %g s, %.2f s wall\n",
           s->name, (long long)s->n_steps, (double)s->n_steps * s->dt,
           proto_now() - r->wall_start);
    if (!opts->quiet) cpl_timing_print(r, stdout);
    if (!opts->quiet) cpl_sparse_print(r, stdout);
    printf("results: %s/%s (logs in %s/logs)\n%s", s->output_dir, CPL_RESULTS_FILE,
           s->output_dir, summary);
  } else if (had_output) {
    fprintf(stderr, "cosim: what was written so far is in %s/%s\n", s->output_dir,
            CPL_RESULTS_FILE);
  }
  cpl_timing_free(r->timing);
  cpl_lugs_teardown(plan, &r->data);
  free(r);
  free(plan);
  return exit_code;
}
