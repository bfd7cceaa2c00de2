/* affinity.c — coupling.affinity "handoff": in a scheme that runs one
 * process at a time (serial, implicit), every hand-off of the step (coupler
 * -> participant -> coupler) wakes a sleeping process. On another core that
 * wake is an inter-processor interrupt, and a virtual machine whose idle
 * vCPUs halt pays tens of microseconds for each (bench/results/tire_soil.md
 * "Hand-offs on one core": 77-80 us per futex round trip across two vCPUs,
 * 6.7 us on one). So the coupler's loop thread and each OpenMP participant's
 * main thread share one core, the hand-off core, and the participants'
 * other threads take the other cores: the wakes stay on one core, and a
 * participant that computes still has every core. The hand-off core is the
 * allowed core with the fewest threads bound to it alone, so runs started
 * side by side take different cores. Only the main threads are
 * bound; the participants bind theirs through the OpenMP standard's places
 * (OMP_PLACES, one place per allowed CPU with the hand-off core first, and
 * OMP_PROC_BIND=close: thread 0 on the first place), so a participant
 * without OpenMP is left where it is. The participants run as SCHED_BATCH
 * (below), so that a wake hands the core over only when the waker sleeps,
 * and their OpenMP threads spin briefly at barriers instead of sleeping.
 *   (scene, allowed CPUs, threads bound per CPU, environment) => (places for
 *   the children, the coupler's loop thread bound) */
#define _GNU_SOURCE
#include "internal.h"

#include <dirent.h>
#include <pthread.h>
#include <sched.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Iterations an OpenMP thread spins at a barrier before it sleeps, for the
 * participants of a hand-off run (libgomp's GOMP_SPINCOUNT; dem_server's own
 * default too). Passive waits made every barrier inside a step a futex wake of
 * the worker on the other core (fem_server: 2.7 % of a paper run's samples in
 * the kernel's wake-up path); a short spin bridges the barriers of a step but
 * not a partner's step: paper scene 0.96-0.98x the passive step in three
 * alternated pairs, while 100 000 made it 1.5x slower (the spinning workers of
 * one process took the core the other's needed; bench/results/tire_soil.md "Hand-offs on one
 * core"). */
#define CPL_HANDOFF_SPINCOUNT "10000"

/* Threads of user processes (kernel threads left out: every CPU has its
 * own) whose allowed CPUs are one CPU of `set`, counted per CPU from /proc.
 * Without this, several runs started by hand at once all bound their
 * hand-offs to the core each coupler happened to start on, often the same
 * one, and ran one core between them. Returns 0 when /proc cannot be read
 * (counts all 0: the coupler's own core is kept). */
static int cpl_count_bound_threads(const cpu_set_t *set, int *bound) {
  memset(bound, 0, CPU_SETSIZE * sizeof *bound);
  DIR *procs = opendir("/proc");
  if (!procs) return 0;
  char path[64], line[256];
  for (struct dirent *p; (p = readdir(procs));) {
    if (p->d_name[0] < '1' || p->d_name[0] > '9') continue;
    snprintf(path, sizeof path, "/proc/%.20s/cmdline", p->d_name);
    FILE *f = fopen(path, "r");
    const int user = f && fgetc(f) != EOF; /* a kernel thread's is empty */
    if (f) fclose(f);
    if (!user) continue;
    snprintf(path, sizeof path, "/proc/%.20s/task", p->d_name);
    DIR *tasks = opendir(path);
    if (!tasks) continue; /* gone since */
    for (struct dirent *t; (t = readdir(tasks));) {
      if (t->d_name[0] < '1' || t->d_name[0] > '9') continue;
      snprintf(path, sizeof path, "/proc/%.20s/task/%.20s/status", p->d_name, t->d_name);
      if (!(f = fopen(path, "r"))) continue;
      while (fgets(line, sizeof line, f)) {
        char *end;
        if (strncmp(line, "Cpus_allowed_list:", 18) != 0) continue;
        const long c = strtol(line + 18, &end, 10);
        if (end != line + 18 && (*end == '\n' || *end == 0) && c >= 0 && c < CPU_SETSIZE &&
            CPU_ISSET((int)c, set))
          bound[c]++;
        break;
      }
      fclose(f);
    }
    closedir(tasks);
  }
  closedir(procs);
  return 1;
}

void cpl_affinity_plan(const cpl_scene *s, int attach, cpl_affinity *a) {
  memset(a, 0, sizeof *a);
  a->core = -1;
  if (s->affinity != CPL_AFFINITY_HANDOFF) {
    snprintf(a->why, sizeof a->why, "none (coupling.affinity)");
    return;
  }
  if (s->scheme == CPL_SCHEME_PARALLEL) { /* a scene's hint that does not fit this scheme */
    snprintf(a->why, sizeof a->why, "none: the parallel scheme runs every process at once "
             "(\"handoff\" serves serial and implicit)");
    return;
  }
  if (attach) { /* the participants start elsewhere, with their own environment */
    snprintf(a->why, sizeof a->why, "none: participants started by hand (--attach) "
             "are not given places");
    return;
  }
  const char *user = getenv("OMP_PLACES") ? "OMP_PLACES" : getenv("OMP_PROC_BIND") ? "OMP_PROC_BIND" : NULL;
  if (user) {
    snprintf(a->why, sizeof a->why, "none: %s is set in the environment (the user's "
             "binding is kept)", user);
    return;
  }
  cpu_set_t set;
  if (sched_getaffinity(0, sizeof set, &set) != 0 || CPU_COUNT(&set) < 2) {
    snprintf(a->why, sizeof a->why, "none: fewer than 2 CPUs allowed");
    return;
  }
  /* the allowed core with the fewest threads bound to it alone (other
   * hand-off runs' loops and main threads); among equals the one the coupler
   * runs on now, where the scheduler found room */
  static int bound[CPU_SETSIZE]; /* once per run, before the children start */
  const int scanned = cpl_count_bound_threads(&set, bound);
  int core = sched_getcpu();
  if (core < 0 || core >= CPU_SETSIZE || !CPU_ISSET(core, &set))
    for (core = 0; core < CPU_SETSIZE && !CPU_ISSET(core, &set); core++) {
    }
  for (int c = 0; c < CPU_SETSIZE; c++)
    if (CPU_ISSET(c, &set) && bound[c] < bound[core]) core = c;
  size_t len = (size_t)snprintf(a->places, sizeof a->places, "{%d}", core);
  for (int c = 0; c < CPU_SETSIZE && len < sizeof a->places; c++)
    if (c != core && CPU_ISSET(c, &set))
      len += (size_t)snprintf(a->places + len, sizeof a->places - len, ",{%d}", c);
  if (len >= sizeof a->places) { /* a machine with more CPUs than the text holds */
    a->places[0] = 0;
    snprintf(a->why, sizeof a->why, "none: too many CPUs to list as OpenMP places");
    return;
  }
  a->core = core;
  snprintf(a->why, sizeof a->why, "handoff: the coupler's loop and each OpenMP participant's "
           "main thread on CPU %d (%d thread%s bound to it alone before this run%s), their other "
           "threads on the other %d CPU%s (OMP_PLACES, OMP_PROC_BIND=close; participants "
           "SCHED_BATCH; GOMP_SPINCOUNT=" CPL_HANDOFF_SPINCOUNT " unless the waits are set)",
           core, bound[core], bound[core] == 1 ? "" : "s", scanned ? "" : ": /proc not read",
           CPU_COUNT(&set) - 1, CPU_COUNT(&set) > 2 ? "s" : "");
}

int cpl_affinity_child_env(const cpl_affinity *a) {
  if (!a || a->core < 0) return 0;
  setenv("OMP_PLACES", a->places, 1);
  setenv("OMP_PROC_BIND", "close", 1);
  if (!getenv("OMP_WAIT_POLICY") && !getenv("GOMP_SPINCOUNT")) /* else the user's */
    setenv("GOMP_SPINCOUNT", CPL_HANDOFF_SPINCOUNT, 1);
  /* SCHED_BATCH: a woken participant does not preempt the process that woke
   * it (the coupler after its post, mid-way to its own wait), it runs when
   * that one sleeps; on the shared core a preempting wakee made the coupler's
   * last microseconds of each hand-off wait for the participant's step
   * (tire_soil.md "Hand-offs on one core"). No privilege needed. */
  const struct sched_param none = {0};
  sched_setscheduler(0, SCHED_BATCH, &none);
  return 1;
}

void cpl_affinity_pin_self(const cpl_affinity *a) {
  if (a->core < 0) return;
  cpu_set_t one;
  CPU_ZERO(&one);
  CPU_SET(a->core, &one);
  const int rc = pthread_setaffinity_np(pthread_self(), sizeof one, &one);
  if (rc != 0) /* the run is the same without it, only slower */
    fprintf(stderr, "cosim: warning: coupling.affinity: cannot bind the coupler's loop to "
            "CPU %d (%s); it runs unbound\n", a->core, strerror(rc));
}
