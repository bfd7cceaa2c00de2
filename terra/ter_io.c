/* ter_io.c — the test records (ter_series) and their CSV form: the one reader
 * and writer of that format (terra.h). */
#include "terra/terra.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>

#define TER_LINE 4096

int ter_series_init(ter_series *t, int ncol, const char *const *cols, proto_err *err) {
  memset(t, 0, sizeof *t);
  if (ncol < 1 || ncol > TER_MAX_COLS) return proto_fail(err, "series: %d columns (1..%d)", ncol, TER_MAX_COLS);
  t->ncol = ncol;
  for (int c = 0; c < ncol; c++) snprintf(t->col[c], TER_NAME, "%s", cols[c]);
  return 0;
}

void ter_series_free(ter_series *t) {
  free(t->row);
  memset(t, 0, sizeof *t);
}

int ter_series_add(ter_series *t, const double *row, proto_err *err) {
  if (t->n == t->cap) {
    int cap = t->cap ? 2 * t->cap : 256;
    double *r = realloc(t->row, sizeof *r * (size_t)cap * t->ncol);
    if (!r) return proto_fail(err, "out of memory (series of %d rows)", cap);
    t->row = r;
    t->cap = cap;
  }
  memcpy(t->row + (size_t)t->n * t->ncol, row, sizeof *row * t->ncol);
  t->n++;
  return 0;
}

int ter_series_meta(ter_series *t, const char *key, const char *fmt, ...) {
  int i;
  for (i = 0; i < t->nmeta; i++)
    if (strcmp(t->meta_key[i], key) == 0) break;
  if (i == TER_MAX_META) return -1;
  if (i == t->nmeta) t->nmeta++;
  snprintf(t->meta_key[i], TER_NAME, "%s", key);
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(t->meta_val[i], sizeof t->meta_val[i], fmt, ap);
  va_end(ap);
  return 0;
}

int ter_series_col(const ter_series *t, const char *name) {
  for (int c = 0; c < t->ncol; c++)
    if (strcmp(t->col[c], name) == 0) return c;
  return -1;
}

const char *ter_series_get_meta(const ter_series *t, const char *key) {
  for (int i = 0; i < t->nmeta; i++)
    if (strcmp(t->meta_key[i], key) == 0) return t->meta_val[i];
  return NULL;
}

int ter_series_meta_num(const ter_series *t, const char *key, double *out, proto_err *err) {
  const char *v = ter_series_get_meta(t, key);
  if (!v) return proto_fail(err, "record lacks '# %s: ...'", key);
  char *end;
  errno = 0;
  *out = strtod(v, &end);
  if (end == v || errno || !isfinite(*out)) return proto_fail(err, "'# %s: %s' is not a number", key, v);
  return 0;
}

int ter_series_write(const ter_series *t, const char *path, proto_err *err) {
  FILE *f = fopen(path, "w");
  if (!f) return proto_fail(err, "%s: cannot write (%s)", path, strerror(errno));
  for (int i = 0; i < t->nmeta; i++) fprintf(f, "# %s: %s\n", t->meta_key[i], t->meta_val[i]);
  for (int c = 0; c < t->ncol; c++) fprintf(f, "%s%s", c ? "," : "", t->col[c]);
  fputc('\n', f);
  for (int r = 0; r < t->n; r++)
    for (int c = 0; c < t->ncol; c++)
      fprintf(f, "%.10g%c", t->row[(size_t)r * t->ncol + c], c + 1 < t->ncol ? ',' : '\n');
  if (fclose(f) != 0) return proto_fail(err, "%s: write failed", path);
  return 0;
}

/* Splits a header or data line at commas (in place); returns the count. */
static int split(char *line, char **field, int cap) {
  int n = 0;
  char *p = line;
  while (n < cap) {
    field[n++] = p;
    char *c = strchr(p, ',');
    if (!c) break;
    *c = 0;
    p = c + 1;
  }
  return n;
}

static void chomp(char *s) {
  size_t l = strlen(s);
  while (l && (s[l - 1] == '\n' || s[l - 1] == '\r' || s[l - 1] == ' ')) s[--l] = 0;
}

int ter_series_read(ter_series *t, const char *path, proto_err *err) {
  memset(t, 0, sizeof *t);
  FILE *f = fopen(path, "r");
  if (!f) return proto_fail(err, "%s: cannot open (%s)", path, strerror(errno));
  char line[TER_LINE];
  int lineno = 0, rc = 0;
  double row[TER_MAX_COLS];
  while (!rc && fgets(line, sizeof line, f)) {
    lineno++;
    chomp(line);
    if (line[0] == 0) continue;
    if (line[0] == '#') {
      char *colon = strchr(line, ':');
      if (!colon) continue;
      *colon = 0;
      const char *key = line + 1, *val = colon + 1;
      while (*key == ' ') key++;
      while (*val == ' ') val++;
      if (t->nmeta < TER_MAX_META) ter_series_meta(t, key, "%s", val);
      continue;
    }
    char *field[TER_MAX_COLS + 1];
    int nf = split(line, field, TER_MAX_COLS + 1);
    if (t->ncol == 0) { /* header */
      if (nf > TER_MAX_COLS) rc = proto_fail(err, "%s:%d: more than %d columns", path, lineno, TER_MAX_COLS);
      t->ncol = nf;
      for (int c = 0; c < nf && !rc; c++) snprintf(t->col[c], TER_NAME, "%s", field[c]);
      continue;
    }
    if (nf != t->ncol) {
      rc = proto_fail(err, "%s:%d: %d values, the header has %d columns", path, lineno, nf, t->ncol);
      break;
    }
    for (int c = 0; c < nf; c++) {
      char *end;
      row[c] = strtod(field[c], &end);
      if (end == field[c] || *end != 0) {
        rc = proto_fail(err, "%s:%d: column '%s': '%s' is not a number", path, lineno, t->col[c], field[c]);
        break;
      }
    }
    if (!rc) rc = ter_series_add(t, row, err);
  }
  fclose(f);
  if (!rc && t->ncol == 0) rc = proto_fail(err, "%s: no header line", path);
  if (rc) ter_series_free(t);
  return rc;
}
