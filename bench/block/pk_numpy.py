#!/usr/bin/python3
"""An independent implementation to compare the block's matrix-free solver
with: rigid rough contact on the free (zero-padded) elastic half-space by
Polonsky & Keer's constrained conjugate gradients (Wear 231 (1999) 206), in
numpy. Nothing is shared with contact_block: Love's coefficients from
Johnson's printed log form (eq. 3.25), numpy's FFT, the algorithm as in the
paper (two products per iteration, no preconditioning). The road is given by
a formula both codes evaluate (bench_scale's `bumpy` case): a paraboloid of
radius R with a bump pattern A cos(2πx/λ) cos(2πy/λ) on it.

    pk_numpy.py N DX R A LAMBDA APPROACH  ->  JSON: force, contacts, iterations, seconds
"""
import json
import sys
import time

import numpy as np


def love(x, y, a, b, Es):
    """Centre displacement per unit force spread over the rectangle 2a x 2b
    (Johnson 1985 eq. 3.25, log form)."""
    xp, xm, yp, ym = x + a, x - a, y + b, y - b
    rpp, rpm, rmp, rmm = np.hypot(xp, yp), np.hypot(xp, ym), np.hypot(xm, yp), np.hypot(xm, ym)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = (xp * np.log((yp + rpp) / (ym + rpm)) + yp * np.log((xp + rpp) / (xm + rmp)) +
             xm * np.log((ym + rmm) / (yp + rmp)) + ym * np.log((xm + rmm) / (xp + rpm)))
    return s / (4 * a * b) / (np.pi * Es)


def main():
    n = int(sys.argv[1])
    dx, R, A, lam, approach = (float(v) for v in sys.argv[2:7])
    dy = dx
    nx = ny = n
    E, nu = 10e6, 0.3
    Es = E / (1 - nu * nu)
    c = (np.arange(n) + 0.5 - 0.5 * n) * dx
    X0, Y0 = np.meshgrid(c, c)
    z = -(X0 ** 2 + Y0 ** 2) / (2 * R) + A * np.cos(2 * np.pi * X0 / lam) * np.cos(2 * np.pi * Y0 / lam)
    t0 = time.process_time()
    # kernel on the 2n box, offsets wrapped (Hockney)
    i = np.arange(2 * nx)
    j = np.arange(2 * ny)
    ii = np.where(i < nx, i, i - 2 * nx)
    jj = np.where(j < ny, j, j - 2 * ny)
    X, Y = np.meshgrid(ii * dx, jj * dy)
    K = love(X, Y, dx / 2, dy / 2, Es)
    K[ny, :] = 0  # the offset ±n is outside the grid
    K[:, nx] = 0
    Kh = np.fft.rfft2(K)

    def conv(p):
        q = np.zeros((2 * ny, 2 * nx))
        q[:ny, :nx] = p
        return np.fft.irfft2(np.fft.rfft2(q) * Kh, s=q.shape)[:ny, :nx]

    h = z + approach  # interference of the rigid road (> 0: overlap)
    p = np.zeros_like(h)
    t = np.zeros_like(h)
    G_old, delta, it = 1.0, 0, 0
    tol = 1e-10 * approach
    while it < 20000:
        it += 1
        u = conv(p)
        g = u - h  # gap
        S = p > 0
        if not S.any():
            S = g < 0
        G = np.sum(g[S] ** 2)
        t = np.where(S, g + (delta * G / G_old) * t, 0.0)
        r = conv(t)
        den = np.sum(r[S] * t[S])
        tau = np.sum(g[S] * t[S]) / den if den > 0 else 0.0
        p = np.where(S, p - tau * t, p)
        p[p < 0] = 0
        nc = (p == 0) & (g < 0)
        if nc.any():
            p[nc] -= tau * g[nc]
            delta = 0
        else:
            delta = 1
        G_old = G
        gap = conv(p) - h
        viol = max(np.abs(gap[p > 0]).max() if (p > 0).any() else 0, max(0, -gap[p == 0].min()))
        if viol < tol:
            break
    sec = time.process_time() - t0
    print(json.dumps({"force": float(p.sum()), "contacts": int((p > 0).sum()), "iterations": it,
                      "seconds": sec, "violation": float(viol)}))


if __name__ == "__main__":
    main()
