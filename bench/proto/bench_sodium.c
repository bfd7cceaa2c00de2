/* bench_sodium.c — the limit for CURVE on the wire (issue 25): libsodium's
 * own throughput on this machine for the ciphers CurveZMQ uses, and for what
 * libzmq 4.3 does around the cipher per frame.
 *
 * Data flow: one buffer of --bytes (default 540000: one 150 x 150 x 3 f8
 * surface array) -> each operation repeated for --seconds -> MB/s and
 * ms per MB on stdout, one line per operation (the minimum time of --rounds
 * rounds: the machine is shared).
 *
 * Operations:
 *   box_afternm        crypto_box_afternm (NaCl API: 32 zero bytes in front,
 *                      what libzmq's CURVE calls per frame; XSalsa20-Poly1305)
 *   box_open_afternm   its inverse (the receiving side)
 *   box_easy_afternm   crypto_box_easy_afternm (the same cipher, no padding)
 *   secretbox_easy     crypto_secretbox_easy (XSalsa20-Poly1305, secret key)
 *   zmq43_encode       what libzmq 4.3.4's curve_mechanism_base_t::encode
 *                      does for one frame: two zero-filled std::vector of
 *                      the frame's size, a copy in, crypto_box_afternm, a new
 *                      message of the frame's size and a copy out
 *   aes256gcm          crypto_aead_aes256gcm_encrypt (AES-NI + PCLMUL when
 *                      the CPU has them): what a data plane could use for
 *                      its large arrays instead of CurveZMQ's XSalsa20
 *   aes256gcm_decrypt  its inverse
 *   memcpy             one copy of the buffer (the memory bandwidth floor)
 *
 *   bench_sodium [--bytes N] [--seconds S] [--rounds R]
 */
#include <sodium.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define DEFAULT_BYTES 540000 /* 150 x 150 nodes x 3 doubles: bench's surface */
#define DEFAULT_SECONDS 0.05 /* per operation and round: ~100 operations, a stable rate */
#define DEFAULT_ROUNDS 20 /* the minimum of many short rounds: the machine is shared */

static double now(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

typedef struct {
  size_t n;
  unsigned char *plain, *box, *out, *key, *nonce;
} bufs;

static void op_box(bufs *b) {
  crypto_box_afternm(b->box, b->plain, b->n + crypto_box_ZEROBYTES, b->nonce, b->key);
}
static void op_box_open(bufs *b) {
  if (crypto_box_open_afternm(b->out, b->box, b->n + crypto_box_ZEROBYTES, b->nonce, b->key))
    fprintf(stderr, "bench_sodium: box_open_afternm failed\n");
}
static void op_box_easy(bufs *b) {
  crypto_box_easy_afternm(b->box, b->plain, b->n, b->nonce, b->key);
}
static void op_secretbox(bufs *b) { crypto_secretbox_easy(b->box, b->plain, b->n, b->nonce, b->key); }
static void op_memcpy(bufs *b) { memcpy(b->out, b->plain, b->n); }
static void op_gcm(bufs *b) {
  crypto_aead_aes256gcm_encrypt(b->box, NULL, b->plain, b->n, NULL, 0, NULL, b->nonce, b->key);
}
static void op_gcm_open(bufs *b) {
  if (crypto_aead_aes256gcm_decrypt(b->out, NULL, NULL, b->box, b->n + crypto_aead_aes256gcm_ABYTES,
                                    NULL, 0, b->nonce, b->key))
    fprintf(stderr, "bench_sodium: aes256gcm_decrypt failed\n");
}

/* libzmq 4.3.4 src/curve_mechanism_base.cpp encode(), in C */
static void op_zmq43(bufs *b) {
  size_t mlen = crypto_box_ZEROBYTES + 1 + b->n;
  unsigned char *pt = calloc(1, mlen), *bx = calloc(1, mlen);
  memcpy(pt + crypto_box_ZEROBYTES + 1, b->plain, b->n);
  crypto_box_afternm(bx, pt, mlen, b->nonce, b->key);
  unsigned char *msg = malloc(16 + mlen - crypto_box_BOXZEROBYTES);
  memcpy(msg + 16, bx + crypto_box_BOXZEROBYTES, mlen - crypto_box_BOXZEROBYTES);
  free(pt);
  free(bx);
  b->out[0] = msg[16]; /* keep the work */
  free(msg);
}

typedef struct {
  const char *name;
  void (*fn)(bufs *);
} op;

int main(int argc, char **argv) {
  size_t n = DEFAULT_BYTES;
  double seconds = DEFAULT_SECONDS;
  int rounds = DEFAULT_ROUNDS;
  for (int i = 1; i + 1 < argc; i += 2) {
    if (strcmp(argv[i], "--bytes") == 0) n = strtoull(argv[i + 1], NULL, 10);
    else if (strcmp(argv[i], "--seconds") == 0) seconds = atof(argv[i + 1]);
    else if (strcmp(argv[i], "--rounds") == 0) rounds = atoi(argv[i + 1]);
    else {
      fprintf(stderr, "bench_sodium: unknown option '%s'\n", argv[i]);
      return 1;
    }
  }
  if (n == 0 || seconds <= 0 || rounds < 1) {
    fprintf(stderr, "bench_sodium: --bytes, --seconds and --rounds must be positive\n");
    return 1;
  }
  if (sodium_init() < 0) {
    fprintf(stderr, "bench_sodium: sodium_init failed\n");
    return 1;
  }
  size_t cap = n + crypto_box_ZEROBYTES + crypto_box_MACBYTES;
  bufs b = {n, calloc(1, cap), calloc(1, cap), calloc(1, cap), calloc(1, crypto_box_BEFORENMBYTES),
            calloc(1, crypto_box_NONCEBYTES)};
  if (!b.plain || !b.box || !b.out || !b.key || !b.nonce) return 1;
  randombytes_buf(b.plain + crypto_box_ZEROBYTES, n);
  unsigned char pk[crypto_box_PUBLICKEYBYTES], sk[crypto_box_SECRETKEYBYTES];
  crypto_box_keypair(pk, sk);
  if (crypto_box_beforenm(b.key, pk, sk) != 0) return 1;
  op_box(&b); /* a valid box for box_open, which comes next and leaves it */
  const op ops[] = {{"box_afternm", op_box}, {"box_open_afternm", op_box_open},
                    {"box_easy_afternm", op_box_easy}, {"secretbox_easy", op_secretbox},
                    {"zmq43_encode", op_zmq43}, {"memcpy", op_memcpy}};
  const op gcm_ops[] = {{"aes256gcm", op_gcm}, {"aes256gcm_decrypt", op_gcm_open}};
  const int gcm = crypto_aead_aes256gcm_is_available();
  printf("# bytes %zu, min of %d rounds of %.2f s; libsodium %s\n", n, rounds, seconds,
         sodium_version_string());
  printf("%-18s %10s %10s\n", "operation", "MB/s", "ms/MB");
  const size_t nops = sizeof ops / sizeof ops[0], ngcm = gcm ? 2 : 0;
  for (size_t o = 0; o < nops + ngcm; o++) {
    const op *it = o < nops ? &ops[o] : &gcm_ops[o - nops];
    if (o == nops) op_gcm(&b); /* a valid ciphertext for the decrypt after it */
    double best = 1e30;
    for (int r = 0; r < rounds; r++) {
      long reps = 0;
      double t0 = now(), t;
      do {
        it->fn(&b);
        reps++;
      } while ((t = now() - t0) < seconds);
      if (t / reps < best) best = t / reps;
    }
    double mb = n / 1e6;
    printf("%-18s %10.0f %10.3f\n", it->name, mb / best, 1e3 * best / mb);
  }
  if (!gcm) printf("aes256gcm          (not available on this CPU: no AES-NI/PCLMUL)\n");
  free(b.plain);
  free(b.box);
  free(b.out);
  free(b.key);
  free(b.nonce);
  return 0;
}
