"""Rollback and checkpoints, participant by participant, over the real
protocol (PROTOCOL.md "Repeating a step", "Checkpoints"): this script plays
the coupler for one participant at a time and checks that
- ready says whether it can roll back;
- a repeat of step k (iteration >= 1) starts from the state of the start of
  step k: repeating with the first inputs gives the first reply bit for bit,
  even after a repeat with other inputs;
- checkpoint -> state arrays, a step, restore -> the same step again gives
  the same bits (the state arrays are its whole changing state);
- (in test_bad_input: a participant without state_save/state_load makes
  the coupler refuse the implicit scheme by name).
contact_block is taken past blocks of its partitioned history convolution,
whose delay lines are part of its state."""
import json
import os
import subprocess

import numpy as np
import zmq

from common import BIN, HERE, check, done, scratch
from ref_coupler import _recv, _send

ROOT = os.path.dirname(os.path.dirname(HERE))


def start(exe, section, dt, n_steps, rollback=True):
    d = scratch("cosim-state-")
    ep = f"ipc://{d}/control"
    ctx = zmq.Context()
    sock = ctx.socket(zmq.ROUTER)
    sock.bind(ep)
    log = open(os.path.join(d, "log"), "w")
    proc = subprocess.Popen([os.path.join(BIN, exe), "--endpoint", ep, "--name", "p"],
                            stdout=log, stderr=log)
    _recv(sock)
    info = {"name": "state", "dt": dt, "t_end": n_steps * dt, "n_steps": n_steps,
            "output_every": n_steps, "output_dir": d, "bus": "", "deadline_s": 60,
            "idle_timeout_s": 120, "rollback": rollback}
    return ctx, sock, proc, info, d


def step(sock, k, dt, arrays, iteration=0):
    extra = {"iteration": iteration} if iteration else {}
    _send(sock, "p", "step", k, (k - 1) * dt, arrays, dt=dt, output=False, **extra)
    _, h, a = _recv(sock)
    check(h["type"] == "done" and h["step"] == k and h.get("iteration", 0) == iteration,
          f"done for step {k} iteration {iteration}")
    check(h.get("compute_s", -1) >= 0, "done carries compute_s")
    return {n: v.copy() for n, v in a.items()}


def same(a, b):
    return a.keys() == b.keys() and all(np.array_equal(a[n], b[n]) for n in a)


def exercise(label, exe, section, dt, inputs, warmup, welcome_arrays=(), stateless=False):
    ctx, sock, proc, info, d = start(exe, section, dt, warmup + 10)
    try:
        _send(sock, "p", "welcome", arrays=list(welcome_arrays), config=section, run=info)
        _, h, ready = _recv(sock)
        check(h.get("rollback") is True, f"{label}: ready says rollback: true")
        for k in range(1, warmup + 1):
            step(sock, k, dt, inputs(k, 0))
        k = warmup + 1
        first = step(sock, k, dt, inputs(k, 0))
        other = step(sock, k, dt, inputs(k, 1), iteration=1)
        again = step(sock, k, dt, inputs(k, 0), iteration=2)
        check(not same(first, other), f"{label}: other inputs give another reply (the test bites)")
        check(same(first, again), f"{label}: a repeat of step {k} restarts from its start state")
        nxt = step(sock, k + 1, dt, inputs(k + 1, 0))
        _send(sock, "p", "checkpoint", k + 1, (k + 1) * dt)
        _, h, state = _recv(sock)
        check(h["type"] == "state" and (stateless or state) and all(n.startswith("state.") for n in state),
              f"{label}: checkpoint -> state arrays {sorted(state)[:6]}")
        state = {n: v.copy() for n, v in state.items()}
        r1 = step(sock, k + 2, dt, inputs(k + 2, 0))
        step(sock, k + 3, dt, inputs(k + 3, 1))
        _send(sock, "p", "restore", k + 1, (k + 1) * dt,
              [(n, v) for n, v in state.items()])
        _, h, _ = _recv(sock)
        check(h["type"] == "restored", f"{label}: restore -> restored")
        r2 = step(sock, k + 2, dt, inputs(k + 2, 0))
        check(same(r1, r2), f"{label}: restored state gives the same step {k + 2}")
        _send(sock, "p", "stop")
        _recv(sock)
        check(proc.wait(timeout=30) == 0, f"{label}: exits 0 after stop")
        del nxt
    finally:
        if proc.poll() is None:
            proc.kill()
        sock.close(linger=0)
        ctx.term()


rng = np.random.default_rng(5)

# fem_server: a small free slab, random nodal forces
slab = {"exec": "fem_server", "mesh": {"generate": "slab", "size": [0.06, 0.06, 0.02], "cells": [3, 3, 1]},
        "element": "tet4", "material": {"E": 2e6, "nu": 0.3, "density": 1100, "damping": 5},
        "initial_static": False, "surface": "zmax"}
N_SLAB = 16
forces = rng.normal(size=(40, 2, N_SLAB, 3))
rim = [("rim_R", np.eye(3)), ("rim_c", np.zeros(3)), ("rim_omega", np.zeros(3)), ("rim_v", np.zeros(3))]
exercise("fem_server", "fem_server", slab, 1e-4,
         lambda k, v: [("nodal_force", forces[k, v])] + rim, warmup=5)

# contact_block: the default tread-block scene's block, past history blocks
block = json.load(open(os.path.join(ROOT, "configs", "tread_block.json")))["processes"]["block"]
dtb = 1.953125e-5
ramp = lambda k, v: [("d_road", np.array([2e-4 * min(k / 60, 1.0) * (1.0 + 0.1 * v)]))]
exercise("contact_block", "contact_block", block, dtb, ramp, warmup=37)
# the matrix-free solver (no kept factor) and the direct history ring
cg = json.loads(json.dumps(block))
cg["solver"].update({"method": "constrained_cg", "history": "direct"})
exercise("contact_block (cg, direct)", "contact_block", cg, dtb, ramp, warmup=21)

# the stubs
exercise("block_stub", "block_stub", {"exec": "block_stub", "stiffness": 1e5}, 1e-3,
         lambda k, v: [("d_road", np.array([1e-5 * k + 1e-6 * v]))], warmup=2)
plane = {"exec": "fem_stub", "surface": {"plane": {"size": [0.1, 0.1], "n": [2, 2], "z": 0}}}
# fem_stub's outputs depend on the rim frame only
rims = [[("nodal_force", np.zeros((9, 3))), ("rim_R", np.eye(3)), ("rim_c", np.array([0, 0, 1e-3 * k + v])),
         ("rim_omega", np.zeros(3)), ("rim_v", np.zeros(3))] for k in range(40) for v in (0, 1)]
exercise("fem_stub", "fem_stub", plane, 1e-3, lambda k, v: rims[2 * k + v], warmup=2, stateless=True)

# dem_stub: its force depends on t only: same inputs or not, the same reply;
# a repeat must still be accepted and answered
x0 = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype=float)
tri = np.array([[0, 1, 2]], dtype=np.int32)
ctx, sock, proc, info, d = start("dem_stub", {"exec": "dem_stub", "force_per_node": [0, 0, 1],
                                              "ramp_time": 0.01}, 1e-3, 10)
_send(sock, "p", "welcome", arrays=[("surface_x0", x0), ("surface_tri", tri)],
      config={"exec": "dem_stub", "force_per_node": [0, 0, 1], "ramp_time": 0.01}, run=info)
_, h, _ = _recv(sock)
check(h.get("rollback") is True, "dem_stub: ready says rollback: true")
a = step(sock, 1, 1e-3, [("x", x0), ("v", np.zeros((3, 3)))])
b = step(sock, 1, 1e-3, [("x", x0 + 1), ("v", np.zeros((3, 3)))], iteration=1)
check(same(a, b), "dem_stub: a repeat answers with the same prescribed force")
_send(sock, "p", "stop")
_recv(sock)
proc.wait(timeout=30)
sock.close(linger=0)
ctx.term()

# dem_server: grains pressed by a coupled surface, with sliding contacts
# and the mesh moving (its contact springs, neighbour lists and the mesh
# nodes are part of its state)
xs = np.array([[-0.05, -0.05, 0.0], [0.05, -0.05, 0.0], [-0.05, 0.05, 0.0], [0.05, 0.05, 0.0]])
ts = np.array([[0, 1, 2], [1, 3, 2]], dtype=np.int32)
pile = [{"x": [0.012 * i - 0.018, 0.012 * j - 0.018, 0.0055 + 0.0115 * lay], "r": 0.006, "material": 0}
        for i in range(4) for j in range(4) for lay in range(2)]
grains = {"exec": "dem_server", "materials": [{"density": 2600, "E": 5e6, "nu": 0.3, "restitution": 0.5,
                                               "friction": 0.5}],
          "particles": pile, "gravity": [0, 0, -9.81], "overlap_tolerance": 0.1,
          "walls": [{"type": "plane", "point": [0, 0, -0.002], "normal": [0, 0, 1]}]}
moves = [[("x", xs + [0, 0, 0.0229 - 1e-5 * k - 2e-6 * v]), ("v", np.tile([1e-3 * v, 0, -0.1], (4, 1)))]
         for k in range(60) for v in (0, 1)]
exercise("dem_server", "dem_server", grains, 1e-4, lambda k, v: moves[2 * k + v], warmup=12,
         welcome_arrays=[("surface_x0", xs + [0, 0, 0.0229]), ("surface_tri", ts)])
done()
