"""Watching and reading runs from Python:

1. cosim.Monitor attached to a running scene through its output dir (the bus
   endpoint found in endpoints.json) receives every row of every
   series topic from its first message on, bit for bit equal to what
   results.h5 holds, and ends by itself when the run ends; tools/monitor.py
   (on the package) plots a named column of the same run headless.
2. cosim.Results reads every dataset of a default run (configs/default.json,
   shortened with --set: 20 steps, a short settle): each one through the API (series as named columns,
   snapshots by step, meshes), the scene, the timing table.
3. cosim.run turns exit codes into exceptions naming the failure.
"""
import os
import subprocess
import sys
import threading
import time

import numpy as np
import zmq

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.join(HERE, "..", "..")
sys.path.insert(0, os.path.join(HERE, "..", "e2e"))
from common import check, done, no_orphans, scene, scratch  # noqa: E402

import cosim  # noqa: E402

# 1. a monitor attached to a running scene
N_STEPS = 6000  # about 1 s unloaded: tools/monitor.py, connecting as the bus binds, joins in time
s = scene("pymon", {
    "fem": {"exec": "fem_stub", "surface": {"plane": {"size": [0.2, 0.16], "n": [4, 4], "z": -0.27}}},
    "dem": {"exec": "dem_stub", "force_per_node": [-0.1, 0.0, 1.0], "ramp_time": 0.1}},
    scenario={"kind": "tire_travel", "rim_center": [0, 0, 0.3], "sinkage_velocity": 0.1,
              "sinkage_force": 20, "slip": 0.05, "omega": 1.8, "radius": 0.272},
    # tools/monitor.py listens on a bus endpoint known before the run starts (it
    # must not attach after a short run has ended); cosim.Monitor finds it in
    # the output dir's endpoints.json while the run goes
    bus={"monitor": "ipc://" + os.path.join(scratch("cosim-bus-"), "bus"),
         "hwm": 100000})
s["time"] = {"dt": 1e-3, "end": N_STEPS * 1e-3}
s["output"]["every"] = 1500
outdir = s["output"]["dir"]
png = os.path.join(scratch("cosim-mon-"), "traction.png")
tool = subprocess.Popen([sys.executable, os.path.join(ROOT, "tools", "monitor.py"),
                         s["bus"]["monitor"], "--topic", "coupler.traction", "--column", "T_R",
                         # given an endpoint the tool ends at the run's last coupler.progress,
                         # or, when it missed that one (a busy machine: the suite at -j2),
                         # PROGRESS_LOST_S after the last message it got: no --seconds
                         "--png", png], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
check("listening" in tool.stderr.readline(), "tools/monitor.py started")
ran = {}
runner = threading.Thread(target=lambda: ran.setdefault("r", cosim.run(s, timeout=120)))
runner.start()
SERIES = {"dem.series": "/dem/series", "fem.series": "/fem/series",
          "coupler.series": "/coupler/series", "coupler.traction": "/coupler/traction",
          "coupler.timing": "/coupler/timing"}
got = {t: [] for t in SERIES}
# the monitor queues every message of the run (5 topics x N_STEPS): a monitor that falls
# behind on a loaded machine loses none (with the default 10 000 it lost a third at -j2
# beside a benchmark; a monitor never slows the run, so the bus drops for a full queue)
with cosim.Monitor(outdir, topics=list(SERIES), timeout=60, hwm=2 * len(SERIES) * N_STEPS) as mon:
    for msg in mon:
        got[msg.topic].append(msg)
runner.join()
try:
    tool_out, tool_err = tool.communicate(timeout=30 + cosim.monitor.PROGRESS_LOST_S)
except subprocess.TimeoutExpired:
    tool.kill()  # not left behind when the suite moves on
    tool_out, tool_err = tool.communicate()
    check(False, f"tools/monitor.py ended by itself after the run: {tool_err[-300:]}")
r = ran.get("r")
check(r is not None, "the run finished")
no_orphans(s, "monitored run")
for topic, path in SERIES.items():
    msgs = got[topic]
    rows = r.file[path][()]
    steps = [m.step for m in msgs]
    check(len(msgs) > 0 and steps == list(range(steps[0], N_STEPS + 1)),
          f"{topic}: every message from the first (step {steps[0] if steps else None}) to the "
          f"last ({len(steps)} of {N_STEPS})")
    check(len(msgs) >= N_STEPS // 4, f"{topic}: the monitor joined early ({len(msgs)} messages)")
    same = sum(m["series"].tobytes() == rows[m.step - 1].tobytes() for m in msgs)
    check(same == len(msgs), f"{topic}: {same} of {len(msgs)} rows equal results.h5 bit for bit")
tr = got["coupler.traction"]
check(tr and tr[0].row and list(tr[0].row) == r.series("coupler", "traction").columns,
      "coupler.traction names its columns")
check(tool.returncode == 0 and os.path.getsize(png) > 1000 and "points" in tool_out,
      f"tools/monitor.py plotted T_R headless: {tool.returncode} {tool_out} {tool_err[-300:]}")
print(f"monitor: {len(got['dem.series'])} of {N_STEPS} dem.series rows from step "
      f"{got['dem.series'][0].step}; tools/monitor.py: {tool_out.strip()}")

# 2. every dataset of a default run, through Results
out = os.path.join(scratch("cosim-default-"), "default")
r = cosim.run(os.path.join(ROOT, "configs", "default.json"),
              set={"time.end": 1e-3, "output.every": 10,
                   "processes.dem.particles.settle_max_steps": 500},  # a short settle: seconds
              output_dir=out, timeout=240)
reached = {}
for p, ds in r.tables():
    t = r.series(p, ds)
    reached[f"/{p}/{ds}"] = t.array
    check(all(np.array_equal(t[c], t.array[:, i]) for i, c in enumerate(t.columns)),
          f"/{p}/{ds}: columns by name")
for p in r.processes:
    for k in r.steps(p):
        for name, a in r.snapshot(p, k).items():
            reached[f"/{p}/steps/{k}/{name}"] = a
    for name, a in r.mesh(p).items():
        reached[f"/{p}/mesh/{name}"] = a
every = r.datasets()
missed = sorted(set(every) - set(reached))
check(not missed and len(every) == len(reached), f"every dataset read through Results: missed {missed}")
bad = [p for p in every if p in reached and not np.array_equal(reached[p], r.file[p][()])]
check(not bad, f"Results gives what the file holds: {bad}")
check(r.series("coupler", "traction")["T_H"].shape == (20,), "traction by name, one row per step")
check(r.steps("dem") == [10, 20] and r.snapshot("dem", -1)["x"].shape[1] == 3, "snapshots by step")
check(r.scene["time"]["end"] == 1e-3 and r.scene["processes"]["dem"]["exec"] == "dem_server",
      "the scene as run")
check("fem.compute" in r.timing and len(r.timing) == 20, f"the timing table: {r.timing}")
print(f"results: {len(every)} datasets of a default run read: {', '.join(sorted(every)[:6])}, ...")

# 3. exit codes as exceptions
bad = scene("pybad", {"block": {"exec": "block_stub"}},
            scenario={"kind": "indentation", "profile": "linear", "depth": 1e-4, "ramp_time": 0.01})
try:
    cosim.run(bad, set={"time.dt": "fast"})
    check(False, "a bad scene raises")
except cosim.SceneError as e:
    check(e.returncode == 1 and "time.dt: expected a number" in str(e), f"SceneError: {e}")
try:
    cosim.run(bad, set={"processes.block.stiffness": -5})
    check(False, "a failing participant raises")
except cosim.ParticipantError as e:
    check(e.participant == "block" and "processes.block.stiffness: must be in [0," in str(e),
          f"ParticipantError names the participant and the key: {e}")
try:
    cosim.run(bad, set={"time.end": 1e6}, timeout=1.5)
    check(False, "a run past its timeout raises")
except cosim.Interrupted as e:
    check(e.returncode == 130 and "did not finish within 1.5 s" in str(e), f"Interrupted: {e}")
    with cosim.Results(e.output_dir) as kept:
        check(len(kept.series("block")) > 0, "an interrupted run keeps its rows")

# 4. given an endpoint, a monitor that missed the last coupler.progress ends
#    progress_lost s after the last message it got: (a) a bare publisher that
#    sends progress of a 100-step run up to step 50, then falls silent; (b) one
#    that sends only rows of a wanted topic (a monitor that joined a short run
#    after its last periodic progress: CI, stop 52, tools/monitor.py above
#    waited for ever)
ctx = zmq.Context()
pub = ctx.socket(zmq.PUB)
ep = "ipc://" + os.path.join(scratch("cosim-lost-"), "bus")
pub.bind(ep)
row = np.zeros(3)
for case, topic in (("progress up to step 50", "nothing.else"), ("rows, no progress", "dem.series")):
    mon = cosim.Monitor(ep, topics=[topic], progress_lost=1.0, timeout=10)  # 10: fails, not hangs
    time.sleep(0.3)  # the subscription reaches the publisher
    for k in range(1, 51):
        if topic == "nothing.else":
            pub.send_multipart(cosim.protocol.encode("coupler.progress", "progress", k, k * 1e-3,
                                                     fields={"n_steps": 100}))
        else:
            pub.send_multipart(cosim.protocol.encode("dem.series", "series", k, k * 1e-3,
                                                     arrays=[("series", row)]))
    t0 = time.monotonic()
    left = list(mon)
    waited = time.monotonic() - t0
    check(len(left) == (0 if topic == "nothing.else" else 50) and 1.0 <= waited < 5.0,
          f"{case}: a monitor that missed the end stopped {waited:.2f} s after the last "
          f"message (expected 1-5 s), {len(left)} rows")
pub.close(0)
ctx.term()
no_orphans(bad, "interrupted run")
pts = cosim.sweep(bad, {"processes.block.stiffness": [1e5, 2e5]},
                  out=scratch("cosim-sweep-"), jobs=2)
forces = [res.series("block")["force"][-1] for _, res in pts]
check([p["processes.block.stiffness"] for p, _ in pts] == [1e5, 2e5] and
      np.isclose(forces[1], 2 * forces[0], rtol=1e-12), f"sweep: one run per value ({forces})")
done()
