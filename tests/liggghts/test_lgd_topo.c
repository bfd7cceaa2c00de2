/* lgd_topo: LIGGGHTS' rule for which triangle edges and corners take part in
 * contact, re-implemented on our own topology so that it can be re-applied as
 * a tread deforms. Checked against LIGGGHTS itself: for eight initial shapes
 * (flat grids with one or two diagonal directions, a tent, a ridge, a valley,
 * random heights, a sine surface, a closed cube) the flags lgd_topo_activity
 * computes equal those LIGGGHTS' set-up (SurfaceMesh::buildNeighbours) gives
 * the same shapes, triangle by triangle. Run with 1 and 2 MPI ranks. */
#include "lgd_test.h"

#include <stdarg.h>

enum { NX = 6, MAX_NODES = (NX + 1) * (NX + 1), MAX_TRI = 2 * NX * NX };

typedef struct shape {
  int nn, nt;
  double x[3 * MAX_NODES];
  int32_t tri[3 * MAX_TRI];
} shape;

static double lcg(uint64_t *s) { /* reproducible heights */
  *s = *s * 6364136223846793005ull + 1442695040888963407ull;
  return (double)(*s >> 11) / 9007199254740992.0;
}

/* An NX × NX grid over [0, 6 cm]² with heights z(i, j); alt: diagonals alternate. */
static void grid(shape *s, int kind, int alt) {
  const double h = 0.01;
  uint64_t seed = 7;
  s->nn = (NX + 1) * (NX + 1);
  s->nt = 2 * NX * NX;
  for (int j = 0; j <= NX; j++)
    for (int i = 0; i <= NX; i++) {
      double *p = &s->x[3 * (j * (NX + 1) + i)];
      p[0] = i * h;
      p[1] = j * h;
      p[2] = kind == 1 ? (i == NX / 2 && j == NX / 2 ? 0.004 : 0)  /* tent */
           : kind == 2 ? -0.3 * fabs(p[0] - 0.03)                   /* ridge */
           : kind == 3 ? 0.2 * fabs(p[1] - 0.03)                    /* valley */
           : kind == 4 ? 0.003 * lcg(&seed)                         /* random */
           : kind == 5 ? 0.004 * sin(80 * p[0]) * cos(60 * p[1])    /* sine */
                       : 0;                                         /* flat */
    }
  int32_t *t = s->tri;
  for (int j = 0; j < NX; j++)
    for (int i = 0; i < NX; i++) {
      const int32_t a = j * (NX + 1) + i, b = a + 1, c = a + NX + 1, d = c + 1;
      const int flip = alt && (i + j) % 2;
      const int32_t tt[6] = {a, b, flip ? c : d, flip ? b : a, d, c};
      memcpy(t, tt, sizeof tt);
      t += 6;
    }
}

static void cube(shape *s) {
  static const int32_t faces[12][3] = {{0, 2, 1}, {0, 3, 2}, {4, 5, 6}, {4, 6, 7}, {0, 1, 5}, {0, 5, 4},
                                       {1, 2, 6}, {1, 6, 5}, {2, 3, 7}, {2, 7, 6}, {3, 0, 4}, {3, 4, 7}};
  s->nn = 8;
  s->nt = 12;
  for (int v = 0; v < 8; v++) {
    s->x[3 * v] = 0.1 + 0.02 * ((v & 1) ^ ((v >> 1) & 1));
    s->x[3 * v + 1] = 0.1 + 0.02 * ((v >> 1) & 1);
    s->x[3 * v + 2] = 0.1 + 0.02 * (v >> 2);
  }
  memcpy(s->tri, faces, sizeof faces);
}

static char g_json[1 << 20];
static size_t g_len;
static void out(const char *fmt, ...) {
  va_list ap;
  va_start(ap, fmt);
  g_len += (size_t)vsnprintf(g_json + g_len, sizeof g_json - g_len, fmt, ap);
  va_end(ap);
}

int main(int argc, char **argv) {
  lgd_test_init(&argc, &argv);
  enum { NS = 8 };
  static shape sh[NS];
  static const char *const names[NS] = {"flat", "flat, alternating diagonals", "tent", "ridge",
                                        "valley", "random heights", "sine", "cube"};
  grid(&sh[0], 0, 0);
  grid(&sh[1], 0, 1);
  grid(&sh[2], 1, 0);
  grid(&sh[3], 2, 1);
  grid(&sh[4], 3, 0);
  grid(&sh[5], 4, 1);
  grid(&sh[6], 5, 0);
  cube(&sh[7]);
  /* every shape as a mesh wall of one scene; one grain far from all of them */
  out("{\"materials\":[{\"density\":2600,\"E\":5e6,\"nu\":0.3,\"restitution\":0.5,\"friction\":0.6}],"
      "\"gravity\":[0,0,0],\"dt\":1e-5,\"particles\":[{\"x\":[0.5,0.5,0.5],\"r\":0.003}],\"walls\":[");
  for (int k = 0; k < NS; k++) {
    out("%s{\"type\":\"mesh\",\"nodes\":[", k ? "," : "");
    for (int a = 0; a < sh[k].nn; a++)
      out("%s[%.17g,%.17g,%.17g]", a ? "," : "", sh[k].x[3 * a], sh[k].x[3 * a + 1], sh[k].x[3 * a + 2]);
    out("],\"triangles\":[");
    for (int t = 0; t < sh[k].nt; t++)
      out("%s[%d,%d,%d]", t ? "," : "", (int)sh[k].tri[3 * t], (int)sh[k].tri[3 * t + 1], (int)sh[k].tri[3 * t + 2]);
    out("]}");
  }
  out("]}");
  dem_model m;
  model_from_json(g_json, &m);
  lgd_sim *sim;
  proto_err err = {{0}};
  if (lgd_open(&sim, MPI_COMM_WORLD, &m, 0, NULL, &err)) die("open", &err);
  for (int k = 0; k < NS; k++) {
    static uint8_t le[3 * MAX_TRI], lc[3 * MAX_TRI], oe[3 * MAX_TRI], oc[3 * MAX_TRI];
    lgd_topo topo;
    if (lgd_topo_build(&topo, sh[k].nn, sh[k].nt, sh[k].tri, &err)) die("topology", &err);
    lgd_topo_activity(&topo, sh[k].x, oe, oc);
    lgd_topo_free(&topo);
    if (lgd_mesh_activity(sim, k, le, lc, &err)) die("activity", &err);
    int edges = 0, corners = 0, ne = 0, nc = 0;
    for (int s = 0; s < 3 * sh[k].nt; s++) {
      edges += le[s] != oe[s];
      corners += lc[s] != oc[s];
      ne += oe[s];
      nc += oc[s];
    }
    if (g_rank == 0)
      printf("%-28s %3d triangles: %3d active edges, %2d active corners; differ from LIGGGHTS: %d, %d\n",
             names[k], sh[k].nt, ne, nc, edges, corners);
    CHECK(edges == 0 && corners == 0, "%s: %d edge and %d corner flags differ from LIGGGHTS'", names[k], edges, corners);
  }
  /* a flat grid keeps only its boundary; a closed cube has every edge once
   * (12 edges) and every corner once (8) */
  int flat_edges = 0;
  {
    lgd_topo topo;
    static uint8_t e[3 * MAX_TRI], c[3 * MAX_TRI];
    if (lgd_topo_build(&topo, sh[7].nn, sh[7].nt, sh[7].tri, &err)) die("topology", &err);
    lgd_topo_activity(&topo, sh[7].x, e, c);
    int ne = 0, nc = 0;
    for (int s = 0; s < 36; s++) { ne += e[s]; nc += c[s]; }
    CHECK(ne == 12 && nc == 8, "cube: %d active edges (12), %d corners (8)", ne, nc);
    lgd_topo_free(&topo);
    if (lgd_topo_build(&topo, sh[0].nn, sh[0].nt, sh[0].tri, &err)) die("topology", &err);
    lgd_topo_activity(&topo, sh[0].x, e, c);
    for (int s = 0; s < 3 * sh[0].nt; s++) flat_edges += e[s];
    lgd_topo_free(&topo);
  }
  CHECK(flat_edges == 4 * NX, "flat grid: %d active edges, expected the %d boundary edges", flat_edges, 4 * NX);
  lgd_close(sim);
  dem_model_free(&m);
  return lgd_test_finish("test_lgd_topo");
}
