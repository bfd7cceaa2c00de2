#!/usr/bin/env python3
"""Reliability benchmark (issue 11): writes its sections of
bench/results/reliability.md, keeping the others (Monitors: bench/proto/
bench_monitor.py; Fuzzing: bench/reliability/run_fuzz.py).

    flock /tmp/cosim-bench.lock /usr/bin/python3 bench/reliability/run_bench.py \
        [--bin build/bin] [--parts faults,cost,soak] [--rounds 3]

faults  each fault injected several times; survived = handled as specified
        (exit code, the culprit named, no process left, results.h5 readable);
        rows lost = rows the bus had published before the fault (so they had
        been computed and recorded) that are missing from results.h5.
cost    the run time of checkpoints (the default scene, real DEM + FEM) and
        of CURVE (lock-step with stubs; big arrays: bench_curve.py), min of
        alternated rounds, as ratios against the same scene without.
soak    10^6 lock-step exchanges with a stub: resident memory and open file
        descriptors of the coupler and the participant along the run.
"""
import argparse
import hashlib
import json
import os
import random
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time

import h5py
import zmq

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, HERE)
from mdsection import write_section  # noqa: E402

OUT = os.path.join(ROOT, "bench", "results", "reliability.md")
ROGUE = os.path.join(ROOT, "tests", "e2e", "rogue.py")
COSIM = BIN = None


# ------------------------------------------------------------ scenes, runs

def scene(name, processes, end, dt=1e-3, every=50, **kw):
    s = {"name": f"{name}_{os.getpid()}_{random.randrange(10**6)}",
         "time": {"dt": dt, "end": end},
         "output": {"dir": os.path.join(tempfile.mkdtemp(prefix="cosim-bench-rel-"), "run"),
                    "every": every},
         "processes": processes}
    s.update(kw)
    return s


def tyre(name, end, n=6, **kw):
    return scene(name, {
        "fem": {"exec": "fem_stub", "surface": {"plane": {"size": [0.2, 0.16], "n": [n, n], "z": -0.27}}},
        "dem": {"exec": "dem_stub", "force_per_node": [-0.1, 0.0, 1.0], "ramp_time": 0.1}}, end,
        scenario={"kind": "tire_travel", "rim_center": [0, 0, 0.3], "sinkage_velocity": 0.1,
                  "sinkage_force": 20, "slip": 0.05, "omega": 1.8, "radius": 0.272}, **kw)


def block(name, end, **kw):
    return scene(name, {"block": {"exec": "block_stub", "stiffness": 3e5}}, end,
                 scenario={"kind": "indentation", "profile": "linear", "depth": 1e-4,
                           "ramp_time": 1}, **kw)


def write(s):
    d = tempfile.mkdtemp(prefix="cosim-bench-cfg-")
    path = os.path.join(d, "scene.json")
    json.dump(s, open(path, "w"))
    return path


def start(s, *args, env=None):
    return subprocess.Popen([COSIM, "run", write(s), "--quiet", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True,
                            env=dict(os.environ, **(env or {})))


def processes_with(marker):
    found = []
    for pid in os.listdir("/proc"):
        if not pid.isdigit() or int(pid) == os.getpid():
            continue
        try:
            cmd = open(f"/proc/{pid}/cmdline", "rb").read().replace(b"\0", b" ").decode(errors="replace")
            state = open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()[0]
        except OSError:
            continue
        if marker in cmd and state != "Z":
            found.append((int(pid), cmd))
    return found


def pid_of(marker, name):
    for _ in range(500):
        for pid, cmd in processes_with(marker):
            if f"--name {name}" in cmd and "cosim run" not in cmd:
                return pid
        time.sleep(0.02)
    return None


def no_orphans(marker):
    for _ in range(100):
        if not processes_with(marker):
            return True
        time.sleep(0.05)
    return False


def rows(s, ds="/coupler/series"):
    try:
        with h5py.File(os.path.join(s["output"]["dir"], "results.h5"), "r") as f:
            return len(f[ds])
    except (OSError, KeyError):
        return -1


class Tail:
    """The last step of `topic` seen on the run's monitor stream (what had
    been recorded: the coupler publishes a row after writing it)."""

    def __init__(self, ep, topic=b"coupler.series"):
        self.last, self.stop = 0, threading.Event()
        self.th = threading.Thread(target=self.run, args=(ep, topic))
        self.th.start()

    def run(self, ep, topic):
        sub = zmq.Context.instance().socket(zmq.SUB)
        sub.setsockopt(zmq.LINGER, 0)
        sub.setsockopt(zmq.SUBSCRIBE, topic)
        sub.connect(ep)
        while not self.stop.is_set():
            if sub.poll(20):
                self.last = max(self.last, json.loads(sub.recv_multipart()[1])["step"])
        sub.close()

    def freeze(self):
        """The last step seen by now (the fault is about to be injected)."""
        time.sleep(0.05)
        return self.last

    def close(self):
        self.stop.set()
        self.th.join()


def with_bus(s):
    s["bus"] = {"monitor": "ipc://" + os.path.join(tempfile.mkdtemp(prefix="cosim-bench-bus-"), "m")}
    return s


# ------------------------------------------------------------------ faults

def fault_kill(victim, seed, real=False):
    rng = random.Random(seed)
    if real:
        s = json.load(open(os.path.join(ROOT, "configs", "default.json")))
        s["name"] = f"killreal_{os.getpid()}_{seed}"
        s["time"]["end"] = 2.0
        s["output"] = {"dir": os.path.join(tempfile.mkdtemp(prefix="cosim-bench-rel-"), "run"),
                       "every": 20}
    else:
        s = tyre(f"kill_{victim}", 1000.0)
    with_bus(s)
    tail = Tail(s["bus"]["monitor"])
    p = start(s)
    pid = pid_of(s["name"], victim)
    while real and tail.last == 0 and p.poll() is None:  # past the DEM's settling
        time.sleep(0.05)
    time.sleep(rng.uniform(0.2, 1.0))
    seen = tail.freeze()
    os.kill(pid, signal.SIGKILL)
    out, err = p.communicate(timeout=120)
    tail.close()
    n = rows(s)
    ok = (p.returncode == 3 and f"failed participant: {victim}" in err and no_orphans(s["name"])
          and n >= 0)
    return ok, max(0, seen - n), f"killed near step {seen}"


def fault_stop_participant(seed):
    s = with_bus(tyre("stopped", 1000.0, coupling={"heartbeat_timeout": 2}))
    tail = Tail(s["bus"]["monitor"])
    p = start(s)
    pid = pid_of(s["name"], "dem")
    time.sleep(random.Random(seed).uniform(0.2, 1.0))
    seen = tail.freeze()
    os.kill(pid, signal.SIGSTOP)
    t0 = time.time()
    out, err = p.communicate(timeout=120)
    took = time.time() - t0
    tail.close()
    n = rows(s)
    ok = p.returncode == 3 and "silent" in err and no_orphans(s["name"]) and n >= 0
    return ok, max(0, seen - n), f"run ended {took:.1f} s after the stop"


def fault_pause_coupler(seed):
    s = tyre("pause", 15.0, coupling={"step_timeout": 1, "heartbeat_timeout": 2})
    p = start(s)
    pid_of(s["name"], "dem")
    time.sleep(random.Random(seed).uniform(0.2, 0.8))
    p.send_signal(signal.SIGSTOP)
    time.sleep(3 + seed)
    p.send_signal(signal.SIGCONT)
    out, err = p.communicate(timeout=120)
    n = rows(s)
    return p.returncode == 0 and n == 15000, max(0, 15000 - n), f"paused {3 + seed} s"


def fault_full_disk(seed):
    mnt = tempfile.mkdtemp(prefix="cosim-bench-full-")
    size = f"{4 + 2 * seed}m"  # seed 1, 2, 3
    if subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", mnt]).returncode:
        return None, 0, "mount not permitted"
    try:
        s = with_bus(tyre("fulldisk", 100.0, n=30, every=10))
        s["output"]["dir"] = os.path.join(mnt, "run")
        tail = Tail(s["bus"]["monitor"])
        p = start(s)
        out, err = p.communicate(timeout=300)
        tail.close()
        n = rows(s, "/dem/series")
        ok = p.returncode == 4 and "errno 28" in err and n > 0
        # what the bus saw was recorded (the coupler publishes after writing)
        return ok, max(0, tail.last - n), f"{size} tmpfs full after {n} steps"
    finally:
        subprocess.run(["umount", mnt])
        shutil.rmtree(mnt, ignore_errors=True)


def digest(s):
    return hashlib.sha256(open(os.path.join(s["output"]["dir"], "results.h5"), "rb").read()).hexdigest()


def fault_concurrent(seed):
    s = block("concurrent", 40.0 + seed)
    p = start(s)
    while not os.path.exists(os.path.join(s["output"]["dir"], "endpoints.json")):
        time.sleep(0.02)
    q = subprocess.run([COSIM, "run", write(s), "--quiet", "--overwrite"], capture_output=True,
                       text=True, timeout=60)
    p.communicate(timeout=300)
    n, want = rows(s), int(round((40.0 + seed) / 1e-3))
    ok = q.returncode == 1 and f"pid {p.pid}" in q.stderr and p.returncode == 0 and n == want
    return ok, max(0, want - n), "second run refused"


def fault_failing_rerun(seed):
    s = block("rerun", 1.0 + seed)
    subprocess.run([COSIM, "run", write(s), "--quiet"], capture_output=True, timeout=60)
    before, n0 = digest(s), rows(s)
    bad = json.loads(json.dumps(s))
    bad["processes"]["block"]["exec"] = ROGUE
    q = subprocess.run([COSIM, "run", write(bad), "--quiet", "--overwrite"], capture_output=True,
                       text=True, timeout=60, env=dict(os.environ, ROGUE_MODE="crash"))
    ok = q.returncode == 3 and digest(s) == before
    return ok, max(0, n0 - rows(s)), "--overwrite, a participant crashes at start"


def attach(s):
    s["coupling"] = {"attach_endpoint": "tcp://127.0.0.1:0", "hello_timeout": 30}
    p = subprocess.Popen([COSIM, "run", write(s), "--attach", "--quiet"], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True)
    line = ""
    while "--endpoint" not in line and p.poll() is None:
        line = p.stderr.readline()
    return p, line.split()


def fault_impostor(seed):
    s = block("impostor", 2.0, security={"curve": True})
    p, words = attach(s)
    ep = words[words.index("--endpoint") + 1]
    keyfile = next(w for w in words if w.startswith("COSIM_CURVE_FILE=")).split("=", 1)[1]
    d = zmq.Context.instance().socket(zmq.DEALER)
    d.setsockopt(zmq.LINGER, 0)
    d.setsockopt(zmq.IDENTITY, b"block")
    if seed % 2:
        d.curve_serverkey = json.load(open(keyfile))["server_public"].encode()
        d.curve_publickey, d.curve_secretkey = zmq.curve_keypair()
    d.connect(ep)
    d.send_multipart([b"block", json.dumps({"v": 1, "type": "hello", "role": "block",
                                            "name": "block"}).encode()])
    answered = d.poll(1500)
    d.close()
    real = subprocess.Popen([os.path.join(BIN, "block_stub"), "--endpoint", ep, "--name", "block"],
                            env=dict(os.environ, COSIM_CURVE_FILE=keyfile),
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    p.communicate(timeout=120)
    real.wait(timeout=30)
    n = rows(s)
    ok = not answered and p.returncode == 0 and n == 2000
    return ok, max(0, 2000 - n), "impostor " + ("with its own keys" if seed % 2 else "without keys")


def fault_stranger(seed):
    s = block("stranger", 2.0)
    p, words = attach(s)
    ep = words[words.index("--endpoint") + 1]
    d = zmq.Context.instance().socket(zmq.DEALER)
    d.setsockopt(zmq.LINGER, 0)
    d.setsockopt(zmq.IDENTITY, f"stranger{seed}".encode())
    d.connect(ep)
    d.send_multipart([b"x", b"garbage"])
    time.sleep(0.3)
    d.close()
    real = subprocess.Popen([os.path.join(BIN, "block_stub"), "--endpoint", ep, "--name", "block"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    out, err = p.communicate(timeout=120)
    real.wait(timeout=30)
    n = rows(s)
    return p.returncode == 0 and n == 2000 and "ignoring" in err, max(0, 2000 - n), "logged, ignored"


def fault_crash_restart(seed):
    """A participant killed after a checkpoint; --restart latest; the
    results must equal a straight run's."""
    procs = {"left": {"exec": "block_stub", "stiffness": 1e5, "gap": -1e-5},
             "right": {"exec": "block_stub", "stiffness": 3e5, "gap": -1e-5}}
    force = {"kind": "indentation", "profile": "force", "road_mass": 0.05, "road_force": 50}
    a = scene("straight", procs, 8000 * 1.953125e-5, dt=1.953125e-5, every=100, scenario=force,
              coupling={"scheme": "implicit"}, checkpoint={"every": 1000})
    subprocess.run([COSIM, "run", write(a), "--quiet"], capture_output=True, timeout=300)
    b = json.loads(json.dumps(a))
    b["name"] += "b"
    b["output"]["dir"] = os.path.join(tempfile.mkdtemp(prefix="cosim-bench-rel-"), "run")
    p = start(b)
    ck = os.path.join(b["output"]["dir"], f"checkpoint_{1000 * (1 + seed)}.h5")
    while not os.path.exists(ck) and p.poll() is None:
        time.sleep(0.01)
    os.kill(pid_of(b["name"], "right"), signal.SIGKILL)
    p.communicate(timeout=120)
    q = subprocess.run([COSIM, "run", write(b), "--quiet", "--restart", "latest"],
                       capture_output=True, text=True, timeout=300)
    fa = h5py.File(os.path.join(a["output"]["dir"], "results.h5"), "r")
    fb = h5py.File(os.path.join(b["output"]["dir"], "results.h5"), "r")
    same = all(fa[k][()].tobytes() == fb[k][()].tobytes() for k in ("/left/series", "/right/series"))
    ok = p.returncode == 3 and q.returncode == 0 and same
    return ok, max(0, len(fa["/left/series"]) - len(fb["/left/series"])), "resumed bit for bit"


FAULTS = [
    ("SIGKILL of fem_stub at a random step", lambda i: fault_kill("fem", i), 5),
    ("SIGKILL of dem_stub at a random step", lambda i: fault_kill("dem", i), 5),
    ("SIGKILL of fem_server (default scene)", lambda i: fault_kill("fem", i, True), 2),
    ("SIGKILL of dem_server (default scene)", lambda i: fault_kill("dem", i, True), 2),
    ("SIGSTOP of a participant (heartbeat_timeout 2 s)", fault_stop_participant, 3),
    ("SIGSTOP/SIGCONT of the coupler, 4-6 s (step_timeout 1 s)", fault_pause_coupler, 3),
    ("full disk (tmpfs of 6, 8, 10 MB)", fault_full_disk, 3),
    ("a second run into the same output.dir", fault_concurrent, 3),
    ("a failing rerun with --overwrite", fault_failing_rerun, 3),
    ("CURVE: an impostor in --attach mode", fault_impostor, 4),
    ("no CURVE: a stranger in --attach mode", fault_stranger, 3),
    ("a crash, then --restart latest", fault_crash_restart, 3),
]


def faults(args):
    lines = ["Each fault injected the number of times given; survived = handled as specified "
             "(the exit code, the culprit named, no process left behind, results.h5 readable, "
             "and what the row says); rows lost = rows the monitor bus had published before "
             "the fault (the coupler publishes a row after writing it) missing from "
             "results.h5 afterwards. `tests/reliability/` asserts the same, once each.", "",
             "| fault | injected | survived | rows lost | note (last) |", "|---|---|---|---|---|"]
    for name, fn, times in FAULTS:
        done = ok = lost = 0
        note = ""
        for i in range(times):
            good, l, note = fn(i + 1)
            if good is None:
                break
            done += 1
            ok += bool(good)
            lost += l
            print(f"{name} #{i + 1}: {'ok' if good else 'FAILED'}, {l} rows lost, {note}", flush=True)
        lines.append(f"| {name} | {done} | {ok} | {lost} | {note} |")
    write_section(OUT, "Faults", "\n".join(lines))


# -------------------------------------------------------------------- cost

LOOP = re.compile(r"Loop time ([0-9.]+) s for (\d+) steps")


def loop_time(s, *args):
    p = subprocess.run([COSIM, "run", write(s), *args], capture_output=True, text=True, timeout=900)
    m = LOOP.search(p.stdout)
    if p.returncode != 0 or not m:
        raise SystemExit(f"run failed: {p.stderr[-500:]}")
    return float(m.group(1)) / int(m.group(2))


def alternate(cases, rounds):
    best = {k: float("inf") for k in cases}
    for r in range(rounds):
        for k, make in cases.items():
            best[k] = min(best[k], loop_time(make()))
            print(f"round {r + 1}: {k}: {1e3 * best[k]:.4f} ms/step (best)", flush=True)
    return best


def default_scene(every):
    s = json.load(open(os.path.join(ROOT, "configs", "default.json")))
    s["name"] = f"ckpt_{os.getpid()}"
    s["time"]["end"] = 600 * 5e-5
    s["output"] = {"dir": os.path.join(tempfile.mkdtemp(prefix="cosim-bench-rel-"), "run"), "every": 100}
    s.pop("bus", None)
    if every:
        s["checkpoint"] = {"every": every, "keep": 2}
    return s


def cost(args):
    ck = alternate({"none": lambda: default_scene(0), "every 100 steps": lambda: default_scene(100),
                    "every 20 steps": lambda: default_scene(20)}, args.rounds)
    s = default_scene(100)
    subprocess.run([COSIM, "run", write(s), "--quiet"], capture_output=True, timeout=900)
    size = max(os.path.getsize(os.path.join(s["output"]["dir"], f)) for f in os.listdir(s["output"]["dir"])
               if f.startswith("checkpoint_"))
    per = (ck["every 20 steps"] - ck["none"]) * 20
    cu = alternate({
        "lock-step, no CURVE": lambda: block("curve0", 20.0),
        "lock-step, CURVE": lambda: block("curve1", 20.0, security={"curve": True}),
    }, args.rounds)
    load = os.getloadavg()[0]
    lines = [f"Min of {args.rounds} alternated runs, the coupler's loop time per step (the "
             f"participants' start and the DEM's settling left out), load average {load:.1f} at "
             f"the end.", "",
             "| run | ms per step | ratio |", "|---|---|---|"]
    for k in ck:
        lines.append(f"| default scene (DEM + FEM), checkpoints {k} | {1e3 * ck[k]:.3f} | "
                     f"{ck[k] / ck['none']:.2f} |")
    lines.append("")
    lines.append(f"One checkpoint of the default scene (2181 grains, 608-node tread): "
                 f"{size / 1e6:.1f} MB, {1e3 * per:.0f} ms (from the every-20 rows).")
    lines += ["", "| run | ms per step | ratio |", "|---|---|---|"]
    for a, b in (("lock-step, no CURVE", "lock-step, CURVE"),):
        for k in (a, b):
            lines.append(f"| {k} | {1e3 * cu[k]:.4f} | {cu[k] / cu[a]:.2f} |")
    lines += ["", "Lock-step: block_stub, 20 000 steps (tiny messages: the cost is latency). "
              "CURVE is on every socket, ipc included, when security.curve is set. Big "
              "messages under CURVE, against the cipher's own speed: the section \"CURVE and "
              "the cipher\" (bench/reliability/bench_curve.py)."]
    write_section(OUT, "Cost of checkpoints and CURVE", "\n".join(lines))


# -------------------------------------------------------------------- soak

def status(pid):
    rss = 0
    for line in open(f"/proc/{pid}/status"):
        if line.startswith("VmRSS:"):
            rss = int(line.split()[1])
    return rss, len(os.listdir(f"/proc/{pid}/fd"))


def soak(args):
    steps = args.soak_steps
    s = block("soak", steps * 1e-3, every=100000)
    p = start(s)
    part = pid_of(s["name"], "block")
    samples, t0 = [], time.time()
    while p.poll() is None:
        try:
            samples.append((time.time() - t0, status(p.pid), status(part)))
        except OSError:
            break
        time.sleep(args.soak_every)
    out, err = p.communicate()
    n = rows(s)
    if p.returncode != 0 or n != steps:
        raise SystemExit(f"soak run failed ({p.returncode}, {n} rows): {err[-500:]}")
    took = samples[-1][0] if samples else 0
    pick = [samples[int(i * (len(samples) - 1) / 9)] for i in range(10)] if len(samples) >= 10 else samples
    lines = [f"block_stub, {steps:,} lock-step exchanges ({took:.0f} s, "
             f"{1e6 * took / steps:.0f} us per step); resident memory (kB) and open file "
             f"descriptors of the coupler and the participant, sampled along the run.", "",
             "| t (s) | coupler RSS | coupler fds | block_stub RSS | block_stub fds |",
             "|---|---|---|---|---|"]
    for t, c, b in pick:
        lines.append(f"| {t:.0f} | {c[0]} | {c[1]} | {b[0]} | {b[1]} |")
    first, last = samples[len(samples) // 10], samples[-1]
    lines += ["", f"From 10 % of the run to its end: coupler RSS {first[1][0]} -> {last[1][0]} kB, "
              f"fds {first[1][1]} -> {last[1][1]}; block_stub RSS {first[2][0]} -> {last[2][0]} kB, "
              f"fds {first[2][1]} -> {last[2][1]}."]
    write_section(OUT, "Soak: 10^6 lock-step exchanges", "\n".join(lines))


def main():
    global COSIM, BIN
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", default="build/bin")
    ap.add_argument("--parts", default="faults,cost,soak")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--soak-steps", type=int, default=1000000)
    ap.add_argument("--soak-every", type=float, default=2.0)
    args = ap.parse_args()
    BIN = os.path.abspath(args.bin)
    COSIM = os.path.join(BIN, "cosim")
    print(f"load average at start: {os.getloadavg()[0]:.1f}", flush=True)
    for part in args.parts.split(","):
        {"faults": faults, "cost": cost, "soak": soak}[part](args)


if __name__ == "__main__":
    main()
