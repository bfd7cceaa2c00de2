/* dem_threads.c — how many threads a run uses ("threads": "auto" or 0).
 *
 * Fork/join parallelism only pays when every thread has a core of its own:
 * one preempted thread stalls the others at each barrier (on 2 cores with one
 * other busy process, 2 threads ran 3x slower than 1). So "auto" takes
 *   cores allowed (sched_getaffinity) − COSIM_CORES_RESERVED (cores that
 *   participants running at the same time need; the coupler or the user sets
 *   it; the serial coupling scheme runs one participant at a time: 0)
 *   − cores busy with other processes,
 * at most one thread per DEM_GRAINS_PER_THREAD grains (below that one thread
 * is faster: bench/results/dem.md), at least one. Other processes' load is
 * measured while this state steps: /proc/stat busy time minus our own CPU
 * time over windows of DEM_PROBE_WINDOW s of stepping, so it follows load
 * that comes and goes (results do not depend on the number of threads, so
 * changing it between steps is safe). Time between steps (a coupled partner
 * computing in the serial scheme) is not counted against the others. */
#define _GNU_SOURCE
#include "dem_server/dem_internal.h"

#include <fcntl.h>
#include <omp.h>
#include <sched.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#define DEM_GRAINS_PER_THREAD 1000 /* measured: bench/results/dem.md "Threads" */
#define DEM_PROBE_WINDOW 0.25      /* s of stepping per load measurement */
#define DEM_RESERVED_ENV "COSIM_CORES_RESERVED"
#define DEM_GOMP_SPINCOUNT "10000" /* iterations a waiting thread spins before it sleeps */

static double now_s(clockid_t clk) {
  struct timespec ts;
  clock_gettime(clk, &ts);
  return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* /proc/stat into buf (NUL-terminated); 0, or −1 when unreadable. No
 * allocation (called between steps). */
static int read_stat(char *buf, size_t cap) {
  int fd = open("/proc/stat", O_RDONLY | O_CLOEXEC);
  if (fd < 0) return -1;
  ssize_t len = read(fd, buf, cap - 1);
  close(fd);
  if (len <= 0) return -1;
  buf[len] = 0;
  return 0;
}

/* Busy time of all CPUs (s) from /proc/stat's first line: everything but
 * idle and iowait. < 0 when unreadable. */
static double busy_seconds(void) {
  char buf[512];
  unsigned long long v[8] = {0};
  if (read_stat(buf, sizeof buf) ||
      sscanf(buf, "cpu %llu %llu %llu %llu %llu %llu %llu %llu", &v[0], &v[1], &v[2], &v[3], &v[4], &v[5], &v[6],
             &v[7]) < 4)
    return -1;
  const double busy = (double)(v[0] + v[1] + v[2] + v[5] + v[6] + v[7]); /* user nice system irq softirq steal */
  return busy / (double)sysconf(_SC_CLK_TCK);
}

/* Runnable threads right now (procs_running in /proc/stat), −1 if unknown. */
static int procs_running(void) {
  char buf[8192];
  if (read_stat(buf, sizeof buf)) return -1;
  const char *p = strstr(buf, "procs_running ");
  return p ? atoi(p + 14) : -1;
}

/* OpenMP places bind this process's threads (OMP_PLACES with OMP_PROC_BIND,
 * as coupling.affinity "handoff" sets): the main thread is then bound to the
 * first place alone, so its own affinity mask says 1. */
static int places_bind(void) {
  return omp_get_proc_bind() != omp_proc_bind_false && omp_get_num_places() > 1;
}

/* The cores this process may use: the CPUs of its places when they bind its
 * threads, else its affinity mask. */
static int cores_allowed(void) {
  if (places_bind()) {
    int n = 0;
    for (int p = 0; p < omp_get_num_places(); p++) n += omp_get_place_num_procs(p);
    if (n > 0) return n;
  }
  cpu_set_t set;
  if (sched_getaffinity(0, sizeof set, &set) == 0) return CPU_COUNT(&set);
  long n = sysconf(_SC_NPROCESSORS_ONLN);
  return n > 0 ? (int)n : 1;
}

/* " (main thread bound to CPU c by the OpenMP places)" when it is, else "". */
static const char *bound_text(char *buf, size_t cap) {
  cpu_set_t set;
  buf[0] = 0;
  if (!places_bind() || sched_getaffinity(0, sizeof set, &set) != 0 || CPU_COUNT(&set) != 1)
    return buf;
  for (int c = 0; c < CPU_SETSIZE; c++)
    if (CPU_ISSET(c, &set)) snprintf(buf, cap, " (main thread bound to CPU %d by the OpenMP places)", c);
  return buf;
}

static void set_threads(dem_state *s, int n) {
  s->work->nthreads = n;
  s->threads = n;
}

int dem_threads_init(const dem_model *m, dem_state *s, proto_err *err) {
  struct dem_work *w = s->work;
  dem_thread_probe *p = &w->probe;
  memset(p, 0, sizeof *p);
  p->cores = cores_allowed();
  char bound[96];
  bound_text(bound, sizeof bound);
  if (m->threads > 0) {
    set_threads(s, m->threads > DEM_MAX_THREADS ? DEM_MAX_THREADS : m->threads);
    snprintf(s->threads_why, sizeof s->threads_why, "threads = %d in the config (%d cores allowed%s)%s",
             s->threads, p->cores, bound, s->threads > p->cores ? ": more threads than cores, expect it slow" : "");
    return 0;
  }
  const char *env = getenv(DEM_RESERVED_ENV);
  if (env && *env) {
    char *end;
    long r = strtol(env, &end, 10);
    if (*end || r < 0 || r > 4096)
      return proto_fail(err, "%s = '%s': expected a number of cores >= 0", DEM_RESERVED_ENV, env);
    p->reserved = (int)r;
  }
  p->on = 1;
  p->cap = m->n_grains / DEM_GRAINS_PER_THREAD;
  if (p->cap > p->cores - p->reserved) p->cap = p->cores - p->reserved;
  if (p->cap > DEM_MAX_THREADS) p->cap = DEM_MAX_THREADS;
  if (p->cap < 1) p->cap = 1;
  /* other processes now: runnable threads besides this one (least of a few looks) */
  int others = 1 << 20;
  for (int k = 0; k < 3; k++) {
    const int r = procs_running();
    if (r >= 1 && r - 1 < others) others = r - 1;
    if (k < 2) usleep(2000);
  }
  if (others == 1 << 20) others = 0;
  int n = p->cores - p->reserved - others;
  n = n > p->cap ? p->cap : (n < 1 ? 1 : n);
  set_threads(s, n);
  snprintf(s->threads_why, sizeof s->threads_why,
           "auto: %d cores allowed%s, %d reserved (%s), %d busy with other processes, at most 1 per %d grains "
           "(%d grains): %d thread%s", p->cores, bound, p->reserved, DEM_RESERVED_ENV, others, DEM_GRAINS_PER_THREAD,
           m->n_grains, n, n > 1 ? "s" : "");
  return 0;
}

void dem_threads_begin(dem_state *s) {
  dem_thread_probe *p = &s->work->probe;
  if (!p->on || p->cap < 2) return;
  p->step_t0 = now_s(CLOCK_MONOTONIC);
  if (p->win_t0 > 0) return;
  p->busy0 = busy_seconds();
  p->self0 = now_s(CLOCK_PROCESS_CPUTIME_ID);
  p->win_t0 = p->step_t0;
  p->in_step = 0;
}

/* Closes a window of DEM_PROBE_WINDOW s of stepping: the cores other
 * processes used while we stepped (lower bound: all time between steps
 * counted as theirs at full machine), and a new thread count; lower at
 * once, higher only after two windows agree. */
void dem_threads_end(dem_state *s) {
  dem_thread_probe *p = &s->work->probe;
  if (!p->on || p->cap < 2) return;
  const double t = now_s(CLOCK_MONOTONIC);
  p->in_step += t - p->step_t0;
  if (p->in_step < DEM_PROBE_WINDOW) return;
  const double busy = busy_seconds(), self = now_s(CLOCK_PROCESS_CPUTIME_ID);
  const double span = t - p->win_t0, gap = span - p->in_step;
  p->win_t0 = 0; /* next window at the next step */
  if (busy < 0 || p->busy0 < 0 || gap > 0.5 * span) return; /* unknown, or mostly not stepping */
  double others = ((busy - p->busy0) - (self - p->self0) - p->cores * gap) / p->in_step;
  if (others < 0) others = 0;
  int n = p->cores - p->reserved - (int)floor(others + 0.5);
  n = n > p->cap ? p->cap : (n < 1 ? 1 : n);
  const int cur = s->threads;
  p->up_votes = n > cur ? p->up_votes + 1 : 0;
  if (n < cur || (n > cur && p->up_votes >= 2)) {
    set_threads(s, n);
    p->up_votes = 0;
    snprintf(s->threads_why, sizeof s->threads_why,
             "auto: other processes used %.2f of %d cores while stepping (%d reserved): %d thread%s", others,
             p->cores, p->reserved, n, n > 1 ? "s" : "");
  }
}

/* libgomp's default wait at a barrier spins 300 000 times before sleeping:
 * with another process on the cores, the waiting thread burns the core its
 * partner could run on and every barrier stalls (bench/results/dem.md:
 * 2 threads of a 20 000-grain bed took 19 s instead of 2.4 s with a short
 * spin). libgomp reads its settings when it is loaded, so the program sets
 * a short spin and starts again. */
void dem_openmp_env(char **argv) {
  if (getenv("GOMP_SPINCOUNT") || getenv("OMP_WAIT_POLICY")) return; /* chosen by the user */
  if (setenv("GOMP_SPINCOUNT", DEM_GOMP_SPINCOUNT, 1)) return;
  execv("/proc/self/exe", argv); /* returns only on failure: then go on as we are */
}
