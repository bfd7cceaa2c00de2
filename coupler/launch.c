/* launch.c — starting participants and making sure none outlives the run
 * (MUSCLE3-style supervision: the first failure stops everything, and the
 * report names the participant and shows the end of its log). Each child
 * leads its own process group, so that stopping it stops what it started
 * too (a launcher such as mpirun and its ranks, a wrapper script and its
 * participant). */
#include "internal.h"

#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

int cpl_spawn(cpl_child *c, const char *name, int argc, const char *const *argv,
              const char *endpoint, const char *log_path, const char *curve_file,
              const cpl_affinity *affinity, proto_err *err) {
  memset(c, 0, sizeof *c);
  snprintf(c->name, sizeof c->name, "%s", name);
  snprintf(c->exec, sizeof c->exec, "%s", argv[argc - 1]);
  snprintf(c->log_path, sizeof c->log_path, "%s", log_path);
  if (argc < 1 || argc > CPL_MAX_ARGV)
    return proto_fail(err, "%s: %d exec arguments (1 to %d)", name, argc, CPL_MAX_ARGV);
  const char *args[CPL_MAX_ARGV + 5];
  for (int i = 0; i < argc; i++) args[i] = argv[i];
  const char *extra[] = {"--endpoint", endpoint, "--name", name, NULL};
  memcpy(args + argc, extra, sizeof extra);
  int log = open(log_path, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (log < 0)
    return proto_fail(err, "%s: cannot create log %s: %s", name, log_path,
                      strerror(errno));
  pid_t parent = getpid();
  pid_t pid = fork();
  if (pid < 0) {
    close(log);
    return proto_fail(err, "%s: fork failed: %s", name, strerror(errno));
  }
  if (pid == 0) {
    /* Die with the launcher, whatever kills it; its own process group, so
     * that the terminal's Ctrl-C goes to the launcher only (which stops
     * everyone in order) and a stop reaches the whole group. */
    prctl(PR_SET_PDEATHSIG, SIGKILL);
    if (getppid() != parent) _exit(1);
    setpgid(0, 0);
    signal(SIGINT, SIG_IGN);
    dup2(log, 1);
    dup2(log, 2);
    int devnull = open("/dev/null", O_RDONLY);
    if (devnull >= 0) dup2(devnull, 0);
    setenv("COSIM_LAUNCHED", "1", 1);
    if (curve_file) setenv(PROTO_ENV_CURVE, curve_file, 1);
    else unsetenv(PROTO_ENV_CURVE);
    /* The coupler itself: `$COSIM_EXE roles --json` is the role table of the
     * very binary that runs the scene (the Python package reads it). */
    char self[CPL_PATH_LEN];
    ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
    if (n > 0) {
      self[n] = 0;
      setenv("COSIM_EXE", self, 1);
    }
    /* Participants take turns on shared cores (serial scheme): OpenMP
     * threads that spin after each parallel region steal the cores of the
     * process computing next (paper-scale tyre, 2 cores, 2 threads each:
     * 1.8x slower; bench/results/coupling.md). Unless the user chose. */
    if (!cpl_affinity_child_env(affinity)) /* handoff: main threads on one core, short spins */
      setenv("OMP_WAIT_POLICY", "passive", 0);
    execv(args[0], (char *const *)args);
    fprintf(stderr, "cannot execute %s: %s\n", args[0], strerror(errno));
    _exit(127);
  }
  setpgid(pid, pid); /* also here: no race with the first kill(-pid) */
  close(log);
  c->pid = pid;
  c->running = 1;
  return 0;
}

static void describe_status(int status, char *out, size_t cap) {
  if (WIFEXITED(status))
    snprintf(out, cap, "exited with status %d", WEXITSTATUS(status));
  else if (WIFSIGNALED(status))
    snprintf(out, cap, "was killed by signal %d (%s)", WTERMSIG(status),
             strsignal(WTERMSIG(status)));
  else
    snprintf(out, cap, "stopped (status %d)", status);
}

int cpl_child_poll(cpl_child *c) {
  if (!c->running) return 0;
  int status;
  pid_t r = waitpid(c->pid, &status, WNOHANG);
  if (r == c->pid) {
    c->running = 0;
    c->status = status;
    describe_status(status, c->how, sizeof c->how);
    return 1;
  }
  return 0;
}

void cpl_child_tail(const cpl_child *c, char *out, size_t cap, int lines) {
  out[0] = 0;
  FILE *f = fopen(c->log_path, "rb");
  if (!f) return;
  fseek(f, 0, SEEK_END);
  long size = ftell(f);
  long from = size > (long)cap - 1 ? size - (long)cap + 1 : 0;
  fseek(f, from, SEEK_SET);
  size_t n = fread(out, 1, cap - 1, f);
  fclose(f);
  out[n] = 0;
  while (n && out[n - 1] == '\n') out[--n] = 0;
  /* keep the last `lines` lines */
  int seen = 0;
  for (size_t i = n; i > 0; i--) {
    if (out[i - 1] == '\n' && ++seen == lines) {
      memmove(out, out + i, n - i + 1);
      return;
    }
  }
}

static void sleep_ms(int ms) {
  struct timespec ts = {ms / 1000, (long)(ms % 1000) * 1000000L};
  nanosleep(&ts, NULL);
}

/* Waits until every child has exited or `seconds` passed. */
static int wait_all(cpl_child *cs, int n, double seconds) {
  double until = proto_now() + seconds;
  while (1) {
    int alive = 0;
    for (int i = 0; i < n; i++) {
      cpl_child_poll(&cs[i]);
      alive += cs[i].running;
    }
    if (!alive || proto_now() > until) return alive;
    sleep_ms(10);
  }
}

/* Signals a child's process group (the child and what it started). */
static void signal_group(const cpl_child *c, int sig) {
  if (kill(-c->pid, sig) < 0 && c->running) kill(c->pid, sig);
}

/* Members of a group whose leader has exited (a wrapper's participant) are
 * not our children: they are waited for by their group's presence. */
static int group_alive(const cpl_child *c) { return kill(-c->pid, 0) == 0; }

static int wait_groups(cpl_child *cs, int n, double seconds) {
  double until = proto_now() + seconds;
  while (1) {
    int alive = wait_all(cs, n, 0);
    for (int i = 0; i < n; i++) alive += !cs[i].running && group_alive(&cs[i]);
    if (!alive || proto_now() > until) return alive;
    sleep_ms(10);
  }
}

void cpl_stop_all(cpl_child *cs, int n, double grace_s) {
  if (wait_groups(cs, n, grace_s) == 0) return;
  for (int i = 0; i < n; i++)
    if (cs[i].running || group_alive(&cs[i])) {
      signal_group(&cs[i], SIGTERM);
      signal_group(&cs[i], SIGCONT); /* a stopped process acts on it only when continued */
    }
  if (wait_groups(cs, n, 2.0) == 0) return;
  for (int i = 0; i < n; i++)
    if (cs[i].running || group_alive(&cs[i])) signal_group(&cs[i], SIGKILL);
  wait_groups(cs, n, 5.0);
}
