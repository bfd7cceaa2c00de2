#!/usr/bin/python3
"""A block participant written in Python from PROTOCOL.md alone: a Hertzian
spring, force = c · max(0, d_road)^1.5 (config key "c", N/m^1.5). The swap
test runs the same scene with it instead of block_stub."""
import json
import sys

import numpy as np
import zmq

args = dict(zip(sys.argv[1::2], sys.argv[2::2]))
name = args.get("--name", "block")


def config_error(sec):
    """The section's first problem, named by key path, or None."""
    for key in sorted(set(sec) - {"exec", "c"}):
        return f"processes.{name}.{key}: unknown key"
    if not isinstance(sec.get("c"), (int, float)):
        return f"processes.{name}.c: expected a number"
    return None


if "--check-config" in args:
    sec = json.load(sys.stdin if args["--check-config"] == "-" else open(args["--check-config"]))
    problem = config_error(sec)
    if problem:
        print(problem, file=sys.stderr)
    sys.exit(1 if problem else 0)
s = zmq.Context().socket(zmq.DEALER)
s.setsockopt(zmq.IDENTITY, name.encode())
s.connect(args["--endpoint"])


def send(type_, step=0, t=0.0, arrays=(), **extra):
    h = {"v": 1, "type": type_, "step": step, "t": t,
         "arrays": [{"name": n, "dtype": "f8", "shape": list(a.shape)} for n, a in arrays]}
    h.update(extra)
    s.send_multipart([name.encode(), json.dumps(h).encode()] + [a.tobytes() for _, a in arrays])


send("hello", role="block", name=name, pid=0)
c = None
while True:
    frames = s.recv_multipart()
    h = json.loads(frames[1])
    if h["type"] == "welcome":
        problem = config_error(h["config"])
        if problem:
            send("error", message=problem)
            sys.exit(1)
        c = float(h["config"]["c"])
        send("ready", series={"series": ["t", "d_road", "force"]})
    elif h["type"] == "step":
        i = [a["name"] for a in h["arrays"]].index("d_road")
        d = np.frombuffer(frames[2 + i], dtype="<f8")[0]
        f = c * max(d, 0.0) ** 1.5
        t = h["t"] + h["dt"]
        send("done", h["step"], t, [("force", np.array([f])),
                                    ("series", np.array([t, d, f]))])
    elif h["type"] == "stop":
        send("bye")
        break
