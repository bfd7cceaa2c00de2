/* error.c — proto's error helpers (proto_fail, proto_wrap, proto_sanitize), the
 * name check and the clock: the bottom of proto, which every other proto file
 * (proto.c, config.c, ...) calls and which calls none of them. */
#include "proto.h"

#include <stdarg.h>
#include <stdio.h>
#include <string.h>
#include <time.h>

/* ------------------------------------------------------------------ errors */

/* Length of the valid UTF-8 sequence at s (1..4), or 0 if it is not one or
 * encodes a C1 control character (U+0080..U+009F). */
static int utf8_len(const unsigned char *s) {
  const unsigned char c = s[0];
  int n = c >= 0xF0 && c <= 0xF4 ? 4 : c >= 0xE0 ? 3 : c >= 0xC2 ? 2 : 0;
  if (c >= 0xF5 || n == 0) return 0;
  for (int i = 1; i < n; i++)
    if ((s[i] & 0xC0) != 0x80) return 0;
  if (n == 2 && c == 0xC2 && s[1] < 0xA0) return 0;        /* C1 controls */
  if (n == 3 && c == 0xE0 && s[1] < 0xA0) return 0;        /* overlong */
  if (n == 3 && c == 0xED && s[1] >= 0xA0) return 0;       /* surrogates */
  if (n == 4 && c == 0xF0 && s[1] < 0x90) return 0;        /* overlong */
  if (n == 4 && c == 0xF4 && s[1] >= 0x90) return 0;       /* > U+10FFFF */
  return n;
}

void proto_sanitize(char *text) {
  unsigned char *s = (unsigned char *)text;
  while (*s) {
    if (*s < 0x80) {
      if ((*s < 0x20 && *s != '\n' && *s != '\t') || *s == 0x7F) *s = '?';
      s++;
      continue;
    }
    int n = utf8_len(s);
    if (n == 0) *s++ = '?';
    else s += n;
  }
}

int proto_fail(proto_err *err, const char *fmt, ...) {
  if (err) {
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(err->msg, sizeof err->msg, fmt, ap);
    va_end(ap);
    proto_sanitize(err->msg);
  }
  return -1;
}

int proto_wrap(proto_err *err, const char *fmt, ...) {
  if (!err) return -1;
  char prefix[512], old[sizeof err->msg];
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(prefix, sizeof prefix, fmt, ap);
  va_end(ap);
  memcpy(old, err->msg, sizeof old);
  snprintf(err->msg, sizeof err->msg, "%s: %s", prefix, old);
  proto_sanitize(err->msg);
  return -1;
}

/* ------------------------------------------------------------------ names */

static int name_char(char c) {
  return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') ||
         (c >= '0' && c <= '9') || c == '_' || c == '-';
}

int proto_name_check(const char *name, proto_name_kind kind, const char *what,
                     proto_err *err) {
  return proto_name_check_len(name, PROTO_NAME_LEN, kind, what, err);
}

int proto_name_check_len(const char *name, size_t cap, proto_name_kind kind,
                         const char *what, proto_err *err) {
  const char *why = NULL;
  size_t len = name ? strnlen(name, cap) : 0;
  if (len == 0) {
    return proto_fail(err, "%s: empty (a name has 1 to %zu characters of "
                      "A-Z a-z 0-9 _ -)", what, cap - 1);
  } else if (len >= cap) {
    why = "longer than the limit";
  } else {
    int seg = 0; /* characters in the current segment */
    for (size_t i = 0; i < len && !why; i++) {
      if (name_char(name[i])) {
        seg++;
      } else if (name[i] == '.' && kind == PROTO_NAME_DOTTED) {
        if (seg == 0) why = "has an empty segment (leading or double dot)";
        seg = 0;
      } else {
        why = name[i] == '/' ? "contains '/'" : "contains a character outside "
                                                "A-Z a-z 0-9 _ -";
      }
    }
    if (!why && seg == 0) why = "ends with a dot";
  }
  if (!why) return 0;
  char shown[PROTO_PATH_CAP]; /* one line: newlines and tabs shown as '?' */
  snprintf(shown, sizeof shown, "%.*s", (int)(cap - 1), name);
  for (char *c = shown; *c; c++)
    if (*c == '\n' || *c == '\t') *c = '?';
  return proto_fail(err, "%s '%s': %s (a name has 1 to %zu characters of "
                    "A-Z a-z 0-9 _ -%s)", what, shown, why, cap - 1,
                    kind == PROTO_NAME_DOTTED ? ", in segments joined by single dots"
                                              : "");
}

double proto_now(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}
