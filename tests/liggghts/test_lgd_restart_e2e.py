"""liggghts_dem checkpoints through cosim (`checkpoint.every`, `cosim run
--restart`) on another rank count: the small bed of tests/dem/e2e_dem_surface.json
under the fem_stub plane pressed into it, launched as `mpirun -np 2 liggghts_dem`,
checkpointed at step STEPS and run to 2 STEPS; then

1. resumed from that checkpoint under `mpirun -np 2` again: every row after
   the checkpoint of the DEM's, the FEM's and the traction series, and the
   last snapshot of the grains, equal the straight run's bit for bit; the
   wall forces to 1e-12 (the force on the tread is LIGGGHTS' own total over
   its triangles, whose order on a rank a restart changes: round-off, see
   liggghts_dem/README.md "Checkpoints");
2. resumed by one rank (`"exec": "liggghts_dem"`: the coupler lets the launcher
   change, coupler/checkpoint.c): equal to 1e-12 of each quantity's largest
   value (another rank count sums a grain's forces in another order: not
   bitwise);
3. resumed with another engine (`dem_server`): refused, naming the exec key."""
import json
import os
import shutil
import sys

import numpy as np

os.environ.setdefault("HDF5_USE_FILE_LOCKING", "FALSE")  # see test_lgd_e2e.py
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "e2e"))
from common import check, done, h5, no_orphans, run, scratch  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
MPI_ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1")
STEPS = 10          # coupling steps before the checkpoint, and after it
DT = 1e-3           # s, the scene's coupling step
TOL = 1e-12         # another rank count: relative to each quantity's largest value
MPI2 = ["mpirun", "-np", "2", "liggghts_dem"]
SERIES = ("/dem/series", "/dem/wall_forces", "/fem/series", "/coupler/traction")
NOT_BITWISE = ("/dem/wall_forces",)  # LIGGGHTS' sum over the triangles, in another order

with open(os.path.join(HERE, "..", "dem", "e2e_dem_surface.json")) as f:
    BASE = json.load(f)
BASE["name"] = f"lgd_restart_{os.getpid()}"
BASE["time"]["end"] = 2 * STEPS * DT
BASE["output"]["every"] = STEPS
BASE["checkpoint"] = {"every": STEPS, "keep": 3}
BASE["scenario"]["rim_center"][2] = 0.285  # the plane 3 mm into the bed from the start
BASE["processes"]["dem"]["exec"] = MPI2


def variant(key, dem_exec):
    s = json.loads(json.dumps(BASE))
    s["output"]["dir"] = os.path.join(scratch("cosim-lgd-restart-"), key)
    s["processes"]["dem"]["exec"] = dem_exec
    return s


def rows_after(f, ds, t0):
    a = f[ds][...]
    return a[a[:, 0] > t0 + 1e-9 * DT]


def compare(what, got, ref, bitwise):
    """Series rows after the checkpoint (wall-clock columns aside: the coupler's
    series is not compared) and the last snapshot of the grains."""
    t0 = STEPS * DT
    worst = 0.0
    for ds in SERIES:
        a, b = rows_after(got, ds, t0), rows_after(ref, ds, t0)
        if not check(a.shape == b.shape and len(a) == STEPS, f"{what}: {ds} has {STEPS} rows after the "
                     f"checkpoint ({a.shape} against {b.shape})"):
            return
        e = np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300)
        worst = max(worst, e)
        if bitwise and ds not in NOT_BITWISE:
            check(np.array_equal(a, b), f"{what}: {ds} equals the straight run's bit for bit ({e:.3g})")
        print(f"{what}: {ds} max |diff| / max = {e:.3g}")
    snap = f"/dem/steps/{2 * STEPS}"
    for q in ("x", "v", "omega"):
        a, b = got[f"{snap}/{q}"][...], ref[f"{snap}/{q}"][...]
        e = np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300)
        worst = max(worst, e)
        if bitwise:
            check(np.array_equal(a, b), f"{what}: {q} at step {2 * STEPS} equals bit for bit ({e:.3g})")
        print(f"{what}: grains' {q} max |diff| / max = {e:.3g}")
    check(worst <= TOL, f"{what}: equal to the straight run to {TOL} ({worst:.3g})")


def restart(key, dem_exec, ckpt):
    s = variant(key, dem_exec)
    os.makedirs(s["output"]["dir"])
    path = os.path.join(s["output"]["dir"], os.path.basename(ckpt))
    shutil.copy(ckpt, path)
    rc, _, err = run(s, "--restart", path, timeout=600, env=MPI_ENV)
    no_orphans(s, key)
    return s, rc, err


straight = variant("straight", MPI2)
rc, _, err = run(straight, timeout=600, env=MPI_ENV)
no_orphans(straight, "straight")
if not check(rc == 0, f"straight run under mpirun -np 2 ok ({err[-500:]})"):
    done()
ref = h5(straight)
check(np.max(np.abs(ref["/fem/series"][:, 3])) > 0, "the plane presses on the grains")
ckpt = os.path.join(straight["output"]["dir"], f"checkpoint_{STEPS}.h5")
check(os.path.exists(ckpt), f"checkpoint of step {STEPS} written")

s, rc, err = restart("np2", MPI2, ckpt)
if check(rc == 0, f"restart under mpirun -np 2 ok ({err[-500:]})"):
    compare("2 ranks resumed on 2", h5(s), ref, bitwise=True)
s, rc, err = restart("np1", "liggghts_dem", ckpt)
if check(rc == 0, f"restart of the 2-rank checkpoint on 1 rank ok ({err[-500:]})"):
    compare("2 ranks resumed on 1", h5(s), ref, bitwise=False)
s, rc, err = restart("engine", "dem_server", ckpt)
check(rc != 0 and "processes.dem.exec" in err,
      f"a restart with another engine is refused naming processes.dem.exec (rc {rc}: {err[-300:]})")
done()
