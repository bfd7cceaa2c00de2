#!/usr/bin/python3
"""A participant that gets its reply wrong on purpose (BAD_MODE), for
test_bad_arrays.py: the package must raise naming the array and its
expected shape, and tell the coupler, which names the participant."""
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "python"))
import numpy as np  # noqa: E402

import cosim  # noqa: E402

MODE = os.environ["BAD_MODE"]
ROLE = "fem" if MODE.startswith("fem") else "block"


def block_reply(step):
    good = dict(force=[1.0], series=[step.t_end, 1.0])
    bad = {"dtype": dict(force=np.ones(1, np.float32)),
           "shape": dict(force=np.ones((1, 1))),
           "int": dict(force=np.ones(1, np.int64)),
           "unknown": dict(force=[1.0], forse=[1.0]),
           "series": dict(series=[step.t_end])}
    if step.k < 2:
        return good
    if MODE == "missing":
        return dict(series=good["series"])
    return dict(good, **bad[MODE])


with cosim.Participant(ROLE, configure=lambda cfg: cfg.ignore_rest()) as p:
    if ROLE == "block":
        p.ready(series=["t", "force"])
        for step in p.steps():
            step.done(**block_reply(step))
    else:
        X0 = np.zeros((25, 3))
        p.ready(surface_x0=X0, surface_tri=np.array([[0, 1, 2]], np.int32))
        for step in p.steps():
            step.done(x=X0[:-1] if MODE == "fem_shape" else X0, v=X0.astype(np.float32)
                      if MODE == "fem_dtype" else X0)
