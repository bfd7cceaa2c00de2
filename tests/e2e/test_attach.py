"""--attach: the coupler binds tcp and waits for participants started by hand
(as they would be on other hosts); the run then goes as usual. A participant
that never comes is reported by name when the hello deadline passes."""
import os
import random
import subprocess
import time

import numpy as np

from common import BIN, COSIM, check, done, h5, no_orphans, scene, write

port = random.randint(20000, 40000)
ep = f"tcp://127.0.0.1:{port}"
s = scene("attach", {"block": {"exec": "block_stub", "stiffness": 3e5}},
          scenario={"kind": "indentation", "profile": "quadratic", "depth": 1e-4,
                    "ramp_time": 0.05})
s["coupling"] = {"attach_endpoint": ep, "hello_timeout": 20, "step_timeout": 5}
s["bus"] = {"monitor": f"tcp://127.0.0.1:{port + 2}"}
path = write(s)
coupler = subprocess.Popen([COSIM, "run", path, "--attach"], stdout=subprocess.PIPE,
                           stderr=subprocess.PIPE, text=True)
time.sleep(0.5)
# started by hand, with the command line the coupler prints
part = subprocess.Popen([os.path.join(BIN, "block_stub"), "--endpoint", ep, "--name", "block"],
                        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
out, err = coupler.communicate(timeout=60)
part.wait(timeout=10)
check(coupler.returncode == 0, f"attached run ok ({err[-300:]})")
check(f"block_stub --endpoint {ep} --name block" in err, "the coupler says how to start each participant")
check(part.returncode == 0, f"the hand-started participant exits 0 after stop ({part.returncode})")
d = 1e-4 * np.minimum((np.arange(1, 51) * 1e-3 / 0.05) ** 2, 1)
rows = h5(s)["/block/series"][:]
check(np.allclose(rows[:, 2], 3e5 * d, rtol=1e-12), "forces of the quadratic profile")

# port 0: the coupler binds a free port and prints the command line with it
s0 = scene("attach_free", {"block": {"exec": "block_stub", "stiffness": 3e5}},
           scenario={"kind": "indentation", "profile": "linear", "depth": 1e-4, "ramp_time": 0.05})
s0["coupling"] = {"attach_endpoint": "tcp://127.0.0.1:0", "hello_timeout": 20, "step_timeout": 5}
coupler = subprocess.Popen([COSIM, "run", write(s0), "--attach"], stdout=subprocess.PIPE,
                           stderr=subprocess.PIPE, text=True)
line = ""
for _ in range(50):
    line = coupler.stderr.readline()
    if "--endpoint" in line:
        break
ep0 = line.split("--endpoint")[1].split()[0] if "--endpoint" in line else ""
check(ep0.startswith("tcp://127.0.0.1:") and not ep0.endswith(":0"),
      f"the printed endpoint has the bound port ({line.strip()})")
part = subprocess.Popen([os.path.join(BIN, "block_stub"), "--endpoint", ep0, "--name", "block"],
                        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
out, err = coupler.communicate(timeout=60)
part.wait(timeout=10)
check(coupler.returncode == 0, f"attached run on a free port ok ({err[-300:]})")

# nobody comes: a clear message within the deadline, exit 3
s2 = scene("attach_absent", {"block": {"exec": "block_stub", "stiffness": 3e5}},
           scenario={"kind": "indentation", "profile": "linear", "depth": 1e-4, "ramp_time": 0.05})
s2["coupling"] = {"attach_endpoint": f"tcp://127.0.0.1:{port + 4}", "hello_timeout": 1}
t0 = time.time()
p = subprocess.run([COSIM, "run", write(s2), "--attach"], capture_output=True, text=True, timeout=30)
check(p.returncode == 3 and "no hello within 1 s" in p.stderr and "block" in p.stderr,
      f"absent participant reported ({p.returncode}: {p.stderr[-300:]})")
check(time.time() - t0 < 10, "and promptly")
no_orphans(s, "attach")
done()
