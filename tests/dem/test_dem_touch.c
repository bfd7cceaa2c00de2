/* Where a surface lowered onto grains first touches one (dem_bed_touch_of:
 * what dem_server and liggghts_dem report as bed_top for rim_center "auto").
 * 1. A flat plate (a grid of triangles) over grains of one height: it
 *    touches at their tops, exactly; a taller grain beside the plate does
 *    not count, a taller one under its edge does.
 * 2. A wheel (a cylinder of radius R along y, nodes on the circle) over a
 *    row of grains: with a grain under its lowest line the touch is that
 *    grain's top, exactly; a taller grain off the bottom at dx moves it to
 *    the analytic sphere-cylinder touch (the axis at distance R + r) or
 *    above it (never a grain inside the wheel), and at most to what the
 *    wheel's height over the nearest point of the grain's disk grown by two
 *    grid cells and a facet allows (the documented conservatism); placed
 *    there, no grain is inside the wheel.
 * 3. No grain under the surface: NAN, count 0. */
#include "dem_test.h"
#include "dem_server/dem_internal.h"

#include <math.h>
#include <stdlib.h>

#define R 0.25     /* m: the wheel's radius */
#define WIDTH 0.1  /* m: its width along y */
#define NA 720     /* nodes around */
#define NW 5       /* nodes across */
#define ZC 1.0     /* m: its axis height as placed (parked) */
#define RG 0.004   /* m: the grains' radius */

static double wheel_x[3 * NA * NW];
static int32_t wheel_tri[6 * NA * (NW - 1)];

static int make_wheel(void) {
  for (int a = 0; a < NA; a++)
    for (int b = 0; b < NW; b++) {
      const double th = 2 * M_PI * a / NA; /* a = 0: the lowest line */
      double *p = &wheel_x[3 * (a * NW + b)];
      p[0] = R * sin(th), p[1] = -WIDTH / 2 + WIDTH * b / (NW - 1), p[2] = ZC - R * cos(th);
    }
  int nt = 0;
  for (int a = 0; a < NA; a++)
    for (int b = 0; b + 1 < NW; b++) {
      const int p = a * NW + b, q = ((a + 1) % NA) * NW + b;
      const int32_t t[6] = {p, q, p + 1, q, q + 1, p + 1};
      memcpy(&wheel_tri[3 * nt], t, sizeof t);
      nt += 2;
    }
  return nt;
}

static void plate(void) {
  enum { N = 11 }; /* 11 x 11 nodes over 0.2 x 0.2 m at z = 0.5 */
  double x[3 * N * N];
  int32_t tri[6 * (N - 1) * (N - 1)];
  int nt = 0;
  for (int i = 0; i < N; i++)
    for (int j = 0; j < N; j++) {
      double *p = &x[3 * (i * N + j)];
      p[0] = 0.02 * i, p[1] = 0.02 * j, p[2] = 0.5;
    }
  for (int i = 0; i + 1 < N; i++)
    for (int j = 0; j + 1 < N; j++) {
      const int p = i * N + j;
      const int32_t t[6] = {p, p + N, p + 1, p + N, p + N + 1, p + 1};
      memcpy(&tri[3 * nt], t, sizeof t);
      nt += 2;
    }
  double g[3 * 5], r[5] = {RG, RG, RG, RG, RG};
  const double at[5][3] = {{0.05, 0.05, 0.1}, {0.1, 0.1, 0.1}, {0.15, 0.02, 0.1}, /* under it */
                           {0.3, 0.1, 0.3},                                        /* beside */
                           {0.2 + 0.5 * RG, 0.1, 0.1}};                            /* under its edge */
  memcpy(g, at, sizeof at);
  proto_err err = {{0}};
  double low;
  int count;
  OK(dem_bed_touch_of(g, r, 4, x, N * N, tri, nt, &low, &count, &err));
  CHECK(low == 0.1 + RG && count == 3, "plate over grains of one height: the touch %.17g m (want "
        "their top %.17g), %d grains under it (want 3: the one beside does not count)", low, 0.1 + RG, count);
  g[14] = 0.2; /* the grain under the edge, taller */
  OK(dem_bed_touch_of(g, r, 5, x, N * N, tri, nt, &low, &count, &err));
  CHECK(low == 0.2 + RG && count == 4, "a taller grain under the plate's edge sets the touch: %.17g m "
        "(want %.17g), %d grains", low, 0.2 + RG, count);
}

static void wheel(void) {
  const int nt = make_wheel();
  enum { NG = 41 };
  double g[3 * NG], r[NG];
  for (int i = 0; i < NG; i++) { /* a row along x at y = 0, tops at 0.2 */
    g[3 * i] = -0.2 + 0.01 * i, g[3 * i + 1] = 0, g[3 * i + 2] = 0.2 - RG;
    r[i] = RG;
  }
  proto_err err = {{0}};
  double low;
  int count;
  OK(dem_bed_touch_of(g, r, NG, wheel_x, NA * NW, wheel_tri, nt, &low, &count, &err));
  CHECK(fabs(low - 0.2) < 1e-15 && count == NG, "wheel over grains of one height, one under its lowest line: "
        "the touch %.17g m (want their top 0.2), %d grains (want %d)", low, count, NG);
  /* raise the grain at dx = 0.05 until it binds */
  const int k = 25;
  const double dx = g[3 * k];
  g[3 * k + 2] = 0.2 + 0.012;
  OK(dem_bed_touch_of(g, r, NG, wheel_x, NA * NW, wheel_tri, nt, &low, &count, &err));
  /* exact: lowered until the axis is R + r from the grain's centre */
  const double exact = g[3 * k + 2] + sqrt((R + RG) * (R + RG) - dx * dx) - R;
  /* the bound: the wheel's height over the disk grown by two cells (RG
   * each) and one facet, i.e. its height at |dx| - w above its lowest line */
  const double w = RG + 2 * RG + 2 * M_PI * R / NA, u = fabs(dx) - w;
  const double bound = g[3 * k + 2] + RG - (R - sqrt(R * R - u * u));
  CHECK(exact > 0.2, "setup: the raised grain binds (%g)", exact);
  CHECK(low >= exact - 1e-12 && low <= bound + 1e-12, "a taller grain off the bottom at dx = %g: the "
        "touch %.12g m, between the exact sphere-cylinder touch %.12g and the bound %.12g", dx, low,
        exact, bound);
  /* no grain inside the wheel placed there: every centre at least R + r from the axis */
  const double axis = ZC - (wheel_x[2] - low); /* wheel_x[2]: the lowest node, parked */
  double gap = INFINITY;
  for (int i = 0; i < NG; i++) {
    const double dz = axis - g[3 * i + 2];
    gap = fmin(gap, sqrt(g[3 * i] * g[3 * i] + dz * dz) - R - r[i]);
  }
  CHECK(gap >= -1e-12, "placed there, the wheel's nearest grain is %.3g m away (want >= 0: none "
        "inside it)", gap);
}

static void none(void) {
  const int nt = make_wheel();
  double g[3] = {1.0, 0, 0}, r[1] = {RG}, low = 0;
  int count = -1;
  proto_err err = {{0}};
  OK(dem_bed_touch_of(g, r, 1, wheel_x, NA * NW, wheel_tri, nt, &low, &count, &err));
  CHECK(isnan(low) && count == 0, "no grain under the wheel: %g, count %d (want NAN, 0)", low, count);
}

int main(void) {
  plate();
  wheel();
  none();
  return cosim_test_done("test_dem_touch");
}
