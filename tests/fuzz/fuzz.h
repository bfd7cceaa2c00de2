/* fuzz.h — shared helpers of the libFuzzer harnesses (tests/fuzz/README.md).
 * Each harness defines LLVMFuzzerTestOneInput; built with -DCOSIM_FUZZ=ON
 * (clang) it is a libFuzzer binary, otherwise replay.c gives it a main()
 * that runs the corpus files through it (the regression test). */
#ifndef COSIM_FUZZ_H
#define COSIM_FUZZ_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

/* A copy of data with a NUL appended (text parsers). */
static inline char *fuzz_text(const uint8_t *data, size_t size) {
  char *t = malloc(size + 1);
  if (!t) return NULL;
  if (size) memcpy(t, data, size);
  t[size] = 0;
  return t;
}

/* The scratch file of this process, removed when it exits. */
static char fuzz_scratch[256];
static inline void fuzz_scratch_remove(void) {
  if (fuzz_scratch[0]) unlink(fuzz_scratch);
}

/* A per-process scratch file (in /dev/shm when there is one) holding data;
 * returns its path (static storage), removed at exit. The file readers under
 * test take paths. */
static inline const char *fuzz_file(const uint8_t *data, size_t size,
                                    const char *suffix) {
  char *path = fuzz_scratch;
  const char *dir = access("/dev/shm", W_OK) == 0 ? "/dev/shm" : "/tmp";
  if (!path[0]) atexit(fuzz_scratch_remove);
  else if (!strstr(path, suffix)) unlink(path); /* another suffix: the old one goes */
  snprintf(path, sizeof fuzz_scratch, "%s/cosim-fuzz-%d%s", dir, (int)getpid(), suffix);
  FILE *f = fopen(path, "wb");
  if (!f) return NULL;
  size_t w = size ? fwrite(data, 1, size, f) : 0;
  if (fclose(f) != 0 || w != size) return NULL;
  return path;
}

/* Splits data at every occurrence of sep into at most max pieces (the last
 * piece takes the rest); returns the count. Pieces point into data. */
static inline int fuzz_split(const uint8_t *data, size_t size, const char *sep,
                             int max, const uint8_t **piece, size_t *len) {
  size_t n = strlen(sep), start = 0;
  int k = 0;
  for (size_t i = 0; k < max - 1 && i + n <= size;) {
    if (memcmp(data + i, sep, n) == 0) {
      piece[k] = data + start;
      len[k++] = i - start;
      i += n;
      start = i;
    } else {
      i++;
    }
  }
  piece[k] = data + start;
  len[k++] = size - start;
  return k;
}

#define FUZZ_MAX_FRAMES 256 /* more than any harness asks for (PROTO_MAX_ARRAYS + 4) */

/* The frames of a message: data split at sep (fuzz_split), each piece copied
 * into a buffer of its exact size (at least 1 byte), so that a read past a
 * frame is an ASan error; returns their count. Free with fuzz_frames_free. */
static inline int fuzz_frames(const uint8_t *data, size_t size, const char *sep, int max,
                              void **frame, size_t *len) {
  const uint8_t *piece[FUZZ_MAX_FRAMES];
  int n = fuzz_split(data, size, sep, max < FUZZ_MAX_FRAMES ? max : FUZZ_MAX_FRAMES, piece, len);
  for (int i = 0; i < n; i++) {
    frame[i] = malloc(len[i] ? len[i] : 1);
    if (len[i]) memcpy(frame[i], piece[i], len[i]);
  }
  return n;
}

static inline void fuzz_frames_free(void **frame, int n) {
  for (int i = 0; i < n; i++) free(frame[i]);
}

#endif
