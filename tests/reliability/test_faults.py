"""Faults a run survives or names (PROTOCOL.md "Liveness"):
- SIGKILL of each participant at a random step (3 seeds): the coupler names
  it (exit 3), leaves no process behind, and results.h5 opens with every
  row up to the kill, the same number in every dataset;
- SIGSTOP of the coupler for longer than step_timeout and heartbeat_timeout,
  then SIGCONT (Ctrl-Z, fg): the run finishes, complete;
- SIGSTOP of a participant: named within heartbeat_timeout (exit 3), long
  before step_timeout.
(A long init: test_settle_liveness.py.)"""
import os
import random
import signal
import subprocess
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "e2e"))
from common import BIN, COSIM, check, done, h5, no_orphans, pid_of, scene, write  # noqa: E402



def tyre_scene(name, end):
    s = scene(name, {
        "fem": {"exec": "fem_stub", "surface": {"plane": {"size": [0.2, 0.16], "n": [6, 6], "z": -0.27}}},
        "dem": {"exec": "dem_stub", "force_per_node": [-0.1, 0.0, 1.0], "ramp_time": 0.1}},
        scenario={"kind": "tire_travel", "rim_center": [0, 0, 0.3], "sinkage_velocity": 0.1,
                  "sinkage_force": 20, "slip": 0.05, "omega": 1.8, "radius": 0.272})
    s["time"] = {"dt": 1e-3, "end": end}
    s["output"]["every"] = 50
    # a participant's start under a sanitizer on a loaded machine can take
    # seconds: the faults here are later ones
    s.setdefault("coupling", {})["hello_timeout"] = 60
    return s


def start(s, *args):
    return subprocess.Popen([COSIM, "run", write(s), "--quiet", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def wait_handshaken(s, p, limit=60):
    """Until every participant has passed its handshake (results.h5 is
    opened then: coupler/run.c): a participant stopped before its hello
    would be named by hello_timeout, not by its silence."""
    path = os.path.join(s["output"]["dir"], "results.h5")
    t0 = time.time()
    while not os.path.exists(path) and p.poll() is None and time.time() - t0 < limit:
        time.sleep(0.05)
    check(os.path.exists(path), f"{s['name']}: the run passed its handshake within {limit} s")


def rows_consistent(s, what):
    f = h5(s)
    names = ["/dem/series", "/fem/series", "/coupler/series", "/coupler/traction"]
    n = [len(f[k]) for k in names]
    t = f["/dem/series"][:, 0]
    check(len(set(n)) == 1 and n[0] > 0, f"{what}: every dataset has the same rows {n}")
    check(np.allclose(t, 1e-3 * np.arange(1, len(t) + 1), rtol=0, atol=1e-12),
          f"{what}: rows are steps 1..{len(t)} in order")
    return n[0]


# --- SIGKILL of each participant at random steps
for seed in (1, 2, 3):
    rng = random.Random(seed)
    for victim in ("fem", "dem"):
        s = tyre_scene(f"kill{seed}{victim}", 1000.0)
        p = start(s)
        pid = pid_of(s["name"], victim, tries=200)
        wait_handshaken(s, p)
        time.sleep(rng.uniform(0.2, 0.8))  # a random step (the run does ~10^4 steps/s)
        os.kill(pid, signal.SIGKILL)
        out, err = p.communicate(timeout=60)
        what = f"seed {seed}, SIGKILL {victim}"
        check(p.returncode == 3 and f"participant '{victim}'" in err and "signal 9" in err
              and f"failed participant: {victim}" in err,
              f"{what}: named, exit 3 ({p.returncode}: {err[-300:]})")
        no_orphans(s, what)
        n = rows_consistent(s, what)
        print(f"{what}: killed after {n} steps", flush=True)

# --- the coupler stopped (Ctrl-Z) longer than its deadlines, then continued
s = tyre_scene("pause", 15.0)
s["coupling"] = {"step_timeout": 1, "heartbeat_timeout": 2, "hello_timeout": 60}
p = start(s)
pid_of(s["name"], "dem", tries=200)
time.sleep(0.5)
p.send_signal(signal.SIGSTOP)
time.sleep(3)
p.send_signal(signal.SIGCONT)
out, err = p.communicate(timeout=120)
check(p.returncode == 0 and "finished" in out,
      f"SIGSTOP/SIGCONT of the coupler for 3 s (step_timeout 1 s): the run finishes "
      f"({p.returncode}: {err[-300:]})")
check(rows_consistent(s, "pause") == 15000, "all 15000 rows")
no_orphans(s, "pause")

# --- a participant stopped: named by its silence
s = tyre_scene("stopped", 1000.0)
s["coupling"] = {"step_timeout": 60, "heartbeat_timeout": 2, "hello_timeout": 60}
p = start(s)
pid = pid_of(s["name"], "dem", tries=200)
wait_handshaken(s, p)
time.sleep(0.5)
os.kill(pid, signal.SIGSTOP)
t0 = time.time()
out, err = p.communicate(timeout=60)
took = time.time() - t0
check(p.returncode == 3 and "participant 'dem'" in err and "silent" in err and
      "heartbeat_timeout" in err, f"a stopped participant is named by its silence "
      f"({p.returncode}: {err[-300:]})")
check(took < 10, f"within seconds ({took:.1f} s; heartbeat_timeout 2 s, step_timeout 60 s)")
no_orphans(s, "stopped participant")

done()
