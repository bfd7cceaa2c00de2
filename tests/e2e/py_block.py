#!/usr/bin/python3
"""A block participant in Python on the cosim package: a Hertzian spring,
force = c · max(0, d_road)^1.5 (config key "c", N/m^1.5). The swap test runs
the same scene with it instead of block_stub."""
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "python"))
import cosim  # noqa: E402

with cosim.Participant("block", configure=lambda cfg: cfg.number("c")) as p:
    p.ready(series=["t", "d_road", "force"])
    for step in p.steps():
        d = step["d_road"][0]
        f = p.params * max(d, 0.0) ** 1.5
        step.done(force=f, series=[step.t_end, d, f])
