"""Checkpoint and restart, bit for bit, on the default scene (dem_server +
fem_server: the grains with their contact springs and neighbour lists, the
tread's displacements and velocities, the rim's phase), shortened with --set:
the rim sinks fast so that the tread meets the bed, the load passes
sinkage_force and the rim starts travelling before the checkpoint of step N.
2N steps straight give the same results.h5, row for row (wall-clock columns
aside), as N steps, then `--restart` from the checkpoint for N more; the
restarted dem_server does not settle its bed again (the checkpoint holds it).
Twice: with the rim's prescribed travel, and in the load rig, whose vertical
degree of freedom accelerates the rim every step (fem_server's frame
acceleration is the difference of the rim's velocities over a step: the last
step's must be in the tread's state; until stop 56 it was not, and a restart
in a rig parted from the straight run at its first step)."""
import os

import h5py
import numpy as np

from rel import ROOT, check, cosim, differences
from common import done, scratch

SCENE = os.path.join(ROOT, "configs", "default.json")
N, DT = 160, 5e-5
base = scratch("cosim-restart-tyre-")
common = ["--quiet", "--set", f"name=restart_tyre_{os.getpid()}", "--set", f"checkpoint.every={N}",
          "--set", "output.every=40", "--set", "scenario.sinkage_velocity=2.5",
          "--set", "scenario.sinkage_force=5"]


def run(out, steps, *extra):
    return cosim("run", SCENE, *common, "--set", f"output.dir={out}",
                 "--set", f"time.end={steps * DT!r}", *extra)


RIGS = {"kinematic": [], "load": ["--set", "scenario.rig=load"]}
for rig, extra in RIGS.items():
    a, b = os.path.join(base, rig + "_straight"), os.path.join(base, rig + "_restarted")
    rc, out, err = run(a, 2 * N, *extra)
    check(rc == 0, f"{rig}: 2N steps straight ({err[-300:]})")
    rc, out, err = run(b, N, *extra)
    check(rc == 0 and os.path.exists(os.path.join(b, f"checkpoint_{N}.h5")),
          f"{rig}: N steps and checkpoint_{N}.h5 ({err[-300:]})")
    rc, out, err = run(b, 2 * N, *extra, "--restart", "latest")
    check(rc == 0, f"{rig}: restarted for N more ({err[-300:]})")
    log = open(os.path.join(b, "logs", "dem.log")).read()
    check("not settling" in log, f"{rig}: the restarted dem_server takes the bed from the checkpoint")
    diff, same = differences(a, b)
    check(not diff and same > 20, f"{rig}: N + restart + N equals 2N straight, bit for bit ({same} "
          f"equal; differences: {diff[:5]})")
    t = h5py.File(os.path.join(a, "results.h5"), "r")["/coupler/traction"][()]
    # travelling: the kinematic rig freezes the rim's height (the sinkage
    # stays), the load rig's height moves with its own acceleration (the
    # sinkage's second difference, zero while it sinks at a set speed)
    load, sink = t[:, 4], t[:, 5]
    travel = (np.diff(sink) == 0) if rig == "kinematic" else (np.abs(np.diff(sink, 2)) > 1e-12)
    check(np.count_nonzero(load[:N]) > 5 and np.count_nonzero(travel[N - 20:N]) > 10,
          f"{rig}: the tread is on the grains and travelling before step {N} (the test bites: "
          f"{np.count_nonzero(load[:N])} steps with load, {np.count_nonzero(travel[N - 20:N])} of "
          f"the last 20 travelling)")
done()
