"""Branches of one state under two coupling schemes, window by window: the
serial-vs-implicit row of the convergence table
(bench/results/sand_calibration.md "Convergence: serial vs implicit"; the
runs: run_sand_branch.sh).

    PYTHONPATH=python /usr/bin/python3 bench/tire_soil/compare_branch.py OUT
        [--a serial] [--b implicit] [--group 5%:1:24000,2:28000,...] [--out CSV]

OUT/<a>/seed<S>_k<K>/ and OUT/<b>/seed<S>_k<K>/ are two branches from the
checkpoint of step K of bed S's run: the same state, then each scheme for the
same steps (one lug passage). Per pair, the window means (every row of the
branch) of T_H, T_R, T_P and the vertical load (N), the sinkage (mm), the slip
(the rig's, unaveraged), the coupler's iterations per step, the largest
overlap (of a radius) and the wall time per step; per group of pairs (--group
NAME:S:K,S:K;NAME:...: the pairs at one slip, e.g. 5 % and 20 %) the mean of
the paired differences b - a with the 95 % half-width of Student t on n - 1
dof (cosim.stats.across_runs), "within" when |mean| <= half-width, and the
largest |b - a| against the load. The wall times are per step of each run
with the others of its batch beside it (run_sand_branch.sh runs a stage's
runs at once), so their ratio is the cost of b against a."""
import argparse
import csv
import os
import re
import sys

import numpy as np

from cosim import Results, stats

FORCES = ("T_H", "T_R", "T_P", "vertical_load")


def window(run_dir):
    """{quantity: value} over one branch's rows."""
    with Results(run_dir) as res:
        tr = res.series("coupler", "traction")
        dbp = res.series("coupler", "dbp")
        cs = res.series("coupler", "series")
        soil = res.series("soil")
        wall = res.timing["wall"]
        out = {q: float(np.mean(tr[q])) for q in FORCES}
        out["sinkage"] = 1e3 * float(np.mean(tr["sinkage"]))
        out["slip"] = float(np.mean(dbp["slip"]))
        out["iterations"] = float(np.mean(cs["iterations"]))
        out["unconverged"] = int(np.count_nonzero(cs["converged"] == 0))
        out["max_overlap"] = float(np.max(soil["max_overlap_ratio"]))
        out["steps"] = len(tr["t"])
        out["t0"], out["t1"] = float(tr["t"][0]), float(tr["t"][-1])
        out["ms_per_step"] = 1e3 * float(np.mean(wall))  # /coupler/timing: per step
        out["load"] = float(res.scene["scenario"]["sinkage_force"])
    return out


def pairs(out_dir, a, b):
    """{(seed, step): (a dir, b dir)} for every branch on both sides."""
    found = {}
    side = os.path.join(out_dir, b)
    if not os.path.isdir(side):
        sys.exit(f"compare_branch: {side} does not exist")
    for name in sorted(os.listdir(side)):
        m = re.fullmatch(r"seed(\d+)_k(\d+)", name)
        if m and os.path.isdir(os.path.join(out_dir, a, name)):
            found[(int(m[1]), int(m[2]))] = (os.path.join(out_dir, a, name), os.path.join(side, name))
    if not found:
        sys.exit(f"compare_branch: no seed<S>_k<K> under both {a}/ and {b}/ in {out_dir}")
    return found


def parse_groups(text, keys):
    if not text:
        return [("all", sorted(keys))]
    groups = []
    for part in text.split(";"):
        name, _, members = part.partition(":")
        sel = []
        for sk in members.split(","):
            s, _, k = sk.partition(":")
            if (int(s), int(k)) not in keys:
                sys.exit(f"compare_branch: --group {name}: no pair seed{s}_k{k}")
            sel.append((int(s), int(k)))
        groups.append((name, sel))
    return groups


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out_dir")
    ap.add_argument("--a", default="serial")
    ap.add_argument("--b", default="implicit")
    ap.add_argument("--group", default="", help="NAME:S:K,S:K;NAME:... (default: one group)")
    ap.add_argument("--out", help="the table as CSV")
    args = ap.parse_args()
    found = pairs(args.out_dir, args.a, args.b)
    vals = {key: (window(da), window(db)) for key, (da, db) in found.items()}
    rows = []
    print(f"{'seed':>4} {'step':>6} {'slip':>6}  " + "  ".join(f"{q:>16}" for q in FORCES + ("sinkage",))
          + f"  {'iter':>5} {'ms/step a, b':>14}")
    for (s, k), (va, vb) in sorted(vals.items()):
        if va["steps"] != vb["steps"] or abs(va["t0"] - vb["t0"]) > 1e-12:
            sys.exit(f"compare_branch: seed{s}_k{k}: the branches cover other steps "
                     f"({va['steps']} from t = {va['t0']}, {vb['steps']} from {vb['t0']})")
        cells = "  ".join(f"{va[q]:7.1f} {vb[q] - va[q]:+8.2f}" for q in FORCES + ("sinkage",))
        print(f"{s:>4} {k:>6} {va['slip']:6.3f}  {cells}  {vb['iterations']:5.2f} "
              f"{va['ms_per_step']:6.2f} {vb['ms_per_step']:6.2f}")
        rows.append({"seed": s, "step": k, **{f"a_{q}": v for q, v in va.items()},
                     **{f"b_{q}": v for q, v in vb.items()}})
    summary = []
    for name, members in parse_groups(args.group, vals):
        load = vals[members[0]][0]["load"]
        slip = np.mean([vals[m][0]["slip"] for m in members])
        print(f"\n{name}: {len(members)} pairs, slip {slip:.3f} (a), load {load:g} N")
        for q in FORCES + ("sinkage",):
            d = [vals[m][1][q] - vals[m][0][q] for m in members]
            acr = stats.across_runs(d)
            mean, half = acr["mean"], acr["half"]
            within = abs(mean) <= half
            scale = load if q != "sinkage" else 1.0
            print(f"  {q:>14}: b - a = {mean:+8.2f} +- {half:7.2f} ({'within' if within else 'OUTSIDE'})"
                  f", largest |b - a| {max(abs(x) for x in d) / scale:.3f}"
                  f"{' W' if q != 'sinkage' else ' mm'}")
            summary.append({"group": name, "quantity": q, "pairs": len(members), "slip_a": slip,
                            "mean_b_minus_a": mean, "ci95": half, "within": int(within),
                            "largest_abs_over_W": max(abs(x) for x in d) / scale if q != "sinkage" else "",
                            "largest_abs_mm": max(abs(x) for x in d) if q == "sinkage" else ""})
        ra = np.mean([vals[m][0]["ms_per_step"] for m in members])
        rb = np.mean([vals[m][1]["ms_per_step"] for m in members])
        it = np.mean([vals[m][1]["iterations"] for m in members])
        print(f"  cost: {rb:.2f} against {ra:.2f} ms per step = {rb / ra:.2f}x; "
              f"{it:.2f} iterations per step (b)")
    if args.out:
        with open(args.out, "w", newline="") as f:
            f.write(f"# compare_branch.py {args.out_dir}: a = {args.a}, b = {args.b}; per pair the "
                    "window means (a_*, b_*), then per group the paired differences\n")
            w = csv.DictWriter(f, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)
            f.write("\n")
            w = csv.DictWriter(f, fieldnames=list(summary[0]))
            w.writeheader()
            w.writerows(summary)


if __name__ == "__main__":
    main()
