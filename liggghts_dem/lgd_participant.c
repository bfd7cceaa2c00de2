/* liggghts_dem — LIGGGHTS as cosim's DEM participant (role "dem",
 * proto/PROTOCOL.md), reading dem_server's config section. Under MPI
 * (`mpirun -np N liggghts_dem --endpoint EP --name NAME`) rank 0 alone talks to
 * the coupler: each callback broadcasts what it received to the other ranks,
 * which wait in worker_loop(), and then every rank does the same collective
 * work (do_*). `--check-config` runs without MPI.
 *
 * This file is the only one that knows the participant API (proto.h). */
#include "liggghts_dem/lgd.h"

#include <math.h>
#include <sched.h>
#include <stdio.h>
#include <sys/stat.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

enum { OP_CONFIGURE = 1, OP_INIT, OP_STEP, OP_FINISH, OP_SAVE, OP_LOAD, OP_QUIT };

typedef struct op_msg {
  int op, output;
  int64_t n_nodes, n_tri, len, restart_step;
  double dt, t; /* OP_LOAD: the checkpoint's coupling step and clock */
} op_msg;

/* A checkpoint's arrays (PROTOCOL.md "Checkpoints and restart"). */
#define LGD_STATE_RESTART "liggghts_restart" /* u1: LIGGGHTS' restart file, as written */
#define LGD_STATE_CLOCK "clock"              /* f8 [2]: t, coupling step (s) */
#define LGD_STATE_SURFACE_X "surface_x"      /* f8 [n_nodes, 3]: after the last DEM step */
#define LGD_STATE_SURFACE_V "surface_v"
#define LGD_STATE_FORCE "force"              /* f8 [n_grains, 3]: the last DEM step's, config order */
#define LGD_STATE_TORQUE "torque"
#define LGD_STATE_FILE "state.restart"       /* in app.state_dir, rank 0 */
/* the largest restart file taken back (bytes): a damaged checkpoint must not
 * make us allocate without bound; 2 GiB is ~10^7 grains with history */
#define LGD_STATE_MAX ((int64_t)1 << 31)

typedef struct app {
  int mpi, rank, clean;
  char name[PROTO_NAME_LEN], key_path[PROTO_NAME_LEN + 16], screen[1024];
  dem_model model;
  int have_model;
  lgd_sim *sim;
  double run_dt;
  int64_t n_nodes;
  double *x, *v;                    /* surface nodes of the step (every rank) */
  double *wall_row;                 /* t, then Fx Fy Fz per wall */
  double *snap;                     /* rank 0: x, v, omega [n*3] each, then r [n] */
  double *snap_x, *snap_v, *snap_w, *snap_r; /* into snap */
  double t_step, t_bcast;           /* rank 0: in step(), broadcasting to the ranks */
  int64_t restart_step;             /* > 0: init need not settle the bed */
  char state_dir[600];              /* rank 0: where LIGGGHTS' restart file goes */
  unsigned char *state_buf;         /* rank 0: the file's bytes (state_save) */
  size_t state_cap;
  double clock[2];                  /* t, coupling step */
  lgd_resume saved;                 /* the last lgd_save (surface: the sim's buffers) */
  double *load_ft;                  /* rank 0, state_load: forces, torques [n_grains*3] each */
  double bed_top;                   /* rank 0: ready's bed_top (dem_bed_ready_top) */
  int bed_top_grains;               /* the grains it was taken over (0: none, no bed_top) */
} app;

static app g_app; /* one per process; the exit handler reads it */

/* ------------------------------------------------ collective work (all ranks) */

static int do_configure(app *a, const char *json, double dt, proto_err *err) {
  if (a->have_model) dem_model_free(&a->model);
  a->have_model = 0;
  cJSON *section = proto_json_parse(json, a->key_path, err);
  int rc;
  if (a->mpi) /* collective: only rank 0 keeps the bed */
    rc = lgd_model_from_json(&a->model, section, a->key_path, MPI_COMM_WORLD, err);
  else
    rc = section ? dem_model_from_json(&a->model, section, a->key_path, err) : -1;
  cJSON_Delete(section);
  a->have_model = rc == 0;
  if (!rc) rc = lgd_check_model(&a->model, err);
  if (!rc && a->rank == 0) { /* dem_server's initial checks: overlaps, grains outside */
    dem_state probe;
    rc = dem_state_init(&a->model, &probe, dt, err); /* and the step of this coupling step */
    if (!rc) dem_state_free(&probe);
  }
  a->run_dt = dt;
  return rc;
}

static int do_init(app *a, int64_t n_nodes, const double *x0, int64_t n_tri, const int32_t *tri,
                   proto_err *err) {
  dem_model *m = &a->model;
  int rc = 0;
  a->n_nodes = n_nodes;
  if (n_nodes > 0) {
    a->x = malloc(sizeof(double) * 3 * (size_t)n_nodes);
    a->v = malloc(sizeof(double) * 3 * (size_t)n_nodes);
    rc = a->x && a->v ? dem_model_set_surface(m, (int)n_nodes, x0, (int)n_tri, tri, err)
                      : proto_fail(err, "out of memory");
  }
  int bad = rc, any;
  MPI_Allreduce(&bad, &any, 1, MPI_INT, MPI_MIN, MPI_COMM_WORLD);
  if (any < 0) return -1; /* deterministic: every rank failed alike */
  lgd_options o = {.screen = a->rank == 0 ? a->screen : NULL, .skip_settle = a->restart_step > 0};
  if (lgd_open(&a->sim, MPI_COMM_WORLD, m, a->run_dt, &o, err)) return -1;
  const size_t n = (size_t)m->n_grains;
  int fail = 0;
  if (a->rank == 0) {
    a->wall_row = calloc(1 + 3 * (size_t)m->n_walls, sizeof(double));
    a->snap = malloc(10 * n * sizeof(double));
    fail = !a->wall_row || !a->snap;
    if (!fail) {
      a->snap_x = a->snap;
      a->snap_v = a->snap + 3 * n;
      a->snap_w = a->snap + 6 * n;
      a->snap_r = a->snap + 9 * n;
      memcpy(a->snap_r, m->radius, n * sizeof(double));
    }
  }
  MPI_Allreduce(MPI_IN_PLACE, &fail, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD); /* before the collective gather */
  if (fail) return a->rank == 0 ? proto_fail(err, "out of memory") : -1;
  /* the settled bed's top as dem_server reports it in its ready (where the
   * lowered surface first touches a grain; scenario.rim_center "auto"): the
   * gathered grains */
  if (lgd_gather(a->sim, a->snap_x, a->snap_v, a->snap_w, err)) return -1;
  if (a->rank != 0) return 0;
  return dem_bed_ready_top(a->snap_x, m->radius, m->n_grains, x0, (int)n_nodes, tri, (int)n_tri,
                           &a->bed_top, &a->bed_top_grains, err);
}

static int do_step(app *a, double dt, int output, proto_err *err) {
  if (lgd_step(a->sim, dt, a->x, a->v, err)) return -1;
  return output ? lgd_gather(a->sim, a->snap_x, a->snap_v, a->snap_w, err) : 0;
}

static void do_finish(app *a) {
  lgd_close(a->sim);
  a->sim = NULL;
  if (a->have_model) dem_model_free(&a->model);
  a->have_model = 0;
  free(a->x); free(a->v); free(a->wall_row); free(a->snap);
  a->x = a->v = a->wall_row = a->snap = a->snap_x = a->snap_v = a->snap_w = a->snap_r = NULL;
}

/* rank 0: the path of the restart file, in a directory of our own */
static int state_path(app *a, char *path, size_t cap, proto_err *err) {
  if (!a->state_dir[0]) {
    const char *base = getenv("TMPDIR");
    snprintf(a->state_dir, sizeof a->state_dir, "%s/cosim-lgd-state-XXXXXX", base && base[0] ? base : "/tmp");
    if (!mkdtemp(a->state_dir)) {
      a->state_dir[0] = 0;
      return proto_fail(err, "cannot create a directory for LIGGGHTS' restart file under %s",
                        base && base[0] ? base : "/tmp");
    }
  }
  snprintf(path, cap, "%s/" LGD_STATE_FILE, a->state_dir);
  return 0;
}

/* Every rank: LIGGGHTS writes its restart file; rank 0 reads it back into
 * state_buf (*len bytes). */
static int do_save(app *a, size_t *len, proto_err *err) {
  char path[700] = "";
  int rc = a->rank == 0 ? state_path(a, path, sizeof path, err) : 0;
  MPI_Bcast(&rc, 1, MPI_INT, 0, MPI_COMM_WORLD);
  if (rc) return -1;
  if (lgd_save(a->sim, path, &a->saved, err)) return -1;
  a->clock[0] = a->saved.t;
  a->clock[1] = a->saved.coupling_dt;
  if (a->rank != 0) return 0;
  FILE *f = fopen(path, "rb");
  long size = -1;
  if (f && fseek(f, 0, SEEK_END) == 0) size = ftell(f);
  if (f) rewind(f);
  if (size > 0 && (size_t)size > a->state_cap) {
    unsigned char *bigger = realloc(a->state_buf, (size_t)size);
    if (bigger) a->state_buf = bigger, a->state_cap = (size_t)size;
  }
  rc = size > 0 && (size_t)size <= a->state_cap && fread(a->state_buf, 1, (size_t)size, f) == (size_t)size
           ? 0 : proto_fail(err, "%s: cannot read LIGGGHTS' restart file back", path);
  if (f) fclose(f);
  unlink(path);
  *len = rc ? 0 : (size_t)size;
  return rc;
}

/* Every rank: LIGGGHTS again, from the restart file rank 0 wrote to path,
 * with the clock in op and the surface in a->x, a->v. */
static int do_load(app *a, const op_msg *op, const char *path, proto_err *err) {
  lgd_close(a->sim);
  a->sim = NULL;
  const size_t n3 = 3 * (size_t)a->model.n_grains;
  const lgd_resume r = {.restart = path, .t = op->t, .coupling_dt = op->dt,
                        .surface_x = a->n_nodes > 0 ? a->x : NULL, .surface_v = a->n_nodes > 0 ? a->v : NULL,
                        .force = a->load_ft, .torque = a->load_ft ? a->load_ft + n3 : NULL};
  lgd_options o = {.screen = a->rank == 0 ? a->screen : NULL, .resume = &r};
  return lgd_open(&a->sim, MPI_COMM_WORLD, &a->model, op->dt > 0 ? op->dt : a->run_dt, &o, err);
}

/* Rank 0 sends the next operation; the others wait for it. A sleeping rank
 * wakes too late (measured: ~0.1 ms per step on an idle machine, 1–2 ms on a
 * loaded one, every step), and a busy-polling one takes a core from an FEM
 * that shares the machine (measured: its step 1.1 → 12 ms on 2 cores). So
 * they poll yielding the core — as fast as spinning on a core nobody else
 * wants, a scheduler tick late when other work is runnable — for OP_POLL_S,
 * longer than a coupling step's FEM and coupler time, and only then sleep
 * (long pauses: start-up, output), leaving if the launcher is gone. */
#define OP_POLL_S 0.02
#define OP_SLEEP_NS 1000000
static void bcast_op(op_msg *op) {
  MPI_Request req;
  MPI_Ibcast(op, (int)sizeof *op, MPI_BYTE, 0, MPI_COMM_WORLD, &req);
  if (g_app.rank == 0) {
    MPI_Wait(&req, MPI_STATUS_IGNORE);
    return;
  }
  const double poll_until = MPI_Wtime() + OP_POLL_S;
  for (int done = 0;;) {
    MPI_Test(&req, &done, MPI_STATUS_IGNORE);
    if (done) return;
    if (MPI_Wtime() < poll_until) {
      sched_yield();
      continue;
    }
    if (getppid() == 1) _exit(1);
    nanosleep(&(struct timespec){0, OP_SLEEP_NS}, NULL);
  }
}

static int worker_loop(app *a) {
  proto_err err = {{0}};
  char *text = NULL;
  int32_t *tri = NULL;
  double *x0 = NULL;
  for (;;) {
    op_msg op = {0};
    bcast_op(&op);
    switch (op.op) {
    case OP_CONFIGURE:
      text = malloc((size_t)op.len + 1);
      MPI_Bcast(text, (int)op.len + 1, MPI_CHAR, 0, MPI_COMM_WORLD);
      MPI_Bcast(a->key_path, sizeof a->key_path, MPI_CHAR, 0, MPI_COMM_WORLD);
      a->restart_step = op.restart_step;
      do_configure(a, text, op.dt, &err); /* rank 0 reports failures */
      free(text);
      break;
    case OP_INIT:
      x0 = malloc(sizeof(double) * 3 * (size_t)(op.n_nodes + 1));
      tri = malloc(sizeof(int32_t) * 3 * (size_t)(op.n_tri + 1));
      if (op.n_nodes > 0) {
        MPI_Bcast(x0, 3 * (int)op.n_nodes, MPI_DOUBLE, 0, MPI_COMM_WORLD);
        MPI_Bcast(tri, 3 * (int)op.n_tri, MPI_INT32_T, 0, MPI_COMM_WORLD);
      }
      do_init(a, op.n_nodes, x0, op.n_tri, tri, &err);
      free(x0);
      free(tri);
      break;
    case OP_STEP:
      if (a->n_nodes > 0) {
        MPI_Bcast(a->x, 3 * (int)a->n_nodes, MPI_DOUBLE, 0, MPI_COMM_WORLD);
        MPI_Bcast(a->v, 3 * (int)a->n_nodes, MPI_DOUBLE, 0, MPI_COMM_WORLD);
      }
      if (a->sim) do_step(a, op.dt, op.output, &err);
      break;
    case OP_FINISH:
      do_finish(a);
      break;
    case OP_SAVE: {
      size_t len;
      if (a->sim) do_save(a, &len, &err);
      break;
    }
    case OP_LOAD:
      if (a->n_nodes > 0) {
        MPI_Bcast(a->x, 3 * (int)a->n_nodes, MPI_DOUBLE, 0, MPI_COMM_WORLD);
        MPI_Bcast(a->v, 3 * (int)a->n_nodes, MPI_DOUBLE, 0, MPI_COMM_WORLD);
      }
      if (a->have_model) do_load(a, &op, "", &err);
      break;
    default:
      return 0;
    }
  }
}

/* ------------------------------------------- rank 0: the participant callbacks */

static int configure(void *user, const proto_run_info *info, const cJSON *section, proto_err *err) {
  app *a = user;
  snprintf(a->name, sizeof a->name, "%s", info->name ? info->name : "dem");
  snprintf(a->key_path, sizeof a->key_path, "%s", info->key_path);
  a->restart_step = info->restart_step;
  char *json = cJSON_PrintUnformatted(section);
  if (!json) return proto_fail(err, "out of memory");
  int rc;
  if (!a->mpi) {
    rc = do_configure(a, json, info->dt, err);
  } else {
    /* LIGGGHTS' screen: next to the process logs when the output folder is here */
    const char *dir = info->output_dir ? info->output_dir : ".";
    char logs[900];
    snprintf(logs, sizeof logs, "%s/logs", dir);
    const char *where = access(logs, W_OK) == 0 ? logs : access(dir, W_OK) == 0 ? dir : NULL;
    if (where) snprintf(a->screen, sizeof a->screen, "%s/%s.liggghts.log", where, a->name);
    else snprintf(a->screen, sizeof a->screen, "/tmp/cosim-%s-liggghts-%d.log", a->name, (int)getpid());
    op_msg op = {.op = OP_CONFIGURE, .len = (int64_t)strlen(json), .dt = info->dt,
                 .restart_step = info->restart_step};
    bcast_op(&op);
    MPI_Bcast(json, (int)op.len + 1, MPI_CHAR, 0, MPI_COMM_WORLD);
    MPI_Bcast(a->key_path, sizeof a->key_path, MPI_CHAR, 0, MPI_COMM_WORLD);
    rc = do_configure(a, json, info->dt, err);
  }
  cJSON_free(json);
  return rc;
}

static int init(void *user, const proto_msg *welcome, proto_msg *ready, proto_err *err) {
  app *a = user;
  const proto_array *xa = proto_msg_find(welcome, PROTO_A_SURFACE_X0);
  const double *x0 = NULL;
  const proto_array *tri = NULL;
  if (xa) {
    const int64_t tshape[2] = {-1, 3};
    x0 = proto_msg_get_f8(welcome, PROTO_A_SURFACE_X0, -1, 3, err);
    tri = proto_msg_get(welcome, PROTO_A_SURFACE_TRI, PROTO_I4, 2, tshape, err);
    if (!x0 || !tri) xa = NULL, x0 = NULL;
  }
  op_msg op = {.op = OP_INIT, .n_nodes = xa ? xa->shape[0] : 0, .n_tri = tri && xa ? tri->shape[0] : 0};
  bcast_op(&op);
  if (op.n_nodes > 0) {
    MPI_Bcast((void *)x0, 3 * (int)op.n_nodes, MPI_DOUBLE, 0, MPI_COMM_WORLD);
    MPI_Bcast((void *)tri->data, 3 * (int)op.n_tri, MPI_INT32_T, 0, MPI_COMM_WORLD);
  }
  if (do_init(a, op.n_nodes, x0, op.n_tri, op.n_tri ? (const int32_t *)tri->data : NULL, err)) return -1;
  const dem_model *m = &a->model;

  if (dem_ready_declare(m, ready, err)) return -1;
  cJSON *h = proto_msg_header(ready);
  int ranks;
  MPI_Comm_size(MPI_COMM_WORLD, &ranks);
  const double dt = lgd_dt(a->sim);
  cJSON_AddNumberToObject(h, "dem_dt", dt);
  cJSON_AddNumberToObject(h, "rayleigh_time", m->rayleigh_time);
  cJSON_AddNumberToObject(h, "grains", m->n_grains);
  cJSON_AddNumberToObject(h, "mpi_ranks", ranks);
  if (a->bed_top_grains > 0) cJSON_AddNumberToObject(h, PROTO_H_BED_TOP, a->bed_top);
  cJSON_AddNumberToObject(h, PROTO_H_BED_TOP_GRAINS, a->bed_top_grains);
  fprintf(stderr, "liggghts_dem: %d grains, %d walls, dt = %.4g s = %.3g Rayleigh times, %d MPI rank%s, "
          "LIGGGHTS screen in %s\n", m->n_grains, m->n_walls, dt, dt / m->rayleigh_time, ranks,
          ranks > 1 ? "s" : "", a->screen);
  return 0;
}

/* Where the time went, per coupling step, in the log (rank 0). */
static void log_timing(const app *a) {
  const lgd_timing *t = a->sim ? lgd_time(a->sim) : NULL;
  if (!t || t->steps == 0) return;
  const double k = 1e3 / (double)t->steps;
  const double *l = t->lig;
  fprintf(stderr, "liggghts_dem: %lld coupling steps (%lld DEM steps) on rank 0, ms per coupling step: "
          "participant %.3f = LIGGGHTS runs %.3f [its loop %.3f: pair %.3f, neighbour lists %.3f, "
          "communication %.3f, output %.3f, the rest (walls, meshes, integration) %.3f] + surface %.3f + nodal/wall forces %.3f + "
          "summary %.3f + broadcast to the ranks %.3f + reply %.3f\n",
          (long long)t->steps, (long long)t->substeps, a->t_step * k, t->run * k, l[LGD_LIG_LOOP] * k,
          l[LGD_LIG_PAIR] * k, l[LGD_LIG_NEIGH] * k, l[LGD_LIG_COMM] * k, l[LGD_LIG_OUTPUT] * k,
          (l[LGD_LIG_LOOP] - l[LGD_LIG_PAIR] - l[LGD_LIG_NEIGH] - l[LGD_LIG_COMM] - l[LGD_LIG_OUTPUT]) * k,
          t->surface * k, t->forces * k, t->summary * k, a->t_bcast * k,
          (a->t_step - t->total - a->t_bcast) * k);
}

static int step(void *user, proto_peer *peer, const proto_step_info *info, const proto_msg *req,
                proto_msg *reply, proto_err *err) {
  (void)peer;
  app *a = user;
  const double t0 = MPI_Wtime();
  op_msg op = {.op = OP_STEP, .dt = info->dt, .output = info->output};
  if (a->n_nodes > 0) { /* checked against the role table by the participant loop */
    memcpy(a->x, proto_msg_data(req, PROTO_A_X), sizeof(double) * 3 * (size_t)a->n_nodes);
    memcpy(a->v, proto_msg_data(req, PROTO_A_V), sizeof(double) * 3 * (size_t)a->n_nodes);
  }
  const double tb = MPI_Wtime();
  bcast_op(&op);
  if (a->n_nodes > 0) {
    MPI_Bcast(a->x, 3 * (int)a->n_nodes, MPI_DOUBLE, 0, MPI_COMM_WORLD);
    MPI_Bcast(a->v, 3 * (int)a->n_nodes, MPI_DOUBLE, 0, MPI_COMM_WORLD);
  }
  a->t_bcast += MPI_Wtime() - tb;
  if (do_step(a, op.dt, op.output, err)) return -1;
  const lgd_out *o = lgd_result(a->sim);
  const dem_model *m = &a->model;
  a->wall_row[0] = o->series[DEM_SERIES_T];
  memcpy(a->wall_row + 1, o->wall_force, sizeof(double) * 3 * (size_t)m->n_walls);
  if (proto_msg_add_f8(reply, PROTO_A_SERIES, DEM_N_SERIES, 0, o->series) ||
      proto_msg_add_prefixed(reply, PROTO_P_SERIES, DEM_WALL_FORCES, PROTO_F8, 1 + 3 * (int64_t)m->n_walls, 0,
                             a->wall_row) ||
      (a->n_nodes > 0 && proto_msg_add_f8(reply, PROTO_A_NODAL_FORCE, a->n_nodes, 3, o->nodal_force)))
    return proto_fail(err, "reply full");
  if (op.output) {
    const int n = m->n_grains;
    const double *snap[DEM_N_SNAP] = {a->snap_x, a->snap_v, a->snap_w, a->snap_r};
    for (int k = 0; k < DEM_N_SNAP; k++)
      if (proto_msg_add_prefixed(reply, PROTO_P_SNAP, DEM_SNAP[k], PROTO_F8, n, k == DEM_SNAP_R ? 0 : 3, snap[k]))
        return proto_fail(err, "reply full");
  }
  a->t_step += MPI_Wtime() - t0;
  return 0;
}

/* The whole changing state: LIGGGHTS' restart file, the clock, the surface
 * (lgd_save). The snapshot and reply buffers are rebuilt by every step. */
static int state_save(void *user, proto_msg *state, proto_err *err) {
  app *a = user;
  if (!a->sim) return proto_fail(err, "state_save before init");
  op_msg op = {.op = OP_SAVE};
  if (a->mpi) bcast_op(&op);
  size_t len = 0;
  if (do_save(a, &len, err)) return -1;
  const int64_t shape[1] = {(int64_t)len};
  if (proto_msg_add(state, PROTO_P_STATE LGD_STATE_RESTART, PROTO_U1, 1, shape, a->state_buf) ||
      proto_msg_add_prefixed(state, PROTO_P_STATE, LGD_STATE_CLOCK, PROTO_F8, 2, 0, a->clock) ||
      proto_msg_add_prefixed(state, PROTO_P_STATE, LGD_STATE_FORCE, PROTO_F8, a->model.n_grains, 3, a->saved.force) ||
      proto_msg_add_prefixed(state, PROTO_P_STATE, LGD_STATE_TORQUE, PROTO_F8, a->model.n_grains, 3,
                             a->saved.torque))
    return proto_fail(err, "state message full");
  if (a->n_nodes == 0) return 0;
  const lgd_resume *r = &a->saved;
  if (proto_msg_add_prefixed(state, PROTO_P_STATE, LGD_STATE_SURFACE_X, PROTO_F8, a->n_nodes, 3, r->surface_x) ||
      proto_msg_add_prefixed(state, PROTO_P_STATE, LGD_STATE_SURFACE_V, PROTO_F8, a->n_nodes, 3, r->surface_v))
    return proto_fail(err, "state message full");
  return 0;
}

static int state_load(void *user, const proto_msg *state, proto_err *err) {
  app *a = user;
  if (!a->have_model) return proto_fail(err, "state_load before configure");
  const proto_array *rs = proto_msg_find(state, PROTO_P_STATE LGD_STATE_RESTART);
  if (!rs || rs->dtype != PROTO_U1 || rs->ndim != 1 || rs->shape[0] < 1 || rs->shape[0] > LGD_STATE_MAX)
    return proto_fail(err, "state: '%s%s' must be a u1 array of 1 to %lld bytes (LIGGGHTS' restart file)",
                      PROTO_P_STATE, LGD_STATE_RESTART, (long long)LGD_STATE_MAX);
  double clock[2];
  if (proto_state_get(state, LGD_STATE_CLOCK, PROTO_F8, 2, clock, err)) return -1;
  if (!(clock[0] >= 0) || !isfinite(clock[0]) || !(clock[1] >= 0) || !isfinite(clock[1]))
    return proto_fail(err, "state.%s: t and the coupling step must be finite and >= 0 (got %g, %g)",
                      LGD_STATE_CLOCK, clock[0], clock[1]);
  const size_t g3 = 3 * (size_t)a->model.n_grains;
  if (!a->load_ft && !(a->load_ft = malloc(sizeof(double) * 2 * g3))) return proto_fail(err, "out of memory");
  if (proto_state_get(state, LGD_STATE_FORCE, PROTO_F8, g3, a->load_ft, err) ||
      proto_state_get(state, LGD_STATE_TORQUE, PROTO_F8, g3, a->load_ft + g3, err))
    return -1;
  const size_t n3 = 3 * (size_t)a->n_nodes;
  if (n3 && (proto_state_get(state, LGD_STATE_SURFACE_X, PROTO_F8, n3, a->x, err) ||
             proto_state_get(state, LGD_STATE_SURFACE_V, PROTO_F8, n3, a->v, err)))
    return -1;
  char path[700];
  if (state_path(a, path, sizeof path, err)) return -1;
  FILE *f = fopen(path, "wb");
  int rc = f && fwrite(rs->data, 1, (size_t)rs->shape[0], f) == (size_t)rs->shape[0] ? 0 : -1;
  if (f && fclose(f)) rc = -1;
  if (rc) {
    unlink(path);
    return proto_fail(err, "%s: cannot write LIGGGHTS' restart file", path);
  }
  op_msg op = {.op = OP_LOAD, .t = clock[0], .dt = clock[1]};
  if (a->mpi) {
    bcast_op(&op);
    if (a->n_nodes > 0) {
      MPI_Bcast(a->x, 3 * (int)a->n_nodes, MPI_DOUBLE, 0, MPI_COMM_WORLD);
      MPI_Bcast(a->v, 3 * (int)a->n_nodes, MPI_DOUBLE, 0, MPI_COMM_WORLD);
    }
  }
  rc = do_load(a, &op, path, err);
  unlink(path);
  return rc;
}

static void finish(void *user) {
  app *a = user;
  log_timing(a);
  if (a->mpi) {
    op_msg op = {.op = OP_FINISH};
    bcast_op(&op);
  }
  do_finish(a);
  free(a->state_buf);
  free(a->load_ft);
  a->load_ft = NULL;
  a->state_buf = NULL;
  a->state_cap = 0;
  if (a->state_dir[0]) rmdir(a->state_dir);
  a->state_dir[0] = 0;
}

/* LIGGGHTS reports its input errors on its screen and then exits: show the
 * end of that screen in our log, where the coupler looks. */
static void show_screen_tail(void) {
  if (g_app.clean || g_app.rank != 0 || !g_app.screen[0]) return;
  FILE *f = fopen(g_app.screen, "r");
  if (!f) return;
  char buf[2048];
  fseek(f, 0, SEEK_END);
  long size = ftell(f), from = size > (long)sizeof buf - 1 ? size - (long)sizeof buf + 1 : 0;
  fseek(f, from, SEEK_SET);
  size_t n = fread(buf, 1, sizeof buf - 1, f);
  fclose(f);
  buf[n] = 0;
  fprintf(stderr, "liggghts_dem: LIGGGHTS stopped the run; the end of its screen (%s):\n%s\n",
          g_app.screen, buf);
}

int main(int argc, char **argv) {
  int mpi = 1;
  for (int i = 1; i < argc; i++)
    if (!strcmp(argv[i], "--check-config") || !strcmp(argv[i], "--help") || !strcmp(argv[i], "-h")) mpi = 0;
  const proto_participant_ops ops = {.role = PROTO_ROLE_DEM, .configure = configure, .init = init,
                                     .step = step, .finish = finish, .state_save = state_save,
                                     .state_load = state_load};
  app *a = &g_app;
  if (!mpi) return proto_participant_main(argc, argv, &ops, a);
  MPI_Init(&argc, &argv);
  a->mpi = 1;
  MPI_Comm_rank(MPI_COMM_WORLD, &a->rank);
  int rc = 0;
  if (a->rank == 0) {
    atexit(show_screen_tail);
    rc = proto_participant_main(argc, argv, &ops, a);
    op_msg quit = {.op = OP_QUIT};
    bcast_op(&quit);
  } else {
    rc = worker_loop(a);
  }
  a->clean = 1;
  MPI_Finalize();
  return rc;
}
