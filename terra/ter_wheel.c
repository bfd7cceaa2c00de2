/* ter_wheel.c — rigid driven wheel on soil (Bekker 1969, Wong & Reece
 * 1967, Janosi & Hanamoto 1961).
 *
 * Angles from the downward vertical through the axle, positive forwards;
 * entry theta_1 = acos(1 - z/r), exit theta_2 = 0 (no rebound).
 *   normal stress (Wong & Reece 1967, front branch theta_m <= theta <= theta_1)
 *     sigma = (k_c/b + k_phi) r^n (cos theta - cos theta_1)^n
 *   rear branch: theta in [0, theta_m] mapped linearly onto [theta_1, theta_m]
 *     of the front one, so sigma is continuous at theta_m and 0 at both ends;
 *   shear displacement (a rim point slips at r w [1 - (1 - s) cos theta]
 *   relative to the soil, d theta/dt = -w):
 *     j = r [(theta_1 - theta) - (1 - s)(sin theta_1 - sin theta)]
 *   shear (Janosi & Hanamoto 1961), sign kept for j < 0:
 *     tau = (c + sigma tan phi) sign(j) (1 - exp(-|j|/K))
 *   force balance (§4):
 *     W = r b Int (sigma cos + tau sin),  F_t = r b Int tau cos,
 *     R = r b Int sigma sin,  T = r^2 b Int tau,  DP = F_t - R.
 */
#include "terra/terra.h"

#include <math.h>
#include <string.h>

#define TER_GL_POINTS 16        /* Gauss–Legendre points per branch of the rim integrals */
#define TER_MAX_GL 64
#define TER_Z_MAX_FRACTION 0.9  /* sinkage bracket (0, 0.9 r] */
#define TER_Z_TOL 1e-10         /* bisection tolerance, fraction of r */
#define TER_C1_DEFAULT 0.43     /* theta_m = (c1 + c2 s) theta_1 (Wong & Reece 1967) */
#define TER_C2_DEFAULT 0.32

void ter_soil_defaults(ter_soil *p) {
  memset(p, 0, sizeof *p);
  p->c1 = TER_C1_DEFAULT;
  p->c2 = TER_C2_DEFAULT;
}

int ter_soil_check(const ter_soil *p, const char *path, proto_err *err) {
  if (!(p->n > 0 && p->n < 5)) return proto_fail(err, "%s.n: must be in (0, 5), got %g", path, p->n);
  if (!isfinite(p->k_c))
    return proto_fail(err, "%s.k_c: must be finite, got %g", path, p->k_c);
  if (!isfinite(p->k_phi)) return proto_fail(err, "%s.k_phi: must be finite, got %g", path, p->k_phi);
  if (!(p->c >= 0) || !isfinite(p->c)) return proto_fail(err, "%s.c: must be >= 0 Pa, got %g", path, p->c);
  if (!(p->phi >= 0 && p->phi < 0.5 * M_PI))
    return proto_fail(err, "%s.phi_deg: must be in [0, 90), got %g", path, p->phi * 180 / M_PI);
  if (!(p->K > 0) || !isfinite(p->K)) return proto_fail(err, "%s.K: must be > 0 m, got %g", path, p->K);
  if (!(p->c1 >= 0 && p->c1 <= 1) || !(p->c2 >= 0 && p->c1 + p->c2 <= 1))
    return proto_fail(err, "%s.c1, c2: need 0 <= c1, 0 <= c2, c1 + c2 <= 1, got %g, %g", path, p->c1,
                      p->c2);
  return 0;
}

int ter_soil_read(const cJSON *obj, const char *path, ter_soil *p, proto_err *err) {
  proto_cfg c;
  ter_soil_defaults(p);
  double phi_deg = 0;
  if (proto_cfg_open(&c, obj, path, err) ||
      proto_cfg_num(&c, "n", PROTO_REQUIRED, 1e-3, 5, &p->n) ||
      proto_cfg_num(&c, "k_c", PROTO_REQUIRED, -1e12, 1e12, &p->k_c) ||
      proto_cfg_num(&c, "k_phi", PROTO_REQUIRED, -1e15, 1e15, &p->k_phi) ||
      proto_cfg_num(&c, "c", PROTO_REQUIRED, 0, 1e9, &p->c) ||
      proto_cfg_num_below(&c, "phi_deg", PROTO_REQUIRED, 0, 90, &phi_deg) ||
      proto_cfg_num(&c, "K", PROTO_REQUIRED, 1e-9, 10, &p->K) ||
      proto_cfg_num(&c, "c1", PROTO_OPTIONAL, 0, 1, &p->c1) ||
      proto_cfg_num(&c, "c2", PROTO_OPTIONAL, 0, 1, &p->c2) || proto_cfg_end(&c))
    return -1;
  p->phi = phi_deg * M_PI / 180;
  return ter_soil_check(p, path, err);
}

int ter_soil_write(cJSON *obj, const ter_soil *p) {
  const char *keys[] = {"n", "k_c", "k_phi", "c", "phi_deg", "K", "c1", "c2"};
  const double vals[] = {p->n, p->k_c, p->k_phi, p->c, p->phi * 180 / M_PI, p->K, p->c1, p->c2};
  for (int i = 0; i < 8; i++)
    if (!cJSON_AddNumberToObject(obj, keys[i], vals[i])) return -1;
  return 0;
}

/* Newton on the Legendre recurrence from Tricomi's initial guesses
 * (Press et al., Numerical Recipes, 3rd ed., §4.6.1 gauleg). */
void ter_gauss_legendre(int n, double *x, double *wt) {
  for (int i = 0; i < (n + 1) / 2; i++) {
    double t = cos(M_PI * (i + 0.75) / (n + 0.5)), dp = 1;
    for (int it = 0; it < 100; it++) {
      double p0 = 1, p1 = 0;
      for (int k = 1; k <= n; k++) { /* P_k = ((2k-1) t P_{k-1} - (k-1) P_{k-2}) / k */
        double p2 = p1;
        p1 = p0;
        p0 = ((2.0 * k - 1) * t * p1 - (k - 1.0) * p2) / k;
      }
      dp = n * (t * p0 - p1) / (t * t - 1);
      double dt = p0 / dp;
      t -= dt;
      if (fabs(dt) < 1e-15) break;
    }
    x[i] = -t;
    x[n - 1 - i] = t;
    wt[i] = wt[n - 1 - i] = 2 / ((1 - t * t) * dp * dp);
  }
}

typedef struct rim {
  double r, b, n, keq, c, tanphi, K, s, th1, thm;
} rim;

static double rim_sigma(const rim *g, double th) {
  double tm = th >= g->thm ? th : g->th1 - th * (g->th1 - g->thm) / g->thm; /* rear map, theta_2 = 0 */
  double d = cos(tm) - cos(g->th1);
  return d > 0 ? g->keq * pow(g->r * d, g->n) : 0; /* guard: round-off below 0 */
}

static double rim_tau(const rim *g, double th, double sigma) {
  double j = g->r * ((g->th1 - th) - (1 - g->s) * (sin(g->th1) - sin(th)));
  double m = 1 - exp(-fabs(j) / g->K);
  return (g->c + sigma * g->tanphi) * (j < 0 ? -m : m);
}

/* accumulates the integrands at theta with weight w: W, Ft, R, T */
static void rim_add(const rim *g, double th, double w, double acc[4]) {
  double sg = rim_sigma(g, th), tu = rim_tau(g, th, sg), ct = cos(th), st = sin(th);
  acc[0] += w * (sg * ct + tu * st);
  acc[1] += w * tu * ct;
  acc[2] += w * sg * st;
  acc[3] += w * tu;
}

void ter_wheel_forces(const ter_wheel *w, const ter_soil *p, double z, double s, int n_mid,
                      ter_forces *out) {
  rim g = {.r = w->r, .b = w->b, .n = p->n, .keq = p->k_c / w->b + p->k_phi, .c = p->c,
           .tanphi = tan(p->phi), .K = p->K, .s = s};
  g.th1 = acos(1 - z / w->r);
  g.thm = (p->c1 + p->c2 * s) * g.th1;
  double acc[4] = {0, 0, 0, 0};
  if (n_mid > 0) {
    const double h = g.th1 / n_mid;
    for (int i = 0; i < n_mid; i++) rim_add(&g, (i + 0.5) * h, h, acc);
  } else {
    double x[TER_GL_POINTS], wt[TER_GL_POINTS];
    ter_gauss_legendre(TER_GL_POINTS, x, wt);
    const double lo[2] = {0, g.thm}, hi[2] = {g.thm, g.th1};
    for (int br = 0; br < 2; br++) {
      double half = 0.5 * (hi[br] - lo[br]), mid = 0.5 * (hi[br] + lo[br]);
      if (!(half > 0)) continue; /* theta_m = 0: no rear branch */
      for (int i = 0; i < TER_GL_POINTS; i++) rim_add(&g, mid + half * x[i], half * wt[i], acc);
    }
  }
  const double rb = w->r * w->b;
  out->z = z;
  out->s = s;
  out->theta1 = g.th1;
  out->thetam = g.thm;
  out->W = rb * acc[0];
  out->Ft = rb * acc[1];
  out->R = rb * acc[2];
  out->DP = out->Ft - out->R;
  out->T = rb * w->r * acc[3];
  out->eff = out->T != 0 ? out->DP * w->r * (1 - s) / out->T : 0;
}

int ter_solve(const ter_wheel *w, const ter_soil *p, double W, double s, ter_forces *out,
              proto_err *err) {
  if (!(w->r > 0 && w->b > 0)) return proto_fail(err, "wheel: radius %g and width %g must be > 0", w->r, w->b);
  if (!(s >= 0 && s < 1))
    return proto_fail(err, "slip %g: the driven-wheel model needs 0 <= s < 1 (braking is another model)", s);
  if (!(W > 0)) return proto_fail(err, "load %g N: must be > 0", W);
  if (ter_soil_check(p, "soil", err)) return -1;
  if (!(p->k_c / w->b + p->k_phi > 0))
    return proto_fail(err, "soil: k_c/b + k_phi = %g at b = %g m must be > 0", p->k_c / w->b + p->k_phi, w->b);
  double lo = 0, hi = TER_Z_MAX_FRACTION * w->r;
  ter_forces f;
  ter_wheel_forces(w, p, hi, s, 0, &f);
  if (f.W < W)
    return proto_fail(err, "no equilibrium (immobilised): at slip %g the wheel carries only %.4g N at "
                      "sinkage 0.9 r = %.4g m, load %.4g N", s, f.W, hi, W);
  while (hi - lo > TER_Z_TOL * w->r) {
    double mid = 0.5 * (lo + hi);
    ter_wheel_forces(w, p, mid, s, 0, &f);
    if (f.W < W) lo = mid;
    else hi = mid;
  }
  ter_wheel_forces(w, p, 0.5 * (lo + hi), s, 0, out);
  return 0;
}

double ter_bekker_z0(const ter_wheel *w, const ter_soil *p, double W) {
  double n = p->n;
  return pow(3 * W / ((3 - n) * (p->k_c + w->b * p->k_phi) * sqrt(2 * w->r)), 2 / (2 * n + 1));
}

double ter_compaction_resistance(const ter_wheel *w, const ter_soil *p, double z) {
  return w->b * (p->k_c / w->b + p->k_phi) * pow(z, p->n + 1) / (p->n + 1);
}
