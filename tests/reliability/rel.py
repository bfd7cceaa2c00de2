"""Helpers of the reliability tests: the e2e helpers, and comparing two runs'
results.h5 dataset by dataset."""
import os
import subprocess
import sys

import h5py
import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "e2e"))
from common import COSIM, check  # noqa: E402,F401

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
# Wall-clock columns (and the timing table) differ between any two runs.
WALL_COLUMNS = {"wall_s"}
WALL_DATASETS = {"/coupler/timing"}


def datasets(f):
    out = {}
    f.visititems(lambda name, obj: out.__setitem__("/" + name, obj)
                 if isinstance(obj, h5py.Dataset) else None)
    return out


def differences(dir_a, dir_b):
    """What differs between two runs' results.h5, bit for bit: names of
    datasets only in one, or whose values differ (wall-clock columns aside)."""
    fa = h5py.File(os.path.join(dir_a, "results.h5"), "r")
    fb = h5py.File(os.path.join(dir_b, "results.h5"), "r")
    da, db = datasets(fa), datasets(fb)
    diff = [f"only in {dir_a}: {k}" for k in sorted(set(da) - set(db))]
    diff += [f"only in {dir_b}: {k}" for k in sorted(set(db) - set(da))]
    same = 0
    for k in sorted(set(da) & set(db)):
        if k in WALL_DATASETS:
            continue
        x, y = da[k][()], db[k][()]
        cols = [c.decode() if isinstance(c, bytes) else str(c) for c in da[k].attrs.get("columns", [])]
        if cols:
            keep = [i for i, c in enumerate(cols) if c not in WALL_COLUMNS]
            x, y = x[:, keep], y[:, keep]
        if x.shape != y.shape or x.tobytes() != y.tobytes():
            diff.append(f"{k}: {x.shape} vs {y.shape}" +
                        (f", max |diff| {np.abs(x - y).max():.3g}" if x.shape == y.shape else ""))
        else:
            same += 1
    for name in sorted(os.listdir(dir_a)):  # the XDMF companions list the same grids
        if name.endswith(".xdmf"):
            ta = open(os.path.join(dir_a, name)).read()
            tb = open(os.path.join(dir_b, name)).read() if os.path.exists(os.path.join(dir_b, name)) else ""
            if ta != tb:
                diff.append(f"{name} differs")
            else:
                same += 1
    return diff, same


def cosim(*args, timeout=600, env=None):
    e = dict(os.environ)
    if env:
        e.update(env)
    p = subprocess.run([COSIM, *args], capture_output=True, text=True, timeout=timeout, env=e)
    return p.returncode, p.stdout, p.stderr


# The road of configs/tread_block.json as a body pushed by a force.
FORCE_ROAD = {"kind": "indentation", "profile": "force", "road_mass": 0.05, "road_force": 50}


def two_spring_blocks(s):
    """The tread-block scene s as two spring blocks (block_stub) under the
    force-driven road, implicit scheme (IQN-ILS): a quick scene whose
    checkpoints hold the coupler's fields, road and accelerator history and
    each block's state."""
    s["scenario"] = dict(FORCE_ROAD)
    s["coupling"] = {"scheme": "implicit"}
    s["processes"] = {"left": {"exec": "block_stub", "stiffness": 1e5, "gap": -1e-5},
                      "right": {"exec": "block_stub", "stiffness": 3e5, "gap": -1e-5}}
    return s
