#!/usr/bin/env python3
"""What monitors cost a run: the stub tyre scene with big snapshots at every
step (150 x 150 surface nodes), run with 0, 1 and 20 monitors that subscribe to
everything and never read, and with one that reads everything. Runs are
alternated (one of each kind per round) and the minimum of the rounds is kept;
the cost is quoted as a ratio against the no-monitor run of the same rounds.

    /usr/bin/python3 bench/proto/bench_monitor.py [--bin build/bin] [--rounds 3]
        [--out bench/results/monitor.md]
"""
import argparse
import json
import os
import subprocess
import tempfile
import threading
import time

import zmq


def scene(name, n, end, ep):
    out = tempfile.mkdtemp(prefix="cosim-bench-mon-")
    return {
        "name": name,
        "time": {"dt": 1e-3, "end": end},
        "output": {"dir": os.path.join(out, name), "every": 1},
        "bus": {"monitor": ep, "hwm": 1000},
        "coupling": {"handshake_timeout": 10, "step_timeout": 30},
        "scenario": {"kind": "tire_travel", "rim_center": [0, 0, 0.3],
                     "sinkage_velocity": 0.1, "sinkage_force": 20, "slip": 0.05,
                     "omega": 1.8, "radius": 0.272},
        "processes": {
            "fem": {"exec": "fem_stub",
                    "surface": {"plane": {"size": [0.2, 0.16], "n": [n, n], "z": -0.27}}},
            "dem": {"exec": "dem_stub", "force_per_node": [-0.1, 0.0, 1.0],
                    "ramp_time": 0.1}},
    }


def reader(ep, stop, count):
    sub = zmq.Context.instance().socket(zmq.SUB)
    sub.setsockopt(zmq.SUBSCRIBE, b"")
    sub.connect(ep)
    while not stop.is_set():
        if sub.poll(50):
            sub.recv_multipart()
            count[0] += 1
    sub.close(linger=0)


def one_run(cosim, n, end, lazy, reading):
    d = tempfile.mkdtemp(prefix="cosim-bench-mon-")
    ep = "ipc://" + os.path.join(d, "monitor")
    s = scene(f"benchmon_{os.getpid()}", n, end, ep)
    path = os.path.join(d, "scene.json")
    with open(path, "w") as f:
        json.dump(s, f)
    ctx = zmq.Context.instance()
    socks = []
    for _ in range(lazy):  # subscribe to everything, never read
        z = ctx.socket(zmq.SUB)
        z.setsockopt(zmq.RCVHWM, 10)
        z.setsockopt(zmq.SUBSCRIBE, b"")
        z.connect(ep)
        socks.append(z)
    stop, count, th = threading.Event(), [0], None
    if reading:
        th = threading.Thread(target=reader, args=(ep, stop, count))
        th.start()
    t0 = time.perf_counter()
    p = subprocess.run([cosim, "run", path], capture_output=True, text=True, timeout=600)
    took = time.perf_counter() - t0
    stop.set()
    if th:
        th.join()
    for z in socks:
        z.close(linger=0)
    if p.returncode != 0:
        raise SystemExit(f"run failed: {p.stderr[-500:]}")
    return took


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--bin", default="build/bin")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--nodes", type=int, default=150)
    ap.add_argument("--end", type=float, default=0.3)
    ap.add_argument("--out", default="bench/results/monitor.md")
    a = ap.parse_args()
    cosim = os.path.abspath(os.path.join(a.bin, "cosim"))
    kinds = [("none", 0, False), ("1 stalled", 1, False), ("20 stalled", 20, False),
             ("1 reading", 0, True)]
    best = {k: float("inf") for k, _, _ in kinds}
    for r in range(a.rounds):
        for name, lazy, reading in kinds:
            best[name] = min(best[name], one_run(cosim, a.nodes, a.end, lazy, reading))
            print(f"round {r + 1}: {name}: {best[name]:.2f} s (best so far)", flush=True)
    load = os.getloadavg()[0]
    steps = int(round(a.end / 1e-3))
    lines = [
        "# What monitors cost a run",
        "",
        f"Stub tyre scene, {a.nodes} x {a.nodes} surface nodes, a snapshot of every "
        f"participant at each of {steps} steps (the worst case for the bus), bus hwm 1000 "
        f"messages. Minimum of {a.rounds} alternated rounds, whole `cosim run` process; "
        f"ratio against the run without monitors of the same rounds. Load average at the "
        f"end: {load:.1f}. `bench/proto/bench_monitor.py` regenerates this file.",
        "",
        "| monitors | wall (s) | ratio |",
        "|---|---|---|",
    ]
    for name, _, _ in kinds:
        lines.append(f"| {name} | {best[name]:.2f} | {best[name] / best['none']:.2f} |")
    lines += ["",
              "A stalled monitor subscribes to every topic and never reads (its queue "
              "fills, then ZeroMQ drops for it); the reading one drains everything.", ""]
    with open(a.out, "w") as f:
        f.write("\n".join(lines))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
