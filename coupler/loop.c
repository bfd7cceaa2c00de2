/* loop.c — the lock-step loop. Serial (Gauss–Seidel) scheme for the tread on
 * soil: DEM gets the surface at t_{k-1}, returns grain forces; the FEM gets
 * those forces and the rim frame at t_k and returns the surface at t_k.
 * The block gets its road displacement at t_k and returns its force. */
#include "run.h"

#include <math.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

/* Sends a step request and waits for the matching "done". */
static int exchange(cpl_runner *r, int i, proto_msg *req, int64_t k) {
  cpl_peer *p = &r->peers[i];
  int from;
  if (cpl_send(r, i, req) < 0) return -1;
  if (cpl_receive(r, i, r->scene->step_timeout, &p->reply, &from) < 0)
    return -1;
  if (strcmp(p->reply.type, "done") != 0 || p->reply.step != k) {
    r->failed_peer = i;
    return proto_fail(&r->err, "participant '%s': expected 'done' for step "
                      "%lld, got '%s' for step %lld", p->proc->name,
                      (long long)k, p->reply.type, (long long)p->reply.step);
  }
  return 0;
}

static void step_request(cpl_runner *r, proto_msg *req, int i, int64_t k,
                         int output) {
  proto_msg_reset(req, r->peers[i].proc->name, "step", k,
                  (double)(k - 1) * r->scene->dt);
  cJSON *h = proto_msg_header(req);
  cJSON_AddNumberToObject(h, "dt", r->scene->dt);
  cJSON_AddBoolToObject(h, "output", output);
}

/* Copies a validated [n,3] f8 array of the reply into dst. */
static int take_nodes(cpl_runner *r, int i, const char *name, double *dst) {
  const double *a = proto_msg_get_f8(&r->peers[i].reply, name,
                                     r->surf.n_nodes, 3, &r->err);
  if (!a) {
    r->failed_peer = i;
    return proto_wrap(&r->err, "participant '%s'", r->peers[i].proc->name);
  }
  for (int64_t j = 0; j < 3 * r->surf.n_nodes; j++)
    if (!isfinite(a[j])) {
      r->failed_peer = i;
      return proto_fail(&r->err, "participant '%s': %s[%lld][%lld] is not "
                        "finite", r->peers[i].proc->name, name,
                        (long long)(j / 3), (long long)(j % 3));
    }
  memcpy(dst, a, sizeof(double) * 3 * (size_t)r->surf.n_nodes);
  return 0;
}

static int step_dem(cpl_runner *r, int64_t k, int output) {
  proto_msg req = {0};
  step_request(r, &req, r->dem, k, output);
  if (r->surf.n_nodes > 0) {
    proto_msg_add_f8(&req, "x", r->surf.n_nodes, 3, r->surf.x);
    proto_msg_add_f8(&req, "v", r->surf.n_nodes, 3, r->surf.v);
  }
  int rc = exchange(r, r->dem, &req, k);
  proto_msg_free(&req);
  if (rc == 0 && r->surf.n_nodes > 0)
    rc = take_nodes(r, r->dem, "nodal_force", r->surf.force);
  return rc;
}

static int step_fem(cpl_runner *r, int64_t k, int output) {
  proto_msg req = {0};
  step_request(r, &req, r->fem, k, output);
  proto_msg_add_f8(&req, "nodal_force", r->surf.n_nodes, 3, r->surf.force);
  proto_msg_add_f8(&req, "rim_R", 3, 3, r->rim.R);
  proto_msg_add_f8(&req, "rim_c", 3, 0, r->rim.c);
  proto_msg_add_f8(&req, "rim_omega", 3, 0, r->rim.w);
  proto_msg_add_f8(&req, "rim_v", 3, 0, r->rim.v);
  int rc = exchange(r, r->fem, &req, k);
  proto_msg_free(&req);
  if (rc == 0) rc = take_nodes(r, r->fem, "x", r->surf.x);
  if (rc == 0) rc = take_nodes(r, r->fem, "v", r->surf.v);
  return rc;
}

/* Road displacement at t_k: prescribed, or the road body moved by the
 * external force against the last contact force (explicit, one-step lag). */
static double road_at(cpl_runner *r, double t) {
  const cpl_scenario *s = &r->scene->scenario;
  if (s->kind != CPL_SCN_INDENTATION) return 0;
  if (s->profile != CPL_PROFILE_FORCE) return cpl_road_displacement(s, t);
  double a = (s->road_force - r->road_force_last) / s->road_mass;
  r->road_velocity += a * r->scene->dt;
  r->d_road += r->road_velocity * r->scene->dt;
  return r->d_road;
}

static int step_block(cpl_runner *r, int64_t k, int output) {
  proto_msg req = {0};
  step_request(r, &req, r->block, k, output);
  r->d_road = road_at(r, (double)k * r->scene->dt);
  proto_msg_add_f8(&req, "d_road", 1, 0, &r->d_road);
  int rc = exchange(r, r->block, &req, k);
  proto_msg_free(&req);
  if (rc == 0) {
    const double *f =
        proto_msg_get_f8(&r->peers[r->block].reply, "force", 1, 0, &r->err);
    if (!f || !isfinite(f[0])) {
      r->failed_peer = r->block;
      return f ? proto_fail(&r->err, "participant '%s': force is not finite",
                            r->peers[r->block].proc->name)
               : proto_wrap(&r->err, "participant '%s'",
                            r->peers[r->block].proc->name);
    }
    r->road_force_last = f[0];
  }
  return rc;
}

/* Traction of seed 000 §5 (T_R: forces against travel, T_H: along it,
 * T_P = T_H - |T_R|), vertical load, sinkage and the torque about the axle,
 * all from the grain forces on the tread nodes. */
static void traction(const cpl_runner *r, double t, double *row) {
  double th = 0, tr = 0, fz = 0, torque = 0;
  const cpl_surface *s = &r->surf;
  for (int64_t i = 0; i < s->n_nodes; i++) {
    const double *f = &s->force[3 * i], *x = &s->x[3 * i];
    if (f[0] > 0) th += f[0];
    else tr += f[0];
    fz += f[2];
    /* y-component of (x - c) × f */
    torque += (x[2] - r->rim.c[2]) * f[0] - (x[0] - r->rim.c[0]) * f[2];
  }
  double sinkage = r->scene->scenario.rim_center[2] - r->rim.c[2];
  double vals[7] = {t, th, tr, th - fabs(tr), fz, sinkage, torque};
  memcpy(row, vals, sizeof vals);
}

static int publish_reply(cpl_runner *r, int i, int output) {
  void *pub = cpl_bus_pub(r->bus);
  if (!pub) return 0;
  const proto_msg *d = &r->peers[i].reply;
  proto_msg m = {0};
  for (int pass = 0; pass < 1 + output; pass++) {
    const char *prefix = pass == 0 ? "series" : "snap.";
    char topic[PROTO_NAME_LEN];
    snprintf(topic, sizeof topic, "%s.%s", r->peers[i].proc->name,
             pass == 0 ? "series" : "snapshot");
    proto_msg_reset(&m, topic, pass == 0 ? "series" : "snapshot", d->step, d->t);
    for (int a = 0; a < d->narrays; a++)
      if (strncmp(d->arrays[a].name, prefix, strlen(prefix)) == 0)
        proto_msg_add(&m, d->arrays[a].name, d->arrays[a].dtype,
                      d->arrays[a].ndim, d->arrays[a].shape, d->arrays[a].data);
    if (m.narrays) proto_publish(pub, &m);
  }
  proto_msg_free(&m);
  return 0;
}

static void publish_progress(cpl_runner *r, int64_t k, double rate) {
  void *pub = cpl_bus_pub(r->bus);
  if (!pub) return;
  proto_msg m = {0};
  double t = (double)k * r->scene->dt;
  proto_msg_reset(&m, "coupler.progress", "progress", k, t);
  cJSON *h = proto_msg_header(&m);
  cJSON_AddNumberToObject(h, "n_steps", (double)r->scene->n_steps);
  cJSON_AddNumberToObject(h, "steps_per_s", rate);
  cJSON_AddNumberToObject(h, "eta_s",
                          rate > 0 ? (double)(r->scene->n_steps - k) / rate : -1);
  proto_publish(pub, &m);
  proto_msg_free(&m);
}

static void show_progress(cpl_runner *r, int64_t k, double rate, int final) {
  if (!r->opts->progress) return;
  double eta = rate > 0 ? (double)(r->scene->n_steps - k) / rate : 0;
  fprintf(stderr, "\r  step %lld/%lld  t = %.4g s  %.0f steps/s  ETA %.0f s   %s",
          (long long)k, (long long)r->scene->n_steps, (double)k * r->scene->dt,
          rate, eta, final ? "\n" : "");
  fflush(stderr);
}

static int record(cpl_runner *r, int64_t k, int output) {
  for (int i = 0; i < r->n; i++) {
    if (cpl_output_done(r->out, r->peers[i].proc->name, &r->peers[i].reply,
                        output, &r->err) < 0) {
      r->failed_peer = i;
      return proto_wrap(&r->err, "output of '%s'", r->peers[i].proc->name);
    }
    publish_reply(r, i, output);
  }
  double t = (double)k * r->scene->dt;
  static const char *const ccols[] = {"t", "wall_s"};
  double crow[2] = {t, proto_now() - r->wall_start};
  if (cpl_output_coupler_row(r->out, "series", 2, ccols, crow, &r->err) < 0)
    return -1;
  if (r->scene->scenario.kind == CPL_SCN_TIRE_TRAVEL) {
    static const char *const tcols[] = {"t", "T_H", "T_R", "T_P",
                                        "vertical_load", "sinkage", "torque"};
    double row[7];
    traction(r, t, row);
    if (cpl_output_coupler_row(r->out, "traction", 7, tcols, row, &r->err) < 0)
      return -1;
  }
  if (output) cpl_output_flush(r->out);
  return 0;
}

static double vertical_load(const cpl_surface *s) {
  double fz = 0;
  for (int64_t i = 0; i < s->n_nodes; i++) fz += s->force[3 * i + 2];
  return fz;
}

int cpl_step_loop(cpl_runner *r) {
  const cpl_scene *s = r->scene;
  double last_shown = proto_now(), start = proto_now();
  for (int64_t k = 1; k <= s->n_steps; k++) {
    int output = (k % s->output_every == 0) || k == s->n_steps;
    int rc = 0;
    if (r->dem >= 0) rc = step_dem(r, k, output);
    if (rc == 0 && r->fem >= 0) {
      cpl_rim_advance(&r->rim, &s->scenario, s->dt, vertical_load(&r->surf));
      rc = step_fem(r, k, output);
    }
    if (rc == 0 && r->block >= 0) rc = step_block(r, k, output);
    if (rc == 0) rc = record(r, k, output);
    if (rc < 0) {
      cpl_output_flush(r->out);
      return proto_wrap(&r->err, "step %lld (t = %g s)", (long long)k,
                        (double)(k - 1) * s->dt);
    }
    double now = proto_now();
    if (now - last_shown > 0.5 || k == s->n_steps) {
      double rate = (double)k / fmax(now - start, 1e-9);
      show_progress(r, k, rate, k == s->n_steps);
      publish_progress(r, k, rate);
      last_shown = now;
    }
  }
  return 0;
}
