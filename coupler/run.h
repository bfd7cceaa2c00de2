/* run.h — the state of one coupled run, shared by run.c (setup, handshake,
 * teardown) and loop.c (the lock-step exchange). Internal to the coupler. */
#ifndef COSIM_COUPLER_RUN_H
#define COSIM_COUPLER_RUN_H

#include "internal.h"

typedef struct cpl_peer {
  cpl_process *proc;
  int connected; /* hello received */
  int stopped;   /* bye received or known gone */
  proto_msg reply;
} cpl_peer;

/* The shared surface of the tread: node positions in the rim frame at rest,
 * and the current world positions/velocities and grain forces on them. */
typedef struct cpl_surface {
  int64_t n_nodes, n_tris;
  double *x0;    /* [n,3] rim frame (owned) */
  int32_t *tri;  /* [m,3] */
  double *x, *v; /* [n,3] world, current */
  double *force; /* [n,3] world: grains on the tread */
} cpl_surface;

typedef struct cpl_runner {
  cpl_scene *scene;
  const cpl_run_opts *opts;
  void *ctx, *router;
  cpl_bus *bus;
  cpl_output *out;
  char run_dir[CPL_PATH_LEN];
  char ctl_endpoint[CPL_PATH_LEN];
  char bus_inner[CPL_PATH_LEN];
  int n;
  cpl_peer peers[CPL_MAX_PROCS];
  cpl_child children[CPL_MAX_PROCS];
  int nchildren;
  int dem, fem, block; /* peer indices or -1 */
  cpl_surface surf;
  cpl_rim rim;
  double d_road, road_velocity, road_force_last; /* block road body */
  double wall_start;
  int failed_peer; /* index of the participant that failed, or -1 */
  proto_err err;
} cpl_runner;

/* Receives the next message from `expect` (a peer index, or -1 for any
 * peer), watching the children, the deadline and Ctrl-C. The sender's index
 * goes to *from. Returns -1 with r->err set and r->failed_peer naming the
 * culprit when one can be named. */
int cpl_receive(cpl_runner *r, int expect, double timeout_s, proto_msg *m,
                int *from);
int cpl_send(cpl_runner *r, int peer, const proto_msg *m);
/* The lock-step loop over all steps (loop.c). */
int cpl_step_loop(cpl_runner *r);

/* Set by the SIGINT/SIGTERM handler: the only process-wide state, because a
 * signal handler can reach nothing else. */
extern volatile int cpl_interrupted;

#endif
