/* blk_model.c — building and checking the block model: grid, road, roughness
 * springs (seed 002 ch. 3.2) and the thesis' spring softening (ch. 4.2.2).
 * Green's functions: blk_green.c; the springs' law, energy and inverse:
 * blk_spring.c. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "contact_block/blk_internal.h"

/* Relative mismatch K(Δ) − K(Δ − n) of a periodic kernel taken as the
 * round-off of its image sums (green/periodic.c converges far below). */
#define BLK_PERIODIC_TOL 1e-9

/* Elements per axis: the matrix-free solver's FFT box is 2n per axis. */
enum { BLK_GRID_MAX = 4096 };

int blk_model_init(blk_model *m, int nx, int ny, double dx, double dy,
                   proto_err *err) {
  memset(m, 0, sizeof *m);
  if (nx < 1 || ny < 1 || nx > BLK_GRID_MAX || ny > BLK_GRID_MAX)
    return proto_fail(err, "grid: nx, ny must be in [1, %d] (got %d x %d)", BLK_GRID_MAX,
                      nx, ny);
  if (!(dx > 0) || !(dy > 0) || !isfinite(dx) || !isfinite(dy))
    return proto_fail(err, "grid: element size must be > 0 (got %g x %g)", dx, dy);
  m->nx = nx;
  m->ny = ny;
  m->M = nx * ny;
  m->dx = dx;
  m->dy = dy;
  m->nox = 2 * nx - 1;
  m->noy = 2 * ny - 1;
  m->z_road = calloc((size_t)m->M, sizeof(double));
  if (!m->z_road) return proto_fail(err, "out of memory");
  m->release_force = GRN_RELEASE_FORCE_DEFAULT;
  m->solver.method = BLK_AUTO;
  m->solver.max_iter = 10;      /* appendix C default */
  m->solver.tol = 1e-13;        /* m; the thesis' 1e-15 is below round-off here */
  m->solver.history = BLK_HIST_AUTO;
  m->solver.tail_tol = 1e-14;
  m->solver.max_force = 1e6;
  m->solver.cg_max_iter = 2000;
  m->solver.tangent = 1;
  return 0;
}

static void springs_release(blk_model *m) {
  free(m->spr_d);
  free(m->spr_F);
  free(m->spr_k);
  free(m->spr_W);
  free(m->spr_table);
  free(m->spr_scale);
  m->spr_d = m->spr_F = m->spr_k = m->spr_W = m->spr_scale = NULL;
  m->spr_table = NULL;
  m->n_knots = m->n_tables = 0;
  m->rigid = 0;
}

void blk_model_free(blk_model *m) {
  free(m->z_road);
  free(m->road_map);
  springs_release(m);
  free(m->g);
  free(m->g_time);
  free(m->g_space);
  free(m->g_static);
  memset(m, 0, sizeof *m);
}

/* ------------------------------------------------------------ random */

static uint64_t splitmix64(uint64_t *s) {
  uint64_t z = (*s += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}
static double uniform01(uint64_t *s) {
  return ((double)(splitmix64(s) >> 11) + 0.5) * (1.0 / 9007199254740992.0);
}
static double gauss(uint64_t *s) {
  double u = uniform01(s), v = uniform01(s);
  return sqrt(-2.0 * log(u)) * cos(2.0 * M_PI * v);
}

/* -------------------------------------------------------------- road */

int blk_road_set(blk_model *m, const double *z, proto_err *err) {
  for (int e = 0; e < m->M; e++) {
    if (!isfinite(z[e]))
      return proto_fail(err, "road: z_road of element %d (i=%d, j=%d) is not finite",
                        e, e % m->nx, e / m->nx);
  }
  memcpy(m->z_road, z, (size_t)m->M * sizeof(double));
  return 0;
}

int blk_road_paraboloid(blk_model *m, double R, proto_err *err) {
  if (!(R > 0) || !isfinite(R)) return proto_fail(err, "road: radius must be > 0");
  const double xc = 0.5 * m->nx * m->dx, yc = 0.5 * m->ny * m->dy;
  for (int j = 0; j < m->ny; j++)
    for (int i = 0; i < m->nx; i++) {
      double x = (i + 0.5) * m->dx - xc, y = (j + 0.5) * m->dy - yc;
      m->z_road[j * m->nx + i] = -(x * x + y * y) / (2.0 * R);
    }
  return 0;
}

int blk_road_random(blk_model *m, double rms, uint64_t seed, proto_err *err) {
  if (!(rms >= 0) || !isfinite(rms)) return proto_fail(err, "road: rms must be >= 0");
  uint64_t s = seed;
  double zmax = -INFINITY;
  for (int e = 0; e < m->M; e++) {
    m->z_road[e] = rms * gauss(&s);
    if (m->z_road[e] > zmax) zmax = m->z_road[e];
  }
  for (int e = 0; e < m->M; e++) m->z_road[e] -= zmax;
  return 0;
}

static int64_t wrap(int64_t i, int64_t n) { return ((i % n) + n) % n; }

/* The map's height at world cell (ci, cj): its own point when the pitches
 * agree, else bilinear between the four points around the cell's centre. */
static double map_height(const blk_model *m, int64_t ci, int64_t cj) {
  const int64_t nx = m->map_nx, ny = m->map_ny;
  if (m->dx == m->map_dx && m->dy == m->map_dy)
    return m->road_map[wrap(cj, ny) * nx + wrap(ci, nx)];
  const double u = (ci + 0.5) * m->dx / m->map_dx - 0.5, v = (cj + 0.5) * m->dy / m->map_dy - 0.5;
  const double fu = floor(u), fv = floor(v), a = u - fu, b = v - fv;
  const int64_t i0 = wrap((int64_t)fu, nx), j0 = wrap((int64_t)fv, ny);
  const int64_t i1 = wrap(i0 + 1, nx), j1 = wrap(j0 + 1, ny);
  const double *z = m->road_map;
  return (1 - b) * ((1 - a) * z[j0 * nx + i0] + a * z[j0 * nx + i1]) +
         b * ((1 - a) * z[j1 * nx + i0] + a * z[j1 * nx + i1]);
}

void blk_road_world(blk_model *m, double x, double y) {
  for (int j = 0; j < m->ny; j++)
    for (int i = 0; i < m->nx; i++) {
      const double xw = x + (i + 0.5 - 0.5 * m->nx) * m->dx;
      const double yw = y + (j + 0.5 - 0.5 * m->ny) * m->dy;
      const int64_t ci = (int64_t)floor(xw / m->dx), cj = (int64_t)floor(yw / m->dy);
      if (m->road_map) {
        m->z_road[j * m->nx + i] = map_height(m, ci, cj);
        continue;
      }
      uint64_t s = m->road_seed ^ ((uint64_t)ci * 0x9E3779B97F4A7C15ull) ^
                   ((uint64_t)cj * 0xC2B2AE3D27D4EB4Full);
      m->z_road[j * m->nx + i] = m->road_rms * gauss(&s);
    }
}

int blk_road_world_map(blk_model *m, const char *path, proto_err *err) {
  grn_surface sf;
  if (grn_surface_read_h5(path, &sf, err)) return -1;
  double mean = 0; /* finite: proto_h5in_read_f8 refuses NaN and inf */
  const size_t n = (size_t)sf.Nx * (size_t)sf.Ny;
  for (size_t e = 0; e < n; e++) mean += sf.z[e];
  mean /= (double)n;
  for (size_t e = 0; e < n; e++) sf.z[e] -= mean;
  free(m->road_map);
  m->road_map = sf.z; /* owned from here */
  m->map_nx = sf.Nx, m->map_ny = sf.Ny, m->map_dx = sf.dx, m->map_dy = sf.dy;
  m->road_world = 1;
  blk_road_world(m, 0, 0);
  return 0;
}

/* ----------------------------------------------------------- springs */

/* T tables of K knots; element e → table e (T = M) or table 0, scale 1. */
static int springs_alloc(blk_model *m, int T, int K, proto_err *err) {
  springs_release(m);
  const size_t n = (size_t)T * (size_t)K;
  m->spr_d = malloc(n * sizeof(double));
  m->spr_F = malloc(n * sizeof(double));
  m->spr_k = malloc(n * sizeof(double));
  m->spr_W = malloc(n * sizeof(double));
  m->spr_table = malloc((size_t)m->M * sizeof(int));
  m->spr_scale = malloc((size_t)m->M * sizeof(double));
  m->n_knots = K;
  m->n_tables = T;
  if (!m->spr_d || !m->spr_F || !m->spr_k || !m->spr_W || !m->spr_table || !m->spr_scale)
    return proto_fail(err, "out of memory");
  for (int e = 0; e < m->M; e++) {
    m->spr_table[e] = T == m->M ? e : 0;
    m->spr_scale[e] = 1.0;
  }
  return 0;
}

static int springs_check(const blk_model *m, proto_err *err) {
  if (m->rigid) return 0;
  const int K = m->n_knots;
  if (K < 2 || !m->spr_d) return proto_fail(err, "springs: none defined (need >= 2 knots)");
  for (int e = 0; e < m->M; e++) {
    const int t = m->spr_table[e];
    if (t < 0 || t >= m->n_tables || !(m->spr_scale[e] > 0) || !isfinite(m->spr_scale[e]))
      return proto_fail(err, "springs: element %d: table %d / scale %g invalid", e, t,
                        m->spr_scale[e]);
  }
  for (int t = 0; t < m->n_tables; t++) {
    const double *d = m->spr_d + (size_t)t * K, *F = m->spr_F + (size_t)t * K,
                 *k = m->spr_k + (size_t)t * K;
    /* tables are per element unless shared: name what the user gave */
    const char *what = m->n_tables == m->M ? "element" : "table";
    const int e = t;
    if (d[0] != 0.0 || F[0] != 0.0)
      return proto_fail(err, "springs: %s %d: table must start at d = 0, F = 0 "
                        "(got d = %g, F = %g)", what, e, d[0], F[0]);
    for (int i = 0; i < K; i++) {
      if (!isfinite(d[i]) || !isfinite(F[i]) || !isfinite(k[i]))
        return proto_fail(err, "springs: %s %d knot %d: not finite", what, e, i);
      if (k[i] < 0)
        return proto_fail(err, "springs: %s %d knot %d: stiffness k = %g < 0 "
                          "(spring law must be monotone)", what, e, i, k[i]);
      if (i > 0 && !(d[i] > d[i - 1]))
        return proto_fail(err, "springs: %s %d knot %d: compression d not "
                          "increasing (%g after %g)", what, e, i, d[i], d[i - 1]);
      if (i > 0 && F[i] < F[i - 1])
        return proto_fail(err, "springs: %s %d knot %d: force decreases (%g after "
                          "%g): non-monotone spring table", what, e, i, F[i], F[i - 1]);
    }
  }
  return 0;
}

int blk_springs_table(blk_model *m, int K, const double *d, const double *F,
                      const double *k, proto_err *err) {
  if (K < 2) return proto_fail(err, "springs: need >= 2 knots (got %d)", K);
  if (springs_alloc(m, m->M, K, err)) return -1;
  size_t n = (size_t)m->M * (size_t)K * sizeof(double);
  memcpy(m->spr_d, d, n);
  memcpy(m->spr_F, F, n);
  memcpy(m->spr_k, k, n);
  if (springs_check(m, err)) return -1;
  blk_springs_energies(m);
  return 0;
}

int blk_springs_linear(blk_model *m, const double *k, int per_element,
                       proto_err *err) {
  /* one unit table F = d (N/m), each element scaled by its stiffness */
  if (springs_alloc(m, 1, 2, err)) return -1;
  const double d1 = 1e-3; /* any knot; linear extension beyond */
  m->spr_d[0] = m->spr_F[0] = 0;
  m->spr_d[1] = m->spr_F[1] = d1;
  m->spr_k[0] = m->spr_k[1] = 1.0;
  for (int e = 0; e < m->M; e++) {
    double ke = per_element ? k[e] : k[0];
    if (!(ke > 0) || !isfinite(ke))
      return proto_fail(err, "springs: linear stiffness of element %d must be > 0 "
                        "(got %g)", e, ke);
    m->spr_scale[e] = ke;
  }
  blk_springs_energies(m);
  return 0;
}

int blk_springs_stiffening(blk_model *m, double k0, double d0, double spread,
                           uint64_t seed, double d_max, int K, proto_err *err) {
  if (!(k0 > 0) || !(d0 > 0) || !(d_max > 0) || !(spread >= 0 && spread < 1) || K < 2)
    return proto_fail(err, "springs: stiffening law needs k0, d0, d_max > 0, "
                      "spread in [0, 1), K >= 2");
  /* one shared table (the law at s = 1), per-element scatter as the scale */
  if (springs_alloc(m, 1, K, err)) return -1;
  for (int i = 0; i < K; i++) {
    double d = d_max * i / (K - 1), q = d / d0;
    m->spr_d[i] = d;
    m->spr_F[i] = k0 * d * (1.0 + q * q); /* cubic: Hermite is exact */
    m->spr_k[i] = k0 * (1.0 + 3.0 * q * q);
  }
  uint64_t s = seed;
  for (int e = 0; e < m->M; e++) m->spr_scale[e] = 1.0 + spread * (2.0 * uniform01(&s) - 1.0);
  blk_springs_energies(m);
  return 0;
}

int blk_springs_lognormal(blk_model *m, double sigma, uint64_t seed, proto_err *err) {
  if (m->rigid || !m->spr_scale)
    return proto_fail(err, "springs.lognormal: needs roughness springs (not rigid)");
  if (!(sigma >= 0) || !isfinite(sigma))
    return proto_fail(err, "springs.lognormal = %g: must be >= 0", sigma);
  uint64_t s = seed;
  for (int e = 0; e < m->M; e++) m->spr_scale[e] *= exp(sigma * gauss(&s) - 0.5 * sigma * sigma);
  return 0;
}

int blk_springs_rigid(blk_model *m, proto_err *err) {
  (void)err;
  springs_release(m);
  m->rigid = 1;
  return 0;
}

/* ------------------------------------------------------ cure 2: soften */

typedef struct ranked {
  double F;
  int e;
} ranked;

static int by_force_desc(const void *a, const void *b) {
  const ranked *x = a, *y = b;
  if (x->F != y->F) return x->F < y->F ? 1 : -1;
  return x->e - y->e; /* ties: by element, deterministic */
}

int blk_springs_soften(blk_model *m, int count, double at, double factor,
                       proto_err *err) {
  if (m->rigid || !m->spr_d)
    return proto_fail(err, "soften: needs roughness springs (not rigid)");
  const int exchange = !(factor > 0);
  if (count < 1 || count > (exchange ? m->M / 2 : m->M))
    return proto_fail(err, "soften: count = %d: must be in [1, %d] (%s)", count,
                      exchange ? m->M / 2 : m->M,
                      exchange ? "exchanged for the next count springs" : "the elements");
  if (!(at > 0) || !isfinite(at))
    return proto_fail(err, "soften: at = %g: must be > 0 (m)", at);
  if (!exchange && !(factor <= 1))
    return proto_fail(err, "soften: factor = %g: must be in (0, 1]", factor);
  ranked *r = malloc((size_t)m->M * sizeof *r);
  if (!r) return proto_fail(err, "out of memory");
  for (int e = 0; e < m->M; e++) {
    double k;
    blk_spring_eval(m, e, at, &r[e].F, &k);
    r[e].e = e;
  }
  qsort(r, (size_t)m->M, sizeof *r, by_force_desc);
  for (int i = 0; i < count; i++) {
    const int e = r[i].e;
    if (exchange) { /* seed 002 app. C.2: the stiffest `count` take the next `count` */
      const int f = r[count + i].e;
      m->spr_table[e] = m->spr_table[f];
      m->spr_scale[e] = m->spr_scale[f];
    } else {
      m->spr_scale[e] *= factor;
    }
  }
  free(r);
  return 0;
}

/* ----------------------------------------------------------- checking */

int blk_model_check(const blk_model *m, proto_err *err) {
  if (m->M < 1 || !m->z_road) return proto_fail(err, "model: grid not initialised");
  for (int e = 0; e < m->M; e++)
    if (!isfinite(m->z_road[e]))
      return proto_fail(err, "road: z_road of element %d (i=%d, j=%d) is not finite", e,
                        e % m->nx, e / m->nx);
  if (!isfinite(m->z_free)) return proto_fail(err, "road: z_free is not finite");
  if (springs_check(m, err)) return -1;
  if (!m->g_static) return proto_fail(err, "green: no Green's functions defined");
  const size_t no = (size_t)m->nox * m->noy;
  for (size_t o = 0; o < no; o++)
    if (!isfinite(m->g_static[o]))
      return proto_fail(err, "green: static compliance at offset index %zu is not finite", o);
  const size_t centre = (size_t)(m->ny - 1) * m->nox + (m->nx - 1);
  if (!(m->g_static[centre] > 0))
    return proto_fail(err, "green: static self-compliance must be > 0 (got %g)",
                      m->g_static[centre]);
  if (m->g) {
    for (size_t i = 0; i < (size_t)m->Q * no; i++)
      if (!isfinite(m->g[i]))
        return proto_fail(err, "green: g sample %zu (k=%zu) is not finite", i, i / no);
  } else if (m->g_time) {
    for (int k = 0; k < m->Q; k++)
      if (!isfinite(m->g_time[k]))
        return proto_fail(err, "green: time shape sample %d is not finite", k);
    for (size_t o = 0; o < no; o++)
      if (!isfinite(m->g_space[o]))
        return proto_fail(err, "green: spatial shape at offset index %zu is not finite", o);
  } else if (!m->solver.quasi_static) {
    return proto_fail(err, "green: static-only Green's functions (%s) need "
                      "solver.quasi_static = true", m->green_model);
  }
  if (!(m->release_force > 0)) return proto_fail(err, "adhesion: release force must be > 0");
  if (m->solver.max_iter < 1) return proto_fail(err, "solver: max_iter must be >= 1");
  if (m->solver.cg_max_iter < 1) return proto_fail(err, "solver: cg_max_iter must be >= 1");
  if (!(m->solver.tol > 0)) return proto_fail(err, "solver: tol must be > 0");
  if (!(m->solver.max_force > 0)) return proto_fail(err, "solver: max_force must be > 0");
  if (m->periodic) { /* periodic kernels: K(Δ) = K(Δ − n) along each axis */
    const double *kern[] = {m->g_static, m->g_space};
    for (int t = 0; t < 2; t++) {
      const double *K = kern[t];
      if (!K) continue;
      double kmax = 0, worst = 0;
      for (size_t o = 0; o < no; o++) kmax = fmax(kmax, fabs(K[o]));
      for (int dj = 0; dj < m->noy; dj++)
        for (int di = 0; di < m->nox; di++) {
          const int ri = di >= m->nx ? di - m->nx : di + (di < m->nx - 1 ? m->nx : 0);
          const int rj = dj >= m->ny ? dj - m->ny : dj + (dj < m->ny - 1 ? m->ny : 0);
          if (ri >= 0 && ri < m->nox && ri != di)
            worst = fmax(worst, fabs(K[(size_t)dj * m->nox + di] - K[(size_t)dj * m->nox + ri]));
          if (rj >= 0 && rj < m->noy && rj != dj)
            worst = fmax(worst, fabs(K[(size_t)dj * m->nox + di] - K[(size_t)rj * m->nox + di]));
        }
      if (!(worst <= BLK_PERIODIC_TOL * kmax))
        return proto_fail(err, "grid.periodic: the Green's functions (%s) are not periodic "
                          "over the %d x %d grid (K(d) != K(d - n) by %.2g of the largest); "
                          "periodic grids need green.kind halfspace or synthetic",
                          m->green_model, m->nx, m->ny, kmax > 0 ? worst / kmax : worst);
    }
    if (m->g)
      return proto_fail(err, "grid.periodic: full (file) Green's functions are not periodic; "
                        "use green.kind halfspace or synthetic");
  }
  const blk_method me = m->solver.method;
  if (m->rigid && (me == BLK_NR_PLAIN || me == BLK_NR_LINESEARCH))
    return proto_fail(err, "solver.method: newton/line_search work on spring compressions; "
                      "rigid springs (hard contact) need dual_newton, constrained_cg or auto");
  if ((me == BLK_NR_PLAIN || me == BLK_NR_LINESEARCH || me == BLK_NR_DUAL) &&
      m->M > BLK_DENSE_MAX)
    return proto_fail(err, "solver.method: the dense solvers keep M x M matrices: at most "
                      "%d elements (grid %d x %d = %d); use constrained_cg or auto",
                      BLK_DENSE_MAX, m->nx, m->ny, m->M);
  return 0;
}
