/* Bad input gives clear errors (issue 5): Green's functions of the wrong
 * shape (in memory and in a green.h5 file), non-monotone spring tables, NaN
 * heights, and config sections with bad keys. */
#include <math.h>
#include <string.h>

#include "blk_test.h"
#include "contact_block/blk.h"
#include "green/green.h"

static proto_err err;

#define EXPECT_ERR(call, needle)                                                   \
  do {                                                                             \
    err.msg[0] = 0;                                                                \
    int rc_ = (call);                                                              \
    CHECK(rc_ == -1, "%s succeeded", #call);                                       \
    CHECK(strstr(err.msg, needle) != NULL, "message '%s' lacks '%s'", err.msg, needle); \
    printf("ok: %s\n    -> %s\n", #call, err.msg);                                 \
  } while (0)

/* green.h5 through its one writer (green/io.c): a 10 x ny grid of Q
 * samples with g = 1e-3 and static = Δt Σ g, element size dx x dy. */
static void write_green(const char *path, int Q, int ny, double dx, double dy) {
  const grn_grid g = {10, ny, dx, dy};
  const int no = (2 * ny - 1) * 19;
  double *buf = malloc(sizeof(double) * (size_t)Q * no), *st = malloc(sizeof(double) * no);
  for (int i = 0; i < Q * no; i++) buf[i] = 1e-3;
  for (int i = 0; i < no; i++) st[i] = Q * 1e-3 / 51200;
  OK(grn_write_green(path, &g, Q, 51200, "zoh", "test", buf, st, NULL, 0, 0, NULL, &err));
  free(buf);
  free(st);
}

static int config_error(const char *json, const char *needle) {
  cJSON *root = proto_json_parse(json, "test", &err);
  blk_model m;
  EXPECT_ERR(blk_model_from_config(&m, root, "processes.block", &err), needle);
  blk_model_free(&m);
  cJSON_Delete(root);
  return 0;
}

int main(void) {
  blk_model m;
  OK(blk_model_init(&m, 10, 10, 1e-3, 1e-3, &err));
  /* Green's functions of the wrong shape */
  double g[4 * 19 * 17] = {0}, st[19 * 17] = {0};
  EXPECT_ERR(blk_green_set(&m, 4, 51200, 19, 17, g, st, "zoh", "x", &err), "[19, 19]");
  write_green("/tmp/blk_test_bad_green.h5", 4, 11, 1e-3, 1e-3); /* offsets [21, 19] */
  EXPECT_ERR(blk_green_load(&m, "/tmp/blk_test_bad_green.h5", &err), "offset grid");
  write_green("/tmp/blk_test_bad_green.h5", 4, 10, 1e-3, 1.2e-3); /* rectangular elements */
  EXPECT_ERR(blk_green_load(&m, "/tmp/blk_test_bad_green.h5", &err), "0.001 x 0.0012 m");
  EXPECT_ERR(blk_green_load(&m, "/nonexistent/green.h5", &err), "cannot open");
  /* static compliance inconsistent with the time sum of g */
  {
    static double g2[4 * 19 * 19], st2[19 * 19];
    for (int i = 0; i < 4 * 19 * 19; i++) g2[i] = 1.0;
    for (int i = 0; i < 19 * 19; i++) st2[i] = 4.0 / 51200;
    st2[5] *= 1.01;
    EXPECT_ERR(blk_green_set(&m, 4, 51200, 19, 19, g2, st2, "zoh", "x", &err),
               "dt * sum_k g(k)");
    st2[5] = 4.0 / 51200;
    OK(blk_green_set(&m, 4, 51200, 19, 19, g2, st2, "zoh", "x", &err));
  }
  /* a correctly shaped file loads */
  write_green("/tmp/blk_test_bad_green.h5", 4, 10, 1e-3, 1e-3);
  OK(blk_green_load(&m, "/tmp/blk_test_bad_green.h5", &err));
  CHECK(m.Q == 4 && m.rate == 51200, "loaded Q %d rate %g", m.Q, m.rate);
  /* a periodic grid refuses Green's functions that are not periodic */
  {
    blk_model mp;
    OK(blk_model_init(&mp, 10, 10, 1e-3, 1e-3, &err));
    mp.periodic = 1;
    OK(blk_green_load(&mp, "/tmp/blk_test_bad_green.h5", &err));
    double kk = 1e5;
    OK(blk_springs_linear(&mp, &kk, 0, &err));
    EXPECT_ERR(blk_model_check(&mp, &err), "grid.periodic");
    blk_model_free(&mp);
  }
  remove("/tmp/blk_test_bad_green.h5");
  /* non-monotone spring table: element 3's force drops at knot 2 */
  enum { K = 4 };
  static double d[100 * K], F[100 * K], k[100 * K];
  for (int e = 0; e < 100; e++)
    for (int i = 0; i < K; i++) {
      d[e * K + i] = 1e-5 * i;
      F[e * K + i] = 1.0 * i;
      k[e * K + i] = 1e5;
    }
  F[3 * K + 2] = 0.5;
  EXPECT_ERR(blk_springs_table(&m, K, d, F, k, &err), "non-monotone");
  F[3 * K + 2] = 2.0;
  k[5 * K + 1] = -1;
  EXPECT_ERR(blk_springs_table(&m, K, d, F, k, &err), "element 5 knot 1");
  k[5 * K + 1] = 1e5;
  d[7 * K + 3] = d[7 * K + 2];
  EXPECT_ERR(blk_springs_table(&m, K, d, F, k, &err), "not increasing");
  /* NaN heights */
  double z[100] = {0};
  z[42] = NAN;
  EXPECT_ERR(blk_road_set(&m, z, &err), "element 42 (i=2, j=4)");
  blk_model_free(&m);
  /* a NaN road displacement stops a step with a message */
  OK(blk_model_init(&m, 2, 2, 1e-3, 1e-3, &err));
  double kk = 1e5;
  OK(blk_springs_linear(&m, &kk, 0, &err));
  OK(blk_green_halfspace(&m, 1e7, 0.3, &err));
  m.solver.quasi_static = 1;
  blk_state s;
  OK(blk_state_create(&m, &s, &err));
  EXPECT_ERR(blk_step(&m, &s, NAN, &err), "d_road is not finite");
  blk_state_free(&s);
  blk_model_free(&m);
  /* config sections: errors name the key path */
  config_error("{\"springs\":{\"kind\":\"linear\",\"k\":-5},\"green\":{\"kind\":\"halfspace\"}}",
               "processes.block.springs.k");
  config_error("{\"springs\":{\"kind\":\"linear\",\"k\":1e5},\"green\":{\"kind\":\"halfspace\"},"
               "\"solver\":{\"quasi_static\":true,\"metod\":\"newton\"}}",
               "processes.block.solver.metod");
  config_error("{\"springs\":{\"kind\":\"linear\",\"k\":1e5},\"green\":{\"kind\":\"halfspace\"}}",
               "quasi_static");
  config_error("{\"springs\":{\"kind\":\"linear\",\"k\":1e5},\"green\":{\"kind\":\"file\","
               "\"file\":\"/nonexistent/g.h5\"}}",
               "processes.block.green");
  /* issue 14: the new keys */
  config_error("{\"grid\":{\"nx\":5000},\"springs\":{\"kind\":\"rigid\"},"
               "\"green\":{\"kind\":\"halfspace\"}}", "processes.block.grid.nx");
  config_error("{\"springs\":{\"kind\":\"rigid\"},\"green\":{\"kind\":\"halfspace\"},"
               "\"solver\":{\"quasi_static\":true,\"method\":\"newton\"}}",
               "rigid springs (hard contact) need dual_newton");
  config_error("{\"springs\":{\"kind\":\"stiffening\",\"soften\":{\"count\":300}},"
               "\"green\":{\"kind\":\"synthetic\"}}", "springs.soften: soften: count = 300");
  config_error("{\"springs\":{\"kind\":\"stiffening\",\"soften\":{\"count\":8,"
               "\"factor\":2}},\"green\":{\"kind\":\"synthetic\"}}",
               "processes.block.springs.soften.factor");
  config_error("{\"springs\":{\"kind\":\"rigid\",\"soften\":{\"count\":8}},"
               "\"green\":{\"kind\":\"synthetic\"}}", "needs roughness springs");
  config_error("{\"grid\":{\"periodic\":true},\"springs\":{\"kind\":\"rigid\"},"
               "\"green\":{\"kind\":\"synthetic\"},\"solver\":{\"method\":\"dense\"}}",
               "processes.block.solver.method");
  config_error("{\"grid\":{\"nx\":100,\"ny\":100},\"springs\":{\"kind\":\"rigid\"},"
               "\"green\":{\"kind\":\"halfspace\"},\"solver\":{\"quasi_static\":true,"
               "\"method\":\"dual_newton\"}}", "dense solvers keep M x M matrices");
  config_error("{\"grid\":{\"nx\":2,\"ny\":2},\"springs\":{\"kind\":\"linear\",\"k\":1e5},"
               "\"green\":{\"kind\":\"synthetic\"},\"road\":{\"kind\":\"values\",\"z\":[0,0,0]}}",
               "processes.block.road.z");
  return cosim_test_done("test_block_badinput");
}
