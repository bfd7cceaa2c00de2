#!/usr/bin/python3
"""A block participant with a long init and a long first step, for
test_liveness.py: it says nothing itself for SILENT_S seconds twice, and reports
progress once in between."""
import os
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "python"))
import cosim  # noqa: E402

SILENT_S = float(os.environ.get("SILENT_S", "1.6"))  # longer than the promised heartbeat_s

with cosim.Participant("block") as p:
    time.sleep(SILENT_S)                 # a long init, silent
    p.progress(0.5, "half way\x07 there")
    time.sleep(0.3)
    p.ready(series=["t"])
    for step in p.steps():
        if step.k == 1:
            time.sleep(SILENT_S)         # a long step, silent
        step.done(force=0.0, series=[step.t_end])
