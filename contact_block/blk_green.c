/* blk_green.c — the block's Green's functions (seed 002 ch. 3.3, appendix
 * C.2): files of cosim_green, the Love half-space (static), the labelled
 * synthetic layer (separable: g(k; o) = g_time[k] · g_space[o]), rate
 * refinement, and the plain double-sum reference of eq. 4–5. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "contact_block/blk.h"
#include "green/green.h"

static void green_release(blk_model *m) {
  free(m->g);
  free(m->g_time);
  free(m->g_space);
  free(m->g_static);
  m->g = m->g_time = m->g_space = m->g_static = NULL;
}

/* Storage for Q samples: full (with_g), separable (sep) or static only. */
static int green_alloc(blk_model *m, int Q, int with_g, int sep, proto_err *err) {
  green_release(m);
  const size_t no = (size_t)m->nox * (size_t)m->noy;
  m->g = with_g ? malloc((size_t)Q * no * sizeof(double)) : NULL;
  m->g_time = sep ? malloc((size_t)Q * sizeof(double)) : NULL;
  m->g_space = sep ? malloc(no * sizeof(double)) : NULL;
  m->g_static = malloc(no * sizeof(double));
  m->Q = Q;
  if ((with_g && !m->g) || (sep && (!m->g_time || !m->g_space)) || !m->g_static)
    return proto_fail(err, "out of memory");
  return 0;
}

double blk_green_at(const blk_model *m, int k, size_t o) {
  if (m->g) return m->g[(size_t)k * m->nox * m->noy + o];
  if (m->g_time) return m->g_time[k] * m->g_space[o];
  return 0.0;
}

static void green_sum_static(blk_model *m) {
  const size_t no = (size_t)m->nox * m->noy;
  const double dt = 1.0 / m->rate;
  if (m->g_time) { /* Δt Σ_k T_k S(o) */
    double s = 0;
    for (int k = 0; k < m->Q; k++) s += m->g_time[k];
    for (size_t o = 0; o < no; o++) m->g_static[o] = s * dt * m->g_space[o];
    return;
  }
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
  if (green_alloc(m, Q, g != NULL, 0, err)) return -1;
  m->rate = g ? rate : 0.0;
  if (g) memcpy(m->g, g, (size_t)Q * no * sizeof(double));
  memcpy(m->g_static, g_static, no * sizeof(double));
  snprintf(m->sampling, sizeof m->sampling, "%s", sampling ? sampling : "zoh");
  snprintf(m->green_model, sizeof m->green_model, "%s", model_name ? model_name : "");
  return 0;
}

/* Love static compliance per offset into C [noy][nox] (periodic grid: the
 * periodic half-space of green/periodic.c). */
static int love_kernel(const blk_model *m, double E, double nu, double *C, proto_err *err) {
  const grn_grid gg = {m->nx, m->ny, m->dx, m->dy};
  if (m->periodic) return grn_static_love_periodic(&gg, E, nu, C, err);
  grn_static_love(&gg, E, nu, C);
  return 0;
}

int blk_green_halfspace(blk_model *m, double E, double nu, proto_err *err) {
  if (!(E > 0) || !(nu >= 0 && nu < 0.5))
    return proto_fail(err, "green: half-space needs E > 0 and nu in [0, 0.5)");
  if (green_alloc(m, 1, 0, 0, err) || love_kernel(m, E, nu, m->g_static, err)) return -1;
  m->rate = 0;
  snprintf(m->sampling, sizeof m->sampling, "static");
  snprintf(m->green_model, sizeof m->green_model, "%s",
           m->periodic ? "halfspace-love-periodic" : "halfspace-love");
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
  if (!(p->E > 0) || !(p->nu >= 0 && p->nu < 0.5))
    return proto_fail(err, "green: half-space needs E > 0 and nu in [0, 0.5)");
  if (green_alloc(m, p->Q, 0, 1, err) || love_kernel(m, p->E, p->nu, m->g_space, err))
    return -1;
  m->rate = p->rate;
  const double dt = 1.0 / p->rate;
  for (int k = 0; k < p->Q; k++)
    m->g_time[k] = p->point_sampling ? synth_h(p, k * dt)
                                     : (synth_s(p, (k + 1) * dt) - synth_s(p, k * dt)) / dt;
  green_sum_static(m);
  snprintf(m->sampling, sizeof m->sampling, "%s", p->point_sampling ? "point" : "zoh");
  snprintf(m->green_model, sizeof m->green_model, "synthetic-mode");
  return 0;
}

int blk_green_materialize(blk_model *m, proto_err *err) {
  if (!m->g_time) return 0; /* full or static: nothing to do */
  const size_t no = (size_t)m->nox * m->noy;
  double *g = malloc((size_t)m->Q * no * sizeof(double));
  if (!g) return proto_fail(err, "out of memory");
  for (int k = 0; k < m->Q; k++)
    for (size_t o = 0; o < no; o++) g[(size_t)k * no + o] = m->g_time[k] * m->g_space[o];
  free(m->g_time);
  free(m->g_space);
  m->g_time = m->g_space = NULL;
  m->g = g;
  return 0;
}

int blk_green_refine(blk_model *m, int factor, proto_err *err) {
  if (factor < 1) return proto_fail(err, "green: refinement factor must be >= 1");
  if (factor == 1) return 0;
  if (!m->g && !m->g_time)
    return proto_fail(err, "green: a static-only model cannot be refined");
  if (blk_green_materialize(m, err)) return -1;
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

void blk_layer_displacement_ref(const blk_model *m, const double *F_hist,
                                int64_t n_rows, double *d_el) {
  const int M = m->M, nx = m->nx;
  memset(d_el, 0, (size_t)M * sizeof(double));
  const int dynamic = (m->g || m->g_time) && !m->solver.quasi_static;
  const int Q = dynamic ? m->Q : 1;
  const double dt = dynamic ? 1.0 / m->rate : 1.0;
  for (int k = 0; k < Q && k < n_rows; k++) {
    const double *Fk = F_hist + (size_t)(n_rows - 1 - k) * M;
    for (int e = 0; e < M; e++) {
      const int ei = e % nx, ej = e / nx;
      double s = 0;
      for (int p = 0; p < M; p++) {
        const size_t o = (size_t)(ej - p / nx + m->ny - 1) * m->nox + (ei - p % nx + nx - 1);
        s += (dynamic ? blk_green_at(m, k, o) : m->g_static[o]) * Fk[p];
      }
      d_el[e] += s * dt;
    }
  }
}
