"""The figures of a tire_road run (scenario tire_road, docs/tire-road.md).

    python3 -m cosim.fig_road RUN_DIR [--step K]

results.h5 (/coupler/lugs, /coupler/traction and the lug processes'
snapshots) ->
  RUN_DIR/road_passages.png  each lug passage's force against time and against
                             its place in the footprint (the face's centre
                             ahead of the rim's centre);
  RUN_DIR/road_psd.png, .csv the tyre's total road force (the blocks' forces
                             plus the road's penalty) over the travel and its
                             one-sided power spectral density up to the block
                             rate's Nyquist frequency (Welch's method, Hann
                             windows, the mean removed: its integral over
                             frequency is the force's variance);
  RUN_DIR/road_footprint.png the blocks' element forces as pressure at one
                             output step (--step K; default the output step
                             with the largest road force), each block where
                             its lug's face is.
Exit codes: 0 ok, 1 bad usage or a run that is not a tire_road run.
"""
import argparse
import os
import sys

import numpy as np

from .errors import CosimError
from .results import Results

PASSAGES, PSD_PNG, PSD_CSV, FOOTPRINT = ("road_passages.png", "road_psd.png", "road_psd.csv",
                                         "road_footprint.png")
WELCH_SEGMENT = 4096  # samples: 80 ms at 51.2 kHz, 12.5 Hz resolution


def lug_processes(results):
    """Names of the scene's processes of exec lug_block, in scene order (the
    order of /coupler/lugs' columns)."""
    sc = results.scene
    if sc.get("scenario", {}).get("kind") != "tire_road":
        raise CosimError("scenario.kind is not 'tire_road': no lugs to draw")
    return [n for n, p in sc["processes"].items()
            if os.path.basename(str(p.get("exec", ""))) == "lug_block"]


def passages(lugs, n_proc):
    """[(process, lug, row slice)] of every passage: the rows in which one
    process serves one lug, in order of their start."""
    out = []
    for p in range(n_proc):
        lug = lugs[f"lug{p}"]
        k = 0
        while k < len(lug):
            if lug[k] < 0:
                k += 1
                continue
            e = k
            while e < len(lug) and lug[e] == lug[k]:
                e += 1
            out.append((p, int(lug[k]), slice(k, e)))
            k = e
    return sorted(out, key=lambda q: q[2].start)


def road_force(lugs, n_proc):
    return lugs["road_penalty"] + sum(lugs[f"force{p}"] for p in range(n_proc))


def psd(force, dt):
    """(frequency Hz, one-sided PSD N^2/Hz) of force minus its mean."""
    from scipy.signal import welch
    x = np.asarray(force, float) - np.mean(force)
    seg = min(WELCH_SEGMENT, len(x))
    return welch(x, fs=1.0 / dt, window="hann", nperseg=seg, detrend=False, scaling="density")


def travel_rows(results):
    tr = results.series("coupler", "traction")
    reached = np.nonzero(tr["vertical_load"] >= results.scene["scenario"]["sinkage_force"])[0]
    return reached[0] if len(reached) else 0


def _figure(*args, **kw):
    """matplotlib's subplots, off screen (Agg)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt.subplots(*args, **kw)


def _save(fig, path):
    import matplotlib.pyplot as plt
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_passages(path, lugs, pas):
    fig, (at, ax) = _figure(1, 2, figsize=(12, 4.5))
    for p, j, s in pas:
        t, x, F = lugs["t"][s], lugs[f"x{p}"][s], lugs[f"force{p}"][s]
        at.plot(t, F, lw=0.8, label=f"lug {j} (process {p})")
        ax.plot(1e3 * x, F, lw=0.8)
    at.set_xlabel("t (s)")
    at.set_ylabel("block force (N)")
    at.set_title("each lug passage against time", fontsize=9)
    if len(pas) <= 12:
        at.legend(fontsize=7)
    ax.set_xlabel("face centre ahead of the rim centre (mm)")
    ax.set_ylabel("block force (N)")
    ax.set_title("against the place in the footprint", fontsize=9)
    _save(fig, path)


def plot_psd(path, t, force, f, p, dt):
    fig, (at, af) = _figure(1, 2, figsize=(12, 4.5))
    at.plot(t, force, lw=0.6)
    at.set_xlabel("t (s)")
    at.set_ylabel("road force (N)")
    at.set_title("the tyre's total road force over the travel", fontsize=9)
    af.semilogy(f[1:], p[1:], lw=0.7)
    af.set_xlim(0, 0.5 / dt)
    af.set_xlabel("frequency (Hz), up to the block rate's Nyquist frequency")
    af.set_ylabel("PSD (N²/Hz)")
    af.set_title(f"Welch, Hann, {min(WELCH_SEGMENT, len(force))}-sample segments", fontsize=9)
    _save(fig, path)


def plot_footprint(path, results, lugs, names, step):
    k = int(np.searchsorted(lugs["t"], step * results.scene["time"]["dt"] - 1e-12))
    fig, ax = _figure(figsize=(7, 5))
    im = None
    for p, name in enumerate(names):
        if lugs[f"lug{p}"][k] < 0:
            continue
        g = results.scene["processes"][name]["grid"]
        nx, ny, dx, dy = g["nx"], g["ny"], g["dx"], g["dy"]
        snap = results.snapshot(name, step)
        pressure = snap["element_force"].reshape(ny, nx) / (dx * dy)
        x0, y0 = lugs[f"x{p}"][k] - 0.5 * nx * dx, lugs[f"y{p}"][k] - 0.5 * ny * dy
        im = ax.imshow(pressure / 1e6, origin="lower", cmap="viridis",
                       extent=[1e3 * x0, 1e3 * (x0 + nx * dx), 1e3 * y0, 1e3 * (y0 + ny * dy)])
    ax.set_xlabel("ahead of the rim centre (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_title(f"block pressure at step {step} (t = {lugs['t'][k]:.4g} s)", fontsize=9)
    ax.set_aspect("equal")
    ax.autoscale()
    if im is not None:
        fig.colorbar(im, ax=ax, label="pressure (MPa)")
    _save(fig, path)


def main(argv):
    ap = argparse.ArgumentParser(prog="python3 -m cosim.fig_road", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("run", help="the run's output dir or its results.h5")
    ap.add_argument("--step", type=int, help="the output step of the footprint")
    a = ap.parse_args(argv)
    base = a.run if os.path.isdir(a.run) else os.path.dirname(a.run) or "."
    try:
        with Results(a.run) as r:
            names = lug_processes(r)
            lugs = r.series("coupler", "lugs")
            dt = float(r.scene["time"]["dt"])
            pas = passages(lugs, len(names))
            plot_passages(os.path.join(base, PASSAGES), lugs, pas)
            k0 = travel_rows(r)
            force = road_force(lugs, len(names))
            if len(force) - k0 < 16:
                raise CosimError("the travel has fewer than 16 rows: no spectrum")
            f, p = psd(force[k0:], dt)
            np.savetxt(os.path.join(base, PSD_CSV), np.column_stack([f, p]), delimiter=",",
                       header="frequency_hz,psd_n2_per_hz (Welch, Hann, mean removed; "
                       "the tyre's road force over the travel)", comments="# ")
            plot_psd(os.path.join(base, PSD_PNG), lugs["t"][k0:], force[k0:], f, p, dt)
            steps = r.steps(names[0]) if names else []
            if not steps:
                raise CosimError("no snapshots of the lug processes (output.every)")
            step = a.step
            if step is None:
                tk = np.array(steps) * dt
                rows = np.clip(np.searchsorted(lugs["t"], tk - 1e-12), 0, len(force) - 1)
                step = steps[int(np.argmax(force[rows]))]
            plot_footprint(os.path.join(base, FOOTPRINT), r, lugs, names, step)
    except (CosimError, KeyError, OSError) as e:
        print(f"cosim.fig_road: {e}", file=sys.stderr)
        return 1
    print(f"cosim.fig_road: {len(pas)} passages, spectrum to {0.5 / dt:.4g} Hz, footprint at "
          f"step {step} -> {base}/road_*.png, {PSD_CSV}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
