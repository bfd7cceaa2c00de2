"""Issue 6 feeds issue 5: `cosim road`, `cosim springs` and `cosim green` write
the files that contact_block reads (green/FORMATS.md), and a `cosim run` of the
block on them converges at every step, with both the ZOH- and the
point-sampled Green's functions."""
import os
import subprocess

import numpy as np

from common import COSIM, check, done, h5, no_orphans, run, scene, scratch

d = scratch("cosim-gb-")
p = lambda name: os.path.join(d, name)
cmds = [["road", "--out", p("road.h5"), "--points", "400", "--pitch", "5e-5", "--lambda-short", "2e-4"],
        ["springs", "--road", p("road.h5"), "--out", p("springs.h5"), "--elements", "10"],
        ["green", "--model", "dynamic", "--elements", "10", "--size", "2e-3", "--Q", "128",
         "--out", p("green.h5"), "--out-point", p("green_point.h5")]]
for c in cmds:
    r = subprocess.run([COSIM, *c], capture_output=True, text=True, timeout=300)
    check(r.returncode == 0, f"cosim {c[0]} ok ({r.stderr[-300:]})")

forces = {}
for sampling in ("green.h5", "green_point.h5"):
    s = scene("green_block", {"block": {
        "exec": "contact_block",
        "grid": {"nx": 10, "ny": 10, "dx": 2e-3, "dy": 2e-3},
        "road": {"kind": "springs_file"},
        "springs": {"kind": "file", "file": p("springs.h5")},
        "green": {"kind": "file", "file": p(sampling)},
        "solver": {"method": "dual_newton"}}},
        scenario={"kind": "indentation", "profile": "linear", "depth": 1e-4, "ramp_time": 0.004})
    s["time"] = {"dt": 1 / 51200, "end": 0.004}
    rc, out, err = run(s)
    check(rc == 0, f"{sampling}: run ok ({err[-300:]})")
    rows = h5(s)["/block/series"][:]
    check(np.all(rows[:, 6] == 1), f"{sampling}: every step converged")
    forces[sampling] = rows[:, 2]
    no_orphans(s, sampling)
f = forces["green.h5"]
check(f[-1] > 1 and np.all(np.diff(f) >= -1e-9 * f[-1]),
      f"ZOH: the force grows with the indentation to {f[-1]:.3g} N")
check(np.any(forces["green_point.h5"] != f), "point sampling gives another history")
done()
