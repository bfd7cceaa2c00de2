"""The package's protocol layer, without cosim in between:

1. framing: encode/decode round trip (zero-copy views), and decode rejects
   what PROTOCOL.md says a receiver rejects, naming the defect;
2. the role table from `cosim roles --json`: every array name the C table
   declares is there (the package declares none itself), and a check names
   the array with its expected shape and bound sizes;
3. a participant (python/examples/hertz_block.py) driven by a coupler written
   here: checkpoint -> state, a repeated step gives the same bits as the
   first, restore -> restored and the state is back; --check-config.
"""
import json
import os
import subprocess
import sys

import numpy as np
import zmq

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "e2e"))
from common import COSIM, check, done  # noqa: E402

import cosim  # noqa: E402
from cosim import protocol as P  # noqa: E402
from cosim.roles import Dims  # noqa: E402

HERTZ = os.path.join(HERE, "..", "..", "python", "examples", "hertz_block.py")


def raises(fn, needle, what):
    try:
        fn()
    except cosim.CosimError as e:
        return check(needle in str(e), f"{what}: message {str(e)!r} lacks {needle!r}")
    return check(False, f"{what}: no error")


# 1. framing
x = np.arange(12.0).reshape(4, 3)
tri = np.array([[0, 1, 2]], dtype=np.int32)
frames = P.encode("soil", "done", 3, 0.5, [("x", x), ("tri", tri)], {"compute_s": 1e-3})
m = P.decode([bytes(memoryview(f)) for f in frames])
check(m.topic == "soil" and m.type == "done" and m.step == 3 and m.t == 0.5, f"header {m}")
check(np.array_equal(m["x"], x) and m["tri"].dtype == np.int32, "arrays round trip")
check(not m["x"].flags.writeable, "received arrays are read-only views")
topic, header, arrays = m
check(topic == "soil" and header["compute_s"] == 1e-3 and set(arrays) == {"x", "tri"},
      "a message unpacks as (topic, header, arrays)")


def frames_with(header, payload=(b"\0" * 8,)):
    h = {"v": 1, "type": "step", "arrays": [{"name": "a", "dtype": "f8", "shape": [1]}]}
    h.update(header)
    return [b"t", json.dumps(h).encode(), *payload]


raises(lambda: P.decode([b"t", b"[1]"]), "header is not a JSON object", "not an object")
raises(lambda: P.decode(frames_with({"v": 2})), "version mismatch", "version")
raises(lambda: P.decode(frames_with({}, (b"\0" * 7,))), "needs 8 bytes, frame has 7", "frame size")
raises(lambda: P.decode(frames_with({}, ())), "header lists 1 array(s) but 0", "frame count")
raises(lambda: P.decode(frames_with({"arrays": [{"name": "a", "dtype": "f4", "shape": [1]}]})),
       "dtype: expected one of", "dtype")
raises(lambda: P.decode(frames_with({"arrays": [{"name": "a", "dtype": "f8", "shape": [-1]}]})),
       "shape[0]: expected a count", "shape")
two = {"arrays": [{"name": "a", "dtype": "f8", "shape": [1]}] * 2}
raises(lambda: P.decode(frames_with(two, (b"\0" * 8,) * 2)), "appears twice", "duplicate")
raises(lambda: P.wire_array("x", np.zeros(3, np.float32)), "dtype float32", "float32 refused")

# 2. the role table, as the C side declares it
table = cosim.RoleTable.load()
c_names = set()
for role in ("dem", "fem", "block", "lug"):
    txt = subprocess.run([COSIM, "roles"], capture_output=True, text=True).stdout
    block = txt.split(f"role {role}\n")[1].split("role ")[0]
    c_names |= {(role, l.split()[0], l.split()[1]) for l in block.splitlines()
                if l.startswith("  ") and not l.startswith("    ")}
py_names = {(role, msg, s.name) for role, msgs in table.roles.items()
            for msg, specs in msgs.items() for s in specs}
check(py_names == c_names, f"the package's table is `cosim roles`: {py_names ^ c_names}")
d = Dims()
table.check("fem", "ready", {"surface_x0": np.zeros((25, 3)), "surface_tri": tri}, d)
check(d.sizes == {"n": 25, "m": 1}, f"ready binds n and m: {d.sizes}")
raises(lambda: table.check("fem", "done", {"x": np.zeros((24, 3)), "v": np.zeros((25, 3))}, d),
       "array 'x': expected f8 [n=25, 3] (surface node positions at t_k, world frame), "
       "got f8 [24, 3]", "shape bound by n")
d = Dims()
table.check("lug", "ready", {"cell_xy": np.zeros((6, 2))}, d)
check(d.sizes == {"c": 6}, f"a lug's ready binds c: {d.sizes}")
raises(lambda: table.check("lug", "step", {"d_road": np.zeros(1), "origin": np.zeros(2),
                                           "base": np.zeros(5)}, d),
       "array 'base': expected f8 [c=6]", "shape bound by c")
raises(lambda: table.check("block", "done", {}, Dims()), "missing array 'force': expected f8 [1]",
       "missing array")

# 3. a coupler written here drives the Python participant
ctx = zmq.Context.instance()
router = ctx.socket(zmq.ROUTER)
router.setsockopt(zmq.RCVTIMEO, 10000)
port = router.bind_to_random_port("tcp://127.0.0.1")
child = subprocess.Popen([HERTZ, "--endpoint", f"tcp://127.0.0.1:{port}", "--name", "blk"],
                         stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


def send(typ, step=0, t=0.0, arrays=(), **fields):
    router.send_multipart([b"blk"] + P.encode("coupler", typ, step, t, list(arrays), fields))


def recv():
    frames = router.recv_multipart()
    return P.decode(frames[1:])


hello = recv()
check(hello.type == "hello" and hello.header["role"] == "block" and hello.header["name"] == "blk",
      f"hello: {hello.header}")
send("welcome", config={"exec": "hertz_block.py", "c": 1e9, "damping": 20.0},
     run={"dt": 1e-4, "n_steps": 10, "rollback": True, "idle_timeout_s": 10})
ready = recv()
check(ready.type == "ready" and ready.header["rollback"] is True and
      ready.header["series"] == {"series": ["t", "d_road", "force", "rate"]}, f"ready: {ready.header}")


def step(k, d, it=0):
    send("step", k, (k - 1) * 1e-4, [("d_road", np.array([d]))], dt=1e-4, iteration=it)
    r = recv()
    check(r.type == "done" and r.step == k and r.header["iteration"] == it, f"done {k}: {r.header}")
    return r


a1 = step(1, 1e-5)
send("checkpoint", 1)
st = recv()
check(st.type == "state" and np.array_equal(st["state.d_prev"], [1e-5]), f"checkpoint: {st.arrays}")
a2 = step(2, 3e-5)
b2 = step(2, 3e-5, it=1)
check(np.array_equal(a2["force"], b2["force"]) and np.array_equal(a2["series"], b2["series"]),
      "a repeated step gives the same bits (the state was rolled back)")
c2 = step(2, 2e-5, it=2)
check(c2["series"][3] == (2e-5 - 1e-5) / 1e-4, "the repeat starts from the state of step 1")
send("restore", 1, 0.0, [("state.d_prev", np.array([0.0]))])
check(recv().type == "restored", "restore -> restored")
a3 = step(3, 1e-5)
check(a3["series"][3] == 1e-5 / 1e-4, f"the restored state is used (rate {a3['series'][3]})")
send("stop")
check(recv().type == "bye", "stop -> bye")
out, _ = child.communicate(timeout=10)
check(child.returncode == 0, f"participant exits 0 after bye: {out}")

# --check-config, as cosim check calls it
p = subprocess.run([HERTZ, "--check-config", "-", "--name", "b"], input='{"c": -1}',
                   capture_output=True, text=True)
check(p.returncode == 1 and "processes.b.c: must be >= 0, got -1" in p.stderr,
      f"--check-config names the key: {p.returncode} {p.stderr!r}")
p = subprocess.run([HERTZ, "--check-config", "-"], input='{"c": 1, "grid": {}}',
                   capture_output=True, text=True)
check(p.returncode == 0, f"a stand-in accepts its solver's keys: {p.stderr!r}")
done()
