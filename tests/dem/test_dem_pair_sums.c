/* The pair sweep's bookkeeping (dem_force.c): a gas of 1 872 grains (four
 * chunks of slots, so that many pairs cross into a later chunk) in free
 * space, colliding and parting again, with friction and rolling friction.
 *  - Linear and angular momentum stay what they were, to round-off: every
 *    pair's share reaches its partner once, and a pair that opens adds
 *    nothing afterwards (a stale share kept in the partner's reverse slot
 *    would push one grain without the other).
 *  - The same run with the grains' law chosen per pair (two materials, one
 *    grain of the second, whose law equals the first's) and set once per
 *    sweep (one material; or two materials and every grain of the first)
 *    gives the same motion, bit for bit. */
#include "dem_test.h"
#include "dem_server/dem_internal.h"

#define NL 12  /* lattice cells per side (NL x NL x (NL + 1) grains) */
#define RAD 0.005
#define GAP 0.0012 /* between neighbours on the lattice: they meet within a few ms */

static const char *MAT =
    "{\"density\":2600,\"E\":1e7,\"nu\":0.3,\"restitution\":0.5,\"friction\":0.5,\"rolling_friction\":0.2}";

/* kind 0: one material; 1: two, all grains of the first; 2: two, grain 7 of
 * the second (the same law) */
static char *gas_json(int kind) {
  const size_t cap = 400000;
  char *j = malloc(cap);
  if (!j) exit(2);
  int len = snprintf(j, cap, "{\"materials\":[%s%s%s],\"gravity\":[0,0,0],\"orientation\":true,\"particles\":[",
                     MAT, kind ? "," : "", kind ? MAT : "");
  uint64_t rng = 12345;
  int n = 0;
  for (int z = 0; z < NL + 1; z++)
    for (int y = 0; y < NL; y++)
      for (int x = 0; x < NL; x++) {
        double u[6];
        for (int a = 0; a < 6; a++) {
          rng = rng * 6364136223846793005ull + 1442695040888963407ull;
          u[a] = (double)(rng >> 11) / 9007199254740992.0 - 0.5; /* [-0.5, 0.5) */
        }
        const double h = 2 * RAD + GAP;
        len += snprintf(j + len, cap - (size_t)len,
                        "%s{\"x\":[%.9f,%.9f,%.9f],\"v\":[%.6f,%.6f,%.6f],\"r\":%g,\"material\":%d}", n ? "," : "",
                        x * h + 0.2 * GAP * u[0], y * h + 0.2 * GAP * u[1], z * h + 0.2 * GAP * u[2], 0.8 * u[3],
                        0.8 * u[4], 0.8 * u[5], RAD * (1 + 0.05 * u[0]), kind == 2 && n == 7 ? 1 : 0);
        n++;
      }
  snprintf(j + len, cap - (size_t)len, "]}");
  return j;
}

/* Linear and angular momentum about the origin (x × m v + I ω). */
static void momenta(const dem_state *s, double *p, double *l) {
  const struct dem_work *w = s->work;
  for (int a = 0; a < 3; a++) p[a] = l[a] = 0;
  for (int i = 0; i < s->n; i++) {
    const double *x = &s->x[3 * i], *v = &s->v[3 * i], *o = &s->omega[3 * i], m = w->mass[i];
    double c[3];
    dem_cross(x, v, c);
    for (int a = 0; a < 3; a++) {
      p[a] += m * v[a];
      l[a] += m * c[a] + w->inertia[i] * o[a];
    }
  }
}

/* Positions, velocities and spins of a and b (by grain id) equal, bit for
 * bit (the models differ: their state exports' model fingerprints do). */
static int same_motion(const dem_state *a, const dem_state *b) {
  const int n = a->n;
  double *ga = malloc(sizeof(double) * 9 * (size_t)n), *gb = malloc(sizeof(double) * 9 * (size_t)n);
  if (!ga || !gb) exit(2);
  const dem_state *st[2] = {a, b};
  double *g[2] = {ga, gb};
  for (int k = 0; k < 2; k++) {
    dem_gather(st[k], st[k]->x, 3, g[k]);
    dem_gather(st[k], st[k]->v, 3, g[k] + 3 * n);
    dem_gather(st[k], st[k]->omega, 3, g[k] + 6 * n);
  }
  const int same = b->n == n && !memcmp(ga, gb, sizeof(double) * 9 * (size_t)n);
  free(ga);
  free(gb);
  return same;
}

int main(void) {
  dem_model m[3];
  dem_state s[3];
  for (int kind = 0; kind < 3; kind++) {
    char *j = gas_json(kind);
    scene(j, &m[kind], &s[kind]);
    free(j);
  }
  CHECK(s[0].work->grain_law == 0 && s[1].work->grain_law == 0 && s[2].work->grain_law == -1,
        "one grain law: %d %d %d (want 0 0 -1)", s[0].work->grain_law, s[1].work->grain_law, s[2].work->grain_law);
  double p0[3], l0[3], pscale = 0, lscale = 0;
  momenta(&s[0], p0, l0);
  for (int i = 0; i < s[0].n; i++) { /* the sums' own size: Σ m |v|, Σ |x| m |v| */
    const double *v = &s[0].v[3 * i], *x = &s[0].x[3 * i];
    pscale += s[0].work->mass[i] * sqrt(dem_dot(v, v));
    lscale += s[0].work->mass[i] * sqrt(dem_dot(v, v)) * sqrt(dem_dot(x, x));
  }
  int64_t touching = 0, opened = 0, prev = -1;
  double worst_p = 0, worst_l = 0;
  for (int k = 0; k < 1500; k++) {
    for (int kind = 0; kind < 3; kind++) dem_test_steps(&m[kind], &s[kind], 1);
    const int64_t c = s[0].work->pair_contacts;
    if (prev >= 0 && c < prev) opened += prev - c;
    touching = c > touching ? c : touching;
    prev = c;
    double p[3], l[3];
    momenta(&s[0], p, l);
    for (int a = 0; a < 3; a++) {
      worst_p = fmax(worst_p, fabs(p[a] - p0[a]) / pscale);
      worst_l = fmax(worst_l, fabs(l[a] - l0[a]) / lscale);
    }
  }
  printf("%d grains in %d chunks, %.3g s: at most %lld pairs touching, contacts fell by %lld in all\n", s[0].n,
         (s[0].n + DEM_CHUNK - 1) / DEM_CHUNK, s[0].t, (long long)touching, (long long)opened);
  printf("momentum change / sum m|v|: %.3g; angular momentum change / sum |x| m|v|: %.3g\n", worst_p, worst_l);
  CHECK(s[0].n > 3 * DEM_CHUNK, "the gas fills more than three chunks");
  CHECK(touching > 500 && opened > 500, "the grains collide and part (%lld, %lld)", (long long)touching,
        (long long)opened);
  CHECK(worst_p < 1e-12, "linear momentum drifts by %.3g of its scale", worst_p);
  CHECK(worst_l < 1e-12, "angular momentum drifts by %.3g of its scale", worst_l);
  CHECK(same_motion(&s[0], &s[1]), "one material against two with every grain of the first: the motion differs");
  CHECK(same_motion(&s[0], &s[2]), "the law set once against per pair: the motion differs");
  for (int kind = 0; kind < 3; kind++) {
    dem_state_free(&s[kind]);
    dem_model_free(&m[kind]);
  }
  return cosim_test_done("test_dem_pair_sums");
}
