/* springs.c — roughness springs from fine road heights (seed 002 ch. 3.2):
 * contact patches above depth d, equivalent punch radii a = sqrt(A/π), the
 * flat-punch stiffness on a bonded incompressible film (punch.c), integrated
 * to F(d); represented by a monotone C¹ cubic Hermite (Fritsch–Carlson,
 * pchip.c; evaluated by the spring law, spring_law.c) and by the thesis'
 * 10th-order polynomial with dF/dd >= 0. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "green/green.h"

void grn_spring_opts_default(grn_spring_opts *o) {
  memset(o, 0, sizeof *o);
  o->K = 33;
  o->E = 25e6;  /* appendix B tread modulus at 0 Hz */
  o->nu = 0.5;  /* incompressible film (Yang 1998) */
  o->d_max_frac = 0.5;
  o->h_floor_frac = 0.02;
  o->film_h = 0;
  o->refine = 8;
  o->release_force = GRN_RELEASE_FORCE_DEFAULT;
  o->poly = 1;
}

/* ----------------------------------------------------- union-find patches */

static int find(int *parent, int i) {
  while (parent[i] != i) {
    parent[i] = parent[parent[i]];
    i = parent[i];
  }
  return i;
}

typedef struct height_index {
  double z;
  int i;
} height_index;

/* Depth span of the knots of a flat element (no relief), m: far below any
 * roughness, it only keeps the depths increasing. */
#define GRN_FLAT_SPAN 1e-9
/* The punch table's a/h range and size: from near the half-space (a/h =
 * 1e-3) to the thin film (a/h = 40; beyond either end grn_punch_phi goes on
 * with the asymptotic laws), 36 points log-spaced (punch.c). */
#define GRN_PUNCH_LAM_MIN 1e-3
#define GRN_PUNCH_LAM_MAX 40.0
enum { GRN_PUNCH_POINTS = 36 };

static int by_height_desc(const void *a, const void *b) {
  double za = ((const height_index *)a)->z, zb = ((const height_index *)b)->z;
  return (za < zb) - (za > zb);
}

int grn_spring_raw(const double *z, int cols, int rows, int stride,
                   double ds_x, double ds_y, const grn_punch_table *pt,
                   const grn_spring_opts *o, int nd, double *d, double *F,
                   double *kraw, proto_err *err) {
  const int n = cols * rows;
  double *zz = malloc(n * sizeof *zz);
  height_index *order = malloc(n * sizeof *order);
  int *parent = malloc(n * sizeof *parent);
  int *size = malloc(n * sizeof *size), *active = malloc(n * sizeof *active);
  if (!zz || !order || !parent || !size || !active) {
    free(zz); free(order); free(parent); free(size); free(active);
    return proto_fail(err, "springs: out of memory");
  }
  double zmax = -INFINITY, zmin = INFINITY;
  for (int j = 0; j < rows; j++)
    for (int i = 0; i < cols; i++) {
      double v = z[(size_t)j * stride + i];
      zz[j * cols + i] = v;
      zmax = fmax(zmax, v);
      zmin = fmin(zmin, v);
    }
  const double relief = zmax - zmin, E_star = o->E / (1 - o->nu * o->nu);
  const double dA = ds_x * ds_y;
  for (int k = 0; k < n; k++) {
    order[k].z = zz[k];
    order[k].i = k;
    parent[k] = -1; /* not in contact */
  }
  qsort(order, n, sizeof *order, by_height_desc);
  int next = 0, nact = 0;
  for (int m = 0; m < nd; m++) {
    /* a flat element (no relief) still gets increasing depths */
    d[m] = fmax(o->d_max_frac * relief, GRN_FLAT_SPAN) * m / (nd - 1);
    /* points above the plane z_max − d join; merge with 4-neighbours */
    while (next < n && order[next].z >= zmax - d[m]) {
      int p = order[next++].i, pi = p % cols, pj = p / cols;
      parent[p] = p;
      size[p] = 1;
      active[nact++] = p;
      const int nb[4][2] = {{-1, 0}, {1, 0}, {0, -1}, {0, 1}};
      for (int q = 0; q < 4; q++) {
        int ni = pi + nb[q][0], nj = pj + nb[q][1];
        if (ni < 0 || nj < 0 || ni >= cols || nj >= rows) continue;
        int nn = nj * cols + ni;
        if (parent[nn] < 0) continue;
        int ra = find(parent, p), rb = find(parent, nn);
        if (ra == rb) continue;
        if (size[ra] < size[rb]) { int t = ra; ra = rb; rb = t; }
        parent[rb] = ra;
        size[ra] += size[rb];
      }
    }
    /* film thickness: thesis rule h = z_max − d − z_min (the rubber between
     * the indentation plane and the deepest valley), floored */
    double h = o->film_h > 0 ? o->film_h
                             : fmax(relief - d[m], o->h_floor_frac * relief);
    double ksum = 0;
    for (int a = 0; a < nact; a++) {
      int p = active[a];
      if (parent[p] != p) continue; /* only roots */
      double radius = sqrt(size[p] * dA / M_PI);
      ksum += 2 * E_star * radius * (h > 0 ? grn_punch_phi(pt, radius / h) : 1.0);
    }
    kraw[m] = ksum;
    F[m] = m == 0 ? 0 : F[m - 1] + 0.5 * (d[m] - d[m - 1]) * (kraw[m] + kraw[m - 1]);
  }
  free(zz); free(order); free(parent); free(size); free(active);
  return 0;
}

/* ------------------------------------------- 10th-order monotone poly fit */

#define NP (GRN_POLY_COEFFS - 1) /* unknowns c_1..c_10 (c_0 = 0: F(0) = 0) */

/* Weighted least squares by Householder QR of the rows (A | b). */
static int lsq(int rows, double *A, double *b, double *x) {
  for (int c = 0; c < NP; c++) {
    double nrm = 0;
    for (int r = c; r < rows; r++) nrm += A[r * NP + c] * A[r * NP + c];
    nrm = sqrt(nrm);
    if (nrm == 0) return -1;
    double alpha = A[c * NP + c] > 0 ? -nrm : nrm;
    double v0 = A[c * NP + c] - alpha;
    /* v = (v0, A[c+1..][c]); H = I − 2 v vᵀ / vᵀv */
    double vtv = v0 * v0;
    for (int r = c + 1; r < rows; r++) vtv += A[r * NP + c] * A[r * NP + c];
    for (int k = c + 1; k <= NP; k++) {
      double dot = v0 * (k < NP ? A[c * NP + k] : b[c]);
      for (int r = c + 1; r < rows; r++) dot += A[r * NP + c] * (k < NP ? A[r * NP + k] : b[r]);
      double f = 2 * dot / vtv;
      if (k < NP) {
        A[c * NP + k] -= f * v0;
        for (int r = c + 1; r < rows; r++) A[r * NP + k] -= f * A[r * NP + c];
      } else {
        b[c] -= f * v0;
        for (int r = c + 1; r < rows; r++) b[r] -= f * A[r * NP + c];
      }
    }
    A[c * NP + c] = alpha;
  }
  for (int c = NP - 1; c >= 0; c--) {
    double s = b[c];
    for (int k = c + 1; k < NP; k++) s -= A[c * NP + k] * x[k];
    x[c] = s / A[c * NP + c];
  }
  return 0;
}

double grn_poly_eval(const double *c, double d, double *dFdd) {
  double F = 0, dF = 0;
  for (int i = NP; i >= 1; i--) {
    F = (F + c[i]) * d;
    if (dFdd) dF = dF * d + i * c[i];
  }
  F += c[0];
  if (dFdd) *dFdd = dF;
  return F;
}

int grn_polyfit_monotone(int n, const double *d, const double *F, double *c,
                         proto_err *err) {
  const double dmax = d[n - 1], Fmax = fmax(fabs(F[n - 1]), 1e-300);
  const int ncheck = 200;
  int *active = calloc(ncheck + 1, sizeof *active);
  double *A = malloc((size_t)(n + ncheck + 1) * NP * sizeof *A);
  double *b = malloc((size_t)(n + ncheck + 1) * sizeof *b), x[NP] = {0};
  if (!active || !A || !b) {
    free(active); free(A); free(b);
    return proto_fail(err, "polyfit: out of memory");
  }
  int rc = -1;
  /* scaled variable s = d/dmax, F/Fmax; constraints p'(s_m) >= 0 enforced as
   * heavily weighted rows p'(s_m) = 0 where violated (active set) */
  for (int it = 0; it < 40; it++) {
    int rows = 0;
    for (int k = 0; k < n; k++, rows++) {
      double s = d[k] / dmax, p = 1;
      for (int i = 0; i < NP; i++) { p *= s; A[rows * NP + i] = p; }
      b[rows] = F[k] / Fmax;
    }
    for (int m = 0; m <= ncheck; m++) {
      if (!active[m]) continue;
      double s = (double)m / ncheck, p = 1, w = 1e3 * sqrt((double)n);
      for (int i = 0; i < NP; i++) { A[rows * NP + i] = w * (i + 1) * p; p *= s; }
      b[rows++] = 0;
    }
    if (lsq(rows, A, b, x)) { proto_fail(err, "polyfit: rank-deficient fit"); goto done; }
    int added = 0;
    for (int m = 0; m <= ncheck; m++) {
      double s = (double)m / ncheck, dp = 0, p = 1;
      for (int i = 0; i < NP; i++) { dp += (i + 1) * x[i] * p; p *= s; }
      if (dp < -1e-12 && !active[m]) { active[m] = 1; added++; }
    }
    if (!added) break;
  }
  c[0] = 0;
  for (int i = 0; i < NP; i++) c[i + 1] = x[i] * Fmax / pow(dmax, i + 1);
  rc = 0;
done:
  free(active); free(A); free(b);
  return rc;
}

/* ------------------------------------------------------ all elements */

void grn_springs_free(grn_springs *sp) {
  free(sp->z_road); free(sp->d); free(sp->F); free(sp->k); free(sp->poly);
  free(sp->err_hermite); free(sp->err_poly);
  free(sp->raw_d); free(sp->raw_F); free(sp->raw_k);
  memset(sp, 0, sizeof *sp);
}

int grn_springs_build(const grn_surface *s, int nx, int ny,
                      const grn_spring_opts *o, grn_springs *out,
                      grn_progress_fn progress, void *user, proto_err *err) {
  memset(out, 0, sizeof *out);
  if (o->K < 3 || o->refine < 1)
    return proto_fail(err, "springs: knots = %d (need >= 3), refine = %d (need >= 1)", o->K, o->refine);
  if (!(o->E > 0) || !(o->nu >= 0 && o->nu <= 0.5))
    return proto_fail(err, "springs: E = %g, nu = %g: need E > 0, 0 <= nu <= 0.5", o->E, o->nu);
  if (!(o->d_max_frac > 0 && o->d_max_frac <= 1))
    return proto_fail(err, "springs: d_max_frac = %g must be in (0, 1]", o->d_max_frac);
  if (o->film_h < 0)
    return proto_fail(err, "springs: film thickness = %g: must be > 0 (or 0 for the relief rule)", o->film_h);
  const int M = nx * ny, K = o->K, Kf = (K - 1) * o->refine + 1;
  out->nx = nx; out->ny = ny; out->K = K; out->Kf = Kf;
  out->release_force = o->release_force;
  out->z_road = malloc(M * sizeof(double));
  out->d = malloc((size_t)M * K * sizeof(double));
  out->F = malloc((size_t)M * K * sizeof(double));
  out->k = malloc((size_t)M * K * sizeof(double));
  out->poly = o->poly ? malloc((size_t)M * GRN_POLY_COEFFS * sizeof(double)) : NULL;
  out->err_hermite = malloc(M * sizeof(double));
  out->err_poly = malloc(M * sizeof(double));
  out->raw_d = malloc((size_t)M * Kf * sizeof(double));
  out->raw_F = malloc((size_t)M * Kf * sizeof(double));
  out->raw_k = malloc((size_t)M * Kf * sizeof(double));
  if (!out->z_road || !out->d || !out->F || !out->k || (o->poly && !out->poly) ||
      !out->err_hermite || !out->err_poly || !out->raw_d || !out->raw_F || !out->raw_k) {
    grn_springs_free(out);
    return proto_fail(err, "springs: out of memory for %d elements", M);
  }
  if (grn_surface_downsample_max(s, nx, ny, out->z_road, err)) {
    grn_springs_free(out);
    return -1;
  }
  const int px = s->Nx / nx, py = s->Ny / ny;
  out->dx = px * s->dx;
  out->dy = py * s->dy;
  grn_punch_table pt;
  /* a/h from half-space to thin film; beyond: the asymptotic laws */
  if (grn_punch_table_build(&pt, o->nu, GRN_PUNCH_LAM_MIN, GRN_PUNCH_LAM_MAX,
                            GRN_PUNCH_POINTS, err)) {
    grn_springs_free(out);
    return proto_wrap(err, "springs");
  }
  for (int e = 0; e < M; e++) {
    int ex = e % nx, ey = e / nx;
    double *rd = out->raw_d + (size_t)e * Kf, *rF = out->raw_F + (size_t)e * Kf,
           *rk = out->raw_k + (size_t)e * Kf;
    if (grn_spring_raw(s->z + (size_t)ey * py * s->Nx + (size_t)ex * px, px, py, s->Nx,
                       s->dx, s->dy, &pt, o, Kf, rd, rF, rk, err)) {
      grn_punch_table_free(&pt);
      grn_springs_free(out);
      return proto_wrap(err, "springs: element %d (%d, %d)", e, ex, ey);
    }
    double *d = out->d + (size_t)e * K, *F = out->F + (size_t)e * K, *k = out->k + (size_t)e * K;
    for (int j = 0; j < K; j++) {
      d[j] = rd[j * o->refine];
      F[j] = rF[j * o->refine];
      k[j] = rk[j * o->refine]; /* the exact dF/dd of the raw curve ... */
    }
    grn_pchip_limit(K, d, F, k); /* ... limited to keep F monotone */
    double eh = 0, ep = 0, scale = fmax(rF[Kf - 1], 1e-300);
    for (int j = 0; j < Kf; j++)
      eh = fmax(eh, fabs(grn_pchip_eval(K, d, F, k, rd[j], NULL) - rF[j]));
    out->err_hermite[e] = eh / scale;
    if (o->poly) {
      double *c = out->poly + (size_t)e * GRN_POLY_COEFFS;
      if (rd[Kf - 1] > 0) {
        if (grn_polyfit_monotone(Kf, rd, rF, c, err)) {
          grn_punch_table_free(&pt);
          grn_springs_free(out);
          return proto_wrap(err, "springs: element %d", e);
        }
        for (int j = 0; j < Kf; j++)
          ep = fmax(ep, fabs(grn_poly_eval(c, rd[j], NULL) - rF[j]));
      } else {
        memset(c, 0, GRN_POLY_COEFFS * sizeof *c);
      }
      out->err_poly[e] = ep / scale;
    } else {
      out->err_poly[e] = NAN;
    }
    if (progress && (e % 20 == 0 || e == M - 1))
      progress(user, (e + 1.0) / M, "elements");
  }
  grn_punch_table_free(&pt);
  return 0;
}
