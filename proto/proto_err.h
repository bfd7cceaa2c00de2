/* proto_err.h — proto's errors: proto_err and the helpers that fill it.
 * Part of proto.h, the one public header: include "proto/proto.h", not this. */
#ifndef COSIM_PROTO_ERR_H
#define COSIM_PROTO_ERR_H
#ifndef COSIM_PROTO_H
#error "include proto/proto.h, not proto_err.h"
#endif

/* ------------------------------------------------------------------ errors */

typedef struct proto_err {
  char msg[1024];
} proto_err;

/* Formats into err->msg (if err is not NULL) and returns -1, so callers can
 * `return proto_fail(err, "...")`. */
int proto_fail(proto_err *err, const char *fmt, ...)
    __attribute__((format(printf, 2, 3)));
/* Prefixes the existing message: "context: <old message>". Returns -1. */
int proto_wrap(proto_err *err, const char *fmt, ...)
    __attribute__((format(printf, 2, 3)));
/* Makes text safe to print on a terminal, in place: control characters
 * (C0 but newline and tab, DEL, C1) and bytes that are not UTF-8 become
 * '?'. proto_fail and proto_wrap apply it to every message, so names and
 * messages that came from a file or the wire never reach a terminal as
 * escape sequences. */
void proto_sanitize(char *text);

#endif
