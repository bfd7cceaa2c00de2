"""coupling.affinity "handoff" (coupler/affinity.c): the coupler's loop and
each OpenMP participant's main thread share one core, the participants run as
SCHED_BATCH, and nothing else changes:
- the tread on grains (configs/default.json, serial and implicit) gives the
  same bits with "handoff" as with "none";
- the schedule printout names the hand-off core, and the dem's log says its
  main thread is bound to that core while it still counts every allowed core
  for its threads;
- in a running stub scene the participants carry OMP_PLACES (the hand-off
  core first), OMP_PROC_BIND=close and GOMP_SPINCOUNT=10000 (not the passive
  waits of other runs), run as SCHED_BATCH, and the coupler's main thread is
  bound to the hand-off core alone;
- the hand-off core is the allowed CPU with the fewest threads bound to it
  alone: with sleepers bound to every other CPU a run takes the free one;
- with the parallel scheme (every process at once) nothing is bound, an
  unknown value is refused naming the key, a user's OMP_PLACES is kept; the
  printout says which.

Usage: test_affinity.py [scenes|live|crowded|refuse ...] (default: all)."""
import os
import re
import signal
import subprocess
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "reliability"))
from common import COSIM, check, done, no_orphans, pid_of, processes_with, scratch  # noqa: E402
from rel import differences  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def allowed_cpus():
    return sorted(os.sched_getaffinity(0))


def run(config, affinity, tag, extra=(), env=None):
    out = os.path.join(scratch("cosim-aff-"), tag)
    p = subprocess.run([COSIM, "run", os.path.join(ROOT, "configs", config), "--set",
                        f"coupling.affinity={affinity}", "--set", f"output.dir={out}", *extra],
                       capture_output=True, text=True, timeout=600, env=env)
    check(p.returncode == 0, f"{tag}: exits 0 (got {p.returncode}: {p.stderr.strip()[-400:]})")
    return out, p.stdout + p.stderr


def handoff_core(text, tag):
    m = re.search(r"affinity: handoff: .* main thread on CPU (\d+)", text)
    if len(allowed_cpus()) < 2:
        check("affinity: none: fewer than 2 CPUs allowed" in text,
              f"{tag}: one CPU: the printout says why nothing is bound")
        return None
    check(m is not None, f"{tag}: the schedule printout names the hand-off core")
    return int(m.group(1)) if m else None


def scenes():
    cpus = allowed_cpus()
    for tag, extra in (("default", ["--set", "time.end=0.002"]),
                       ("default_implicit", ["--set", "time.end=0.0005", "--set",
                                             "coupling.scheme=implicit"])):
        a, ta = run("default.json", "none", tag + "-none", extra)
        b, tb = run("default.json", "handoff", tag + "-handoff", extra)
        check("affinity: none (coupling.affinity)" in ta, f"{tag}: 'none' is printed")
        core = handoff_core(tb, tag)
        diff, n = differences(a, b)
        check(not diff and n > 5, f"{tag}: handoff and none bitwise equal ({n} datasets; {diff[:4]})")
        if core is None:
            continue
        log = open(os.path.join(b, "logs", "dem.log")).read()
        check(f"main thread bound to CPU {core} by the OpenMP places" in log,
              f"{tag}: the dem's main thread is on the hand-off core CPU {core}")
        check(f"auto: {len(cpus)} cores allowed" in log,
              f"{tag}: the dem still counts the {len(cpus)} allowed cores for its threads")
        log_a = open(os.path.join(a, "logs", "dem.log")).read()
        check("bound to CPU" not in log_a, f"{tag}: with 'none' nothing is bound")


def field(path, name):
    for line in open(path):
        if line.startswith(name + ":"):
            return line.split(":", 1)[1].strip()
    return None


def live():
    """A long stub run with handoff: look at the processes while they step."""
    cpus = allowed_cpus()
    if len(cpus) < 2:
        print("live: one CPU allowed, nothing to bind: skipped")
        return
    name = f"affinity_{os.getpid()}"
    out = os.path.join(scratch("cosim-aff-"), name)
    p = subprocess.Popen([COSIM, "run", os.path.join(ROOT, "configs", "stub_tire.json"),
                          "--set", "coupling.affinity=handoff", "--set", f"name={name}",
                          "--set", "time.end=1000", "--set", f"output.dir={out}"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        fem = pid_of(name, "fem")
        check(fem is not None, "the fem stub started")
        coupler = None
        for _ in range(200):  # until the loop runs (its steps are in results.h5)
            coupler = next((pid for pid, cmd in processes_with(name) if "cosim run" in cmd), None)
            if coupler and os.path.exists(os.path.join(out, "results.h5")):
                bound = field(f"/proc/{coupler}/task/{coupler}/status", "Cpus_allowed_list")
                if bound and "," not in bound and "-" not in bound:
                    break
            time.sleep(0.05)
        check(coupler is not None, "the coupler found")
        bound = field(f"/proc/{coupler}/task/{coupler}/status", "Cpus_allowed_list")
        check(bound is not None and bound.isdigit() and int(bound) in cpus,
              f"the coupler's loop thread is bound to one allowed CPU: {bound}")
        env = open(f"/proc/{fem}/environ", "rb").read().split(b"\0")
        places = [e.decode() for e in env if e.startswith(b"OMP_PLACES=")]
        check(places == ["OMP_PLACES={" + str(bound) + "}" + "".join(
            ",{%d}" % c for c in cpus if str(c) != bound)],
            f"the participant's OMP_PLACES starts at the coupler's core {bound}: {places}")
        check(b"OMP_PROC_BIND=close" in env, "the participant has OMP_PROC_BIND=close")
        check(b"GOMP_SPINCOUNT=10000" in env and not any(e.startswith(b"OMP_WAIT_POLICY=") for e in env),
              "the participant's OpenMP waits spin briefly (GOMP_SPINCOUNT=10000, no passive policy)")
        policy = int(open(f"/proc/{fem}/stat").read().rsplit(")", 1)[1].split()[38])
        check(policy == 3, f"the participant runs as SCHED_BATCH (policy {policy}, want 3)")
    finally:
        p.send_signal(signal.SIGINT)
        try:
            p.communicate(timeout=60)
        except subprocess.TimeoutExpired:
            p.kill()
            p.communicate()
    check(p.returncode == 130, f"interrupted: exit 130 (got {p.returncode})")
    no_orphans({"name": name}, "after the interrupt")


# more threads bound to each other CPU than other tests' hand-off runs bind to
# one (a coupler loop and two participants' main threads each)
SLEEPERS_PER_CPU = 8


def crowded():
    """The hand-off core is the allowed CPU with the fewest threads bound to it
    alone: with sleepers bound to every other CPU, a run takes the free one,
    whichever CPU that is (before, each run took the core its coupler started
    on, and runs started side by side piled onto one)."""
    cpus = allowed_cpus()
    if len(cpus) < 2 or len(cpus) > 16:
        print(f"crowded: {len(cpus)} CPUs allowed: skipped (2-16 needed)")
        return
    for free in cpus[:2]:
        sleepers = [subprocess.Popen(["taskset", "-c", str(c), "sleep", "600"])
                    for c in cpus if c != free for _ in range(SLEEPERS_PER_CPU)]
        try:
            wait_bound(sleepers)
            _, text = run("stub_tire.json", "handoff", f"crowded_{free}", ["--set", "time.end=0.001"])
        finally:
            for p in sleepers:
                p.kill()
                p.wait()
        core = handoff_core(text, f"crowded_{free}")
        check(core == free, f"with {SLEEPERS_PER_CPU} sleepers bound to each other CPU the "
              f"hand-off core is the free CPU {free} (got {core})")
        # other tests' runs may hold a few threads there: the count, not a zero
        m = re.search(rf"main thread on CPU {free} \((\d+) threads? bound to it alone before this run\)", text)
        check(m is not None and int(m.group(1)) < SLEEPERS_PER_CPU,
              f"crowded_{free}: the printout counts the threads bound to the chosen core "
              f"({m.group(0) if m else 'no count'})")


def wait_bound(procs, timeout=10.0):
    """Until every process's allowed CPUs are one CPU (taskset has bound it)."""
    end = time.time() + timeout
    for p in procs:
        while time.time() < end:
            bound = field(f"/proc/{p.pid}/status", "Cpus_allowed_list")
            if bound and bound.isdigit():
                break
            time.sleep(0.01)
    check(time.time() < end, "the sleepers are bound within 10 s")


def refuse():
    scene = os.path.join(ROOT, "configs", "default.json")
    _, text = run("stub_tire.json", "handoff", "parallel", ["--set", "time.end=0.01", "--set",
                                                            "coupling.scheme=parallel"])
    check("affinity: none: the parallel scheme runs every process at once" in text,
          "parallel: handoff is not applied, and the printout says why")
    p = subprocess.run([COSIM, "check", scene, "--set", "coupling.affinity=pinned"],
                       capture_output=True, text=True, timeout=120)
    check(p.returncode == 1 and "coupling.affinity" in p.stderr,
          f"an unknown value is refused naming the key: {p.stderr.strip()[-300:]}")
    env = dict(os.environ, OMP_PLACES="cores")
    out, text = run("stub_tire.json", "handoff", "user_places", ["--set", "time.end=0.01"], env=env)
    check("affinity: none: OMP_PLACES is set in the environment" in text,
          "a user's OMP_PLACES is kept, and the printout says so")


if __name__ == "__main__":
    parts = sys.argv[1:] or ["scenes", "live", "crowded", "refuse"]
    for part in parts:
        {"scenes": scenes, "live": live, "crowded": crowded, "refuse": refuse}[part]()
    done()
