"""An independent coupler for tests, written from PROTOCOL.md: it runs one
dem and one fem process in the staggered ordering cosim had before its
schemes became data (the dem on the surface of t_{k-1}, its nodal forces to
the fem in the same step, scenario "none": the rim frame at rest at the
origin), and returns the processes' series rows. A test compares them with
`cosim run` (scheme serial): the same participants given the same inputs
must give the same bits."""
import json
import os
import subprocess

import numpy as np
import zmq

from common import scratch

DTYPES = {"f8": "<f8", "i4": "<i4", "i8": "<i8", "u1": "u1"}
CODES = {np.dtype("<f8"): "f8", np.dtype("<i4"): "i4", np.dtype("<i8"): "i8", np.dtype("u1"): "u1"}


def _send(sock, name, type_, step=0, t=0.0, arrays=(), **extra):
    h = {"v": 1, "type": type_, "step": step, "t": t,
         "arrays": [{"name": n, "dtype": CODES[a.dtype], "shape": list(a.shape)}
                    for n, a in arrays]}
    h.update(extra)
    sock.send_multipart([name.encode(), name.encode(), json.dumps(h).encode()] +
                        [np.ascontiguousarray(a).tobytes() for _, a in arrays])


def _recv(sock, timeout_ms=60000):
    while True:  # heartbeats (PROTOCOL.md "Liveness") come whenever a participant is
        if not sock.poll(timeout_ms):  # silent for a while: on a loaded machine, any time
            raise RuntimeError("reference coupler: no reply")
        frames = sock.recv_multipart()
        ident, h = frames[0].decode(), json.loads(frames[2])
        if h["type"] != "heartbeat":
            break
    arrays = {a["name"]: np.frombuffer(fr, dtype=DTYPES[a["dtype"]]).reshape(a["shape"])
              for a, fr in zip(h["arrays"], frames[3:])}
    if h["type"] == "error":
        raise RuntimeError(f"{ident}: {h.get('message')}")
    return ident, h, arrays


def run(bin_dir, dem_section, fem_section, dt, n_steps):
    """Runs the old serial loop; returns (dem rows, fem rows) as arrays."""
    run_dir = scratch("cosim-ref-")
    ep = f"ipc://{run_dir}/control"
    ctx = zmq.Context()
    sock = ctx.socket(zmq.ROUTER)
    sock.bind(ep)
    procs = {}
    for name, sec in (("fem", fem_section), ("dem", dem_section)):
        log = open(os.path.join(run_dir, name + ".log"), "w")
        procs[name] = subprocess.Popen([os.path.join(bin_dir, sec["exec"]), "--endpoint", ep,
                                        "--name", name], stdout=log, stderr=log)
    try:
        for _ in range(2):
            ident, h, _ = _recv(sock)
            assert h["type"] == "hello", h
        info = {"name": "ref", "dt": dt, "t_end": n_steps * dt, "n_steps": n_steps,
                "output_every": n_steps, "output_dir": run_dir, "bus": "",
                "deadline_s": 60, "idle_timeout_s": 600}
        _send(sock, "fem", "welcome", config=fem_section, run=info)
        _, h, ready = _recv(sock)
        x0 = ready["surface_x0"].copy()
        tri = ready["surface_tri"].copy()
        _send(sock, "dem", "welcome", arrays=[("surface_x0", x0), ("surface_tri", tri)],
              config=dem_section, run=info)
        _recv(sock)
        x, v, force = x0.copy(), np.zeros_like(x0), np.zeros_like(x0)
        R, c, w, vr = np.eye(3), np.zeros(3), np.zeros(3), np.zeros(3)
        dem_rows, fem_rows = [], []
        for k in range(1, n_steps + 1):
            t0 = (k - 1) * dt
            _send(sock, "dem", "step", k, t0, [("x", x), ("v", v)], dt=dt, output=False)
            _, h, a = _recv(sock)
            force = a["nodal_force"].copy()
            dem_rows.append(a["series"].copy())
            _send(sock, "fem", "step", k, t0, [("nodal_force", force), ("rim_R", R),
                                              ("rim_c", c), ("rim_omega", w), ("rim_v", vr)],
                  dt=dt, output=False)
            _, h, a = _recv(sock)
            x, v = a["x"].copy(), a["v"].copy()
            fem_rows.append(a["series"].copy())
        for name in ("dem", "fem"):
            _send(sock, name, "stop")
            _recv(sock)
        return np.array(dem_rows), np.array(fem_rows)
    finally:
        for p in procs.values():
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                p.kill()
        sock.close(linger=0)
        ctx.term()
