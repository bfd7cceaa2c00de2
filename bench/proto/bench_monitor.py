#!/usr/bin/env python3
"""What monitors cost a run: the stub tyre scene with big snapshots at every
step (150 x 150 surface nodes), run with 0, 1, 20 and 50 monitors that
subscribe to everything on the monitor stream and never read (stalled, with
ZeroMQ's default receive queue, as a naive monitor has), with 20 stalled
ones that also subscribe to the snapshot stream, and with one that reads
everything on both. Runs are alternated (one of each kind per round) and the
minimum of the rounds is kept; the cost is quoted as a ratio against the
no-monitor run of the same rounds. Writes the section "Monitors" of
bench/results/reliability.md.

    flock /tmp/cosim-bench.lock /usr/bin/python3 bench/proto/bench_monitor.py
        [--bin build/bin] [--rounds 3] [--out bench/results/reliability.md]
"""
import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import threading
import time

import zmq

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "reliability"))
from mdsection import write_section  # noqa: E402


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
    sub.connect(ep + "-snapshots")
    while not stop.is_set():
        if sub.poll(50):
            sub.recv_multipart()
            count[0] += 1
    sub.close(linger=0)


def one_run(cosim, n, end, lazy, reading, snapshots=False):
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
        z.setsockopt(zmq.SUBSCRIBE, b"")
        z.connect(ep)
        if snapshots:
            z.connect(ep + "-snapshots")
        socks.append(z)
    stop, count, th = threading.Event(), [0], None
    if reading:
        th = threading.Thread(target=reader, args=(ep, stop, count))
        th.start()
    t0 = time.perf_counter()
    p = subprocess.run([cosim, "run", path], capture_output=True, text=True, timeout=600)
    took = time.perf_counter() - t0
    shutil.rmtree(d, ignore_errors=True)  # a snapshot every step: GBs per run
    shutil.rmtree(os.path.dirname(s["output"]["dir"]), ignore_errors=True)
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
    ap.add_argument("--out", default="bench/results/reliability.md")
    a = ap.parse_args()
    cosim = os.path.abspath(os.path.join(a.bin, "cosim"))
    kinds = [("none", 0, False, False), ("1 stalled", 1, False, False),
             ("20 stalled", 20, False, False), ("50 stalled", 50, False, False),
             ("20 stalled, snapshot stream too", 20, False, True),
             ("1 reading both streams", 0, True, False)]
    best = {k[0]: float("inf") for k in kinds}
    load0 = os.getloadavg()[0]
    for r in range(a.rounds):
        for name, lazy, reading, snaps in kinds:
            best[name] = min(best[name], one_run(cosim, a.nodes, a.end, lazy, reading, snaps))
            print(f"round {r + 1}: {name}: {best[name]:.2f} s (best so far)", flush=True)
    load = os.getloadavg()[0]
    steps = int(round(a.end / 1e-3))
    lines = [
        f"Stub tyre scene, {a.nodes} x {a.nodes} surface nodes, a snapshot of every "
        f"participant at each of {steps} steps (the worst case for the bus: "
        f"{a.nodes * a.nodes * 3 * 8 / 1e6:.2f} MB per snapshot array), bus.hwm 1000, "
        f"bus.snapshot_hwm 2. A stalled monitor subscribes to every topic of the monitor "
        f"stream and never reads, with ZeroMQ's default receive queue (1000 messages); "
        f"the reading one drains both streams. Minimum of {a.rounds} alternated rounds, "
        f"whole `cosim run` process; ratio against the run without monitors of the same "
        f"rounds. Load average {load0:.1f} at the start, {load:.1f} at the end. "
        f"`flock /tmp/cosim-bench.lock /usr/bin/python3 bench/proto/bench_monitor.py` "
        f"regenerates this section.",
        "",
        "| monitors | wall (s) | ratio |",
        "|---|---|---|",
    ]
    for name, _, _, _ in kinds:
        lines.append(f"| {name} | {best[name]:.2f} | {best[name] / best['none']:.2f} |")
    lines += ["",
              "Snapshots travel only on the snapshot stream, so a monitor that subscribes "
              "to everything on the monitor stream costs the run the copy of small messages "
              "only; one that also subscribes to snapshots and does not read makes the run "
              "send it snapshots until its own receive queue is full (ZeroMQ cannot tell a "
              "subscriber's I/O thread from its reader), which is what the snapshot-stream "
              "row costs.", ""]
    write_section(a.out, "Monitors", "\n".join(lines))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
