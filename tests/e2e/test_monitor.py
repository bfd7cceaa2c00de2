"""The monitor bus: a SUB attached during a run receives the expected topics,
with arrays equal to what results.h5 holds (snapshots on their own stream);
a monitor that never reads does not block the run (it finishes, complete);
one that subscribes to everything on the monitor stream gets no snapshots. What such a monitor costs in wall
time is measured by bench/proto/bench_monitor.py, not asserted here: the
machine is shared and a timing ratio fails at random."""
import json
import os
import subprocess
import threading
import time

import numpy as np
import zmq

from common import COSIM, check, done, h5, no_orphans, scene, scratch, write


def tyre_scene(name, n, end, every):
    s = scene(name, {
        "fem": {"exec": "fem_stub", "surface": {"plane": {"size": [0.2, 0.16], "n": [n, n], "z": -0.27}}},
        "dem": {"exec": "dem_stub", "force_per_node": [-0.1, 0.0, 1.0], "ramp_time": 0.1}},
        scenario={"kind": "tire_travel", "rim_center": [0, 0, 0.3], "sinkage_velocity": 0.1,
                  "sinkage_force": 20, "slip": 0.05, "omega": 1.8, "radius": 0.272})
    s["time"] = {"dt": 1e-3, "end": end}
    s["output"]["every"] = every
    ep = "ipc://" + os.path.join(scratch("cosim-bus-"), "monitor")
    s["bus"] = {"monitor": ep, "hwm": 100000, "snapshot_hwm": 1000}
    return s, ep


def collect(ep, stop, got, snapshots=True):
    sub = zmq.Context.instance().socket(zmq.SUB)
    sub.setsockopt(zmq.RCVHWM, 0)
    sub.setsockopt(zmq.SUBSCRIBE, b"")
    sub.connect(ep)
    if snapshots:
        sub.connect(ep + "-snapshots")  # the snapshot stream (bus.snapshots' default)
    # after the run (stop set) drain what is queued: a reader descheduled on a
    # loaded machine may be hundreds of messages behind when the run ends
    while True:
        stopping = stop.is_set()
        if not sub.poll(1000 if stopping else 100):
            if stopping:
                break
            continue
        frames = sub.recv_multipart()
        hdr = json.loads(frames[1])
        arrays = {a["name"]: np.frombuffer(fr, dtype="<" + a["dtype"]).reshape(a["shape"])
                  for a, fr in zip(hdr["arrays"], frames[2:])}
        got.append((frames[0].decode(), hdr, arrays))
    sub.close()


def run_with_lazy_monitor(s, ep):
    """A monitor that subscribes to everything and never reads."""
    lazy = zmq.Context.instance().socket(zmq.SUB)
    lazy.setsockopt(zmq.RCVHWM, 10)
    lazy.setsockopt(zmq.SUBSCRIBE, b"")
    lazy.connect(ep)
    p = subprocess.run([COSIM, "run", write(s)], capture_output=True, text=True, timeout=300)
    lazy.close(linger=0)
    return p


# 1. an attached monitor sees the series and snapshots of the HDF5 file (a
# queue deep enough for the whole run: with the default hwm a reader slower
# than the run loses messages, by design)
s, ep = tyre_scene("monitor", 4, 5.0, 100)
got, stop, main_only = [], threading.Event(), []
th = threading.Thread(target=collect, args=(ep, stop, got))
th2 = threading.Thread(target=collect, args=(ep, stop, main_only, False))
th.start()
th2.start()
time.sleep(0.3)
p = subprocess.run([COSIM, "run", write(s)], capture_output=True, text=True, timeout=120)
time.sleep(0.3)
stop.set()
th.join()
th2.join()
main_topics = {t for t, _, _ in main_only}
check("dem.series" in main_topics and not any(t.endswith(".snapshot") for t in main_topics),
      f"the monitor stream alone carries the series and no snapshot ({sorted(main_topics)})")
check(p.returncode == 0, f"run ok ({p.stderr[-300:]})")
no_orphans(s, "monitor run")
topics = {t for t, _, _ in got}
for want in ("dem.series", "fem.series", "dem.snapshot", "coupler.progress"):
    check(want in topics, f"bus carries {want} (got {sorted(topics)})")
f = h5(s)
dem = f["/dem/series"][:]
series = [(h["step"], a["series"]) for t, h, a in got if t == "dem.series"]
# A subscriber that joins while the run is going misses what was published
# before its subscription reached the proxy (ZeroMQ's late joiner); from then
# on it must miss nothing (the queue is deep enough here).
steps = [st for st, _ in series]
check(len(steps) > 0 and steps == list(range(steps[0], len(dem) + 1)),
      f"monitor got every dem.series message from its first one (step "
      f"{steps[0] if steps else None}) to the last ({len(steps)} messages)")
check(len(steps) >= 0.25 * len(dem), f"monitor joined early enough ({len(steps)} of {len(dem)})")
mismatch = sum(not np.array_equal(row, dem[step - 1]) for step, row in series)
check(mismatch == 0, f"every dem.series row equals results.h5 ({mismatch} differ)")
snaps = [(h["step"], a) for t, h, a in got if t == "dem.snapshot"]
# the snapshot stream is another connection: it joins on its own (late joiner)
first = snaps[0][0] if snaps else len(dem) + 1
want = [k for k in range(100, len(dem) + 1, 100) if k >= first]
check([st for st, _ in snaps] == want and len(want) >= 0.25 * len(dem) / 100,
      f"every snapshot from the first one on: {[st for st, _ in snaps]}")
bad = sum(not np.array_equal(a["snap.x"], f[f"/dem/steps/{step}/x"][:]) for step, a in snaps)
check(bad == 0, f"every snapshot equals results.h5 ({bad} differ)")

# 2. a monitor that never reads does not block the run: it finishes, and
# every row and snapshot is in results.h5 (big snapshots, every step)
s2, ep2 = tyre_scene("lazymon", 150, 0.3, 1)
p = run_with_lazy_monitor(s2, ep2)
check(p.returncode == 0, f"run with a non-reading monitor ok ({p.stderr[-300:]})")
no_orphans(s2, "lazy monitor run")
f = h5(s2)
n = len(f["/dem/series"])
check(n == 300, f"all 300 rows written with a non-reading monitor ({n})")
check(len(f["/dem/steps"]) == 300, f"all 300 snapshots written ({len(f['/dem/steps'])})")
done()
