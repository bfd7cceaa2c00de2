/* stub.h — what the stubs share. A stub accepts the whole section of the
 * solver it stands in for (README "Swapping a solver for a stub"): it reads
 * its own keys and names the others once in its log instead of refusing
 * them, so one --set processes.<p>.exec=<stub> swaps any scene's solver. */
#ifndef COSIM_STUB_H
#define COSIM_STUB_H

#include <stdio.h>

#include "proto/proto.h"

/* Ends reading a stub's section: logs the keys it did not use. */
static inline int stub_cfg_end(const proto_cfg *c, const char *stub) {
  char keys[600];
  int n = proto_cfg_unused(c, keys, sizeof keys);
  if (n > 0)
    fprintf(stderr, "%s: %s: ignoring %d key%s of the solver it stands in for: %s\n",
            stub, c->path[0] ? c->path : "section", n, n > 1 ? "s" : "", keys);
  return 0;
}

/* State callbacks of a stub whose outputs depend only on its inputs and t:
 * it has no changing state, so the empty state is its whole state. */
static inline int stub_state_none_save(void *user, proto_msg *state, proto_err *err) {
  (void)user, (void)state, (void)err;
  return 0;
}
static inline int stub_state_none_load(void *user, const proto_msg *state,
                                       proto_err *err) {
  (void)user, (void)state, (void)err;
  return 0;
}

#endif
