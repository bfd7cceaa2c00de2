"""`cosim sweep` settles once per bed and starts every run from it (issue 21).

The default scene (a small bed generated and settled in the run, the tread
over it), cut to a few coupled steps; two slips x `--repeat 2` (seeds 1, 2):
1. two settle-only runs (one per seed: DIR/beds/settle.log has two lines, each
   with the dem's own "settled in" figures, and two bed files, each recorded
   with its seed in bed-<id>.json), four coupled runs;
2. every run loaded its bed: its scene's processes.dem.particles is
   {"file": the bed of its seed}, its dem log says the saved state
   continued, and no run settled;
3. a run from the shared bed is the run that settles its own bed, bit for
   bit (slip 0.1, seed 1 run alone with `cosim run`: every dataset of
   results.h5 but wall times);
4. resumed (`--resume`, one value more, `--jobs 2`): no bed settled again
   (settle.log and the bed files unchanged: a bed's id leaves out
   coupling.affinity, which runs at once get "none", as fem_server gets
   threads 1), the finished runs not
   rerun (their results.h5 untouched), the new value's runs load the
   existing beds and ran with coupling.affinity "none" and the tread on one
   thread;
5. a bed's id leaves out the scene's prose (`notes`: an edit of them gave
   every bed of the sand scene a new id) and keeps what settles it.
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
# a few coupled steps; a bed settled 2000 steps (the test is about sharing it, not its rest)
SHORT = ["--set", "time.end=0.005", "--set", "output.every=50",
         "--set", "processes.dem.particles.settle_max_steps=2000"]
SEED_KEY = "processes.dem.particles.seed"
out = scratch("cosim-sweep-beds-")


def sweep(values, *more):
    p = subprocess.run([COSIM, "sweep", SCENE, "--values", values, "--repeat", "2", "--out", out,
                        *SHORT, *more], capture_output=True, text=True, timeout=600)
    check(p.returncode == 0, f"sweep {values} {' '.join(more)} exits 0 (got {p.returncode}: "
          f"{p.stderr.strip()[-600:]})")
    with open(os.path.join(out, "runs.csv")) as f:
        return list(csv.DictReader(l for l in f if not l.startswith("#")))


def settle_lines():
    with open(os.path.join(out, "beds", "settle.log")) as f:
        return f.read().splitlines()


def beds():
    """{seed: bed file} from the beds' records."""
    found = {}
    for name in sorted(os.listdir(os.path.join(out, "beds"))):
        if name.endswith(".json"):
            with open(os.path.join(out, "beds", name)) as f:
                rec = json.load(f)
            found[rec["point"][SEED_KEY]] = os.path.join(out, "beds", rec["beds"]["dem"])
    return found


def dem_log(run_dir):
    with open(os.path.join(out, run_dir, "logs", "dem.log")) as f:
        return f.read()


# 1. settled once per seed
rows = sweep("scenario.slip=0.05,0.1")
lines = settle_lines()
print("\n".join(lines))
check(len(lines) == 2, f"two settle runs for two seeds and two slips (settle.log: {len(lines)} lines)")
check(all("2181 grains in 2000 steps" in l for l in lines), "settle.log has the dem's settling figures")
bed_of = beds()
check(sorted(bed_of) == [1, 2] and all(os.path.isfile(b) for b in bed_of.values()),
      f"a bed file per seed ({bed_of})")
check(len(rows) == 4, f"four runs ({len(rows)})")

# 2. every run loaded the bed of its seed
for r in rows:
    seed = json.loads(r[SEED_KEY])
    with h5py.File(os.path.join(out, r["dir"], "results.h5"), "r") as f:
        used = json.loads(f.attrs["config"])["processes"]["dem"]["particles"]
    check(used == {"file": bed_of[seed]}, f"{r['dir']} loaded the bed of seed {seed} ({used})")
    log = dem_log(r["dir"])
    check("its saved state continues" in log and "settled in" not in log,
          f"{r['dir']}: the dem continued the saved bed, did not settle")

# 3. the shared bed's run == the run that settles its own bed
alone = os.path.join(scratch("cosim-sweep-beds-alone-"), "run")
p = subprocess.run([COSIM, "run", SCENE, *SHORT, "--set", "scenario.slip=0.1",
                    "--set", f"{SEED_KEY}=1", "--set", f"output.dir={alone}"],
                   capture_output=True, text=True, timeout=600)
check(p.returncode == 0, f"seed 1 alone exits 0 (got {p.returncode}: {p.stderr.strip()[-300:]})")
with open(os.path.join(alone, "logs", "dem.log")) as f:
    check("settled in" in f.read(), "the run alone settles its own bed")
SKIP = ("wall", "timing")


def datasets(h5):
    found = {}
    with h5py.File(h5, "r") as f:
        def take(name, o):
            if isinstance(o, h5py.Dataset) and not any(s in name for s in SKIP):
                v = o[()]
                cols = [c.decode() if isinstance(c, bytes) else str(c) for c in o.attrs.get("columns", [])]
                if getattr(v, "ndim", 0) == 2 and len(cols) == v.shape[1]:
                    v = v[:, [i for i, c in enumerate(cols) if not any(s in c for s in SKIP)]]
                found[name] = v.tobytes() if isinstance(v, np.ndarray) else v
        f.visititems(take)
    return found


shared_dir = [r["dir"] for r in rows if json.loads(r[SEED_KEY]) == 1 and
              json.loads(r["scenario.slip"]) == 0.1][0]
x = datasets(os.path.join(out, shared_dir, "results.h5"))
y = datasets(os.path.join(alone, "results.h5"))
check(set(x) == set(y) and len(x) > 5, f"same datasets ({len(x)} / {len(y)})")
differ = [n for n in x if n in y and x[n] != y[n]]
check(not differ, f"the run from the shared bed is the self-settled run bit for bit (differ: {differ[:5]})")

# 4. resumed with one more value: nothing settled or rerun that was done
stamp = {b: os.stat(b).st_mtime_ns for b in bed_of.values()}
runs_done = {r["dir"]: os.stat(os.path.join(out, r["dir"], "results.h5")).st_mtime_ns for r in rows}
rows = sweep("scenario.slip=0.05,0.1,0.2", "--resume", "--jobs", "2")
check(settle_lines() == lines, f"resumed: no bed settled again (settle.log: {len(settle_lines())} lines)")
check(all(os.stat(b).st_mtime_ns == t for b, t in stamp.items()), "resumed: the bed files untouched")
check(all(os.stat(os.path.join(out, d, "results.h5")).st_mtime_ns == t for d, t in runs_done.items()),
      "resumed: the finished runs not rerun")
check(len(rows) == 6, f"resumed: six runs in runs.csv ({len(rows)})")
for r in rows:
    if json.loads(r["scenario.slip"]) == 0.2:
        with h5py.File(os.path.join(out, r["dir"], "results.h5"), "r") as f:
            used = json.loads(f.attrs["config"])["processes"]["dem"]["particles"]
            affinity = json.loads(f.attrs["config"]).get("coupling", {}).get("affinity")
            fem_threads = json.loads(f.attrs["config"])["processes"]["fem"].get("threads")
        seed = json.loads(r[SEED_KEY])
        check(used == {"file": bed_of[seed]}, f"new value {r['dir']} loaded the bed of seed {seed}")
        check(affinity == "none", f"new value {r['dir']}: run with --jobs 2, coupling.affinity "
              f"'none' (got {affinity!r})")
        check(fem_threads == 1, f"new value {r['dir']}: run with --jobs 2, the tread on one thread "
              f"(processes.fem.threads {fem_threads!r})")

# 5. the id: not the notes, but what the bed is settled with
from cosim.sweep_beds import bed_id, settled_beds  # noqa: E402
with open(SCENE) as f:
    base = json.load(f)
names = settled_beds(base)
edited = dict(base, notes=str(base.get("notes", "")) + " (edited)")
check(bed_id(edited, names) == bed_id(base, names), "a bed's id leaves out the scene's notes")
stiffer = json.loads(json.dumps(base))
stiffer["processes"]["dem"]["materials"][0]["E"] *= 2
check(bed_id(stiffer, names) != bed_id(base, names), "a bed's id changes with the grains' E")
done()
