#!/usr/bin/python3
"""A hostile participant for the hostile-input tests (tests/input). It speaks
the protocol (PROTOCOL.md) but lies in one way, chosen by HOSTILE_MODE:
version19    hello with "v": 1.9
dup_header   hello whose header gives "role" twice
no_series    declares series, then answers step 2 without its row
series_path  declares a series dataset named "../../coupler/series"
array_slash  answers step 1 with an array named "snap/../x"
esc_error    reports an error whose text is full of terminal escape sequences
esc_identity connects under a routing identity with escape sequences
topic_nul    hello whose topic holds a NUL byte
iteration    answers step 1 with "iteration": 1e300
"""
import json
import os
import sys
import time

import zmq

mode = os.environ.get("HOSTILE_MODE", "")
args = dict(zip(sys.argv[1::2], sys.argv[2::2]))
if "--check-config" in args:
    sys.exit(0)
name, endpoint = args["--name"], args["--endpoint"]
ESC = "\x1b]0;owned\x07\x1b[2J\x1b[31m"

ctx = zmq.Context()
s = ctx.socket(zmq.DEALER)
s.setsockopt(zmq.IDENTITY, (ESC + name).encode() if mode == "esc_identity" else name.encode())
s.setsockopt(zmq.LINGER, 1000)
s.connect(endpoint)


def header(type_, v=1, arrays=(), step=0, t=0.0, **kw):
    h = {"v": v, "type": type_, "step": step, "t": t, "arrays": list(arrays)}
    h.update(kw)
    return json.dumps(h).encode()


def f8(*values):
    import struct
    return struct.pack("<%dd" % len(values), *values)


topic = name.encode()
if mode == "version19":
    s.send_multipart([topic, header("hello", v=1.9, role="block", name=name)])
elif mode == "dup_header":
    s.send_multipart([topic, b'{"v": 1, "type": "hello", "role": "block", "role": "dem"}'])
elif mode == "topic_nul":
    s.send_multipart([topic + b"\0x", header("hello", role="block", name=name)])
else:
    s.send_multipart([topic, header("hello", role="block", name=name)])
    welcome = s.recv_multipart()
    if mode == "esc_error":
        s.send_multipart([topic, header("error", message="bad things" + ESC + " happened")])
    else:
        series = {"../../coupler/series": ["t"]} if mode == "series_path" else {"series": ["t", "force"]}
        s.send_multipart([topic, header("ready", role="block", series=series)])
        while True:
            frames = s.recv_multipart()
            h = json.loads(frames[1])
            if h["type"] != "step":
                break
            k, t = h["step"], h["t"] + h["dt"]
            arrays = [{"name": "force", "dtype": "f8", "shape": [1]}]
            data = [f8(1.0)]
            if not (mode == "no_series" and k == 2):
                arrays.append({"name": "series", "dtype": "f8", "shape": [2]})
                data.append(f8(t, 1.0))
            if mode == "array_slash":
                arrays.append({"name": "snap/../x", "dtype": "f8", "shape": [1]})
                data.append(f8(0.0))
            extra = {"iteration": 1e300} if mode == "iteration" else {}
            s.send_multipart([topic, header("done", arrays=arrays, step=k, t=t, **extra)] + data)
time.sleep(3600)  # wait to be stopped
