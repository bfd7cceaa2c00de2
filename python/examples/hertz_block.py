#!/usr/bin/python3
"""A tread block in Python: a Hertzian contact with viscous damping,

    force = c · max(0, d)^1.5 + damping · (d - d_prev) / dt   (while in contact)

d the road's displacement towards the block (role "block"). It stands in for
contact_block in a block scene, one string swapped:

    cosim run configs/tread_block.json \\
        --set processes.block.exec=python/examples/hertz_block.py \\
        --set processes.block.c=1e9

Keys: c (N/m^1.5, required), damping (N s/m, default 0); the keys of the
solver it stands in for are named in its log and ignored. Its state (the
last displacement) is saved and loaded, so it takes part in the implicit
scheme and in checkpoints.
"""
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
import numpy as np  # noqa: E402

import cosim  # noqa: E402


def configure(cfg):
    c, damping = cfg.number("c", min=0), cfg.number("damping", 0.0, min=0)
    ignored = cfg.ignore_rest()
    if ignored:
        print(f"hertz_block: ignoring {len(ignored)} keys: {', '.join(ignored)}")
    return c, damping


d_prev = np.zeros(1)  # the state: the displacement at the end of the last step
with cosim.Participant("block", configure=configure,
                       save_state=lambda: {"d_prev": d_prev},
                       load_state=lambda s: d_prev.__setitem__(0, s["d_prev"][0])) as p:
    c, damping = p.params
    p.ready(series=["t", "d_road", "force", "rate"])
    for step in p.steps():
        d = step["d_road"][0]
        rate = (d - d_prev[0]) / step.dt
        force = c * d ** 1.5 + damping * rate if d > 0 else 0.0
        d_prev[0] = d
        step.done(force=force, series=[step.t_end, d, force, rate])
