/* test_dem_nodeset.c — the sparse exchange's node set is a superset of what
 * the contact search reaches (dem_server/dem_nodeset.c, PROTOCOL.md "Sparse
 * exchange"). Two copies of one scene step side by side: A gets every node
 * of the coupled surface each coupling step (the dense exchange), B only the
 * nodes proto_reach_nodes picks for the reach box B reported at the end of
 * its last step (what the coupler sends, x_index). Checked at every DEM
 * sub-step: every node that carries a force in A is in B's set; A's and B's
 * nodal forces are the same bits; no grain of B leaves its box. At the end
 * the grains of A and B are the same bits. Not vacuous: the surface rolls
 * into the grains and out again, so some steps carry forces while most nodes
 * stay out of the set. And the guard fires: a box one grain diameter too low
 * lets grains out, which dem_reach_escaped reports.
 * A third copy C takes every node and builds its mesh candidate lists at
 * every sub-step: A and B, which build them only when a moved triangle comes
 * near a grain (dem_mesh_lists_check), give C's forces to the bit, and B,
 * whose left-out nodes jump when they join the set again, found such jumps
 * clear of the grains (the lists kept) at least once.
 *
 * The scene: 6 x 4 x 2 grains of r = 5 mm in contact, no gravity, no walls,
 * and a triangulated rim sector (radius 0.1 m, +-60 deg) sinking, travelling
 * and turning over them (node velocities v_c + w x (x - c)), 4 DEM sub-steps
 * per coupling step. */
#include "dem_test.h"
#include "dem_server/dem_internal.h"

#include <string.h>

#define NA 30 /* nodes around (sector) */
#define NW 5  /* nodes across */
#define NN (NA * NW)
#define NT ((NA - 1) * (NW - 1) * 2)
#define RIM 0.1
#define NSUB 4       /* DEM steps per coupling step */
#define STEPS 400    /* coupling steps */
#define DT_DEM 1e-5  /* s */

typedef struct rig {
  double c[3], v[3], w; /* centre, its velocity, spin about +y */
  double x0[NN * 3];
} rig;

static void surface_nodes(const rig *g, double angle, double *x, double *v) {
  const double ca = cos(angle), sa = sin(angle);
  for (int q = 0; q < NN; q++) {
    const double *p = &g->x0[3 * q];
    double r[3] = {ca * p[0] + sa * p[2], p[1], -sa * p[0] + ca * p[2]};
    for (int d = 0; d < 3; d++) x[3 * q + d] = g->c[d] + r[d];
    v[3 * q + 0] = g->v[0] + g->w * r[2];
    v[3 * q + 1] = g->v[1];
    v[3 * q + 2] = g->v[2] - g->w * r[0];
  }
}

static void build(dem_model *m, dem_state *s, const double *x, const int32_t *tri) {
  char json[16384];
  int len = snprintf(json, sizeof json,
                     "{\"materials\":[{\"density\":2600,\"E\":5e6,\"nu\":0.3,\"restitution\":0.5,"
                     "\"friction\":0.6},{\"density\":1100,\"E\":20e6,\"nu\":0.45,"
                     "\"restitution\":0.5,\"friction\":0.8}],\"surface_material\":1,"
                     "\"gravity\":[0,0,0],\"dt\":%g,\"particles\":[", DT_DEM);
  const double r = 0.005;
  int n = 0;
  for (int i = 0; i < 6; i++)
    for (int j = 0; j < 4; j++)
      for (int k = 0; k < 2; k++)
        len += snprintf(json + len, sizeof json - len,
                        "%s{\"x\":[%.6f,%.6f,%.6f],\"r\":%g,\"material\":0}", n++ ? "," : "",
                        -0.025 + 2 * r * i, -0.015 + 2 * r * j, -r - 2 * r * k, r * (1 - 0.04 * k));
  snprintf(json + len, sizeof json - len, "]}");
  proto_err err = {{0}};
  cJSON *j = cJSON_Parse(json);
  if (!j || dem_model_from_json(m, j, "processes.dem", &err) ||
      dem_model_set_surface(m, NN, x, NT, tri, &err) || dem_state_init(m, s, 0, &err)) {
    fprintf(stderr, "setup: %s\n", err.msg);
    exit(2);
  }
  cJSON_Delete(j);
}

static int row_zero(const double *f) {
  return f[0] == 0 && f[1] == 0 && f[2] == 0 && !signbit(f[0]) && !signbit(f[1]) && !signbit(f[2]);
}

/* The lists check alone: one grain at rest, a plate (2 triangles) coming down
 * on it from 10 mm above its top at 1 m/s, and a far pair of triangles in the
 * same mesh jumping 1 cm every step (a sparse set's stale nodes). The grain
 * has no neighbour to rebuild for: only the check can list the plate before
 * it touches. Against a copy that builds its lists at every step: the same
 * forces to the bit, the far jumps kept the lists, and the plate pushed the
 * grain. Returns the rows that differ. */
static int plate_on_grain(void) {
  const double r = 0.005, h = r + 0.01, far = 1.0;
  double x[8 * 3] = {-0.05, -0.05, h, 0.05, -0.05, h, 0.05, 0.05, h, -0.05, 0.05, h,
                     far, 0, 0, far + 0.01, 0, 0, far + 0.01, 0.01, 0, far, 0.01, 0};
  const int32_t tri[4 * 3] = {0, 1, 2, 0, 2, 3, 4, 5, 6, 4, 6, 7};
  double v[8 * 3] = {0};
  for (int a = 0; a < 4; a++) v[3 * a + 2] = -1.0;
  const char *json = "{\"materials\":[{\"density\":2600,\"E\":5e6,\"nu\":0.3,\"restitution\":0.5,"
                     "\"friction\":0.6}],\"gravity\":[0,0,0],\"dt\":1e-5,\"skin\":0.002,"
                     "\"particles\":[{\"x\":[0,0,0],\"r\":0.005}]}";
  dem_model m[2];
  dem_state s[2];
  proto_err err = {{0}};
  for (int c = 0; c < 2; c++) {
    cJSON *j = cJSON_Parse(json);
    if (!j || dem_model_from_json(&m[c], j, "processes.dem", &err) ||
        dem_model_set_surface(&m[c], 8, x, 4, tri, &err) || dem_state_init(&m[c], &s[c], 0, &err)) {
      fprintf(stderr, "plate setup: %s\n", err.msg);
      exit(2);
    }
    cJSON_Delete(j);
  }
  int differ = 0, touched = 0;
  for (int k = 0; k < 1500; k++) {
    for (int a = 0; a < 4; a++) x[3 * a + 2] = h - 1.0 * 1e-5 * k;
    for (int a = 4; a < 8; a++) x[3 * a + 1] = 0.01 * (k % 7) + (a >= 6 ? 0.01 : 0);
    for (int c = 0; c < 2; c++) dem_mesh_set_nodes(&m[c], &s[c], 0, x, v);
    s[1].work->lists_dirty = 1;
    for (int c = 0; c < 2; c++)
      if (dem_step(&m[c], &s[c], &err)) {
        fprintf(stderr, "plate step %d: %s\n", k, err.msg);
        exit(2);
      }
    differ += memcmp(s[0].mesh_force[0], s[1].mesh_force[0], sizeof(double) * 3 * 8) != 0;
    touched |= s[1].mesh_force[0][2] != 0;
  }
  printf("plate: %lld list builds for node moves, %lld checks with every moved triangle clear; "
         "grain at %.3e m/s\n", (long long)s[0].work->mesh_builds, (long long)s[0].work->mesh_clear, s[0].v[2]);
  CHECK(touched && s[1].v[2] < 0, "the plate pushed the grain (v_z %g m/s)", s[1].v[2]);
  CHECK(s[0].work->mesh_clear > 100 && s[0].work->mesh_builds > 0,
        "the far jumps kept the lists (%lld checks), the plate's approach built them (%lld)",
        (long long)s[0].work->mesh_clear, (long long)s[0].work->mesh_builds);
  CHECK(memcmp(s[0].x, s[1].x, 3 * sizeof(double)) == 0 && memcmp(s[0].v, s[1].v, 3 * sizeof(double)) == 0,
        "the grain ends as the same bits");
  for (int c = 0; c < 2; c++) {
    dem_state_free(&s[c]);
    dem_model_free(&m[c]);
  }
  return differ;
}

int main(void) {
  CHECK(plate_on_grain() == 0, "lists built when a moved triangle comes near a grain give the forces of "
        "lists built at every step, to the bit");
  rig g = {{-0.01, 0.0, RIM + 0.001}, {0.5, 0.0, -0.5}, 5.0, {0}};
  for (int a = 0; a < NA; a++)
    for (int b = 0; b < NW; b++) {
      const double th = (-60.0 + 120.0 * a / (NA - 1)) * M_PI / 180;
      double *p = &g.x0[3 * (a * NW + b)];
      p[0] = RIM * sin(th);
      p[1] = -0.025 + 0.05 * b / (NW - 1);
      p[2] = -RIM * cos(th);
    }
  int32_t tri[NT * 3];
  int nt = 0;
  for (int a = 0; a + 1 < NA; a++)
    for (int b = 0; b + 1 < NW; b++) {
      const int p = a * NW + b, q = p + NW;
      const int32_t t[6] = {p, q, p + 1, q, q + 1, p + 1}; /* outward (down) */
      memcpy(&tri[3 * nt], t, sizeof t);
      nt += 2;
    }
  double x[NN * 3], v[NN * 3], xr[NN * 3], vr[NN * 3], box[6];
  int32_t idx[NN];
  uint8_t mark[NN], seen[NN], live[NT];
  surface_nodes(&g, 0, x, v);
  dem_model ma, mb, mc;
  dem_state A, B, C;
  build(&ma, &A, x, tri);
  build(&mb, &B, x, tri);
  build(&mc, &C, x, tri);
  proto_err err = {{0}};
  const double dt = NSUB * DT_DEM;
  int have_box = 0, missing = 0, differ = 0, escaped = 0, box_differ = 0, differ_c = 0;
  int force_steps = 0, sparse_steps = 0, fewest_out = NN;
  for (int k = 0; k < STEPS; k++) {
    if (k == STEPS / 2) g.v[2] = 0.5; /* back out: contacts open */
    surface_nodes(&g, g.w * A.t, x, v);
    dem_mesh_set_nodes(&ma, &A, 0, x, v);
    dem_mesh_set_nodes(&mc, &C, 0, x, v);
    int64_t kx = NN;
    if (have_box) {
      kx = proto_reach_nodes(x, v, dt, tri, NT, NN, box, mark, idx);
      for (int64_t j = 0; j < kx; j++) {
        memcpy(&xr[3 * j], &x[3 * idx[j]], 3 * sizeof(double));
        memcpy(&vr[3 * j], &v[3 * idx[j]], 3 * sizeof(double));
      }
      dem_mesh_set_nodes_sparse(&mb, &B, 0, kx, idx, xr, vr, seen, live);
    } else {
      dem_mesh_set_nodes(&mb, &B, 0, x, v);
      memset(mark, 1, sizeof mark);
    }
    int forced = 0;
    for (int sub = 0; sub < NSUB; sub++) {
      C.work->lists_dirty = 1; /* its lists built again at this step */
      if (dem_step(&ma, &A, &err) || dem_step(&mb, &B, &err) || dem_step(&mc, &C, &err)) {
        fprintf(stderr, "step %d: %s\n", k, err.msg);
        return 2;
      }
      for (int q = 0; q < NN; q++) {
        const double *fa = &A.mesh_force[0][3 * q], *fb = &B.mesh_force[0][3 * q];
        if (!row_zero(fa)) forced = 1, missing += !mark[q];
        differ += memcmp(fa, fb, 3 * sizeof(double)) != 0;
        differ_c += memcmp(fa, &C.mesh_force[0][3 * q], 3 * sizeof(double)) != 0;
      }
      escaped += have_box && dem_reach_escaped(&B, box) >= 0;
    }
    force_steps += forced;
    if (kx < NN) sparse_steps++;
    if (forced && NN - kx < fewest_out) fewest_out = NN - (int)kx;
    for (int d = 0; d < 3; d++) g.c[d] += g.v[d] * dt;
    dem_reach_box(&mb, &B, dt, box);
    double want[6];
    dem_test_reach_by_hand(&mb, &B, dt, want, NULL, NULL);
    box_differ += memcmp(box, want, sizeof want) != 0;
    have_box = 1;
  }
  printf("%d coupling steps with forces, %d with nodes left out, at least %d of %d nodes left "
         "out while forces acted\n", force_steps, sparse_steps, fewest_out, NN);
  CHECK(missing == 0, "every node that carries a force is in the set sent (%d were not)", missing);
  CHECK(differ == 0, "sparse and dense nodal forces are the same bits (%d rows differ)", differ);
  CHECK(escaped == 0, "no grain left its reach box (%d sub-steps)", escaped);
  CHECK(box_differ == 0, "the reach box is the grains' sphere box grown by skin + 2 v_max dt, "
        "to the bit (%d of %d steps differ)", box_differ, STEPS);
  CHECK(force_steps > 20, "the surface pressed the grains in %d coupling steps", force_steps);
  CHECK(sparse_steps > STEPS / 2, "the set left nodes out in %d of %d steps", sparse_steps, STEPS);
  CHECK(fewest_out > NN / 4, "while carrying force, at least %d of %d nodes were left out",
        fewest_out, NN);
  printf("mesh list builds for node moves: A %lld, B %lld; checks with every moved triangle clear: "
         "A %lld, B %lld\n", (long long)A.work->mesh_builds, (long long)B.work->mesh_builds,
         (long long)A.work->mesh_clear, (long long)B.work->mesh_clear);
  CHECK(differ_c == 0, "lists built only when a moved triangle comes near a grain give the forces of "
        "lists built every sub-step, to the bit (%d rows differ)", differ_c);
  CHECK(B.work->mesh_clear > 0, "the sparse copy kept its lists through moves clear of the grains "
        "(%lld checks)", (long long)B.work->mesh_clear);
  const size_t b3 = sizeof(double) * 3 * (size_t)A.n;
  CHECK(A.n == B.n && memcmp(A.x, B.x, b3) == 0 && memcmp(A.v, B.v, b3) == 0 &&
            memcmp(A.omega, B.omega, b3) == 0,
        "the grains of both end as the same bits");
  /* the guard: a box whose top is a grain diameter too low lets grains out */
  double low[6];
  dem_reach_box(&mb, &B, dt, low);
  low[5] -= 0.01;
  CHECK(dem_reach_escaped(&B, low) >= 0, "a grain outside a box is reported");
  dem_state_free(&A);
  dem_state_free(&B);
  dem_state_free(&C);
  dem_model_free(&ma);
  dem_model_free(&mb);
  dem_model_free(&mc);
  return cosim_test_done("dem_nodeset");
}
