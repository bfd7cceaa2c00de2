/* bench_block.c — runs a block scene in-process (no coupler): the
 * processes.block section and the indentation scenario of a scene JSON
 * (same profiles as coupler/scenario.c), with --set overrides. Writes one CSV
 * row per step and prints a one-line summary.
 *
 *   bench_block SCENE.json [--set key=value]... [--csv out.csv] [--label L]
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "contact_block/blk.h"

typedef struct profile {
  int kind; /* 0 linear, 1 quadratic, 2 load-hold-unload, 3 sinusoidal */
  double depth, ramp_time, hold_time, amplitude, frequency;
  double unload_time; /* bench only: unloading ramp (default ramp_time) */
} profile;

static double road(const profile *p, double t) {
  double x = p->ramp_time > 0 ? t / p->ramp_time : 0;
  switch (p->kind) {
  case 0: return p->depth * fmin(x, 1.0);
  case 1: return p->depth * fmin(x * x, 1.0);
  case 2:
    if (t <= p->ramp_time) return p->depth * x;
    if (t <= p->ramp_time + p->hold_time) return p->depth;
    return p->depth * (1.0 - (t - p->ramp_time - p->hold_time) / p->unload_time);
  default: return p->depth + p->amplitude * sin(2 * M_PI * p->frequency * t);
  }
}

/* CPU time of this process (the machine is shared: wall time includes waiting). */
static double cpu_seconds(void) {
  struct timespec ts;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

static double num(const cJSON *o, const char *k, double def) {
  const cJSON *v = cJSON_GetObjectItem(o, k);
  return cJSON_IsNumber(v) ? v->valuedouble : def;
}

int main(int argc, char **argv) {
  proto_err err = {{0}};
  if (argc < 2) {
    fprintf(stderr, "usage: bench_block SCENE.json [--set k=v]... [--csv F] [--label L]\n");
    return 2;
  }
  cJSON *root = proto_json_load(argv[1], &err);
  if (!root) {
    fprintf(stderr, "%s\n", err.msg);
    return 1;
  }
  const char *csv = NULL, *label = "run";
  for (int i = 2; i < argc; i++) {
    if (!strcmp(argv[i], "--set") && i + 1 < argc) {
      if (proto_json_set(root, argv[++i], &err)) {
        fprintf(stderr, "%s\n", err.msg);
        return 1;
      }
    } else if (!strcmp(argv[i], "--csv") && i + 1 < argc) {
      csv = argv[++i];
    } else if (!strcmp(argv[i], "--label") && i + 1 < argc) {
      label = argv[++i];
    } else {
      fprintf(stderr, "unknown argument %s\n", argv[i]);
      return 2;
    }
  }
  const cJSON *time = cJSON_GetObjectItem(root, "time");
  const cJSON *scn = cJSON_GetObjectItem(root, "scenario");
  const cJSON *procs = cJSON_GetObjectItem(root, "processes");
  const cJSON *sec = procs ? cJSON_GetObjectItem(procs, "block") : NULL;
  if (!time || !scn || !sec) {
    fprintf(stderr, "%s: needs time, scenario and processes.block\n", argv[1]);
    return 1;
  }
  static const char *const kinds[] = {"linear", "quadratic", "load_hold_unload",
                                      "sinusoidal"};
  profile p = {0};
  const cJSON *pk = cJSON_GetObjectItem(scn, "profile");
  for (int i = 0; i < 4; i++)
    if (cJSON_IsString(pk) && !strcmp(pk->valuestring, kinds[i])) p.kind = i;
  p.depth = num(scn, "depth", 0);
  p.ramp_time = num(scn, "ramp_time", 0);
  p.hold_time = num(scn, "hold_time", 0);
  p.amplitude = num(scn, "amplitude", 0);
  p.frequency = num(scn, "frequency", 0);
  p.unload_time = num(scn, "unload_time", p.ramp_time);
  const double t_end = num(time, "end", 0);
  blk_model m;
  if (blk_model_from_config(&m, sec, "processes.block", &err)) {
    fprintf(stderr, "%s\n", err.msg);
    return 1;
  }
  const double dt = m.rate > 0 ? 1.0 / m.rate : num(time, "dt", 1e-5);
  const long n_steps = lround(t_end / dt);
  blk_state s;
  if (blk_state_create(&m, &s, &err)) {
    fprintf(stderr, "%s\n", err.msg);
    return 1;
  }
  FILE *out = csv ? fopen(csv, "w") : NULL;
  if (out)
    fprintf(out, "step,t,d_road,force,contacts,iterations,converged,residual,cuts,k_max,"
                 "stiffness,products\n");
  long total_it = 0, max_it = 0, n_fail = 0, n_fact = 0, n_prod = 0;
  double first_fail_d = NAN, Fmax = 0, Fmin = 0;
  const double t0 = proto_now(), c0 = cpu_seconds();
  int rc = 0;
  long n_done = 0;
  for (long n = 1; n <= n_steps; n++) {
    const double t = n * dt, d = road(&p, t);
    if (blk_step(&m, &s, d, &err)) {
      fprintf(stderr, "%s: %s\n", label, err.msg);
      rc = 1;
      break;
    }
    n_done = n;
    total_it += s.iterations;
    n_fact += s.factorizations;
    n_prod += s.products;
    if (s.iterations > max_it) max_it = s.iterations;
    if (!s.converged) {
      if (!n_fail) first_fail_d = d;
      n_fail++;
    }
    Fmax = fmax(Fmax, s.total_force);
    Fmin = fmin(Fmin, s.total_force);
    double k_max = 0; /* stiffest spring in contact (N/m), for the K_crit argument */
    for (int e = 0; e < m.M; e++) {
      if (s.force[e] == 0.0) continue; /* out of contact */
      double Fe, ke;
      blk_spring_eval(&m, e, fabs(s.d_rs[e]), &Fe, &ke);
      if (ke > k_max) k_max = ke;
    }
    if (out)
      fprintf(out, "%ld,%.9e,%.9e,%.9e,%d,%d,%d,%.3e,%d,%.4e,%.9e,%d\n", n, t, d,
              s.total_force, s.n_contact, s.iterations, s.converged, s.residual,
              s.line_search_cuts, k_max, s.stiffness, s.products);
  }
  const double wall = proto_now() - t0, cpu = cpu_seconds() - c0;
  printf("%s: steps %ld  wall %.3f s  cpu %.3f s  iterations/step %.2f (max %ld)  factorizations/step "
         "%.2f  products/step %.2f  not converged %ld (first at d = %.4g mm)  F max %.4g N  "
         "F min %.4g N  F end %.4g N  contacts %d\n",
         label, n_done, wall, cpu, (double)total_it / (n_done ? n_done : 1), max_it,
         (double)n_fact / (n_done ? n_done : 1), (double)n_prod / (n_done ? n_done : 1), n_fail,
         first_fail_d * 1e3, Fmax, Fmin, s.total_force, s.n_contact);
  if (out) fclose(out);
  blk_state_free(&s);
  blk_model_free(&m);
  cJSON_Delete(root);
  return rc;
}
