/* dem_state_export/import: a settling bed in a box, ploughed by a rigid
 * moving plate (mesh wall) and pressed by a coupled mesh whose nodes are set
 * every coupling step, with sliding contacts: N steps straight == N/2, export,
 * import into a fresh state (also one with another thread count), N/2 —
 * bitwise. A state of another model, and damaged arrays, are refused with a
 * message naming the array. A state saved with sleep off continues with sleep
 * on (every grain awake, as in a run whose grains never slept: bitwise the
 * run without sleep while none falls asleep); not the other way. A state in
 * which no grain touches a mesh continues under other meshes (a coupled
 * surface of 4 x 4 squares held above the bed, continued under 8 x 8: bitwise
 * the run under its own); a state with mesh contacts is refused by them. */
#include "dem_test.h"
#include "dem_server/dem_internal.h"
#include <string.h>

static const char *JSON =
    "{\"materials\":[{\"density\":2600,\"E\":5e6,\"nu\":0.3,\"restitution\":0.5,\"friction\":0.6}],"
    "\"threads\":%d,\"dt\":5e-5,"
    "\"walls\":[{\"type\":\"box\",\"lo\":[0,0,0],\"hi\":[0.1414213562,0.1414213562,1],\"open_top\":true},"
    /* a vertical plate in x = 0 ploughing along +x */
    "{\"type\":\"mesh\",\"nodes\":[[0,0.01,0.015],[0,0.13,0.015],[0,0.13,0.12],[0,0.01,0.12]],"
    "\"triangles\":[[0,1,2],[0,2,3]],\"velocity\":[0.4,0,0]}],"
    "\"particles\":{\"generate\":\"bed\",\"scale\":0.02,\"seed\":%d}%s}";

/* The coupled "foot": a 4 x 4 grid of squares, 6 cm wide, coming down. */
#define FOOT_N 4
#define FOOT_NODES ((FOOT_N + 1) * (FOOT_N + 1))
static const double FOOT_Z0 = 0.07, FOOT_VZ = -0.15, FOOT_VX = 0.1;
static const int COUPLING = 10; /* DEM steps per coupling step */

static void foot(double t, double *x, double *v) {
  for (int j = 0; j <= FOOT_N; j++)
    for (int i = 0; i <= FOOT_N; i++) {
      double *p = &x[3 * (j * (FOOT_N + 1) + i)], *u = &v[3 * (j * (FOOT_N + 1) + i)];
      /* a slightly bent sheet: edge and vertex contacts too */
      p[0] = 0.04 + 0.015 * i + FOOT_VX * t;
      p[1] = 0.04 + 0.015 * j;
      p[2] = FOOT_Z0 + FOOT_VZ * t + 0.002 * ((i + j) % 2);
      u[0] = FOOT_VX; u[1] = 0; u[2] = FOOT_VZ;
    }
}

/* extra: more top-level keys (",\"sleep\":{...}") or "" */
static void make_with(int threads, int seed, const char *extra, dem_model *m, dem_state *s) {
  char json[2048];
  snprintf(json, sizeof json, JSON, threads, seed, extra);
  proto_err err = {{0}};
  cJSON *j = cJSON_Parse(json);
  int32_t tri[6 * FOOT_N * FOOT_N];
  for (int b = 0; b < FOOT_N; b++)
    for (int a = 0; a < FOOT_N; a++) {
      int32_t *t = &tri[6 * (b * FOOT_N + a)], n0 = b * (FOOT_N + 1) + a;
      t[0] = n0; t[1] = n0 + 1; t[2] = n0 + FOOT_N + 2;
      t[3] = n0; t[4] = n0 + FOOT_N + 2; t[5] = n0 + FOOT_N + 1;
    }
  double x[3 * FOOT_NODES], v[3 * FOOT_NODES];
  foot(0, x, v);
  if (!j || dem_model_from_json(m, j, "processes.dem", &err) ||
      dem_model_set_surface(m, FOOT_NODES, x, 2 * FOOT_N * FOOT_N, tri, &err) || dem_state_init(m, s, 0, &err)) {
    fprintf(stderr, "setup: %s\n", err.msg);
    exit(2);
  }
  cJSON_Delete(j);
}

static void make(int threads, int seed, dem_model *m, dem_state *s) { make_with(threads, seed, "", m, s); }

/* Steps k0..k1−1; the coupled nodes are set at each coupling step. */
static void run(const dem_model *m, dem_state *s, int k0, int k1) {
  proto_err err;
  double x[3 * FOOT_NODES], v[3 * FOOT_NODES];
  for (int k = k0; k < k1; k++) {
    if (k % COUPLING == 0) {
      foot(k * s->dt, x, v);
      dem_mesh_set_nodes(m, s, m->n_meshes - 1, x, v);
    }
    if (dem_step(m, s, &err)) { fprintf(stderr, "step %d: %s\n", k, err.msg); exit(1); }
  }
}

/* Grain–grain contacts at the Coulomb limit (|k_t s| ≥ 0.9 μ k_n δ: sliding
 * or about to), plane and mesh contacts holding a spring. */
static void count_contacts(const dem_model *m, const dem_state *s, int *slide, int *plane, int *mesh) {
  const struct dem_work *w = s->work;
  const dem_pair_law *l = &m->law[0][0];
  *slide = *plane = *mesh = 0;
  for (int i = 0; i < s->n; i++)
    for (int k = w->nl_start[i]; k < w->nl_start[i + 1]; k++) {
      const int j = w->nl_j[k];
      double d[3] = {s->x[3 * i] - s->x[3 * j], s->x[3 * i + 1] - s->x[3 * j + 1], s->x[3 * i + 2] - s->x[3 * j + 2]};
      const double delta = s->radius[i] + s->radius[j] - sqrt(dem_dot(d, d));
      if (delta <= 0) continue;
      const double rs = s->radius[i] * s->radius[j] / (s->radius[i] + s->radius[j]);
      const double kn = 4.0 / 3.0 * l->Estar * sqrt(rs * delta), kt = 8 * l->Gstar * sqrt(rs * delta);
      const double *sh = &w->nl_shear[3 * k];
      *slide += kt * sqrt(dem_dot(sh, sh)) >= 0.9 * l->mu * kn * delta;
    }
  for (size_t k = 0; k < (size_t)m->n_planes * s->n * 3; k++) *plane += w->wall_shear[k] != 0;
  for (size_t k = 0; k < (size_t)s->n * DEM_MESH_SLOTS; k++) *mesh += w->mc_key[k] != 0;
}

/* A deep copy of the exported arrays (as a checkpoint file would hold them). */
static void copy_msg(const proto_msg *in, proto_msg *out, void **bufs) {
  proto_msg_reset(out, "state", "state", 0, 0);
  for (int a = 0; a < in->narrays; a++) {
    const proto_array *x = &in->arrays[a];
    bufs[a] = malloc(x->nbytes + 1);
    memcpy(bufs[a], x->data, x->nbytes);
    proto_msg_add(out, x->name, x->dtype, x->ndim, x->shape, bufs[a]);
  }
}

static void expect_refused(const dem_model *m, dem_state *s, const proto_msg *msg, const char *what,
                           const char *want) {
  proto_err err = {{0}};
  int rc = dem_state_import(m, s, msg, &err);
  printf("%-36s -> %s\n", what, rc ? err.msg : "(accepted)");
  CHECK(rc != 0, "%s: accepted", what);
  CHECK(rc == 0 || strstr(err.msg, want), "%s: message lacks '%s'", what, want);
}

static proto_array *find(proto_msg *m, const char *name) {
  for (int a = 0; a < m->narrays; a++)
    if (!strcmp(m->arrays[a].name, name)) return &m->arrays[a];
  fprintf(stderr, "no array %s\n", name);
  exit(2);
}

/* x, v, omega of every grain in model order into out [9 n] (slot order
 * differs between states). */
static void gather_xvw(const dem_state *s, double *out) {
  dem_gather(s, s->x, 3, out);
  dem_gather(s, s->v, 3, out + 3 * (size_t)s->n);
  dem_gather(s, s->omega, 3, out + 6 * (size_t)s->n);
}

/* Without the plate (plough: true for the plate), the coupled surface a flat
 * sheet of n x n squares at z (above the bed: out of reach; low: on it). */
static const char *JSON_NO_PLATE =
    "{\"materials\":[{\"density\":2600,\"E\":5e6,\"nu\":0.3,\"restitution\":0.5,\"friction\":0.6}],"
    "\"threads\":1,\"dt\":5e-5,"
    "\"walls\":[{\"type\":\"box\",\"lo\":[0,0,0],\"hi\":[0.1414213562,0.1414213562,1],\"open_top\":true}%s],"
    "\"particles\":{\"generate\":\"bed\",\"scale\":0.02,\"seed\":7}}";
static const char *PLATE =
    ",{\"type\":\"mesh\",\"nodes\":[[0,0.01,0.015],[0,0.13,0.015],[0,0.13,0.12],[0,0.01,0.12]],"
    "\"triangles\":[[0,1,2],[0,2,3]],\"velocity\":[0.4,0,0]}";
static void make_sheet(int plate, int n, double z, dem_model *m, dem_state *s) {
  char json[2048];
  snprintf(json, sizeof json, JSON_NO_PLATE, plate ? PLATE : "");
  proto_err err = {{0}};
  cJSON *j = cJSON_Parse(json);
  const int nodes = (n + 1) * (n + 1);
  int32_t *tri = malloc(sizeof(int32_t) * 6 * (size_t)(n * n));
  double *x = malloc(sizeof(double) * 3 * (size_t)nodes);
  for (int b = 0; b <= n; b++)
    for (int a = 0; a <= n; a++) {
      double *p = &x[3 * (b * (n + 1) + a)];
      p[0] = 0.04 + 0.06 * a / n;
      p[1] = 0.04 + 0.06 * b / n;
      p[2] = z;
    }
  for (int b = 0; b < n; b++)
    for (int a = 0; a < n; a++) {
      int32_t *t = &tri[6 * (b * n + a)], n0 = b * (n + 1) + a;
      t[0] = n0; t[1] = n0 + 1; t[2] = n0 + n + 2;
      t[3] = n0; t[4] = n0 + n + 2; t[5] = n0 + n + 1;
    }
  if (!j || dem_model_from_json(m, j, "processes.dem", &err) ||
      dem_model_set_surface(m, nodes, x, 2 * n * n, tri, &err) || dem_state_init(m, s, 0, &err)) {
    fprintf(stderr, "setup: %s\n", err.msg);
    exit(2);
  }
  cJSON_Delete(j);
  free(tri);
  free(x);
}

static void steps(const dem_model *m, dem_state *s, int k) {
  proto_err err;
  for (int i = 0; i < k; i++)
    if (dem_step(m, s, &err)) { fprintf(stderr, "step: %s\n", err.msg); exit(1); }
}

/* Other meshes: accepted when no grain touches one (bitwise the run under its
 * own meshes), refused by the contacts otherwise. cp: the plough's state. */
static void other_meshes(const proto_msg *cp) {
  const int S = 1500, M = 1000;
  const double HIGH = 0.5; /* the bed's top is below 0.06 m */
  dem_model ma, mb;
  dem_state a, b;
  make_sheet(0, 4, HIGH, &ma, &a);
  steps(&ma, &a, S);
  int slide, plane, mesh;
  count_contacts(&ma, &a, &slide, &plane, &mesh);
  CHECK(mesh == 0 && a.contacts > 100, "the sheet above the bed: %d mesh contacts, %lld contacts", mesh,
        (long long)a.contacts);
  proto_err err = {{0}};
  proto_msg ex = {0}, st = {0};
  void *bufs[PROTO_MAX_ARRAYS];
  proto_msg_reset(&ex, "state", "state", 0, 0);
  CHECK(dem_state_export(&ma, &a, &ex, &err) == 0, "export: %s", err.msg);
  copy_msg(&ex, &st, bufs);
  proto_msg_free(&ex);
  make_sheet(0, 8, HIGH, &mb, &b);
  CHECK(ma.meshes[0].n_tri != mb.meshes[0].n_tri, "the two sheets differ");
  CHECK(dem_state_import(&mb, &b, &st, &err) == 0, "a state without mesh contacts under other meshes: %s",
        err.msg);
  CHECK(dem_state_other_meshes(&mb, &st) == 1 && dem_state_other_meshes(&ma, &st) == 0,
        "dem_state_other_meshes tells the two models apart");
  steps(&ma, &a, M);
  steps(&mb, &b, M);
  const int n = ma.n_grains;
  double *xa = malloc(sizeof(double) * 9 * (size_t)n), *xb = malloc(sizeof(double) * 9 * (size_t)n);
  gather_xvw(&a, xa);
  gather_xvw(&b, xb);
  printf("other meshes (4 x 4 -> 8 x 8 squares, %d -> %d triangles, above the bed): KE %.17g (own %.17g), "
         "%lld contacts (own %lld)\n", ma.meshes[0].n_tri, mb.meshes[0].n_tri, b.kinetic_energy,
         a.kinetic_energy, (long long)b.contacts, (long long)a.contacts);
  CHECK(a.kinetic_energy > 0 && memcmp(xa, xb, sizeof(double) * 9 * (size_t)n) == 0 &&
            a.kinetic_energy == b.kinetic_energy && a.contacts == b.contacts && a.step == b.step,
        "continued under other meshes out of reach: x, v, omega, KE, contacts or step differ");
  CHECK(memcmp(b.mesh_x[0], mb.meshes[0].x0, sizeof(double) * 3 * (size_t)mb.meshes[0].n_nodes) == 0,
        "the new meshes' nodes are where the model puts them");
  /* the plough's state, with mesh springs, under a finer sheet: refused by the contacts */
  dem_model mc;
  dem_state c;
  make_sheet(1, 8, FOOT_Z0, &mc, &c);
  expect_refused(&mc, &c, cp, "mesh contacts, other meshes", "grain-mesh contacts of the state");
  /* and a state of other grains under other meshes: refused by the grains */
  dem_model md;
  dem_state d;
  make_sheet(1, 8, FOOT_Z0, &md, &d);
  proto_array *model = NULL;
  for (int k = 0; k < st.narrays; k++)
    if (!strcmp(st.arrays[k].name, "state.model")) model = &st.arrays[k];
  ((int64_t *)model->data)[0] ^= 1; /* IO_M_GRAINS, and the fingerprint no longer matches it */
  expect_refused(&md, &d, &st, "other grains and meshes", "another model");
  for (int k = 0; k < st.narrays; k++) free(bufs[k]);
  proto_msg_free(&st);
  free(xa);
  free(xb);
  dem_state_free(&a);
  dem_state_free(&b);
  dem_state_free(&c);
  dem_state_free(&d);
  dem_model_free(&ma);
  dem_model_free(&mb);
  dem_model_free(&mc);
  dem_model_free(&md);
}

int main(void) {
  const int N = 3000, H = N / 2;
  dem_model m;
  dem_state a;
  make(1, 7, &m, &a);
  const int n = m.n_grains, nodes = FOOT_NODES;
  run(&m, &a, 0, N);
  double *xa = malloc(sizeof(double) * 9 * n);
  gather_xvw(&a, xa);

  /* half, export (deep copy), a fresh state imports it, the other half */
  dem_state b;
  dem_model mb;
  make(1, 7, &mb, &b);
  run(&mb, &b, 0, H);
  int slide, plane, mesh;
  count_contacts(&mb, &b, &slide, &plane, &mesh);
  printf("%d grains; at the export (step %d): %lld contacts, %d grain pairs at the Coulomb limit, "
         "%d plane and %d mesh springs, %lld rebuilds\n",
         n, H, (long long)b.contacts, slide, plane, mesh, (long long)b.rebuilds);
  CHECK(slide > 10 && plane > 10 && mesh > 5, "scene does not exercise sliding, wall and mesh contacts");
  proto_err err = {{0}};
  proto_msg ex = {0}, cp = {0};
  void *bufs[PROTO_MAX_ARRAYS];
  proto_msg_reset(&ex, "state", "state", 0, 0);
  CHECK(dem_state_export(&mb, &b, &ex, &err) == 0, "export: %s", err.msg);
  copy_msg(&ex, &cp, bufs);
  printf("exported %d arrays\n", ex.narrays);
  /* exporting again allocates nothing new and gives the same buffers */
  proto_msg ex2 = {0};
  proto_msg_reset(&ex2, "state", "state", 0, 0);
  dem_state_export(&mb, &b, &ex2, &err);
  for (int k = 0; k < ex.narrays; k++) CHECK(ex2.arrays[k].data == ex.arrays[k].data, "export buffers moved");
  proto_msg_free(&ex2);
  proto_msg_free(&ex);
  dem_state_free(&b);
  for (int threads = 1; threads <= 2; threads++) {
    dem_model mc;
    dem_state c;
    make(threads, 7, &mc, &c);
    CHECK(dem_state_import(&mc, &c, &cp, &err) == 0, "import: %s", err.msg);
    run(&mc, &c, H, N);
    double *xc = malloc(sizeof(double) * 9 * n);
    gather_xvw(&c, xc);
    printf("%d thread(s) after import: KE %.17g (straight %.17g), step %lld, t %.17g\n", threads,
           c.kinetic_energy, a.kinetic_energy, (long long)c.step, c.t);
    CHECK(memcmp(xa, xc, sizeof(double) * 9 * n) == 0, "x, v, ω differ after export/import (%d threads)", threads);
    CHECK(c.kinetic_energy == a.kinetic_energy && c.t == a.t && c.step == a.step && c.rebuilds == a.rebuilds,
          "KE, t, step or rebuilds differ after export/import");
    CHECK(memcmp(c.wall_force, a.wall_force, sizeof(double) * 3 * m.n_walls) == 0, "wall forces differ");
    CHECK(memcmp(c.mesh_force[1], a.mesh_force[1], sizeof(double) * 3 * nodes) == 0 &&
              memcmp(c.mesh_x[0], a.mesh_x[0], sizeof(double) * 3 * 4) == 0,
          "mesh nodal forces or plate position differ");
    free(xc);
    dem_state_free(&c);
    dem_model_free(&mc);
  }

  /* sleep off -> on: accepted, every grain awake; with thresholds no grain
   * meets (velocity 1e-12 m/s) the run is bitwise the one without sleep */
  {
    dem_model ms;
    dem_state ss;
    make_with(1, 7, ",\"sleep\":{\"velocity\":1e-12,\"distance\":0.01}", &ms, &ss);
    CHECK(dem_state_import(&ms, &ss, &cp, &err) == 0, "a sleep-off state into a sleep-on model: %s", err.msg);
    CHECK(ss.sleeping == 0 && ss.work->n_active == n, "after the import %lld grains asleep, %d awake of %d",
          (long long)ss.sleeping, ss.work->n_active, n);
    run(&ms, &ss, H, N);
    double *xs = malloc(sizeof(double) * 9 * n);
    gather_xvw(&ss, xs);
    printf("sleep off -> on: KE %.17g (straight %.17g), %lld asleep at the end\n", ss.kinetic_energy,
           a.kinetic_energy, (long long)ss.sleeping);
    CHECK(ss.sleeping == 0, "a grain fell asleep at velocity 1e-12 m/s");
    CHECK(memcmp(xa, xs, sizeof(double) * 9 * n) == 0 && ss.kinetic_energy == a.kinetic_energy,
          "sleep off -> on, no grain asleep: x, v, omega or KE differ from the run without sleep");
    /* and back: a sleep-on state into a sleep-off model is refused */
    proto_msg es = {0};
    proto_msg_reset(&es, "state", "state", 0, 0);
    CHECK(dem_state_export(&ms, &ss, &es, &err) == 0, "export with sleep: %s", err.msg);
    dem_model mo;
    dem_state so;
    make(1, 7, &mo, &so);
    expect_refused(&mo, &so, &es, "sleep-on state, sleep-off model", "sleep (on or off)");
    dem_state_free(&so);
    dem_model_free(&mo);
    proto_msg_free(&es);
    free(xs);
    dem_state_free(&ss);
    dem_model_free(&ms);
  }

  other_meshes(&cp);

  /* refusals: another model; damaged arrays (the state stays usable) */
  {
    dem_model mo;
    dem_state so;
    make(1, 8, &mo, &so); /* same counts, other radii */
    expect_refused(&mo, &so, &cp, "state of another model", "another model");
    dem_state_free(&so);
    dem_model_free(&mo);
  }
  dem_state d;
  dem_model md;
  make(1, 7, &md, &d);
  proto_array *nlj = find(&cp, "state.nl_j");
  int32_t *js = (int32_t *)nlj->data, save = js[0];
  js[0] = -5;
  expect_refused(&md, &d, &cp, "neighbour index out of range", "state.nl_j");
  js[0] = save;
  proto_array *v = find(&cp, "state.v");
  v->shape[0]--;
  expect_refused(&md, &d, &cp, "wrong shape", "state.v");
  v->shape[0]++;
  proto_array *id = find(&cp, "state.id");
  int32_t *ids = (int32_t *)id->data, id0 = ids[0];
  ids[0] = ids[1];
  expect_refused(&md, &d, &cp, "id not a permutation", "state.id");
  ids[0] = id0;
  v->dtype = PROTO_I8;
  expect_refused(&md, &d, &cp, "wrong dtype", "state.v");
  v->dtype = PROTO_F8;
  snprintf(find(&cp, "state.mc_key")->name, PROTO_NAME_LEN, "state.mc_keys");
  expect_refused(&md, &d, &cp, "missing array", "state.mc_key");
  snprintf(find(&cp, "state.mc_keys")->name, PROTO_NAME_LEN, "state.mc_key");
  CHECK(dem_state_import(&md, &d, &cp, &err) == 0, "the repaired message is refused: %s", err.msg);
  dem_state_free(&d);
  dem_model_free(&md);

  for (int k = 0; k < cp.narrays; k++) free(bufs[k]);
  proto_msg_free(&cp);
  free(xa);
  dem_state_free(&a);
  dem_model_free(&m);
  dem_model_free(&mb);
  return cosim_test_done("test_dem_state_io");
}
