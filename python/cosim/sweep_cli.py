"""``cosim sweep``: one tyre run per value of a scene key, then a summary.

    cosim sweep SCENE --values scenario.slip=0,0.05,0.1,0.2,0.3 [--set K=V]...
                [--jobs N] --out DIR [--skip-travel M] [--reference REF.csv |
                --terra-params PARAMS.json] [--overwrite] [--keep-going]

Each run goes to ``DIR/<key>=<value>/`` (ports: whatever the scene says; its
``tcp://...:0`` endpoints are free ports chosen by each run). Then
``DIR/summary.csv`` holds, per value, the mean, min and max of T_H, T_R, T_P,
the vertical load and the sinkage from ``/coupler/traction`` over the steady
part of the travel, and ``DIR/summary.png`` draws them like seed 000 fig. 15
(T_H, |T_R|, T_P with their min–max range) beside the terramechanics
reference (terra/README.md "Files and how to call the reference").

The steady window: the travel starts at the first row whose vertical load
reaches ``scenario.sinkage_force`` (the coupler's switch, coupler/scenario.c);
the first ``--skip-travel`` metres of travel (default 0.1 m: the contact patch
and the tread's spin-up settle) are left out; the window ends with the run.
It is written into summary.csv as ``# window`` lines and per row.
"""
import argparse
import csv
import json
import math
import os
import shutil
import subprocess
import sys

import numpy as np

from .errors import CosimError, RunError
from .results import Results
from .roles import cosim_executable
from .runner import _dir_name, sweep as run_sweep

QUANTITIES = ["T_H", "T_R", "T_P", "vertical_load", "sinkage"]
STATS = ["mean", "min", "max"]
SUMMARY_FILE, PLOT_FILE, REFERENCE_FILE = "summary.csv", "summary.png", "reference.csv"
DEFAULT_SKIP_TRAVEL_M = 0.1
DEFAULT_WIDTH_M = 0.165  # the paper's tyre (seed 000 table 2), if the scene does not say
REFERENCE_SLIP_STEP = 0.01
DODGE = 0.012  # horizontal offset of the three quantities, fraction of the value range


class UsageError(CosimError):
    """Bad arguments to ``cosim sweep`` (exit 1)."""


def parse_value(text):
    """One value: JSON if it parses (numbers, true, "x", [..]), else the text."""
    try:
        return json.loads(text)
    except ValueError:
        return text


def parse_values(spec):
    """``key.path=v1,v2,...`` (or ``key.path=[v1, v2]`` as one JSON list)
    -> (key, [values])."""
    key, eq, rest = spec.partition("=")
    key = key.strip()
    if not eq or not key:
        raise UsageError(f"--values '{spec}': expected KEY.PATH=V1,V2,...")
    rest = rest.strip()
    if rest.startswith("["):
        try:
            values = json.loads(rest)
        except ValueError as e:
            raise UsageError(f"--values {key}: '{rest}' is not a JSON list ({e})") from None
    else:
        values = [parse_value(v.strip()) for v in rest.split(",")]
    if not values or any(v == "" for v in values):
        raise UsageError(f"--values {key}: empty value in '{rest}'")
    seen = [json.dumps(v) for v in values]
    dup = sorted({v for v in seen if seen.count(v) > 1})
    if dup:
        raise UsageError(f"--values {key}: value {dup[0]} given twice")
    return key, values


def parse_set(spec):
    key, eq, value = spec.partition("=")
    if not eq or not key.strip():
        raise UsageError(f"--set '{spec}': expected KEY.PATH=VALUE")
    return key.strip(), parse_value(value)


def travel_window(traction, scene, skip_travel):
    """(row mask, t0, t1, travel_start) of the steady travel of one run."""
    sc = scene.get("scenario", {})
    if sc.get("kind") != "tire_travel":
        raise CosimError("scenario.kind is not 'tire_travel': no traction to summarise")
    t, load = traction["t"], traction["vertical_load"]
    reached = np.nonzero(load >= sc["sinkage_force"])[0]
    if len(reached) == 0:
        return np.zeros(len(t), bool), math.nan, math.nan, math.nan
    start = t[reached[0]]
    speed = sc["omega"] * sc["radius"] * (1 - sc["slip"])
    t0 = start + (skip_travel / speed if speed > 0 else 0.0)
    mask = t >= t0
    return mask, t0, (t[-1] if mask.any() else math.nan), start


def summarise_run(results, skip_travel):
    """{column: value} of one run: the window and mean/min/max of each quantity."""
    tr = results.series("coupler", "traction")
    mask, t0, t1, start = travel_window(tr, results.scene, skip_travel)
    row = {"travel_start_s": start, "window_t0_s": t0, "window_t1_s": t1,
           "window_rows": int(mask.sum())}
    for q in QUANTITIES:
        v = tr[q][mask]
        for st in STATS:
            row[f"{q}_{st}"] = float(getattr(np, st)(v)) if len(v) else math.nan
    return row


def summary_columns(keys):
    return (list(keys) + ["travel_start_s", "window_t0_s", "window_t1_s", "window_rows"] +
            [f"{q}_{st}" for q in QUANTITIES for st in STATS] + ["dir"])


def write_summary(path, keys, rows, skip_travel):
    cols = summary_columns(keys)
    with open(path, "w", newline="") as f:
        f.write("# cosim sweep summary: per run, mean/min/max of /coupler/traction columns\n")
        f.write("# window: from the first row with vertical_load >= scenario.sinkage_force "
                f"(travel start) plus {skip_travel:g} m of travel at omega*radius*(1-slip), "
                "to the end of the run (columns window_t0_s, window_t1_s)\n")
        f.write("# units: N (T_H, T_R, T_P, vertical_load), m (sinkage), s (times)\n")
        w = csv.writer(f)
        w.writerow(cols)
        for r in rows:
            w.writerow([json.dumps(r[c]) if c in keys else
                        (f"{r[c]:.9g}" if isinstance(r[c], float) else r[c]) for c in cols])


def reference_curve(args, scene, out):
    """The terramechanics reference for the scene's wheel and load: a
    record from --reference (copied into the sweep's dir, which then holds
    all it draws), or `cosim terra curve` on --terra-params."""
    path = os.path.join(out, REFERENCE_FILE)
    if args.reference:
        if not os.path.exists(path) or not os.path.samefile(args.reference, path):
            shutil.copyfile(args.reference, path)
        return path
    if not args.terra_params:
        return None
    sc = scene.get("scenario", {})
    width = DEFAULT_WIDTH_M
    for p in scene.get("processes", {}).values():
        width = p.get("mesh", {}).get("width", width) if isinstance(p, dict) else width
    cmd = [cosim_executable(args.cosim), "terra", "curve", "--params", args.terra_params,
           "--radius", str(sc["radius"]), "--width", str(width),
           "--load", str(sc["sinkage_force"]),
           "--slips", f"0:{max(0.3, args.max_slip):g}:{REFERENCE_SLIP_STEP:g}", "--out", path]
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode != 0:
        raise CosimError(f"cosim terra curve failed: {p.stderr.strip()}")
    return path


def read_reference(path):
    """A terra record (``# key: value`` lines, then a header) as a numpy
    record array (genfromtxt would take the first comment line for the names)."""
    with open(path) as f:
        body = [l for l in f if not l.startswith("#")]
    return np.genfromtxt(body, delimiter=",", names=True)


def read_summary(path, notes=None):
    """summary.csv back as rows of {column: value} (numbers as floats, the
    swept key's values as JSON), the form write_summary took them in; the
    `# ` comment lines appended to `notes` if it is a list."""
    with open(path, newline="") as f:
        lines = list(f)
    body = [l for l in lines if not l.startswith("#")]
    if notes is not None:
        notes += [l[2:].rstrip("\n") for l in lines if l.startswith("# ")]
    rows = []
    for r in csv.DictReader(body):
        row = {}
        for c, v in r.items():
            try:
                row[c] = json.loads(v)
            except ValueError:
                row[c] = v
        rows.append(row)
    return rows


def draw(ax, key, rows, ref_path, ref_label="terramechanics"):
    """Seed 000 fig. 15 on one axis: T_H, |T_R|, T_P (mean, min-max) over the
    swept key, the reference's T/r, T/r - DP and DP dashed."""
    xs = [r[key] for r in rows]
    numeric = all(isinstance(x, (int, float)) for x in xs)
    styles = [("T_H", "T_H (gross tractive effort)", "tab:blue", 1),
              ("T_R", "|T_R| (running resistance)", "tab:red", -1),
              ("T_P", "T_P (drawbar pull)", "tab:green", 1)]
    pos = np.array(xs, float) if numeric else np.arange(len(xs), dtype=float)
    span = np.ptp(pos) if len(pos) > 1 else 1.0
    for j, (q, label, color, sign) in enumerate(styles):
        at = pos + (j - 1) * DODGE * span  # side by side, so the ranges stay readable
        mean = np.array([sign * r[f"{q}_mean"] for r in rows])
        a = np.array([sign * r[f"{q}_min"] for r in rows])
        b = np.array([sign * r[f"{q}_max"] for r in rows])
        lo, hi = np.minimum(a, b), np.maximum(a, b)
        ax.errorbar(at, mean, yerr=[mean - lo, hi - mean], fmt="o-", color=color,
                    capsize=4, label=f"DEM–FEM {label}: mean, min–max")
    if ref_path:
        ref = read_reference(ref_path)
        s = ref["s"]
        for col, label, color in [("T_over_r", "T/r", "tab:blue"),
                                  ("DP", "DP", "tab:green")]:
            ax.plot(s, ref[col], "--", color=color, label=f"{ref_label} {label}")
        ax.plot(s, ref["T_over_r"] - ref["DP"], "--", color="tab:red",
                label=f"{ref_label} T/r − DP")
    if not numeric:
        ax.set_xticks(pos, [json.dumps(x) for x in xs])
    ax.axhline(0, color="0.6", lw=0.8)
    ax.set_xlabel(key)
    ax.legend(fontsize=7)
    return pos


def plot(path, key, rows, ref_path, title, ref_label="terramechanics"):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(7, 4.5))
    draw(ax, key, rows, ref_path, ref_label)
    ax.set_ylabel("force (N)")
    ax.set_title(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def check_points(scene, sets, key, values, cosim):
    """`cosim check` each point first: a wrong key or value is named before
    any run starts."""
    for v in values:
        cmd = [cosim_executable(cosim), "check", scene]
        for k, x in list(sets.items()) + [(key, v)]:
            cmd += ["--set", f"{k}={json.dumps(x)}"]
        p = subprocess.run(cmd, capture_output=True, text=True)
        if p.returncode != 0:
            raise UsageError(f"{key}={json.dumps(v)}: {p.stderr.strip() or p.stdout.strip()}")


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # exit 1 (bad usage), as cosim run
        raise UsageError(f"{message}\n{self.format_usage().strip()}")


def main(argv):
    ap = _Parser(prog="cosim sweep", description=__doc__.split("\n\n")[0])
    ap.add_argument("scene")
    ap.add_argument("--values", required=True, metavar="KEY.PATH=V1,V2,...")
    ap.add_argument("--set", action="append", default=[], metavar="KEY.PATH=VALUE")
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--out", required=True)
    ap.add_argument("--skip-travel", type=float, default=DEFAULT_SKIP_TRAVEL_M, metavar="M")
    ap.add_argument("--reference", metavar="REF.csv")
    ap.add_argument("--terra-params", metavar="PARAMS.json")
    ap.add_argument("--overwrite", action="store_true")
    ap.add_argument("--keep-going", action="store_true")
    ap.add_argument("--summary-only", action="store_true",
                    help="summarise the runs already in --out")
    ap.add_argument("--cosim", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.jobs < 1:
        raise UsageError(f"--jobs: must be at least 1, got {args.jobs}")
    if args.skip_travel < 0:
        raise UsageError(f"--skip-travel: must be >= 0, got {args.skip_travel:g}")
    if not os.path.isfile(args.scene):
        raise UsageError(f"{args.scene}: no such scene file")
    for f in (args.reference, args.terra_params):
        if f and not os.path.isfile(f):
            raise UsageError(f"{f}: no such file")
    key, values = parse_values(args.values)
    sets = dict(parse_set(s) for s in args.set)
    if key in sets:
        raise UsageError(f"{key}: given both in --values and --set")
    numeric = [v for v in values if isinstance(v, (int, float))]
    args.max_slip = max(numeric) if key == "scenario.slip" and numeric else 0.3
    os.makedirs(args.out, exist_ok=True)
    if not args.summary_only:
        check_points(args.scene, sets, key, values, args.cosim)
        run_args = ["--overwrite"] if args.overwrite else []
        done = run_sweep(args.scene, {key: values}, args.out, set=sets, jobs=args.jobs,
                         keep_going=args.keep_going, quiet=True, cosim=args.cosim,
                         args=run_args)
    else:
        done = [({key: v}, os.path.join(args.out, _dir_name({key: v}))) for v in values]
    rows, scene = [], None
    for point, res in done:
        d = os.path.join(args.out, _dir_name(point))
        if isinstance(res, Exception):
            print(f"cosim sweep: {res}", file=sys.stderr)
            continue
        with (res if isinstance(res, Results) else Results(res)) as r:
            row = summarise_run(r, args.skip_travel)
            scene = scene or r.scene
        row.update(point)
        row["dir"] = os.path.basename(d)
        if row["window_rows"] == 0:
            why = ("the vertical load never reached scenario.sinkage_force"
                   if math.isnan(row["travel_start_s"]) else
                   f"the run ended within --skip-travel {args.skip_travel:g} m of travel "
                   f"(travel from t = {row['travel_start_s']:g} s)")
            print(f"cosim sweep: {row['dir']}: no steady travel: {why}", file=sys.stderr)
        rows.append(row)
    if not rows:
        raise RunError("cosim sweep: no run finished")
    write_summary(os.path.join(args.out, SUMMARY_FILE), [key], rows, args.skip_travel)
    ref = reference_curve(args, scene, args.out)
    title = f"{scene.get('name', args.scene)}: traction over the steady travel"
    load = scene.get("scenario", {}).get("sinkage_force")
    plot(os.path.join(args.out, PLOT_FILE), key, rows, ref, title,
         f"terramechanics ({load:g} N)" if args.terra_params and load else "terramechanics")
    print(f"summary: {os.path.join(args.out, SUMMARY_FILE)}, plot: "
          f"{os.path.join(args.out, PLOT_FILE)}")
    return 0 if len(rows) == len(done) else 3
