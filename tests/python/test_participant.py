"""Python participants on cosim.Participant swap in for the C solvers of the
scenes, one string changed, and give the analytic result:

1. python/examples/hertz_block.py for contact_block in configs/tread_block.json:
   the road follows the linear profile d = depth min(t_k / ramp, 1), the
   force is c d^1.5 (rtol 1e-12); the block's own keys are named and ignored.
2. The same block with damping on the force-driven road, implicit scheme: the
   coupler repeats steps, the participant rolls its state (the last
   displacement) back, so force = c d^1.5 + eta (d_k - d_{k-1}) / dt holds
   with the converged d of consecutive steps (it fails if the state of a
   discarded iterate leaks into the next one).
3. python/examples/rigid_tread.py for fem_stub in configs/stub_tire.json: the
   surface follows the rim, x = R(angle) X0 + c and v = v_rim + omega x r at
   the analytic rim motion of the scenario (sinkage at 0.1 m/s until the
   grains carry 20 N, then rolling at omega, travel at omega R (1 - s)),
   to 1e-12 m; the forces it receives are dem_stub's, bit for bit."""
import json
import math
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.join(HERE, "..", "..")
sys.path.insert(0, os.path.join(HERE, "..", "e2e"))
from common import check, done, no_orphans, scene  # noqa: E402

import cosim  # noqa: E402

EXAMPLES = os.path.join(ROOT, "python", "examples")
HERTZ, TREAD = os.path.join(EXAMPLES, "hertz_block.py"), os.path.join(EXAMPLES, "rigid_tread.py")


def config(name):
    with open(os.path.join(ROOT, "configs", name)) as f:
        return json.load(f)


def as_test_scene(cfg, name):
    """The scene as it is, with a unique name and a private output dir."""
    s = scene(name, cfg["processes"])
    for key in ("time", "scenario", "coupling"):
        s[key] = cfg[key]
    s["output"]["every"] = cfg["output"]["every"]
    return s


# 1. Hertz block for contact_block
cfg = config("tread_block.json")
s = as_test_scene(cfg, "py_hertz")
C = 1e9
r = cosim.run(s, set={"processes.block.exec": HERTZ, "processes.block.c": C})
no_orphans(s, "hertz swap")
blk = r.series("block")
sc, dt = cfg["scenario"], cfg["time"]["dt"]
n = len(blk)
t = np.arange(1, n + 1) * dt
d = sc["depth"] * np.minimum(t / sc["ramp_time"], 1.0)
check(n == round(cfg["time"]["end"] / dt), f"one row per step ({n})")
check(np.allclose(blk["t"], t, rtol=1e-12, atol=0), "t column is t_k")
check(np.allclose(blk["d_road"], d, rtol=1e-12, atol=0), "road on the linear profile")
print(f"hertz: {n} steps, max rel err of the force {np.max(np.abs(blk['force'] / (C * d ** 1.5) - 1)):.2g}")
check(np.allclose(blk["force"], C * d ** 1.5, rtol=1e-12, atol=0),
      f"Hertz force c d^1.5 (max rel err "
      f"{np.max(np.abs(blk['force'] / (C * d ** 1.5) - 1)):.2g})")
log = open(os.path.join(s["output"]["dir"], "logs", "block.log")).read()
check("ignoring 6 keys: adhesion, green, grid, road, solver, springs" in log,
      f"the stand-in names the contact_block keys it ignores: {log!r}")
check(r.steps("block") == [], "no snapshots asked of the block")

# 2. implicit scheme, force-driven road: rollback of the Python state
ETA, M, F, DT = 50.0, 0.4, 200.0, 1e-5
s = scene("py_implicit", {"block": {"exec": HERTZ, "c": C, "damping": ETA}},
          scenario={"kind": "indentation", "profile": "force", "road_mass": M, "road_force": F})
s["time"] = {"dt": DT, "end": 300 * DT}
s["coupling"]["scheme"] = "implicit"
s["coupling"]["implicit"] = {"tolerance": 1e-12, "max_iterations": 100}
r = cosim.run(s)
no_orphans(s, "implicit")
blk, cs = r.series("block"), r.series("coupler")
d = blk["d_road"]
d_prev = np.concatenate([[0.0], d[:-1]])
want = np.where(d > 0, C * np.maximum(d, 0) ** 1.5 + ETA * (d - d_prev) / DT, 0.0)
print(f"implicit: iterations per step {cs['iterations'].min():g}..{cs['iterations'].max():g}, "
      f"max force err {np.max(np.abs(blk['force'] - want)):.3g} N of {np.max(blk['force']):.3g} N")
check(np.max(cs["iterations"]) > 2, f"steps were repeated (iterations up to {np.max(cs['iterations'])})")
check(np.all(cs["converged"] == 1), "every step converged")
check(np.allclose(blk["force"], want, rtol=1e-12, atol=1e-9),
      f"force from the converged d of consecutive steps: the state was rolled back "
      f"(max err {np.max(np.abs(blk['force'] - want)):.3g} N)")
check(d.max() > 0 and np.all(np.abs(blk["force"]) < 10 * F), "the road pressed the block")

# 3. rigid tread for fem_stub
cfg = config("stub_tire.json")
s = as_test_scene(cfg, "py_tread")
r = cosim.run(s, set={"processes.fem.exec": TREAD})
no_orphans(s, "tread swap")
dem, fem, trac = r.series("dem"), r.series("fem"), r.series("coupler", "traction")
check(np.array_equal(fem.array[:, 1:4], dem.array[:, 1:4]),
      "the tread gets the grains' forces of the same step, bit for bit")
sc, dt = cfg["scenario"], cfg["time"]["dt"]
k = np.arange(1, len(dem) + 1)
load = dem["force_z"]
k0 = int(k[load >= sc["sinkage_force"]][0])  # first step that travels (serial)
sink = sc["sinkage_velocity"] * dt * (k0 - 1)
check(abs(trac["sinkage"][-1] - sink) < 1e-12, f"sinkage stops at {sink * 1e3:.1f} mm")
X0 = r.mesh("fem")
check(set(X0) == {"tri"}, f"mesh written from ready: {sorted(X0)}")
c0 = np.array(sc["rim_center"], float)


def rim(step):
    """The rim frame the fem sees at t_step (the dem sees t_{step-1})."""
    moves = max(0, step - k0 + 1)
    angle = sc["omega"] * moves * dt
    c = c0 + [sc["radius"] * sc["omega"] * (1 - sc["slip"]) * moves * dt, 0,
              -sc["sinkage_velocity"] * dt * min(step, k0 - 1)]
    R = np.array([[math.cos(angle), 0, math.sin(angle)], [0, 1, 0],
                  [-math.sin(angle), 0, math.cos(angle)]])
    return R, c, moves


plane = cfg["processes"]["fem"]["surface"]["plane"]
(lx, ly), (nx, ny) = plane["size"], plane["n"]
y, x = np.mgrid[0:ny + 1, 0:nx + 1]
X = np.stack([lx * (x / nx - 0.5), ly * (y / ny - 0.5), np.full(x.shape, plane["z"])], -1).reshape(-1, 3)
steps = r.steps("fem")
check(steps == [50, 100, 150, 200], f"snapshots at the output steps: {steps}")
worst_x = worst_v = 0.0
for st in steps:
    R, c, moves = rim(st)
    snap = r.snapshot("fem", st)
    rr = X @ R.T
    w = np.array([0, sc["omega"], 0]) if moves else np.zeros(3)
    vr = (np.array([sc["radius"] * sc["omega"] * (1 - sc["slip"]), 0, 0]) if moves
          else np.array([0, 0, -sc["sinkage_velocity"]]))
    worst_x = max(worst_x, np.abs(snap["x"] - (rr + c)).max())
    worst_v = max(worst_v, np.abs(snap["v"] - (vr + np.cross(w, rr))).max())
print(f"tread: max err x {worst_x:.2g} m, v {worst_v:.2g} m/s over {len(steps)} snapshots")
check(worst_x < 1e-12, f"surface x = R X0 + c at every snapshot (max err {worst_x:.2g} m)")
check(worst_v < 1e-12, f"surface v = v_rim + omega x r (max err {worst_v:.2g} m/s)")
xd = open(os.path.join(s["output"]["dir"], "fem.xdmf")).read()
check("Triangle" in xd and "/fem/steps/200/x" in xd, "the tread's snapshots described in fem.xdmf")
done()
