"""Bad arrays from a Python participant: a wrong dtype or shape, a missing
or unknown array, a series row of the wrong length. The package raises
(ArrayError, in the participant's log) naming the array and its expected
dtype and shape; the coupler gets the same message as an error, stops the
run with exit 3 and names the participant. cosim.run turns that into a
ParticipantError that names it too."""
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "e2e"))
from common import check, done, no_orphans, scene  # noqa: E402

import cosim  # noqa: E402

BAD = os.path.join(HERE, "bad_participant.py")
BLOCK = {"kind": "indentation", "profile": "linear", "depth": 1e-4, "ramp_time": 0.01}
TYRE = {"kind": "tire_travel", "rim_center": [0, 0, 0.3], "sinkage_velocity": 0.1,
        "sinkage_force": 20, "slip": 0.05, "omega": 1.8, "radius": 0.272}
CASES = [  # mode, name, what the message must say
    ("dtype", "block", ["step 2: done (role block): wrong shape or dtype of array 'force': "
                        "expected f8 [1]", "got float32 [1]"]),
    ("shape", "block", ["array 'force': expected f8 [1]", "got f8 [1, 1]"]),
    ("int", "block", ["array 'force': expected f8 [1]", "got i8 [1]"]),
    ("missing", "block", ["step 2: done (role block): missing array 'force': expected f8 [1] "
                          "(total normal contact force"]),
    ("unknown", "block", ["step 2: 'forse' is not an array of role block's done message "
                          "(the role table has: force)"]),
    ("series", "block", ["step 2: series 'series': expected f8 [2] (t, force), got float64 [1]"]),
    ("fem_shape", "tyre", ["array 'x': expected f8 [n=25, 3]", "got f8 [24, 3]"]),
    ("fem_dtype", "tyre", ["array 'v': expected f8 [n=25, 3]", "got float32 [25, 3]"]),
]

for mode, name, needles in CASES:
    if name == "block":
        s = scene(f"bad_{mode}", {"block": {"exec": BAD}}, scenario=BLOCK)
    else:
        s = scene(f"bad_{mode}", {"tyre": {"exec": BAD},
                                  "soil": {"exec": "dem_stub", "force_per_node": [0, 0, 1]}},
                  scenario=TYRE)
    os.environ["BAD_MODE"] = mode
    try:
        cosim.run(s, timeout=60)
        check(False, f"{mode}: the run should fail")
        continue
    except cosim.ParticipantError as e:
        err = e
    check(err.returncode == 3 and err.participant == name,
          f"{mode}: exit 3 naming participant '{name}' ({err.returncode}, {err.participant})")
    check(f"participant '{name}'" in str(err) and "reported an error" in err.stderr,
          f"{mode}: the coupler names the participant: {str(err)[:300]}")
    log = open(os.path.join(s["output"]["dir"], "logs", f"{name}.log")).read()
    check("cosim.errors.ArrayError" in log, f"{mode}: the participant raised ArrayError: {log[-500:]}")
    for n in needles:
        check(n in str(err), f"{mode}: the coupler's message has {n!r}: {str(err)[:400]}")
        check(n in log, f"{mode}: the raised exception has {n!r}")
    no_orphans(s, mode)
done()
