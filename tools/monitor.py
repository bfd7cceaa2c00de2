#!/usr/bin/python3
"""Live plot of a time series published on a cosim run's monitor bus.

    /usr/bin/python3 tools/monitor.py ENDPOINT [--topic dem.series]
                                      [--column 1] [--seconds 0] [--png out.png]

ENDPOINT is the scene's bus.monitor (e.g. tcp://127.0.0.1:5560). The topic's
messages carry an array "series" (one row per step); column names are in the
run's results.h5 (attribute "columns"), or pass --column by index. With
--png the plot is also saved (useful without a display: MPLBACKEND=Agg).
It may join late and may be closed at any time: the run does not wait for it.
"""
import argparse
import json
import sys

import numpy as np
import zmq


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("endpoint")
    ap.add_argument("--topic", default="dem.series")
    ap.add_argument("--column", type=int, default=1, help="column of the series row to plot (0 is t)")
    ap.add_argument("--seconds", type=float, default=0, help="stop after this long (0: until Ctrl-C)")
    ap.add_argument("--png", help="save the plot to this file as well")
    a = ap.parse_args()

    import matplotlib
    if a.png and not sys.stdout.isatty():
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    sub = zmq.Context().socket(zmq.SUB)
    sub.setsockopt_string(zmq.SUBSCRIBE, a.topic)
    sub.connect(a.endpoint)
    t, y = [], []
    fig, ax = plt.subplots()
    (line,) = ax.plot([], [], "-")
    ax.set_xlabel("t [s]")
    ax.set_ylabel(f"{a.topic} column {a.column}")
    ax.set_title(f"cosim monitor: {a.endpoint}")
    plt.ion()
    import time
    start = time.time()
    try:
        while not a.seconds or time.time() - start < a.seconds:
            if sub.poll(100):
                frames = sub.recv_multipart()
                hdr = json.loads(frames[1])
                for spec, fr in zip(hdr["arrays"], frames[2:]):
                    if spec["name"] == "series":
                        row = np.frombuffer(fr, dtype="<f8")
                        t.append(row[0])
                        y.append(row[a.column])
                # drain what queued up, then redraw once
                continue_draw = not sub.poll(0)
                if continue_draw:
                    line.set_data(t, y)
                    ax.relim()
                    ax.autoscale_view()
                    plt.pause(0.001)
            else:
                plt.pause(0.05)
    except KeyboardInterrupt:
        pass
    line.set_data(t, y)
    ax.relim()
    ax.autoscale_view()
    if a.png:
        fig.savefig(a.png, dpi=100)
        print(f"{len(t)} points, saved {a.png}")


if __name__ == "__main__":
    main()
