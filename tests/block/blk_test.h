/* blk_test.h — tiny check macros for the block tests. */
#ifndef BLK_TEST_H
#define BLK_TEST_H
#include <stdio.h>
#include <stdlib.h>

static int blk_test_failures = 0;
#define CHECK(cond, ...)                                              \
  do {                                                                \
    if (!(cond)) {                                                    \
      fprintf(stderr, "FAIL %s:%d: %s: ", __FILE__, __LINE__, #cond); \
      fprintf(stderr, __VA_ARGS__);                                   \
      fprintf(stderr, "\n");                                          \
      blk_test_failures++;                                            \
    }                                                                 \
  } while (0)
/* Tests declare `static proto_err err;` and pass &err to the call. */
#define OK(call)                                                      \
  do {                                                                \
    if ((call) != 0) {                                                \
      fprintf(stderr, "FAIL %s:%d: %s: %s\n", __FILE__, __LINE__, #call, err.msg); \
      exit(1);                                                        \
    }                                                                 \
  } while (0)
#endif
