"""A damaged or hostile checkpoint is refused on restart (exit 1) with an
error naming the file and the dataset, and the earlier run's output.dir
(results.h5, the checkpoints) is left exactly as it was. Checkpoints are
read through proto's HDF5 input layer (proto_h5in_*): a dataset missing, of
another type, rank or size, one whose shape claims more than a message can
carry, a cut file, another file's attributes. The coupler's own state is
checked against the run before results.h5 is opened. The intact checkpoint
then restarts (so what was refused was the damage). A state array a
participant refuses (well-formed, another size) fails the restart before
results.h5 is opened too: every state is restored first."""
import hashlib
import json
import os
import shutil

import h5py
import numpy as np

from rel import ROOT, check, cosim, two_spring_blocks
from common import done, scratch, write

DT = 1.953125e-5
CKPT = "checkpoint_200.h5"


# where a running coupler listens: rewritten by every run that gets as far as
# starting its processes (the coupler's state is checked after the handshake)
LIVE = {"endpoints.json"}


def snapshot(d):
    """Every file of output.dir (logs, the lock and LIVE aside): its digest."""
    out = {}
    for name in sorted(os.listdir(d)):
        p = os.path.join(d, name)
        if os.path.isfile(p) and not name.startswith(".") and name not in LIVE:
            out[name] = hashlib.sha256(open(p, "rb").read()).hexdigest()
    return out


s = two_spring_blocks(json.load(open(os.path.join(ROOT, "configs", "tread_block.json"))))
s["name"] = f"bad_checkpoint_{os.getpid()}"
s["time"]["end"] = 400 * DT
s["output"]["every"] = 50
s["checkpoint"] = {"every": 100, "keep": 4}
base = scratch("cosim-badckpt-")
run_dir = s["output"]["dir"] = os.path.join(base, "run")
scene = write(s)
rc, out, err = cosim("run", scene, "--quiet")
good = os.path.join(run_dir, CKPT)
check(rc == 0 and os.path.exists(good), f"the run and its {CKPT} ({err[-300:]})")
before = snapshot(run_dir)


def replace(f, path, data=None, **kw):
    del f[path]
    f.create_dataset(path, data=data, **kw)


# (what, how the copy is damaged, what the error must say, exit code)
CASES = [
    ("a missing dataset", lambda f: f.__delitem__("coupler/step"),
     "/coupler/step: dataset missing"),
    ("the step of another type", lambda f: replace(f, "coupler/step", np.array([200.0])),
     "/coupler/step: another type or size"),
    ("a negative step", lambda f: replace(f, "coupler/step", np.array([-7], dtype="<i8")),
     "/coupler/step: step -7"),
    ("a coupler field of the wrong size",
     lambda f: replace(f, "coupler/rim.c", np.zeros(2)),
     "/coupler/rim.c: different there"),
    ("the accelerator's history of the wrong size",
     lambda f: replace(f, "coupler/accel.G", np.zeros(7)),
     "/coupler/accel.G: different there"),
    ("a state array of rank 4",
     lambda f: replace(f, "participants/left/state.force", np.zeros((1, 1, 1, 1))),
     "/participants/left/state.force: has 4 dimension(s), expected 1 to 3"),
    ("a state array of strings",
     lambda f: replace(f, "participants/left/state.force", np.array([b"1.0"])),
     "/participants/left/state.force: expected numbers"),
    ("a state array of f4",
     lambda f: replace(f, "participants/right/state.force", np.zeros(1, dtype="<f4")),
     "/participants/right/state.force: expected f8, i4, i8 or u1"),
    ("a state array whose shape claims 2^40 doubles (no storage)",
     lambda f: replace(f, "participants/left/state.force", shape=(1 << 40,), dtype="<f8",
                       chunks=(1024,)),
     "/participants/left/state.force: shape [1099511627776] holds more than"),
    ("a state array not named state.<x>",
     lambda f: f.move("participants/left/state.force", "participants/left/force"),
     "/participants/left/force: state arrays are named state."),
    ("a participant without its role",
     lambda f: f["participants/right"].attrs.__delitem__("role"),
     "/participants/right: attribute role missing"),
    ("the participants' group missing", lambda f: f.__delitem__("participants"),
     "/participants: group missing"),
    ("another file's magic", lambda f: f.attrs.__setitem__("cosim", "results"),
     "not a cosim checkpoint"),
    # well-formed, but not what the participant saved: it refuses (exit 3),
    # still before results.h5 is opened
    ("a state array of the wrong size (the participant refuses it)",
     lambda f: replace(f, "participants/left/state.force", np.zeros(2)),
     "array 'state.force' is f8 with 16 bytes, expected f8 with 8 bytes", 3),
]

for what, damage, says, *code in CASES:
    code = code[0] if code else 1
    bad = os.path.join(base, "bad.h5")
    shutil.copyfile(good, bad)
    with h5py.File(bad, "r+") as f:
        damage(f)
    rc, out, err = cosim("run", scene, "--quiet", "--restart", bad)
    # (a sanitizer's report would exit 1 too: none may come with the refusal)
    check(rc == code and bad in err and says in err and "Sanitizer" not in err,
          f"{what}: refused, exit {code}, naming the file and '{says}' ({rc}: {err[-300:]})")
    now = snapshot(run_dir)
    check(now == before, f"{what}: output.dir untouched "
          f"({[k for k in set(now) | set(before) if now.get(k) != before.get(k)]})")

# a cut file: not HDF5 any more
cut = os.path.join(base, "cut.h5")
data = open(good, "rb").read()
open(cut, "wb").write(data[:len(data) // 2])
rc, out, err = cosim("run", scene, "--quiet", "--restart", cut)
check(rc == 1 and f"{cut}: cannot open as HDF5" in err and "Sanitizer" not in err,
      f"a checkpoint cut in half: refused, exit 1 ({rc}: {err[-300:]})")
check(snapshot(run_dir) == before, "a cut checkpoint: output.dir untouched")

# the intact one restarts
rc, out, err = cosim("run", scene, "--quiet", "--restart", good)
check(rc == 0, f"the intact {CKPT} restarts ({err[-300:]})")
done()
