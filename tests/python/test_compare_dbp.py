"""bench/tire_soil/compare_dbp.py on saved sides (per-run bin means, the files
--save-a/--save-b write): one row of the convergence table without its runs.

1. Paired: b = a + a known shift per bed in T_P at one bin; the per-bed
   differences' mean and Student-t half-width are the ones computed here, the
   shifted bin is "NO" and the others "yes" (differences 0 exactly); --out
   writes the table with its comment line.
2. Unpaired: the sides' means and the combined half-width
   sqrt(a_ci95^2 + b_ci95^2).
3. Refused, naming the cause, with exit 1: sides of different windows (a
   saved side keeps its own), a file that is not one of bin means, a window
   that is not a number, bins of another width.
"""
import csv
import os
import subprocess
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, os.path.join(HERE, "..", "e2e"))
from common import check, done, scratch  # noqa: E402
from cosim import stats  # noqa: E402

TOOL = os.path.join(ROOT, "bench", "tire_soil", "compare_dbp.py")
HEAD = "# cosim dbp per-run bin means (compare_dbp.py): bin width "
Q = ("T_H", "T_R", "T_P", "vertical_load", "sinkage")
SEEDS, BINS, LOAD = (1, 2, 3, 4), (0, 1, 2), 1000.0
SHIFT = {1: 10.0, 2: 14.0, 3: 9.0, 4: 12.0}  # N added to b's T_P at bin 1, per bed
rng = np.random.default_rng(2026120701)
tmp = scratch("cosim-cmpdbp-")


def values():
    return {(s, k): {q: float(rng.normal(100 * k, 20)) for q in Q} for s in SEEDS for k in BINS}


def write(path, vals, width=0.05, window="0.109075"):
    with open(path, "w", newline="") as f:
        f.write(f"{HEAD}{width:g} (slip); rows averaged over {window} s (centred); forces in N\n")
        w = csv.writer(f)
        w.writerow(["seed", "slip_lo", *Q, "load"])
        for (s, k), v in vals.items():
            w.writerow([s, f"{k * width:.4f}", *(repr(v[q]) for q in Q), LOAD])


def tool(*args):
    p = subprocess.run([sys.executable, TOOL, *args], capture_output=True, text=True, timeout=60,
                       env=dict(os.environ, PYTHONPATH=os.path.join(ROOT, "python")))
    return p.returncode, p.stdout, p.stderr


def table(path):
    with open(path) as f:
        return [r for r in csv.DictReader(line for line in f if not line.startswith("#"))]


a = values()
b = {key: dict(v) for key, v in a.items()}
for s in SEEDS:
    b[(s, 1)]["T_P"] += SHIFT[s]
pa, pb = os.path.join(tmp, "a.csv"), os.path.join(tmp, "b.csv")
write(pa, a)
write(pb, b)

# 1. paired
out = os.path.join(tmp, "paired.csv")
rc, so, se = tool(pa, pb, "--paired", "--out", out, "--title", "a and b")
check(rc == 0, f"paired: ran ({se[-300:]})")
rows = table(out)
want = stats.across_runs(list(SHIFT.values()))
shifted = [r for r in rows if r["quantity"] == "T_P" and abs(float(r["slip_lo"]) - 0.05) < 1e-9]
check(len(shifted) == 1 and abs(float(shifted[0]["diff"]) - want["mean"]) < 0.006 and
      abs(float(shifted[0]["diff_ci95"]) - want["half"]) < 0.006 and shifted[0]["within"] == "NO",
      f"paired: the shifted bin's difference {want['mean']:.2f} +- {want['half']:.2f}, outside "
      f"({shifted[0] if shifted else None})")
rest = [r for r in rows if r is not (shifted[0] if shifted else None)]
check(len(rows) == len(BINS) * len(Q) and all(float(r["diff"]) == 0 and r["within"] == "yes" for r in rest),
      f"paired: every other row a difference of 0, within ({len(rows)} rows)")
with open(out) as f:
    first = f.readline()
check(first.startswith("# a and b; paired by seed") and "0.109075 s" in first,
      f"paired: the table says what it is ({first.strip()})")
check("T_H/T_R/T_P within: 8 of 9" in so, f"paired: the count printed ({so.splitlines()[0]})")

# 2. unpaired
out = os.path.join(tmp, "unpaired.csv")
rc, so, se = tool(pa, pb, "--out", out)
check(rc == 0, f"unpaired: ran ({se[-300:]})")
r = [r for r in table(out) if r["quantity"] == "T_H" and float(r["slip_lo"]) == 0.0][0]
sa = stats.across_runs([a[(s, 0)]["T_H"] for s in SEEDS])
check(abs(float(r["a_mean"]) - sa["mean"]) < 0.006 and
      abs(float(r["diff_ci95"]) - np.hypot(sa["half"], sa["half"])) < 0.006,
      f"unpaired: the means and sqrt(a_ci95^2 + b_ci95^2) ({r['a_mean']}, {r['diff_ci95']})")

# 3. refused
pw = os.path.join(tmp, "w.csv")
write(pw, b, window="0.1")
rc, so, se = tool(pa, pw, "--paired")
check(rc == 1 and "averaged over" in se, f"different windows refused ({se.strip()})")
pn = os.path.join(tmp, "n.csv")
write(pn, b, window="xx")
rc, so, se = tool(pa, pn, "--paired")
check(rc == 1 and "n.csv" in se and "no number" in se, f"a window that is no number refused ({se.strip()})")
pj = os.path.join(tmp, "junk.csv")
with open(pj, "w") as f:
    f.write("seed,slip_lo\n1,0\n")
rc, so, se = tool(pa, pj)
check(rc == 1 and "junk.csv" in se and "not a file of per-run bin means" in se,
      f"a file that is not one refused ({se.strip()})")
pbw = os.path.join(tmp, "bw.csv")
write(pbw, b, width=0.02)
rc, so, se = tool(pa, pbw)
check(rc == 1 and "bins of 0.02" in se, f"bins of another width refused ({se.strip()})")
done()
