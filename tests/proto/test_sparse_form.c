/* The sparse form of a role-table array (proto/roles.c, PROTOCOL.md "Sparse
 * exchange"): with "<name>_index" (i4 [k], strictly increasing, < n) the
 * array has k rows; a bad index (order, range, dtype, length) or a row count
 * that disagrees is refused naming the array; proto_msg_dense expands it to
 * the dense rows with +0.0 elsewhere; proto_reach_nodes picks the nodes of
 * the triangles whose box over the step meets a box, and only those;
 * proto_first_nonfinite finds the first inf or nan of an array. */
#include <float.h>
#include <math.h>
#include <string.h>

#include "proto/proto.h"
#include "cosim_test.h"

/* A dem done of step 1 with a sparse nodal_force of k rows over nodes idx. */
static void done_msg(proto_msg *m, const int32_t *idx, int64_t k, const double *rows,
                     int64_t nrows) {
  proto_msg_reset(m, "dem", "done", 1, 0);
  proto_msg_add_i4(m, PROTO_A_NODAL_FORCE_INDEX, k, 0, idx);
  proto_msg_add_f8(m, PROTO_A_NODAL_FORCE, nrows, 3, rows);
}

int main(void) {
  proto_err err = {{0}};
  double x0[4][3] = {{0}};
  int32_t tri[2][3] = {{0, 1, 2}, {1, 3, 2}};
  proto_msg m = {0};
  proto_dims d;
  proto_dims_init(&d);
  proto_msg_reset(&m, "dem", "welcome", 0, 0);
  proto_msg_add_f8(&m, PROTO_A_SURFACE_X0, 4, 3, &x0[0][0]);
  proto_msg_add_i4(&m, PROTO_A_SURFACE_TRI, 2, 3, &tri[0][0]);
  OK(proto_role_check(PROTO_ROLE_DEM, PROTO_MSG_WELCOME, &m, &d, &err));

  const double rows[2][3] = {{1, -0.0, 2}, {3, 4, 5}};
  int32_t good[2] = {1, 3};
  done_msg(&m, good, 2, &rows[0][0], 2);
  OK(proto_role_check(PROTO_ROLE_DEM, PROTO_MSG_DONE, &m, &d, &err));
  CHECK(d.nodes == 4, "k does not rebind n");
  const int32_t *idx;
  CHECK(proto_msg_sparse(&m, PROTO_A_NODAL_FORCE, &idx) == 2 && idx[1] == 3);
  double dense[4][3];
  memset(dense, 0xff, sizeof dense);
  const double *f = proto_msg_dense(&m, PROTO_A_NODAL_FORCE, 4, 3, &dense[0][0]);
  const double want[4][3] = {{0, 0, 0}, {1, -0.0, 2}, {0, 0, 0}, {3, 4, 5}};
  CHECK(f == &dense[0][0] && memcmp(dense, want, sizeof want) == 0,
        "expanded: listed rows as sent (-0.0 kept), the others +0.0");
  /* no rows at all: an empty sparse form is valid */
  done_msg(&m, good, 0, &rows[0][0], 0);
  OK(proto_role_check(PROTO_ROLE_DEM, PROTO_MSG_DONE, &m, &d, &err));
  /* dense stays dense */
  proto_msg_reset(&m, "dem", "done", 1, 0);
  proto_msg_add_f8(&m, PROTO_A_NODAL_FORCE, 4, 3, &want[0][0]);
  OK(proto_role_check(PROTO_ROLE_DEM, PROTO_MSG_DONE, &m, &d, &err));
  CHECK(proto_msg_sparse(&m, PROTO_A_NODAL_FORCE, &idx) == -1 && !idx);
  CHECK(proto_msg_dense(&m, PROTO_A_NODAL_FORCE, 4, 3, &dense[0][0]) == proto_msg_data(&m, PROTO_A_NODAL_FORCE));

  /* refused: rows that disagree with the index, order, range, dtype */
  done_msg(&m, good, 2, &rows[0][0], 1);
  FAILS_WITH(proto_role_check(PROTO_ROLE_DEM, PROTO_MSG_DONE, &m, &d, &err),
             "array 'nodal_force': expected f8 [2, 3]");
  int32_t twice[2] = {1, 1}, back[2] = {3, 1}, out[2] = {1, 4}, neg[2] = {-1, 2};
  done_msg(&m, twice, 2, &rows[0][0], 2);
  FAILS_WITH(proto_role_check(PROTO_ROLE_DEM, PROTO_MSG_DONE, &m, &d, &err),
             "nodal_force_index[1] = 1: expected node indices in [0, 4), strictly increasing");
  done_msg(&m, back, 2, &rows[0][0], 2);
  FAILS_WITH(proto_role_check(PROTO_ROLE_DEM, PROTO_MSG_DONE, &m, &d, &err), "nodal_force_index[1] = 1");
  done_msg(&m, out, 2, &rows[0][0], 2);
  FAILS_WITH(proto_role_check(PROTO_ROLE_DEM, PROTO_MSG_DONE, &m, &d, &err), "nodal_force_index[1] = 4");
  done_msg(&m, neg, 2, &rows[0][0], 2);
  FAILS_WITH(proto_role_check(PROTO_ROLE_DEM, PROTO_MSG_DONE, &m, &d, &err), "nodal_force_index[0] = -1");
  int32_t five[5] = {0, 1, 2, 3, 3};
  done_msg(&m, five, 5, &rows[0][0], 2);
  FAILS_WITH(proto_role_check(PROTO_ROLE_DEM, PROTO_MSG_DONE, &m, &d, &err), "'nodal_force_index'");
  proto_msg_reset(&m, "dem", "done", 1, 0);
  proto_msg_add_f8(&m, PROTO_A_NODAL_FORCE_INDEX, 2, 0, &rows[0][0]);
  proto_msg_add_f8(&m, PROTO_A_NODAL_FORCE, 2, 3, &rows[0][0]);
  FAILS_WITH(proto_role_check(PROTO_ROLE_DEM, PROTO_MSG_DONE, &m, &d, &err),
             "wrong shape or dtype of array 'nodal_force_index': expected i4 [k]");
  /* an index the table does not declare for that message is not one: x in
   * a dem done is not a row of the table, so x_index there changes nothing */
  proto_msg_reset(&m, "dem", "done", 1, 0);
  proto_msg_add_i4(&m, PROTO_A_X_INDEX, 2, 0, good);
  proto_msg_add_f8(&m, PROTO_A_NODAL_FORCE, 4, 3, &want[0][0]);
  OK(proto_role_check(PROTO_ROLE_DEM, PROTO_MSG_DONE, &m, &d, &err));

  /* the JSON form: index rows are "sparse_index", shape ["k"] */
  cJSON *j = proto_role_table_json();
  char *txt = cJSON_PrintUnformatted(j);
  CHECK(strstr(txt, "\"name\":\"x_index\",\"dtype\":\"i4\",\"shape\":[\"k\"]") != NULL, "%s", "x_index row");
  CHECK(strstr(txt, "\"when\":\"sparse_index\"") != NULL);
  free(txt);
  cJSON_Delete(j);

  /* proto_reach_nodes: a strip of 3 triangles along x (nodes 0..4 at
   * x = 0, 1, 2, 3, 4, alternating y); a box over x in [0.5, 0.6] meets only
   * the first triangle's box; with v the step moves the strip by v dt, and
   * the box swept over the step decides */
  const double sx[5][3] = {{0, 0, 0}, {1, 1, 0}, {2, 0, 0}, {3, 1, 0}, {4, 0, 0}};
  const double still[5][3] = {{0}};
  const int32_t st[3][3] = {{0, 1, 2}, {1, 3, 2}, {2, 3, 4}};
  const double box[6] = {0.5, -1, -1, 0.6, 2, 1};
  uint8_t mark[5];
  int32_t sel[5];
  int64_t k = proto_reach_nodes(&sx[0][0], &still[0][0], 1e-3, &st[0][0], 3, 5, box, mark, sel);
  CHECK(k == 3 && sel[0] == 0 && sel[1] == 1 && sel[2] == 2, "only triangle 0 meets x in [0.5, 0.6] (%lld)",
        (long long)k);
  const double box_far[6] = {5.5, -1, -1, 6, 2, 1};
  CHECK(proto_reach_nodes(&sx[0][0], &still[0][0], 1e-3, &st[0][0], 3, 5, box_far, mark, sel) == 0,
        "a box beyond the strip: no node");
  double fast[5][3] = {{0}};
  for (int a = 0; a < 5; a++) fast[a][0] = 2000; /* 2 m in the step of 1 ms */
  k = proto_reach_nodes(&sx[0][0], &fast[0][0], 1e-3, &st[0][0], 3, 5, box_far, mark, sel);
  CHECK(k == 3 && sel[0] == 2 && sel[2] == 4, "swept over the step, the last triangle reaches x = 5.5 (%lld)",
        (long long)k);
  /* against the contract's words, triangle by triangle, on random meshes
   * and boxes (a triangle whose box over the step, grown by the rounding,
   * meets the box sends its nodes), boxes near the nodes' coordinates so
   * that the comparisons at the rounding's edge happen */
  enum { RN = 40, RT = 60 };
  double rx[RN * 3], rv[RN * 3];
  int32_t rt[RT * 3];
  uint8_t rmark[RN], rwant[RN];
  int32_t rsel[RN];
  unsigned seed = 12345;
  int differ = 0;
  for (int trial = 0; trial < 2000 && !differ; trial++) {
    for (int i = 0; i < RN * 3; i++) {
      seed = seed * 1103515245u + 12345u;
      rx[i] = (double)(seed >> 16 & 1023) / 1024.0;
      seed = seed * 1103515245u + 12345u;
      rv[i] = trial % 2 ? ((double)(seed >> 16 & 1023) / 512.0 - 1.0) * 50 : 0;
    }
    for (int i = 0; i < RT * 3; i++) {
      seed = seed * 1103515245u + 12345u;
      rt[i] = (int32_t)((seed >> 16) % RN);
    }
    double rb[6];
    for (int d = 0; d < 3; d++) {
      seed = seed * 1103515245u + 12345u;
      const double a = rx[3 * (int)((seed >> 16) % RN) + d];
      seed = seed * 1103515245u + 12345u;
      const double b = a + (trial % 3 ? (double)(seed >> 16 & 255) / 2048.0 : 0);
      rb[d] = a + (trial % 5 == 0 ? PROTO_REACH_ROUNDING : 0);
      rb[3 + d] = b;
    }
    memset(rwant, 0, sizeof rwant);
    for (int t = 0; t < RT; t++) {
      int meets = 1;
      for (int d = 0; d < 3; d++) {
        double lo = INFINITY, hi = -INFINITY;
        for (int c = 0; c < 3; c++) {
          const double p = rx[3 * rt[3 * t + c] + d], q = p + rv[3 * rt[3 * t + c] + d] * 1e-3;
          lo = fmin(lo, fmin(p, q));
          hi = fmax(hi, fmax(p, q));
        }
        meets &= lo - PROTO_REACH_ROUNDING <= rb[3 + d] && hi + PROTO_REACH_ROUNDING >= rb[d];
      }
      for (int c = 0; meets && c < 3; c++) rwant[rt[3 * t + c]] = 1;
    }
    const int64_t got = proto_reach_nodes(rx, rv, 1e-3, rt, RT, RN, rb, rmark, rsel);
    int64_t nwant = 0;
    for (int a = 0; a < RN; a++) nwant += rwant[a];
    differ = got != nwant || memcmp(rmark, rwant, RN) != 0;
    for (int64_t j = 0; !differ && j < got; j++) differ = !rwant[rsel[j]] || (j > 0 && rsel[j] <= rsel[j - 1]);
    CHECK(!differ, "random mesh %d: the nodes sent are those of the triangles whose swept box meets "
          "the box (%lld sent, %lld by the contract)", trial, (long long)got, (long long)nwant);
  }
  /* proto_first_nonfinite (the check of every array that crosses a step):
   * the first inf or nan of either sign at any place, none in finite
   * extremes (+-DBL_MAX, subnormals, -0.0), -1 for an empty array */
  enum { FN = 203 };
  double fv[FN];
  const double edge[] = {DBL_MAX, -DBL_MAX, 4.9e-324, -4.9e-324, -0.0, DBL_MIN, 1.0};
  for (int i = 0; i < FN; i++) fv[i] = edge[i % 7];
  CHECK(proto_first_nonfinite(fv, FN) == -1, "finite extremes are finite");
  CHECK(proto_first_nonfinite(fv, 0) == -1, "an empty array has none");
  const double bad[] = {INFINITY, -INFINITY, NAN, -NAN};
  for (int b = 0; b < 4; b++)
    for (int at = 0; at < FN; at += 1 + at / 8) {
      double keep = fv[at];
      fv[at] = bad[b];
      if (at + 5 < FN) fv[at + 5] = bad[(b + 1) % 4]; /* a later one does not hide it */
      const int64_t got = proto_first_nonfinite(fv, FN);
      CHECK(got == at, "non-finite value %d at %d: found at %lld", b, at, (long long)got);
      CHECK(proto_first_nonfinite(fv, at) == -1, "before %d: none", at);
      fv[at] = keep;
      if (at + 5 < FN) fv[at + 5] = edge[(at + 5) % 7];
    }
  proto_msg_free(&m);
  return cosim_test_done("sparse_form");
}
