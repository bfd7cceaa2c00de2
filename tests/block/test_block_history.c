/* The partitioned FFT history (several levels of growing blocks, issue 5
 * speed work) on a long Green's function and a small rectangular block:
 *  - the layer displacement equals the plain convolution of the recorded
 *    forces (eq. 4–5) to round-off, at steps inside every level and after
 *    the force ring has wrapped;
 *  - FFT and direct history agree to 1e-10 relative;
 * both for the synthetic layer (even in the offset: real spectra; separable,
 * so the FFT history runs on packed elements) and for an asymmetric copy of
 * it (complex spectra, non-symmetric compliance); and, for the synthetic
 * layer, the separable history (ring of forces, one spatial product) equals
 * the plain convolution too. */
#include <math.h>
#include <string.h>

#include "blk_test.h"
#include "contact_block/blk.h"

static proto_err err;

enum { NX = 7, NY = 5, M = NX * NY, Q = 600, NS = 700 };

static void scene(blk_model *m, int asym) {
  OK(blk_model_init(m, NX, NY, 1e-3, 1.2e-3, &err));
  OK(blk_road_random(m, 1e-5, 3, &err));
  OK(blk_springs_stiffening(m, 2e5, 2e-5, 0.5, 7, 5e-4, 33, &err));
  blk_synth sy = {.E = 25e6, .nu = 0.49, .rate = 51200, .Q = Q, .f_mode = 800,
                  .zeta = 0.02, .beta = 0.25, .tau_fast = 2e-5, .point_sampling = 0};
  OK(blk_green_synthetic(m, &sy, &err));
  m->solver.method = BLK_NR_PLAIN;
  m->solver.max_iter = 50;
  m->solver.tail_tol = 0; /* all Q samples, as the plain convolution */
  if (!asym) return;
  /* tilt g over the offsets (not a layer, a test of the general path) */
  OK(blk_green_materialize(m, &err));
  for (int k = 0; k < m->Q; k++)
    for (int dj = 0; dj < m->noy; dj++)
      for (int di = 0; di < m->nox; di++)
        m->g[((size_t)k * m->noy + dj) * m->nox + di] *=
            (1 + 0.3 * (di - (NX - 1)) / NX) * (1 + 0.2 * (dj - (NY - 1)) / NY);
  for (int o = 0; o < m->nox * m->noy; o++) {
    double sum = 0;
    for (int k = 0; k < m->Q; k++) sum += m->g[(size_t)k * m->nox * m->noy + o];
    m->g_static[o] = sum / m->rate;
  }
}

static double max_abs(const double *a, int n) {
  double x = 0;
  for (int i = 0; i < n; i++) x = fmax(x, fabs(a[i]));
  return x;
}

static void check(int asym) {
  static double Fh[3][NS * M], del[3][M];
  blk_model m;
  scene(&m, asym);
  double worst_conv = 0, worst_sep = 0;
  for (int h = 0; h < (asym ? 2 : 3); h++) {
    m.solver.history = h == 2 ? BLK_HIST_SEPARABLE : h ? BLK_HIST_DIRECT : BLK_HIST_FFT;
    blk_state s;
    OK(blk_state_create(&m, &s, &err));
    for (int n = 1; n <= NS; n++) {
      /* load, hold, partial unload: forces change over the whole record */
      const double d = 1e-4 * (n < 300 ? n / 300.0 : n < 450 ? 1.0 : 1.0 - (n - 450) / 600.0);
      OK(blk_step(&m, &s, d, &err));
      CHECK(s.converged, "step %d not converged (residual %g)", n, s.residual);
      memcpy(Fh[h] + (size_t)(n - 1) * M, s.force, sizeof(double) * M);
      if (h != 1 && (n % 50 == 0 || n == 9 || n == 33 || n == 129 || n == Q + 1)) {
        double ref[M];
        blk_layer_displacement_ref(&m, Fh[h], n, ref);
        double dmax = 0;
        for (int e = 0; e < M; e++) dmax = fmax(dmax, fabs(s.d_el[e] - ref[e]));
        if (h == 0) worst_conv = fmax(worst_conv, dmax / max_abs(ref, M));
        else worst_sep = fmax(worst_sep, dmax / max_abs(ref, M));
      }
    }
    memcpy(del[h], s.d_el, sizeof del[h]);
    blk_state_free(&s);
  }
  const char *what = asym ? "asymmetric g" : "synthetic g";
  printf("%s: d_el vs plain convolution (FFT history, %d steps, Q = %d): worst rel %.2e\n",
         what, NS, Q, worst_conv);
  CHECK(worst_conv <= 1e-12, "%s: d_el differs from the convolution by %.3e rel", what,
        worst_conv);
  if (!asym) {
    printf("%s: d_el vs plain convolution (separable history): worst rel %.2e\n", what,
           worst_sep);
    CHECK(worst_sep <= 1e-12, "separable history differs from the convolution by %.3e",
          worst_sep);
  }
  double fd = 0, dd = 0;
  for (int i = 0; i < NS * M; i++) fd = fmax(fd, fabs(Fh[0][i] - Fh[1][i]));
  for (int e = 0; e < M; e++) dd = fmax(dd, fabs(del[0][e] - del[1][e]));
  const double fref = max_abs(Fh[1], NS * M), dref = max_abs(del[1], M);
  printf("%s: FFT vs direct: element forces rel %.2e, d_el rel %.2e (max force %.3g N)\n",
         what, fd / fref, dd / dref, fref);
  CHECK(fref > 0.1, "%s: scene carries no load: max element force %g N", what, fref);
  CHECK(fd <= 1e-10 * fref, "%s: FFT/direct force mismatch %.2e rel", what, fd / fref);
  CHECK(dd <= 1e-10 * dref, "%s: FFT/direct d_el mismatch %.2e rel", what, dd / dref);
  blk_model_free(&m);
}

int main(void) {
  check(0);
  check(1);
  return cosim_test_done("test_block_history");
}
