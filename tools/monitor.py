#!/usr/bin/python3
"""Live plot of a time series on a cosim run's monitor bus (cosim.Monitor).

    /usr/bin/python3 tools/monitor.py OUTPUT_DIR|ENDPOINT [--topic dem.series]
                                      [--column 1|NAME] [--seconds 0] [--png out.png]

OUTPUT_DIR is the run's output.dir (its endpoints.json names the bus), or the
bus endpoint (tcp://127.0.0.1:PORT); the plot ends with the run. The column
is an index of the series row (0 is t) or, for topics that name their columns
(coupler.traction, coupler.series, coupler.timing), a name. --png saves the
plot (without a display: MPLBACKEND=Agg). The run never waits for it.
"""
import argparse
import os
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "python"))
import cosim  # noqa: E402

ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
ap.add_argument("source")
ap.add_argument("--topic", default="dem.series")
ap.add_argument("--column", default="1", help="index in the row (0 is t), or a column name")
ap.add_argument("--seconds", type=float, default=0, help="stop after this long (0: at the run's end)")
ap.add_argument("--png", help="save the plot to this file as well")
a = ap.parse_args()
import matplotlib.pyplot as plt  # noqa: E402

fig, ax = plt.subplots()
(line,) = ax.plot([], [], "-")
ax.set(xlabel="t [s]", ylabel=f"{a.topic} {a.column}", title=f"cosim monitor: {a.source}")
plt.ion()
t, y, drawn, start = [], [], 0.0, time.monotonic()
mon = cosim.Monitor(a.source, topics=[a.topic], timeout=a.seconds or None)
print(f"monitor.py: listening on {mon.endpoint}", file=sys.stderr, flush=True)
try:
    for msg in mon:
        names = msg.header.get("columns") or []
        if not a.column.isdigit() and a.column not in names:
            sys.exit(f"monitor.py: {a.topic} has no column '{a.column}' ({', '.join(names) or 'unnamed'})")
        t.append(msg.t)
        y.append(msg["series"][int(a.column) if a.column.isdigit() else names.index(a.column)])
        if time.monotonic() - drawn > 0.2 or not t[1:]:
            line.set_data(t, y)
            ax.relim()
            ax.autoscale_view()
            plt.pause(0.001)
            drawn = time.monotonic()
        if a.seconds and time.monotonic() - start > a.seconds:
            break
except KeyboardInterrupt:
    pass
mon.close()
line.set_data(t, y)
ax.relim()
ax.autoscale_view()
if a.png:
    fig.savefig(a.png, dpi=100)
    print(f"{len(t)} points, saved {a.png}")
