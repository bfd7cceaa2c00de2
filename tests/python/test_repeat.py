"""`cosim sweep --repeat N`: independent realisations on different beds.

The default scene (a small three-layer bed generated and settled in the run),
cut to a few coupled steps: `--repeat 2` runs seeds s0 and s0 + 1 of the bed
generator (s0 from the scene: 1). Checked:
1. runs.csv has one row per (value, seed), each run in its own directory,
   whose results.h5 used the bed settled with that seed;
2. the two realisations differ (the settled grains are not where the other
   bed's are): different beds, not one bed twice;
3. a realisation is reproducible: seed 2 run again on its own with `cosim run`
   gives the same results.h5 bit for bit (every dataset but wall times).
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
from common import COSIM, check, done, scratch  # noqa: E402

SCENE = os.path.join(HERE, "..", "..", "configs", "default.json")
SHORT = ["--set", "time.end=0.005", "--set", "output.every=50"]
SEED_KEY = "processes.dem.particles.seed"
out = scratch("cosim-repeat-")

p = subprocess.run([COSIM, "sweep", SCENE, "--values", "scenario.slip=0.05", "--repeat", "2",
                    "--out", out, *SHORT], capture_output=True, text=True, timeout=600)
check(p.returncode == 0, f"sweep --repeat 2 exits 0 (got {p.returncode}: {p.stderr.strip()[-400:]})")
with open(os.path.join(out, "runs.csv")) as f:
    rows = list(csv.DictReader(l for l in f if not l.startswith("#")))
check([json.loads(r[SEED_KEY]) for r in rows] == [1, 2], f"runs.csv: seeds 1 and 2 ({len(rows)} rows)")


def positions(h5):
    """The grains' positions in the last snapshot of a run."""
    with h5py.File(h5, "r") as f:
        steps = f["dem/steps"]
        last = steps[max(steps, key=int)]
        return last["x"][()] if "x" in last else last[sorted(last)[0]][()]


h5s = []
for r, seed in zip(rows, (1, 2)):
    h5 = os.path.join(out, r["dir"], "results.h5")
    check(os.path.isfile(h5), f"seed {seed}: {h5}")
    with h5py.File(h5, "r") as f:
        used = json.loads(f.attrs["config"])["processes"]["dem"]["particles"]
    # the bed of that seed, settled once into DIR/beds (cosim/sweep_beds.py)
    rec = [json.load(open(os.path.join(out, "beds", b))) for b in os.listdir(os.path.join(out, "beds"))
           if b.endswith(".json")]
    bed = [os.path.join(out, "beds", x["beds"]["dem"]) for x in rec if x["point"][SEED_KEY] == seed]
    check(len(bed) == 1 and used == {"file": os.path.abspath(bed[0])}, f"run {r['dir']} used the bed of seed {seed}")
    h5s.append(h5)
a, b = positions(h5s[0]), positions(h5s[1])
check(a.shape != b.shape or np.max(np.abs(a - b)) > 1e-3, "the two beds differ (grains moved > 1 mm)")

# 3. seed 2 once more, alone: the same run bit for bit
again = os.path.join(scratch("cosim-repeat-again-"), "run")
p = subprocess.run([COSIM, "run", SCENE, "--quiet", *SHORT, "--set", "scenario.slip=0.05",
                    "--set", f"{SEED_KEY}=2", "--set", f"output.dir={again}"],
                   capture_output=True, text=True, timeout=600)
check(p.returncode == 0, f"seed 2 again exits 0 (got {p.returncode}: {p.stderr.strip()[-300:]})")
SKIP = ("wall", "timing")


def datasets(h5):
    out = {}
    with h5py.File(h5, "r") as f:
        def take(name, o):
            if isinstance(o, h5py.Dataset) and not any(s in name for s in SKIP):
                v = o[()]
                cols = [c.decode() if isinstance(c, bytes) else str(c) for c in o.attrs.get("columns", [])]
                if getattr(v, "ndim", 0) == 2 and len(cols) == v.shape[1]:
                    v = v[:, [i for i, c in enumerate(cols) if not any(s in c for s in SKIP)]]
                out[name] = v.tobytes() if isinstance(v, np.ndarray) else v
        f.visititems(take)
    return out


x, y = datasets(h5s[1]), datasets(os.path.join(again, "results.h5"))
check(set(x) == set(y) and len(x) > 5, f"same datasets ({len(x)} / {len(y)})")
differ = [n for n in x if n in y and x[n] != y[n]]
check(not differ, f"seed 2 reproduces bit for bit (differ: {differ[:5]})")
done()
