/* Bad input gives clear errors: inverted and degenerate elements, an orphan
 * node, E <= 0, nu >= 0.5, unknown keys, missing groups; Gmsh MSH 4.1 round
 * trip (ASCII and binary, TET4 and TET10) and broken / unsupported files. */
#include "fem_test.h"

#include <string.h>
#include <unistd.h>

static char tmpdir[256];

static void expect_error(int rc, const proto_err *err, const char *needle, const char *what) {
  CHECK(rc != 0, "%s: accepted", what);
  CHECK(rc == 0 || strstr(err->msg, needle) != NULL, "%s: message '%s' lacks '%s'", what, err->msg, needle);
  if (rc) printf("%-28s -> %s\n", what, err->msg);
}

static void small_box(fem_mesh *m) {
  proto_err err;
  const double L[3] = {1, 1, 1};
  const int n[3] = {2, 2, 2};
  OK(fem_gen_box(m, L, n, 0.1, &err));
}

static void mesh_errors(void) {
  proto_err err;
  fem_mesh m;
  fem_model md;
  const fem_material mat = {20e6, 0.45, 1100, 0};
  small_box(&m);
  int32_t t = m.conn[5 * 4 + 1]; /* swap two nodes of element 5 */
  m.conn[5 * 4 + 1] = m.conn[5 * 4 + 2];
  m.conn[5 * 4 + 2] = t;
  expect_error(fem_model_init(&md, &m, &mat, &err), &err, "element 5 is inverted", "inverted element");
  fem_model_free(&md);

  small_box(&m);
  int32_t *c = m.conn + 7 * 4; /* flatten element 7: node 3 onto the plane of 0,1,2 */
  for (int d = 0; d < 3; d++)
    m.x[3 * c[3] + d] = (m.x[3 * c[0] + d] + m.x[3 * c[1] + d] + m.x[3 * c[2] + d]) / 3;
  int rc = fem_mesh_check(&m, &err);
  CHECK(rc != 0 && (strstr(err.msg, "degenerate") || strstr(err.msg, "inverted")), "degenerate: %s", err.msg);
  if (rc) printf("%-28s -> %s\n", "degenerate element", err.msg);
  fem_mesh_free(&m);

  small_box(&m);
  m.x = realloc(m.x, sizeof *m.x * 3 * (m.n_nodes + 1));
  m.x[3 * m.n_nodes] = 5;
  m.x[3 * m.n_nodes + 1] = m.x[3 * m.n_nodes + 2] = 0;
  m.n_nodes++;
  char want[64];
  snprintf(want, sizeof want, "node %d (5, 0, 0) belongs to no element", m.n_nodes - 1);
  expect_error(fem_model_init(&md, &m, &mat, &err), &err, want, "orphan node");
  fem_model_free(&md);

  fem_material bad = mat;
  bad.E = 0;
  expect_error(fem_material_check(&bad, "material", &err), &err, "material.E: must be > 0", "E = 0");
  bad = mat;
  bad.nu = 0.5;
  expect_error(fem_material_check(&bad, "material", &err), &err, "material.nu: must be in (-1, 0.5)", "nu = 0.5");

  small_box(&m);
  OK(fem_model_init(&md, &m, &mat, &err));
  expect_error(fem_model_fix_group(&md, "rim", 7, &err), &err, "no surface group 'rim'", "missing group");
  OK(fem_model_assemble(&md, &err));
  double *b = calloc(md.n_dof, sizeof *b), *u = calloc(md.n_dof, sizeof *u);
  b[0] = 1;
  fem_factor *fac = NULL;
  expect_error(fem_static_solve(&md, &fac, FEM_CHOLMOD, 0, b, u, NULL, &err), &err, "not positive definite",
               "unconstrained body");
  /* the solver workspace belongs to one assembly */
  OK(fem_model_fix_group(&md, "xmin", 7, &err));
  OK(fem_model_assemble(&md, &err));
  expect_error(fem_static_solve(&md, &fac, FEM_CHOLMOD, 0, b, u, NULL, &err), &err,
               "earlier assembly", "solver workspace of an earlier assembly");
  fem_factor_free(&fac);
  OK(fem_static_solve(&md, &fac, FEM_CHOLMOD, 0, b, u, NULL, &err));
  fem_factor_free(&fac);
  /* the stable step needs the state's scratch */
  fem_state st = {0};
  expect_error(fem_stable_dt(&md, &st, 10, &err), &err, "fem_state_init first", "stable step without a state");
  free(b);
  free(u);
  fem_model_free(&md);
}

static void config_errors(void) {
  static const struct { const char *json, *needle, *what; } cases[] = {
    {"{\"exec\":\"fem_server\",\"mesh\":{\"generate\":\"bar\"},\"material\":{\"E\":-1,\"nu\":0.3,\"density\":1000}}",
     "processes.fem.material.E: must be > 0", "config E < 0"},
    {"{\"mesh\":{\"generate\":\"bar\"},\"material\":{\"E\":1e6,\"nu\":0.5,\"density\":1000}}",
     "processes.fem.material.nu: must be in (-1, 0.5)", "config nu = 0.5"},
    {"{\"mesh\":{\"generate\":\"bar\"},\"material\":{\"E\":1e6,\"nu\":0.3,\"density\":1000},\"presure\":1}",
     "processes.fem.presure: unknown key", "config typo"},
    {"{\"mesh\":{\"generate\":\"ball\"},\"material\":{\"E\":1e6,\"nu\":0.3,\"density\":1000}}",
     "processes.fem.mesh.generate", "config generator"},
    {"{\"mesh\":{\"generate\":\"bar\"},\"element\":\"hex8\",\"material\":{\"E\":1e6,\"nu\":0.3,\"density\":1000}}",
     "processes.fem.element", "config element"},
    {"{\"mesh\":{\"generate\":\"bar\",\"cells\":[0,1,1]},\"material\":{\"E\":1e6,\"nu\":0.3,\"density\":1000}}",
     "processes.fem.mesh.cells[0]", "config cells"},
    {"{\"mesh\":{},\"material\":{\"E\":1e6,\"nu\":0.3,\"density\":1000}}",
     "processes.fem.mesh: give exactly one of", "config empty mesh"},
    {"{\"mesh\":{\"generate\":\"bar\"},\"material\":{\"E\":1e6,\"nu\":0.3,\"density\":1000},\"fixed\":{\"group\":\"xmin\",\"components\":\"xw\"}}",
     "processes.fem.fixed.components", "config components"},
    {"{\"mesh\":{\"generate\":\"bar\"},\"material\":{\"E\":1e6,\"nu\":0.3,\"density\":1000},\"road\":{\"z\":0}}",
     "processes.fem.road.k_area: required key is missing", "config road without k_area"},
    {"{\"mesh\":{\"generate\":\"bar\"},\"material\":{\"E\":1e6,\"nu\":0.3,\"density\":1000},\"road\":{\"k_area\":0}}",
     "processes.fem.road.k_area: must be a finite penalty per unit area > 0 (N/m^3), got 0", "config road k_area 0"},
    {"{\"mesh\":{\"generate\":\"bar\"},\"material\":{\"E\":1e6,\"nu\":0.3,\"density\":1000},\"road\":{\"k_area\":1e8,\"height\":0}}",
     "processes.fem.road.height: unknown key", "config road typo"},
    {"{\"mesh\":{\"generate\":\"bar\"},\"material\":{\"E\":1e6,\"nu\":0.3,\"density\":1000},\"road\":{\"k_area\":1e8,\"z\":\"low\"}}",
     "processes.fem.road.z", "config road z not a number"},
    {"{\"mesh\":{\"generate\":\"bar\"},\"material\":{\"E\":1e6,\"nu\":0.3,\"density\":1000},\"road\":1}",
     "processes.fem.road", "config road not an object"},
    {"{\"mesh\":{\"generate\":\"bar\"},\"material\":{\"E\":1e6,\"nu\":0.3,\"density\":1000},\"reaction\":\"rim\"}",
     "processes.fem.reaction", "config reaction not a bool"},
    {"{\"mesh\":{\"generate\":\"tread\",\"phase_deg\":400},\"material\":{\"E\":1e6,\"nu\":0.3,\"density\":1000}}",
     "processes.fem.mesh.phase_deg", "config tread phase"},
    {"{\"mesh\":{\"generate\":\"bar\"},\"material\":{\"E\":1e6,\"nu\":0.3,\"density\":1000},\"threads\":1.5}",
     "processes.fem.threads: expected \"auto\"", "config threads not a count"},
    {"{\"mesh\":{\"generate\":\"bar\"},\"material\":{\"E\":1e6,\"nu\":0.3,\"density\":1000},\"threads\":\"many\"}",
     "processes.fem.threads: expected \"auto\"", "config threads word"},
  };
  for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
    proto_err err;
    cJSON *j = cJSON_Parse(cases[i].json);
    fem_config c;
    expect_error(fem_config_read(j, "processes.fem", &c, &err), &err, cases[i].needle, cases[i].what);
    cJSON_Delete(j);
  }
  /* a good section builds; a missing fixed group is named */
  proto_err err;
  cJSON *j = cJSON_Parse("{\"exec\":\"x\",\"mesh\":{\"generate\":\"bar\"},\"material\":{\"E\":1e6,\"nu\":0.3,"
                         "\"density\":1000},\"fixed\":[{\"group\":\"rim\"}]}");
  fem_config c;
  OK(fem_config_read(j, "processes.fem", &c, &err));
  CHECK(c.threads == 0, "threads: default %d, want 0 (auto)", c.threads);
  cJSON_AddNumberToObject(j, "threads", 1);
  OK(fem_config_read(j, "processes.fem", &c, &err));
  CHECK(c.threads == 1, "threads 1 read as %d", c.threads);
  fem_model md;
  expect_error(fem_config_build(&c, &md, &err), &err, "processes.fem.fixed[0].group: no surface group 'rim'", "config missing group");
  fem_model_free(&md);
  cJSON_Delete(j);
}

static void write_text(const char *path, const char *text) {
  FILE *f = fopen(path, "w");
  fputs(text, f);
  fclose(f);
}

static void msh_roundtrip(int tet10, int binary) {
  proto_err err;
  fem_mesh a, b;
  small_box(&a);
  if (tet10) OK(fem_mesh_to_tet10(&a, NULL, NULL, &err));
  char path[300];
  snprintf(path, sizeof path, "%s/rt_%d_%d.msh", tmpdir, tet10, binary);
  OK(fem_msh_write(path, &a, binary, &err));
  OK(fem_msh_read(path, &b, &err));
  int same = a.n_nodes == b.n_nodes && a.n_elems == b.n_elems && a.nodes_per_elem == b.nodes_per_elem &&
             a.n_groups == b.n_groups;
  for (int32_t i = 0; same && i < a.n_nodes * 3; i++) same = a.x[i] == b.x[i];
  for (int32_t i = 0; same && i < a.n_elems * a.nodes_per_elem; i++) same = a.conn[i] == b.conn[i];
  for (int g = 0; same && g < a.n_groups; g++) {
    int h = fem_mesh_group(&b, a.groups[g].name, &err);
    same = h >= 0 && b.groups[h].n_faces == a.groups[g].n_faces;
  }
  printf("msh round trip %s %s: %d nodes, %d elements, %d groups: %s\n", tet10 ? "tet10" : "tet4",
         binary ? "binary" : "ascii", b.n_nodes, b.n_elems, b.n_groups, same ? "identical" : "DIFFERENT");
  CHECK(same, "msh round trip differs (tet10 %d, binary %d)", tet10, binary);
  /* truncated file */
  FILE *f = fopen(path, "rb");
  fseek(f, 0, SEEK_END);
  long sz = ftell(f);
  fseek(f, 0, SEEK_SET);
  char *buf = malloc(sz);
  size_t got = fread(buf, 1, sz, f);
  fclose(f);
  snprintf(path, sizeof path, "%s/trunc_%d_%d.msh", tmpdir, tet10, binary);
  f = fopen(path, "wb");
  fwrite(buf, 1, got * 2 / 3, f);
  fclose(f);
  free(buf);
  fem_mesh c;
  int rc = fem_msh_read(path, &c, &err);
  CHECK(rc != 0 && strstr(err.msg, path), "truncated file accepted or unnamed: %s", err.msg);
  if (rc) printf("%-28s -> %s\n", "truncated msh", err.msg);
  fem_mesh_free(&a);
  fem_mesh_free(&b);
}

static void msh_errors(void) {
  proto_err err;
  fem_mesh m;
  char path[300];
  snprintf(path, sizeof path, "%s/hex.msh", tmpdir);
  write_text(path, "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 8 1 8\n3 1 0 8\n1\n2\n3\n4\n5\n6\n7\n8\n"
                   "0 0 0\n1 0 0\n1 1 0\n0 1 0\n0 0 1\n1 0 1\n1 1 1\n0 1 1\n$EndNodes\n"
                   "$Elements\n1 1 1 1\n3 1 5 1\n1 1 2 3 4 5 6 7 8\n$EndElements\n");
  expect_error(fem_msh_read(path, &m, &err), &err, "unsupported element type 5", "hexahedron in msh");
  snprintf(path, sizeof path, "%s/v2.msh", tmpdir);
  write_text(path, "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n");
  expect_error(fem_msh_read(path, &m, &err), &err, "only MSH version 4.1", "msh version 2.2");
  snprintf(path, sizeof path, "%s/junk.msh", tmpdir);
  write_text(path, "solid foo\n");
  expect_error(fem_msh_read(path, &m, &err), &err, "junk.msh", "not a mesh");
  expect_error(fem_msh_read("/nonexistent/x.msh", &m, &err), &err, "cannot open", "missing file");
  /* a triangle in a physical group that is not on the boundary */
  snprintf(path, sizeof path, "%s/inner_tri.msh", tmpdir);
  write_text(path, "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$PhysicalNames\n1\n2 2 \"rim\"\n$EndPhysicalNames\n"
                   "$Entities\n0 0 1 1\n1 0 0 0 0 0 0 1 2 0\n1 0 0 0 0 0 0 0 0\n$EndEntities\n"
                   "$Nodes\n1 5 1 5\n3 1 0 5\n1\n2\n3\n4\n5\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n0 0 -1\n$EndNodes\n"
                   "$Elements\n2 3 1 3\n3 1 4 2\n1 1 2 3 4\n2 1 3 2 5\n2 1 2 1\n3 1 2 3\n$EndElements\n");
  expect_error(fem_msh_read(path, &m, &err), &err, "is not a boundary face", "interior face in group");
}

/* A unit cube in the structure Gmsh 4.1 writes: point/curve/surface/volume
 * entities with bounding tags, one node block per entity, sparse node tags,
 * point and line elements, a named physical surface (z = 0) and a surface
 * entity without physical tags (ignored). 12 tets = 12 face triangles + the
 * centre node. */
static void gmsh_style_file(void) {
  proto_err err;
  char path[300];
  snprintf(path, sizeof path, "%s/gmsh_style.msh", tmpdir);
  FILE *f = fopen(path, "w");
  fprintf(f, "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$PhysicalNames\n2\n2 5 \"bottom\"\n3 9 \"solid\"\n"
             "$EndPhysicalNames\n$Entities\n8 1 2 1\n");
  for (int c = 0; c < 8; c++) fprintf(f, "%d %d %d %d 0 \n", c + 1, c & 1, (c >> 1) & 1, (c >> 2) & 1);
  fprintf(f, "1 0 0 0 1 0 0 0 2 1 -2 \n");
  fprintf(f, "1 0 0 0 1 1 0 1 5 4 1 2 3 4 \n2 0 0 0 1 1 1 0 5 1 2 3 4 5 \n");
  fprintf(f, "1 0 0 0 1 1 1 1 9 2 1 2 \n$EndEntities\n");
  fprintf(f, "$Nodes\n9 9 1 100\n");
  for (int c = 0; c < 8; c++) fprintf(f, "0 %d 0 1\n%d\n%d %d %d\n", c + 1, c + 1, c & 1, (c >> 1) & 1, (c >> 2) & 1);
  fprintf(f, "3 1 0 1\n100\n0.5 0.5 0.5\n$EndNodes\n");
  /* the 6 faces as corner quads (x + 2y + 4z), split into triangles */
  static const int quad[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  int tri[12][3], nt = 0;
  for (int q = 0; q < 6; q++) {
    int t1[3] = {quad[q][0], quad[q][1], quad[q][2]}, t2[3] = {quad[q][0], quad[q][2], quad[q][3]};
    memcpy(tri[nt++], t1, sizeof t1);
    memcpy(tri[nt++], t2, sizeof t2);
  }
  fprintf(f, "$Elements\n5 26 1 26\n0 1 15 1\n1 1 \n1 1 1 1\n2 1 2 \n2 1 2 2\n");
  for (int t = 0; t < 2; t++) fprintf(f, "%d %d %d %d \n", 3 + t, tri[t][0] + 1, tri[t][1] + 1, tri[t][2] + 1);
  fprintf(f, "2 2 2 10\n");
  for (int t = 2; t < 12; t++) fprintf(f, "%d %d %d %d \n", 3 + t, tri[t][0] + 1, tri[t][1] + 1, tri[t][2] + 1);
  fprintf(f, "3 1 4 12\n");
  for (int t = 0; t < 12; t++) { /* (a, c, b, centre) is positive for an outward face (a, b, c)? check */
    double x[4][3];
    int v[4] = {tri[t][0], tri[t][2], tri[t][1], -1};
    for (int k = 0; k < 3; k++)
      for (int d = 0; d < 3; d++) x[k][d] = (v[k] >> d) & 1;
    for (int d = 0; d < 3; d++) x[3][d] = 0.5;
    double a[3], b[3], c[3];
    for (int d = 0; d < 3; d++) { a[d] = x[1][d] - x[0][d]; b[d] = x[2][d] - x[0][d]; c[d] = x[3][d] - x[0][d]; }
    double det = a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) + a[2] * (b[0] * c[1] - b[1] * c[0]);
    if (det < 0) { int tmp = v[1]; v[1] = v[2]; v[2] = tmp; }
    fprintf(f, "%d %d %d %d 100 \n", 15 + t, v[0] + 1, v[1] + 1, v[2] + 1);
  }
  fprintf(f, "$EndElements\n");
  fclose(f);
  fem_mesh m;
  OK(fem_msh_read(path, &m, &err));
  int g = fem_mesh_group(&m, "bottom", &err);
  fem_material mat = {1e6, 0.3, 1000, 0};
  fem_model md;
  OK(fem_model_init(&md, &m, &mat, &err));
  double vol = 0;
  for (int32_t e = 0; e < md.mesh.n_elems; e++) vol += md.wdet[e];
  printf("gmsh-style msh: %d nodes, %d tets, %d groups, 'bottom' %d faces, volume %.15g\n", md.mesh.n_nodes,
         md.mesh.n_elems, md.mesh.n_groups, g >= 0 ? md.mesh.groups[g].n_faces : -1, vol);
  CHECK(md.mesh.n_nodes == 9 && md.mesh.n_elems == 12 && md.mesh.n_groups == 1 && g == 0 &&
        md.mesh.groups[0].n_faces == 2 && fabs(vol - 1) < 1e-14, "gmsh-style file read wrongly");
  fem_model_free(&md);
}

int main(void) {
  snprintf(tmpdir, sizeof tmpdir, "/tmp/test_fem_input_%d", (int)getpid());
  char cmd[300];
  snprintf(cmd, sizeof cmd, "mkdir -p %s", tmpdir);
  if (system(cmd) != 0) return 1;
  mesh_errors();
  config_errors();
  for (int t = 0; t < 2; t++)
    for (int bin = 0; bin < 2; bin++) msh_roundtrip(t, bin);
  msh_errors();
  gmsh_style_file();
  snprintf(cmd, sizeof cmd, "rm -rf %s", tmpdir);
  if (system(cmd) != 0) return 1;
  return cosim_test_done("test_fem_input");
}
