/* Scenario tire_road's physics (coupler/scenario_lugs.c) on a hand-built
 * surface: two lug pads (3 x 3 nodes each, on the outer radius R) and a
 * groove strip below them. The pads are found as two lugs with the areas of
 * their triangles; a face's approach is the road height minus its
 * area-weighted mean height; a block's force spread onto the nodes sums to
 * the force and has its moment about the face's centre (the centre of
 * pressure given); the lug processes take the nearest lugs, keep a lug
 * until it has left the road with no force, and a lug with no process left
 * is an error naming the fix; the road's penalty acts on nodes off the lug
 * faces only. The block grid laid on the faces (coupler/scenario_lugmap.c):
 * cells beyond a face's edge are off it, a face height linear along the face
 * is interpolated exactly (the base is its offset from the mean), a turned
 * face takes the same map, and the cells' forces spread back sum to theirs
 * and have their moment. */
#include <math.h>
#include <string.h>

#include "coupler/coupler.h"
#include "cosim_test.h"

#define R 0.25
#define GROOVE 0.01
#define NPAD 9
#define NN (2 * NPAD + 3)
#define NT (2 * 8 + 4)

static double x0[3 * NN];
static int32_t tri[3 * NT];

/* Pad p at angle theta0 (about y; theta 0 is straight down, z = -R): 3 x 3
 * nodes at angles theta0 + {-a, 0, a} and y in {-w, 0, w}, 8 triangles. */
static void pad(int p, double theta0, int *nt) {
  const double a = 0.02, w = 0.01;
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++) {
      double *q = &x0[3 * (p * NPAD + 3 * i + j)];
      const double th = theta0 + (i - 1) * a;
      q[0] = R * sin(th), q[1] = (j - 1) * w, q[2] = -R * cos(th);
    }
  for (int i = 0; i < 2; i++)
    for (int j = 0; j < 2; j++) {
      const int32_t c = (int32_t)(p * NPAD + 3 * i + j);
      const int32_t t[6] = {c, c + 3, c + 1, c + 1, c + 3, c + 4};
      memcpy(&tri[3 * *nt], t, sizeof t);
      *nt += 2;
    }
}

static void build(void) {
  int nt = 0;
  pad(0, 0.0, &nt);
  pad(1, 0.5, &nt);
  /* a groove strip: 3 nodes GROOVE below pad 0's last row, 4 triangles to it */
  for (int j = 0; j < 3; j++) {
    double *q = &x0[3 * (2 * NPAD + j)];
    const double th = 0.04;
    q[0] = (R - GROOVE) * sin(th), q[1] = (j - 1) * 0.01, q[2] = -(R - GROOVE) * cos(th);
  }
  const int32_t t[12] = {6, 18, 7, 7, 18, 19, 7, 19, 8, 8, 19, 20};
  memcpy(&tri[3 * nt], t, sizeof t);
}

/* The area of pad p's triangles (computed here from their corners). */
static double pad_area(int p) {
  double A = 0;
  for (int t = 8 * p; t < 8 * p + 8; t++) {
    const double *a = &x0[3 * tri[3 * t]], *b = &x0[3 * tri[3 * t + 1]], *c = &x0[3 * tri[3 * t + 2]];
    const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    const double n[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
    A += 0.5 * sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  }
  return A;
}

static void found(void) {
  cpl_lugs L;
  proto_err err = {0};
  OK(cpl_lugs_find(x0, NN, tri, NT, 1e-9, &L, &err));
  CHECK(L.n == 2, "two lugs, got %d", L.n);
  CHECK(fabs(L.outer_radius - R) < 1e-15, "outer radius %g", L.outer_radius);
  for (int j = 0; j < L.n; j++) {
    CHECK(L.start[j + 1] - L.start[j] == NPAD, "lug %d: 9 nodes (%d)", j, L.start[j + 1] - L.start[j]);
    CHECK(fabs(L.area[j] - pad_area(j)) < 1e-15, "lug %d: area %.17g of its triangles %.17g", j,
          L.area[j], pad_area(j));
  }
  CHECK(L.node[L.start[0]] == 0 && L.node[L.start[1]] == NPAD, "lugs numbered by their first node");
  int on = 0;
  for (int i = 0; i < NN; i++) on += L.on_lug[i];
  CHECK(on == 2 * NPAD && !L.on_lug[18], "the groove nodes are on no lug (%d on lugs)", on);
  cpl_lugs_free(&L);
  FAILS_WITH(cpl_lugs_find(x0, 2 * NPAD, tri, 0, 1e-9, &L, &err), "has no lug faces");
}

static void approach_and_spread(void) {
  cpl_lugs L;
  proto_err err = {0};
  OK(cpl_lugs_find(x0, NN, tri, NT, 1e-9, &L, &err));
  double x[3 * NN];
  memcpy(x, x0, sizeof x);
  for (int i = 0; i < NN; i++) x[3 * i + 2] += R + 1e-4; /* the rim 0.1 mm above z = R... */
  double zbar = 0;
  for (int e = L.start[0]; e < L.start[1]; e++) zbar += L.weight[e] * x[3 * L.node[e] + 2];
  zbar /= L.area[0];
  const double road = 2e-4;
  CHECK(fabs(cpl_lug_approach(&L, 0, x, road) - (road - zbar)) < 1e-18,
        "approach = road - the area-weighted mean height");
  CHECK(cpl_lug_approach(&L, 0, x, road) > 0 && cpl_lug_approach(&L, 1, x, road) < -0.01,
        "pad 0 is in the road, pad 1 far above it");
  /* spread: the sum and the moment about the face's centre */
  double cx = 0, cy = 0;
  for (int e = L.start[0]; e < L.start[1]; e++) {
    cx += L.weight[e] / L.area[0] * x[3 * L.node[e]];
    cy += L.weight[e] / L.area[0] * x[3 * L.node[e] + 1];
  }
  const double cops[3][2] = {{0, 0}, {2e-3, -1.5e-3}, {-4e-3, 6e-3}}, F = 123.25;
  for (int c = 0; c < 3; c++) {
    double f[3 * NN] = {0}, sum = 0, mx = 0, my = 0, other = 0;
    cpl_lug_spread(&L, 0, x, F, cops[c], f);
    for (int i = 0; i < NN; i++) {
      sum += f[3 * i + 2];
      mx += f[3 * i + 2] * (x[3 * i] - cx);
      my += f[3 * i + 2] * (x[3 * i + 1] - cy);
      other += fabs(f[3 * i]) + fabs(f[3 * i + 1]) + (L.on_lug[i] && i < NPAD ? 0 : fabs(f[3 * i + 2]));
    }
    CHECK(fabs(sum - F) < 1e-12 * F, "cop %d: the nodal forces sum to F (%.17g)", c, sum);
    CHECK(fabs(mx - F * cops[c][0]) < 1e-12 * F * 1e-2 && fabs(my - F * cops[c][1]) < 1e-12 * F * 1e-2,
          "cop %d: their moment is F x cop (%.3g %.3g vs %.3g %.3g)", c, mx, my, F * cops[c][0],
          F * cops[c][1]);
    CHECK(other == 0, "cop %d: nothing off lug 0's nodes and no tangential force", c);
    if (c == 0) {
      int prop = 1;
      for (int e = L.start[0]; e < L.start[1]; e++)
        prop &= fabs(f[3 * L.node[e] + 2] - F * L.weight[e] / L.area[0]) < 1e-13 * F;
      CHECK(prop, "at the centre the forces go by the nodes' areas");
    }
  }
  /* the road's penalty: the groove nodes pushed below the road, the lug nodes ignored */
  double f[3 * NN] = {0};
  const double k = 1e5, deep = 0.5;
  const double sum = cpl_road_penalty(&L, x, NN, deep, k, f);
  double want = 0;
  for (int i = 2 * NPAD; i < NN; i++) want += k * (deep - x[3 * i + 2]);
  CHECK(fabs(sum - want) < 1e-9 * want && f[3 * 0 + 2] == 0 && f[3 * 20 + 2] > 0,
        "penalty on the groove nodes only (%g, want %g)", sum, want);
  cpl_lugs_free(&L);
}

static void assignment(void) {
  cpl_lug_slots S = {0};
  proto_err err = {0};
  S.n = 2;
  S.lug[0] = S.lug[1] = -1;
  const double engage = 1e-3;
  double d[3] = {-0.01, -0.01, -0.01}, force[2] = {0, 0};
  OK(cpl_lug_assign(&S, 3, d, engage, force, &err));
  CHECK(S.lug[0] == -1 && S.lug[1] == -1 && S.handovers == 0, "no lug near: none taken");
  d[2] = -5e-4;
  OK(cpl_lug_assign(&S, 3, d, engage, force, &err));
  CHECK(S.lug[0] == 2 && S.reset[0] == 1 && S.handovers == 1, "lug 2 within engage: process 0, reset");
  OK(cpl_lug_assign(&S, 3, d, engage, force, &err));
  CHECK(S.lug[0] == 2 && S.reset[0] == 0, "kept, no reset the next step");
  d[0] = 2e-4, d[1] = 3e-4;
  const cpl_lug_slots before = S; /* the run stops at the error: the test goes on from here */
  FAILS_WITH(cpl_lug_assign(&S, 3, d, engage, force, &err), "add processes of role lug");
  S = before;
  d[0] = -0.01;
  OK(cpl_lug_assign(&S, 3, d, engage, force, &err));
  CHECK(S.lug[1] == 1 && S.reset[1] == 1, "lug 1 takes the free process 1");
  d[2] = -0.01, force[0] = 5;
  OK(cpl_lug_assign(&S, 3, d, engage, force, &err));
  CHECK(S.lug[0] == 2, "a lug that has left the road still holding force keeps its process");
  force[0] = 0, d[0] = -2e-4;
  OK(cpl_lug_assign(&S, 3, d, engage, force, &err));
  CHECK(S.lug[0] == 0 && S.reset[0] == 1 && S.handovers == 3,
        "with no force left it is freed, and lug 0 takes it afresh (%d)", S.lug[0]);
}

/* 6 x 4 cells of 2 x 6 mm about the face centre: the pads span u = ±R sin 0.02 =
 * ±4.9998 mm, y = ±10 mm, so the outer columns (u = ±5 mm) lie beyond the edge. */
enum { CX = 6, CY = 4, NC = CX * CY };
static void grid(double *xy) {
  for (int q = 0; q < NC; q++) xy[2 * q] = (q % CX - 2.5) * 2e-3, xy[2 * q + 1] = (q / CX - 1.5) * 6e-3;
}

static void face_map(void) {
  cpl_lugs L;
  proto_err err = {0};
  double xy[2 * NC];
  grid(xy);
  OK(cpl_lugs_find(x0, NN, tri, NT, 1e-9, &L, &err));
  OK(cpl_lugs_map(&L, x0, tri, NT, xy, NC, &err));
  int on = 0, edge = 1;
  for (int q = 0; q < NC; q++) {
    const int inside = fabs(xy[2 * q]) < 4.9e-3;
    on += L.cell_node[3 * q] >= 0;
    edge &= (L.cell_node[3 * q] >= 0) == inside;
  }
  CHECK(on == 16 && edge && fabs(L.covered - 16.0 / NC) < 1e-15,
        "the 16 inner cells on the face, the outer columns off it (%d on, covered %g)", on, L.covered);
  double dw = 0;
  for (int s = 0; s < 3 * NC; s++) /* pad 1 is pad 0 turned by 0.5 rad: the same map */
    dw = fmax(dw, fabs(L.cell_w[3 * NC + s] - L.cell_w[s]) +
                      (L.cell_node[3 * NC + s] - (L.cell_node[s] < 0 ? -1 - NPAD : L.cell_node[s]) != NPAD));
  CHECK(dw < 1e-12, "the turned face takes the same triangles and weights (%.3g)", dw);
  /* pad 0's heights linear in the face's plane: z = z0 + b u + c y (u = x at the bottom) */
  double x[3 * NN], cx = 0;
  memcpy(x, x0, sizeof x);
  for (int e = L.start[0]; e < L.start[1]; e++) cx += L.weight[e] / L.area[0] * x0[3 * L.node[e]];
  const double b = 0.03, c = -0.02, z0 = 1e-3;
  for (int i = 0; i < NPAD; i++) x[3 * i + 2] = z0 + b * (x0[3 * i] - cx) + c * x0[3 * i + 1];
  double base[NC], worst = 0;
  cpl_lug_base(&L, 0, x, base);
  for (int q = 0; q < NC; q++)
    worst = fmax(worst, L.cell_node[3 * q] < 0 ? fabs(base[q] - CPL_LUG_OFF_FACE)
                                               : fabs(base[q] + b * xy[2 * q] + c * xy[2 * q + 1]));
  CHECK(worst < 1e-17, "base = mean height - the face's height under each cell (%.3g m off)", worst);
  /* the cells' forces back: their sum and moment about the face centre */
  double F[NC], f[3 * NN] = {0}, sum = 0, mx = 0, my = 0, want[3] = {0, 0, 0}, other = 0;
  for (int q = 0; q < NC; q++) F[q] = 1 + 0.37 * q;
  const double spread = cpl_lug_spread_cells(&L, 0, F, f);
  for (int q = 0; q < NC; q++)
    if (L.cell_node[3 * q] >= 0)
      want[0] += F[q], want[1] += F[q] * xy[2 * q], want[2] += F[q] * xy[2 * q + 1];
  for (int i = 0; i < NN; i++) {
    sum += f[3 * i + 2], mx += f[3 * i + 2] * (x[3 * i] - cx), my += f[3 * i + 2] * x[3 * i + 1];
    other += fabs(f[3 * i]) + fabs(f[3 * i + 1]) + (i < NPAD ? 0 : fabs(f[3 * i + 2]));
  }
  CHECK(fabs(sum - want[0]) < 1e-13 * want[0] && fabs(spread - want[0]) < 1e-13 * want[0],
        "the nodal forces sum to the cells' on the face (%.17g, %.17g)", sum, want[0]);
  CHECK(fabs(mx - want[1]) < 1e-15 * want[0] && fabs(my - want[2]) < 1e-15 * want[0],
        "and have their moment (%.3g %.3g against %.3g %.3g N m)", mx, my, want[1], want[2]);
  CHECK(other == 0, "nothing off lug 0's nodes and no tangential force");
  cpl_lugs_free(&L);
}

int main(void) {
  build();
  found();
  approach_and_spread();
  face_map();
  assignment();
  return cosim_test_done("test_lugs");
}
