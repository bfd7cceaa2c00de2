"""Shared memory and sockets carry the same bits (proto/PROTOCOL.md "Shared
memory"): the same scene run with coupling.transport "auto" (participants on
this host: shm) and "socket" (frames) gives bitwise-identical results.h5 and
checkpoints, serial and implicit; the schedule printout names each process's
transport; the participants really map memfd segments; and a participant
killed with SIGKILL mid-run leaves no segment in /dev/shm nor the run
directory (/tmp/cosim-<name>-*) behind.

Usage: test_shm.py [stubs|scenes|kill ...] (default: all three)."""
import glob
import json
import os
import re
import signal
import subprocess
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "reliability"))
from common import COSIM, check, done, no_orphans, pid_of, scratch  # noqa: E402
from rel import differences  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
# 41 x 41 nodes: [n,3] arrays of 40 KB, above PROTO_SHM_MIN_BYTES (4096 B),
# so x, v and nodal_force travel in the segments (4 x 4 would stay frames)
FINE = ["--set", "processes.fem.surface.plane.n=[40,40]"]


def dev_shm():
    """/dev/shm's entries, less the scratch files of what may run beside this
    test: the benchmarks' run dirs (cosim-bench-*) and the fuzz replays'
    inputs (cosim-fuzz-<pid>.*, tests/fuzz; ctest -j runs them alongside)."""
    try:
        return {e for e in os.listdir("/dev/shm")
                if not e.startswith(("cosim-bench-", "cosim-fuzz-"))}
    except OSError:
        return set()


def run(config, transport, tag, extra=()):
    out = os.path.join(scratch("cosim-shm-"), tag)
    p = subprocess.run([COSIM, "run", os.path.join(ROOT, "configs", config),
                        "--set", f"coupling.transport={transport}", "--set",
                        f"output.dir={out}", *extra], capture_output=True, text=True,
                       timeout=600)
    check(p.returncode == 0, f"{tag}: exits 0 (got {p.returncode}: {p.stderr.strip()[-400:]})")
    return out, p.stdout + p.stderr


def schedule_says(text, tag, want):
    lines = [l for l in text.splitlines() if l.strip()[:2] in ("1.", "2.", "3.")
             and "(" in l and "coupler:" not in l]
    check(lines and all(f"[{want}]:" in l for l in lines),
          f"{tag}: the schedule says {want} for every process: {lines}")


def doorbell_says(text, tag):
    """The timing table's 'shm NAME: P of S messages to it posted in the
    segment': the doorbell carried (nearly) every message of the loop."""
    import re
    rows = re.findall(r"shm (\S+): (\d+) of (\d+) messages to it posted", text)
    check(rows and all(int(p) > 0 and int(p) >= 0.9 * int(s) for _, p, s in rows),
          f"{tag}: the doorbell carried the messages: {rows}")


def same(config, tag, extra=(), want_shm=True):
    a, ta = run(config, "auto", tag + "-auto", extra)
    b, tb = run(config, "socket", tag + "-socket", extra)
    if want_shm:
        schedule_says(ta, tag + " auto", "shm")
        doorbell_says(ta, tag + " auto")
    check("messages to it posted" not in tb, f"{tag} socket: nothing posted")
    schedule_says(tb, tag + " socket", "tcp/ipc")
    check('coupling.transport is "socket"' in tb, f"{tag}: the socket run says why")
    diff, n = differences(a, b)
    check(not diff and n > 5, f"{tag}: shm and socket bitwise equal ({n} datasets; {diff[:4]})")
    for ca in sorted(glob.glob(os.path.join(a, "checkpoint_*.h5"))):
        cb = os.path.join(b, os.path.basename(ca))
        check(os.path.exists(cb), f"{tag}: {os.path.basename(ca)} in both")
        if os.path.exists(cb):
            import h5py
            fa, fb = h5py.File(ca, "r"), h5py.File(cb, "r")
            got = {}
            fa.visititems(lambda k, o: got.setdefault(k, o[()].tobytes())
                          if isinstance(o, h5py.Dataset) else None)
            other = {}
            fb.visititems(lambda k, o: other.setdefault(k, o[()].tobytes())
                          if isinstance(o, h5py.Dataset) else None)
            check(got == other and len(got) > 0,
                  f"{tag}: {os.path.basename(ca)} bitwise equal ({len(got)} datasets)")
    return a, b


def stubs():
    ckpt = ["--set", "checkpoint.every=50"]
    same("stub_tire.json", "stub_tire", FINE + ckpt)
    same("stub_tire.json", "stub_tire_implicit", FINE + ckpt +
         ["--set", "coupling.scheme=implicit", "--set", "time.end=0.05"])
    # the scene as it is: a 4 x 4 surface, every array a frame, same bits
    same("stub_tire.json", "stub_tire_coarse", ["--set", "time.end=0.05"])


def scenes():
    same("tire_fem_stub_dem.json", "tire_fem_stub_dem", ["--set", "time.end=0.004"])
    same("default.json", "default", ["--set", "time.end=0.002"])
    same("default.json", "default_implicit", ["--set", "time.end=0.0005", "--set",
                                              "coupling.scheme=implicit"])


def kill():
    """SIGKILL the dem mid-run: no segment left in /dev/shm or the run dir."""
    before = dev_shm()
    name = f"shmkill_{os.getpid()}"
    out = os.path.join(scratch("cosim-shm-"), name)
    p = subprocess.Popen([COSIM, "run", os.path.join(ROOT, "configs", "stub_tire.json"),
                          "--quiet", *FINE, "--set", f"name={name}", "--set",
                          "time.end=1000", "--set", f"output.dir={out}"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    dem = pid_of(name, "dem")
    fem = pid_of(name, "fem")
    check(dem and fem, "both participants started")
    run_dirs = []
    mapped = 0
    for _ in range(200):  # until the loop runs (results.h5 and steps)
        time.sleep(0.05)
        run_dirs = glob.glob(f"/tmp/cosim-{name}-*")
        try:
            maps = open(f"/proc/{dem}/maps").read()
            mapped = maps.count("memfd:cosim-shm")
        except OSError:
            break
        if mapped >= 2 and os.path.exists(os.path.join(out, "results.h5")):
            break
    check(mapped >= 2, f"the dem maps the coupler's segment and its own ({mapped} memfd maps)")
    check(len(run_dirs) == 1, f"a run directory while it runs: {run_dirs}")
    check(dev_shm() == before, f"nothing in /dev/shm while it runs: {dev_shm() - before}")
    time.sleep(0.3)
    if dem:
        os.kill(dem, signal.SIGKILL)
    try:
        _, err = p.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        p.kill()
        _, err = p.communicate()
    check(p.returncode not in (0, None), f"the run fails (exit {p.returncode})")
    check("killed by signal 9" in err, f"the coupler names the kill: {err.strip()[-300:]}")
    no_orphans({"name": name}, "after the kill")
    check(dev_shm() == before, f"no segment left in /dev/shm: {dev_shm() - before}")
    left = [d for d in run_dirs if os.path.exists(d)]
    check(not left, f"the run directory is gone: {left}")
    stray = [f for f in os.listdir(out) if "shm" in f or "memfd" in f] if os.path.isdir(out) else []
    check(not stray, f"nothing shm-like in output.dir: {stray}")


if __name__ == "__main__":
    parts = sys.argv[1:] or ["stubs", "scenes", "kill"]
    for part in parts:
        {"stubs": stubs, "scenes": scenes, "kill": kill}[part]()
    done()
