"""Liveness of a Python participant, as PROTOCOL.md's liveness rules say,
driven by a coupler written here:

1. with the role table of this build: when it lists no heartbeat message the
   hello promises none and none are sent (the coupler of this build would
   not know them);
2. with a table that lists 'heartbeat' (COSIM_ROLES): the hello promises
   heartbeat_s, and from hello to bye the participant is never silent for
   longer than that -- while it waits for the welcome, during a silent init
   (phase init), during a silent step (phase step, its number), while idle;
   p.progress() reaches the coupler (fraction, printable text);
3. run.idle_timeout_s 0 (what the coupler sends a participant it launched) means
   never give up on silence: a request that comes 0.5 s after the last is served.
"""
import json
import os
import subprocess
import sys
import time

import zmq

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "e2e"))
from common import COSIM, check, done, scratch  # noqa: E402

from cosim import protocol as P  # noqa: E402

SLOW = os.path.join(HERE, "slow_participant.py")
table = json.loads(subprocess.run([COSIM, "roles", "--json"], capture_output=True,
                                  text=True).stdout)


def drive(env, welcome_delay, idle_timeout=20, gap=0.0):
    """Runs the slow participant against a ROUTER here; returns the
    messages it sent with their arrival times."""
    router = zmq.Context.instance().socket(zmq.ROUTER)
    router.setsockopt(zmq.LINGER, 0)
    port = router.bind_to_random_port("tcp://127.0.0.1")
    child = subprocess.Popen([SLOW, "--endpoint", f"tcp://127.0.0.1:{port}", "--name", "blk"],
                             env=dict(os.environ, **env), stdout=subprocess.PIPE,
                             stderr=subprocess.STDOUT, text=True)
    got = []

    def recv_until(typ, timeout=10):
        """Receives (time-stamping each message as it comes) until a
        message of type typ; typ None: for timeout seconds."""
        until = time.monotonic() + timeout
        while time.monotonic() < until:
            if router.poll(10):
                m = P.decode(router.recv_multipart()[1:])
                got.append((time.monotonic(), m))
                if m.type == typ:
                    return m
        if typ:
            raise TimeoutError(f"no {typ}")

    def send(typ, step=0, t=0.0, arrays=(), **fields):
        router.send_multipart([b"blk"] + P.encode("coupler", typ, step, t, list(arrays), fields))

    try:
        recv_until("hello")
        recv_until(None, welcome_delay)  # the coupler waits for others' hellos
        send("welcome", config={"exec": "slow"}, run={"dt": 1e-3, "n_steps": 2, "idle_timeout_s": idle_timeout})
        recv_until("ready")
        import numpy as np
        for k in (1, 2):
            recv_until(None, gap if k == 2 else 0)  # the coupler busy with other participants
            send("step", k, (k - 1) * 1e-3, [("d_road", np.zeros(1))], dt=1e-3)
            recv_until("done")
        recv_until(None, 1.2 if welcome_delay else 0)  # idle between requests
        send("stop")
        recv_until("bye")
    except TimeoutError as e:
        check(False, f"{e}: {[m.type for _, m in got]}")
    out, _ = child.communicate(timeout=10)
    check(child.returncode == 0, f"participant ok: {out[-300:]}")
    router.close()
    return got


# 1. this build's table
got = drive({"SILENT_S": "0.1"}, 0.0)
has_beats = any(m["type"] == "heartbeat" for m in table["messages"])
hello = got[0][1]
if not has_beats:
    check("heartbeat_s" not in hello.header, f"no heartbeats promised: {hello.header}")
    check(all(m.type != "heartbeat" for _, m in got), "none sent")
else:
    check(hello.header.get("heartbeat_s") == P.HEARTBEAT_S, "this build's table has heartbeats")

# 2. a table with heartbeats
if not has_beats:
    table["messages"].append({"type": "heartbeat", "direction": "participant->coupler"})
path = os.path.join(scratch("cosim-roles-"), "roles.json")
with open(path, "w") as f:
    json.dump(table, f)
got = drive({"COSIM_ROLES": path}, 1.5)
types = [m.type for _, m in got]
check(got[0][1].header.get("heartbeat_s") == P.HEARTBEAT_S, f"hello promises heartbeat_s: {got[0][1].header}")
gaps = [b[0] - a[0] for a, b in zip(got, got[1:])]
# beats go every HEARTBEAT_S / 2; the coupler's default heartbeat_timeout is
# 2 HEARTBEAT_S (coupler/scene.c), the silence it must never see. A process
# descheduled on a loaded machine may go quiet past HEARTBEAT_S itself (seen
# at load 6 on 2 cores), so the bound checked is the coupler's.
check(max(gaps) < 2 * P.HEARTBEAT_S, f"never silent for the coupler's heartbeat_timeout "
      f"{2 * P.HEARTBEAT_S} s from hello to bye (longest {max(gaps):.2f} s)")
beats = [m for _, m in got if m.type == "heartbeat"]
phases = {m.header["phase"] for m in beats}
check({"welcome", "init", "step", "idle"} <= phases, f"heartbeats in every phase: {sorted(phases)}")
check(any(m.header["phase"] == "step" and m.step == 1 for m in beats), "a step's heartbeat names it")
prog = [m.header for m in beats if "progress" in m.header]
check(prog and prog[0]["progress"] == 0.5 and prog[0]["what"] == "half way there",
      f"progress reaches the coupler, printable: {prog[:1]}")
check(types[-1] == "bye" and "ready" in types and types.count("done") == 2, f"the run: {types}")
# 3. idle_timeout_s 0: no limit (it gave up after one 100 ms poll: a loaded machine's
# coupler, busy with another participant for longer, saw "Host unreachable")
got = drive({"SILENT_S": "0.1"}, 0.0, idle_timeout=0, gap=0.5)
check([m.type for _, m in got].count("done") == 2, "idle_timeout_s 0: both steps served "
      f"after a 0.5 s silence: {[m.type for _, m in got]}")
print(f"liveness: {len(beats)} heartbeats, phases {sorted(phases)}, longest silence {max(gaps):.2f} s")
done()
