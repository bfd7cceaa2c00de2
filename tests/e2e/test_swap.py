"""Swapping one exec gives the other participant's result: the same block
scene with block_stub (linear spring) and with py_block.py (a Hertzian spring
written in Python from PROTOCOL.md alone), via --set."""
import os

import numpy as np

from common import HERE, check, done, h5, no_orphans, run, scene

s = scene("swap", {"block": {"exec": "block_stub", "stiffness": 2e5}},
          scenario={"kind": "indentation", "profile": "linear", "depth": 2e-4,
                    "ramp_time": 0.04})
rc, out, err = run(s)
check(rc == 0, f"block_stub run ok ({err})")
d = np.minimum(np.arange(1, 51) * 1e-3 / 0.04, 1.0) * 2e-4
lin = h5(s)["/block/series"][:]
check(np.allclose(lin[:, 1], d, rtol=1e-12), "road displacement follows the linear profile")
check(np.allclose(lin[:, 2], 2e5 * d, rtol=1e-12), "linear spring force")

py = os.path.join(HERE, "py_block.py")
s["output"]["dir"] += "_py"
rc, out, err = run(s, "--set", f"processes.block.exec={py}", "--set", "processes.block.c=1e9",
                   "--set", "processes.block.stiffness=null")
# stiffness=null is still a key py_block does not know: its own check must refuse it
check(rc == 3 and "processes.block" in err, f"py_block refuses an unknown key (rc {rc}: {err[-300:]})")
no_orphans(s, "refused swap")
path = s["processes"]["block"]
del path["stiffness"]
path["exec"], path["c"] = py, 1e9
rc, out, err = run(s)
check(rc == 0, f"py_block run ok ({err})")
hz = h5(s)["/block/series"][:]
check(np.allclose(hz[:, 2], 1e9 * d ** 1.5, rtol=1e-12), "Hertzian force after the swap")
check(not np.allclose(hz[:, 2], lin[:, 2]), "the swapped participant gives the other result")
no_orphans(s, "swap")
done()
