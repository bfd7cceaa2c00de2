"""Checkpoint and restart, bit for bit, on the tread-block scene
(contact_block, whose state holds its history convolution's buffers):
2N steps straight give the same results.h5, row for row (wall-clock columns
aside), as N steps, then a restart from the checkpoint of step N for N more
(the restarted run continues the same results.h5):
- the scene as it is (serial scheme, prescribed indentation);
- the road as a body pushed by a force, implicit scheme with IQN-ILS (the
  road's state and the accelerator's history reused across steps are in the
  checkpoint);
- after a crash: a block (of two spring blocks under that road) killed after
  a checkpoint, `--restart latest` finishes the run, equal to the straight one.
Also: a restart refuses a scene that differs in a key that decides the
results, naming the key."""
import json
import os
import signal
import subprocess
import time

from rel import COSIM, FORCE_ROAD, ROOT, check, cosim, differences, two_spring_blocks
from common import done, processes_with, scratch, write

SCENE = os.path.join(ROOT, "configs", "tread_block.json")
N = 160  # of 343 steps
DT = 1.953125e-5
FORCE = FORCE_ROAD


def scene(name, **changes):
    s = json.load(open(SCENE))
    s["name"] = f"{name}_{os.getpid()}"
    s["time"]["end"] = 2 * N * DT
    s["output"]["every"] = 40
    s["checkpoint"] = {"every": N, "keep": 2}
    s.update(changes)
    return s


def straight_and_restarted(label, s):
    base = scratch("cosim-restart-")
    a, b = os.path.join(base, "straight"), os.path.join(base, "restarted")
    s["output"]["dir"] = a
    rc, out, err = cosim("run", write(s), "--quiet")
    check(rc == 0, f"{label}: 2N steps straight ({err[-300:]})")
    s["output"]["dir"] = b
    half = json.loads(json.dumps(s))
    half["time"]["end"] = N * DT
    rc, out, err = cosim("run", write(half), "--quiet")
    check(rc == 0 and os.path.exists(os.path.join(b, f"checkpoint_{N}.h5")),
          f"{label}: N steps, checkpoint_{N}.h5 written ({err[-300:]})")
    rc, out, err = cosim("run", write(s), "--quiet", "--restart", os.path.join(b, f"checkpoint_{N}.h5"))
    check(rc == 0, f"{label}: restarted for N more ({err[-300:]})")
    diff, same = differences(a, b)
    check(not diff and same > 10, f"{label}: N + restart + N equals 2N straight, bit for bit "
          f"({same} datasets equal; differences: {diff[:5]})")
    return s


straight_and_restarted("serial", scene("restart_block"))
s = straight_and_restarted("implicit, force-driven road",
                           scene("restart_road", scenario=FORCE,
                                 coupling={"scheme": "implicit"}))

# a scene that does not continue the checkpoint is refused, by key
bad = json.loads(json.dumps(s))
bad["processes"]["block"]["green"]["zeta"] = 0.2
rc, out, err = cosim("run", write(bad), "--quiet", "--restart", "latest")
check(rc == 1 and "processes.block.green.zeta" in err,
      f"a changed scene is refused, naming the key ({rc}: {err[-300:]})")

# after a crash: kill a block once a checkpoint exists, resume from the latest
# (two spring blocks under the force-driven road, implicit: a quick scene)
s = two_spring_blocks(scene("restart_crash"))
s["time"]["end"] = 8000 * DT
s["output"]["every"] = 100
s["checkpoint"] = {"every": 1000, "keep": 2}
base = scratch("cosim-restart-")
s["output"]["dir"] = os.path.join(base, "straight")
rc, out, err = cosim("run", write(s), "--quiet")
check(rc == 0, f"crash: the straight run ({err[-300:]})")
s["output"]["dir"] = os.path.join(base, "crashed")
p = subprocess.Popen([COSIM, "run", write(s), "--quiet"], stdout=subprocess.PIPE,
                     stderr=subprocess.PIPE, text=True)
ckpt = os.path.join(s["output"]["dir"], "checkpoint_2000.h5")
for _ in range(3000):
    if os.path.exists(ckpt) or p.poll() is not None:
        break
    time.sleep(0.01)
victims = [pid for pid, cmd in processes_with(s["name"]) if "--name right" in cmd]
for pid in victims:
    os.kill(pid, signal.SIGKILL)
out, err = p.communicate(timeout=120)
check(victims and p.returncode == 3, f"crash: a block killed after step 2000's checkpoint, "
      f"exit 3 ({p.returncode}: {err[-200:]})")
rc, out, err = cosim("run", write(s), "--quiet", "--restart", "latest")
check(rc == 0, f"crash: --restart latest finishes the run ({err[-300:]})")
diff, same = differences(os.path.join(base, "straight"), s["output"]["dir"])
check(not diff, f"crash: the resumed results equal the straight run's ({same} equal; {diff[:5]})")
done()
