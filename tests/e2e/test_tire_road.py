"""Scenario tire_road (docs/tire-road.md) with real processes: the 165/65 R13
tread (fem_server) rolls on a smooth road, its lugs served by lug_block
processes (linear springs, flat road). Checks, on configs/tire_road.json
shortened and with smaller block grids:
- the tread's vertical load each step is exactly the lug blocks' forces plus
  the road's penalty (the force the FEM gets is what the blocks gave);
- each block's own series row has the force and approach the coupler's
  /coupler/lugs row has, bit for bit, one row per step;
- lugs are handed over between the processes (more lugs taken than there are
  processes), and a process gives up a lug only once its force is zero, so
  no force is lost at a handover; the block's history starts afresh there;
- bad scenes: a dem in tire_road, the implicit scheme, too few lug processes
  for the lugs near the road, lug processes of different grids, an unknown
  lug_face — each refused with a message that names it."""
import json
import os

import h5py
import numpy as np

from common import HERE, check, columns, done, run, scene

base = json.load(open(os.path.join(HERE, "..", "..", "configs", "tire_road.json")))
procs = base["processes"]
for name in ("lug0", "lug1", "lug2"):
    procs[name]["grid"] = {"nx": 8, "ny": 15, "dx": 6.6e-3, "dy": 6.6e-3}
    procs[name]["springs"] = {"kind": "linear", "k": 8e5}  # the same stiffness per area
s = scene("tire_road", procs, scenario=dict(base["scenario"], sinkage_velocity=0.1))
s["time"] = {"dt": base["time"]["dt"], "end": 0.2}
s["output"]["every"] = 2048
s["coupling"]["step_timeout"] = 60
s["coupling"]["handshake_timeout"] = 120
rc, out, err = run(s, "--quiet", timeout=900)
check(rc == 0, f"tire_road runs to the end (rc {rc}: {err.strip()[-600:]})")

with h5py.File(os.path.join(s["output"]["dir"], "results.h5"), "r") as f:
    lugs, lc = f["coupler/lugs"][()], columns(f["coupler/lugs"])
    tr, tc = f["coupler/traction"][()], columns(f["coupler/traction"])
    own = {p: (f[f"{p}/series"][()], columns(f[f"{p}/series"])) for p in ("lug0", "lug1", "lug2")}
n = len(lugs)
col = {c: lugs[:, i] for i, c in enumerate(lc)}
check(n == round(0.2 / s["time"]["dt"]), f"one /coupler/lugs row per step ({n})")
load = tr[:, tc.index("vertical_load")]
total = col["road_penalty"] + sum(col[f"force{p}"] for p in range(3))
check(np.max(np.abs(load - total)) <= 1e-12 * max(1.0, np.max(np.abs(load))),
      f"the tread's load is the blocks' forces plus the penalty every step "
      f"(max difference {np.max(np.abs(load - total)):.3g} N of {np.max(load):.4g} N)")
check(np.max(load) > 100, f"the lugs carry load ({np.max(load):.4g} N)")
for p in range(3):
    rows, cols = own[f"lug{p}"]
    check(len(rows) == n, f"lug{p}: a series row every step ({len(rows)})")
    same = (rows[:, cols.index("force")].tobytes() == col[f"force{p}"].tobytes() and
            rows[:, cols.index("d_road")].tobytes() == col[f"d{p}"].tobytes())
    check(same, f"lug{p}: its own force and approach are the coupler's, bit for bit")
taken = int(col["handovers"][-1])
print(f"{n} steps, {taken} lugs taken, largest load {np.max(load):.4g} N, penalty {np.max(col['road_penalty']):.3g} N")
check(taken >= 2, f"lugs handed over: {taken} taken")
lost = 0
for p in range(3):
    lug, F = col[f"lug{p}"], col[f"force{p}"]
    for k in np.nonzero(lug[1:] != lug[:-1])[0]:
        lost += lug[k] >= 0 and F[k] != 0  # given up while still holding force
check(lost == 0, "no lug given up while its block still held force")

# the figures and the spectrum (python3 -m cosim.fig_road)
import subprocess  # noqa: E402
import sys  # noqa: E402
env = dict(os.environ, PYTHONPATH=os.path.join(HERE, "..", "..", "python"))
p = subprocess.run([sys.executable, "-m", "cosim.fig_road", s["output"]["dir"]], env=env,
                   capture_output=True, text=True, timeout=300)
check(p.returncode == 0, f"cosim.fig_road runs ({p.stderr.strip()[-300:]})")
for png in ("road_passages.png", "road_psd.png", "road_footprint.png"):
    f = os.path.join(s["output"]["dir"], png)
    check(os.path.exists(f) and os.path.getsize(f) > 1000, f"{png} written")
spec = np.loadtxt(os.path.join(s["output"]["dir"], "road_psd.csv"), delimiter=",")
check(abs(spec[-1, 0] - 0.5 / s["time"]["dt"]) < 1e-6 and np.all(spec[:, 1] >= 0),
      f"the spectrum reaches the block rate's Nyquist frequency ({spec[-1, 0]:.6g} Hz)")
check(f"{taken} passages" in p.stdout, f"one passage per lug taken ({p.stdout.strip()})")

# one lug passage with a prescribed lug-face motion: a rigid 20 x 20 mm face (fem_stub)
# on a rim sinking at depth / ramp_time is the thesis' linear indentation; the lug block
# (tread_block.json's block) must give the stand-alone block scene's force history. The
# lug action reads the face of t_{k-1}: the lug block's step k is the scene's step k - 1
# (its first step, at d = 0, touches nothing).
tb = json.load(open(os.path.join(HERE, "..", "..", "configs", "tread_block.json")))
ref = scene("tread_block_ref", tb["processes"], scenario=tb["scenario"])
ref["time"] = tb["time"]
rc, out, err = run(ref, "--quiet", timeout=120)
check(rc == 0, f"the stand-alone block runs ({err.strip()[-300:]})")
sc = tb["scenario"]
face = {"exec": "fem_stub", "surface": {
    "nodes": [[-0.01, -0.01, -0.27], [0.01, -0.01, -0.27], [0.01, 0.01, -0.27], [-0.01, 0.01, -0.27]],
    "triangles": [[0, 1, 2], [0, 2, 3]]}}
lug = dict(tb["processes"]["block"], exec="lug_block")
one_pass = scene("tire_road_pass", {"fem": face, "lug0": lug}, scenario={
    "kind": "tire_road", "rim_center": [0, 0, "auto"], "auto_gap": 0,
    "sinkage_velocity": sc["depth"] / sc["ramp_time"], "sinkage_force": 1e9, "omega": 0,
    "slip": 0, "road_z": 0})
one_pass["time"] = dict(tb["time"], end=tb["time"]["end"] + tb["time"]["dt"])
rc, out, err = run(one_pass, "--quiet", timeout=120)
check(rc == 0, f"one lug passage runs ({err.strip()[-300:]})")
with h5py.File(os.path.join(ref["output"]["dir"], "results.h5"), "r") as f:
    fr, cr = f["block/series"][()], columns(f["block/series"])
with h5py.File(os.path.join(one_pass["output"]["dir"], "results.h5"), "r") as f:
    fl, cl = f["lug0/series"][()], columns(f["lug0/series"])
F_ref, F_lug = fr[:, cr.index("force")], fl[1:, cl.index("force")]
d_ref, d_lug = fr[:, cr.index("d_road")], fl[1:, cl.index("d_road")]
m = min(len(F_ref), len(F_lug))
dF = np.max(np.abs(F_ref[:m] - F_lug[:m]))
print(f"one passage: {m} steps, peak {np.max(F_ref):.4g} N, max |dF| {dF:.3g} N, "
      f"max |dd| {np.max(np.abs(d_ref[:m] - d_lug[:m])):.3g} m")
check(m == len(F_ref) and fl[0, cl.index("force")] == 0, "the same steps; the first at d = 0 free")
check(np.max(F_ref) > 1 and dF <= 1e-9 * np.max(np.abs(F_ref)),
      f"the lug block's forces are the stand-alone block's to round-off ({dF:.3g} N)")

# bad scenes, each refused by name
bad = scene("tire_road_dem", dict(procs, dem={"exec": "dem_stub"}), scenario=base["scenario"])
rc, out, err = run(bad, cmd="run", timeout=120)
check(rc != 0 and "'tire_road' needs one process of role fem" in err,
      f"a dem in tire_road is refused ({err.strip()[-300:]})")
bad = scene("tire_road_implicit", procs, scenario=base["scenario"],
            coupling={"scheme": "implicit"})
rc, out, err = run(bad, cmd="check", timeout=120)
check(rc != 0 and "coupling.scheme: 'implicit'" in err, f"implicit refused ({err.strip()[-300:]})")
one = {"fem": procs["fem"], "lug0": procs["lug0"]}
few = scene("tire_road_few", one, scenario=dict(base["scenario"], lug_engage=0.05))
few["time"] = {"dt": base["time"]["dt"], "end": 0.001}
few["coupling"]["handshake_timeout"] = 120
rc, out, err = run(few, "--quiet", timeout=300)
check(rc != 0 and "add processes of role lug" in err,
      f"more lugs near the road than lug processes: named ({err.strip()[-300:]})")
two = {"fem": procs["fem"], "lug0": procs["lug0"],
       "lug1": dict(procs["lug1"], grid=dict(procs["lug1"]["grid"], nx=procs["lug1"]["grid"]["nx"] + 1))}
grids = scene("tire_road_grids", two, scenario=base["scenario"])
grids["time"] = {"dt": base["time"]["dt"], "end": 0.001}
grids["coupling"]["handshake_timeout"] = 120
rc, out, err = run(grids, "--quiet", timeout=300)
check(rc != 0 and "'lug0' and 'lug1' have different block grids" in err,
      f"lug processes with different grids: named ({err.strip()[-300:]})")
bad = scene("tire_road_face", procs, scenario=dict(base["scenario"], lug_face="bulged"))
rc, out, err = run(bad, cmd="check", timeout=120)
check(rc != 0 and "lug_face" in err and "bulged" in err,
      f"an unknown lug_face is refused by name ({err.strip()[-300:]})")
done()
