"""The figure and table of a dbp-rig run (scenario.rig = "dbp", coupler/README.md).

    python3 -m cosim.fig_dbp RUN_DIR [--png PATH] [--csv PATH] [--bin-width W]
                             [--window S] [--slip-points SLIPS.csv] [--reference REF.csv]
    python3 -m cosim.fig_dbp RUN_DIR RUN_DIR... --out DIR [the same options]
    python3 -m cosim.fig_dbp --curve CURVE.csv --png PATH [--slip-points SLIPS.csv]
                             [--check PATH] [--reference REF.csv]

results.h5 (/coupler/traction, /coupler/dbp) -> RUN_DIR/dbp_curve.csv (the
curve binned by the measured slip, each row's slip and forces averaged over
the window centred on it, --window S or the scene's scenario.dbp_window, 0 for
none; 95 % batch-means intervals: cosim.traction.dbp_curve) and
RUN_DIR/dbp.png: left, T_H, |T_R|, T_P and the resistive force against the
slip (the bins with their intervals; the running averages of /coupler/dbp
as thin lines), right, the carriage speed, the resistive force and the slip
against time. --slip-points draws slip-controlled
runs' points for the cross-check (a CSV with columns slip, T_H_mean, T_H_ci95,
T_R_mean, T_R_ci95, T_P_mean, T_P_ci95: e.g. a `cosim sweep` summary.csv over
scenario.slip; or another dbp_curve.csv, whose bins are then the points: two
curves compared bin by bin, e.g. a step and its refinement). --reference draws a terramechanics reference dashed beside the
curve (a `cosim terra curve` record for the scene's wheel and load: T/r as T_H,
T/r - DP as |T_R|, DP as T_P, and the band over its packings faint;
terra/README.md "Files and how to call the reference"); its load must be the
scene's sinkage_force.

With --slip-points the cross-check is also written as a table
(cross_check.csv beside the PNG, or --check PATH; cosim.traction.dbp_cross_check:
per point and quantity the curve interpolated at the point's slip, the
difference and whether it lies within the combined 95 % half-width) and
printed. --curve CURVE.csv draws a curve saved earlier (a dbp_curve.csv, one
run's or across runs) instead of runs, with the same options (needs --png).

Several runs (dbp runs of one scene on different beds, e.g. the runs of a
`cosim sweep --repeat N`): DIR/dbp_curve.csv is the curve across them
(cosim.traction.dbp_curve_across: per slip bin the mean of the runs' bin
means, its 95 % interval from their spread, the runs that reach the bin, their
min and max) and DIR/dbp.png draws it with each run's bins faint. Runs whose
load, wheel or ramp differ are refused, naming the key and both runs.

Exit codes: 0 ok, 1 bad usage or a run that is not a dbp run.
"""
import contextlib
import argparse
import csv
import math
import os
import sys

import numpy as np

from .errors import CosimError
from .results import Results
from . import terra_ref, traction

CURVE_FILE, PLOT_FILE = "dbp_curve.csv", "dbp.png"
# T_H, |T_R|, T_P drawn as seed 000 fig. 15 draws them; the force the rig measured
COLORS = {"T_H": "tab:blue", "T_R": "tab:red", "T_P": "tab:green", "resistive_force": "0.35"}
LABELS = {"T_H": "T_H", "T_R": "|T_R|", "T_P": "T_P", "resistive_force": "resistive force"}


def read_points(path):
    """Slip-controlled points: {slip, q_mean, q_ci95} rows of a CSV (# lines
    skipped); the slip from the column slip, scenario.slip or, in another
    dbp_curve.csv, slip_mean (each bin a point: one curve against another)."""
    with open(path) as f:
        rows = list(csv.DictReader(line for line in f if not line.startswith("#")))
    out = []
    for r in rows:
        slip = r.get("slip", r.get("scenario.slip", r.get("slip_mean")))
        if slip is None:
            raise CosimError(f"{path}: no column 'slip', 'scenario.slip' or 'slip_mean'")
        out.append({k: float(v) for k, v in r.items() if k and v not in (None, "")
                    and k.endswith(("_mean", "_ci95"))}
                   | {"slip": float(slip)})
    return out


def read_reference(path, load):
    """A `cosim terra curve` record (terra_ref.read_reference), refused unless
    its `# load_N:` line is `load` N and it has the columns drawn."""
    with open(path) as f:
        meta = dict(l[2:].split(": ", 1) for l in f if l.startswith("# ") and ": " in l)
    if "load_N" not in meta:
        raise CosimError(f"{path}: not a terra curve record (no '# load_N:' line)")
    if abs(float(meta["load_N"]) - float(load)) > 1e-6 * abs(float(load)):
        raise CosimError(f"{path}: made for a load of {meta['load_N'].strip()} N, the run's "
                         f"scenario.sinkage_force is {float(load):g} N")
    ref = terra_ref.read_reference(path)
    need = ("s", "T_over_r", "DP")
    if ref.dtype.names is None or any(c not in ref.dtype.names for c in need) or ref.size == 0:
        raise CosimError(f"{path}: needs the columns {', '.join(need)} and at least one row")
    return np.atleast_1d(ref)


def draw_points(ax, points):
    """Slip-controlled runs' means (read_points) as open squares with their
    intervals (none where a point has no interval)."""
    for p in points or []:
        for q in ("T_H", "T_R", "T_P"):
            if f"{q}_mean" in p:
                sign = -1 if q == "T_R" else 1
                ci = p.get(f"{q}_ci95", math.nan)
                ax.errorbar([p["slip"]], [sign * p[f"{q}_mean"]], yerr=[0 if math.isnan(ci) else ci],
                            fmt="s", mfc="none", ms=8, capsize=4, color=COLORS[q])


def points_label(path):
    """What the squares of the points file at path are: the bins of another
    curve (a file write_dbp_curve wrote), else slip-controlled runs."""
    try:
        with open(path) as f:
            curve = f.readline().startswith(traction.CURVE_HEADER)
    except (OSError, TypeError):  # no file (None, or points given as a list)
        curve = False
    return f"the bins of {os.path.basename(path)}" if curve else "slip-controlled"


def finish_curve(ax, points, ref, title, squares="slip-controlled"):
    """The curve's axis: slip-controlled points (or another curve's bins:
    squares says which), the reference dashed, the zero line, labels, title
    and legend."""
    draw_points(ax, points)
    if ref is not None:
        terra_ref.draw_reference(ax, ref, band=True)
    ax.axhline(0, color="k", lw=0.5)
    ax.set_xlabel("slip (measured)")
    ax.set_ylabel("force (N)")
    ax.set_title(title + (f"; squares: {squares}" if points else "")
                 + ("; dashed: terramechanics" if ref is not None else ""), fontsize=9)
    ax.legend(fontsize=7)


def plot(path, results, curve, points=None, ref=None, squares="slip-controlled"):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    d = traction.dbp_series(results)
    sc = results.scene["scenario"]
    ramp = d["phase"] == traction.DBP_PHASE_RAMP
    fig, (ax, at) = plt.subplots(1, 2, figsize=(12, 4.8))
    for q in ("T_H", "T_R", "T_P", "resistive_force"):
        sign = -1 if q == "T_R" else 1
        x = np.array([r["slip_mean"] for r in curve])
        y = sign * np.array([r[f"{q}_mean"] for r in curve])
        e = np.array([r[f"{q}_ci95"] for r in curve])
        ax.errorbar(x, y, yerr=np.where(np.isnan(e), 0, e), fmt="o", ms=4, capsize=3,
                    color=COLORS[q], label=f"{LABELS[q]} (bins; bars: 95 % where a bin is long enough)")
        avg = f"{q}_avg"
        if avg in d:
            ax.plot(d["slip_avg"][ramp], sign * d[avg][ramp], "-", lw=0.7, alpha=0.6,
                    color=COLORS[q])
    finish_curve(ax, points, ref, f"dbp rig: load {sc['sinkage_force']} N; lines: running "
                 f"averages over {sc.get('dbp_window', 0.1)} s", squares)
    travel = d["phase"] > 0
    travel[np.argmax(travel)] = False  # the release step: the carriage not yet driven
    t = d["t"][travel]
    at.plot(t, d["carriage_speed"][travel], color="tab:purple", label="carriage speed (m/s)")
    at.plot(t, d["slip"][travel], color="tab:orange", label="slip")
    at.set_xlabel("t (s)")
    at.set_ylabel("carriage speed (m/s), slip")
    af = at.twinx()
    af.plot(t, d["resistive_force"][travel], color="0.35", label="resistive force (N)")
    af.set_ylabel("resistive force (N)")
    h1, l1 = at.get_legend_handles_labels()
    h2, l2 = af.get_legend_handles_labels()
    at.legend(h1 + h2, l1 + l2, fontsize=8, loc="upper left")
    at.set_title("the rig against time (from the travel start)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_across(path, runs, names, curves, across, points=None, ref=None, squares="slip-controlled"):
    """The curve across runs: the means with their 95 % intervals (across
    the runs' bin means), each run's bins faint; right, each run's slip and
    resistive force against time."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    sc = runs[0].scene["scenario"]
    fig, (ax, at) = plt.subplots(1, 2, figsize=(12, 4.8))
    for q in ("T_H", "T_R", "T_P"):
        sign = -1 if q == "T_R" else 1
        for curve in curves:
            ax.plot([r["slip_mean"] for r in curve], [sign * r[f"{q}_mean"] for r in curve],
                    ".", ms=3, alpha=0.35, color=COLORS[q])
        x = np.array([r["slip_mean"] for r in across])
        y = sign * np.array([r[f"{q}_mean"] for r in across])
        e = np.array([r[f"{q}_ci95"] for r in across])
        ax.errorbar(x, y, yerr=np.where(np.isnan(e), 0, e), fmt="o-", ms=4, capsize=3,
                    color=COLORS[q], label=f"{LABELS[q]}: mean of {len(runs)} runs, 95 % "
                    "(dots: each run's bins)")
    finish_curve(ax, points, ref, f"dbp rig, {len(runs)} runs: load {sc['sinkage_force']} N", squares)
    for r, name in zip(runs, names):
        d = traction.dbp_series(r)
        travel = d["phase"] > 0
        at.plot(d["t"][travel], d["slip"][travel], lw=0.8, label=f"slip: {name}")
    at.set_xlabel("t (s)")
    at.set_ylabel("slip")
    at.legend(fontsize=7, loc="upper left")
    at.set_title("each run's slip against time (from the travel start)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def write_across(paths, out_dir, bin_width=traction.DBP_BIN_WIDTH, csv_path=None, png=None,
                 points=None, reference=None, check=None, points_name="points", window=None):
    """The curve across the dbp runs in paths (their dirs or results.h5):
    dbp_curve.csv and dbp.png into out_dir (or csv_path, png), and with
    points their cross-check (cross_check, into check); returns
    (csv_path, png, bins). A CosimError when the runs are not realisations
    of one curve or one has no ramp. window: traction.dbp_curve's."""
    names = [os.path.basename(os.path.normpath(p if os.path.isdir(p) else os.path.dirname(p) or "."))
             for p in paths]
    with contextlib.ExitStack() as stack:
        runs = [stack.enter_context(Results(p)) for p in paths]
        traction.dbp_same_ramp([r.scene for r in runs], list(paths))
        curves = [traction.dbp_curve(r, bin_width, window=window) for r in runs]
        for p, c in zip(paths, curves):
            if not c:
                raise CosimError(f"{p}: no rows in the ramp (phase 2)")
        load = float(runs[0].scene["scenario"]["sinkage_force"])
        across = traction.dbp_curve_across(curves, load, bin_width)
        ref = read_reference(reference, load) if reference else None
        os.makedirs(out_dir, exist_ok=True)
        csv_path = csv_path or os.path.join(out_dir, CURVE_FILE)
        traction.write_dbp_curve(csv_path, across, runs[0].scene, runs=names, window=window)
        png = png or os.path.join(out_dir, PLOT_FILE)
        plot_across(png, runs, names, curves, across, points, ref,
                    points_label(points_name))
    if points:
        cross_check(across, points, check, png, csv_path, points_name)
    return csv_path, png, len(across)


def plot_saved(path, curve, name, load, points=None, ref=None, squares="slip-controlled"):
    """A saved curve (traction.read_dbp_curve) with its intervals."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(7, 4.8))
    x = np.array([r["slip_mean"] for r in curve])
    for q in ("T_H", "T_R", "T_P"):
        sign = -1 if q == "T_R" else 1
        e = np.array([r[f"{q}_ci95"] for r in curve])
        ax.errorbar(x, sign * np.array([r[f"{q}_mean"] for r in curve]),
                    yerr=np.where(np.isnan(e), 0, e), fmt="o-", ms=4, capsize=3,
                    color=COLORS[q], label=f"{LABELS[q]} ({name}; bars: 95 %)")
    finish_curve(ax, points, ref, f"dbp curve: load {load:g} N", squares)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def cross_check(curve, points, path, png, curve_name, points_name):
    """Writes (to path, default cross_check.csv beside png) and prints the
    cross-check of the slip-controlled points against the curve."""
    path = path or os.path.join(os.path.dirname(png) or ".", "cross_check.csv")
    rows = traction.dbp_cross_check(curve, points)
    traction.write_cross_check(path, rows, curve_name, points_name)
    for r in rows:
        verdict = {True: "agree", False: "DIFFER", None: "no verdict"}[r["agree"]]
        print(f"cosim.fig_dbp: cross-check slip {r['slip']:.3g} {r['quantity']}: point "
              f"{r['point_mean']:.4g} +- {r['point_ci95']:.3g}, curve {r['curve_mean']:.4g} +- "
              f"{r['curve_ci95']:.3g}: difference {r['difference']:.3g} +- {r['ci95']:.3g}: {verdict}")
    print(f"cosim.fig_dbp: cross-check -> {path}")


def main(argv):
    ap = argparse.ArgumentParser(prog="python3 -m cosim.fig_dbp", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("run", nargs="*", help="the run's output dir or its results.h5; several: "
                    "dbp runs of one scene on different beds, averaged bin by bin (needs --out)")
    ap.add_argument("--out", help="with several runs: the dir of dbp_curve.csv and dbp.png")
    ap.add_argument("--png", help=f"default RUN_DIR/{PLOT_FILE}")
    ap.add_argument("--csv", help=f"default RUN_DIR/{CURVE_FILE}")
    ap.add_argument("--bin-width", type=float, default=traction.DBP_BIN_WIDTH)
    ap.add_argument("--window", type=float, help="average each row's slip and forces over "
                    "this many s first (default the scene's scenario.dbp_window; 0: none)")
    ap.add_argument("--slip-points", help="CSV of slip-controlled runs' means to draw")
    ap.add_argument("--reference", help="a `cosim terra curve` record for the scene's wheel "
                    "and load, drawn dashed")
    ap.add_argument("--check", help="the cross-check table (with --slip-points; default "
                    "cross_check.csv beside the PNG)")
    ap.add_argument("--curve", help="a saved dbp_curve.csv to draw instead of runs (needs --png)")
    a = ap.parse_args(argv)
    if not a.bin_width > 0:
        ap.error(f"--bin-width: must be > 0, got {a.bin_width}")
    if a.window is not None and not (a.window >= 0 and math.isfinite(a.window)):
        ap.error(f"--window: must be >= 0 s, got {a.window}")
    if a.curve:
        if a.run or not a.png:
            ap.error("--curve: give --png and no run dirs")
        try:
            curve, load = traction.read_dbp_curve(a.curve)
            points = read_points(a.slip_points) if a.slip_points else None
            ref = read_reference(a.reference, load) if a.reference else None
            os.makedirs(os.path.dirname(a.png) or ".", exist_ok=True)
            plot_saved(a.png, curve, os.path.basename(a.curve), load, points, ref,
                       points_label(a.slip_points))
            print(f"cosim.fig_dbp: {len(curve)} slip bins of {a.curve} -> {a.png}")
            if points:
                cross_check(curve, points, a.check, a.png, a.curve, a.slip_points)
        except (CosimError, KeyError, OSError, ValueError) as e:
            print(f"cosim.fig_dbp: {e}", file=sys.stderr)
            return 1
        return 0
    if not a.run:
        ap.error("give a run dir (or --curve)")
    if len(a.run) > 1:
        if not a.out:
            ap.error(f"--out: needed with several runs ({len(a.run)} given)")
        try:
            points = read_points(a.slip_points) if a.slip_points else None
            csv_path, png, bins = write_across(a.run, a.out, a.bin_width, a.csv, a.png, points,
                                               a.reference, a.check, a.slip_points, a.window)
        except (CosimError, KeyError, OSError, ValueError) as e:
            print(f"cosim.fig_dbp: {e}", file=sys.stderr)
            return 1
        print(f"cosim.fig_dbp: {bins} slip bins across {len(a.run)} runs -> {csv_path}, {png}")
        return 0
    a.run = a.run[0]
    base = a.run if os.path.isdir(a.run) else os.path.dirname(a.run) or "."
    try:
        with Results(a.run) as r:
            curve = traction.dbp_curve(r, a.bin_width, window=a.window)
            if not curve:
                raise CosimError(f"{a.run}: no rows in the ramp (phase 2): the run ended in "
                                 "the hold or before the travel")
            csv_path = a.csv or os.path.join(base, CURVE_FILE)
            traction.write_dbp_curve(csv_path, curve, r.scene, window=a.window)
            points = read_points(a.slip_points) if a.slip_points else None
            ref = (read_reference(a.reference, r.scene["scenario"]["sinkage_force"])
                   if a.reference else None)
            png = a.png or os.path.join(base, PLOT_FILE)
            plot(png, r, curve, points, ref, points_label(a.slip_points))
            if points:
                cross_check(curve, points, a.check, png, csv_path, a.slip_points)
    except (CosimError, KeyError, OSError, ValueError) as e:
        print(f"cosim.fig_dbp: {e}", file=sys.stderr)
        return 1
    print(f"cosim.fig_dbp: {len(curve)} slip bins -> {csv_path}, {png}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
