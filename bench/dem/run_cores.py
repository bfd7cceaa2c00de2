"""dem_server on 1 and 2 threads against LIGGGHTS 3.8 on 1 and 2 MPI ranks, in
the same run, on the three scenes of bench/results/dem.md "Every core":
  settling  the 20 000-grain settling bed (gen_data.py, 1 x 1 m): 5000 steps of
            falling and impact, then 1000 steps timed separately;
  settled   the same bed settled (our state after 20 000 steps, as a data
            file for LIGGGHTS): 1000 steps;
  plough    the paper's bed (21 812 grains, 0.6 x 0.3 m, 0.23 m deep, settled)
            with a 24 000-triangle wheel (wheel.py) pressed in and driven
            through it: 2400 steps down, 2000 steps rolling with 20 % slip;
  sleep     (dem_server only) the plough scene rolling one lug period, all
            grains awake against "sleep": time and the mean force on the wheel;
  threads   (dem_server only) small beds on 1 and 2 threads.
Each round runs every configuration once, one after the other (alternated),
holding the shared benchmark lock for the round (a few minutes at most); the
fastest of ROUNDS rounds is kept, and every sample with the load average
before it goes to the JSON.
usage: run_cores.py BUILD_BIN OUTDIR [ROUNDS] [scenes...]"""
import fcntl, json, os, re, subprocess, sys, time

BIN, OUT = sys.argv[1], sys.argv[2]
ROUNDS = int(sys.argv[3]) if len(sys.argv) > 3 and sys.argv[3].isdigit() else 3
SCENES = [a for a in sys.argv[3:] if not a.isdigit()] or ["settling", "settled", "plough"]
HERE = os.path.dirname(os.path.abspath(__file__))
WORK = os.environ.get("DEM_BENCH_WORK", "/tmp/dem_bench_work")
LOCK = os.environ.get("DEM_BENCH_LOCK", "/tmp/cosim-bench.lock")
PY = "/usr/bin/python3"
os.makedirs(WORK, exist_ok=True)
os.makedirs(OUT, exist_ok=True)
MPI = ["mpirun", "--allow-run-as-root", "-np", "2"]


def sh(cmd, locked=True):
    """Runs cmd; returns stdout and the 1-minute load average just before.
    (The timed runs are made while the round holds the lock.)"""
    load = float(open("/proc/loadavg").read().split()[0])
    r = subprocess.run(cmd, capture_output=True, text=True, cwd=WORK)
    if r.returncode:
        sys.exit("failed: %s\n%s%s" % (" ".join(cmd), r.stdout[-2000:], r.stderr[-2000:]))
    return r.stdout, load


def w(name):
    return os.path.join(WORK, name)


def loops(log):
    return [float(v) for v in re.findall(r"Loop time of ([\d.eE+-]+)", open(log).read())]


def ours_times(out, labels):
    return [float(re.search(r"%s \d+ steps: ([\d.]+) s wall" % l, out).group(1)) for l in labels]


def prepare():
    if not os.path.exists(w("bed20k.data")):
        subprocess.run([PY, os.path.join(HERE, "gen_data.py"), "20000", "1.0", w("bed20k.data"), "1"], check=True)
    if not os.path.exists(w("rest20k.h5")):  # settled by us: 20 000 steps, 2 threads (not timed)
        sh([os.path.join(BIN, "bench_dem"), w("bed20k.data"), "1.0", "20000", "0", "0", "5e-5", "-",
            w("rest20k.h5")], locked=False)
    if not os.path.exists(w("rest20k.data")):
        subprocess.run([PY, os.path.join(HERE, "h5_to_data.py"), w("rest20k.h5"), "1.0", w("rest20k.data")],
                       check=True)
    if not os.path.exists(w("deep.h5")):  # the paper's bed in 0.6 x 0.3 m, settled 30 000 steps
        sh([os.path.join(BIN, "bench_dem"), "--bed=1.0", "0.6x0.3", "30000", "0", "0", "5e-5", "-",
            w("deep.h5")], locked=False)
    if not os.path.exists(w("deep.data")):
        subprocess.run([PY, os.path.join(HERE, "h5_to_data.py"), w("deep.h5"), "0.6x0.3", w("deep.data"), "0.5"],
                       check=True)
    if not os.path.exists(w("wheel.txt")):
        subprocess.run([PY, os.path.join(HERE, "wheel.py"), w("deep.h5"), w("wheel"), "1000", "10", "0.27",
                        "0.15", "0.015", "16", "0.2", "0.15", "0.003"], check=True)


def settling():
    lig = ["liggghts", "-in", os.path.join(HERE, "bed.liggghts"), "-var", "data", w("bed20k.data"), "-var", "L",
           "1.0", "-var", "dt", "5e-5", "-var", "nsettle", "5000", "-var", "nrun", "1000", "-var", "dump",
           w("settling.dump")]
    runs = {
        "ours_1": lambda: ours_times(sh([os.path.join(BIN, "bench_dem"), w("bed20k.data"), "1.0", "5000", "1000",
                                          "1", "5e-5"])[0], ["settle", "run"]),
        "ours_2": lambda: ours_times(sh([os.path.join(BIN, "bench_dem"), w("bed20k.data"), "1.0", "5000", "1000",
                                          "2", "5e-5"])[0], ["settle", "run"]),
        "liggghts_1": lambda: (sh(lig + ["-log", w("s1.log")]), loops(w("s1.log")))[1],
        "liggghts_2_default": lambda: (sh(MPI + lig + ["-log", w("s2d.log")]), loops(w("s2d.log")))[1],
        "liggghts_2": lambda: (sh(MPI + lig + ["-var", "pz", "1", "-log", w("s2.log")]), loops(w("s2.log")))[1],
    }
    return runs


def settled():
    lig = ["liggghts", "-in", os.path.join(HERE, "bed.liggghts"), "-var", "data", w("rest20k.data"), "-var", "L",
           "1.0", "-var", "dt", "5e-5", "-var", "nsettle", "0", "-var", "nrun", "1000", "-var", "dump",
           w("settled.dump")]
    ours = lambda t: ours_times(sh([os.path.join(BIN, "bench_dem"), w("rest20k.h5"), "1.0", "0", "1000", t,
                                    "5e-5"])[0], ["run"])
    return {
        "ours_1": lambda: ours("1"),
        "ours_2": lambda: ours("2"),
        "liggghts_1": lambda: (sh(lig + ["-log", w("t1.log")]), loops(w("t1.log"))[1:])[1],
        "liggghts_2": lambda: (sh(MPI + lig + ["-var", "pz", "1", "-log", w("t2.log")]), loops(w("t2.log"))[1:])[1],
    }


def plough():
    cz = float(open(w("wheel.txt")).readline().split()[3]) - 0.25 * 2400 * 5e-5
    lig = ["liggghts", "-in", os.path.join(HERE, "plough.liggghts"), "-var", "data", w("deep.data"), "-var", "stl",
           w("wheel.stl"), "-var", "Lx", "0.6", "-var", "Ly", "0.3", "-var", "dt", "5e-5", "-var", "vdesc", "0.25",
           "-var", "ndesc", "2400", "-var", "vx", "0.3", "-var", "cx", "0.2", "-var", "cy", "0.15", "-var", "cz",
           repr(cz), "-var", "period", repr(2 * 3.141592653589793 / 1.316), "-var", "nmove", "2000"]
    ours = lambda t: ours_times(sh([os.path.join(BIN, "bench_plough"), w("deep.h5"), w("wheel.txt"), "0.6x0.3",
                                    "2400", "0.25", "2000", "0.3", "1.316", t, "0", "10"])[0], ["descent", "move"])
    return {
        "ours_1": lambda: ours("1"),
        "ours_2": lambda: ours("2"),
        "liggghts_1": lambda: (sh(lig + ["-log", w("p1.log")]), loops(w("p1.log")))[1],
        "liggghts_2": lambda: (sh(MPI + lig + ["-var", "pz", "1", "-log", w("p2.log")]), loops(w("p2.log")))[1],
    }


def threads():
    """Small beds (gen_data.py, same density as the 20 000-grain bed): 1 and 2
    threads, 2000 steps of settling: where 2 threads stop paying (the "auto"
    threshold of dem_threads.c)."""
    runs = {}
    for n in (500, 1000, 2000, 4000):
        L = "%.4f" % (n / 20000) ** 0.5
        data = w("bed%d.data" % n)
        if not os.path.exists(data):
            subprocess.run([PY, os.path.join(HERE, "gen_data.py"), str(n), L, data, "1"], check=True)
        for t in ("1", "2"):
            runs["n%d_%s" % (n, t)] = (lambda d, l, t: lambda: ours_times(
                sh([os.path.join(BIN, "bench_dem"), d, l, "2000", "1", t, "5e-5"])[0], ["settle"]))(data, L, t)
    return runs


def sleep():
    """The plough scene rolling for one lug period (6000 steps), one thread:
    all grains awake (coupling every 10 steps; and every 9 and 11 steps, which
    changes nothing but round-off: the spread of chaos) against "sleep"."""
    def ours(sleep, couple):
        def run():
            out, _ = sh([os.path.join(BIN, "bench_plough"), w("deep.h5"), w("wheel.txt"), "0.6x0.3", "2400", "0.25",
                         "6000", "0.3", "1.316", "1", sleep, couple])
            f = re.search(r"mean over the last \d+ steps: (\S+) (\S+) (\S+) N", out).groups()
            asleep = int(re.search(r"move \d+ steps: .* (\d+) sleeping", out).group(1))
            cpu = [float(re.search(r"%s \d+ steps: [\d.]+ s wall ([\d.]+) s cpu" % l, out).group(1))
                   for l in ("descent", "move")]
            return ours_times(out, ["descent", "move"]) + [float(v) for v in f] + [asleep] + cpu
        return run
    return {"awake_10": ours("0", "10"), "awake_9": ours("0", "9"), "awake_11": ours("0", "11"),
            "sleep": ours("1", "10"), "sleep_v0.01": ours("0.01", "10")}


prepare()
res_path = os.path.join(OUT, "dem_cores.json")
res = json.load(open(res_path)) if os.path.exists(res_path) else {}
for scene in SCENES:
    runs = {"settling": settling, "settled": settled, "plough": plough, "sleep": sleep, "threads": threads}[scene]()
    samples = {k: [] for k in runs}
    for rnd in range(ROUNDS):
        lock = open(LOCK, "a")
        fcntl.flock(lock, fcntl.LOCK_EX)  # the round, alone among the benchmarks
        for k, fn in runs.items():
            load = float(open("/proc/loadavg").read().split()[0])
            t = fn()
            ph = t[:2] if scene == "sleep" else t  # sleep: descent, move, force x y z, asleep
            samples[k].append({"phases": ph, "total": sum(ph), "load": load, "extra": t[2:],
                               "time": time.strftime("%H:%M")})
            print(scene, rnd, k, ["%.3f" % v for v in t], "load %.2f" % load, flush=True)
        fcntl.flock(lock, fcntl.LOCK_UN)
        lock.close()
    old = res.get(scene, {})
    for k in samples:  # runs of the same binaries pool their samples (the machine is shared: more chances)
        samples[k] = old.get("samples", {}).get(k, []) + samples[k]
    best = {k: min(s, key=lambda e: e["total"]) for k, s in samples.items()}
    res[scene] = {"rounds": old.get("rounds", 0) + ROUNDS, "best": best, "samples": samples,
                  "date": time.strftime("%Y-%m-%d %H:%M")}
    json.dump(res, open(res_path, "w"), indent=1)
print("results in", res_path)
