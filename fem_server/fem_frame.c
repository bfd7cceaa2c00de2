/* fem_frame.c — the moving (rim) frame the tread is solved in.
 *
 * fem_server writes a material point X of the tread as
 *     x(t) = R(t) (X + u(t)) + c(t),   dR/dt = R [Omega]x,
 * with Omega the angular velocity in frame components (Omega = R^T omega).
 * Differentiating twice, with r = X + u:
 *     dx/dt   = R (du/dt + Omega x r) + dc/dt
 *     d2x/dt2 = R (d2u/dt2 + 2 Omega x du/dt + dOmega/dt x r
 *                  + Omega x (Omega x r)) + d2c/dt2
 * (Goldstein, Classical Mechanics, 3rd ed., §4.10). Newton's law rho d2x/dt2 =
 * div sigma + rho g, rotated into the frame (the linear strain of u is that
 * of the rotated body, so K is unchanged), becomes seed 000 eq. 28 with the
 * extra body force per unit mass
 *     -[acc + alpha x r + Omega x (Omega x r) + 2 Omega x du/dt],
 *     acc = R^T d2c/dt2, alpha = dOmega/dt = R^T d(omega)/dt
 * (origin acceleration, Euler, centrifugal, Coriolis). The Galerkin form with
 * the lumped mass gives these nodal forces with m_a in place of rho. This
 * file holds the position-dependent part; the Coriolis term is integrated by
 * fem_explicit.c. */
#include "fem_server/fem.h"
#include "fem_server/fem_internal.h"

#include <string.h>

void fem_frame_point_acc(const fem_frame *fr, const double r[3], double a[3]) {
  const double *w = fr->omega, *al = fr->alpha;
  double wr[3];
  fem_cross(w, r, wr);
  double cen[3], eul[3];
  fem_cross(w, wr, cen); /* Omega x (Omega x r) = -(centripetal pull) */
  fem_cross(al, r, eul);
  for (int d = 0; d < 3; d++) a[d] = fr->acc[d] + eul[d] + cen[d];
}

int fem_frame_rotating(const fem_frame *fr) {
  for (int d = 0; d < 3; d++)
    if (fr->omega[d] != 0 || fr->alpha[d] != 0) return 1;
  return 0;
}

void fem_load_frame(const fem_model *md, const fem_frame *fr, const double *u, double *b) {
  for (int32_t n = 0; n < md->mesh.n_nodes; n++) {
    double r[3], a[3];
    for (int d = 0; d < 3; d++) r[d] = md->mesh.x[3 * (size_t)n + d] + (u ? u[3 * (size_t)n + d] : 0);
    fem_frame_point_acc(fr, r, a);
    for (int d = 0; d < 3; d++) b[3 * (size_t)n + d] -= md->mass[n] * a[d];
  }
}

/* y = R^T x for a row-major R */
static void rot_t(const double *R, const double *x, double *y) {
  for (int a = 0; a < 3; a++) y[a] = R[a] * x[0] + R[3 + a] * x[1] + R[6 + a] * x[2];
}

void fem_frame_from_rim(fem_state *st, const double R[9], const double w[3], const double v[3],
                        double span) {
  fem_frame *fr = &st->frame;
  rot_t(R, w, fr->omega);
  double dw[3] = {0, 0, 0}, dv[3] = {0, 0, 0};
  if (st->rim_has_prev && span > 0)
    for (int d = 0; d < 3; d++) {
      dw[d] = (w[d] - st->rim_w_prev[d]) / span;
      dv[d] = (v[d] - st->rim_v_prev[d]) / span;
    }
  /* d(omega_world)/dt = R dOmega/dt (omega x omega = 0), so alpha = R^T d(omega)/dt */
  rot_t(R, dw, fr->alpha);
  rot_t(R, dv, fr->acc);
  memcpy(st->rim_w_prev, w, sizeof st->rim_w_prev);
  memcpy(st->rim_v_prev, v, sizeof st->rim_v_prev);
  st->rim_has_prev = 1;
}
