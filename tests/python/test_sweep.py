"""`cosim sweep` (python/cosim/sweep_cli.py through the cosim binary):

1. a tiny tyre-travel scene on stubs, two slips, two runs at once: each run
   in its own DIR/<key>=<value>/, summary.csv has the documented columns, one
   row per value, and every mean/min/max equals what the test computes itself
   from that run's results.h5 over the window it derives on its own (first
   row at the target load, plus the skipped travel at omega R (1 - s));
   the PNG is written;
2. bad arguments exit 1 with a message naming what is wrong, before any run;
3. a scene's top-level "notes" is accepted as a string and refused otherwise.
"""
import csv
import json
import os
import subprocess
import sys

import h5py
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "e2e"))
from common import COSIM, check, done, scene, scratch, write  # noqa: E402
import cosim  # noqa: E402

SLIPS = [0.0, 0.2]
SKIP = 0.01  # m of travel left out of the window
SCEN = {"kind": "tire_travel", "rim_center": [0, 0, 0.3], "sinkage_velocity": 0.1,
        "sinkage_force": 20, "slip": 0.05, "omega": 1.8, "radius": 0.272}
s = scene("sweep", {
    "fem": {"exec": "fem_stub", "surface": {"plane": {"size": [0.2, 0.16], "n": [4, 4], "z": -0.27}}},
    # the ramp (0.15 s) outlasts the travel start (~0.12 s): the window's values vary
    "dem": {"exec": "dem_stub", "force_per_node": [-0.1, 0.0, 1.0], "ramp_time": 0.15}},
    scenario=SCEN)
s["time"] = {"dt": 1e-3, "end": 0.25}
path = write(s)
out = scratch("cosim-sweep-")


BATCH_TIME = 0.004  # s: batches of at least 4 rows (dt 1e-3)


def batch_half(x, min_rows=4):
    """95 % half-width of the mean by batch means, as the summary documents it:
    32 batches, halved while the batch means' lag-1 correlation is above 0.2,
    at least 8 batches of min_rows (>= 4) rows, none when still correlated
    at the fewest; Student t with b - 1 degrees of freedom."""
    from scipy.stats import t as student
    b = min(32, len(x) // max(4, min_rows))
    while b >= 8:
        m = len(x) // b
        bm = x[:b * m].reshape(b, m).mean(axis=1)
        d = bm - bm.mean()
        r = (d[1:] @ d[:-1]) / (d @ d) if d @ d > 0 else 0.0
        if r <= 0.2:
            return student.ppf(0.975, b - 1) * bm.std(ddof=1) / np.sqrt(b)
        if b // 2 < 8:
            return float("nan")  # still correlated at the fewest batches
        b //= 2
    return float("nan")


def sweep(*args):
    p = subprocess.run([COSIM, "sweep", *args], capture_output=True, text=True, timeout=120)
    return p.returncode, p.stdout, p.stderr


# 1. two runs at once, summary against results.h5
rc, so, se = sweep(path, "--values", "scenario.slip=" + ",".join(map(str, SLIPS)),
                   "--jobs", "2", "--out", out, "--skip-travel", str(SKIP),
                   "--batch-time", str(BATCH_TIME))
check(rc == 0, f"sweep exits 0 (got {rc}: {se.strip()[-400:]})")
with open(os.path.join(out, "summary.csv")) as f:
    lines = f.read().splitlines()
comments = [l for l in lines if l.startswith("#")]
check(any(l.startswith("# window:") for l in comments), "summary.csv states the window")
rows = list(csv.DictReader(l for l in lines if not l.startswith("#")))
Q = ["T_H", "T_R", "T_P", "vertical_load", "sinkage"]
want_cols = (["scenario.slip", "travel_start_s", "window_t0_s", "window_t1_s", "window_rows",
              "runs"] + [f"{q}_{st}" for q in Q for st in ("mean", "ci95", "min", "max")] + ["dir"])
check(rows and list(rows[0].keys()) == want_cols, f"summary.csv columns {want_cols}")
check(len(rows) == len(SLIPS), f"one row per value ({len(rows)})")
api_rows = {}
for slip, row in zip(SLIPS, rows):
    check(float(row["scenario.slip"]) == slip, f"row for slip {slip}")
    h5 = os.path.join(out, row["dir"], "results.h5")
    check(row["dir"] == f"scenario.slip={slip}" and os.path.isfile(h5), f"run dir of slip {slip}")
    with h5py.File(h5, "r") as f:
        cols = [c.decode() if isinstance(c, bytes) else c for c in f["coupler/traction"].attrs["columns"]]
        tr = f["coupler/traction"][()]
        used = json.loads(f.attrs["config"])
    check(used["scenario"]["slip"] == slip, f"run of slip {slip} used slip {used['scenario']['slip']}")
    col = {c: tr[:, i] for i, c in enumerate(cols)}
    with cosim.Results(os.path.join(out, row["dir"])) as res:
        api_rows[slip] = res.traction_summary(SKIP, BATCH_TIME)
    start = col["t"][np.argmax(col["vertical_load"] >= SCEN["sinkage_force"])]
    t0 = start + SKIP / (SCEN["omega"] * SCEN["radius"] * (1 - slip))
    w = col["t"] >= t0
    check(0 < w.sum() < len(w) and int(row["window_rows"]) == w.sum(),
          f"slip {slip}: window rows {row['window_rows']} == {w.sum()}")
    check(abs(float(row["window_t0_s"]) - t0) < 1e-9 and float(row["window_t1_s"]) == col["t"][-1],
          f"slip {slip}: window [{row['window_t0_s']}, {row['window_t1_s']}]")
    check(np.ptp(col["vertical_load"][w]) > 0, "the load varies over the window (test is not trivial)")
    for q in Q:
        for st, fn in (("mean", np.mean), ("min", np.min), ("max", np.max)):
            got, ref = float(row[f"{q}_{st}"]), float(fn(col[q][w]))
            check(abs(got - ref) <= 1e-8 * max(1.0, abs(ref)), f"slip {slip} {q}_{st}: {got} vs {ref}")
        api = api_rows[slip][f"{q}_ci95"]
        check((np.isnan(api) and np.isnan(float(row[f"{q}_ci95"]))) or
              abs(api - float(row[f"{q}_ci95"])) <= 1e-8 * abs(api),
              f"slip {slip} {q}_ci95: Results.traction_summary gives summary.csv's ({api})")
        got, ref = float(row[f"{q}_ci95"]), batch_half(col[q][w])
        check((np.isnan(got) and np.isnan(ref)) or abs(got - ref) <= 1e-8 * max(1e-12, abs(ref)),
              f"slip {slip} {q}_ci95: {got} vs batch means {ref}")
check(any(np.isfinite(float(r[f"{q}_ci95"])) and float(r[f"{q}_ci95"]) > 0 for r in rows for q in Q),
      "some interval is finite and non-zero (the comparison above is not only nan == nan)")
check(os.path.getsize(os.path.join(out, "summary.png")) > 1000, "summary.png written")

# the summary again, now beside the terramechanics reference for the scene's wheel
params = os.path.join(HERE, "..", "..", "bench", "results", "tire_soil_terra_params_deep.json")
os.remove(os.path.join(out, "summary.png"))
rc, so, se = sweep(path, "--values", "scenario.slip=" + ",".join(map(str, SLIPS)), "--out", out,
                   "--skip-travel", str(SKIP), "--summary-only", "--terra-params", params)
check(rc == 0 and os.path.getsize(os.path.join(out, "summary.png")) > 1000,
      f"--summary-only --terra-params redraws the plot (got {rc}: {se.strip()[-300:]})")
ref_path = os.path.join(out, "reference.csv")
ref = open(ref_path).read() if os.path.exists(ref_path) else ""
check(f"# load_N: {SCEN['sinkage_force']}" in ref and "T_over_r" in ref,
      "the reference is computed for the scene's load")

# a record given with --reference from elsewhere is copied into the sweep's dir (which then
# holds everything its plot draws)
elsewhere = os.path.join(scratch("cosim-sweep-ref-"), "my_reference.csv")
open(elsewhere, "w").write(ref)
os.remove(ref_path)
rc, so, se = sweep(path, "--values", "scenario.slip=" + ",".join(map(str, SLIPS)), "--out", out,
                   "--skip-travel", str(SKIP), "--summary-only", "--reference", elsewhere)
check(rc == 0 and os.path.exists(ref_path) and open(ref_path).read() == ref,
      f"--reference is copied to the sweep's reference.csv (got {rc}: {se.strip()[-300:]})")

# 2. bad arguments: exit 1, the message names the problem, no run started
bad = scratch("cosim-sweep-bad-")
cases = [
    ([path, "--out", bad], "--values"),
    ([path, "--values", "scenario.slip", "--out", bad], "KEY.PATH=V1,V2"),
    ([path, "--values", "scenario.slip=0,,0.1", "--out", bad], "empty value"),
    ([path, "--values", "scenario.slip=0,0", "--out", bad], "given twice"),
    ([path, "--values", "scenario.slipp=0,0.1", "--out", bad], "scenario.slipp"),
    ([path, "--values", "scenario.slip=\"fast\"", "--out", bad], "scenario.slip"),
    ([path, "--values", "scenario.slip=0,0.1", "--jobs", "0", "--out", bad], "--jobs"),
    ([path, "--values", "scenario.slip=0,0.1", "--repeat", "0", "--out", bad], "--repeat"),
    # the stub soil has no bed whose seed could vary
    ([path, "--values", "scenario.slip=0", "--repeat", "2", "--out", bad], "particles.generate"),
    ([path, "--values", "scenario.slip=0", "--set", "scenario.slip=0.1", "--out", bad],
     "both in --values and --set"),
    ([path + ".missing", "--values", "scenario.slip=0", "--out", bad], "no such scene"),
]
for args, want in cases:
    rc, so, se = sweep(*args)
    check(rc == 1 and want in se, f"{' '.join(args[1:])}: exit 1 naming '{want}' "
          f"(got {rc}: {se.strip()[-300:]})")
check(not [d for d in os.listdir(bad) if d.startswith("scenario")], "no run started on bad arguments")

# 3. a scene's "notes" (the paper scenes' reading of the tables) must be a string
for notes, ok in (("why the numbers are what they are", True), (5, False), (["a"], False)):
    s2 = dict(s, notes=notes)
    p = subprocess.run([COSIM, "check", write(s2)], capture_output=True, text=True, timeout=60)
    check((p.returncode == 0) == ok and (ok or "notes: expected a string" in p.stderr),
          f"notes = {notes!r}: {'accepted' if ok else 'refused by name'} (got {p.returncode}: {p.stderr.strip()})")
done()
