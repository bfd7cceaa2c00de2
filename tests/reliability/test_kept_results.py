"""A run never destroys an earlier run's results (README "Output"):
- a second run into the same output.dir while the first runs is refused at
  once (exit 1), naming the first one's pid; the first finishes, complete;
- a rerun without --overwrite is refused (exit 1), the earlier file intact;
- a rerun with --overwrite that fails before its participants pass their
  handshake (one crashes at start: exit 3; an exec that is not there: exit 1)
  leaves the earlier file intact: results.h5 is made only after the handshake;
- a results.h5 that is not an HDF5 file is never written over, --overwrite
  or not (exit 1)."""
import hashlib
import os
import subprocess
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "e2e"))
from common import COSIM, HERE, check, done, h5, no_orphans, run, scene, write  # noqa: E402

ROGUE = os.path.join(HERE, "rogue.py")


def block_scene(name, end):
    s = scene(name, {"block": {"exec": "block_stub", "stiffness": 3e5}},
              scenario={"kind": "indentation", "profile": "linear", "depth": 1e-4, "ramp_time": 1})
    s["time"] = {"dt": 1e-3, "end": end}
    s["output"]["every"] = 1000
    return s


def digest(path):
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()


# --- two runs into one dir at once: the second is refused at once
first = block_scene("kept", 60.0)  # 60 000 steps: a few seconds
results = os.path.join(first["output"]["dir"], "results.h5")
path = write(first)
a = subprocess.Popen([COSIM, "run", path, "--quiet"], stdout=subprocess.PIPE,
                     stderr=subprocess.PIPE, text=True)
endpoints = os.path.join(first["output"]["dir"], "endpoints.json")
for _ in range(200):  # the lock is taken before endpoints.json is written
    if os.path.exists(endpoints):
        break
    time.sleep(0.05)
t0 = time.time()
b = subprocess.run([COSIM, "run", path, "--quiet", "--overwrite"], capture_output=True,
                   text=True, timeout=60)
took = time.time() - t0
still = a.poll() is None
check(b.returncode == 1 and f"in use by another cosim run (pid {a.pid})" in b.stderr,
      f"a second run into the same dir is refused naming the first's pid ({b.returncode}: "
      f"{b.stderr[-300:]})")
check(took < 5 and still, f"refused at once ({took:.1f} s), while the first still runs ({still})")
out, err = a.communicate(timeout=240)
check(a.returncode == 0 and "finished" in out, f"the first run finishes ({a.returncode}: {err[-300:]})")
rows = len(h5(first)["/block/series"])
check(rows == 60000, f"the first run's results are complete ({rows} of 60000 rows)")
no_orphans(first, "concurrent runs")
before = digest(results)

# --- reruns into the same dir
rc, out, err = run(first, "--quiet")
check(rc == 1 and "holds the results of an earlier run" in err and "--overwrite" in err,
      f"a rerun without --overwrite is refused ({rc}: {err[-300:]})")
check(digest(results) == before, "and the earlier results.h5 is untouched")

crash = dict(first)
crash["processes"] = {"block": {"exec": ROGUE}}
crash["coupling"] = {"hello_timeout": 5}
rc, out, err = run(crash, "--quiet", "--overwrite", env={"ROGUE_MODE": "crash"})
check(rc == 3 and "crashing on purpose" in err, f"a rerun whose participant crashes at start: "
      f"exit 3 ({rc}: {err[-300:]})")
check(digest(results) == before, "and the earlier results.h5 is untouched (made only after the "
      "handshake)")

missing = dict(first)
missing["processes"] = {"block": {"exec": "no_such_participant"}}
rc, out, err = run(missing, "--quiet", "--overwrite")
check(rc == 1 and "not found" in err, f"a rerun with a missing exec: exit 1 ({rc}: {err[-200:]})")
check(digest(results) == before, "and the earlier results.h5 is untouched")

# --- --overwrite replaces the results of a run that completes
short = dict(first)
short["time"] = {"dt": 1e-3, "end": 0.5}
rc, out, err = run(short, "--quiet", "--overwrite")
check(rc == 0 and len(h5(first)["/block/series"]) == 500,
      f"--overwrite replaces them with a complete run ({rc}: {err[-200:]})")

# --- a results.h5 that is not HDF5 is never written over
with open(results, "wb") as f:
    f.write(b"my notes, not cosim's\n")
before = digest(results)
for extra in ((), ("--overwrite",)):
    rc, out, err = run(short, "--quiet", *extra)
    check(rc == 1 and "is not an HDF5 file" in err and "never writes over it" in err,
          f"a non-HDF5 results.h5 is refused {extra} ({rc}: {err[-200:]})")
    check(digest(results) == before, f"and left as it was {extra}")
no_orphans(first, "reruns")
done()
