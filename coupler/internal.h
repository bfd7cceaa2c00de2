/* internal.h — coupler internals shared by its files (not a public API). */
#ifndef COSIM_COUPLER_INTERNAL_H
#define COSIM_COUPLER_INTERNAL_H

#include <sys/types.h>

#include "coupler.h"

/* ---- affinity.c: coupling.affinity (the hand-offs of a step on one core) */
typedef struct cpl_affinity {
  int core;         /* the hand-off core, or -1: nothing bound */
  char places[512]; /* OMP_PLACES for the children: "{core},{c1},..." */
  char why[384];    /* what was done or why not (the schedule printout) */
} cpl_affinity;
/* Decides from the scene, the CPUs the coupler may use, the threads already
 * bound to one of them alone (the hand-off core is the least taken) and the
 * environment (a user's OMP_PLACES / OMP_PROC_BIND is kept); before the
 * children start. */
void cpl_affinity_plan(const cpl_scene *s, int attach, cpl_affinity *a);
/* In a child between fork and exec (a core only): OMP_PLACES, OMP_PROC_BIND, a
 * short GOMP_SPINCOUNT (unless the user chose the waits), SCHED_BATCH; 1 when
 * it chose the OpenMP waits (else the launcher makes them passive). */
int cpl_affinity_child_env(const cpl_affinity *a);
/* Binds the calling thread (the loop) to the hand-off core, if any; a
 * failure is a warning: the results are the same unbound. */
void cpl_affinity_pin_self(const cpl_affinity *a);

/* ---- launch.c: child processes */
typedef struct cpl_child {
  char name[PROTO_NAME_LEN];
  char exec[CPL_PATH_LEN];
  char log_path[CPL_PATH_LEN];
  pid_t pid;
  int running;
  int status;    /* waitpid status once exited */
  char how[128]; /* "exited with status 3", "was killed by signal 11 (...)" */
} cpl_child;

/* Starts argv (launcher prefix + participant) + --endpoint EP --name NAME
 * in its own process group, output to log_path; curve_file (or NULL): its
 * CURVE key file, passed in the environment (never on the command line). */
int cpl_spawn(cpl_child *c, const char *name, int argc, const char *const *argv,
              const char *endpoint, const char *log_path, const char *curve_file,
              const cpl_affinity *affinity, proto_err *err);
/* Returns 1 if the child has just been found to have exited. */
int cpl_child_poll(cpl_child *c);
/* Last `lines` lines of the child's log into out. */
void cpl_child_tail(const cpl_child *c, char *out, size_t cap, int lines);
/* Waits grace_s for children (and their process groups) to exit, then
 * SIGTERM, then SIGKILL, to each whole group; reaps. */
void cpl_stop_all(cpl_child *cs, int n, double grace_s);

/* ---- bus.c: the monitor bus, a proxy in a thread */
typedef struct cpl_bus cpl_bus;
struct cpl_zap; /* zap.c, below */
typedef struct cpl_bus_eps {
  char inner[CPL_PATH_LEN];     /* where publishers connect (welcome.run.bus) */
  char monitor[CPL_PATH_LEN];   /* monitors: everything but snapshots */
  char snapshots[CPL_PATH_LEN]; /* monitors: the snapshot stream */
} cpl_bus_eps;
/* Binds the endpoints in eps (port 0: any free port; replaced by what was
 * bound) in the bus's own ZeroMQ context (ctx is not used for them: the
 * bus's threads run at nice 10, behind the run's). With the run's CURVE keys (zap, or
 * NULL) every side is a CURVE server (ZAP domains CPL_ZAP_BUS for the inner
 * side, CPL_ZAP_MONITOR for the others), with a ZAP handler of its own. */
cpl_bus *cpl_bus_start(void *ctx, cpl_bus_eps *eps, int hwm, int snapshot_hwm,
                       const struct cpl_zap *zap, proto_err *err);
/* The coupler's own publisher; NULL while no monitor subscribes to anything
 * (a message then reaches nobody: PUB drops it), so the loop builds none. */
void *cpl_bus_pub(cpl_bus *b);
/* Does any monitor subscribe on the snapshot stream? If not, the loop need
 * not copy its snapshots onto the bus (they would be dropped). */
int cpl_bus_snapshots_wanted(cpl_bus *b);
void cpl_bus_stop(cpl_bus *b);

/* ---- output.c: results.h5 and XDMF */
typedef struct cpl_output cpl_output;
/* Creates output.dir/results.h5; or, when continue_step >= 0 (a restart)
 * and the file exists, continues it after the rows of that step (what
 * came later goes: the restart computes it again). */
cpl_output *cpl_output_open(const cpl_scene *s, int64_t continue_step, proto_err *err);
/* 1 once a write or flush of the results failed (exit 4, not the
 * participant's fault). */
int cpl_output_io_failed(const cpl_output *o);
/* Declares a participant's datasets from its ready message. */
int cpl_output_participant(cpl_output *o, const char *name,
                           const proto_msg *ready, proto_err *err);
/* Appends series rows and, at output steps, writes snapshot arrays. */
int cpl_output_done(cpl_output *o, const char *name, const proto_msg *done,
                    int output_step, proto_err *err);
int cpl_output_coupler_row(cpl_output *o, const char *dataset, int ncols,
                           const char *const *columns, const double *row,
                           proto_err *err);
int cpl_output_flush(cpl_output *o, proto_err *err);
/* Root attributes "control_endpoint", "bus_monitor" (the bound endpoints). */
int cpl_output_endpoints(cpl_output *o, const char *control, const char *bus,
                         proto_err *err);
int cpl_output_close(cpl_output *o, proto_err *err);
/* Bytes the output may still need to write after a write error: what a
 * final flush writes (buffered rows, metadata). */
int64_t cpl_output_pending_bytes(const cpl_output *o);
const char *cpl_output_path(const cpl_output *o);
/* The last row written to a participant's "series" (for the summary). */
int cpl_output_summary(const cpl_output *o, char *out, size_t cap);

/* ---- run.c */
/* Exit codes of `cosim run` (README "What runs"). */
enum { CPL_EXIT_OK = 0, CPL_EXIT_USAGE = 1, CPL_EXIT_PARTICIPANT = 3, CPL_EXIT_OUTPUT = 4,
       CPL_EXIT_INTERRUPTED = 130 };
/* output.dir/endpoints.json: the endpoints a run actually bound */
#define CPL_ENDPOINTS_FILE "endpoints.json"

typedef struct cpl_run_opts {
  int attach;           /* wait for participants started by hand */
  int progress;         /* show progress (tty) */
  int quiet;            /* no schedule, no timing table */
  int overwrite;        /* replace an earlier run's results.h5 */
  const char *restart;  /* checkpoint file, or "latest" (NULL: none) */
  int branch;           /* restart is a --branch: a new run from its state */
} cpl_run_opts;

/* ---- outdir.c: output.dir — the lock, the kept-results rule, a reserve */
#define CPL_RESULTS_FILE "results.h5"
#define CPL_LOCK_FILE ".cosim.lock"
int cpl_mkdirs(const char *path, proto_err *err);
/* Takes the run's exclusive lock on dir (made if needed), kept until
 * cpl_outdir_unlock: a second run into the same dir is refused at once,
 * naming the holder's pid. Returns the lock's fd, or -1. */
int cpl_outdir_lock(const char *dir, proto_err *err);
void cpl_outdir_unlock(int fd);
/* The kept-results rule for dir/results.h5 before anything is written:
 * absent: fine; an HDF5 file: continued by a restart, replaced with
 * overwrite, else refused; anything else: always refused. */
int cpl_outdir_results(const char *dir, int restart, int overwrite, proto_err *err);
/* A file of `bytes` in dir that a write error frees, so the results can be
 * closed complete on a full disk (0 on success). */
int cpl_reserve_make(const char *dir, int64_t bytes, proto_err *err);
void cpl_reserve_release(const char *dir);

/* ---- zap.c: CURVE keys of a run and the ZAP handler (security.curve) */
#define CPL_ZAP_CONTROL "cosim.control"
#define CPL_ZAP_BUS "cosim.bus"
#define CPL_ZAP_MONITOR "cosim.monitor"
typedef struct cpl_zap cpl_zap;
/* Makes the run's keys (the coupler's pair, one pair per process and one
 * for monitors), writes the client key files into the private dir (0600)
 * and starts the ZAP handler on ctx, before any CURVE socket binds. */
cpl_zap *cpl_zap_start(void *ctx, const char *dir, const cpl_scene *s, proto_err *err);
const char *cpl_zap_secret(const cpl_zap *z);    /* the coupler's */
const char *cpl_zap_public(const cpl_zap *z);
const char *cpl_zap_key_file(const cpl_zap *z, int proc); /* process i's */
const char *cpl_zap_monitor_file(const cpl_zap *z);
void cpl_zap_stop(cpl_zap *z); /* also removes the key files */
/* One more ZAP handler with z's keys, on another context (the bus's). */
typedef struct cpl_zap_handler cpl_zap_handler;
cpl_zap_handler *cpl_zap_serve(const cpl_zap *z, void *ctx, proto_err *err);
void cpl_zap_handler_stop(cpl_zap_handler *h);
int cpl_run(cpl_scene *s, const cpl_run_opts *opts);

/* ---- monitor.c */
int cpl_monitor_main(int argc, char **argv);

#endif
