#!/usr/bin/python3
"""A misbehaving participant for the bad-input tests. ROGUE_MODE says how:
crash       exit(3) at once, before any handshake
segv        die by SIGSEGV at once
silent      connect and never say anything
mute        say hello, then never answer the welcome
version     say hello with protocol version 2
truncated   say hello with an array frame shorter than its header claims
oversized   say hello with an array header claiming 1e12 doubles
role        say hello with a role that does not exist
crash_step  behave until the first step, then exit(5)
nan         answer steps, with a NaN force from step 3 on
"""
import json
import os
import signal
import sys
import time

import zmq

mode = os.environ.get("ROGUE_MODE", "silent")
args = dict(zip(sys.argv[1::2], sys.argv[2::2]))
if "--check-config" in args:
    sys.exit(0)
name, endpoint = args["--name"], args["--endpoint"]
if mode == "crash":
    print("rogue: crashing on purpose", file=sys.stderr)
    sys.exit(3)
if mode == "segv":
    os.kill(os.getpid(), signal.SIGSEGV)

ctx = zmq.Context()
s = ctx.socket(zmq.DEALER)
s.setsockopt(zmq.IDENTITY, name.encode())
s.setsockopt(zmq.LINGER, 1000)
s.connect(endpoint)


def header(type_, v=1, arrays=(), step=0, **kw):
    h = {"v": v, "type": type_, "step": step, "t": 0.0, "arrays": list(arrays)}
    h.update(kw)
    return json.dumps(h).encode()


role = os.environ.get("ROGUE_ROLE", "block")
if mode == "silent":
    time.sleep(3600)
elif mode == "version":
    s.send_multipart([name.encode(), header("hello", v=2, role=role, name=name)])
elif mode == "truncated":
    arr = [{"name": "x", "dtype": "f8", "shape": [10, 3]}]
    s.send_multipart([name.encode(), header("hello", arrays=arr, role=role), b"\0" * 17])
elif mode == "oversized":
    arr = [{"name": "x", "dtype": "f8", "shape": [1000000000000]}]
    s.send_multipart([name.encode(), header("hello", arrays=arr, role=role), b"\0" * 8])
elif mode == "role":
    s.send_multipart([name.encode(), header("hello", role="blob", name=name)])
else:
    s.send_multipart([name.encode(), header("hello", role=role, name=name)])
    welcome = s.recv_multipart()
    if mode == "nan":
        import numpy as np
        s.send_multipart([name.encode(), header("ready", series={"series": ["t", "force"]})])
        while True:
            h = json.loads(s.recv_multipart()[1])
            if h["type"] != "step":
                break
            f = np.array([float("nan") if h["step"] >= 3 else 1.0])
            row = np.array([h["t"] + h["dt"], f[0]])
            arrays = [{"name": "force", "dtype": "f8", "shape": [1]},
                      {"name": "series", "dtype": "f8", "shape": [2]}]
            s.send_multipart([name.encode(), header("done", arrays=arrays, step=h["step"]),
                              f.tobytes(), row.tobytes()])
    if mode == "crash_step":
        s.send_multipart([name.encode(), header("ready", series={"series": ["t"]})])
        s.recv_multipart()
        print("rogue: crashing at the first step", file=sys.stderr)
        sys.exit(5)
time.sleep(3600)  # mute, and whatever comes after a bad hello: wait to be killed
