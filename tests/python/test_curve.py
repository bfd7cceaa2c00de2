"""CURVE from Python (security.curve, PROTOCOL.md): a participant given a key
file in COSIM_CURVE_FILE speaks to a CURVE server, one with the wrong server
key gets no message through, a key file readable by others is refused by
name; a Monitor with the monitors' key file receives from a CURVE bus."""
import json
import os
import subprocess
import sys
import time

import numpy as np
import zmq

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "e2e"))
from common import check, done, scratch  # noqa: E402

import cosim  # noqa: E402
from cosim import protocol as P  # noqa: E402

HERTZ = os.path.join(HERE, "..", "..", "python", "examples", "hertz_block.py")
ctx = zmq.Context.instance()
server_pub, server_sec = zmq.curve_keypair()
client_pub, client_sec = zmq.curve_keypair()
other_pub, _ = zmq.curve_keypair()
d = scratch("cosim-curve-")


def key_file(name, server, mode=0o600):
    path = os.path.join(d, name)
    with open(path, "w") as f:
        json.dump({"server_public": server.decode(), "public": client_pub.decode(),
                   "secret": client_sec.decode()}, f)
    os.chmod(path, mode)
    return path


def hello_with(keys, wait_ms):
    """(first message the CURVE router got within wait_ms or None, participant output)."""
    router = ctx.socket(zmq.ROUTER)
    router.curve_server = True
    router.curve_secretkey = server_sec
    router.setsockopt(zmq.LINGER, 0)
    port = router.bind_to_random_port("tcp://127.0.0.1")
    env = dict(os.environ, COSIM_CURVE_FILE=keys, COSIM_HANDSHAKE_TIMEOUT="3")
    child = subprocess.Popen([HERTZ, "--endpoint", f"tcp://127.0.0.1:{port}", "--name", "blk"],
                             env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    m = P.decode(router.recv_multipart()[1:]) if router.poll(wait_ms) else None
    if m is None:
        # nothing came through: let the participant end by itself (its refusal,
        # or the 3 s handshake timeout), so its output is whole on a busy machine
        try:
            child.wait(timeout=60)
        except subprocess.TimeoutExpired:
            pass
    child.kill()
    out, _ = child.communicate()
    router.close()
    return m, out


if zmq.has("curve"):
    m, out = hello_with(key_file("good.json", server_pub), 10000)
    check(m is not None and m.type == "hello", f"a keyed participant says hello over CURVE: {out[-300:]}")
    m, out = hello_with(key_file("wrong.json", other_pub), 1500)
    check(m is None, "a participant with the wrong server key gets nothing through")
    m, out = hello_with(key_file("open.json", server_pub, 0o644), 1500)
    check(m is None and "readable by others" in out, f"an open key file is refused: {out[-300:]}")
    # a monitor on a CURVE bus
    pub = ctx.socket(zmq.PUB)
    pub.curve_server = True
    pub.curve_secretkey = server_sec
    port = pub.bind_to_random_port("tcp://127.0.0.1")
    mon = cosim.Monitor(f"tcp://127.0.0.1:{port}", topics="x.", timeout=1,
                        key_file=key_file("mon.json", server_pub))
    got = []
    for i in range(30):  # until the subscription has arrived
        pub.send_multipart(P.encode("x.series", "series", i, 0.0, [("series", np.arange(2.0))]))
        time.sleep(0.05)
    got = [m.step for m in mon]
    check(len(got) > 0 and got == list(range(got[0], 30)), f"a keyed monitor receives: {got}")
    pub.close(0)
else:
    print("libzmq without CURVE: skipped")
done()
