/* blk_model.c — building and checking the block model: grid, road, roughness
 * springs (seed 002 ch. 3.2), Green's functions (ch. 3.3, appendix C.2). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "contact_block/blk.h"
#include "green/green.h"

int blk_model_init(blk_model *m, int nx, int ny, double dx, double dy,
                   proto_err *err) {
  memset(m, 0, sizeof *m);
  if (nx < 1 || ny < 1 || nx > 4096 || ny > 4096)
    return proto_fail(err, "grid: nx, ny must be in [1, 4096] (got %d x %d)", nx, ny);
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
  m->release_force = 0.6; /* N, seed 002 ch. 5.1 default */
  m->solver.method = BLK_NR_PLAIN;
  m->solver.max_iter = 10;      /* appendix C default */
  m->solver.tol = 1e-13;        /* m; the thesis' 1e-15 is below round-off here */
  m->solver.history = BLK_HIST_FFT;
  m->solver.tail_tol = 1e-14;
  m->solver.max_force = 1e6;
  return 0;
}

void blk_model_free(blk_model *m) {
  free(m->z_road);
  free(m->spr_d);
  free(m->spr_F);
  free(m->spr_k);
  free(m->g);
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

/* ----------------------------------------------------------- springs */

static int springs_alloc(blk_model *m, int K, proto_err *err) {
  free(m->spr_d);
  free(m->spr_F);
  free(m->spr_k);
  size_t n = (size_t)m->M * (size_t)K;
  m->spr_d = malloc(n * sizeof(double));
  m->spr_F = malloc(n * sizeof(double));
  m->spr_k = malloc(n * sizeof(double));
  m->n_knots = K;
  if (!m->spr_d || !m->spr_F || !m->spr_k) return proto_fail(err, "out of memory");
  return 0;
}

static int springs_check(const blk_model *m, proto_err *err) {
  const int K = m->n_knots;
  if (K < 2 || !m->spr_d) return proto_fail(err, "springs: none defined (need >= 2 knots)");
  for (int e = 0; e < m->M; e++) {
    const double *d = m->spr_d + (size_t)e * K, *F = m->spr_F + (size_t)e * K,
                 *k = m->spr_k + (size_t)e * K;
    if (d[0] != 0.0 || F[0] != 0.0)
      return proto_fail(err, "springs: element %d: table must start at d = 0, F = 0 "
                        "(got d = %g, F = %g)", e, d[0], F[0]);
    for (int i = 0; i < K; i++) {
      if (!isfinite(d[i]) || !isfinite(F[i]) || !isfinite(k[i]))
        return proto_fail(err, "springs: element %d knot %d: not finite", e, i);
      if (k[i] < 0)
        return proto_fail(err, "springs: element %d knot %d: stiffness k = %g < 0 "
                          "(spring law must be monotone)", e, i, k[i]);
      if (i > 0 && !(d[i] > d[i - 1]))
        return proto_fail(err, "springs: element %d knot %d: compression d not "
                          "increasing (%g after %g)", e, i, d[i], d[i - 1]);
      if (i > 0 && F[i] < F[i - 1])
        return proto_fail(err, "springs: element %d knot %d: force decreases (%g after "
                          "%g): non-monotone spring table", e, i, F[i], F[i - 1]);
    }
  }
  return 0;
}

int blk_springs_table(blk_model *m, int K, const double *d, const double *F,
                      const double *k, proto_err *err) {
  if (K < 2) return proto_fail(err, "springs: need >= 2 knots (got %d)", K);
  if (springs_alloc(m, K, err)) return -1;
  size_t n = (size_t)m->M * (size_t)K * sizeof(double);
  memcpy(m->spr_d, d, n);
  memcpy(m->spr_F, F, n);
  memcpy(m->spr_k, k, n);
  return springs_check(m, err);
}

int blk_springs_linear(blk_model *m, const double *k, int per_element,
                       proto_err *err) {
  if (springs_alloc(m, 2, err)) return -1;
  for (int e = 0; e < m->M; e++) {
    double ke = per_element ? k[e] : k[0];
    if (!(ke > 0) || !isfinite(ke))
      return proto_fail(err, "springs: linear stiffness of element %d must be > 0 "
                        "(got %g)", e, ke);
    const double d1 = 1e-3; /* any knot; linear extension beyond */
    m->spr_d[2 * e] = 0;
    m->spr_d[2 * e + 1] = d1;
    m->spr_F[2 * e] = 0;
    m->spr_F[2 * e + 1] = ke * d1;
    m->spr_k[2 * e] = ke;
    m->spr_k[2 * e + 1] = ke;
  }
  return 0;
}

int blk_springs_stiffening(blk_model *m, double k0, double d0, double spread,
                           uint64_t seed, double d_max, int K, proto_err *err) {
  if (!(k0 > 0) || !(d0 > 0) || !(d_max > 0) || !(spread >= 0 && spread < 1) || K < 2)
    return proto_fail(err, "springs: stiffening law needs k0, d0, d_max > 0, "
                      "spread in [0, 1), K >= 2");
  if (springs_alloc(m, K, err)) return -1;
  uint64_t s = seed;
  for (int e = 0; e < m->M; e++) {
    double sc = 1.0 + spread * (2.0 * uniform01(&s) - 1.0);
    for (int i = 0; i < K; i++) {
      double d = d_max * i / (K - 1), q = d / d0;
      size_t at = (size_t)e * K + i;
      m->spr_d[at] = d;
      m->spr_F[at] = sc * k0 * d * (1.0 + q * q); /* cubic: Hermite is exact */
      m->spr_k[at] = sc * k0 * (1.0 + 3.0 * q * q);
    }
  }
  return 0;
}

void blk_spring_eval(const blk_model *m, int e, double d, double *F, double *k) {
  const int K = m->n_knots;
  const double *kd = m->spr_d + (size_t)e * K, *kF = m->spr_F + (size_t)e * K,
               *kk = m->spr_k + (size_t)e * K;
  if (d <= 0) {
    *F = 0;
    *k = 0;
    return;
  }
  if (d >= kd[K - 1]) { /* linear extension with the last slope */
    *F = kF[K - 1] + kk[K - 1] * (d - kd[K - 1]);
    *k = kk[K - 1];
    return;
  }
  /* the knot interval kd[lo] <= d < kd[lo+1] (unique: knots increase):
   * guessed as for equally spaced knots (the synthetic tables), checked,
   * else bisection */
  int lo = (int)(d / kd[K - 1] * (K - 1)), hi;
  if (lo > K - 2) lo = K - 2;
  if (lo + 1 < K - 1 && kd[lo + 1] <= d) lo++;
  else if (lo > 0 && kd[lo] > d) lo--;
  if (kd[lo] <= d && d < kd[lo + 1]) {
    hi = lo + 1;
  } else {
    lo = 0;
    hi = K - 1;
    while (hi - lo > 1) {
      int mid = (lo + hi) / 2;
      if (kd[mid] <= d) lo = mid; else hi = mid;
    }
  }
  /* cubic Hermite on [d_lo, d_hi] (green/FORMATS.md) */
  const double h = kd[hi] - kd[lo], t = (d - kd[lo]) / h, t2 = t * t, t3 = t2 * t;
  const double h00 = 2 * t3 - 3 * t2 + 1, h10 = t3 - 2 * t2 + t,
               h01 = -2 * t3 + 3 * t2, h11 = t3 - t2;
  *F = h00 * kF[lo] + h10 * h * kk[lo] + h01 * kF[hi] + h11 * h * kk[hi];
  const double d00 = (6 * t2 - 6 * t) / h, d10 = 3 * t2 - 4 * t + 1,
               d01 = (-6 * t2 + 6 * t) / h, d11 = 3 * t2 - 2 * t;
  *k = d00 * kF[lo] + d10 * kk[lo] + d01 * kF[hi] + d11 * kk[hi];
  if (*k < 0) *k = 0; /* monotone data: only round-off can make it negative */
}

/* ---------------------------------------------------- Green's functions */

static int green_alloc(blk_model *m, int Q, int with_g, proto_err *err) {
  free(m->g);
  free(m->g_static);
  size_t no = (size_t)m->nox * (size_t)m->noy;
  m->g = with_g ? malloc((size_t)Q * no * sizeof(double)) : NULL;
  m->g_static = malloc(no * sizeof(double));
  m->Q = Q;
  if ((with_g && !m->g) || !m->g_static) return proto_fail(err, "out of memory");
  return 0;
}

static void green_sum_static(blk_model *m) {
  const size_t no = (size_t)m->nox * m->noy;
  const double dt = 1.0 / m->rate;
  for (size_t o = 0; o < no; o++) {
    double s = 0;
    for (int k = 0; k < m->Q; k++) s += m->g[(size_t)k * no + o];
    m->g_static[o] = s * dt;
  }
}

int blk_green_set(blk_model *m, int Q, double rate, int noy, int nox,
                  const double *g, const double *g_static, const char *sampling,
                  const char *model_name, proto_err *err) {
  if (noy != m->noy || nox != m->nox)
    return proto_fail(err, "green: offset grid must be [2ny-1, 2nx-1] = [%d, %d] "
                      "for a %d x %d block (got [%d, %d])", m->noy, m->nox, m->nx,
                      m->ny, noy, nox);
  if (Q < 1) return proto_fail(err, "green: need >= 1 sample (got %d)", Q);
  if (g && !(rate > 0 && isfinite(rate)))
    return proto_fail(err, "green: rate must be > 0 for a dynamic g (got %g)", rate);
  if (green_alloc(m, Q, g != NULL, err)) return -1;
  const size_t no = (size_t)nox * noy;
  if (g) { /* green/FORMATS.md: static = Δt Σ_k g(k) for a dynamic file */
    double smax = 0, worst = 0;
    size_t at = 0;
    for (size_t o = 0; o < no; o++) smax = fmax(smax, fabs(g_static[o]));
    for (size_t o = 0; o < no; o++) {
      double sum = 0;
      for (int k = 0; k < Q; k++) sum += g[(size_t)k * no + o];
      const double dev = fabs(sum / rate - g_static[o]);
      if (!(dev <= worst)) { /* also catches NaN */
        worst = dev;
        at = o;
      }
    }
    if (!(worst <= 1e-6 * smax))
      return proto_fail(err, "green: static compliance differs from dt * sum_k g(k) by %.3g "
                        "(relative to the largest, limit 1e-6) at offset (dj=%d, di=%d)",
                        smax > 0 ? worst / smax : worst, (int)(at / nox) - (m->ny - 1),
                        (int)(at % nox) - (m->nx - 1));
  }
  m->rate = g ? rate : 0.0;
  if (g) memcpy(m->g, g, (size_t)Q * no * sizeof(double));
  memcpy(m->g_static, g_static, no * sizeof(double));
  snprintf(m->sampling, sizeof m->sampling, "%s", sampling ? sampling : "zoh");
  snprintf(m->green_model, sizeof m->green_model, "%s", model_name ? model_name : "");
  return 0;
}

int blk_green_halfspace(blk_model *m, double E, double nu, proto_err *err) {
  if (!(E > 0) || !(nu >= 0 && nu < 0.5))
    return proto_fail(err, "green: half-space needs E > 0 and nu in [0, 0.5)");
  if (green_alloc(m, 1, 0, err)) return -1;
  for (int dj = 0; dj < m->noy; dj++)
    for (int di = 0; di < m->nox; di++)
      m->g_static[dj * m->nox + di] =
          grn_love_compliance((di - (m->nx - 1)) * m->dx, (dj - (m->ny - 1)) * m->dy,
                              0.5 * m->dx, 0.5 * m->dy, E, nu);
  m->rate = 0;
  snprintf(m->sampling, sizeof m->sampling, "static");
  snprintf(m->green_model, sizeof m->green_model, "halfspace-love");
  return 0;
}

/* Unit-area time shape of blk_synth: impulse response h and step response s. */
static double synth_h(const blk_synth *p, double t) {
  const double w = 2 * M_PI * p->f_mode, wd = w * sqrt(1 - p->zeta * p->zeta);
  return p->beta * exp(-t / p->tau_fast) / p->tau_fast +
         (1 - p->beta) * w * w / wd * exp(-p->zeta * w * t) * sin(wd * t);
}
static double synth_s(const blk_synth *p, double t) {
  const double w = 2 * M_PI * p->f_mode, wd = w * sqrt(1 - p->zeta * p->zeta);
  return p->beta * (1 - exp(-t / p->tau_fast)) +
         (1 - p->beta) * (1 - exp(-p->zeta * w * t) *
                                  (cos(wd * t) + p->zeta * w / wd * sin(wd * t)));
}

int blk_green_synthetic(blk_model *m, const blk_synth *p, proto_err *err) {
  if (!(p->rate > 0) || p->Q < 1 || !(p->f_mode > 0) || !(p->zeta > 0 && p->zeta < 1) ||
      !(p->beta >= 0 && p->beta <= 1) || !(p->tau_fast > 0))
    return proto_fail(err, "green: synthetic needs rate, Q, f_mode, tau_fast > 0, "
                      "zeta in (0, 1), beta in [0, 1]");
  if (blk_green_halfspace(m, p->E, p->nu, err)) return -1;
  const size_t no = (size_t)m->nox * m->noy;
  double *S = malloc(no * sizeof(double));
  if (!S) return proto_fail(err, "out of memory");
  memcpy(S, m->g_static, no * sizeof(double));
  if (green_alloc(m, p->Q, 1, err)) {
    free(S);
    return -1;
  }
  m->rate = p->rate;
  const double dt = 1.0 / p->rate;
  for (int k = 0; k < p->Q; k++) {
    double hk = p->point_sampling ? synth_h(p, k * dt)
                                  : (synth_s(p, (k + 1) * dt) - synth_s(p, k * dt)) / dt;
    for (size_t o = 0; o < no; o++) m->g[(size_t)k * no + o] = S[o] * hk;
  }
  free(S);
  green_sum_static(m);
  snprintf(m->sampling, sizeof m->sampling, "%s", p->point_sampling ? "point" : "zoh");
  snprintf(m->green_model, sizeof m->green_model, "synthetic-mode");
  return 0;
}

int blk_green_refine(blk_model *m, int factor, proto_err *err) {
  if (factor < 1) return proto_fail(err, "green: refinement factor must be >= 1");
  if (factor == 1) return 0;
  if (!m->g) return proto_fail(err, "green: a static-only model cannot be refined");
  const size_t no = (size_t)m->nox * m->noy;
  const int Q = m->Q, Qn = (Q - 1) * factor + 1;
  double *gn = malloc((size_t)Qn * no * sizeof(double));
  if (!gn) return proto_fail(err, "out of memory");
  const int point = strcmp(m->sampling, "point") == 0;
  const double dt = 1.0 / m->rate, dtn = dt / factor;
  for (size_t o = 0; o < no; o++) {
    if (point) { /* appendix C.2: linear interpolation between samples */
      for (int j = 0; j < Qn; j++) {
        int k = j / factor, r = j % factor;
        double a = (double)r / factor;
        double g0 = m->g[(size_t)k * no + o];
        double g1 = k + 1 < Q ? m->g[(size_t)(k + 1) * no + o] : 0.0;
        gn[(size_t)j * no + o] = (1 - a) * g0 + a * g1;
      }
    } else { /* ZOH: cubic Hermite on the step response S(t_k) = Δt Σ_{i<k} g_i,
                slopes from the neighbouring sample averages, then increments */
      double S0 = 0, prevS = 0;
      for (int k = 0; k < Q; k++) {
        double gk = m->g[(size_t)k * no + o];
        double gprev = k > 0 ? m->g[(size_t)(k - 1) * no + o] : gk;
        double gnext = k + 1 < Q ? m->g[(size_t)(k + 1) * no + o] : 0.0;
        double S1 = S0 + gk * dt;
        double m0 = 0.5 * (gprev + gk), m1 = 0.5 * (gk + gnext);
        for (int r = 0; r < factor && k * factor + r < Qn; r++) {
          double t = (double)(r + 1) / factor, t2 = t * t, t3 = t2 * t;
          double St = (2 * t3 - 3 * t2 + 1) * S0 + (t3 - 2 * t2 + t) * dt * m0 +
                      (-2 * t3 + 3 * t2) * S1 + (t3 - t2) * dt * m1;
          gn[(size_t)(k * factor + r) * no + o] = (St - prevS) / dtn;
          prevS = St;
        }
        S0 = S1;
      }
    }
  }
  free(m->g);
  m->g = gn;
  m->Q = Qn;
  m->rate *= factor;
  green_sum_static(m);
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
  } else if (!m->solver.quasi_static) {
    return proto_fail(err, "green: static-only Green's functions (%s) need "
                      "solver.quasi_static = true", m->green_model);
  }
  if (!(m->release_force > 0)) return proto_fail(err, "adhesion: release force must be > 0");
  if (m->solver.max_iter < 1) return proto_fail(err, "solver: max_iter must be >= 1");
  if (!(m->solver.tol > 0)) return proto_fail(err, "solver: tol must be > 0");
  if (!(m->solver.max_force > 0)) return proto_fail(err, "solver: max_force must be > 0");
  return 0;
}

/* ∫_0^d F(s) ds of element e (the spring's stored energy W, d ≥ 0): exact
 * integral of the cubic Hermite pieces, linear beyond the last knot. */
double blk_spring_energy(const blk_model *m, int e, double d) {
  const int K = m->n_knots;
  const double *kd = m->spr_d + (size_t)e * K, *kF = m->spr_F + (size_t)e * K,
               *kk = m->spr_k + (size_t)e * K;
  if (d <= 0) return 0;
  double W = 0;
  for (int i = 0; i + 1 < K; i++) {
    const double h = kd[i + 1] - kd[i];
    const double t = d >= kd[i + 1] ? 1.0 : (d - kd[i]) / h;
    const double t2 = t * t, t3 = t2 * t, t4 = t3 * t;
    W += h * ((t4 / 2 - t3 + t) * kF[i] + (t4 / 4 - 2 * t3 / 3 + t2 / 2) * h * kk[i] +
              (-t4 / 2 + t3) * kF[i + 1] + (t4 / 4 - t3 / 3) * h * kk[i + 1]);
    if (d <= kd[i + 1]) return W;
  }
  const double s = d - kd[K - 1];
  return W + kF[K - 1] * s + 0.5 * kk[K - 1] * s * s;
}

/* Inverse spring law: the compression d ≥ 0 at which element e carries F ≥ 0
 * (safeguarded Newton on the monotone Hermite piece). */
double blk_spring_inverse(const blk_model *m, int e, double F) {
  const int K = m->n_knots;
  const double *kd = m->spr_d + (size_t)e * K, *kF = m->spr_F + (size_t)e * K,
               *kk = m->spr_k + (size_t)e * K;
  if (F <= 0) return 0;
  if (F >= kF[K - 1]) {
    if (kk[K - 1] > 0) return kd[K - 1] + (F - kF[K - 1]) / kk[K - 1];
    return kd[K - 1];
  }
  int lo = 0, hi = K - 1; /* kF[lo] <= F < kF[hi] */
  while (hi - lo > 1) {
    int mid = (lo + hi) / 2;
    if (kF[mid] <= F) lo = mid; else hi = mid;
  }
  double a = kd[lo], b = kd[hi], x = a + (b - a) * (F - kF[lo]) / (kF[hi] - kF[lo]);
  for (int it = 0; it < 100; it++) {
    double Fx, kx;
    blk_spring_eval(m, e, x, &Fx, &kx);
    const double r = Fx - F;
    if (r > 0) b = x; else a = x;
    if (fabs(r) <= 1e-15 * F || b - a <= 1e-16 * b) break;
    double xn = kx > 0 ? x - r / kx : 0.5 * (a + b);
    if (!(xn > a && xn < b)) xn = 0.5 * (a + b);
    x = xn;
  }
  return x;
}
