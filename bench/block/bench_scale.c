/* bench_scale.c — the block solvers against grid size (issue 14): one case
 * per process, one JSON line on stdout (bench/block/run_scale.py drives it).
 *
 *   bench_scale hertz N METHOD            quasi-static rigid Hertz, one cold solve
 *   bench_scale ramp N METHOD DYN STEPS [HIST [SAG [RATE]]]  stiffening springs on a
 *                                         crowned rough road (edge sag SAG, default
 *                                         0.15 mm), STEPS steps of a ramp (DYN 1:
 *                                         synthetic ZOH layer at RATE x 51.2 kHz with
 *                                         RATE x 256 samples, the same 5 ms memory;
 *                                         HIST separable|fft|auto)
 *   bench_scale bumpy N DX R A LAMBDA D METHOD  the road of pk_numpy.py
 *   bench_scale rough ROAD.h5 METHOD FRAC [periodic]  rigid road from `cosim road` (one
 *                                         element per road point), the approach
 *                                         with FRAC of the area in contact
 * METHOD: cg | dual | newton | auto. Times are CPU seconds of this process. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "contact_block/blk.h"
#include "green/green.h"

static proto_err err;
#define OK(call)                                                 \
  do {                                                           \
    if ((call) != 0) {                                           \
      fprintf(stderr, "bench_scale: %s: %s\n", #call, err.msg);  \
      exit(1);                                                   \
    }                                                            \
  } while (0)

static double cpu(void) {
  struct timespec t;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return t.tv_sec + 1e-9 * t.tv_nsec;
}

/* Peak resident set of this process (VmHWM: getrusage's maximum would
 * include the parent's across exec). */
static long rss_kb(void) {
  FILE *f = fopen("/proc/self/status", "r");
  char line[256];
  long kb = -1;
  while (f && fgets(line, sizeof line, f))
    if (sscanf(line, "VmHWM: %ld", &kb) == 1) break;
  if (f) fclose(f);
  return kb;
}

static blk_method method_of(const char *s) {
  if (!strcmp(s, "cg")) return BLK_CG;
  if (!strcmp(s, "dual")) return BLK_NR_DUAL;
  if (!strcmp(s, "newton")) return BLK_NR_PLAIN;
  if (!strcmp(s, "auto")) return BLK_AUTO;
  fprintf(stderr, "bench_scale: method %s: expected cg, dual, newton or auto\n", s);
  exit(2);
}

static size_t model_bytes(const blk_model *m) {
  const size_t no = (size_t)m->nox * m->noy;
  size_t b = (size_t)m->M * (sizeof(double) + (m->spr_scale ? sizeof(double) + sizeof(int) : 0));
  b += (size_t)m->n_tables * m->n_knots * 4 * sizeof(double);
  b += no * sizeof(double) * (1 + (m->g_space ? 1 : 0));
  if (m->g) b += (size_t)m->Q * no * sizeof(double);
  if (m->g_time) b += (size_t)m->Q * sizeof(double);
  return b;
}

static void report(const char *what, const blk_model *m, const blk_state *s, double setup,
                   double loop, int steps, long products, long iters, double extra) {
  printf("{\"case\": \"%s\", \"nx\": %d, \"ny\": %d, \"M\": %d, \"method\": %d, "
         "\"quasi_static\": %d, \"setup_s\": %.6f, \"loop_s\": %.6f, \"steps\": %d, "
         "\"per_step_s\": %.6e, \"products_per_step\": %.2f, \"iterations_per_step\": %.2f, "
         "\"state_bytes\": %zu, \"model_bytes\": %zu, \"rss_kb\": %ld, \"force\": %.10e, "
         "\"contacts\": %d, \"stiffness\": %.6e, \"converged\": %d, \"residual\": %.3e, "
         "\"extra\": %.6e}\n",
         what, m->nx, m->ny, m->M, s->method, m->solver.quasi_static, setup, loop, steps,
         loop / steps, (double)products / steps, (double)iters / steps, blk_state_bytes(s),
         model_bytes(m), rss_kb(), s->total_force, s->n_contact, s->stiffness, s->converged,
         s->residual, extra);
}

/* One cold quasi-static solve at the approach d on a rigid road already in
 * m (Love half-space E = 10 MPa, ν = 0.3); times from t0 (set-up). */
static void rigid_solve(blk_model *m, blk_state *s, blk_method me, double d, double t0,
                        double *setup, double *loop) {
  OK(blk_green_halfspace(m, 10e6, 0.3, &err));
  OK(blk_springs_rigid(m, &err));
  m->solver.quasi_static = 1;
  m->solver.method = me;
  m->solver.max_iter = 50;
  m->solver.tol = 1e-10 * d;
  OK(blk_state_create(m, s, &err));
  const double t1 = cpu();
  OK(blk_step(m, s, d, &err));
  *setup = t1 - t0;
  *loop = cpu() - t1;
}

/* Quasi-static Hertz, rigid road, one cold solve; extra = relative force error. */
static void hertz(int n, blk_method me) {
  const double dx = 1e-4, R = 0.1, Es = 10e6 / (1 - 0.3 * 0.3);
  double t0 = cpu(), setup, loop;
  blk_model m;
  OK(blk_model_init(&m, n, n, dx, dx, &err));
  OK(blk_road_paraboloid(&m, R, &err));
  const double a = 0.35 * n * dx, delta = a * a / R;
  blk_state s;
  rigid_solve(&m, &s, me, delta, t0, &setup, &loop);
  const double F_h = 4.0 / 3.0 * Es * sqrt(R) * pow(delta, 1.5);
  report("hertz", &m, &s, setup, loop, 1, s.products, s.iterations, s.total_force / F_h - 1);
  blk_state_free(&s);
  blk_model_free(&m);
}

/* Stiffening springs (the default scene's law) on a curved rough road,
 * 1 mm elements: a ramp of `steps` steps to 0.2 mm; dynamic: synthetic ZOH
 * layer at 51.2 kHz. extra = mean contact fraction at the end. */
static void ramp(int n, blk_method me, int dyn, int steps, blk_history_kind hist, double sag,
                 int rate) {
  double t0 = cpu();
  blk_model m;
  OK(blk_model_init(&m, n, n, 1e-3, 1e-3, &err));
  OK(blk_road_random(&m, 3e-5, 1, &err));
  /* a crown sagging `sag` at the block's edge (default 0.15 mm) */
  const double R = pow(0.5 * n * 1e-3, 2) / (2 * sag);
  for (int j = 0; j < n; j++)
    for (int i = 0; i < n; i++) {
      const double x = (i + 0.5 - 0.5 * n) * 1e-3, y = (j + 0.5 - 0.5 * n) * 1e-3;
      m.z_road[j * n + i] -= (x * x + y * y) / (2 * R);
    }
  OK(blk_springs_stiffening(&m, 3e5, 1.5e-6, 0.5, 2, 5e-4, 33, &err));
  blk_synth sy = {.E = 25e6, .nu = 0.49, .rate = 51200.0 * rate, .Q = 256 * rate, .f_mode = 2000,
                  .zeta = 0.1, .beta = 0.0, .tau_fast = 2e-5, .point_sampling = 0};
  OK(blk_green_synthetic(&m, &sy, &err));
  m.solver.quasi_static = !dyn;
  m.solver.method = me;
  m.solver.max_iter = 50;
  m.solver.history = hist;
  blk_state s;
  OK(blk_state_create(&m, &s, &err));
  const double t1 = cpu();
  long products = 0, iters = 0;
  for (int k = 1; k <= steps; k++) {
    OK(blk_step(&m, &s, 2e-4 * k / steps, &err));
    products += s.products;
    iters += s.iterations;
  }
  const double t2 = cpu();
  report(dyn ? "ramp_dynamic" : "ramp_quasi_static", &m, &s, t1 - t0, t2 - t1, steps, products,
         iters, (double)s.n_contact / m.M);
  blk_state_free(&s);
  blk_model_free(&m);
}

/* Rigid self-affine road (cosim road), one element per road point: the
 * approach is bracketed by the height distribution and bisected (cheap
 * solves at a loose tolerance) to `frac` of the area in contact, then the
 * timed cold solve at the default tolerance. extra = contact fraction. */
static void rough(const char *path, blk_method me, double frac, int periodic) {
  grn_surface sf;
  OK(grn_surface_read_h5(path, &sf, &err));
  const double E = 25e6, nu = 0.49;
  blk_model m;
  OK(blk_model_init(&m, sf.Nx, sf.Ny, sf.dx, sf.dy, &err));
  m.periodic = periodic; /* the generated road is periodic over the patch */
  double top = -INFINITY;
  for (int e = 0; e < m.M; e++) top = fmax(top, sf.z[e]);
  for (int e = 0; e < m.M; e++) m.z_road[e] = sf.z[e] - top;
  OK(blk_green_halfspace(&m, E, nu, &err));
  OK(blk_springs_rigid(&m, &err));
  m.solver.quasi_static = 1;
  m.solver.method = me;
  m.solver.max_iter = 50;
  blk_state s;
  OK(blk_state_create(&m, &s, &err));
  /* geometric overlap at the approach d covers the points above −d: an upper
   * bound of the contact; bisection on the elastic contact fraction */
  const double tol = m.solver.tol;
  m.solver.tol = 1e-3 * grn_surface_rms(&sf); /* the bracket needs no more */
  double lo = 0, hi = 10 * grn_surface_rms(&sf);
  if (periodic) { /* below full contact: the mean overlap stays negative */
    double mean = 0;
    for (int e = 0; e < m.M; e++) mean += m.z_road[e];
    hi = fmin(hi, -mean / m.M);
  }
  for (int it = 0; it < 14; it++) {
    const double d = 0.5 * (lo + hi);
    blk_state_reset(&m, &s);
    OK(blk_step(&m, &s, d, &err));
    if ((double)s.n_contact / m.M < frac) lo = d; else hi = d;
  }
  const double d = 0.5 * (lo + hi);
  m.solver.tol = tol;
  blk_state_reset(&m, &s);
  const double t1 = cpu();
  OK(blk_step(&m, &s, d, &err));
  const double t2 = cpu();
  report(periodic ? "rough_periodic" : "rough", &m, &s, 0, t2 - t1, 1, s.products, s.iterations,
         (double)s.n_contact / m.M);
  blk_state_free(&s);
  blk_model_free(&m);
  grn_surface_free(&sf);
}

/* Independent comparison (bench/block/pk_numpy.py): a paraboloid with a bump
 * pattern, z = −r²/(2R) + A cos(2πx/λ) cos(2πy/λ), rigid, quasi-static, one
 * cold solve at the approach d; the same formula in both codes. */
static void bumpy(int n, double dx, double R, double A, double lam, double d, blk_method me) {
  double t0 = cpu(), setup, loop;
  blk_model m;
  OK(blk_model_init(&m, n, n, dx, dx, &err));
  for (int j = 0; j < n; j++)
    for (int i = 0; i < n; i++) {
      const double x = (i + 0.5 - 0.5 * n) * dx, y = (j + 0.5 - 0.5 * n) * dx;
      m.z_road[j * n + i] = -(x * x + y * y) / (2 * R) +
                            A * cos(2 * M_PI * x / lam) * cos(2 * M_PI * y / lam);
    }
  blk_state s;
  rigid_solve(&m, &s, me, d, t0, &setup, &loop);
  report("bumpy", &m, &s, setup, loop, 1, s.products, s.iterations, 0);
  blk_state_free(&s);
  blk_model_free(&m);
}

int main(int argc, char **argv) {
  if (argc >= 4 && !strcmp(argv[1], "hertz")) hertz(atoi(argv[2]), method_of(argv[3]));
  else if (argc >= 6 && !strcmp(argv[1], "ramp"))
    ramp(atoi(argv[2]), method_of(argv[3]), atoi(argv[4]), atoi(argv[5]),
         argc > 6 && strcmp(argv[6], "auto")
             ? (!strcmp(argv[6], "separable") ? BLK_HIST_SEPARABLE : BLK_HIST_FFT)
             : BLK_HIST_AUTO,
         argc > 7 ? atof(argv[7]) : 1.5e-4, argc > 8 ? atoi(argv[8]) : 1);
  else if (argc >= 9 && !strcmp(argv[1], "bumpy"))
    bumpy(atoi(argv[2]), atof(argv[3]), atof(argv[4]), atof(argv[5]), atof(argv[6]),
          atof(argv[7]), method_of(argv[8]));
  else if (argc >= 5 && !strcmp(argv[1], "rough"))
    rough(argv[2], method_of(argv[3]), atof(argv[4]), argc > 5 && !strcmp(argv[5], "periodic"));
  else {
    fprintf(stderr, "usage: bench_scale hertz N METHOD | ramp N METHOD DYN STEPS [HIST [SAG [RATE]]] | "
                    "bumpy N DX R A LAMBDA D METHOD | rough ROAD.h5 METHOD FRAC\n");
    return 2;
  }
  return 0;
}
