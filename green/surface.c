/* surface.c — self-affine rough road surfaces (generator, readers, PSD
 * check) and the down-sampling to the block grid (seed 002 ch. 3.1). */
#include <complex.h>
#include <errno.h>
#include <fftw3.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "green/green.h"
#include "green/h5util.h"

/* The road file (FORMATS.md): /road/heights [Ny][Nx], attributes dx, dy. */
#define G_ROAD "/road"
#define D_HEIGHTS "heights"

/* splitmix64: small, seedable, reproducible across platforms */
static uint64_t splitmix64(uint64_t *s) {
  uint64_t z = (*s += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}
static double uniform01(uint64_t *s) { return (splitmix64(s) >> 11) * 0x1.0p-53; }

void grn_surface_free(grn_surface *s) {
  free(s->z);
  s->z = NULL;
}

double grn_surface_rms(const grn_surface *s) {
  size_t n = (size_t)s->Nx * s->Ny;
  double m = 0, v = 0;
  for (size_t k = 0; k < n; k++) m += s->z[k];
  m /= n;
  for (size_t k = 0; k < n; k++) v += (s->z[k] - m) * (s->z[k] - m);
  return sqrt(v / n);
}

int grn_surface_generate(const grn_surface_params *p, grn_surface *s,
                         proto_err *err) {
  memset(s, 0, sizeof *s);
  if (p->Nx < 4 || p->Ny < 4)
    return proto_fail(err, "road: points = %d x %d: need at least 4 x 4", p->Nx, p->Ny);
  if (!(p->dx > 0) || !(p->dy > 0))
    return proto_fail(err, "road: pitch dx = %g, dy = %g: must be > 0", p->dx, p->dy);
  if (!(p->hurst > 0 && p->hurst < 1))
    return proto_fail(err, "road: hurst = %g: must be in (0, 1)", p->hurst);
  if (!(p->rms > 0) || !isfinite(p->rms))
    return proto_fail(err, "road: rms = %g: must be > 0", p->rms);
  if (!(p->lambda_short > 0) || !(p->lambda_long > p->lambda_short))
    return proto_fail(err, "road: lambda_short = %g, lambda_long = %g: need 0 < short < long",
                      p->lambda_short, p->lambda_long);
  if (p->lambda_short < 2 * fmax(p->dx, p->dy))
    return proto_fail(err, "road: lambda_short = %g m is below two pitches (%g m)",
                      p->lambda_short, 2 * fmax(p->dx, p->dy));
  if ((int64_t)p->Nx * p->Ny > GRN_MAX_POINTS)
    return proto_fail(err, "road: points = %d x %d: more than %lld", p->Nx, p->Ny,
                      (long long)GRN_MAX_POINTS);
  const int Nx = p->Nx, Ny = p->Ny, nqx = Nx / 2 + 1;
  fftw_complex *c = fftw_alloc_complex((size_t)Ny * nqx);
  s->z = malloc((size_t)Nx * Ny * sizeof *s->z);
  double *out = fftw_alloc_real((size_t)Nx * Ny);
  if (!c || !s->z || !out) {
    fftw_free(c);
    fftw_free(out);
    grn_surface_free(s);
    return proto_fail(err, "road: out of memory for %d x %d points", Nx, Ny);
  }
  fftw_plan plan = fftw_plan_dft_c2r_2d(Ny, Nx, c, out, FFTW_ESTIMATE);
  const double qL = 2 * M_PI / p->lambda_long, qS = 2 * M_PI / p->lambda_short;
  uint64_t st = p->seed;
  /* random phases, amplitude sqrt(C(q)): C = const below q_L (roll-off),
   * ∝ q^{-2(1+H)} up to q_S, 0 above (Persson's self-affine model) */
  for (int j = 0; j < Ny; j++) {
    int jj = j <= Ny / 2 ? j : j - Ny;
    for (int i = 0; i < nqx; i++) {
      double qx = 2 * M_PI * i / (Nx * p->dx), qy = 2 * M_PI * jj / (Ny * p->dy);
      double q = hypot(qx, qy), C = 0;
      if (q > 0 && q <= qS)
        C = q < qL ? 1.0 : pow(q / qL, -2 * (1 + p->hurst));
      double ph = 2 * M_PI * uniform01(&st);
      c[(size_t)j * nqx + i] = sqrt(C) * cexp(I * ph);
    }
  }
  /* Hermitian symmetry on the columns that c2r reads both halves of */
  for (int i = 0; i < nqx; i += (Nx % 2 == 0 && Nx / 2 > 0) ? Nx / 2 : nqx) {
    for (int j = Ny / 2 + 1; j < Ny; j++)
      c[(size_t)j * nqx + i] = conj(c[(size_t)(Ny - j) * nqx + i]);
    c[i] = creal(c[i]);
    if (Ny % 2 == 0) c[(size_t)(Ny / 2) * nqx + i] = creal(c[(size_t)(Ny / 2) * nqx + i]);
  }
  fftw_execute(plan);
  fftw_destroy_plan(plan);
  s->Nx = Nx;
  s->Ny = Ny;
  s->dx = p->dx;
  s->dy = p->dy;
  memcpy(s->z, out, (size_t)Nx * Ny * sizeof *s->z);
  fftw_free(out);
  fftw_free(c);
  double r = grn_surface_rms(s), m = 0;
  if (!(r > 0)) {
    grn_surface_free(s);
    return proto_fail(err, "road: no wavelengths between lambda_short and the grid size");
  }
  size_t n = (size_t)Nx * Ny;
  for (size_t k = 0; k < n; k++) m += s->z[k];
  m /= n;
  for (size_t k = 0; k < n; k++) s->z[k] = (s->z[k] - m) * p->rms / r;
  return 0;
}

double grn_surface_psd_slope(const grn_surface *s, double q_lo, double q_hi,
                             proto_err *err) {
  const int Nx = s->Nx, Ny = s->Ny, nqx = Nx / 2 + 1, nb = 24;
  double *in = fftw_alloc_real((size_t)Nx * Ny);
  fftw_complex *c = fftw_alloc_complex((size_t)Ny * nqx);
  double sum[24] = {0}, cnt[24] = {0}, qs[24] = {0};
  if (!in || !c) {
    fftw_free(in);
    fftw_free(c);
    proto_fail(err, "psd: out of memory");
    return NAN;
  }
  fftw_plan plan = fftw_plan_dft_r2c_2d(Ny, Nx, in, c, FFTW_ESTIMATE);
  memcpy(in, s->z, (size_t)Nx * Ny * sizeof *in);
  fftw_execute(plan);
  fftw_destroy_plan(plan);
  for (int j = 0; j < Ny; j++) {
    int jj = j <= Ny / 2 ? j : j - Ny;
    for (int i = 0; i < nqx; i++) {
      double q = hypot(2 * M_PI * i / (Nx * s->dx), 2 * M_PI * jj / (Ny * s->dy));
      if (q < q_lo || q >= q_hi) continue;
      int b = (int)(nb * log(q / q_lo) / log(q_hi / q_lo));
      double a = cabs(c[(size_t)j * nqx + i]);
      sum[b] += a * a;
      cnt[b] += 1;
      qs[b] += log(q);
    }
  }
  fftw_free(in);
  fftw_free(c);
  /* least squares of log C against log q over the filled bins */
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  int m = 0;
  for (int b = 0; b < nb; b++) {
    if (cnt[b] < 1) continue;
    double x = qs[b] / cnt[b], y = log(sum[b] / cnt[b]);
    sx += x; sy += y; sxx += x * x; sxy += x * y;
    m++;
  }
  if (m < 3) {
    proto_fail(err, "psd: fewer than 3 filled bins in [%g, %g] 1/m", q_lo, q_hi);
    return NAN;
  }
  return (m * sxy - sx * sy) / (m * sxx - sx * sx);
}

int grn_surface_downsample_max(const grn_surface *s, int nx, int ny,
                               double *z_road, proto_err *err) {
  if (nx < 1 || ny < 1 || s->Nx % nx || s->Ny % ny)
    return proto_fail(err, "road: %d x %d points do not divide into %d x %d elements",
                      s->Nx, s->Ny, nx, ny);
  const int px = s->Nx / nx, py = s->Ny / ny;
  for (int ey = 0; ey < ny; ey++)
    for (int ex = 0; ex < nx; ex++) {
      double zmax = -INFINITY;
      for (int j = ey * py; j < (ey + 1) * py; j++)
        for (int i = ex * px; i < (ex + 1) * px; i++)
          zmax = fmax(zmax, s->z[(size_t)j * s->Nx + i]);
      z_road[ey * nx + ex] = zmax;
    }
  return 0;
}

/* ------------------------------------------------------------ readers */

int grn_surface_read_text(const char *path, double dx, double dy,
                          grn_surface *s, proto_err *err) {
  memset(s, 0, sizeof *s);
  FILE *fp = fopen(path, "r");
  if (!fp)
    return proto_fail(err, "%s: %s", path, strerror(errno));
  size_t cap = 0, n = 0, linecap = 0;
  char *line = NULL;
  int cols = -1, rows = 0, lineno = 0, rc = -1;
  double *z = NULL;
  while (getline(&line, &linecap, fp) > 0) {
    lineno++;
    char *p = line;
    while (*p == ' ' || *p == '\t') p++;
    if (*p == '#') {
      double v;
      if (sscanf(p, "# dx = %lf", &v) == 1) dx = v;
      if (sscanf(p, "# dy = %lf", &v) == 1) dy = v;
      continue;
    }
    int c = 0;
    for (;;) {
      while (*p == ' ' || *p == '\t' || *p == ',') p++;
      if (*p == '\n' || *p == '\r' || *p == '\0') break;
      char *end;
      double v = strtod(p, &end);
      if (end == p) {
        proto_fail(err, "%s:%d: column %d: '%.*s' is not a number", path, lineno, c + 1,
                   (int)fmin(20, strcspn(p, " \t,\r\n")), p);
        goto done;
      }
      if (!isfinite(v)) {
        proto_fail(err, "%s:%d: column %d: height '%.*s' is not a finite number (NaN/inf "
                        "in the height map)", path, lineno, c + 1,
                   (int)fmin(20, strcspn(p, " \t,\r\n")), p);
        goto done;
      }
      if ((int64_t)n == GRN_MAX_POINTS) {
        proto_fail(err, "%s:%d: more than %lld heights", path, lineno,
                   (long long)GRN_MAX_POINTS);
        goto done;
      }
      if (n == cap) {
        cap = cap ? 2 * cap : 4096;
        double *nz = realloc(z, cap * sizeof *z);
        if (!nz) { proto_fail(err, "%s: out of memory", path); goto done; }
        z = nz;
      }
      z[n++] = v;
      c++;
      p = end;
    }
    if (c == 0) continue;
    if (cols >= 0 && c != cols) {
      proto_fail(err, "%s:%d: %d values, previous rows had %d", path, lineno, c, cols);
      goto done;
    }
    cols = c;
    rows++;
  }
  if (rows < 2 || cols < 2) {
    proto_fail(err, "%s: need at least 2 x 2 heights, found %d x %d", path, rows, cols < 0 ? 0 : cols);
    goto done;
  }
  if (!(dx > 0) || !(dy > 0) || !isfinite(dx) || !isfinite(dy)) {
    proto_fail(err, "%s: pitch dx = %g, dy = %g: give '# dx = ...' lines or options > 0", path, dx, dy);
    goto done;
  }
  s->Nx = cols; s->Ny = rows; s->dx = dx; s->dy = dy; s->z = z;
  z = NULL;
  rc = 0;
done:
  free(line);
  free(z);
  fclose(fp);
  return rc;
}

int grn_surface_read_h5(const char *path, grn_surface *s, proto_err *err) {
  memset(s, 0, sizeof *s);
  proto_h5in *f = proto_h5in_open(path, err);
  if (!f) return -1;
  int rc = -1;
  double dx = 0, dy = 0;
  int64_t dims[2] = {-1, -1};
  int ax = proto_h5in_attr_f8(f, G_ROAD, "dx", &dx, err);
  int ay = ax < 0 ? -1 : proto_h5in_attr_f8(f, G_ROAD, "dy", &dy, err);
  if (ax < 0 || ay < 0) goto done;
  if (ax || ay || !(dx > 0) || !(dy > 0)) {
    proto_fail(err, "%s: /road needs attributes dx, dy > 0 (m)", path);
    goto done;
  }
  if (proto_h5in_read_f8(f, G_ROAD "/" D_HEIGHTS, 2, dims, GRN_MAX_POINTS, &s->z, err) < 0)
    goto done;
  if (dims[0] < 2 || dims[1] < 2 || dims[0] > INT32_MAX || dims[1] > INT32_MAX) {
    proto_fail(err, "%s:/road/heights: need at least 2 x 2 heights, found %lld x %lld",
               path, (long long)dims[0], (long long)dims[1]);
    goto done;
  }
  s->Ny = (int)dims[0]; s->Nx = (int)dims[1]; s->dx = dx; s->dy = dy;
  rc = 0;
done:
  proto_h5in_close(f);
  if (rc) grn_surface_free(s);
  return rc;
}

int grn_surface_write_h5(const char *path, const grn_surface *s,
                         const grn_surface_params *p, proto_err *err) {
  proto_h5 *f = proto_h5_create(path, err);
  if (!f) return -1;
  const int64_t dims[2] = {s->Ny, s->Nx};
  int rc = grn_h5_write(f, G_ROAD, D_HEIGHTS, 2, dims, s->z, err);
  if (!rc) rc = proto_h5_attr_f8(f, G_ROAD, "dx", s->dx, err);
  if (!rc) rc = proto_h5_attr_f8(f, G_ROAD, "dy", s->dy, err);
  if (!rc && p) {
    rc = proto_h5_attr_f8(f, G_ROAD, "hurst", p->hurst, err);
    if (!rc) rc = proto_h5_attr_f8(f, G_ROAD, "rms", p->rms, err);
    if (!rc) rc = proto_h5_attr_f8(f, G_ROAD, "lambda_short", p->lambda_short, err);
    if (!rc) rc = proto_h5_attr_f8(f, G_ROAD, "lambda_long", p->lambda_long, err);
    if (!rc) rc = proto_h5_attr_i8(f, G_ROAD, "seed", (int64_t)p->seed, err);
  }
  return proto_h5_close(f, rc ? NULL : err) < 0 || rc ? -1 : 0;
}
