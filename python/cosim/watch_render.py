"""The picture of ``cosim watch``: the latest snapshot of each process, drawn
server-side with matplotlib (Agg, no display) to a PNG.

What a snapshot is, is told by its arrays (PROTOCOL.md "Snapshots"):
- grains: ``x`` [n, 3], ``v`` [n, 3] and ``r`` [n] (dem_server) -- from above
  (x-y) and from the side (x-z), each grain a dot coloured by its speed |v|;
- a block: ``x`` [M, 3] and ``element_force`` [M] (contact_block) -- its
  pressure map from above: on a regular grid of element centres (contact_block's
  elements) each element's force over its cell dx dy; else the forces as dots;
- anything else with ``x`` [n, 3] (the tread's nodes, a stub's surface): its
  outline, the convex hull of the nodes in each view, over the grains.
"""
import io

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

FIG_SIZE_IN = (11.0, 4.6)
DPI = 90
GRAIN_MARK_PT2 = 4.0    # marker area of one grain, pt^2: a bed of ~1e4 grains stays readable
NODE_MARK_PT2 = 2.0     # outline nodes when no grains are drawn
BLOCK_MARK_PT2 = 14.0
VIEWS = (("from above", 0, 1, "x (m)", "y (m)"), ("from the side", 0, 2, "x (m)", "z (m)"))


def kind(arrays):
    if "element_force" in arrays and "x" in arrays:
        return "block"
    if {"x", "v", "r"} <= set(arrays):
        return "grains"
    return "outline" if "x" in arrays and np.ndim(arrays["x"]) == 2 else None


def convex_hull(p):
    """The convex hull of 2-D points p [n, 2], counter-clockwise, closed
    (Andrew 1979, "Another efficient algorithm for convex hulls in two dimensions",
    Inf. Process. Lett. 9: the monotone chain)."""
    pts = np.unique(np.asarray(p, dtype=float), axis=0)
    if len(pts) < 3:
        return pts

    def half(seq):
        h = []
        for q in seq:
            while len(h) >= 2 and ((h[-1][0] - h[-2][0]) * (q[1] - h[-2][1]) -
                                   (h[-1][1] - h[-2][1]) * (q[0] - h[-2][0])) <= 0:
                h.pop()
            h.append(q)
        return h[:-1]

    hull = half(pts) + half(pts[::-1])
    return np.array(hull + hull[:1])


def _title(name, step, t):
    return f"{name} step {step}" + (f", t = {t:.4g} s" if t is not None else "")


def _draw_grains(fig, axes, grains, outlines):
    sc = None
    for ax, (view, i, j, xl, yl) in zip(axes, VIEWS):
        for name, (step, t, a) in grains:
            x, speed = np.asarray(a["x"]), np.linalg.norm(np.asarray(a["v"]), axis=1)
            sc = ax.scatter(x[:, i], x[:, j], c=speed, s=GRAIN_MARK_PT2, cmap="viridis",
                            linewidths=0)
            ax.set_title(f"{_title(name, step, t)}, {view}", fontsize=9)
        _draw_outlines(ax, outlines, i, j, NODE_MARK_PT2 if not grains else 0.0)
        ax.set_xlabel(xl)
        ax.set_ylabel(yl)
        ax.set_aspect("equal", adjustable="datalim")
    if sc is not None:
        fig.colorbar(sc, ax=list(axes), label="grain speed |v| (m/s)", shrink=0.85)


def _draw_outlines(ax, outlines, i, j, mark):
    for name, (step, t, a) in outlines:
        x = np.asarray(a["x"])
        if mark:
            ax.scatter(x[:, i], x[:, j], s=mark, color="0.4", linewidths=0)
        h = convex_hull(x[:, [i, j]])
        ax.plot(h[:, 0], h[:, 1], color="crimson", lw=1.2, label=f"{name} outline")
    if outlines:
        ax.legend(loc="upper right", fontsize=7)


def _grid(x):
    """(xs, ys, ix, iy) when the points x [M, 2] are the cells of a regular grid
    (every x_i with every y_j, once), else None."""
    xs, ix = np.unique(x[:, 0], return_inverse=True)
    ys, iy = np.unique(x[:, 1], return_inverse=True)
    if len(xs) < 2 or len(ys) < 2 or len(xs) * len(ys) != len(x) or \
            len(set(zip(ix.tolist(), iy.tolist()))) != len(x):
        return None
    return xs, ys, ix, iy


def _edges(c):
    """Cell edges of the centres c (uniform spacing)."""
    h = (c[-1] - c[0]) / (len(c) - 1)
    return np.append(c - h / 2, c[-1] + h / 2), h


def _draw_block(fig, ax, name, step, t, a):
    """On a regular grid: the pressure p = F / (dx dy) of each element as a map;
    else the element forces as dots."""
    x, force = np.asarray(a["x"]), np.asarray(a["element_force"]).ravel()
    g = _grid(x[:, :2])
    if g is not None:
        (ex, dx), (ey, dy) = _edges(g[0]), _edges(g[1])
        p = np.full((len(g[1]), len(g[0])), np.nan)
        p[g[3], g[2]] = force / (dx * dy)
        sc = ax.pcolormesh(ex, ey, p, cmap="inferno")
        what, label = "pressure", "contact pressure F / (dx dy) (Pa)"
    else:
        sc = ax.scatter(x[:, 0], x[:, 1], c=force, s=BLOCK_MARK_PT2, marker="s",
                        cmap="inferno", linewidths=0)
        what, label = "element force", "element normal force (N)"
    ax.set_title(f"{_title(name, step, t)}: {what}, from above", fontsize=9)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_aspect("equal", adjustable="datalim")
    fig.colorbar(sc, ax=ax, label=label, shrink=0.85)


def snapshot_png(snapshots):
    """PNG bytes of {process: (step, t or None, {array: ndarray})}."""
    by_kind = {"grains": [], "block": [], "outline": []}
    for name, snap in sorted(snapshots.items()):
        k = kind(snap[2])
        if k:
            by_kind[k].append((name, snap))
    fig = Figure(figsize=FIG_SIZE_IN, dpi=DPI)
    FigureCanvasAgg(fig)
    blocks = by_kind["block"]
    if blocks and not by_kind["grains"]:
        axes = fig.subplots(1, len(blocks), squeeze=False)[0]
        for ax, (name, (step, t, a)) in zip(axes, blocks):
            _draw_block(fig, ax, name, step, t, a)
    else:
        axes = fig.subplots(1, 2)
        _draw_grains(fig, axes, by_kind["grains"], by_kind["outline"])
        if not by_kind["grains"]:
            for ax, (view, *_rest) in zip(axes, VIEWS):
                ax.set_title(", ".join(_title(n, s[0], s[1]) for n, s in by_kind["outline"])
                             + f", {view}", fontsize=9)
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()
