"""Checkpoint and restart, bit for bit, on the default scene (dem_server +
fem_server: the grains with their contact springs and neighbour lists, the
tread's displacements and velocities, the rim's phase), shortened with --set:
the rim sinks fast so that the tread meets the bed, the load passes
sinkage_force and the rim starts travelling before the checkpoint of step N.
2N steps straight give the same results.h5, row for row (wall-clock columns
aside), as N steps, then `--restart` from the checkpoint for N more; the
restarted dem_server does not settle its bed again (the checkpoint holds it)."""
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


a, b = os.path.join(base, "straight"), os.path.join(base, "restarted")
rc, out, err = run(a, 2 * N)
check(rc == 0, f"2N steps straight ({err[-300:]})")
rc, out, err = run(b, N)
check(rc == 0 and os.path.exists(os.path.join(b, f"checkpoint_{N}.h5")),
      f"N steps and checkpoint_{N}.h5 ({err[-300:]})")
rc, out, err = run(b, 2 * N, "--restart", "latest")
check(rc == 0, f"restarted for N more ({err[-300:]})")
log = open(os.path.join(b, "logs", "dem.log")).read()
check("not settling" in log, "the restarted dem_server takes the bed from the checkpoint")
diff, same = differences(a, b)
check(not diff and same > 20, f"N + restart + N equals 2N straight, bit for bit ({same} equal; "
      f"differences: {diff[:5]})")
t = h5py.File(os.path.join(a, "results.h5"), "r")["/coupler/traction"][()]
load, travel = t[:, 4], np.diff(t[:, 5]) == 0
check(np.count_nonzero(load[:N]) > 5 and travel[:N].any(),
      f"the tread is on the grains and travelling before step {N} (the test bites: "
      f"{np.count_nonzero(load[:N])} steps with load)")
done()
