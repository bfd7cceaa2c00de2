"""Bad input: each case gives a clear message naming what is wrong, a
non-zero exit, no hang, and no participant left running."""
import json
import os
import signal
import stat
import subprocess
import time

from common import COSIM, HERE, check, done, no_orphans, remove_run_dirs, run, scene, scratch, write

ROGUE = os.path.join(HERE, "rogue.py")
PY_BLOCK = os.path.join(HERE, "py_block.py")


def block_scene(name, **block):
    b = {"exec": "block_stub", "stiffness": 1e5}
    b.update(block)
    return scene(name, {"block": b}, scenario={"kind": "indentation", "profile": "linear",
                                                "depth": 1e-4, "ramp_time": 0.01})


def expect(name, s, rc_want, needles, cmd="run", text=None, env=None, max_s=20):
    t0 = time.time()
    try:
        rc, out, err = run(s, cmd=cmd, text=text, env=env, timeout=60)
    except subprocess.TimeoutExpired:
        check(False, f"{name}: hung")
        return
    took = time.time() - t0
    check(rc == rc_want, f"{name}: exit {rc}, expected {rc_want}; stderr: {err.strip()[-400:]}")
    for n in needles:
        check(n in err, f"{name}: message lacks {n!r}: {err.strip()[-400:]}")
    check(took < max_s, f"{name}: took {took:.1f} s")
    no_orphans(s, name)


# --- config errors: exit 1, the message names the key path
s = block_scene("badjson")
expect("malformed JSON", s, 1, ["scene.json:3:", "malformed JSON"],
       text='{\n "name": "x",\n "time": {"dt": 1e-3,, "end": 1}\n}')
for cmd in ("run", "check"):
    s = block_scene("unknown"); s["time"]["ned"] = 1
    expect(f"{cmd}: unknown key", s, 1, ["time.ned: unknown key"], cmd=cmd)
    s = block_scene("type"); s["time"]["dt"] = "fast"
    expect(f"{cmd}: wrong type", s, 1, ["time.dt: expected a number"], cmd=cmd)
    s = block_scene("range"); s["output"]["every"] = 0
    expect(f"{cmd}: out of range", s, 1, ["output.every: must be in [1,"], cmd=cmd)
s = block_scene("inner", stiffness=-5)
expect("check: a participant's own key", s, 1, ["processes.block.stiffness: must be in [0,"], cmd="check")
expect("run: a participant's own key", s, 3, ["processes.block.stiffness: must be in [0,",
                                              "failed participant: block"])
s = block_scene("inner2", stifness=5)
s["processes"]["block"] = {"exec": PY_BLOCK, "c": 1e9, "stifness": 5}
expect("run: a typo inside a participant's section", s, 3, ["processes.block.stifness: unknown key"])
# a stub accepts the section of the solver it stands in for, naming what it ignores
s = block_scene("stub_lenient", grid={"nx": 4}, solver={"method": "newton"})
expect("a stub ignores its solver's keys", s, 0, [])
log = open(os.path.join(s["output"]["dir"], "logs", "block.log")).read()
check("ignoring 2 keys" in log and "grid, solver" in log, f"the stub names the keys it ignores: {log!r}")
# the same process name twice, or five times: refused, no crash
for n in (2, 5):
    s = block_scene(f"dup{n}")
    body = ", ".join(['"block": {"exec": "block_stub", "stiffness": 1e5}'] * n)
    text = json.dumps(s).replace('"processes": {"block": {"exec": "block_stub", "stiffness": 100000.0}}',
                                 '"processes": {' + body + '}')
    check(text.count('"block":') == n, "duplicate scene written")
    for cmd in ("run", "check"):
        expect(f"{cmd}: process key given {n} times", s, 1, ["processes.block: duplicate key"],
               cmd=cmd, text=text)
# exec as a list: a non-string element is named
s = block_scene("execlist"); s["processes"]["block"]["exec"] = ["env", 5]
expect("exec list with a number", s, 1, ["processes.block.exec[1]: expected a non-empty string"])
# implicit coupling needs every participant to roll back: py_block cannot
s = block_scene("norollback")
s["processes"]["block"] = {"exec": PY_BLOCK, "c": 1e9}
s["coupling"]["scheme"] = "implicit"
expect("implicit without rollback", s, 1, ["'implicit' repeats steps", "participant 'block'",
                                           "cannot roll back"])
s = block_scene("noexec"); s["processes"]["block"]["exec"] = "no_such_solver"
expect("missing exec", s, 1, ["processes.block.exec: 'no_such_solver' not found"])
expect("check: missing exec", s, 1, ["processes.block.exec: 'no_such_solver' not found"], cmd="check")
d = scratch("cosim-bad-input-")
plain = os.path.join(d, "not_executable")
open(plain, "w").write("#!/bin/sh\n")
os.chmod(plain, stat.S_IRUSR | stat.S_IWUSR)
s = block_scene("nonexec"); s["processes"]["block"]["exec"] = plain
expect("non-executable exec", s, 1, ["processes.block.exec:", "is not an executable file"])
s = block_scene("scen"); s["scenario"] = {"kind": "tire_travel", "sinkage_velocity": 1,
                                           "sinkage_force": 1, "omega": 1}
expect("scenario needs roles", s, 1, ["'tire_travel' needs a process of role dem and one of role fem",
                                      "block (block)"])

# --- participants that misbehave: exit 3, the message names the participant
def rogue(mode, needles, name=None, max_s=20, role="block"):
    s = block_scene(name or mode, )
    s["processes"]["block"] = {"exec": ROGUE}
    s["coupling"] = {"hello_timeout": 2, "handshake_timeout": 2, "step_timeout": 2}
    expect(f"rogue {mode}", s, 3, needles + ["failed participant: block"],
           env={"ROGUE_MODE": mode, "ROGUE_ROLE": role}, max_s=max_s)


rogue("crash", ["participant 'block'", "exited with status 3", "crashing on purpose"])
rogue("segv", ["participant 'block'", "signal 11"])
rogue("silent", ["no hello within 2 s", "block"])
rogue("mute", ["participant 'block' did not answer within"])
rogue("version", ["protocol version mismatch", "participant 'block'"])
rogue("truncated", ["needs 240 bytes, frame has 17", "participant 'block'"])
rogue("oversized", ["exceeds the limit", "participant 'block'"])
rogue("role", ["participant 'block': hello with unknown role blob"])
rogue("nan", ["participant 'block': force[0] is not finite", "step 3"])
rogue("crash_step", ["participant 'block'", "exited with status 5", "crashing at the first step"])

# --- Ctrl-C during a long run: exit 130, everyone stopped, results kept
s = block_scene("sigint")
s["time"] = {"dt": 1e-3, "end": 1e6}
s["output"]["every"] = 100
p = subprocess.Popen([COSIM, "run", write(s)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
time.sleep(1.5)
p.send_signal(signal.SIGINT)
try:
    out, err = p.communicate(timeout=20)
    check(p.returncode == 130, f"Ctrl-C: exit {p.returncode}, expected 130 ({err[-300:]})")
    check("interrupted" in err, f"Ctrl-C: message says interrupted ({err[-300:]})")
except subprocess.TimeoutExpired:
    p.kill()
    check(False, "Ctrl-C: cosim did not stop")
no_orphans(s, "Ctrl-C")
import h5py
with h5py.File(os.path.join(s["output"]["dir"], "results.h5"), "r") as f:
    rows = f["/block/series"].shape[0]
    check(rows >= 100, f"Ctrl-C: rows written before the interrupt are kept ({rows})")

# --- the launcher killed hard: its children die with it (no orphans)
s = block_scene("sigkill")
s["time"] = {"dt": 1e-3, "end": 1e6}
p = subprocess.Popen([COSIM, "run", write(s)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
time.sleep(1.0)
p.kill()
p.wait()
no_orphans(s, "launcher killed with SIGKILL")
remove_run_dirs(s)
done()
