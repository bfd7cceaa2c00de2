"""exec as an argv list with a launcher prefix (PROTOCOL.md "Starting a
participant"): cosim appends --endpoint EP --name NAME to the list, checks a
section with the last element alone, and supervises through the launcher:
exit codes and logs come through, and stopping the run stops the launcher's
children too (each process gets its own process group). launcher.sh starts
the participant as its child, as mpirun does."""
import os
import shutil
import signal
import subprocess
import time

import numpy as np

from common import BIN, COSIM, HERE, check, done, h5, no_orphans, processes_with, remove_run_dirs, run, scene, write

LAUNCHER = os.path.join(HERE, "launcher.sh")
ROGUE = os.path.join(HERE, "rogue.py")


def block_scene(name, exec_list, end=0.05, **kw):
    return scene(name, {"block": dict({"exec": exec_list, "stiffness": 2e5}, **kw)},
                 scenario={"kind": "indentation", "profile": "linear", "depth": 2e-4,
                           "ramp_time": 0.04}, time={"dt": 1e-3, "end": end})


# a normal run through the launcher
s = block_scene("launch_ok", [LAUNCHER, "block_stub"])
rc, out, err = run(s)
check(rc == 0, f"run through a launcher ok ({err[-300:]})")
log = open(os.path.join(s["output"]["dir"], "logs", "block.log")).read()
check("launcher: starting" in log and "--endpoint" in log and "--name block" in log,
      f"the launcher got the participant and cosim's arguments ({log[:300]!r})")
d = np.minimum(np.arange(1, 51) * 1e-3 / 0.04, 1.0) * 2e-4
check(np.allclose(h5(s)["/block/series"][:, 2], 2e5 * d, rtol=1e-12), "results through the launcher")
no_orphans(s, "launcher run")
# cosim check: the section is checked by the participant alone
s = block_scene("launch_check", [LAUNCHER, "block_stub"], stiffness=-1)
rc, out, err = run(s, cmd="check")
check(rc == 1 and "processes.block.stiffness: must be in [0," in err,
      f"check goes to the last element of exec ({rc}: {err.strip()[-200:]})")
s = block_scene("launch_missing", ["no_such_launcher", "block_stub"])
rc, out, err = run(s)
check(rc == 1 and "processes.block.exec[0]: 'no_such_launcher' not found" in err,
      f"a missing launcher is named ({err.strip()[-200:]})")
# the participant behind the launcher fails: its status and log come through
s = block_scene("launch_crash", [LAUNCHER, ROGUE])
rc, out, err = run(s, env={"ROGUE_MODE": "crash_step", "ROGUE_ROLE": "block"})
check(rc == 3 and "participant 'block'" in err and "exited with status 5" in err
      and "crashing at the first step" in err, f"a crash behind the launcher is reported ({rc}: {err[-400:]})")
no_orphans(s, "crash behind a launcher")
# Ctrl-C: the launcher and its child are stopped
s = block_scene("launch_sigint", [LAUNCHER, "block_stub"], end=1e6)
p = subprocess.Popen([COSIM, "run", write(s)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
time.sleep(1.5)
n_before = len(processes_with(s["name"]))
p.send_signal(signal.SIGINT)
out, err = p.communicate(timeout=30)
check(p.returncode == 130, f"Ctrl-C through a launcher: exit 130 ({p.returncode}: {err[-200:]})")
check(n_before >= 2, f"launcher and participant were both running ({n_before})")
no_orphans(s, "Ctrl-C behind a launcher")
# the launcher killed hard: the participant behind it goes too
s = block_scene("launch_sigkill", [LAUNCHER, "block_stub"], end=1e6)
p = subprocess.Popen([COSIM, "run", write(s)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
time.sleep(1.5)
p.kill()
p.wait()
no_orphans(s, "cosim killed with SIGKILL, launcher in between")
remove_run_dirs(s)
# a real MPI launcher, when there is one
mpirun = shutil.which("mpirun")
if mpirun:
    s = block_scene("launch_mpirun", [mpirun, "--allow-run-as-root", "--oversubscribe", "-np", "1",
                                      "block_stub"])
    rc, out, err = run(s, timeout=120)
    check(rc == 0, f"run through mpirun -np 1 ({err[-300:]})")
    no_orphans(s, "mpirun")
else:
    print("mpirun not installed: the MPI launcher case is not run")
done()
