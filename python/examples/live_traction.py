#!/usr/bin/python3
"""Traction while it runs: T_H, T_R and T_P of a tyre scene, plotted live
from the monitor bus.

    build/bin/cosim run configs/default.json &       # its bus: bus.monitor
    /usr/bin/python3 python/examples/live_traction.py runs/default [--png traction.png]

The argument is the run's output.dir (or the bus endpoint). The plot follows
the run and stays open at its end (with --png it is saved and the script
exits: for machines without a display, MPLBACKEND=Agg).
"""
import argparse
import os
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
import cosim  # noqa: E402

COLUMNS = ("T_H", "T_R", "T_P")  # seed 000 §5: gross tractive effort, running resistance, drawbar pull
REDRAW_S = 0.25

ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
ap.add_argument("run", help="the run's output.dir, or its bus endpoint")
ap.add_argument("--png", help="save the figure here at the end (and exit)")
a = ap.parse_args()
import matplotlib  # noqa: E402
if a.png:
    matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

fig, ax = plt.subplots(figsize=(7, 4))
lines = {c: ax.plot([], [], label=c)[0] for c in COLUMNS}
ax.set_xlabel("t [s]")
ax.set_ylabel("force [N]")
ax.legend(loc="upper left")
plt.ion()
t, rows, drawn = [], {c: [] for c in COLUMNS}, 0.0


def draw():
    for c in COLUMNS:
        lines[c].set_data(t, rows[c])
    ax.relim()
    ax.autoscale_view()
    ax.set_title(f"traction, t = {t[-1]:.4g} s" if t else "waiting for the run")
    plt.pause(0.001)


for msg in cosim.Monitor(a.run, topics="coupler.traction"):
    row = msg.row  # {"t": ..., "T_H": ..., ...}: the columns of /coupler/traction
    t.append(row["t"])
    for c in COLUMNS:
        rows[c].append(row[c])
    if time.monotonic() - drawn > REDRAW_S:
        draw()
        drawn = time.monotonic()
draw()
if a.png:
    fig.savefig(a.png, dpi=100)
    print(f"{len(t)} rows, saved {a.png}")
else:
    plt.ioff()
    plt.show()
