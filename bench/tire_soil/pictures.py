"""Headless pictures like seed 000 fig. 16-18 from a tyre run's snapshots:
grains coloured by their velocity along the travel (x), the tread's elements
by the vertical strain eps33 (zz), seen from the side (x-z), the back (y-z)
and the top (x-y).

    PYTHONPATH=python /usr/bin/python3 bench/tire_soil/pictures.py RUN_DIR OUT.png [STEP]

STEP: a snapshot step (default: the last). Grains within 0.35 m (along x) of
the axle, drawn as discs of their radius, nearer ones over farther ones."""
import sys

import numpy as np

from cosim import Results

WINDOW_M = 0.35    # grains drawn within this distance of the rim along x
SLICE_M = 0.03     # the back view: grains within this distance of the axle's x
ABOVE_M = 0.09     # side and back views: the tread up to this height above the grains
EPS33 = 5          # Tensor6 order xx xy xz yy yz zz (fem_server README)


def discs(ax, x, y, r, c, norm, cmap):
    from matplotlib.collections import EllipseCollection
    ec = EllipseCollection(2 * r, 2 * r, np.zeros_like(r), units="xy", offsets=np.c_[x, y],
                           offset_transform=ax.transData, cmap=cmap, norm=norm, linewidths=0)
    ec.set_array(c)
    ax.add_collection(ec)
    return ec


def main():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import Normalize
    run, out = sys.argv[1], sys.argv[2]
    with Results(run) as r:
        names = {p: r.scene["processes"][p]["exec"] for p in r.scene["processes"]}
        soil = next(p for p, e in names.items() if "dem" in e)
        tyre = next(p for p, e in names.items() if "fem" in e)
        step = int(sys.argv[3]) if len(sys.argv) > 3 else r.steps(soil)[-1]
        g = r.snapshot(soil, step)
        t = r.snapshot(tyre, step)
        cells = r.mesh(tyre)["cells"]
        dt = r.scene["time"]["dt"]
        width = r.scene["processes"][tyre].get("mesh", {}).get("width", 0.165)
    xt = t["x"]
    centre = 0.5 * (xt.min(axis=0) + xt.max(axis=0))
    eps = t["strain"][:, EPS33]
    cen = xt[cells].mean(axis=1)
    gx, gv, gr = g["x"], g["v"][:, 0], g["r"]
    near = np.abs(gx[:, 0] - centre[0]) < WINDOW_M
    top = (gx[near, 2] + gr[near]).max()
    vlim = max(1e-3, np.percentile(np.abs(gv[near]), 99.5))
    low = cen[:, 2] < top + ABOVE_M
    elim = max(1e-6, np.percentile(np.abs(eps[low]), 99))
    vn, en = Normalize(-vlim, vlim), Normalize(-elim, elim)
    fig = plt.figure(figsize=(14, 9))
    gs = fig.add_gridspec(2, 2, height_ratios=[1, 1.3])
    side, back, above = fig.add_subplot(gs[0, :]), fig.add_subplot(gs[1, 0]), fig.add_subplot(gs[1, 1])
    # side: the grains under the tread's width, the far ones first
    m = near & (np.abs(gx[:, 1] - centre[1]) < width / 2)
    o = np.argsort(-gx[m, 1])
    pts = discs(side, gx[m, 0][o], gx[m, 2][o], gr[m][o], gv[m][o], vn, "coolwarm")
    side.scatter(cen[low, 0], cen[low, 2], c=eps[low], s=2, cmap="viridis", norm=en, linewidths=0)
    side.set_xlim(centre[0] - WINDOW_M, centre[0] + WINDOW_M)
    side.set_ylim(0, top + ABOVE_M)
    side.set_title("side (x–z): grains under the tread's width", fontsize=9)
    # back: a slice through the axle
    m = np.abs(gx[:, 0] - centre[0]) < SLICE_M
    o = np.argsort(gx[m, 0])
    discs(back, gx[m, 1][o], gx[m, 2][o], gr[m][o], gv[m][o], vn, "coolwarm")
    sl = low & (np.abs(cen[:, 0] - centre[0]) < SLICE_M)
    te = back.scatter(cen[sl, 1], cen[sl, 2], c=eps[sl], s=3, cmap="viridis", norm=en, linewidths=0)
    back.set_xlim(centre[1] - 2 * width, centre[1] + 2 * width)
    back.set_ylim(0, top + ABOVE_M)
    back.set_title(f"back (y–z): slice |x − x_axle| < {SLICE_M} m", fontsize=9)
    # top: every grain near the tyre, the high ones last (the rut), no tread
    o = np.argsort(gx[near, 2])
    discs(above, gx[near, 0][o], gx[near, 1][o], gr[near][o], gv[near][o], vn, "coolwarm")
    above.set_xlim(centre[0] - WINDOW_M, centre[0] + WINDOW_M)
    above.set_ylim(centre[1] - 2 * width, centre[1] + 2 * width)
    above.set_title("top (x–y): the grains (tread not drawn)", fontsize=9)
    for ax, (a, b) in ((side, "xz"), (back, "yz"), (above, "xy")):
        ax.set_aspect("equal")
        ax.set_xlabel(a + " (m)")
        ax.set_ylabel(b + " (m)")
    fig.colorbar(pts, ax=[side, back, above], shrink=0.6, pad=0.01,
                 label="grain velocity along travel v_x (m/s)")
    fig.colorbar(te, ax=[side, back, above], shrink=0.6, pad=0.02, label="tread ε33 (element mean)")
    fig.suptitle(f"step {step} (t = {step * dt:.3f} s), axle at x = {centre[0]:.3f} m", fontsize=10)
    fig.savefig(out, dpi=100)
    print("wrote", out)


if __name__ == "__main__":
    main()
