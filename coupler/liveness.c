/* liveness.c — receiving from the participants while watching them
 * (PROTOCOL.md "Liveness"; the supervisor of MUSCLE3, Veen & Hoekstra 2020,
 * and ZMTP 3.1 heartbeats, ZeroMQ RFC 37): a child that exits is
 * named with the end of its log; one that announced heartbeats and falls
 * silent for coupling.heartbeat_timeout is named (stopped, hung, or its
 * host unreachable), whatever its init or step time; one that does not
 * answer within a deadline without reporting progress is named. The
 * deadlines run on a watch clock that stands still while the coupler itself
 * does not run (Ctrl-Z, SIGSTOP): they measure the participants' silence,
 * not the coupler's pauses. Heartbeats carry init progress, which `cosim
 * run` shows. Messages from identities the scene does not name are logged
 * and ignored: a stray process cannot end the run. */
#include "runner.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#define POLL_MS 100
/* Between messages the children are looked at (waitpid) at most this
 * often (s): once per message is two system calls per step for nothing. */
#define CHILD_CHECK_S 0.05
/* The most one look credits (a little more than a poll): a longer gap is
 * the coupler's own pause, or its own work between two waits. */
#define WATCH_MAX_GAP_S 0.25
#define STRANGERS_SHOWN 5   /* unknown identities logged; then only counted */

/* (wall clock now) -> (watch clock, advanced by at most WATCH_MAX_GAP_S) */
double cpl_watch_at(cpl_runner *r, double now) {
  double gap = now - r->watch_wall;
  r->watch_wall = now;
  if (gap > 0) r->watch += gap < WATCH_MAX_GAP_S ? gap : WATCH_MAX_GAP_S;
  return r->watch;
}

double cpl_watch(cpl_runner *r) { return cpl_watch_at(r, proto_now()); }

void cpl_printable(char *out, size_t cap, const char *s) {
  size_t n = 0;
  for (; s && *s && n + 1 < cap; s++)
    out[n++] = (*s >= 0x20 && *s <= 0x7e) || *s == '\n' || *s == '\t' ? *s : '?';
  if (cap) out[n] = 0;
}

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

/* (peers' last messages, watch clock) -> (the one silent too long, named) */
int cpl_check_silence(cpl_runner *r, double now) {
  for (int i = 0; i < r->n; i++) {
    const cpl_peer *p = &r->peers[i];
    if (!p->connected || p->stopped || p->hb_s <= 0 ||
        now - p->heard <= r->scene->heartbeat_timeout)
      continue;
    r->failed_peer = i;
    return proto_fail(&r->err, "participant '%s' (%s, pid %d) has been silent for "
                      "%.0f s (coupling.heartbeat_timeout; it promised a message "
                      "every %g s): it is stopped, hung, or cannot reach the "
                      "coupler", p->proc->name, p->proc->exec, p->pid,
                      now - p->heard, p->hb_s);
  }
  return 0;
}

/* Large arrays through the peer's segment once it took the offer (run.c). */
int cpl_send(cpl_runner *r, int peer, const proto_msg *m) {
  cpl_peer *p = &r->peers[peer];
  if (proto_send_via(r->router, p->proc->name, m, 0, p->shm_on ? p->shm_out : NULL,
                     &r->err) == 0) {
    p->awaited = 1;
    return 0;
  }
  r->failed_peer = peer;
  /* its connection is gone: if it died, say how (waitpid may need a moment) */
  for (int tries = 0; tries < 10; tries++) {
    if (check_children(r) < 0) return -1;
    proto_poll_in(r->router, 10);
  }
  return -1;
}

static int handle_error_reply(cpl_runner *r, int from, const proto_msg *m) {
  const cJSON *msg = cJSON_GetObjectItemCaseSensitive(m->header, PROTO_H_MESSAGE);
  char text[sizeof r->err.msg];
  cpl_printable(text, sizeof text, cJSON_IsString(msg) ? msg->valuestring : "(no message)");
  r->failed_peer = from;
  r->peers[from].stopped = 1;
  return proto_fail(&r->err, "participant '%s' (%s) reported an error: %s",
                    r->peers[from].proc->name, r->peers[from].proc->exec, text);
}

/* Init progress: one status line on a terminal, else a line per tenth. */
static void show_progress(cpl_runner *r, int i) {
  cpl_peer *p = &r->peers[i];
  if (r->opts->quiet || p->progress < 0) return;
  int tenth = (int)floor(10 * p->progress);
  if (r->opts->progress) {
    fprintf(stderr, "\r  %s: %s %3.0f %%   ", p->proc->name, p->what, 100 * p->progress);
  } else if (tenth != p->shown) {
    printf("cosim: %s: %s %.0f %%\n", p->proc->name, p->what, 100 * p->progress);
    fflush(stdout);
  }
  p->shown = tenth;
}

static void take_heartbeat(cpl_runner *r, int i, const proto_msg *m) {
  cpl_peer *p = &r->peers[i];
  const cJSON *prog = cJSON_GetObjectItemCaseSensitive(m->header, PROTO_H_PROGRESS);
  const cJSON *what = cJSON_GetObjectItemCaseSensitive(m->header, PROTO_H_WHAT);
  if (!cJSON_IsNumber(prog)) return;
  char text[sizeof p->what];
  cpl_printable(text, sizeof text, cJSON_IsString(what) ? what->valuestring : "");
  if (prog->valuedouble != p->progress || strcmp(text, p->what) != 0) {
    p->progressed = r->watch; /* news: the deadline starts again */
    p->progress = prog->valuedouble;
    snprintf(p->what, sizeof p->what, "%s", text[0] ? text : "working");
    if (!p->initialized) show_progress(r, i);
  }
}

int cpl_take_hello(cpl_runner *r, int from, const proto_msg *m) {
  cpl_peer *p = &r->peers[from];
  const cJSON *role = cJSON_GetObjectItemCaseSensitive(m->header, PROTO_H_ROLE);
  const cJSON *hb = cJSON_GetObjectItemCaseSensitive(m->header, PROTO_H_HEARTBEAT_S);
  const cJSON *pid = cJSON_GetObjectItemCaseSensitive(m->header, PROTO_H_PID);
  int rl = cJSON_IsString(role) ? proto_role_parse(role->valuestring) : -1;
  if (strcmp(m->type, proto_msg_type(PROTO_MSG_HELLO)) == 0 && !p->connected && rl >= 0) {
    p->role = (proto_role)rl;
    proto_dims_init(&p->dims);
    p->connected = 1;
    p->pid = cJSON_IsNumber(pid) ? (int)pid->valuedouble : 0;
    /* a promise we can hold it to: at least every 0.01 s .. 1/2 timeout */
    p->hb_s = cJSON_IsNumber(hb) && hb->valuedouble >= 0.01 &&
                      hb->valuedouble <= 0.5 * r->scene->heartbeat_timeout
                  ? hb->valuedouble
                  : 0;
    p->progress = -1;
    p->shown = -1;
    /* same host: its hello names our host and boot id (and so can map) */
    const cJSON *host = cJSON_GetObjectItemCaseSensitive(m->header, PROTO_H_HOST);
    const cJSON *hn = cJSON_GetObjectItemCaseSensitive(host, "name");
    const cJSON *hbid = cJSON_GetObjectItemCaseSensitive(host, "boot_id");
    char name[256], boot[64];
    p->same_host = cJSON_IsString(hn) && cJSON_IsString(hbid) &&
                   proto_shm_host(name, sizeof name, boot, sizeof boot) == 0 &&
                   strcmp(hn->valuestring, name) == 0 && strcmp(hbid->valuestring, boot) == 0;
    return 0;
  }
  r->failed_peer = from;
  if (strcmp(m->type, proto_msg_type(PROTO_MSG_HELLO)) != 0 || p->connected)
    return proto_fail(&r->err, "participant '%s': expected one hello, got '%s'",
                      p->proc->name, m->type);
  char text[PROTO_NAME_LEN];
  cpl_printable(text, sizeof text, cJSON_IsString(role) ? role->valuestring : "");
  return proto_fail(&r->err, "participant '%s': hello with %s role%s%s (roles: "
                    "dem, fem, block)", p->proc->name,
                    cJSON_IsString(role) ? "unknown" : "no",
                    cJSON_IsString(role) ? " " : "", text);
}

/* Somebody the scene does not name: logged (a few times), ignored. */
static void stranger(cpl_runner *r, const char *identity) {
  if (r->strangers++ >= STRANGERS_SHOWN) return;
  char text[PROTO_NAME_LEN];
  cpl_printable(text, sizeof text, identity);
  fprintf(stderr, "cosim: ignoring a message from '%s', which is not a process of "
          "this scene%s\n", text, r->strangers == STRANGERS_SHOWN ? " (further ones "
          "are only counted)" : "");
}

static int timed_out(cpl_runner *r, int expect, double timeout_s, const char *key) {
  if (expect >= 0) r->failed_peer = expect;
  return proto_fail(&r->err, "%s%s%s did not answer within %g s (coupling.%s)",
                    expect >= 0 ? "participant '" : "",
                    expect >= 0 ? r->peers[expect].proc->name : "a participant",
                    expect >= 0 ? "'" : "", timeout_s, key);
}

/* The reader of a sender's segment (NULL: it has none, descriptors are refused). */
static proto_shm *segment_of(void *ctx, const char *identity) {
  cpl_runner *r = ctx;
  int i = peer_of(r, identity);
  return i >= 0 ? r->peers[i].shm_in : NULL;
}

/* The segments whose senders owe a reply (expect, or every awaited peer):
 * their bells are watched beside the socket. Returns how many. */
static int bells_of(cpl_runner *r, int expect, proto_shm **rds, int *who) {
  int n = 0;
  for (int i = 0; i < r->n; i++) {
    const cpl_peer *p = &r->peers[i];
    if (!p->shm_on || !(expect >= 0 ? i == expect : p->awaited)) continue;
    rds[n] = p->shm_in;
    who[n++] = i;
  }
  return n;
}

/* (sockets, bells, children, watch clock) -> (the next message, or the culprit named) */
int cpl_receive(cpl_runner *r, int expect, double timeout_s, const char *key,
                proto_msg *m, int *from) {
  const double start = cpl_watch(r), began = proto_now();
  while (1) {
    if (cpl_interrupted)
      return proto_fail(&r->err, "interrupted by signal %d", cpl_interrupted);
    const double now = cpl_watch(r);
    /* the process table at most every CHILD_CHECK_S: a wait that goes on
     * looks at it again after each slice of the socket's poll */
    if (now - r->children_checked >= CHILD_CHECK_S || now < r->children_checked) {
      if (check_children(r) < 0) return -1;
      r->children_checked = now;
    }
    if (cpl_check_silence(r, now) < 0) return -1;
    double since = start;
    if (expect >= 0 && r->peers[expect].progressed > since) since = r->peers[expect].progressed;
    const double left = since + timeout_s - now;
    if (left <= 0) return timed_out(r, expect, timeout_s, key);
    proto_shm *rds[CPL_MAX_PROCS];
    int who[CPL_MAX_PROCS];
    const int nb = bells_of(r, expect, rds, who);
    const int got = proto_wait_in(r->router, rds, nb,
                                  left > POLL_MS * 1e-3 ? POLL_MS : (int)(left * 1e3) + 1, began);
    if (got <= 0) continue;
    char identity[PROTO_NAME_LEN] = {0};
    proto_msg *dst = m ? m : &r->inbox;
    if (got >= 2) /* posted in the segment of who[got - 2] */
      snprintf(identity, sizeof identity, "%s", r->peers[who[got - 2]].proc->name);
    int rc = proto_recv_found(r->router, got, rds, dst, identity, segment_of, r, &r->err);
    int sender = peer_of(r, identity);
    if (sender < 0) {
      stranger(r, identity);
      continue;
    }
    r->peers[sender].heard = cpl_watch(r);
    if (rc < 0) {
      r->failed_peer = sender;
      return proto_wrap(&r->err, "from participant '%s'", identity);
    }
    cpl_printable(dst->type, sizeof dst->type, dst->type); /* it may reach the terminal */
    if (strcmp(dst->type, proto_msg_type(PROTO_MSG_HEARTBEAT)) == 0) {
      take_heartbeat(r, sender, dst);
      continue;
    }
    r->peers[sender].awaited = 0;
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
