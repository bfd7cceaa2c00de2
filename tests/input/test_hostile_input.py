"""Hostile input end to end (issue 11): a scene, a participant's wire
messages, and the files the participants read. Each case is refused with
exit 1 (a bad scene or file) or 3 (a participant that lied), a message that
names the key path / array / file and position, no escape sequence on the
terminal, and no process left behind."""
import json
import os
import subprocess
import sys

import h5py
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "e2e"))
from common import BIN, COSIM, check, done, no_orphans, run, scene, scratch, write  # noqa: E402

HOSTILE = os.path.join(HERE, "hostile.py")
FUZZ_CORPUS = os.path.join(HERE, "..", "fuzz", "corpus")


def block_scene(name, **block):
    b = {"exec": "block_stub", "stiffness": 1e5}
    b.update(block)
    return scene(name, {"block": b}, scenario={"kind": "indentation", "profile": "linear",
                                                "depth": 1e-4, "ramp_time": 0.01})


def expect(name, s, rc_want, needles, *args, cmd="run", text=None, env=None):
    try:
        rc, out, err = run(s, *args, cmd=cmd, text=text, env=env, timeout=60)
    except subprocess.TimeoutExpired:
        check(False, f"{name}: hung")
        return ""
    check(rc == rc_want, f"{name}: exit {rc}, expected {rc_want}; stderr: {err.strip()[-400:]}")
    for n in needles:
        check(n in err, f"{name}: message lacks {n!r}: {err.strip()[-400:]}")
    check("\x1b" not in err and "\x1b" not in out, f"{name}: an escape sequence reached the terminal")
    no_orphans(s, name)
    return err


def dup_text(s, old, new):
    """The scene as JSON text with `old` (a JSON fragment) replaced: how a key
    given twice gets into a file (json.dumps cannot write one)."""
    text = json.dumps(s)
    check(old in text, f"fragment {old!r} in the scene")
    return text.replace(old, new, 1)


# --- a key given twice, anywhere: exit 1, "duplicate", the key path
for n in (2, 5):
    s = block_scene(f"dup{n}")
    body = ", ".join(['"block": {"exec": "block_stub", "stiffness": 100000.0}'] * n)
    text = dup_text(s, '"processes": {"block": {"exec": "block_stub", "stiffness": 100000.0}}',
                    '"processes": {' + body + '}')
    for cmd in ("run", "check"):
        expect(f"{cmd}: process key given {n} times", s, 1,
               ["processes.block: duplicate key", f"given {n} times"], cmd=cmd, text=text)
s = block_scene("dupcore")
text = dup_text(s, '"time": {', '"time": {"dt": 1, "end": 2}, "time": {')
expect("a core key twice", s, 1, ["scene.json: time: duplicate key"], cmd="check", text=text)
s = block_scene("dupnested")
text = dup_text(s, '"handshake_timeout": 5', '"handshake_timeout": 5, "handshake_timeout": 6')
expect("a nested key twice", s, 1, ["coupling.handshake_timeout: duplicate key"], cmd="check",
       text=text)
s = block_scene("dupsection")
text = dup_text(s, '"stiffness": 100000.0', '"stiffness": 100000.0, "stiffness": 5')
expect("a key twice inside a process section", s, 1,
       ["processes.block.stiffness: duplicate key"], text=text)
s = block_scene("duplist", scenario={"kind": "none"})
s["processes"]["block"] = {"exec": "contact_block", "grid": {"nx": 4, "ny": 4}}
text = dup_text(s, '"nx": 4', '"nx": 4, "nx": 8')
expect("a key twice in a participant's own section", s, 1,
       ["processes.block.grid.nx: duplicate key"], cmd="check", text=text)
# a participant alone: --check-config refuses it as well
d = scratch("cosim-hostile-")
for exe in ("block_stub", "contact_block", "dem_server", "fem_server", "dem_stub", "fem_stub"):
    path = os.path.join(d, f"{exe}.json")
    with open(path, "w") as f:
        f.write('{"exec": "x", "a": {"b": 1, "b": 2}}')
    p = subprocess.run([os.path.join(BIN, exe), "--check-config", path, "--name", "p"],
                       capture_output=True, text=True, timeout=60)
    check(p.returncode == 1 and "a.b: duplicate key" in p.stderr,
          f"{exe} --check-config with a duplicate key: exit {p.returncode}, {p.stderr.strip()!r}")

# --- --set: strings stay strings
s = block_scene("setdir")
base = os.path.dirname(s["output"]["dir"])
os.chdir(base)
rc, out, err = run(s, "--set", "output.dir=2024/run1", "--quiet")
check(rc == 0, f"--set output.dir=2024/run1: exit {rc}: {err[-300:]}")
check(os.path.exists(os.path.join(base, "2024", "run1", "results.h5")),
      "--set output.dir=2024/run1 writes into the directory 2024/run1")
rc, out, err = run(s, "--set", "output.dir=2024", "--quiet")
check(rc == 0 and os.path.exists(os.path.join(base, "2024", "results.h5")),
      f"--set output.dir=2024 (the scene has a string there) is the directory '2024': {err[-300:]}")
expect("--set output.dir:=2024 (JSON: a number)", s, 1,
       ["output.dir: expected a string, got the number 2024"], "--set", "output.dir:=2024")
expect("--set KEY:=not-json", s, 1, ["is not one JSON value"], "--set", "time.end:=0.5x")
expect("--set time.end=fast", s, 1, ["time.end: expected a number, got a string"],
       "--set", "time.end=fast", cmd="check")
expect("--set into a list that is not one", s, 1, ["index out of range or not a list"],
       "--set", "time[0]=1", cmd="check")

# --- scene names: one grammar
for bad, needle in (("a/b", "contains '/'"), ("..", "contains a character"), ("x\u001b[2J", "contains a character")):
    s = block_scene("names")
    s["processes"] = {bad: {"exec": "block_stub", "stiffness": 1e5}}
    expect(f"process name {bad!r}", s, 1, ["processes: process name", needle], cmd="check")
s = block_scene("reserved")
s["processes"] = {"coupler": {"exec": "block_stub", "stiffness": 1e5}}
expect("process name 'coupler'", s, 1, ["processes.coupler: the name is reserved"], cmd="check")


# --- a participant that lies on the wire: exit 3, named, no escape sequence
def hostile(mode, needles, rc=3):
    s = block_scene("hostile_" + mode)
    s["processes"]["block"] = {"exec": HOSTILE}
    s["coupling"] = {"handshake_timeout": 3, "step_timeout": 3, "hello_timeout": 3}
    err = expect(f"hostile {mode}", s, rc, needles, env={"HOSTILE_MODE": mode})
    return s, err


hostile("version19", ["protocol version mismatch: peer speaks v1.9", "participant 'block'"])
hostile("dup_header", ["header.role: duplicate key", "participant 'block'"])
hostile("topic_nul", ["topic contains a NUL byte", "participant 'block'"])
s, _ = hostile("no_series", ["participant 'block'", "missing array 'series' (f8 [2])",
                             "ready declared the series dataset 'series'",
                             "failed participant: block"])
with h5py.File(os.path.join(s["output"]["dir"], "results.h5"), "r") as f:
    check(f["/block/series"].shape[0] == 1, "no_series: the rows before the bad step are kept")
s, _ = hostile("series_path", ["ready.series: dataset '../../coupler/series'", "participant 'block'"])
res = os.path.join(s["output"]["dir"], "results.h5")
if os.path.exists(res):  # a run that fails in the handshake leaves no results file
    with h5py.File(res, "r") as f:
        names = []
        f.visit(names.append)
        check(not any(".." in n for n in names), f"series_path: no group named '..' ({names})")
hostile("array_slash", ["arrays[2].name 'snap/../x': contains '/'", "participant 'block'"])
_, err = hostile("esc_error", ["participant 'block'", "reported an error: bad things?]0;owned??[2J?[31m happened"])
hostile("iteration", ["header field 'iteration' must be an integer", "participant 'block'"])
# a stranger's messages are logged (terminal-safe) and ignored; the process
# that should have said hello is then named
_, err = hostile("esc_identity", ["ignoring a message from '?]0;owned??[2J?[31mblock'",
                                  "no hello within 3 s (coupling.hello_timeout) from: block"])


# --- files the participants read: exit 1, the file and the object or line named
def check_config(exe, section, needles, name):
    path = os.path.join(d, name + ".json")
    with open(path, "w") as f:
        json.dump(section, f)
    try:
        p = subprocess.run([os.path.join(BIN, exe), "--check-config", path, "--name", "p"],
                           capture_output=True, text=True, timeout=60)
    except subprocess.TimeoutExpired:
        check(False, f"{name}: {exe} --check-config hung")
        return
    check(p.returncode == 1, f"{name}: exit {p.returncode}, expected 1 ({p.stderr.strip()[-300:]})")
    for n in needles:
        check(n in p.stderr, f"{name}: message lacks {n!r}: {p.stderr.strip()[-300:]}")


def h5file(name, build):
    path = os.path.join(d, name + ".h5")
    with h5py.File(path, "w") as f:
        build(f)
    return path


block = {"exec": "contact_block", "grid": {"nx": 4, "ny": 3, "dx": 1e-3, "dy": 1e-3},
         "road": {"kind": "paraboloid", "radius": 0.05}, "springs": {"kind": "linear", "k": 1e5}}


def green_huge(f):
    g = f.create_group("green")
    g.create_dataset("static", shape=(5, 7), dtype="f8")
    g.create_dataset("g", shape=(10**9, 5, 7), dtype="f8", chunks=(1, 5, 7))  # no storage
    g.attrs["rate"] = 51200.0


def green_attr_array(f):
    g = f.create_group("green")
    g.create_dataset("static", data=np.ones((5, 7)))
    g.attrs["rate"] = np.zeros(1000)


def green_shape(f):
    f.create_group("green").create_dataset("static", data=np.ones((21, 19)))


def green_nan(f):
    st = np.ones((5, 7))
    st[2, 3] = np.nan
    f.create_group("green").create_dataset("static", data=st)


for name, build, needles in (
        ("green_huge", green_huge, ["/green/g: shape [1000000000,5,7] holds more than"]),
        ("green_attr_array", green_attr_array, ["attribute rate must hold one value (it holds 1000)"]),
        ("green_shape", green_shape, ["offset grid", "/green/static: shape [21,19], expected [5,7]"]),
        ("green_nan", green_nan, ["/green/static: element [2][3] is nan"])):
    sec = dict(block, green={"kind": "file", "file": h5file(name, build)})
    check_config("contact_block", sec, [name + ".h5"] + needles, name)


def springs_knots(f):
    g = f.create_group("springs")
    for k in ("d", "F", "k"):
        g.create_dataset(k, shape=(12, 10**8), dtype="f8", chunks=(1, 1024))


sec = dict(block, green={"kind": "halfspace", "E": 2.5e7, "nu": 0.49},
           springs={"kind": "file", "file": h5file("springs_knots", springs_knots)})
check_config("contact_block", sec, ["springs_knots.h5:/springs/d: shape [12,100000000] holds more than",
                                    "2 <= K <= 65536 knots"], "springs_knots")


def bed_rank3(f):
    f.create_dataset("r", data=np.ones((2, 2, 2)))
    f.create_dataset("x", data=np.zeros((2, 3)))


def bed_short_x(f):
    f.create_dataset("r", data=np.full(4, 0.01))
    f.create_dataset("x", data=np.zeros((3, 3)))


dem = {"exec": "dem_server", "materials": [{"density": 2600, "E": 1e7, "nu": 0.3, "restitution": 0.5,
                                            "friction": 0.5}],
       "walls": [{"type": "box", "lo": [0, 0, 0], "hi": [1, 1, 1]}]}
check_config("dem_server", dict(dem, particles={"file": h5file("bed_rank3", bed_rank3)}),
             ["bed_rank3.h5:r: has 3 dimension(s), expected 1", "particles.file"], "bed_rank3")
check_config("dem_server", dict(dem, particles={"file": h5file("bed_short_x", bed_short_x)}),
             ["bed_short_x.h5:x: shape [3,3], expected [4,3]"], "bed_short_x")

fem = {"exec": "fem_server", "material": {"E": 2e7, "nu": 0.45, "density": 1100}}
huge = os.path.join(FUZZ_CORPUS, "fuzz_msh", "regress_oom_node_count_6.8GB")
check_config("fem_server", dict(fem, mesh={"file": huge}),
             ["regress_oom_node_count_6.8GB", "section $Nodes", "does not fit in the"], "msh_huge")
check_config("fem_server", dict(fem, mesh={"generate": "bar", "cells": [100000, 100000, 100000]}),
             ["processes.p.mesh.cells: 100000 x 100000 x 100000 cells make more than"], "fem_cells")
bad_msh = os.path.join(d, "bad.msh")
with open(bad_msh, "w") as f:
    f.write("$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 2 1 2\n3 1 0 2\n1\n2\n0 0 0\n"
            "1 0 nan\n$EndNodes\n")
check_config("fem_server", dict(fem, mesh={"file": bad_msh}),
             ["bad.msh:10: section $Nodes: a coordinate is not a finite number"], "msh_nan")
with open(bad_msh, "w") as f:
    f.write("$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 1 1 1\n3 1 0 1\n1\n0 0 0\n$EndNodes\n"
            "$Nodes\n")
check_config("fem_server", dict(fem, mesh={"file": bad_msh}),
             ["section $Nodes: the section appears twice"], "msh_twice")


# cosim road --from: the road readers
def road_run(path, needles, name):
    out = os.path.join(d, "road_out.h5")
    p = subprocess.run([COSIM, "road", "--from", path, "--out", out], capture_output=True,
                       text=True, timeout=60)
    check(p.returncode == 1, f"{name}: exit {p.returncode} ({p.stderr.strip()[-300:]})")
    for n in needles:
        check(n in p.stderr, f"{name}: message lacks {n!r}: {p.stderr.strip()[-300:]}")


def road_huge(f):
    g = f.create_group("road")
    g.create_dataset("heights", shape=(10**6, 10**6), dtype="f8", chunks=(64, 64))
    g.attrs["dx"] = 1e-5
    g.attrs["dy"] = 1e-5


def road_text_attr(f):
    g = f.create_group("road")
    g.create_dataset("heights", data=np.zeros((4, 4)))
    g.attrs["dx"] = "1e-5"
    g.attrs["dy"] = 1e-5


road_run(h5file("road_huge", road_huge), ["road_huge.h5:/road/heights: shape [1000000,1000000] holds more"],
         "road_huge")
road_run(h5file("road_text_attr", road_text_attr), ["road_text_attr.h5:/road: attribute dx must be a number"],
         "road_text_attr")
txt = os.path.join(d, "road.txt")
with open(txt, "w") as f:
    f.write("# dx = inf\n# dy = 1e-5\n0 1\n2 3\n")
road_run(txt, ["road.txt: pitch dx = inf"], "road_text_inf")
with open(txt, "w") as f:
    f.write("# dx = 1e-5\n# dy = 1e-5\n0 1 2\n2 3\n")
road_run(txt, ["road.txt:4: 2 values, previous rows had 3"], "road_text_ragged")
done()
