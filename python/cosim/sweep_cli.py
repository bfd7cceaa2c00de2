"""``cosim sweep``: one tyre run per value of a scene key, then a summary.

    cosim sweep SCENE --values scenario.slip=0,0.05,0.1,0.2,0.3 [--set K=V]...
                [--jobs N] --out DIR [--repeat N] [--skip-travel M] [--batch-time S]
                [--reference REF.csv | --terra-params PARAMS.json] [--overwrite]
                [--keep-going] [--resume] [--no-bed-reuse]

Each run goes to ``DIR/<key>=<value>/`` (ports: whatever the scene says; its
``tcp://...:0`` endpoints are free ports chosen by each run). Then
``DIR/summary.csv`` holds, per value, the mean, its 95 % confidence interval
(half-width ``_ci95``), min and max of T_H, T_R, T_P, the vertical load and
the sinkage from ``/coupler/traction`` over the steady part of the travel,
and ``DIR/summary.png`` draws them like seed 000 fig. 15 (T_H, |T_R|, T_P
with their 95 % intervals, the min–max range faint) beside the terramechanics
reference (terra/README.md "Files and how to call the reference").

``--repeat N`` runs N realisations of each value on different beds: the bed
generator's seed (``processes.<dem>.particles.seed``, the scene's value s0,
default 1) is s0, s0 + 1, ..., s0 + N - 1, each run in
``DIR/<key>=<value>,<seed key>=<seed>/``. Each distinct bed (one per seed when
only the scenario is swept) is settled once, by a settle-only run into
``DIR/beds/``, and every run of it starts from that saved bed, which
continues the settling bit for bit (cosim/sweep_beds.py; ``--no-bed-reuse``:
each run settles its own, as before); the realisations are independent, and
the same seed gives the same run bit for bit either way. ``--jobs N`` runs N
at once, each with ``coupling.affinity`` "none" unless ``--set`` gives it
(cosim.runner.concurrent_sets: "handoff" binds a run to one core, which
runs that share the machine must not), and each fem_server with
``threads`` 1 unless the scene or ``--set`` gives it (its other threads
would only wait at barriers on shared cores). ``--resume`` skips
the points whose results.h5 already reaches time.end and reruns the others;
beds already in ``DIR/beds/`` are never settled again. summary.csv then
gives per value the mean of the run means and its interval from their
spread (Student t, N - 1 degrees of freedom); ``DIR/runs.csv`` has one row
per run with its own batch-means interval. With
one run per value the interval is the run's batch-means interval
(cosim/stats.py says how the batches are chosen), each batch at least
``--batch-time`` seconds long (default ``scenario.dbp_window``, 0.1 s: it
should cover the traction's correlation time, a lug's passage); a window
too short for 8 such batches, or whose batch means stay correlated, has no
interval (empty: too short to say).

A drawbar-pull scene (``scenario.rig = "dbp"``) sweeps the slip within each
run, so its window means mix slips; its answer is the traction-slip curve:
per value, ``DIR/dbp/`` (``DIR/dbp_<key>=<value>/`` for several values) holds
``dbp_curve.csv`` and ``dbp.png``, the curve across that value's runs
(``--repeat N``: N beds; cosim.fig_dbp.write_across: per slip bin the mean of
the runs' bin means and its 95 % interval from their spread), beside the
reference.

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
from . import stats
from .traction import QUANTITIES, is_dbp, summarise_run, travel_window  # noqa: F401 (report.py)
from .terra_ref import draw_reference, read_reference
from . import fig_dbp
from .roles import cosim_executable
from .runner import _dir_name, concurrent_sets, grid_points, sweep as run_sweep
from .sweep_beds import BEDS_DIR

STATS = ["mean", "ci95", "min", "max"]  # ci95: half-width of the mean's 95 % interval
SUMMARY_FILE, PLOT_FILE, REFERENCE_FILE = "summary.csv", "summary.png", "reference.csv"
RUNS_FILE = "runs.csv"
DBP_DIR = "dbp"  # a dbp scene's curve across its runs (DIR/dbp, or DIR/dbp_<key>=<value>)
SEED_KEY = "seed"  # in a dem section's "particles" that generates a "bed"
DEFAULT_SEED = 1   # dem_server's default bed seed
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


def combine_runs(runs):
    """One summary row of the N run rows of one value: the mean of the run
    means with its interval from their spread (stats.across_runs), min and
    max over all runs, the windows' means; one run stands as it is."""
    if len(runs) == 1:
        return dict(runs[0])
    row = {c: float(np.mean([r[c] for r in runs]))
           for c in ("travel_start_s", "window_t0_s", "window_t1_s")}
    row["window_rows"] = int(sum(r["window_rows"] for r in runs))
    ok = [r for r in runs if r["window_rows"] > 0]
    row["runs"] = len(ok)
    for q in QUANTITIES:
        a = stats.across_runs([r[f"{q}_mean"] for r in ok])
        row[f"{q}_mean"], row[f"{q}_ci95"] = a["mean"], a["half"]
        row[f"{q}_min"] = min((r[f"{q}_min"] for r in ok), default=math.nan)
        row[f"{q}_max"] = max((r[f"{q}_max"] for r in ok), default=math.nan)
    return row


def summary_columns(keys):
    return (list(keys) + ["travel_start_s", "window_t0_s", "window_t1_s", "window_rows", "runs"] +
            [f"{q}_{st}" for q in QUANTITIES for st in STATS] + ["dir"])


def write_summary(path, keys, rows, skip_travel, per_run=False):
    cols = summary_columns(keys)
    with open(path, "w", newline="") as f:
        what = "per run" if per_run else "per value"
        f.write(f"# cosim sweep summary: {what}, mean, 95 % interval (ci95: half-width), min "
                "and max of /coupler/traction columns\n")
        f.write("# window: from the first row with vertical_load >= scenario.sinkage_force "
                f"(travel start) plus {skip_travel:g} m of travel at omega*radius*(1-slip), "
                "to the end of the run (columns window_t0_s, window_t1_s; over several runs "
                "their means)\n")
        f.write("# ci95: one run: non-overlapping batch means within its window, each batch at "
                "least --batch-time (default scenario.dbp_window, 0.1 s) long, none when the "
                "batch means stay correlated (cosim.stats.interval); several runs (column runs): Student t on the spread of the run "
                "means (cosim.stats.across_runs); empty (nan) when too short to say\n")
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
                try:
                    row[c] = float(v)  # nan, inf
                except ValueError:
                    row[c] = v
        rows.append(row)
    return rows


def draw(ax, key, rows, ref_path, ref_label="terramechanics"):
    """Seed 000 fig. 15 on one axis: T_H, |T_R|, T_P over the swept key (mean
    with its 95 % interval where the rows have one, the min–max range as a
    faint band), the reference's T/r, T/r - DP and DP dashed."""
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
        ci = np.array([r.get(f"{q}_ci95", math.nan) for r in rows], float)
        order = np.argsort(at)
        ax.fill_between(at[order], lo[order], hi[order], color=color, alpha=0.08, lw=0)
        if np.isfinite(ci).any():
            ax.errorbar(at, mean, yerr=np.where(np.isfinite(ci), ci, 0), fmt="o-", color=color,
                        capsize=4, label=f"DEM–FEM {label}: mean, 95 % interval (band: min–max)")
        else:
            ax.errorbar(at, mean, yerr=[mean - lo, hi - mean], fmt="o-", color=color,
                        capsize=4, label=f"DEM–FEM {label}: mean, min–max")
    if ref_path:
        draw_reference(ax, read_reference(ref_path), ref_label)
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


def seed_key(scene_path, sets):
    """(key path, first seed) of the one dem section that generates its bed;
    a UsageError naming what is missing otherwise (--repeat needs a bed to
    vary)."""
    with open(scene_path) as f:
        scene = json.load(f)
    found = [n for n, p in scene.get("processes", {}).items()
             if isinstance(p, dict) and isinstance(p.get("particles"), dict)
             and p["particles"].get("generate") == "bed"]
    if len(found) != 1:
        raise UsageError(f"--repeat: needs exactly one process whose particles.generate is "
                         f"\"bed\" (its seed is varied); {scene_path} has {len(found)}")
    key = f"processes.{found[0]}.particles.{SEED_KEY}"
    s0 = sets.pop(key, scene["processes"][found[0]]["particles"].get(SEED_KEY, DEFAULT_SEED))
    if not isinstance(s0, int) or isinstance(s0, bool) or s0 < 0:
        raise UsageError(f"{key}: expected a non-negative integer seed, got {json.dumps(s0)}")
    return key, s0


def group_rows(key, rows):
    """The run rows of each value of key, in order of first appearance."""
    groups = {}
    for r in rows:
        groups.setdefault(json.dumps(r[key]), []).append(r)
    out = []
    for runs in groups.values():
        row = combine_runs(runs)
        row[key] = runs[0][key]
        row["dir"] = ";".join(r["dir"] for r in runs)
        out.append(row)
    return out


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # exit 1 (bad usage), as cosim run
        raise UsageError(f"{message}\n{self.format_usage().strip()}")


def main(argv):
    ap = _Parser(prog="cosim sweep", description=__doc__.split("\n\n")[0])
    ap.add_argument("scene")
    ap.add_argument("--values", required=True, metavar="KEY.PATH=V1,V2,...")
    ap.add_argument("--set", action="append", default=[], metavar="KEY.PATH=VALUE")
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--repeat", type=int, default=1, metavar="N",
                    help="N realisations per value, on beds of seeds s0 .. s0+N-1")
    ap.add_argument("--out", required=True)
    ap.add_argument("--skip-travel", type=float, default=DEFAULT_SKIP_TRAVEL_M, metavar="M")
    ap.add_argument("--batch-time", type=float, default=None, metavar="S",
                    help="shortest batch of an interval (default scenario.dbp_window, 0.1 s)")
    ap.add_argument("--reference", metavar="REF.csv")
    ap.add_argument("--terra-params", metavar="PARAMS.json")
    ap.add_argument("--overwrite", action="store_true")
    ap.add_argument("--keep-going", action="store_true")
    ap.add_argument("--resume", action="store_true",
                    help="skip the points already run to time.end; rerun the rest")
    ap.add_argument("--no-bed-reuse", action="store_true",
                    help="every run settles its own bed (default: once per bed, in DIR/beds)")
    ap.add_argument("--summary-only", action="store_true",
                    help="summarise the runs already in --out")
    ap.add_argument("--cosim", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.jobs < 1:
        raise UsageError(f"--jobs: must be at least 1, got {args.jobs}")
    if args.repeat < 1:
        raise UsageError(f"--repeat: must be at least 1, got {args.repeat}")
    if args.skip_travel < 0:
        raise UsageError(f"--skip-travel: must be >= 0, got {args.skip_travel:g}")
    if args.batch_time is not None and not args.batch_time > 0:
        raise UsageError(f"--batch-time: must be > 0 s, got {args.batch_time:g}")
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
    grid = {key: values}
    if args.repeat > 1:
        skey, s0 = seed_key(args.scene, sets)
        grid[skey] = list(range(s0, s0 + args.repeat))
    os.makedirs(args.out, exist_ok=True)
    if not args.summary_only:
        check_points(args.scene, sets, key, values, args.cosim)
        run_args = ["--overwrite"] if args.overwrite else []
        shared = concurrent_sets(sets, args.jobs, args.scene)  # what sweep() would add itself
        added = ", ".join(f"{k} {json.dumps(v)}" for k, v in shared.items() if k not in sets)
        if added:
            print(f"cosim sweep: --jobs {args.jobs}: the runs get {added} (they share the "
                  "cores; --set to choose)", flush=True)
        sets = shared
        beds = None if args.no_bed_reuse else os.path.join(args.out, BEDS_DIR)
        done = run_sweep(args.scene, grid, args.out, set=sets, jobs=args.jobs,
                         keep_going=args.keep_going, quiet=True, cosim=args.cosim,
                         args=run_args, beds=beds, resume=args.resume)
    else:
        done = [(p, os.path.join(args.out, _dir_name(p))) for p in grid_points(grid)]
    rows, scene = [], None
    for point, res in done:
        d = os.path.join(args.out, _dir_name(point))
        if isinstance(res, Exception):
            print(f"cosim sweep: {res}", file=sys.stderr)
            continue
        with (res if isinstance(res, Results) else Results(res)) as r:
            row = summarise_run(r, args.skip_travel, args.batch_time)
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
    finished = len(rows)
    if args.repeat > 1:
        write_summary(os.path.join(args.out, RUNS_FILE), list(grid), rows, args.skip_travel,
                      per_run=True)
        rows = group_rows(key, rows)
    write_summary(os.path.join(args.out, SUMMARY_FILE), [key], rows, args.skip_travel)
    ref = reference_curve(args, scene, args.out)
    title = f"{scene.get('name', args.scene)}: traction over the steady travel"
    load = scene.get("scenario", {}).get("sinkage_force")
    plot(os.path.join(args.out, PLOT_FILE), key, rows, ref, title,
         f"terramechanics ({load:g} N)" if args.terra_params and load else "terramechanics")
    print(f"summary: {os.path.join(args.out, SUMMARY_FILE)}, plot: "
          f"{os.path.join(args.out, PLOT_FILE)}")
    if scene and is_dbp(scene):
        # a dbp run's window mixes the slips its ramp swept: its curve is the answer
        for row in rows:
            dirs = [os.path.join(args.out, d) for d in row["dir"].split(";")]
            out = os.path.join(args.out, DBP_DIR if len(rows) == 1 else
                               f"{DBP_DIR}_{_dir_name({key: row[key]})}")
            try:
                csv_path, png, bins = fig_dbp.write_across(dirs, out, reference=ref)
            except CosimError as e:
                print(f"cosim sweep: dbp curve of {key}={json.dumps(row[key])}: {e}", file=sys.stderr)
                continue
            print(f"dbp curve over {len(dirs)} run(s) of {key}={json.dumps(row[key])} "
                  f"({bins} slip bins): {csv_path}, {png} (summary.csv's window means mix the "
                  "slips the ramp swept)")
    return 0 if finished == len(done) else 3
