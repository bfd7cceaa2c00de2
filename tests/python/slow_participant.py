#!/usr/bin/python3
"""A block participant with a long init and a long first step, for
test_liveness.py: it says nothing itself for 1.6 s twice, and reports
progress once in between."""
import os
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "python"))
import cosim  # noqa: E402

with cosim.Participant("block") as p:
    time.sleep(1.6)                      # a long init, silent
    p.progress(0.5, "half way\x07 there")
    time.sleep(0.3)
    p.ready(series=["t"])
    for step in p.steps():
        if step.k == 1:
            time.sleep(1.6)              # a long step, silent
        step.done(force=0.0, series=[step.t_end])
