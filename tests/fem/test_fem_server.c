/* End to end: runs the real fem_server process and plays the coupler on a
 * ROUTER socket (PROTOCOL.md, role "fem"). Checks the ready message (surface
 * mesh outward-oriented, series and snapshot declarations), the rim frame
 * (a rigidly moving, unloaded, pre-inflated tread returns x = R x0 + c and
 * v = v_c + omega x (x - c) up to the centrifugal drift of the spinning
 * rim), snapshot arrays at output steps, a response to nodal forces
 * (explicit and quasi-static), and a clean stop. */
#include "fem_test.h"

#include <signal.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>
#include <zmq.h>

static void *ctx, *router;
static char endpoint[128];
static pid_t child; /* killed when a check fails, so the test never hangs */

static void kill_child(void) {
  if (child > 0) kill(child, SIGKILL);
}

static pid_t spawn(const char *exe) {
  pid_t pid = fork();
  if (pid == 0) {
    execl(exe, exe, "--endpoint", endpoint, "--name", "fem", (char *)NULL);
    _exit(127);
  }
  return pid;
}

static void recv_msg(proto_msg *m, const char *want_type) {
  proto_err err;
  char id[PROTO_NAME_LEN];
  if (proto_poll_in(router, 60000) != 1) {
    fprintf(stderr, "FAIL: no message from fem_server (waiting for %s)\n", want_type);
    exit(1);
  }
  OK(proto_recv(router, m, id, &err));
  /* liveness: a long init (the static solve under a sanitizer) sends heartbeats */
  while (strcmp(m->type, proto_msg_type(PROTO_MSG_HEARTBEAT)) == 0) {
    if (proto_poll_in(router, 60000) != 1) {
      fprintf(stderr, "FAIL: only heartbeats from fem_server (waiting for %s)\n", want_type);
      exit(1);
    }
    OK(proto_recv(router, m, id, &err));
  }
  if (strcmp(m->type, want_type) != 0) {
    const cJSON *msg = m->header ? cJSON_GetObjectItem(m->header, PROTO_H_MESSAGE) : NULL;
    fprintf(stderr, "FAIL: expected '%s', got '%s' %s\n", want_type, m->type,
            cJSON_IsString(msg) ? msg->valuestring : "");
    exit(1);
  }
}

static void send_msg(proto_msg *m) {
  proto_err err;
  OK(proto_send_to(router, "fem", m, &err));
}

static void rot_y(double th, double *R) { /* row-major rotation about y */
  double c = cos(th), s = sin(th);
  double r[9] = {c, 0, s, 0, 1, 0, -s, 0, c};
  memcpy(R, r, sizeof r);
}

static int run(const char *exe, const char *mode, const char *element) {
  proto_msg m = {0};
  pid_t pid = spawn(exe);
  child = pid;
  recv_msg(&m, "hello");
  char cfg[1024];
  snprintf(cfg, sizeof cfg,
           "{\"exec\":\"fem_server\",\"mesh\":{\"generate\":\"tread\",\"refine\":0.5,\"lugs\":16},"
           "\"material\":{\"E\":2e7,\"nu\":0.45,\"density\":1100,\"damping\":20},"
           "\"fixed\":{\"group\":\"rim\"},\"pressure\":{\"group\":\"inner\",\"value\":2e5},"
           "\"mode\":\"%s\",\"element\":\"%s\"}", mode, element);
  proto_msg_reset(&m, "fem", "welcome", 0, 0);
  cJSON *h = proto_msg_header(&m);
  cJSON_AddItemToObject(h, PROTO_H_CONFIG, cJSON_Parse(cfg));
  cJSON *run = cJSON_AddObjectToObject(h, PROTO_H_RUN);
  const double dt = 2e-4;
  cJSON_AddNumberToObject(run, PROTO_H_DT, dt);
  cJSON_AddNumberToObject(run, "t_end", 10 * dt);
  cJSON_AddNumberToObject(run, "n_steps", 10);
  cJSON_AddNumberToObject(run, "output_every", 2);
  cJSON_AddStringToObject(run, "output_dir", "/tmp");
  send_msg(&m);
  recv_msg(&m, "ready");
  proto_err err;
  const proto_array *xa = proto_msg_find(&m, PROTO_A_SURFACE_X0),
                    *ta = proto_msg_find(&m, PROTO_A_SURFACE_TRI);
  CHECK(xa && ta && xa->ndim == 2 && xa->shape[1] == 3 && ta->shape[1] == 3, "ready lacks the surface mesh");
  int64_t n = xa->shape[0], nt = ta->shape[0];
  double *x0 = malloc(sizeof *x0 * 3 * n);
  memcpy(x0, xa->data, sizeof *x0 * 3 * n);
  const int32_t *tri = ta->data;
  /* lug-top triangles (all corners at the outer radius) face outward */
  double rmax = 0;
  for (int64_t i = 0; i < n; i++) rmax = fmax(rmax, hypot(x0[3 * i], x0[3 * i + 2]));
  int outward = 0, inward = 0;
  for (int64_t k = 0; k < nt; k++) {
    const double *a = x0 + 3 * tri[3 * k], *b = x0 + 3 * tri[3 * k + 1], *c = x0 + 3 * tri[3 * k + 2];
    if (hypot(a[0], a[2]) < rmax - 1e-3 || hypot(b[0], b[2]) < rmax - 1e-3 || hypot(c[0], c[2]) < rmax - 1e-3)
      continue;
    double u[3], v[3];
    for (int d = 0; d < 3; d++) { u[d] = b[d] - a[d]; v[d] = c[d] - a[d]; }
    double nx = u[1] * v[2] - u[2] * v[1], nz = u[0] * v[1] - u[1] * v[0];
    if (nx * a[0] + nz * a[2] > 0) outward++; else inward++;
  }
  /* every triangle index in range, every surface node used */
  int bad_index = 0;
  char *used = calloc(n, 1);
  for (int64_t k = 0; k < 3 * nt; k++) {
    if (tri[k] < 0 || tri[k] >= n) bad_index++;
    else used[tri[k]] = 1;
  }
  int unused = 0;
  for (int64_t i = 0; i < n; i++) unused += !used[i];
  free(used);
  CHECK(bad_index == 0 && unused == 0, "%s %s: %d triangle indices out of range, %d surface nodes unused",
        mode, element, bad_index, unused);
  printf("%s %s: ready: %lld surface nodes, %lld triangles; lug-top triangles outward %d, inward %d\n", mode, element,
         (long long)n, (long long)nt, outward, inward);
  CHECK(outward > 0 && inward == 0, "surface triangles not outward");
  const cJSON *series = cJSON_GetObjectItem(m.header, "series");
  CHECK(series && cJSON_GetArraySize(cJSON_GetObjectItem(series, "series")) == 5, "series columns");
  const cJSON *snap = cJSON_GetObjectItem(m.header, "snapshot");
  CHECK(snap && proto_msg_find(&m, "mesh.cells") && proto_msg_find(&m, "mesh.x0"), "snapshot declaration");
  int64_t n_nodes = proto_msg_find(&m, "mesh.x0")->shape[0], n_el = proto_msg_find(&m, "mesh.cells")->shape[0];

  double *force = calloc(3 * n, sizeof *force), R[9];
  double c[3] = {0.1, 0.0, 0.3}, w[3] = {0, 2.0, 0}, vc[3] = {1.0, 0, 0};
  double e_first = 0;
  for (int k = 1; k <= 4; k++) {
    double th = 0.2 * k;
    rot_y(th, R);
    if (k >= 3) /* push the bottom of the tread up with 2 kN in total */
      for (int64_t i = 0; i < n; i++) {
        double xw[3];
        for (int a = 0; a < 3; a++) xw[a] = R[3 * a] * x0[3 * i] + R[3 * a + 1] * x0[3 * i + 1] + R[3 * a + 2] * x0[3 * i + 2];
        force[3 * i + 2] = xw[2] < -0.26 ? 1 : 0;
      }
    double ftot = 0;
    for (int64_t i = 0; i < n; i++) ftot += force[3 * i + 2];
    for (int64_t i = 0; i < n && ftot > 0; i++) force[3 * i + 2] *= 2000 / ftot;
    proto_msg_reset(&m, "fem", "step", k, (k - 1) * dt);
    cJSON_AddNumberToObject(proto_msg_header(&m), PROTO_H_DT, dt);
    cJSON_AddBoolToObject(proto_msg_header(&m), PROTO_H_OUTPUT, k % 2 == 0);
    proto_msg_add_f8(&m, PROTO_A_NODAL_FORCE, n, 3, force);
    proto_msg_add_f8(&m, PROTO_A_RIM_R, 3, 3, R);
    proto_msg_add_f8(&m, PROTO_A_RIM_C, 3, 0, c);
    proto_msg_add_f8(&m, PROTO_A_RIM_OMEGA, 3, 0, w);
    proto_msg_add_f8(&m, PROTO_A_RIM_V, 3, 0, vc);
    send_msg(&m);
    recv_msg(&m, "done");
    const double *x = proto_msg_get_f8(&m, PROTO_A_X, n, 3, &err),
                 *v = proto_msg_get_f8(&m, PROTO_A_V, n, 3, &err);
    const double *row = proto_msg_get_f8(&m, PROTO_A_SERIES, FEM_N_SERIES, 0, &err);
    CHECK(x && v && row, "done lacks x, v or series: %s", err.msg);
    if (!x || !v || !row) break;
    double ex = 0, ev = 0;
    for (int64_t i = 0; i < n; i++) {
      double r[3], vr[3];
      for (int a = 0; a < 3; a++) r[a] = R[3 * a] * x0[3 * i] + R[3 * a + 1] * x0[3 * i + 1] + R[3 * a + 2] * x0[3 * i + 2];
      vr[0] = vc[0] + w[1] * r[2] - w[2] * r[1];
      vr[1] = vc[1] + w[2] * r[0] - w[0] * r[2];
      vr[2] = vc[2] + w[0] * r[1] - w[1] * r[0];
      for (int a = 0; a < 3; a++) {
        ex = fmax(ex, fabs(x[3 * i + a] - c[a] - r[a]));
        ev = fmax(ev, fabs(v[3 * i + a] - vr[a]));
      }
    }
    printf("%s step %d: t %.4g, strain energy %.4g J, kinetic %.3g J, sub-step %.3g s x %g; "
           "max |x - (R x0 + c)| %.2e m, max |v - rigid| %.2e m/s\n", mode, k, m.t,
           row[FEM_SERIES_STRAIN], row[FEM_SERIES_KINETIC], row[FEM_SERIES_DT_SUB],
           row[FEM_SERIES_SUB_STEPS], ex, ev);
    if (k == 1) e_first = row[FEM_SERIES_STRAIN];
    if (k <= 2) {
      /* The tread starts at rest relative to a rim spinning at |w| = 2 rad/s:
       * only the centrifugal force moves it off the rigid motion. Explicit:
       * no node outruns a free particle at the outer radius, whose leapfrog
       * path after n sub-steps is a dt^2 n(n+1)/2 with a = w^2 r_max
       * (factor 1.5 for elastic pulls between nodes). Quasi-static: the
       * steady stretch stays below that of a free thin ring at r_max,
       * rho w^2 r^3/E (the rim nodes are held), and the velocity vanishes
       * once the lagged frame load has converged (step 2). */
      const double a_cf = w[1] * w[1] * rmax, ns = k * row[FEM_SERIES_SUB_STEPS];
      const double dts = row[FEM_SERIES_DT_SUB];
      const double x_free = 0.5 * a_cf * dts * dts * ns * (ns + 1), v_free = a_cf * dts * ns;
      const double x_ring = 1100 * w[1] * w[1] * rmax * rmax * rmax / 2e7;
      if (strcmp(mode, "explicit") == 0) {
        CHECK(ex > 0.2 * x_free && ex < 1.5 * x_free,
              "%s: motion off the rigid rim %.3e m, expected the centrifugal drift ~%.3e m", mode, ex,
              x_free);
        CHECK(ev > 0.2 * v_free && ev < 1.5 * v_free,
              "%s: velocity off the rigid rim %.3e m/s, expected ~%.3e m/s", mode, ev, v_free);
      } else {
        CHECK(ex > 1e-3 * x_ring && ex < x_ring,
              "%s: steady centrifugal stretch %.3e m, expected below the free ring's %.3e m", mode,
              ex, x_ring);
        if (k == 2) CHECK(ev < 1e-5, "%s: rigid velocity not reproduced (%.3e m/s)", mode, ev);
      }
      CHECK(e_first > 0, "%s: inflation gives no strain energy", mode);
    } else {
      CHECK(ex > 1e-6, "%s: nodal forces did not deform the tread", mode);
      CHECK(row[FEM_SERIES_STRAIN] != e_first, "%s: strain energy unchanged", mode);
    }
    if (k % 2 == 0) {
      const double *su = proto_msg_get_f8(&m, "snap.u", n_nodes, 3, &err);
      const double *ss = proto_msg_get_f8(&m, "snap.strain", n_el, 6, &err);
      const double *sx = proto_msg_get_f8(&m, "snap.x", n_nodes, 3, &err);
      CHECK(su && ss && sx, "snapshot arrays missing at an output step: %s", err.msg);
    } else {
      CHECK(!proto_msg_find(&m, "snap.u"), "snapshot at a non-output step");
    }
  }
  proto_msg_reset(&m, "fem", "stop", 5, 5 * dt);
  send_msg(&m);
  recv_msg(&m, "bye");
  int status = 0;
  waitpid(pid, &status, 0);
  child = 0;
  CHECK(WIFEXITED(status) && WEXITSTATUS(status) == 0, "fem_server exit status %d", status);
  proto_msg_free(&m);
  free(x0);
  free(force);
  return 0;
}

int main(int argc, char **argv) {
  atexit(kill_child);
  if (argc < 2) {
    fprintf(stderr, "usage: test_fem_server PATH/fem_server\n");
    return 2;
  }
  snprintf(endpoint, sizeof endpoint, "ipc:///tmp/test_fem_server_%d.ipc", (int)getpid());
  ctx = zmq_ctx_new();
  router = zmq_socket(ctx, ZMQ_ROUTER);
  int linger = 0;
  zmq_setsockopt(router, ZMQ_LINGER, &linger, sizeof linger);
  if (zmq_bind(router, endpoint) != 0) return 1;
  run(argv[1], "explicit", "tet4");
  run(argv[1], "quasi_static", "tet4");
  run(argv[1], "explicit", "tet10");
  zmq_close(router);
  zmq_ctx_term(ctx);
  unlink(endpoint + 6);
  return cosim_test_done("test_fem_server");
}
