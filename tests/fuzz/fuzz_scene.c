/* fuzz_scene — the scene loader: proto_json_parse (duplicate keys), the
 * --set overrides, and every core-key reader of cpl_scene_from_json. Input:
 * optional leading lines "--set KEY=VALUE", then the JSON text. */
#include "coupler/coupler.h"
#include "fuzz.h"

#define MAX_SETS 8

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  char *text = fuzz_text(data, size);
  if (!text) return 0;
  char *sets[MAX_SETS];
  int nset = 0;
  char *json = text;
  while (nset < MAX_SETS && strncmp(json, "--set ", 6) == 0) {
    char *nl = strchr(json, '\n');
    if (!nl) break;
    *nl = 0;
    sets[nset++] = json + 6;
    json = nl + 1;
  }
  proto_err err = {{0}};
  cJSON *root = proto_json_parse(json, "fuzz.json", &err);
  if (root) {
    cpl_scene s;
    if (cpl_scene_from_json(&s, root, "fuzz.json", nset, sets, &err) == 0) {
      proto_role roles[CPL_MAX_PROCS];
      for (int i = 0; i < s.nprocs; i++) roles[i] = (proto_role)(i % PROTO_N_ROLES);
      cpl_check_roles(&s, roles, &err);
      cJSON *sec = s.nprocs ? cpl_section_for_participant(&s.procs[0]) : NULL;
      cJSON_Delete(sec);
    }
    cpl_scene_free(&s);
  }
  for (const char *c = err.msg; *c; c++)
    if (*c == 0x1b) __builtin_trap();
  free(text);
  return 0;
}
