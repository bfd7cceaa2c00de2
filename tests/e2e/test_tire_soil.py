"""The tread on soil, coupled through cosim: fem_server (the paper's tread
band, coarse) pressed into a small dem_server bed by the tire_travel
scenario. Forces must balance across the processes: the grain forces the
coupler sums on the tread nodes equal the force the DEM reports on its
coupled mesh wall, and box + tread carry the weight of the grains."""
import numpy as np

from common import check, done, h5, no_orphans, run, scene

GRAIN = {"density": 2600, "E": 5e6, "nu": 0.3, "restitution": 0.5, "friction": 0.6}
RUBBER = {"density": 1100, "E": 20e6, "nu": 0.45, "restitution": 0.5, "friction": 0.8}
s = scene("tire_soil", {
    "fem": {"exec": "fem_server", "mesh": {"generate": "tread", "refine": 0.5, "lugs": 16},
            "element": "tet4", "material": {"E": 20e6, "nu": 0.45, "density": 1100, "damping": 50},
            "fixed": {"group": "rim"}, "pressure": {"group": "inner", "value": 2e5}},
    "dem": {"exec": "dem_server", "materials": [GRAIN, RUBBER],
            "particles": {"generate": "bed", "scale": 0.04, "size": [0.3, 0.2],
                          "settle_max_steps": 4000},
            "walls": [{"type": "box", "lo": [0, 0, 0], "hi": [0.3, 0.2, 0.6], "open_top": True}],
            "surface_material": 1, "gravity": [0, 0, -9.81]}},
    scenario={"kind": "tire_travel", "rim_center": [0.15, 0.1, 0.325], "sinkage_velocity": 0.2,
              "sinkage_force": 30, "slip": 0.05, "omega": 2.0, "radius": 0.272})
s["time"] = {"dt": 5e-5, "end": 0.14}
s["output"]["every"] = 700
s["coupling"] = {"handshake_timeout": 300, "step_timeout": 60}
rc, out, err = run(s, timeout=600)
check(rc == 0, f"coupled run ok ({err[-400:]})")
no_orphans(s, "tire on soil")
f = h5(s)
trac, walls = f["/coupler/traction"][:], f["/dem/wall_forces"][:]
load, mesh_fz, box_fz = trac[:, 4], walls[:, 6], walls[:, 3]
touching = load > 1.0
check(touching.sum() > 50, f"the tread reached the grains ({touching.sum()} steps with load > 1 N, max {load.max():.3g} N)")
# one force, two bookkeepings: nodal forces summed by the coupler vs the DEM's own wall sum
err_rel = np.max(np.abs(load - mesh_fz)) / max(load.max(), 1e-30)
check(err_rel < 1e-9, f"sum of nodal forces = DEM mesh-wall force (max rel diff {err_rel:.2g})")
r = f["/dem/steps/700/r"][:]
weight = (4 / 3 * np.pi * r ** 3).sum() * 2600 * 9.81
# Newton: box + tread + weight = rate of change of the grains' momentum, which
# fluctuates step by step (±10 % here) but averages out over the contact
# (the grains start and end nearly at rest)
resid = (box_fz[touching] + mesh_fz[touching] + weight) / weight
check(abs(resid.mean()) < 0.03, f"box + tread carry the weight of the grains on average "
      f"(mean residual {resid.mean():.4f} of the weight {weight:.3g} N)")
fem = f["/fem/series"][:]
check(np.all(np.isfinite(fem)) and fem[-1, 1] > 0, "the tread deforms (strain energy > 0, finite)")
done()
