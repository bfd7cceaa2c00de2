/* fuzz_config — the participants' config readers, as their configure() runs
 * them for `--check-config` and the welcome: dem_model_from_json (+ the
 * initial-state probe), fem_config_read + fem_config_build, and
 * blk_model_from_config. The first byte picks the participant, the rest is
 * the processes.<name> section (JSON).
 *
 * Valid sections may ask for large models (a million grains, a 4096² block):
 * that is legal input whose cost is the user's choice, not a defect, so
 * sections whose size keys exceed a small budget are skipped (budget[] below;
 * the limits above the budget are tested by tests/input). Sections that
 * would write files (mesh.write, particles.save) are skipped too. */
#include "contact_block/blk.h"
#include "dem_server/dem.h"
#include "fem_server/fem.h"
#include "fuzz.h"

enum { P_DEM, P_FEM, P_BLOCK, N_PARTS };
static const char *const paths[N_PARTS] = {"processes.dem", "processes.fem",
                                           "processes.block"};

/* Keys whose value sets a model's size or work, and the largest value run. */
static const struct {
  const char *key;
  double max;
} budget[] = {{"cells", 6},     {"lugs", 8},     {"refine", 2},    {"nx", 24},
              {"ny", 24},       {"samples", 2048}, {"knots", 512}, {"count", 4096},
              {"power_iterations", 500}, {"scale", 0.02}, {"threads", 2},
              {"oversample", 4}, {"period_factor", 4}};
static const char *const writers[] = {"write", "save"};

/* 1 if the section stays within the budget (recursively). */
static int within_budget(const cJSON *node, const char *key) {
  if (cJSON_IsNumber(node) && key)
    for (size_t i = 0; i < sizeof budget / sizeof *budget; i++)
      if (strcmp(key, budget[i].key) == 0 && !(node->valuedouble <= budget[i].max))
        return 0;
  if (key)
    for (size_t i = 0; i < sizeof writers / sizeof *writers; i++)
      if (strcmp(key, writers[i]) == 0) return 0;
  for (const cJSON *c = node->child; c; c = c->next)
    if (!within_budget(c, cJSON_IsArray(node) ? key : c->string)) return 0;
  return 1;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  if (size < 1) return 0;
  int part = data[0] % N_PARTS;
  char *text = fuzz_text(data + 1, size - 1);
  if (!text) return 0;
  proto_err err = {{0}};
  cJSON *section = proto_json_parse(text, "section.json", &err);
  free(text);
  if (!section || !within_budget(section, NULL)) {
    cJSON_Delete(section);
    return 0;
  }
  if (part == P_DEM) {
    dem_model m;
    memset(&m, 0, sizeof m);
    if (dem_model_from_json(&m, section, paths[part], &err) == 0) {
      dem_state probe;
      if (dem_state_init(&m, &probe, 0, &err) == 0) dem_state_free(&probe);
    }
    dem_model_free(&m);
  } else if (part == P_FEM) {
    fem_config c;
    if (fem_config_read(section, paths[part], &c, &err) == 0 &&
        c.source != FEM_GEN_TREAD) { /* the tread mesh is seconds of work */
      fem_model md;
      if (fem_config_build(&c, &md, &err) == 0) fem_model_free(&md);
    }
  } else {
    blk_model m;
    blk_model_from_config(&m, section, paths[part], &err);
    blk_model_free(&m);
  }
  for (const char *c = err.msg; *c; c++)
    if (*c == 0x1b) __builtin_trap();
  if (getenv("COSIM_FUZZ_VERBOSE"))
    fprintf(stderr, "%s: %s\n", paths[part], err.msg[0] ? err.msg : "ok");
  cJSON_Delete(section);
  return 0;
}
