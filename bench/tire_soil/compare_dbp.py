"""Two dbp sweeps of the sand scene side by side: one row of the convergence
table (bench/results/sand_calibration.md).

    PYTHONPATH=python /usr/bin/python3 bench/tire_soil/compare_dbp.py A B
        [--paired] [--bin-width 0.05] [--window S] [--slip-min 0] [--slip-max 0.40] [--out CSV]
        [--title TEXT] [--save-a A_RUNS.csv] [--save-b B_RUNS.csv]

A, B: `cosim sweep` output dirs (their runs.csv lists the runs; a = the
reference setting, b = the changed one), or a side's per-run bin means saved
earlier with --save-a/--save-b (a CSV: seed, slip_lo and the quantities, one
row per run and bin): a row's reference need not be run again in a later
sitting once its runs are gone (the values, not the wall time, carry over).
Per slip bin (edges at multiples of the width, from --slip-min to
--slip-max) and quantity (T_H, T_R, T_P, vertical load in N, sinkage in mm),
each run's bin mean (cosim.traction.dbp_curve: the rows averaged over --window
s, default each run's scenario.dbp_window, 0 for none; both sides must have
the same window, a saved side says its own), then:

- --paired (the same beds on both sides: runs matched by
  processes.soil.particles.seed): the per-bed differences b - a, their mean
  +- the 95 % half-width of Student t on n - 1 dof (cosim.stats.across_runs);
  "within" when |mean| <= half-width;
- otherwise (different beds): each side's mean across its runs +- its 95 %
  half-width, and "within" when |b - a| <= sqrt(half_a^2 + half_b^2), the
  combined half-width the earlier rows used (wider than a Welch interval for
  equal spreads: it errs towards "within", so the count of bins outside is
  the figure to read, beside the differences themselves).

Prints the count of T_H / T_R / T_P comparisons within and the largest |b - a|
against the load W (scenario.sinkage_force); --out writes the table as CSV
with a comment line that says which is which."""
import argparse
import csv
import math
import os
import sys

from cosim import Results, read_summary, stats, traction

# the dbp curve's quantities but the rig's own resistive force
QUANTITIES = tuple(q for q in traction.DBP_QUANTITIES if q != "resistive_force")
SCALE = {"sinkage": 1e3}  # m -> mm; the forces in N
SEED_KEY = "processes.soil.particles.seed"


def sweep_runs(sweep_dir):
    """[(seed, run dir)] of a sweep, in runs.csv order (cosim.read_summary)."""
    path = os.path.join(sweep_dir, "runs.csv")
    if not os.path.exists(path):
        sys.exit(f"compare_dbp: {path} does not exist: is '{sweep_dir}' a cosim sweep output dir?")
    rows = read_summary(path)
    if not rows or "dir" not in rows[0]:
        sys.exit(f"compare_dbp: {path} lists no runs (no 'dir' column)")
    return [(r.get(SEED_KEY), os.path.join(sweep_dir, str(r["dir"]))) for r in rows]


def bin_means(run_dir, width, window):
    """{bin index: {quantity: mean}} of one run, its load W and the window
    (s) its rows were averaged over."""
    with Results(run_dir) as res:
        curve = traction.dbp_curve(res, width, window=window)
        load = float(res.scene["scenario"]["sinkage_force"])
        window_s = traction.window_seconds(res.scene, window)
    if not curve:
        sys.exit(f"compare_dbp: {run_dir} has no dbp ramp rows (not a dbp run?)")
    return {round(r["slip_lo"] / width): {q: r[f"{q}_mean"] * SCALE.get(q, 1.0) for q in QUANTITIES}
            for r in curve}, load, window_s


BINS_HEAD = "# cosim dbp per-run bin means (compare_dbp.py): bin width "
WINDOW_WORD = "; rows averaged over "  # the saved window, s; a file without it: unaveraged
# two sides' windows are one when they differ by less than this (relative): each is a whole
# number of its run's steps (0.10908 s is 0.109075 s at 12.5 us and 0.10908 at 6.25 us)
WINDOW_REL_TOL = 1e-3


def saved_bins(path, width):
    """([(seed, {bin index: {quantity: mean}}, load)], window s) from a
    --save-a/--save-b CSV."""
    with open(path) as f:
        head = f.readline()  # BINS_HEAD, the width, the window
    if not head.startswith(BINS_HEAD):
        sys.exit(f"compare_dbp: {path} is not a file of per-run bin means (--save-a/--save-b)")
    try:
        window_s = float(head.split(WINDOW_WORD)[1].split()[0]) if WINDOW_WORD in head else 0.0
    except (IndexError, ValueError):
        sys.exit(f"compare_dbp: {path}: no number after '{WINDOW_WORD.strip('; ')}' in its first line")
    saved = float(head[len(BINS_HEAD):].split()[0])
    if abs(saved - width) > 1e-12:
        sys.exit(f"compare_dbp: {path} has bins of {saved:g}, not --bin-width {width:g}")
    runs = {}
    for r in read_summary(path):
        try:
            bins = {q: float(r[q]) for q in QUANTITIES}
            k = round(float(r["slip_lo"]) / width)
            runs.setdefault(str(r["seed"]), ({}, float(r["load"])))[0][k] = bins
        except (KeyError, TypeError, ValueError) as e:
            sys.exit(f"compare_dbp: {path}: a row without a number for {e}: {r}")
    return [(s, m, w) for s, (m, w) in runs.items()], window_s


def side_bins(src, width, window):
    """A side's runs, [(seed, bins, load)], and the window (s) of their rows'
    averages (a window of one row, unaveraged, is 0), from a sweep dir or a
    saved CSV."""
    if os.path.isfile(src):
        return saved_bins(src, width)
    runs, windows = [], set()
    for s, d in sweep_runs(src):
        bins, load, window_s = bin_means(d, width, window)
        runs.append((str(s), bins, load))
        windows.add(window_s)
    if len(windows) != 1:
        sys.exit(f"compare_dbp: {src}: its runs' windows differ ({sorted(windows)} s)")
    return runs, windows.pop()


def save_bins(path, side, width, window_s):
    tmp = path + ".tmp"
    with open(tmp, "w", newline="") as f:
        f.write(f"{BINS_HEAD}{width:g} (slip){WINDOW_WORD}{window_s:.6g} s (centred; 0: "
                "unaveraged); forces in N, sinkage in mm, load in N\n")
        w = csv.writer(f)
        w.writerow(["seed", "slip_lo", *QUANTITIES, "load"])
        for seed, bins, load in side:
            for k in sorted(bins):
                w.writerow([seed, f"{k * width:.4f}", *(repr(bins[k][q]) for q in QUANTITIES), repr(load)])
    os.replace(tmp, path)


def compare(sa, sb, paired, width, slip_min, slip_max):
    """sa, sb: each side's [(seed, bins, load)] (side_bins)."""
    if paired:
        seeds_b = {s: (m, w) for s, m, w in sb}
        common = [(s, m, w) for s, m, w in sa if s in seeds_b]
        if len(common) < 2:
            sys.exit("compare_dbp: --paired needs at least two seeds run in both sweeps "
                     f"(a: {[s for s, _, _ in sa]}, b: {[s for s, _, _ in sb]})")
        sa, sb = common, [(s, *seeds_b[s]) for s, _, _ in common]
    ma = [(m, w) for _, m, w in sa]
    mb = [(m, w) for _, m, w in sb]
    loads = {w for _, w in ma + mb}
    if len(loads) != 1:
        sys.exit(f"compare_dbp: the runs differ in scenario.sinkage_force {sorted(loads)}: not one curve")
    load = loads.pop()
    kmin, kmax = math.ceil(slip_min / width - 1e-9), math.floor(slip_max / width + 1e-9)
    keys = sorted(k for k in set.intersection(*[set(m) for m, _ in ma + mb]) if kmin <= k < kmax)
    rows = []
    for k in keys:
        for q in QUANTITIES:
            va = [m[k][q] for m, _ in ma]
            vb = [m[k][q] for m, _ in mb]
            a, b = stats.across_runs(va), stats.across_runs(vb)
            if paired:
                d = stats.across_runs([y - x for x, y in zip(va, vb)])
                diff, half = d["mean"], d["half"]
            else:
                diff, half = b["mean"] - a["mean"], math.hypot(a["half"], b["half"])
            rows.append({"slip_lo": k * width, "quantity": q, "a_mean": a["mean"], "a_ci95": a["half"],
                         "b_mean": b["mean"], "b_ci95": b["half"], "diff": diff, "diff_ci95": half,
                         "within": "yes" if abs(diff) <= half else "NO"})
    return rows, load, len(sa), len(sb)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("a", help="the reference sweep's output dir")
    ap.add_argument("b", help="the changed sweep's output dir")
    ap.add_argument("--paired", action="store_true", help="the same beds: pair the runs by seed")
    ap.add_argument("--bin-width", type=float, default=0.05)
    ap.add_argument("--window", type=float, help="average each row over this many s first "
                    "(default each run's scenario.dbp_window; 0: none)")
    ap.add_argument("--slip-min", type=float, default=0.0)
    ap.add_argument("--slip-max", type=float, default=0.40)
    ap.add_argument("--out", help="CSV to write")
    ap.add_argument("--title", default="", help="the CSV's comment line (what a and b are)")
    ap.add_argument("--save-a", help="write a's per-run bin means to this CSV (to compare with later)")
    ap.add_argument("--save-b", help="write b's per-run bin means to this CSV")
    o = ap.parse_args()
    if not (o.bin_width > 0) or not (o.slip_max > o.slip_min):
        sys.exit("compare_dbp: --bin-width must be positive and --slip-max above --slip-min")
    if o.window is not None and not (o.window >= 0 and math.isfinite(o.window)):
        sys.exit(f"compare_dbp: --window must be >= 0 s, got {o.window}")
    (sa, wa), (sb, wb) = side_bins(o.a, o.bin_width, o.window), side_bins(o.b, o.bin_width, o.window)
    if abs(wa - wb) > WINDOW_REL_TOL * max(wa, wb):  # whole rows of each side's step
        sys.exit(f"compare_dbp: a's rows are averaged over {wa:g} s, b's over {wb:g} s: give "
                 "--window (a saved side keeps the window it was saved with)")
    for path, side, window_s in ((o.save_a, sa, wa), (o.save_b, sb, wb)):
        if path:
            save_bins(path, side, o.bin_width, window_s)
    rows, load, na, nb = compare(sa, sb, o.paired, o.bin_width, o.slip_min, o.slip_max)
    if not rows:
        sys.exit("compare_dbp: no slip bin from --slip-min to --slip-max is filled in every run")
    forces = [r for r in rows if r["quantity"] in ("T_H", "T_R", "T_P")]
    within = sum(r["within"] == "yes" for r in forces)
    worst = max(forces, key=lambda r: abs(r["diff"]))
    how = "paired by seed" if o.paired else "unpaired"
    if o.out:  # before the printout: a reader that closes the pipe early loses nothing
        tmp = o.out + ".tmp"
        with open(tmp, "w", newline="") as f:
            f.write(f"# {o.title or 'a = ' + o.a + ', b = ' + o.b}; {how}; bins of {o.bin_width:g} in slip, "
                    f"rows averaged over {wa:.6g} s; "
                    f"W = {load:g} N; forces in N, sinkage in mm; within: |diff| <= diff_ci95 "
                    f"({'Student t on the per-bed differences' if o.paired else 'sqrt(a_ci95^2 + b_ci95^2)'})\n")
            w = csv.DictWriter(f, fieldnames=list(rows[0]))
            w.writeheader()
            for r in rows:
                w.writerow({k: (f"{v:.2f}" if isinstance(v, float) else v) for k, v in r.items()})
        os.replace(tmp, o.out)
    print(f"{how}: a {na} runs, b {nb} runs; T_H/T_R/T_P within: {within} of {len(forces)}; "
          f"largest |b - a| {abs(worst['diff']):.1f} N = {abs(worst['diff']) / load:.3f} W "
          f"({worst['quantity']} at {worst['slip_lo']:.2f})")
    for r in rows:
        print(f"  {r['slip_lo']:5.2f} {r['quantity']:>13}  a {r['a_mean']:8.1f} +- {r['a_ci95']:6.1f}  "
              f"b {r['b_mean']:8.1f} +- {r['b_ci95']:6.1f}  b-a {r['diff']:7.1f} +- {r['diff_ci95']:6.1f}  "
              f"{r['within']}")


if __name__ == "__main__":
    main()
