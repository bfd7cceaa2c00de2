"""End to end through real processes over ipc: the tyre-travel scenario with
fem_stub (rigid surface following the rim) and dem_stub (prescribed forces).
Checks the values in results.h5 against what the scenario must produce."""
import json
import math
import os
import xml.etree.ElementTree as ET

import numpy as np

from common import check, done, h5, no_orphans, run, scene, columns

N_NODES = 25  # plane n = [4, 4]
s = scene("stub_run", {
    "fem": {"exec": "fem_stub",
            "surface": {"plane": {"size": [0.2, 0.16], "n": [4, 4], "z": -0.27}}},
    "dem": {"exec": "dem_stub", "force_per_node": [-0.1, 0.0, 1.0], "ramp_time": 0.1}},
    scenario={"kind": "tire_travel", "rim_center": [0, 0, 0.3], "sinkage_velocity": 0.1,
              "sinkage_force": 20, "slip": 0.05, "omega": 1.8, "radius": 0.272})
s["time"] = {"dt": 1e-3, "end": 0.2}
s["output"]["every"] = 50
rc, out, err = run(s)
check(rc == 0, f"run exits 0 (got {rc}: {err})")
check("results:" in out and "results.h5" in out, "run prints where its results are")
no_orphans(s, "normal run")

f = h5(s)
dem, fem, trac = f["/dem/series"][:], f["/fem/series"][:], f["/coupler/traction"][:]
check(dem.shape == (200, 5) and fem.shape == (200, 5) and trac.shape == (200, 7),
      f"one row per step: {dem.shape} {fem.shape} {trac.shape}")
check(columns(f["/coupler/traction"]) == ["t", "T_H", "T_R", "T_P", "vertical_load", "sinkage", "torque"],
      "traction columns")
t = np.arange(1, 201) * 1e-3
ramp = np.minimum(t / 0.1, 1.0)
check(np.allclose(dem[:, 0], t, rtol=0, atol=1e-12), "dem time column is t_k")
check(np.allclose(dem[:, 3], N_NODES * ramp, rtol=1e-12), "dem total Fz = 25 N x ramp")
# the FEM receives exactly what the DEM sent, in the same step
check(np.array_equal(fem[:, 1:4], dem[:, 1:4]), "fem received the dem forces")
check(np.allclose(trac[:, 2], -0.1 * N_NODES * ramp, rtol=1e-12), "T_R = sum of negative Fx")
check(np.all(trac[:, 1] == 0), "T_H = 0 (no forward force)")
check(np.allclose(trac[:, 3], trac[:, 1] - np.abs(trac[:, 2])), "T_P = T_H - |T_R|")
# sinkage at 0.1 m/s until the load reaches 20 N (t = 0.08 s: 79 moves)
check(abs(trac[-1, 5] - 0.0079) < 1e-9, f"sinkage stops at 7.9 mm (got {trac[-1, 5]})")
# snapshot at step 50: surface = X0 + c, c_z = 0.3 - 0.1 * 49 dt (DEM sees t_49)
x50 = f["/dem/steps/50/x"][:]
check(x50.shape == (N_NODES, 3), "snapshot shape")
check(np.allclose(x50[:, 2], 0.3 - 0.0049 - 0.27, atol=1e-12), "snapshot z at step 50")
check(np.allclose(np.sort(np.unique(x50[:, 0].round(12))), np.linspace(-0.1, 0.1, 5)), "snapshot x")
# after the sinkage phase the rim rotates: at step 200 the surface is rotated
x200 = f["/dem/steps/200/x"][:]
angle = 1.8 * (199 - 79) * 1e-3  # travel began at step 80, the DEM sees t_199
cx = 0.272 * 1.8 * 0.95 * (199 - 79) * 1e-3
X0 = x50 - np.array([0, 0, 0.3 - 0.0049])
R = np.array([[math.cos(angle), 0, math.sin(angle)], [0, 1, 0], [-math.sin(angle), 0, math.cos(angle)]])
expect = X0 @ R.T + np.array([cx, 0, 0.3 - 0.0079])
check(np.allclose(x200, expect, atol=1e-9), f"rotated surface at step 200 (max err {np.abs(x200 - expect).max():.3g})")
cfg = json.loads(f.attrs["config"])
check(cfg["name"] == s["name"] and cfg["processes"]["dem"]["force_per_node"] == [-0.1, 0.0, 1.0],
      "config stored in the file")
steps = sorted(int(k) for k in f["/dem/steps"].keys())
check(steps == [50, 100, 150, 200], f"snapshots at output steps: {steps}")
xd = ET.parse(os.path.join(s["output"]["dir"], "dem.xdmf")).getroot()
grids = xd.findall(".//Grid[@GridType='Uniform']")
check(len(grids) == 4, f"XDMF lists 4 snapshots (got {len(grids)})")
done()
