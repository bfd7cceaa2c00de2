"""The scenes in configs/ as a user runs them:
1. every real solver of every scene swaps for its stub with one --set
   (README "Swapping a solver for a stub"): `cosim check` accepts each swap;
2. two runs of configs/default.json started together both finish: the
   scene's ports are chosen at bind time (port 0) and written to each
   run's endpoints.json (and results.h5), which `cosim monitor DIR` reads.
`test_configs.py swap dem|fem` instead runs that README swap of
configs/default.json as the README gives it, to the scene's time.end (the
fem_stub swap runs the real grain bed: a "slow" test)."""
import glob
import json
import os
import subprocess
import time

import sys

import h5py
import numpy as np

from common import COSIM, HERE, check, done, scratch

ROOT = os.path.dirname(os.path.dirname(HERE))
STUB = {"fem_server": "fem_stub", "dem_server": "dem_stub", "contact_block": "block_stub",
        "lug_block": "lug_stub"}
END = "time.end=0.002"  # 40 steps of the default scene
# The last series row is the step ending at k dt = time.end: the coupler's t is
# a product, not a running sum, so it is time.end to a few ulps.
T_END_REL = 1e-12
SETTLE = "processes.dem.particles.settle_max_steps=300"  # a shorter settling: fast also under ASan
DEFAULT = os.path.join(ROOT, "configs", "default.json")


def cosim(*args, timeout=300, cwd=None):
    return subprocess.run([COSIM, *args], capture_output=True, text=True, timeout=timeout,
                          cwd=cwd)


def columns(ds):
    return [c.decode() if isinstance(c, bytes) else str(c) for c in ds.attrs["columns"]]


def readme_swap(proc, stub):
    """The README's swap of configs/default.json, run to the scene's end."""
    sc = json.load(open(DEFAULT))
    out = os.path.join(scratch("cosim-configs-"), f"swap_{proc}")
    p = cosim("run", DEFAULT, "--set", f"processes.{proc}.exec={stub}",
              "--set", f"output.dir={out}", "--quiet", timeout=540)
    check(p.returncode == 0, f"README swap processes.{proc}.exec={stub} runs ({p.stderr[-400:]})")
    if p.returncode != 0:
        return
    log = open(os.path.join(out, "logs", f"{proc}.log")).read()
    check("ignoring" in log and "key" in log, f"{stub} names the keys it ignores ({log[:200]!r})")
    end, dt = sc["time"]["end"], sc["time"]["dt"]
    with h5py.File(os.path.join(out, "results.h5"), "r") as f:
        tr, cols = f["/coupler/traction"][:], columns(f["/coupler/traction"])
        fem, fem_cols = f["/fem/series"][:], columns(f["/fem/series"])
    steps = round(end / dt)
    check(tr.shape[0] == steps and abs(tr[-1, 0] - end) <= T_END_REL * end,
          f"{stub} swap reached time.end = {end} s: {tr.shape[0]} of {steps} steps, "
          f"last t = {tr[-1, 0]!r}")
    if proc != "fem":
        return
    load = tr[:, cols.index("vertical_load")]
    force = sc["scenario"]["sinkage_force"]
    check(load.max() >= force, f"the sinkage phase ended: the grains carried "
          f"sinkage_force = {force} N (max vertical load {load.max():.4g} N)")
    # the stub reports the force it was given: its series is the coupler's sum
    check(np.array_equal(fem[:, fem_cols.index("force_z")], load),
          "fem_stub's force_z is the vertical load the coupler sent it, every step")


if len(sys.argv) == 3 and sys.argv[1] == "swap":
    readme_swap(sys.argv[2], {"dem": "dem_stub", "fem": "fem_stub"}[sys.argv[2]])
    done()
    sys.exit(0)

# 1. every real solver of every scene, swapped (check: each section is
# validated by the stub it is handed to)
for path in sorted(glob.glob(os.path.join(ROOT, "configs", "*.json"))):
    scene = json.load(open(path))
    for name, sec in scene["processes"].items():
        if sec.get("exec") not in STUB:
            continue
        p = cosim("check", path, "--set", f"processes.{name}.exec={STUB[sec['exec']]}")
        check(p.returncode == 0, f"{os.path.basename(path)}: {name} -> {STUB[sec['exec']]} "
              f"passes cosim check ({p.stderr.strip()[-300:]})")

tmp = scratch("cosim-configs-")

# 2. two runs of the default scene at once
# the first twin runs long enough (2000 steps: progress is published every
# 0.5 s) for the monitor started beside it to hear it also on a loaded machine
procs, outs = [], []
for i in range(2):
    out = os.path.join(tmp, f"twin{i}")
    outs.append(out)
    procs.append(subprocess.Popen([COSIM, "run", DEFAULT, "--set", "time.end=0.1" if i == 0 else END,
                                   "--set", SETTLE,
                                   "--set", f"output.dir={out}", "--quiet"],
                                  stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True))
# while they run: `cosim monitor OUTPUT_DIR` finds the bus through endpoints.json
ep_file = os.path.join(outs[0], "endpoints.json")
for _ in range(600):
    if os.path.exists(ep_file) or procs[0].poll() is not None:
        break
    time.sleep(0.05)
mon = cosim("monitor", outs[0], "--topic", "coupler.progress", "--count", "1", "--timeout", "120")
results = [p.communicate(timeout=600) for p in procs]
for i, (p, (out, err)) in enumerate(zip(procs, results)):
    check(p.returncode == 0, f"run {i} of two concurrent default runs finished ({err[-400:]})")
eps = [json.load(open(os.path.join(o, "endpoints.json"))) for o in outs]
check(eps[0]["bus_monitor"] != eps[1]["bus_monitor"] and ":0" not in eps[0]["bus_monitor"],
      f"each run bound its own free port: {eps[0]['bus_monitor']} {eps[1]['bus_monitor']}")
with h5py.File(os.path.join(outs[1], "results.h5"), "r") as f:
    attr = f.attrs["bus_monitor"]
    attr = attr.decode() if isinstance(attr, bytes) else str(attr)
    check(attr == eps[1]["bus_monitor"], "results.h5 records the bound endpoint")
check(mon.returncode == 0 and "coupler.progress" in mon.stdout,
      f"cosim monitor OUTPUT_DIR follows the run's bus ({mon.returncode}: {mon.stdout[:200]} {mon.stderr[:200]})")
bad = cosim("monitor", tmp)
check(bad.returncode == 1 and "neither an endpoint" in bad.stderr,
      f"cosim monitor on a directory without endpoints.json says so ({bad.stderr.strip()})")
done()
