"""liggghts_dem in place of dem_server, through cosim: started by the launcher
(one MPI rank) and started by hand under `mpirun -np 2` with `cosim run
--attach` (as on a cluster).

1. A grain squeezed and dragged by the fem_stub surface (sinking, then
   rolling): the force history equals dem_server's to 1e-6 (one DEM step per
   coupling step, where dem_server's returned nodal forces already are the
   step average; tests/liggghts/test_lgd_impact.c covers sub-steps).
2. The stub tyre scene (fem_stub pressed into a settled bed, 25 DEM sub-steps
   per coupling step) and 3. a small coupled tyre scene (fem_server's tread
   band on a bed that dem_server settled and saved once, which both DEMs then
   load): the nodal forces sum to minus the tread's force on the grains
   (LIGGGHTS' own mesh total) to 1e-12 at every step, and the traction is
   close to dem_server's (a granular bed diverges chaotically: the means over
   the contact are compared; in the stub scene each DEM settles its own bed).
4. rim_center "auto" on that saved bed: liggghts_dem's ready gives the bed top
   dem_server's gives, to the printed digit."""
import json
import os
import random
import re
import subprocess
import sys
import time

import numpy as np

# the coupler's results.h5 descriptor is inherited by its children, and the
# daemon a one-rank MPI start leaves behind can hold the file's lock a moment
# after cosim has exited: read without taking the lock
os.environ.setdefault("HDF5_USE_FILE_LOCKING", "FALSE")
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "e2e"))
from common import BIN, COSIM, check, done, h5, no_orphans, run, scene, scratch, write  # noqa: E402

MPI_ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1")
GRAIN = {"density": 2600, "E": 5e6, "nu": 0.3, "restitution": 0.5, "friction": 0.6}
RUBBER = {"density": 1100, "E": 20e6, "nu": 0.45, "restitution": 0.5, "friction": 0.8}


def variant(s, name, dem_exec):
    """A copy of scene s under its own name and output folder, DEM swapped."""
    v = json.loads(json.dumps(s))
    v["name"] = f"{s['name']}_{name}"
    v["output"]["dir"] = s["output"]["dir"] + "_" + name
    v["processes"]["dem"]["exec"] = dem_exec
    return v


def run_attached(s, ranks, timeout=600):
    """cosim run --attach; every participant started by hand, liggghts_dem
    under mpirun. Returns the coupler's exit code and stderr."""
    port = random.randint(20000, 40000)
    s["coupling"]["attach_endpoint"] = f"tcp://127.0.0.1:{port}"
    s.setdefault("bus", {})["monitor"] = f"tcp://127.0.0.1:{port + 2}"
    coupler = subprocess.Popen([COSIM, "run", write(s), "--attach"], stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True)
    time.sleep(0.3)
    parts = []
    for name, sec in s["processes"].items():
        cmd = [os.path.join(BIN, sec["exec"]), "--endpoint", s["coupling"]["attach_endpoint"],
               "--name", name]
        if sec["exec"] == "liggghts_dem":
            cmd = ["mpirun", "-np", str(ranks)] + cmd
        parts.append(subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                      env=MPI_ENV))
    _, err = coupler.communicate(timeout=timeout)
    for p in parts:
        _, perr = p.communicate(timeout=60)
        check(p.returncode == 0, f"{s['name']}: participant exits 0 ({perr[-400:]})")
    return coupler.returncode, err


def runs(s, attach_too=True):
    """dem_server, liggghts_dem (1 rank, launched), liggghts_dem (2 ranks,
    attached): the three scenes, each checked to have run."""
    out = {}
    for key, dem in (("dem_server", "dem_server"), ("np1", "liggghts_dem")):
        v = variant(s, key, dem)
        rc, _, err = run(v, timeout=600, env=MPI_ENV)
        check(rc == 0, f"{v['name']}: run ok ({err[-500:]})")
        out[key] = v
        no_orphans(v, v["name"])
    if attach_too:
        v = variant(s, "np2", "liggghts_dem")
        rc, err = run_attached(v, 2)
        check(rc == 0, f"{v['name']}: attached run under mpirun -np 2 ok ({err[-500:]})")
        out["np2"] = v
    return out


def rel_diff(a, b):
    return np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300)


# ---------------------------------------------------------------- 1. squeeze
squeeze = scene("lgd_squeeze", {
    "fem": {"exec": "fem_stub", "surface": {"plane": {"size": [0.04, 0.04], "n": [4, 4], "z": -0.27}}},
    "dem": {"exec": "dem_server", "materials": [GRAIN], "gravity": [0, 0, -9.81], "dt": 2e-5,
            "walls": [{"type": "plane", "point": [0, 0, 0], "normal": [0, 0, 1]}],
            "particles": [{"x": [0.001, 0.002, 0.0035], "r": 0.0035}]}},
    scenario={"kind": "tire_travel", "rim_center": [0, 0, 0.278], "sinkage_velocity": 0.1,
              "sinkage_force": 0.3, "slip": 0.05, "omega": 1.8, "radius": 0.272})
squeeze["time"] = {"dt": 2e-5, "end": 0.03}
squeeze["output"]["every"] = 500
r = runs(squeeze)
# launched through MPI: an argv exec with the launcher in front (the coupler
# appends --endpoint/--name and supervises mpirun)
v = variant(squeeze, "np2_launched", ["mpirun", "-np", "2", "liggghts_dem"])
rc, _, err = run(v, timeout=600, env=MPI_ENV)
check(rc == 0, f"{v['name']}: launched under mpirun -np 2 ok ({err[-500:]})")
no_orphans(v, v["name"])
r["np2_launched"] = v
ref = h5(r["dem_server"])
check(np.max(np.abs(ref["/fem/series"][:, 3])) > 0.3, "squeeze: the plate pressed the grain")
for key in ("np1", "np2", "np2_launched"):
    f = h5(r[key])
    for ds, cols in (("/dem/wall_forces", slice(1, None)), ("/fem/series", slice(1, 4)),
                     ("/coupler/traction", slice(1, None))):
        e = rel_diff(f[ds][:, cols], ref[ds][:, cols])
        print(f"squeeze {key}: {ds} max |diff| / max = {e:.3g}")
        check(e < 1e-6, f"squeeze {key}: {ds} equals dem_server's to 1e-6 ({e:.3g})")


# limit_force (the normal force never pulls): LIGGGHTS' `limitForce on` in the
# pair style and the walls; a grain bouncing off the floor (where the damping
# would pull as it leaves)
lf = variant(squeeze, "limit", "dem_server")
lf["processes"]["dem"]["limit_force"] = True
lf["processes"]["dem"]["particles"] = [{"x": [0.001, 0.002, 0.0036], "v": [0, 0, -0.7], "r": 0.0035}]
lf_runs = {}
for key, dem in (("dem_server", "dem_server"), ("np1", "liggghts_dem")):
    v = variant(lf, key, dem)
    rc, _, err = run(v, timeout=600, env=MPI_ENV)
    check(rc == 0, f"{v['name']}: run ok ({err[-500:]})")
    lf_runs[key] = h5(v)
for ds, cols in (("/dem/wall_forces", slice(1, None)), ("/coupler/traction", slice(1, None))):
    e = rel_diff(lf_runs["np1"][ds][:, cols], lf_runs["dem_server"][ds][:, cols])
    print(f"impact limit_force np1: {ds} max |diff| / max = {e:.3g}")
    check(e < 1e-6, f"impact limit_force: {ds} equals dem_server's to 1e-6 ({e:.3g})")
# the same impact without the clamp differs (else this part could not fail)
nolf = variant(lf, "nolimit", "dem_server")
nolf["processes"]["dem"]["limit_force"] = False
rc, _, err = run(nolf, timeout=600, env=MPI_ENV)
check(rc == 0, f"{nolf['name']}: run ok ({err[-500:]})")
e = rel_diff(h5(nolf)["/dem/wall_forces"][:, 1:], lf_runs["dem_server"]["/dem/wall_forces"][:, 1:])
print(f"impact: limit_force changes dem_server's wall forces by {e:.3g} of their maximum")
check(e > 1e-3, f"impact: limit_force changes the wall forces ({e:.3g})")


# A surface with a flat triangle (LIGGGHTS would drop it, and the nodal forces
# need every triangle) is refused by name, and the run stops cleanly.
bad = scene("lgd_degenerate", {
    "fem": {"exec": "fem_stub", "surface": {"nodes": [[0, 0, -0.27], [0.02, 0, -0.27], [0, 0.02, -0.27],
                                                       [0.04, 0, -0.27]],
                                             "triangles": [[0, 1, 2], [0, 1, 3]]}},
    "dem": {"exec": "liggghts_dem", "materials": [GRAIN], "gravity": [0, 0, -9.81],
            "particles": [{"x": [0.005, 0.005, 0.02], "r": 0.0035}]}},
    scenario={"kind": "tire_travel", "rim_center": [0, 0, 0.3], "sinkage_velocity": 0.1, "sinkage_force": 1,
              "slip": 0.05, "omega": 1.8, "radius": 0.272})
rc, _, err = run(bad, timeout=120, env=MPI_ENV)
check(rc == 3 and "surface_tri[1]: the triangle (nodes 0, 1, 3) has no area" in err,
      f"degenerate surface triangle refused by name ({rc}: {err[-400:]})")
no_orphans(bad, "degenerate surface")


# ------------------------------------------------- 2. and 3. the tyre scenes
def conservation(f, mesh_wall, name):
    """Nodal-force sum (what the FEM side received) against the DEM's mesh
    wall force (LIGGGHTS' stress module: minus the force on the grains)."""
    wall = f["/dem/wall_forces"][:, 1 + 3 * mesh_wall:4 + 3 * mesh_wall]
    trac = f["/coupler/traction"][:]
    load = trac[:, 4]
    e = np.max(np.abs(wall[:, 2] - load)) / np.max(np.abs(load))
    print(f"{name}: max |sum of nodal F_z - DEM mesh force| / max = {e:.3g}")
    check(np.max(np.abs(load)) > 1.0 and e < 1e-12, f"{name}: nodal forces sum to the mesh force ({e:.3g})")
    return trac


def traction_means(trac):
    touching = trac[:, 4] > 0.2 * np.max(trac[:, 4])
    return {c: trac[touching, i].mean() for i, c in ((1, "T_H"), (2, "T_R"), (3, "T_P"), (4, "load"))}


def compare_traction(runs_, name, tol):
    base = traction_means(h5(runs_["dem_server"])["/coupler/traction"][:])
    for key in ("np1", "np2"):
        if key not in runs_:
            continue
        m = traction_means(h5(runs_[key])["/coupler/traction"][:])
        text = ", ".join(f"{c} {m[c]:.4g} ({base[c]:.4g})" for c in base)
        print(f"{name} {key}: mean over the contact, liggghts_dem (dem_server): {text}")
        load_err = abs(m["load"] - base["load"]) / abs(base["load"])
        check(load_err < tol, f"{name} {key}: mean vertical load within {tol:.0%} of dem_server's "
              f"({load_err:.3g})")
        for c in ("T_H", "T_R", "T_P"):
            err = abs(m[c] - base[c]) / max(abs(base["load"]), 1e-30)
            check(err < tol, f"{name} {key}: mean {c} within {tol:.0%} of the load of dem_server's "
                  f"({err:.3g})")


here = os.path.dirname(os.path.abspath(__file__))
with open(os.path.join(here, "..", "dem", "e2e_dem_surface.json")) as fh:
    stub = json.load(fh)
stub_scene = scene("lgd_stub_tyre", stub["processes"], scenario=stub["scenario"])
stub_scene["time"], stub_scene["output"]["every"] = stub["time"], 50
stub_scene["coupling"].update({"handshake_timeout": 60, "step_timeout": 60})
r = runs(stub_scene)
for key, v in r.items():
    conservation(h5(v), 1, f"stub tyre {key}")
compare_traction(r, "stub tyre", 0.10)

def tyre_scene(name, particles, end):
    s = scene(name, {
        "fem": {"exec": "fem_server", "mesh": {"generate": "tread", "refine": 0.5, "lugs": 16},
                "element": "tet4", "material": {"E": 20e6, "nu": 0.45, "density": 1100, "damping": 50},
                "fixed": {"group": "rim"}, "pressure": {"group": "inner", "value": 2e5}},
        "dem": {"exec": "dem_server", "materials": [GRAIN, RUBBER], "particles": particles,
                "walls": [{"type": "box", "lo": [0, 0, 0], "hi": [0.3, 0.2, 0.6], "open_top": True}],
                "surface_material": 1, "gravity": [0, 0, -9.81], "overlap_tolerance": 0.1}},
        scenario={"kind": "tire_travel", "rim_center": [0.15, 0.1, 0.325], "sinkage_velocity": 0.2,
                  "sinkage_force": 30, "slip": 0.05, "omega": 2.0, "radius": 0.272})
    s["time"] = {"dt": 5e-5, "end": end}
    s["output"]["every"] = 700
    s["coupling"].update({"handshake_timeout": 300, "step_timeout": 60})
    return s


# the bed, settled by dem_server once (a settled bed overlaps by a few % of a
# radius, hence overlap_tolerance)
bed = os.path.join(scratch("cosim-lgd-"), "settled_bed.h5")
settle = tyre_scene("lgd_bed", {"generate": "bed", "scale": 0.04, "size": [0.3, 0.2],
                                "settle_max_steps": 4000, "save": bed}, 5e-5)
rc, _, err = run(settle, timeout=600)
check(rc == 0 and os.path.exists(bed), f"bed settled and saved ({err[-300:]})")
r = runs(tyre_scene("lgd_tyre", {"file": bed}, 0.14))
for key, v in r.items():
    conservation(h5(v), 1, f"coupled tyre {key}")
compare_traction(r, "coupled tyre", 0.05)

# 4. rim_center "auto" (the tread placed over the bed's top under it): liggghts_dem
# reports the same bed top as dem_server on the same saved bed (it reported none,
# and the run was refused)
tops = {}
for key, dem in (("dem_server", "dem_server"), ("np1", "liggghts_dem")):
    v = variant(tyre_scene("lgd_auto", {"file": bed}, 1e-4), key, dem)
    v["scenario"]["rim_center"] = [0.15, 0.1, "auto"]
    rc, _, err = run(v, timeout=600, env=MPI_ENV)
    m = re.search(r'rim_center "auto": bed top (\S+) m', err)
    check(rc == 0 and m is not None, f"{v['name']}: the rim placed by the bed top ({err[-400:]})")
    tops[key] = m.group(1) if m else None
    no_orphans(v, v["name"])
check(tops["dem_server"] is not None and tops["dem_server"] == tops["np1"],
      f"liggghts_dem's bed top is dem_server's: {tops}")
done()
