/* cli.c — `cosim_green road|springs|green [options]` (also reached as
 * `cosim road|springs|green ...`): writes road.h5, springs.h5 and green.h5
 * (green/FORMATS.md) with progress on a terminal. */
#include <errno.h>
#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "green/green.h"

static void progress(void *user, double fraction, const char *what) {
  const char *stage = user;
  if (isatty(2))
    fprintf(stderr, "\r%s: %s %5.1f%%%s", stage, what, 100 * fraction, fraction >= 1 ? "\n" : "");
  else if (fraction >= 1)
    fprintf(stderr, "%s: %s done\n", stage, what);
}

static int num(const char *opt, const char *s, double *out, proto_err *err) {
  char *end;
  double v = strtod(s, &end);
  if (end == s || *end || !isfinite(v))
    return proto_fail(err, "--%s = '%s': expected a finite number", opt, s);
  *out = v;
  return 0;
}

static int positive(const char *opt, const char *s, double *out, proto_err *err) {
  if (num(opt, s, out, err)) return -1;
  if (!(*out > 0)) return proto_fail(err, "--%s = %s: must be > 0", opt, s);
  return 0;
}

static int count(const char *opt, const char *s, int *out, proto_err *err) {
  double v = 0;
  if (num(opt, s, &v, err)) return -1;
  if (v < 1 || v > 1e6 || v != floor(v))
    return proto_fail(err, "--%s = %s: expected a positive integer", opt, s);
  *out = (int)v;
  return 0;
}

/* N or NXxNY, each in [1, 1e6] (no int overflow whatever the text) */
static int pair(const char *opt, const char *s, int *a, int *b, proto_err *err) {
  char *end;
  errno = 0;
  long x = strtol(s, &end, 10), y = x;
  if (end != s && *end == 'x') {
    const char *t = end + 1;
    y = strtol(t, &end, 10);
    if (end == t) y = 0;
  }
  if (end == s || *end || errno || x < 1 || y < 1 || x > 1000000 || y > 1000000)
    return proto_fail(err, "--%s = '%s': expected N or NXxNY, each 1 to 1000000", opt, s);
  *a = (int)x;
  *b = (int)y;
  return 0;
}

/* --size DX or DXxDY (m): square or rectangular elements */
static int size_pair(const char *s, double *dx, double *dy, proto_err *err) {
  char *end;
  const double a = strtod(s, &end);
  double b = a;
  if (end != s && *end == 'x') {
    const char *t = end + 1;
    b = strtod(t, &end);
    if (end == t) b = NAN;
  }
  if (end == s || *end || !(a > 0) || !(b > 0) || !isfinite(a) || !isfinite(b))
    return proto_fail(err, "--size = '%s': expected DX or DXxDY in m, > 0 (e.g. 1e-3 or "
                      "1.5e-3x1e-3)", s);
  *dx = a;
  *dy = b;
  return 0;
}

static int has_suffix(const char *s, const char *suf) {
  size_t n = strlen(s), m = strlen(suf);
  return n >= m && strcmp(s + n - m, suf) == 0;
}

static int load_road(const char *path, double pitch, grn_surface *s, proto_err *err) {
  if (has_suffix(path, ".h5") || has_suffix(path, ".hdf5"))
    return grn_surface_read_h5(path, s, err);
  return grn_surface_read_text(path, pitch, pitch, s, err);
}

/* ------------------------------------------------------------- road */

static int cmd_road(int argc, char **argv, proto_err *err) {
  grn_surface_params p = {2000, 2000, 1e-5, 1e-5, 0.8, 1e-4, 5e-5, 1e-2, 1};
  const char *out = "road.h5", *from = NULL;
  double pitch = 0;
  static struct option lo[] = {{"out", 1, 0, 'o'}, {"points", 1, 0, 'n'}, {"pitch", 1, 0, 'p'},
                               {"hurst", 1, 0, 'H'}, {"rms", 1, 0, 'r'}, {"lambda-short", 1, 0, 's'},
                               {"lambda-long", 1, 0, 'l'}, {"seed", 1, 0, 'S'}, {"from", 1, 0, 'f'},
                               {0, 0, 0, 0}};
  int c, seed = 1;
  while ((c = getopt_long(argc, argv, "", lo, NULL)) != -1) {
    int rc = 0;
    switch (c) {
    case 'o': out = optarg; break;
    case 'n': rc = pair("points", optarg, &p.Nx, &p.Ny, err); break;
    case 'p': rc = positive("pitch", optarg, &p.dx, err); p.dy = p.dx; pitch = p.dx; break;
    case 'H': rc = num("hurst", optarg, &p.hurst, err); break;
    case 'r': rc = positive("rms", optarg, &p.rms, err); break;
    case 's': rc = positive("lambda-short", optarg, &p.lambda_short, err); break;
    case 'l': rc = positive("lambda-long", optarg, &p.lambda_long, err); break;
    case 'S': rc = count("seed", optarg, &seed, err); p.seed = (uint64_t)seed; break;
    case 'f': from = optarg; break;
    default: return proto_fail(err, "road: unknown option (see cosim_green --help)");
    }
    if (rc) return -1;
  }
  grn_surface s;
  if (from ? load_road(from, pitch, &s, err) : grn_surface_generate(&p, &s, err))
    return -1;
  double rms = grn_surface_rms(&s);
  fprintf(stderr, "road: %d x %d points, pitch %g x %g m, rms %.4g m\n", s.Nx, s.Ny, s.dx, s.dy, rms);
  if (!from) {
    proto_err e2;
    double slope = grn_surface_psd_slope(&s, 2 * M_PI / p.lambda_long, 2 * M_PI / p.lambda_short, &e2);
    fprintf(stderr, "road: PSD slope %.4f (target %.4f = -2(1+H))\n", slope, -2 * (1 + p.hurst));
  }
  int rc = grn_surface_write_h5(out, &s, from ? NULL : &p, err);
  grn_surface_free(&s);
  if (!rc) fprintf(stderr, "road: wrote %s\n", out);
  return rc;
}

/* ---------------------------------------------------------- springs */

static int cmd_springs(int argc, char **argv, proto_err *err) {
  grn_spring_opts o;
  grn_spring_opts_default(&o);
  const char *out = "springs.h5", *road = NULL, *film = "relief";
  int nx = 20, ny = 20;
  double pitch = 0;
  static struct option lo[] = {{"road", 1, 0, 'r'}, {"out", 1, 0, 'o'}, {"elements", 1, 0, 'e'},
                               {"knots", 1, 0, 'k'}, {"E", 1, 0, 'E'}, {"nu", 1, 0, 'n'},
                               {"film", 1, 0, 'f'}, {"d-max-frac", 1, 0, 'd'},
                               {"release-force", 1, 0, 'R'}, {"no-poly", 0, 0, 'P'},
                               {"pitch", 1, 0, 'p'}, {0, 0, 0, 0}};
  int c;
  while ((c = getopt_long(argc, argv, "", lo, NULL)) != -1) {
    int rc = 0;
    switch (c) {
    case 'r': road = optarg; break;
    case 'o': out = optarg; break;
    case 'e': rc = pair("elements", optarg, &nx, &ny, err); break;
    case 'k': rc = count("knots", optarg, &o.K, err); break;
    case 'E': rc = positive("E", optarg, &o.E, err); break;
    case 'n': rc = num("nu", optarg, &o.nu, err); break;
    case 'f': film = optarg;
      if (strcmp(film, "relief") != 0) rc = positive("film", optarg, &o.film_h, err);
      break;
    case 'd': rc = positive("d-max-frac", optarg, &o.d_max_frac, err); break;
    case 'R': rc = num("release-force", optarg, &o.release_force, err); break;
    case 'P': o.poly = 0; break;
    case 'p': rc = positive("pitch", optarg, &pitch, err); break;
    default: return proto_fail(err, "springs: unknown option (see cosim_green --help)");
    }
    if (rc) return -1;
  }
  if (!road) return proto_fail(err, "springs: --road FILE is required (.h5 or text grid)");
  grn_surface s;
  if (load_road(road, pitch, &s, err)) return -1;
  grn_springs sp;
  int rc = grn_springs_build(&s, nx, ny, &o, &sp, progress, "springs", err);
  grn_surface_free(&s);
  if (rc) return -1;
  char rule[256];
  if (o.film_h > 0)
    snprintf(rule, sizeof rule, "constant h = %g m", o.film_h);
  else
    snprintf(rule, sizeof rule, "h(d) = z_max - z_min - d (seed 002 ch. 3.2), floor %g of the relief",
             o.h_floor_frac);
  double eh = 0, ep = 0;
  for (int e = 0; e < nx * ny; e++) {
    eh = fmax(eh, sp.err_hermite[e]);
    if (o.poly) ep = fmax(ep, sp.err_poly[e]);
  }
  fprintf(stderr, "springs: %d x %d elements of %g x %g m, %d knots; worst error vs raw "
                  "curve (of F(d_max)): hermite %.2e, poly %.2e\n", nx, ny, sp.dx, sp.dy, o.K, eh, ep);
  rc = grn_write_springs(out, &sp, rule, err);
  grn_springs_free(&sp);
  if (!rc) fprintf(stderr, "springs: wrote %s\n", out);
  return rc;
}

/* ------------------------------------------------------------ green */

/* The options of `cosim_green green`. */
typedef struct green_args {
  grn_material mat;
  grn_dyn_opts o;
  grn_grid g;
  double h, E;
  const char *out, *out_point, *model, *table;
} green_args;

static int green_parse(int argc, char **argv, green_args *a, proto_err *err) {
  grn_material_default(&a->mat);
  grn_dyn_opts_default(&a->o);
  /* The thesis' Q = 256 (5 ms at 51.2 kHz) stops before the appendix-B layer
   * has crept to its static value: the time sum then misses the static
   * coefficient by 1.24 %. 512 samples bring that to 0.53 % (1024: 0.02 %),
   * so the tool's own 1 % check passes with its defaults. */
  a->o.Q = 512;
  a->g = (grn_grid){20, 20, 1e-3, 1e-3};
  a->h = 0.01;
  a->E = -1;
  a->out = "green.h5";
  a->out_point = a->table = NULL;
  a->model = "dynamic";
  static struct option lo[] = {{"model", 1, 0, 'm'}, {"elements", 1, 0, 'e'}, {"size", 1, 0, 's'},
                               {"thickness", 1, 0, 'h'}, {"E", 1, 0, 'E'}, {"nu", 1, 0, 'n'},
                               {"rho", 1, 0, 'r'}, {"table", 1, 0, 't'}, {"Q", 1, 0, 'Q'},
                               {"rate", 1, 0, 'R'}, {"out", 1, 0, 'o'}, {"out-point", 1, 0, 'P'},
                               {"oversample", 1, 0, 'O'}, {"period-factor", 1, 0, 'F'},
                               {"pad", 1, 0, 'p'}, {0, 0, 0, 0}};
  int c;
  while ((c = getopt_long(argc, argv, "", lo, NULL)) != -1) {
    int rc = 0;
    switch (c) {
    case 'm': a->model = optarg; break;
    case 'e': rc = pair("elements", optarg, &a->g.nx, &a->g.ny, err); break;
    case 's': rc = size_pair(optarg, &a->g.dx, &a->g.dy, err); break;
    case 'h': rc = num("thickness", optarg, &a->h, err);
      if (!rc && !(a->h > 0)) rc = proto_fail(err, "--thickness = %s: must be > 0", optarg);
      break;
    case 'E': rc = positive("E", optarg, &a->E, err); break;
    case 'n': rc = num("nu", optarg, &a->mat.nu, err); break;
    case 'r': rc = positive("rho", optarg, &a->mat.rho, err); break;
    case 't': a->table = optarg; break;
    case 'Q': rc = count("Q", optarg, &a->o.Q, err); break;
    case 'R': rc = positive("rate", optarg, &a->o.rate, err); break;
    case 'o': a->out = optarg; break;
    case 'P': a->out_point = optarg; break;
    case 'O': rc = count("oversample", optarg, &a->o.oversample, err); break;
    case 'F': rc = count("period-factor", optarg, &a->o.period_factor, err); break;
    case 'p': rc = count("pad", optarg, &a->o.pad, err); break;
    default: return proto_fail(err, "green: unknown option (see cosim_green --help)");
    }
    if (rc) return -1;
  }
  if (a->table && grn_material_load(&a->mat, a->table, err)) return -1;
  if (a->E > 0) { /* a constant modulus overrides the table's */
    for (int i = 0; i < a->mat.n; i++) a->mat.E[i] = a->E;
  }
  return grn_material_check(&a->mat, err);
}

/* Δt Σ_k g_k at offset m of Q samples of nk offsets (the static value of a
 * settled response). */
static double time_sum(const double *gk, int Q, int nk, int m, double rate) {
  double s = 0;
  for (int k = 0; k < Q; k++) s += gk[(size_t)k * nk + m] / rate;
  return s;
}

/* Relative miss of the ZOH time sum against the static coefficient above
 * which the response has not settled within Q samples (a warning). */
#define GREEN_SETTLED_TOL 0.01

/* The dynamic layer: ZOH (and point) samples, checked against the static
 * layer with the f = 0 modulus (into stat), written to a->out (and
 * a->out_point). */
static int green_dynamic_write(green_args *a, double *stat, int nk, int c0,
                               proto_err *err) {
  const grn_dyn_opts *o = &a->o;
  double *gz = malloc((size_t)o->Q * nk * sizeof *gz), *gp = malloc((size_t)o->Q * nk * sizeof *gp);
  double *sum = malloc(nk * sizeof *sum);
  a->o.progress = progress;
  a->o.progress_user = "green";
  int rc = (gz && gp && sum) ? grn_dynamic(&a->g, &a->mat, a->h, o, gz, gp, stat, err)
                             : proto_fail(err, "green: out of memory");
  if (!rc) {
    double worst = 0, worst_p = 0;
    for (int m = 0; m < nk; m++) {
      const double sz = time_sum(gz, o->Q, nk, m, o->rate);
      const double sp = time_sum(gp, o->Q, nk, m, o->rate);
      worst = fmax(worst, fabs(sz - stat[m]) / stat[c0]);
      worst_p = fmax(worst_p, fabs(sp - stat[m]) / stat[c0]);
      sum[m] = sz;
    }
    fprintf(stderr, "green: time sum vs static (relaxed modulus): zoh %.2e, point %.2e "
                    "(worst offset, of the self coefficient %.4g m/N)\n", worst, worst_p, stat[c0]);
    if (worst > GREEN_SETTLED_TOL)
      fprintf(stderr, "green: WARNING: the zoh time sum misses the static coefficient by "
                      "%.1f%% > 1%%: the response has not settled within Q = %d samples "
                      "(raise --Q or check the loss-factor table)\n", 100 * worst, o->Q);
    const char *model_s = "layer-dynamic";
    rc = grn_write_green(a->out, &a->g, o->Q, o->rate, "zoh", model_s, gz, sum, stat, worst,
                         a->h, &a->mat, err);
    if (!rc && a->out_point) {
      for (int m = 0; m < nk; m++) sum[m] = time_sum(gp, o->Q, nk, m, o->rate);
      rc = grn_write_green(a->out_point, &a->g, o->Q, o->rate, "point", model_s, gp, sum, stat,
                           worst_p, a->h, &a->mat, err);
      if (!rc) fprintf(stderr, "green: wrote %s\n", a->out_point);
    }
  }
  free(gz);
  free(gp);
  free(sum);
  return rc;
}

static int cmd_green(int argc, char **argv, proto_err *err) {
  green_args a;
  if (green_parse(argc, argv, &a, err)) return -1;
  const grn_grid *g = &a.g;
  const int nk = (2 * g->nx - 1) * (2 * g->ny - 1), c0 = (g->ny - 1) * (2 * g->nx - 1) + g->nx - 1;
  double *stat = malloc(nk * sizeof *stat);
  if (!stat) return proto_fail(err, "green: out of memory");
  int rc = 0;
  if (strcmp(a.model, "love") == 0) {
    grn_static_love(g, a.mat.E[0], a.mat.nu, stat);
    rc = grn_write_green(a.out, g, 1, 0, "static", "halfspace-love", NULL, stat, NULL, 0, 0,
                         &a.mat, err);
  } else if (strcmp(a.model, "layer") == 0) {
    rc = grn_static_layer(g, a.h, a.mat.E[0], a.mat.nu, a.o.pad, stat, err);
    if (!rc)
      rc = grn_write_green(a.out, g, 1, 0, "static", "layer", NULL, stat, NULL, 0, a.h, &a.mat,
                           err);
  } else if (strcmp(a.model, "dynamic") == 0) {
    rc = green_dynamic_write(&a, stat, nk, c0, err);
  } else {
    rc = proto_fail(err, "--model = '%s': expected love, layer or dynamic", a.model);
  }
  if (!rc) fprintf(stderr, "green: wrote %s (self coefficient %.4g m/N)\n", a.out, stat[c0]);
  free(stat);
  return rc;
}

static void usage(void) {
  fputs(
      "usage: cosim_green road    [--out road.h5] [--points 2000[x2000]] [--pitch 1e-5]\n"
      "                           [--hurst 0.8] [--rms 1e-4] [--lambda-short 5e-5]\n"
      "                           [--lambda-long 1e-2] [--seed 1] [--from heights.txt|.h5]\n"
      "       cosim_green springs --road road.h5|heights.txt [--pitch P] [--out springs.h5]\n"
      "                           [--elements 20[x20]] [--knots 33] [--E 25e6] [--nu 0.5]\n"
      "                           [--film relief|THICKNESS] [--d-max-frac 0.5]\n"
      "                           [--release-force 0.6] [--no-poly]\n"
      "       cosim_green green   [--model dynamic|layer|love] [--elements 20[x20]]\n"
      "                           [--size 1e-3|DXxDY] [--thickness 0.01] [--E E] [--nu 0.499]\n"
      "                           [--rho 1300] [--table f_E_eta.txt] [--Q 512] [--rate 51200]\n"
      "                           [--out green.h5] [--out-point green_point.h5]\n"
      "                           [--oversample 4] [--period-factor 4] [--pad N]\n"
      "Files: green/FORMATS.md. Defaults: seed 002 appendix B tread layer.\n",
      stderr);
}

int main(int argc, char **argv) {
  if (argc < 2) {
    usage();
    return 2;
  }
  for (int i = 1; i < argc; i++) /* `cosim road --help` too */
    if (!strcmp(argv[i], "--help") || !strcmp(argv[i], "-h")) {
      usage();
      return 0;
    }
  proto_err err = {{0}};
  int rc;
  const char *cmd = argv[1];
  if (!strcmp(cmd, "road")) rc = cmd_road(argc - 1, argv + 1, &err);
  else if (!strcmp(cmd, "springs")) rc = cmd_springs(argc - 1, argv + 1, &err);
  else if (!strcmp(cmd, "green")) rc = cmd_green(argc - 1, argv + 1, &err);
  else {
    usage();
    return 2;
  }
  if (rc) {
    fprintf(stderr, "cosim_green %s: %s\n", cmd, err.msg);
    return 1;
  }
  return 0;
}
