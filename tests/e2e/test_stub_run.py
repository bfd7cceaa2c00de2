"""End to end through real processes over ipc: configs/stub_tire.json (the
tyre-travel scenario with fem_stub, a rigid surface following the rim, and
dem_stub, prescribed forces), with each coupling scheme. Checks the values in results.h5 against what the
scenario and the scheme must produce, computed here from their definitions:

- dem_stub returns the impulse of its ramped force over each step / dt
  (the role table), i.e. 25 N x the ramp's mean over [t_{k-1}, t_k];
- serial: the rim moves with the load of the same step; the tread gets the
  grains' forces of the same step;
- parallel: the rim moves with the load of the previous step; the tread gets
  the forces one step late (the one-step lag, Jacobi);
- implicit: the rim as parallel; the tread gets the forces of the same step
  (the fixed point is exact here: neither stub's output depends on its
  input), in 3 iterations at the first step (relaxation, then one IQN-ILS
  step) and 2 afterwards (the reused columns)."""
import json
import math
import os
import xml.etree.ElementTree as ET

import numpy as np

from common import HERE, check, done, h5, no_orphans, run, scene, columns

N_NODES = 25  # plane n = [4, 4]
DT, RAMP, LOAD = 1e-3, 0.1, 20.0
k = np.arange(1, 201)
t = k * DT
# mean of min(t/T, 1) over [t_{k-1}, t_k]: (t_k + t_{k-1}) / (2T) inside the ramp
ramp_mean = np.minimum((t + t - DT) / (2 * RAMP), 1.0)
load = N_NODES * 1.0 * ramp_mean
first_loaded = int(k[load >= LOAD][0])  # the first step whose load reaches 20 N


def expected_travel_start(scheme):
    """The first step in which the rim travels instead of sinking."""
    return first_loaded if scheme == "serial" else first_loaded + 1


def run_scheme(scheme):
    """configs/stub_tire.json as it is, with the scheme set."""
    cfg = json.load(open(os.path.join(HERE, "..", "..", "configs", "stub_tire.json")))
    s = scene(f"stub_run_{scheme}", cfg["processes"], scenario=cfg["scenario"], time=cfg["time"])
    s["output"]["every"] = cfg["output"]["every"]
    s["coupling"] = dict(cfg["coupling"], scheme=scheme)
    rc, out, err = run(s)
    check(rc == 0, f"{scheme}: run exits 0 (got {rc}: {err})")
    check("results:" in out and "results.h5" in out, f"{scheme}: run prints where its results are")
    check("Loop time" in out and "dem.compute" in out, f"{scheme}: the timing table is printed")
    # not a terminal: progress as a line per tenth of the run, the last at the end
    check("cosim: step 200/200 (100 %)" in out, f"{scheme}: a batch run's log shows its progress")
    no_orphans(s, f"{scheme} run")
    return s


def check_common(s, scheme):
    f = h5(s)
    dem, fem, trac = f["/dem/series"][:], f["/fem/series"][:], f["/coupler/traction"][:]
    check(dem.shape == (200, 5) and fem.shape == (200, 5) and trac.shape == (200, 7),
          f"{scheme}: one row per step: {dem.shape} {fem.shape} {trac.shape}")
    check(columns(f["/coupler/traction"]) == ["t", "T_H", "T_R", "T_P", "vertical_load", "sinkage", "torque"],
          "traction columns")
    check(np.allclose(dem[:, 0], t, rtol=0, atol=1e-12), f"{scheme}: dem time column is t_k")
    check(np.allclose(dem[:, 3], load, rtol=1e-12), f"{scheme}: dem Fz = 25 N x mean ramp of the step")
    check(np.allclose(trac[:, 2], -0.1 * N_NODES * ramp_mean, rtol=1e-12), f"{scheme}: T_R = sum of negative Fx")
    check(np.all(trac[:, 1] == 0), "T_H = 0 (no forward force)")
    check(np.allclose(trac[:, 3], trac[:, 1] - np.abs(trac[:, 2])), "T_P = T_H - |T_R|")
    # the tread received the grains' forces: same step, or one step late
    if scheme == "parallel":
        check(np.array_equal(fem[1:, 1:4], dem[:-1, 1:4]) and np.all(fem[0, 1:4] == 0),
              "parallel: the tread gets the forces of the previous step")
    else:
        check(np.array_equal(fem[:, 1:4], dem[:, 1:4]), f"{scheme}: the tread gets the forces of the same step")
    # sinkage at 0.1 m/s in every step before travel starts
    k0 = expected_travel_start(scheme)
    sink = 0.1 * DT * (k0 - 1)
    check(abs(trac[-1, 5] - sink) < 1e-12, f"{scheme}: sinkage stops at {sink * 1e3:.1f} mm (got {trac[-1, 5]})")
    # snapshot at step 50: surface = X0 + c, c_z = 0.3 - 0.1 * 49 dt (the DEM sees t_49)
    x50 = f["/dem/steps/50/x"][:]
    check(x50.shape == (N_NODES, 3), "snapshot shape")
    check(np.allclose(x50[:, 2], 0.3 - 0.0049 - 0.27, atol=1e-12), f"{scheme}: snapshot z at step 50")
    check(np.allclose(np.sort(np.unique(x50[:, 0].round(12))), np.linspace(-0.1, 0.1, 5)), "snapshot x")
    # after the sinkage phase the rim rotates: the DEM sees the surface of t_199
    x200 = f["/dem/steps/200/x"][:]
    moves = 199 - k0 + 1
    angle, cx = 1.8 * moves * DT, 0.272 * 1.8 * 0.95 * moves * DT
    X0 = x50 - np.array([0, 0, 0.3 - 0.0049])
    R = np.array([[math.cos(angle), 0, math.sin(angle)], [0, 1, 0], [-math.sin(angle), 0, math.cos(angle)]])
    expect = X0 @ R.T + np.array([cx, 0, 0.3 - sink])
    check(np.allclose(x200, expect, atol=1e-9),
          f"{scheme}: rotated surface at step 200 (max err {np.abs(x200 - expect).max():.3g})")
    cs = f["/coupler/series"][:]
    ccols = columns(f["/coupler/series"])
    it = cs[:, ccols.index("iterations")]
    conv = cs[:, ccols.index("converged")]
    if scheme == "implicit":
        check(it[0] == 3 and np.all(it[1:] == 2), f"implicit: 3 then 2 iterations per step (got {it[:4]}...)")
        check(np.all(conv == 1), "implicit: every step converged")
    else:
        check(np.all(it == 1), f"{scheme}: one pass per step")
    tim = f["/coupler/timing"]
    tcols = columns(tim)
    check(tim.shape[0] == 200 and "dem.compute" in tcols and "fem.waiting" in tcols
          and "coupler.mapping" in tcols, f"{scheme}: /coupler/timing has a row per step ({tcols[:6]})")
    check(np.all(tim[:, tcols.index("wall")] > 0), "timing: positive wall time")
    return f


def two_beds():
    """Two processes of role dem on one surface (freely named): the tread
    gets the sum of their forces, in the order of the scene."""
    s = scene("two_beds", {
        "tyre": {"exec": "fem_stub",
                 "surface": {"plane": {"size": [0.2, 0.16], "n": [4, 4], "z": -0.27}}},
        "soil": {"exec": "dem_stub", "force_per_node": [-0.1, 0.0, 1.0], "ramp_time": RAMP},
        "stones": {"exec": "dem_stub", "force_per_node": [0.05, 0.02, 0.5], "ramp_time": 0}},
        scenario={"kind": "tire_travel", "rim_center": [0, 0, 0.3], "sinkage_velocity": 0.1,
                  "sinkage_force": LOAD, "slip": 0.05, "omega": 1.8, "radius": 0.272})
    s["time"] = {"dt": DT, "end": 0.05}
    rc, out, err = run(s)
    check(rc == 0, f"two dem processes: run ok ({err[-300:]})")
    check("soil (dem)" in out and "stones (dem)" in out and "tyre (fem)" in out,
          f"the schedule names the processes and their roles: {out[:400]}")
    no_orphans(s, "two beds")
    f = h5(s)
    soil, stones, tyre = f["/soil/series"][:], f["/stones/series"][:], f["/tyre/series"][:]
    check(np.allclose(tyre[:, 1:4], soil[:, 1:4] + stones[:, 1:4], rtol=1e-12, atol=1e-15),
          "the tread receives the sum of both beds' forces")
    trac = f["/coupler/traction"][:]
    check(np.allclose(trac[:, 4], soil[:, 3] + stones[:, 3], rtol=1e-12), "vertical load = both beds")


two_beds()
for scheme in ("serial", "parallel", "implicit"):
    s = run_scheme(scheme)
    f = check_common(s, scheme)
    if scheme == "serial":
        cfg = json.loads(f.attrs["config"])
        check(cfg["name"] == s["name"] and cfg["processes"]["dem"]["force_per_node"] == [-0.1, 0.0, 1.0],
              "config stored in the file")
        steps = sorted(int(x) for x in f["/dem/steps"].keys())
        check(steps == [50, 100, 150, 200], f"snapshots at output steps: {steps}")
        xd = ET.parse(os.path.join(s["output"]["dir"], "dem.xdmf")).getroot()
        grids = xd.findall(".//Grid[@GridType='Uniform']")
        check(len(grids) == 4, f"XDMF lists 4 snapshots (got {len(grids)})")
done()
