"""Sparse and dense exchange carry the same bits (proto/PROTOCOL.md "Sparse
exchange"): the same scene run with coupling.sparse true (the default) and
false gives bitwise-identical results.h5 (wall-clock columns aside), and the
sparse run did send less: its end-of-run summary gives shares below 100 %.

  stubs    configs/stub_tire.json with the dem stub's bed_top (only the nodes
           below it carry force: sparse nodal_force both ways), serial and
           implicit (with checkpoints).
  default  configs/default.json to t = 0.16 s: the tread reaches the grains at
           t = 0.142 s. With dem sleep on and off (as shipped), dem_server
           sends (index, force) rows and gets x, v of the nodes near its grains
           only (with sleep: near the box its active region looks at, grown by
           reach_speed times the surface's speed, and the fastest node); the
           share of the bytes sent to it is below 100 % both ways.
  implicit configs/default.json, the implicit scheme (every step repeated, the
           processes rolling back), the rim sinking fast so that the tread is in
           the bed within 300 steps; checkpoints every 150 steps, and a restart
           from the sparse run's checkpoint continues it bit for bit.

Usage: test_sparse.py [stubs|default|implicit ...] (default: all three)."""
import os
import re
import subprocess
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "reliability"))
from common import COSIM, check, done, scratch  # noqa: E402
from rel import differences  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def run(config, sparse, out, extra=()):
    p = subprocess.run([COSIM, "run", os.path.join(ROOT, "configs", config), "--set",
                        f"coupling.sparse={'true' if sparse else 'false'}", "--set",
                        f"output.dir={out}", *extra], capture_output=True, text=True,
                       timeout=900)
    check(p.returncode == 0, f"{out}: exits 0 (got {p.returncode}: {p.stderr.strip()[-400:]})")
    return p.stdout + p.stderr


def shares(text):
    """{process: (to it %, from it %)} from the end-of-run summary."""
    return {m[0]: (float(m[1]), float(m[2])) for m in
            re.findall(r"^  (\S+)\s+to it\s+([\d.]+) % .*from it\s+([\d.]+) %", text, re.M)}


def same(config, tag, extra=(), want_less=("dem",), want_less_to=()):
    base = scratch("cosim-sparse-")
    a, b = os.path.join(base, tag + "-sparse"), os.path.join(base, tag + "-dense")
    ta = run(config, True, a, extra)
    tb = run(config, False, b, extra)
    diff, n = differences(a, b)
    check(not diff and n > 5, f"{tag}: sparse and dense bitwise equal ({n} datasets; {diff[:4]})")
    got = shares(ta)
    for p in want_less:
        check(p in got and min(got[p]) < 100,
              f"{tag}: the sparse run sent less to or from {p} ({got})")
    for p in want_less_to:
        check(p in got and got[p][0] < 100, f"{tag}: the sparse run sent less to {p} (x, v: {got})")
    print(f"{tag}: shares of the dense bytes (to, from) {got}")
    check("sparse exchange" not in tb, f"{tag}: the dense run prints no sparse summary")
    return a, b


def stubs():
    bed = ["--set", "processes.dem.bed_top=0.02"]
    same("stub_tire.json", "stub_tire", bed, want_less=("dem", "fem"))
    same("stub_tire.json", "stub_tire_implicit", bed + [
        "--set", "coupling.scheme=implicit", "--set", "checkpoint.every=50"],
        want_less=("dem", "fem"))


def dem_rows(out):
    """(x/v nodes, nodes, force rows) of each output step in the dem's log."""
    log = open(os.path.join(out, "logs", "dem.log")).read()
    return [(int(x), int(n), int(f)) for x, n, f in
            re.findall(r"sparse exchange: x, v of (\d+) of (\d+) nodes, nodal force of (\d+)", log)]


def default():
    short = ["--set", "time.end=0.16", "--set", "output.every=400"]
    a, _ = same("default.json", "default", short + ["--set", "processes.dem.sleep=true"],
                want_less_to=("dem",))
    rows = dem_rows(a)
    check(rows and rows[-1][2] > 0 and rows[-1][0] < rows[-1][1],
          f"default (sleep): the tread is in the bed, a part of it travels to the dem ({rows[-2:]})")
    a, _ = same("default.json", "default_awake", short + ["--set", "processes.dem.sleep=false"],
                want_less_to=("dem",))
    rows = dem_rows(a)
    check(rows and rows[-1][2] > 0 and rows[-1][0] < rows[-1][1] / 3,
          f"default (no sleep): the tread is in the bed, a part of it travels ({rows[-2:]})")


FAST = ["--set", "scenario.sinkage_velocity=2.5", "--set", "scenario.sinkage_force=5",
        "--set", "output.every=50", "--set", "coupling.scheme=implicit",
        "--set", "processes.dem.sleep=false"]  # sleep off: x, v sparse too


def implicit():
    end = ["--set", "time.end=0.015"]  # 300 steps of 5e-5 s; contact from about step 120
    a, b = same("default.json", "default_implicit", FAST + end + ["--set", "checkpoint.every=150"])
    rows = dem_rows(a)
    check(rows and max(r[2] for r in rows) > 0 and min(r[0] for r in rows) < rows[0][1] / 3,
          f"implicit: the tread carried grain forces, x, v went sparse ({rows[-3:]})")
    # the sparse run's checkpoint of step 150, restarted to 300: the same bits
    c = os.path.join(scratch("cosim-sparse-"), "restarted")
    run("default.json", True, c, FAST + ["--set", "time.end=0.0075", "--set",
                                         "checkpoint.every=150"])
    run("default.json", True, c, FAST + end + ["--set", "checkpoint.every=150", "--restart",
                                               "latest"])
    diff, n = differences(a, c)
    check(not diff and n > 5, f"implicit: a sparse restart continues bit for bit ({n}; {diff[:4]})")


if __name__ == "__main__":
    for what in sys.argv[1:] or ["stubs", "default", "implicit"]:
        {"stubs": stubs, "default": default, "implicit": implicit}[what]()
    done()
