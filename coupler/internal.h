/* internal.h — coupler internals shared by its files (not a public API). */
#ifndef COSIM_COUPLER_INTERNAL_H
#define COSIM_COUPLER_INTERNAL_H

#include <sys/types.h>

#include "coupler.h"

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
 * in its own process group, output to log_path. */
int cpl_spawn(cpl_child *c, const char *name, int argc, const char *const *argv,
              const char *endpoint, const char *log_path, proto_err *err);
/* Returns 1 if the child has just been found to have exited. */
int cpl_child_poll(cpl_child *c);
/* Last `lines` lines of the child's log into out. */
void cpl_child_tail(const cpl_child *c, char *out, size_t cap, int lines);
/* Waits grace_s for children (and their process groups) to exit, then
 * SIGTERM, then SIGKILL, to each whole group; reaps. */
void cpl_stop_all(cpl_child *cs, int n, double grace_s);

/* ---- bus.c: XSUB/XPUB proxy in a thread */
typedef struct cpl_bus cpl_bus;
/* inner: where publishers connect (participants get it in welcome);
 * public_ep: where monitors connect. Either may have port 0 (any free
 * port): the endpoints actually bound go to inner_out / public_out (cap
 * bytes each; inner_out may alias inner). */
cpl_bus *cpl_bus_start(void *ctx, const char *inner, const char *public_ep,
                       int hwm, char *inner_out, char *public_out, size_t cap,
                       proto_err *err);
void *cpl_bus_pub(cpl_bus *b); /* the coupler's own publisher */
void cpl_bus_stop(cpl_bus *b);

/* ---- output.c: results.h5 and XDMF */
typedef struct cpl_output cpl_output;
cpl_output *cpl_output_open(const cpl_scene *s, proto_err *err);
/* Declares a participant's datasets from its ready message. */
int cpl_output_participant(cpl_output *o, const char *name,
                           const proto_msg *ready, proto_err *err);
/* Appends series rows and, at output steps, writes snapshot arrays. */
int cpl_output_done(cpl_output *o, const char *name, const proto_msg *done,
                    int output_step, proto_err *err);
int cpl_output_coupler_row(cpl_output *o, const char *dataset, int ncols,
                           const char *const *columns, const double *row,
                           proto_err *err);
int cpl_output_flush(cpl_output *o);
/* Root attributes "control_endpoint", "bus_monitor" (the bound endpoints). */
int cpl_output_endpoints(cpl_output *o, const char *control, const char *bus,
                         proto_err *err);
int cpl_output_close(cpl_output *o);
const char *cpl_output_path(const cpl_output *o);
/* The last row written to a participant's "series" (for the summary). */
int cpl_output_summary(const cpl_output *o, char *out, size_t cap);

/* ---- run.c */
/* output.dir/endpoints.json: the endpoints a run actually bound */
#define CPL_ENDPOINTS_FILE "endpoints.json"

typedef struct cpl_run_opts {
  int attach;           /* wait for participants started by hand */
  int progress;         /* show progress (tty) */
  int quiet;            /* no schedule, no timing table */
} cpl_run_opts;
int cpl_run(cpl_scene *s, const cpl_run_opts *opts);

/* ---- monitor.c */
int cpl_monitor_main(int argc, char **argv);

#endif
