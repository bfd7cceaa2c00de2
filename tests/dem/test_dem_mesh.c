/* Sphere–triangle contact (seed 000 §4.3–4.4): closest-point classification by
 * ζ (eq. 35); a grain sliding and rolling across a flat plane made of
 * triangles — straight over edges and through vertices shared by six
 * triangles — feels exactly the force of a plane wall (no bump, one force per
 * grain); the reaction on the nodes (eq. 42) is minus the force on the grain;
 * a grain on a groove's floor that also touches the convex edge of the step
 * beside it feels both contacts (two Hertz forces), a grain only over the
 * floor one. */
#include "dem_test.h"
#include "dem_server/dem_internal.h"
#include <string.h>

static const double R = 5e-3;

static int classify_count(const double *z) {
  int c = 0;
  for (int k = 0; k < 3; k++) c += z[k] > 1e-12;
  return c;
}

static void test_closest(void) {
  const double a[3] = {0, 0, 0}, b[3] = {1, 0, 0}, c[3] = {0, 1, 0};
  double q[3], z[3];
  const double p_face[3] = {0.2, 0.3, 0.5}, p_edge[3] = {0.5, -0.4, 0.2}, p_vert[3] = {-1, -1, 0.3},
               p_hyp[3] = {1, 1, -0.2};
  dem_closest_on_triangle(p_face, a, b, c, q, z);
  CHECK(classify_count(z) == 3 && fabs(q[0] - 0.2) < 1e-15 && fabs(q[1] - 0.3) < 1e-15 && q[2] == 0,
        "face case: q = (%g %g %g)", q[0], q[1], q[2]);
  CHECK(fabs(z[0] - 0.5) < 1e-15 && fabs(z[1] - 0.2) < 1e-15 && fabs(z[2] - 0.3) < 1e-15,
        "face case ζ = (%g %g %g)", z[0], z[1], z[2]);
  dem_closest_on_triangle(p_edge, a, b, c, q, z);
  CHECK(classify_count(z) == 2 && z[2] == 0 && fabs(q[0] - 0.5) < 1e-15 && q[1] == 0,
        "edge case: ζ = (%g %g %g)", z[0], z[1], z[2]);
  dem_closest_on_triangle(p_vert, a, b, c, q, z);
  CHECK(classify_count(z) == 1 && z[0] == 1, "vertex case: ζ = (%g %g %g)", z[0], z[1], z[2]);
  dem_closest_on_triangle(p_hyp, a, b, c, q, z);
  CHECK(classify_count(z) == 2 && z[0] == 0 && fabs(q[0] - 0.5) < 1e-15, "hypotenuse case");
}

/* A 10 x 10 grid of 1 cm squares split by their diagonal into 200 triangles
 * (vertices where six triangles meet), or the plane z = 0. */
static void make_scene_belt(int mesh, const double *x0, const double *v0, double belt, dem_model *m,
                            dem_state *s);
static void make_scene(int mesh, const double *x0, const double *v0, dem_model *m, dem_state *s) {
  make_scene_belt(mesh, x0, v0, 0.0, m, s);
}

static void make_scene_belt(int mesh, const double *x0, const double *v0, double belt, dem_model *m,
                            dem_state *s) {
  static char json[200000];
  int len = snprintf(json, sizeof json,
      "{\"materials\":[{\"density\":2600,\"E\":1e7,\"nu\":0.3,\"restitution\":0.5,\"friction\":0.3}],"
      "\"gravity\":[0,0,-9.81],\"dt_fraction\":0.05,\"walls\":[");
  if (mesh) {
    const int n = 10;
    const double h = 0.01, lo = -0.05;
    len += snprintf(json + len, sizeof json - len, "{\"type\":\"mesh\",\"nodes\":[");
    for (int j = 0; j <= n; j++)
      for (int i = 0; i <= n; i++)
        len += snprintf(json + len, sizeof json - len, "%s[%.17g,%.17g,0]", i + j ? "," : "",
                        lo + i * h, lo + j * h);
    len += snprintf(json + len, sizeof json - len, "],\"triangles\":[");
    for (int j = 0; j < n; j++)
      for (int i = 0; i < n; i++) {
        int a = j * (n + 1) + i, b = a + 1, c = a + n + 1, d = c + 1;
        len += snprintf(json + len, sizeof json - len, "%s[%d,%d,%d],[%d,%d,%d]", i + j ? "," : "",
                        a, b, d, a, d, c);
      }
    len += snprintf(json + len, sizeof json - len, "],\"velocity\":[%.17g,0,0]}", belt);
  } else {
    len += snprintf(json + len, sizeof json - len,
                    "{\"type\":\"plane\",\"point\":[0,0,0],\"normal\":[0,0,1]}");
  }
  snprintf(json + len, sizeof json - len,
           "],\"particles\":[{\"x\":[%.17g,%.17g,%.17g],\"v\":[%.17g,%.17g,0],\"r\":%g}]}", x0[0],
           x0[1], x0[2], v0[0], v0[1], R);
  scene(json, m, s);
}

/* Runs the same grain over the mesh and over the plane; compares per step. */
static void compare_paths(const char *name, const double *x0, const double *v0, int steps) {
  dem_model mm, mp;
  dem_state sm, sp;
  proto_err err;
  make_scene(1, x0, v0, &mm, &sm);
  make_scene(0, x0, v0, &mp, &sp);
  double worst_f = 0, worst_react = 0, worst_x = 0;
  int64_t contacts_max = 0, contact_steps = 0;
  for (int k = 0; k < steps; k++) {
    if (dem_step(&mm, &sm, &err) || dem_step(&mp, &sp, &err)) { fprintf(stderr, "%s\n", err.msg); exit(1); }
    double fm[3], fp[3], nod[3] = {0, 0, 0};
    for (int a = 0; a < 3; a++) {
      fm[a] = sm.force[a]; /* contact force (gravity is not in force) */
      fp[a] = sp.force[a];
    }
    double scale = sqrt(dem_dot(fp, fp));
    if (scale > 0) {
      contact_steps++;
      double d[3] = {fm[0] - fp[0], fm[1] - fp[1], fm[2] - fp[2]};
      double e = sqrt(dem_dot(d, d)) / scale;
      if (e > worst_f) worst_f = e;
      for (int q = 0; q < mm.meshes[0].n_nodes; q++)
        for (int a = 0; a < 3; a++) nod[a] += sm.mesh_force[0][3 * q + a];
      double r[3] = {nod[0] + fm[0], nod[1] + fm[1], nod[2] + fm[2]};
      e = sqrt(dem_dot(r, r)) / scale;
      if (e > worst_react) worst_react = e;
    }
    double dx[3] = {sm.x[0] - sp.x[0], sm.x[1] - sp.x[1], sm.x[2] - sp.x[2]};
    if (sqrt(dem_dot(dx, dx)) > worst_x) worst_x = sqrt(dem_dot(dx, dx));
    if (sm.contacts > contacts_max) contacts_max = sm.contacts;
  }
  printf("%s: %d steps, end at (%.4f, %.4f), v = %.3g, |v - omega x r| = %.3g\n", name, steps,
         sm.x[0], sm.x[1], sqrt(sm.v[0] * sm.v[0] + sm.v[1] * sm.v[1]),
         hypot(sm.v[0] - R * sm.omega[1], sm.v[1] + R * sm.omega[0]));
  printf("  max |F_mesh - F_plane| / |F_plane| = %.3g, max |sum nodal + F| / |F| = %.3g, "
         "max |x_mesh - x_plane| = %.3g m, max contacts = %lld\n",
         worst_f, worst_react, worst_x, (long long)contacts_max);
  CHECK(contact_steps == steps, "%s: grain lost contact", name);
  CHECK(worst_f <= 1e-9, "%s: mesh force differs from the plane's by %.3g", name, worst_f);
  CHECK(worst_react <= 1e-12, "%s: nodal reaction off by %.3g", name, worst_react);
  CHECK(contacts_max == 1, "%s: %lld contacts for one grain", name, (long long)contacts_max);
  /* the mesh wall's total force is minus the contact force on the grain */
  double fw[3], fm[3];
  for (int a = 0; a < 3; a++) { fw[a] = sm.wall_force[a]; fm[a] = sm.force[a]; }
  CHECK(fabs(fw[2] + fm[2]) <= 1e-12 * fabs(fm[2]), "%s: wall_force %g vs %g", name, fw[2], fm[2]);
  dem_state_free(&sm); dem_state_free(&sp);
  dem_model_free(&mm); dem_model_free(&mp);
}

/* A grain dropped at rest on a moving triangulated belt (rigid mesh with a
 * velocity: nodes move; the contact candidates and the BVH are rebuilt when
 * the nodes have moved skin/2): friction drags it until it rolls,
 * v = U / (1 + r_c²/(2/5 r²)) (2/7 U for r_c = r). */
static void test_belt(double z0) {
  const double U = 0.2, x0[3] = {0, 0, z0}, v0[2] = {0, 0};
  dem_model m;
  dem_state s;
  proto_err err;
  make_scene_belt(1, x0, v0, U, &m, &s);
  if (dem_advance(&m, &s, 0.1, &err)) { fprintf(stderr, "%s\n", err.msg); exit(1); }
  const double rc = R - 0.5 * (R - z0); /* contact point in the middle of the overlap */
  CHECK_REL("belt: final grain speed U/(1 + r_c^2/(0.4 r^2))",
            s.v[0], U / (1 + rc * rc / (0.4 * R * R)), 1e-4);
  CHECK_REL("belt: rolling on the belt, v - omega r_c = U", s.v[0] - s.omega[1] * rc, U, 1e-4);
  /* the BVH followed the belt: its root box was refitted at the last list
   * rebuild, at most skin/2 behind the nodes */
  const dem_bvh *b = &s.work->bvh[0];
  const double lag = 0.5 * m.skin + 1e-12;
  CHECK(fabs(b->lo[0] - (-0.05 + U * s.t)) <= lag && fabs(b->hi[0] - (0.05 + U * s.t)) <= lag,
        "BVH root not refitted: [%g, %g] at t = %g", b->lo[0], b->hi[0], s.t);
  CHECK(s.work->ml_start[1] - s.work->ml_start[0] >= 1, "no contact candidate for the rolling grain");
  /* a deformation that doubles the boxes' area triggers a rebuild at the next
   * step; every leaf box still holds its triangle */
  double *x = malloc(sizeof(double) * 3 * m.meshes[0].n_nodes), *v = calloc(3 * m.meshes[0].n_nodes, sizeof(double));
  for (int q = 0; q < m.meshes[0].n_nodes; q++) {
    x[3 * q] = 4 * s.mesh_x[0][3 * q];
    x[3 * q + 1] = 4 * s.mesh_x[0][3 * q + 1];
    x[3 * q + 2] = 0.01 * sin(100 * s.mesh_x[0][3 * q]);
  }
  double before = b->area_built;
  dem_mesh_set_nodes(&m, &s, 0, x, v);
  if (dem_step(&m, &s, &err)) { fprintf(stderr, "%s\n", err.msg); exit(1); }
  CHECK(b->area_built > 2 * before, "BVH not rebuilt after a 4x stretch (%g -> %g)", before, b->area_built);
  int bad = 0;
  for (int nd = 0; nd < b->n_nodes; nd++) {
    if (b->left[nd] >= 0) continue;
    const int32_t *t = &m.meshes[0].tri[3 * (~b->left[nd])];
    for (int a = 0; a < 3; a++)
      for (int d = 0; d < 3; d++)
        bad += x[3 * t[a] + d] < b->lo[3 * nd + d] || x[3 * t[a] + d] > b->hi[3 * nd + d];
  }
  CHECK(bad == 0, "%d node coordinates outside their leaf boxes", bad);
  free(x);
  free(v);
  dem_state_free(&s);
  dem_model_free(&m);
}

/* A step in x, extruded along y: floor z = 0 for x in [-2, 0] cm, a wall x = 0
 * up to z = H, the top z = H for x in [0, 2] cm; 1 cm cells, two triangles
 * each, so the wall's triangles share nodes with the floor's. A grain at rest
 * on the floor near the wall, its centre above H: it touches the floor's face
 * and the step's convex top edge. The static force is the sum of the two
 * Hertz forces, 4/3 E* sqrt(r) δ^1.5 along each normal (floor: +z; edge: from
 * the edge to the centre), written out here, not taken from dem_hertz. */
static void step_scene(const double *p, dem_model *m, dem_state *s) {
  static char json[20000];
  const double H = 0.003, px[6] = {-0.02, -0.01, 0, 0, 0.01, 0.02}, pz[6] = {0, 0, 0, H, H, H};
  int len = snprintf(json, sizeof json,
      "{\"materials\":[{\"density\":2600,\"E\":1e7,\"nu\":0.3,\"restitution\":0.5,\"friction\":0.3}],"
      "\"gravity\":[0,0,0],\"walls\":[{\"type\":\"mesh\",\"nodes\":[");
  for (int j = 0; j < 5; j++)
    for (int i = 0; i < 6; i++)
      len += snprintf(json + len, sizeof json - len, "%s[%.17g,%.17g,%.17g]", i + j ? "," : "", px[i],
                      -0.02 + 0.01 * j, pz[i]);
  len += snprintf(json + len, sizeof json - len, "],\"triangles\":[");
  for (int j = 0; j < 4; j++)
    for (int i = 0; i < 5; i++) {
      int a = 6 * j + i, b = a + 1, c = a + 6, d = c + 1;
      len += snprintf(json + len, sizeof json - len, "%s[%d,%d,%d],[%d,%d,%d]", i + j ? "," : "", a, b, d,
                      a, d, c);
    }
  snprintf(json + len, sizeof json - len,
           "]}],\"particles\":[{\"x\":[%.17g,%.17g,%.17g],\"v\":[0,0,0],\"r\":%g}]}", p[0], p[1], p[2], R);
  scene(json, m, s);
}

/* Static Hertz force of a grain of radius R on a wall of its material (E 1e7, ν 0.3). */
static double hertz(double delta) {
  const double estar = 1e7 / (2 * (1 - 0.09));
  return 4.0 / 3.0 * estar * sqrt(R) * pow(delta, 1.5);
}

static void test_groove_edge(void) {
  const double H = 0.003;
  struct { const char *name; double x, z; int contacts; } cases[] = {
    {"floor and the step's convex edge", -0.0046, 0.0048, 2},
    {"floor only (edge out of reach)", -0.0060, 0.0048, 1},
    {"convex edge only (above the floor)", -0.0038, 0.0058, 1},
  };
  for (int c = 0; c < 3; c++) {
    const double p[3] = {cases[c].x, 0.0033, cases[c].z};
    dem_model m;
    dem_state s;
    step_scene(p, &m, &s);
    double want[3] = {0, 0, 0};
    const double df = R - p[2]; /* floor */
    if (df > 0) want[2] += hertz(df);
    const double ex = p[0], ez = p[2] - H, de = R - hypot(ex, ez); /* edge (0, y, H) */
    if (de > 0) {
      const double fe = hertz(de) / hypot(ex, ez);
      want[0] += fe * ex;
      want[2] += fe * ez;
    }
    const double *f = s.force, scale = hypot(want[0], want[2]);
    const double e = sqrt((f[0] - want[0]) * (f[0] - want[0]) + f[1] * f[1] + (f[2] - want[2]) * (f[2] - want[2]));
    printf("step: %s: F = (%.6g, %.3g, %.6g) N, Hertz sum (%.6g, 0, %.6g), %lld contacts\n", cases[c].name, f[0],
           f[1], f[2], want[0], want[2], (long long)s.contacts);
    CHECK(e <= 1e-9 * scale, "step, %s: force off the two Hertz forces by %.3g of them", cases[c].name, e / scale);
    CHECK(s.contacts == cases[c].contacts, "step, %s: %lld contacts, want %d", cases[c].name,
          (long long)s.contacts, cases[c].contacts);
    dem_state_free(&s);
    dem_model_free(&m);
  }
}

int main(void) {
  test_closest();
  test_groove_edge();
  /* resting overlap so the grain starts in contact */
  const double mass = 2600 * 4.0 / 3.0 * M_PI * R * R * R, estar = 1e7 / (2 * (1 - 0.09));
  const double z0 = R - pow(3 * mass * 9.81 / (4 * estar * sqrt(R)), 2.0 / 3.0);
  /* along the diagonal edges, through vertices shared by six triangles; slides then rolls */
  const double xa[3] = {-0.04, -0.04, z0}, va[2] = {0.4, 0.4};
  compare_paths("diagonal (edges + vertices)", xa, va, 7000);
  /* an oblique line crossing edges at arbitrary points */
  const double xb[3] = {-0.045, -0.0213, z0}, vb[2] = {0.5, 0.185};
  compare_paths("oblique (edge crossings)", xb, vb, 7000);
  /* resting exactly on a vertex shared by six triangles */
  const double xc[3] = {0.0, 0.0, z0}, vc[2] = {0, 0};
  compare_paths("resting on a vertex", xc, vc, 2000);
  test_belt(z0);
  return cosim_test_done("test_dem_mesh");
}
