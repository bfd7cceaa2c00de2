#!/usr/bin/python3
"""Force-driven road (the thesis' future work, ch. 8) through the coupler:
`cosim run configs/tread_block.json` with scenario.profile = force (the coupler
moves a road mass under an external force; contact_block answers with the
contact force). Plots force and road displacement, appends to block.md.

    /usr/bin/python3 bench/block/force_road.py BUILD_DIR
"""
import os
import subprocess
import sys

import h5py
import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
BUILD = sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "build-block")
RES = os.path.join(ROOT, "bench", "results")
out = "/tmp/blk_bench/force_road"
cases = [(0.05, 50.0), (0.05, 100.0), (0.2, 50.0)]
fig, ax = plt.subplots(1, 2, figsize=(11, 4))
lines = ["## Force-driven road (coupler, scenario.profile = force)\n",
         "A road mass m pushed by a constant force F_ext against the block (ZOH synthetic "
         "layer, 51.2 kHz, 20 ms): the contact force oscillates about F_ext (no damping "
         "other than the layer's).\n",
         "| road mass (kg) | F_ext (N) | mean contact force over the last 10 ms (N) | max (N) |",
         "|---|---|---|---|"]
for m, F in cases:
    d = "%s_m%g_F%g" % (out, m, F)
    subprocess.run([os.path.join(BUILD, "bin", "cosim"), "run", os.path.join(ROOT, "configs", "tread_block.json"),
                    "--quiet", "--set", "output.dir=" + d, "--set", "scenario.profile=force",
                    "--set", "scenario.road_mass=%g" % m, "--set", "scenario.road_force=%g" % F,
                    "--set", "time.end=0.02"], check=True, capture_output=True)
    with h5py.File(os.path.join(d, "results.h5")) as f:
        s = f["/block/series"][:]
        cols = [c.decode() if isinstance(c, bytes) else c for c in f["/block/series"].attrs["columns"]]
    t, dr, fc = s[:, cols.index("t")], s[:, cols.index("d_road")], s[:, cols.index("force")]
    ax[0].plot(t * 1e3, fc, lw=1, label="m = %g kg, F = %g N" % (m, F))
    ax[1].plot(t * 1e3, dr * 1e3, lw=1, label="m = %g kg, F = %g N" % (m, F))
    late = t > 0.01
    lines.append("| %g | %g | %.1f | %.1f |" % (m, F, fc[late].mean(), fc.max()))
ax[0].set_ylabel("contact force (N)")
ax[1].set_ylabel("road displacement (mm)")
for a in ax:
    a.set_xlabel("time (ms)")
    a.legend(fontsize=8)
fig.tight_layout()
fig.savefig(os.path.join(RES, "block_force_road.png"), dpi=110)
lines.append("\n![force road](block_force_road.png)\n")
with open(os.path.join(RES, "block.md"), "a") as f:
    f.write("\n".join(lines) + "\n")
print("\n".join(lines))
