"""Helpers for the end-to-end tests: run `cosim` on a scene written from a
dict, read results.h5, and make sure no participant process is left behind."""
import glob
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time

import h5py
import numpy as np

BIN = os.environ.get("COSIM_BIN", os.path.join(os.getcwd(), "bin"))
HERE = os.path.dirname(os.path.abspath(__file__))
COSIM = os.path.join(BIN, "cosim")
FAILURES = []
SCRATCH = []  # temporary folders of this test: removed when every check passed
# Python's temporary files and folders of this test go into one folder of its
# own, removed with the others: cosim.run keeps the scene file it wrote for a
# dict scene when the run fails (its error names the file), and tests fail
# runs on purpose
tempfile.tempdir = tempfile.mkdtemp(prefix="cosim-test-")
SCRATCH.append(tempfile.tempdir)


def scratch(prefix):
    d = tempfile.mkdtemp(prefix=prefix)
    SCRATCH.append(d)
    return d


def remove_run_dirs(s):
    """The run directory of scene s's cosim killed hard (SIGKILL: it cannot
    remove its own; cosim makes it as /tmp/cosim-<name>-XXXXXX)."""
    for d in glob.glob(f"/tmp/cosim-{s['name']}-*"):
        shutil.rmtree(d, ignore_errors=True)


def check(cond, what):
    """Records a failed check (the test goes on, and fails at the end)."""
    if not cond:
        FAILURES.append(what)
        print("FAIL:", what, flush=True)
    return cond


def done():
    if FAILURES:
        print(f"{len(FAILURES)} check(s) failed (outputs kept in {', '.join(SCRATCH)})")
        sys.exit(1)
    for d in SCRATCH:  # runs write hundreds of MB: a passing test leaves none behind
        shutil.rmtree(d, ignore_errors=True)
    print("all checks passed")


def scene(name, processes, **kw):
    """A scene dict with a unique name (the name appears in every
    participant's command line, which is how orphans are found)."""
    uniq = f"{name}_{os.getpid()}_{int(time.time() * 1e3) % 100000}"
    s = {"name": uniq,
         "time": {"dt": 1e-3, "end": 0.05},
         "output": {"dir": os.path.join(scratch("cosim-e2e-"), uniq),
                    "every": 10},
         "coupling": {"handshake_timeout": 5, "step_timeout": 5},
         "processes": processes}
    s.update(kw)
    return s


def write(s, text=None):
    d = scratch("cosim-cfg-")
    path = os.path.join(d, "scene.json")
    with open(path, "w") as f:
        f.write(text if text is not None else json.dumps(s, indent=1))
    return path


def run(s, *args, cmd="run", text=None, timeout=60, env=None):
    """Runs `cosim CMD scene.json ARGS`; returns (rc, stdout, stderr)."""
    path = write(s, text)
    e = dict(os.environ)
    if env:
        e.update(env)
    p = subprocess.run([COSIM, cmd, path, *args], capture_output=True,
                       text=True, timeout=timeout, env=e)
    return p.returncode, p.stdout, p.stderr


def processes_with(marker):
    """PIDs whose command line contains marker (excluding ourselves)."""
    found = []
    for pid in os.listdir("/proc"):
        if not pid.isdigit() or int(pid) == os.getpid():
            continue
        try:
            with open(f"/proc/{pid}/cmdline", "rb") as f:
                cmd = f.read().replace(b"\0", b" ").decode(errors="replace")
            with open(f"/proc/{pid}/stat") as f:
                state = f.read().rsplit(")", 1)[1].split()[0]
        except OSError:
            continue
        if marker in cmd and state != "Z":
            found.append((int(pid), cmd))
    return found


def pid_of(marker, name, tries=500):
    """The participant `name` of the run whose command lines carry marker
    (the scene's name), once it is running; None if it never shows."""
    for _ in range(tries):
        for pid, cmd in processes_with(marker):
            if f"--name {name}" in cmd and "cosim run" not in cmd:
                return pid
        time.sleep(0.02)
    return None


def no_orphans(s, what):
    # give the kernel a moment to reap what was killed
    for _ in range(50):
        left = processes_with(s["name"])
        if not left:
            return True
        time.sleep(0.05)
    return check(False, f"{what}: orphan processes left: {left}")


def h5(s):
    return h5py.File(os.path.join(s["output"]["dir"], "results.h5"), "r")


def columns(ds):
    return [c.decode() if isinstance(c, bytes) else str(c) for c in ds.attrs["columns"]]
