/* run.c — one coupled run: private run directory, sockets (free ports where
 * asked: port 0), bus, starting the participants, handshake (each process
 * says its role), the schedule, the loop (loop.c), and a teardown that
 * leaves no process behind whatever happened. */
#include "run.h"

#include <errno.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zmq.h>

volatile int cpl_interrupted = 0;

static void on_signal(int sig) { cpl_interrupted = sig; }

static int peer_of(const cpl_runner *r, const char *identity) {
  for (int i = 0; i < r->n; i++)
    if (strcmp(r->peers[i].proc->name, identity) == 0) return i;
  return -1;
}

/* A child exited unexpectedly: say who, how, and what its log says. */
static int report_exit(cpl_runner *r, int c) {
  char tail[700];
  cpl_child_tail(&r->children[c], tail, sizeof tail, 8);
  for (int i = 0; i < r->n; i++)
    if (strcmp(r->peers[i].proc->name, r->children[c].name) == 0) {
      r->failed_peer = i;
      r->peers[i].stopped = 1;
    }
  return proto_fail(&r->err, "participant '%s' (%s, pid %d) %s; its log %s "
                    "ends with:\n%s", r->children[c].name, r->children[c].exec,
                    (int)r->children[c].pid, r->children[c].how,
                    r->children[c].log_path, tail[0] ? tail : "(empty)");
}

static int check_children(cpl_runner *r) {
  for (int c = 0; c < r->nchildren; c++)
    if (cpl_child_poll(&r->children[c])) return report_exit(r, c);
  return 0;
}

int cpl_send(cpl_runner *r, int peer, const proto_msg *m) {
  if (proto_send_to(r->router, r->peers[peer].proc->name, m, &r->err) == 0)
    return 0;
  r->failed_peer = peer;
  return -1;
}

static int handle_error_reply(cpl_runner *r, int from, const proto_msg *m) {
  const cJSON *msg = cJSON_GetObjectItemCaseSensitive(m->header, PROTO_H_MESSAGE);
  r->failed_peer = from;
  r->peers[from].stopped = 1;
  return proto_fail(&r->err, "participant '%s' (%s) reported an error: %s",
                    r->peers[from].proc->name, r->peers[from].proc->exec,
                    cJSON_IsString(msg) ? msg->valuestring : "(no message)");
}

/* m == NULL: the message lands in the sender's reply slot. */
int cpl_receive(cpl_runner *r, int expect, double timeout_s, proto_msg *m,
                int *from) {
  double until = proto_now() + timeout_s;
  while (1) {
    if (cpl_interrupted)
      return proto_fail(&r->err, "interrupted by signal %d", cpl_interrupted);
    if (check_children(r) < 0) return -1;
    double left = until - proto_now();
    if (left <= 0) {
      if (expect >= 0) r->failed_peer = expect;
      return proto_fail(&r->err, "%s%s%s did not answer within %g s "
                        "(coupling.%s)", expect >= 0 ? "participant '" : "",
                        expect >= 0 ? r->peers[expect].proc->name : "a participant",
                        expect >= 0 ? "'" : "", timeout_s,
                        r->opts->attach ? "handshake_timeout" : "step_timeout");
    }
    int p = proto_poll_in(r->router, left > 0.1 ? 100 : (int)(left * 1e3) + 1);
    if (p <= 0) continue;
    char identity[PROTO_NAME_LEN] = {0};
    proto_msg *dst = m ? m : &r->inbox;
    int rc = proto_recv(r->router, dst, identity, &r->err);
    int sender = peer_of(r, identity);
    if (sender < 0) {
      /* Not one of ours (a stray or misnamed process): refuse it loudly. */
      return proto_fail(&r->err, "a process calling itself '%s' connected, "
                        "but the scene has no such participant", identity);
    }
    if (rc < 0) {
      r->failed_peer = sender;
      return proto_wrap(&r->err, "from participant '%s'", identity);
    }
    if (!m) { /* swap into the sender's slot; its old buffers are reused */
      proto_msg t = r->peers[sender].reply;
      r->peers[sender].reply = r->inbox;
      r->inbox = t;
      dst = &r->peers[sender].reply;
    }
    if (strcmp(dst->type, proto_msg_type(PROTO_MSG_ERROR)) == 0)
      return handle_error_reply(r, sender, dst);
    if (expect >= 0 && sender != expect) {
      r->failed_peer = sender;
      return proto_fail(&r->err, "participant '%s' sent '%s' out of turn",
                        identity, dst->type);
    }
    *from = sender;
    return 0;
  }
}

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

static int setup_sockets(cpl_runner *r) {
  cpl_scene *s = r->scene;
  r->ctx = zmq_ctx_new();
  r->router = zmq_socket(r->ctx, ZMQ_ROUTER);
  proto_socket_limits(r->router);
  int on = 1, linger = 0;
  zmq_setsockopt(r->router, ZMQ_ROUTER_MANDATORY, &on, sizeof on);
  zmq_setsockopt(r->router, ZMQ_LINGER, &linger, sizeof linger);
  if (r->opts->attach) {
    snprintf(r->ctl_endpoint, sizeof r->ctl_endpoint, "%s", s->attach_endpoint);
    host_any_port(s->attach_endpoint, r->bus_inner, sizeof r->bus_inner);
  } else {
    snprintf(r->run_dir, sizeof r->run_dir, "/tmp/cosim-%s-XXXXXX", s->name);
    if (!mkdtemp(r->run_dir)) /* mode 0700: a private run directory */
      return proto_fail(&r->err, "cannot create a run directory: %s",
                        strerror(errno));
    snprintf(r->ctl_endpoint, sizeof r->ctl_endpoint, "ipc://%s/control",
             r->run_dir);
    snprintf(r->bus_inner, sizeof r->bus_inner, "ipc://%s/bus", r->run_dir);
  }
  if (zmq_bind(r->router, r->ctl_endpoint) != 0)
    return proto_fail(&r->err, "cannot bind %s%s: %s", r->ctl_endpoint,
                      r->opts->attach ? " (coupling.attach_endpoint)" : "",
                      zmq_strerror(errno));
  last_endpoint(r->router, r->ctl_endpoint, sizeof r->ctl_endpoint);
  if (s->bus_monitor[0]) {
    r->bus = cpl_bus_start(r->ctx, r->bus_inner, s->bus_monitor, (int)s->bus_hwm,
                           r->bus_inner, r->bus_public, sizeof r->bus_public, &r->err);
    if (!r->bus) return -1;
  } else {
    r->bus_inner[0] = 0;
  }
  return 0;
}

/* output.dir/endpoints.json and root attributes of results.h5: where the
 * control socket and the monitor bus actually are (ports chosen at bind). */
static int write_endpoints(cpl_runner *r) {
  cJSON *o = cJSON_CreateObject();
  cJSON_AddStringToObject(o, "control", r->ctl_endpoint);
  cJSON_AddStringToObject(o, "bus_monitor", r->bus_public);
  cJSON_AddStringToObject(o, "bus_inner", r->bus_inner);
  cJSON_AddNumberToObject(o, "pid", (double)getpid());
  char *text = cJSON_Print(o);
  cJSON_Delete(o);
  char path[CPL_PATH_LEN + 32];
  snprintf(path, sizeof path, "%s/%s", r->scene->output_dir, CPL_ENDPOINTS_FILE);
  FILE *f = text ? fopen(path, "w") : NULL;
  int rc = f && fprintf(f, "%s\n", text) > 0 ? 0 : -1;
  if (f && fclose(f) != 0) rc = -1;
  free(text);
  if (rc < 0) return proto_fail(&r->err, "cannot write %s", path);
  if (cpl_output_endpoints(r->out, r->ctl_endpoint, r->bus_public, &r->err) < 0)
    return -1;
  if (r->bus_public[0] && !r->opts->quiet)
    printf("cosim: monitor bus at %s (also in %s)\n", r->bus_public, path);
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
                  r->ctl_endpoint, log, &r->err) < 0)
      return -1;
    r->nchildren++;
  }
  return 0;
}

static int hello_ok(cpl_runner *r, int from, const proto_msg *m) {
  cpl_peer *p = &r->peers[from];
  const cJSON *role = cJSON_GetObjectItemCaseSensitive(m->header, PROTO_H_ROLE);
  int rl = cJSON_IsString(role) ? proto_role_parse(role->valuestring) : -1;
  if (strcmp(m->type, proto_msg_type(PROTO_MSG_HELLO)) == 0 && !p->connected && rl >= 0) {
    p->role = (proto_role)rl;
    proto_dims_init(&p->dims);
    p->connected = 1;
    return 0;
  }
  r->failed_peer = from;
  if (strcmp(m->type, proto_msg_type(PROTO_MSG_HELLO)) != 0 || p->connected)
    return proto_fail(&r->err, "participant '%s': expected one hello, got '%s'",
                      p->proc->name, m->type);
  return proto_fail(&r->err, "participant '%s': hello with %s role%s%s (roles: "
                    "dem, fem, block)", p->proc->name,
                    cJSON_IsString(role) ? "unknown" : "no",
                    cJSON_IsString(role) ? " " : "",
                    cJSON_IsString(role) ? role->valuestring : "");
}

static int wait_hellos(cpl_runner *r) {
  if (r->opts->attach) {
    fprintf(stderr, "cosim: waiting %g s for participants; start each with\n",
            r->scene->handshake_timeout);
    for (int i = 0; i < r->n; i++)
      fprintf(stderr, "  %s --endpoint %s --name %s\n", r->peers[i].proc->exec,
              r->ctl_endpoint, r->peers[i].proc->name);
  }
  int missing = r->n;
  double until = proto_now() + r->scene->handshake_timeout;
  proto_msg m = {0};
  while (missing > 0) {
    int from = -1;
    double left = until - proto_now();
    if (cpl_receive(r, -1, left > 0 ? left : 0, &m, &from) < 0) {
      if (strstr(r->err.msg, "did not answer")) {
        char names[256] = {0};
        for (int i = 0; i < r->n; i++)
          if (!r->peers[i].connected) {
            strncat(names, " ", sizeof names - strlen(names) - 1);
            strncat(names, r->peers[i].proc->name, sizeof names - strlen(names) - 1);
            if (r->failed_peer < 0) r->failed_peer = i;
          }
        proto_fail(&r->err, "no handshake within %g s (coupling."
                   "handshake_timeout) from:%s", r->scene->handshake_timeout,
                   names);
      }
      proto_msg_free(&m);
      return -1;
    }
    if (hello_ok(r, from, &m) < 0) {
      proto_msg_free(&m);
      return -1;
    }
    missing--;
  }
  proto_msg_free(&m);
  proto_role roles[CPL_MAX_PROCS];
  r->fem = -1;
  for (int i = 0; i < r->n; i++) {
    roles[i] = r->peers[i].role;
    r->n_of_role[roles[i]]++;
    if (roles[i] == PROTO_ROLE_FEM) r->fem = i;
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
  cJSON_AddStringToObject(run, "bus", r->bus_inner);
  cJSON_AddNumberToObject(run, "deadline_s", s->step_timeout);
  cJSON_AddStringToObject(run, "scheme", cpl_scheme_name(s->scheme));
  cJSON_AddBoolToObject(run, PROTO_H_ROLLBACK, s->scheme == CPL_SCHEME_IMPLICIT);
  /* a participant waits for others' steps too: be generous before giving
   * up (implicit: every iteration of a step) */
  double per_step = s->step_timeout * (r->n + 1) *
                    (s->scheme == CPL_SCHEME_IMPLICIT ? (double)s->implicit.max_iterations : 1);
  cJSON_AddNumberToObject(run, "idle_timeout_s", per_step + s->handshake_timeout);
}

/* Keeps the fem's surface for the coupling (world = rim frame at t = 0). */
static int take_surface(cpl_runner *r, const proto_msg *ready) {
  const proto_array *x0 = proto_msg_find(ready, PROTO_A_SURFACE_X0);
  const proto_array *tri = proto_msg_find(ready, PROTO_A_SURFACE_TRI);
  cpl_surface *s = &r->surf;
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
                        "of %lld", r->peers[r->fem].proc->name, t[i],
                        (long long)s->n_nodes);
  return 0;
}

/* World positions at t = 0 and the rim frame into the fields. */
static void init_fields(cpl_runner *r) {
  const cpl_surface *s = &r->surf;
  double *x = r->fields[CPL_F_SURF_X].cur;
  for (int64_t i = 0; i < s->n_nodes; i++)
    for (int a = 0; a < 3; a++) {
      double acc = r->rim.c[a];
      for (int b = 0; b < 3; b++) acc += r->rim.R[3 * a + b] * s->x0[3 * i + b];
      x[3 * i + a] = acc;
    }
  memcpy(r->fields[CPL_F_RIM_R].cur, r->rim.R, sizeof r->rim.R);
  memcpy(r->fields[CPL_F_RIM_C].cur, r->rim.c, sizeof r->rim.c);
  memcpy(r->fields[CPL_F_RIM_OMEGA].cur, r->rim.w, sizeof r->rim.w);
  memcpy(r->fields[CPL_F_RIM_V].cur, r->rim.v, sizeof r->rim.v);
}

static int welcome_one(cpl_runner *r, int i) {
  cpl_peer *p = &r->peers[i];
  proto_msg w = {0};
  proto_msg_reset(&w, p->proc->name, proto_msg_type(PROTO_MSG_WELCOME), 0, 0);
  fill_run_header(r, &w, p->proc);
  if (p->role == PROTO_ROLE_DEM && r->surf.n_nodes > 0) {
    proto_msg_add_f8(&w, PROTO_A_SURFACE_X0, r->surf.n_nodes, 3,
                     r->fields[CPL_F_SURF_X].cur);
    proto_msg_add_i4(&w, PROTO_A_SURFACE_TRI, r->surf.n_tris, 3, r->surf.tri);
  }
  /* the coupler's copy of the conversation's dims (n, m; surface or not) */
  int rc = proto_role_check(p->role, PROTO_MSG_WELCOME, &w, &p->dims, &r->err);
  if (rc == 0) rc = cpl_send(r, i, &w);
  proto_msg_free(&w);
  int from;
  if (rc == 0)
    rc = cpl_receive(r, i, r->scene->handshake_timeout + r->scene->step_timeout,
                     &p->reply, &from);
  if (rc == 0 && strcmp(p->reply.type, proto_msg_type(PROTO_MSG_READY)) != 0)
    rc = proto_fail(&r->err, "participant '%s': expected 'ready', got '%s'",
                    p->proc->name, p->reply.type);
  if (rc == 0 &&
      proto_role_check(p->role, PROTO_MSG_READY, &p->reply, &p->dims, &r->err) < 0)
    rc = proto_wrap(&r->err, "participant '%s'", p->proc->name);
  p->rollback = cJSON_IsTrue(cJSON_GetObjectItemCaseSensitive(p->reply.header,
                                                              PROTO_H_ROLLBACK));
  if (rc == 0 && i == r->fem) rc = take_surface(r, &p->reply);
  if (rc == 0) rc = cpl_output_participant(r->out, p->proc->name, &p->reply, &r->err);
  if (rc < 0 && r->failed_peer < 0) r->failed_peer = i;
  return rc;
}

/* The fem first (its surface goes to the dem processes), then the rest. */
static int welcome_all(cpl_runner *r) {
  if (r->fem >= 0 && welcome_one(r, r->fem) < 0) return -1;
  if (cpl_fields_init(r, r->surf.n_nodes, &r->err) < 0) return -1;
  init_fields(r);
  for (int i = 0; i < r->n; i++)
    if (i != r->fem && welcome_one(r, i) < 0) return -1;
  return 0;
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
      while (proto_now() < until && proto_poll_in(r->router, 100) > 0) {
        char id[PROTO_NAME_LEN];
        if (proto_recv(r->router, &reply, id, &ignore) == 0 &&
            strcmp(id, r->peers[i].proc->name) == 0)
          break;
      }
    }
    r->peers[i].stopped = 1;
  }
  proto_msg_free(&m);
  proto_msg_free(&reply);
}

static void teardown(cpl_runner *r, int ok) {
  if (ok) say_stop(r);
  cpl_stop_all(r->children, r->nchildren, ok ? 3.0 : 0.5);
  for (int i = 0; i < r->n; i++) proto_msg_free(&r->peers[i].reply);
  proto_msg_free(&r->inbox);
  cpl_bus_stop(r->bus);
  if (r->router) zmq_close(r->router);
  if (r->ctx) zmq_ctx_term(r->ctx);
  if (r->run_dir[0]) {
    char path[CPL_PATH_LEN + 16];
    snprintf(path, sizeof path, "%s/control", r->run_dir);
    unlink(path);
    snprintf(path, sizeof path, "%s/bus", r->run_dir);
    unlink(path);
    rmdir(r->run_dir);
  }
  free(r->surf.x0);
  free(r->surf.tri);
  cpl_fields_free(r);
  cpl_accel_free(r->accel);
  free(r->xi), free(r->xt), free(r->x_start), free(r->v_dem), free(r->f_fem),
      free(r->carry);
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

static int prepare(cpl_runner *r) {
  int rc = 0;
  if (!r->opts->attach)
    for (int i = 0; i < r->n && rc == 0; i++)
      rc = cpl_resolve_exec(&r->scene->procs[i], &r->err);
  if (rc == 0) {
    r->out = cpl_output_open(r->scene, &r->err);
    rc = r->out ? 0 : -1;
  }
  if (rc == 0) rc = setup_sockets(r);
  if (rc == 0) rc = write_endpoints(r);
  if (rc == 0 && !r->opts->attach) rc = start_children(r);
  if (rc == 0) rc = wait_hellos(r);
  if (rc == 0) rc = welcome_all(r);
  if (rc == 0) rc = check_rollback(r);
  if (rc == 0) {
    cpl_schedule_build(r);
    if (!r->opts->quiet) cpl_schedule_print(r, stdout);
    fflush(stdout);
    r->timing = cpl_timing_create(r);
    if (!r->timing) rc = proto_fail(&r->err, "out of memory (timing)");
  }
  return rc;
}

int cpl_run(cpl_scene *s, const cpl_run_opts *opts) {
  cpl_runner *r = calloc(1, sizeof *r);
  if (!r) return 4;
  r->scene = s;
  r->opts = opts;
  r->failed_peer = -1;
  r->fem = -1;
  r->n = s->nprocs;
  for (int i = 0; i < r->n; i++) r->peers[i].proc = &s->procs[i];
  install_signals();
  cpl_rim_init(&r->rim, &s->scenario);
  r->road.a = s->scenario.kind == CPL_SCN_INDENTATION && s->scenario.profile == CPL_PROFILE_FORCE
                  ? s->scenario.road_force / s->scenario.road_mass
                  : 0;
  r->wall_start = proto_now();
  int rc = prepare(r);
  if (rc == 0) rc = cpl_step_loop(r);
  int exit_code = 0;
  if (rc < 0) {
    exit_code = cpl_interrupted ? 130 : r->failed_peer >= 0 ? 3 : 1;
    fprintf(stderr, "\ncosim: run '%s' failed: %s\n", s->name, r->err.msg);
    if (r->failed_peer >= 0)
      fprintf(stderr, "cosim: failed participant: %s\n",
              r->peers[r->failed_peer].proc->name);
  }
  teardown(r, rc == 0);
  char summary[2048] = {0};
  if (r->out) cpl_output_summary(r->out, summary, sizeof summary);
  if (r->out && cpl_output_close(r->out) < 0 && exit_code == 0) {
    fprintf(stderr, "cosim: could not write %s/results.h5 completely\n",
            s->output_dir);
    exit_code = 4;
  }
  if (exit_code == 0) {
    printf("cosim: run '%s' finished: %lld steps, t = %g s, %.2f s wall\n",
           s->name, (long long)s->n_steps, (double)s->n_steps * s->dt,
           proto_now() - r->wall_start);
    if (!opts->quiet) cpl_timing_print(r, stdout);
    printf("results: %s/results.h5 (logs in %s/logs)\n%s", s->output_dir,
           s->output_dir, summary);
  } else if (r->out || exit_code != 1) {
    fprintf(stderr, "cosim: what was written so far is in %s/results.h5\n",
            s->output_dir);
  }
  cpl_timing_free(r->timing);
  free(r);
  return exit_code;
}
