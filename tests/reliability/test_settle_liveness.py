"""A long init is not a hung one (PROTOCOL.md "Liveness"): the default
scene's dem_server settles its bed in init (seconds here, minutes at paper
scale) and reports its progress in its heartbeats:
- `cosim run` shows it, and each new report starts handshake_timeout again,
  so a handshake_timeout shorter than the settling does not fire;
- stopped in the middle of it, the DEM is named within heartbeat_timeout,
  although handshake_timeout is long."""
import os
import re
import signal
import subprocess
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "e2e"))
from common import COSIM, check, done, no_orphans, pid_of, scratch  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


out_dir = os.path.join(scratch("cosim-settle-"), "settle")
default = os.path.join(ROOT, "configs", "default.json")
marker = f"settle_{os.getpid()}"
# one DEM thread and a settling that runs all 20 000 steps (about 3 s here;
# the default bed settles in about 1 s, shorter than the limit below)
common = ["--set", f"name={marker}", "--set", f"output.dir={out_dir}", "--overwrite",
          "--set", "processes.dem.threads:=1", "--set", "processes.dem.particles.settle_ke_per_grain:=0",
          "--set", "processes.dem.particles.settle_max_steps:=20000"]
LIMIT = 1.5  # s: handshake_timeout, shorter than the settling
p = subprocess.run([COSIM, "run", default, *common, "--set", "time.end=1e-4",
                    "--set", f"coupling.handshake_timeout={LIMIT}"],
                   capture_output=True, text=True, timeout=600)
log = open(os.path.join(out_dir, "logs", "dem.log")).read()
settle = float(re.search(r"settled in \d+ steps \(([0-9.]+) s\)", log).group(1)) if "settled" in log else 0
check(p.returncode == 0 and "dem: settling the bed" in p.stdout,
      f"settling reports progress and outlives handshake_timeout {LIMIT} s ({p.returncode}: "
      f"{p.stdout[-300:]} {p.stderr[-300:]})")
check(settle > LIMIT, f"the settling took longer than handshake_timeout ({settle} s; the test bites)")
p = subprocess.Popen([COSIM, "run", default, *common, "--set", "coupling.handshake_timeout=300",
                      "--set", "coupling.heartbeat_timeout=2"], stdout=subprocess.PIPE,
                     stderr=subprocess.PIPE, text=True)
line = ""
while "settling" not in line and p.poll() is None:  # the first progress line: it settles
    line = p.stdout.readline()
pid = pid_of(marker, "dem")
os.kill(pid, signal.SIGSTOP)
t0 = time.time()
out, err = p.communicate(timeout=120)
took = time.time() - t0
check("settling the bed" in line, f"progress while settling ({line.strip()})")
check(p.returncode == 3 and "participant 'dem'" in err and "silent" in err,
      f"stopped while settling: named ({p.returncode}: {err[-300:]})")
check(took < 15, f"within seconds ({took:.1f} s; heartbeat_timeout 2 s, handshake_timeout 300 s)")
no_orphans({"name": marker}, "stopped while settling")
done()
