#!/usr/bin/env python3
"""Scale-out benchmarks of liggghts_dem (bench/results/scale_out.md data).

  tyre: the paper's bed (21 812 grains, settled by bench/dem/paper_bed.json)
        with the paper's tyre (fem_server, 23 808 TET4) sinking into it, one
        DEM step per coupling step: ms per coupled step for dem_server with 1
        and 2 threads, liggghts_dem under -np 1 (launched) and -np 2 (attached,
        mpirun), and dem_stub (FEM + coupler alone); alternated runs.
  bed:  bench_lgd_bed: a 10^6-grain bed under mpirun -np 2 (and smaller beds
        under -np 1 and 2 for the per-rank cost).

Every timed run holds /tmp/cosim-bench.lock (one engineer times at once).
usage: run_scale_out.py BUILD_BIN_DIR [tyre] [bed] [--repeats N]
Writes bench/results/scale_out.json (merged with what is there)."""
import fcntl
import json
import os
import random
import re
import subprocess
import sys
import time
from contextlib import contextmanager

# the coupler's results.h5 descriptor is inherited by its children, and the
# daemon a one-rank MPI start leaves behind can hold the file's lock a moment
# after cosim has exited: read without taking the lock
os.environ.setdefault("HDF5_USE_FILE_LOCKING", "FALSE")
import h5py  # noqa: E402
import numpy as np

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
WORK = os.path.join(ROOT, "runs", "scale_out")
RESULTS = os.path.join(ROOT, "bench", "results", "scale_out.json")
MPI_ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1")
WINDOW = (100, None)  # coupled steps timed: from the 100th to the end


@contextmanager
def bench_lock():
    if os.environ.get("SCALE_OUT_END"):  # smoke tests of this script time nothing
        yield
        return
    with open("/tmp/cosim-bench.lock", "w") as f:
        fcntl.flock(f, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(f, fcntl.LOCK_UN)


def load():
    return os.getloadavg()[0]


def paper_bed(bin_dir):
    bed = os.path.join(WORK, "paper_bed.h5")
    if not os.path.exists(bed):
        print("settling the paper bed (once) ...", flush=True)
        subprocess.run([os.path.join(bin_dir, "cosim"), "run", os.path.join(ROOT, "bench/dem/paper_bed.json"),
                        "--set", "output.dir=" + os.path.join(WORK, "bed_run"), "--quiet"],
                       cwd=WORK, check=True)
    return bed


TIMING = re.compile(r"liggghts_dem: (\d+) coupling steps .*?participant ([\d.]+) = LIGGGHTS runs ([\d.]+) "
                    r"\[its loop ([\d.]+): pair ([\d.]+), neighbour lists ([\d.]+), communication ([\d.]+), "
                    r"output ([\d.]+), the rest \(walls, meshes, integration\) ([\d.]+)\] \+ surface ([\d.]+) "
                    r"\+ nodal/wall forces ([\d.]+) \+ summary ([\d.]+) \+ broadcast to the ranks ([\d.]+) "
                    r"\+ reply ([\d.]+)")
TIMING_KEYS = ["steps", "participant", "liggghts_runs", "loop", "pair", "neigh", "comm", "output", "rest",
               "surface", "forces", "summary", "broadcast", "reply"]


def parse_timing(text):
    m = TIMING.search(text or "")
    return {k: float(v) for k, v in zip(TIMING_KEYS, m.groups())} if m else None


def tyre_scene(tag, dem):
    with open(os.path.join(ROOT, "bench/liggghts/paper_tyre.json")) as f:
        s = json.load(f)
    s["name"] = f"scale_out_{tag}"
    if os.environ.get("SCALE_OUT_END"):  # smoke tests of this script
        s["time"]["end"] = float(os.environ["SCALE_OUT_END"])
    s["output"]["dir"] = os.path.join(WORK, tag)
    base = s["processes"]["dem"]
    if dem == "dem_stub":
        s["processes"]["dem"] = {"exec": "dem_stub"}
    else:
        base["exec"] = dem[0]
        base["particles"] = {"file": os.path.join(WORK, "paper_bed.h5")}
        if dem[0] == "dem_server":
            base["threads"] = dem[1]
    return s


def run_launched(bin_dir, s):
    path = os.path.join(WORK, s["name"] + ".json")
    with open(path, "w") as f:
        json.dump(s, f, indent=1)
    t0 = time.time()
    p = subprocess.run([os.path.join(bin_dir, "cosim"), "run", path, "--quiet"], capture_output=True, text=True,
                       env=MPI_ENV, cwd=WORK)
    if p.returncode:
        raise RuntimeError(f"{s['name']}: {p.stderr[-800:]}")
    log = open(os.path.join(s["output"]["dir"], "logs", "dem.log")).read()
    return time.time() - t0, log


def run_attached(bin_dir, s, ranks):
    port = random.randint(20000, 40000)
    s["coupling"]["attach_endpoint"] = f"tcp://127.0.0.1:{port}"
    path = os.path.join(WORK, s["name"] + ".json")
    with open(path, "w") as f:
        json.dump(s, f, indent=1)
    t0 = time.time()
    coupler = subprocess.Popen([os.path.join(bin_dir, "cosim"), "run", path, "--attach", "--quiet"],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=WORK)
    time.sleep(0.3)
    ep = s["coupling"]["attach_endpoint"]
    fem = subprocess.Popen([os.path.join(bin_dir, "fem_server"), "--endpoint", ep, "--name", "fem"],
                           stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, cwd=WORK)
    dem = subprocess.Popen(["mpirun", "-np", str(ranks), os.path.join(bin_dir, "liggghts_dem"), "--endpoint", ep,
                            "--name", "dem"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                           env=MPI_ENV, cwd=WORK)
    _, err = coupler.communicate()
    _, derr = dem.communicate()
    fem.communicate()
    if coupler.returncode:
        raise RuntimeError(f"{s['name']}: {err[-800:]} {derr[-800:]}")
    return time.time() - t0, derr


def analyse(s):
    f = h5py.File(os.path.join(s["output"]["dir"], "results.h5"), "r")
    wall = f["/coupler/series"][:, 1]
    trac = f["/coupler/traction"][:]
    lo = WINDOW[0]
    hi = len(wall) - 1
    touch = np.nonzero(trac[:, 4] > 1.0)[0]
    return {"steps": int(len(wall)), "ms_per_step": (wall[hi] - wall[lo]) / (hi - lo) * 1e3,
            "startup_s": float(wall[0]), "contact_from_step": int(touch[0]) + 1 if len(touch) else None,
            "load_mean_N": float(trac[lo:, 4].mean()), "load_max_N": float(trac[:, 4].max()),
            "T_H_mean": float(trac[lo:, 1].mean()), "T_P_mean": float(trac[lo:, 3].mean())}


def tyre(bin_dir, repeats):
    paper_bed(bin_dir)
    configs = [("dem_server_1t", ("dem_server", 1), 0), ("dem_server_2t", ("dem_server", 2), 0),
               ("liggghts_dem_np1", ("liggghts_dem",), 1), ("liggghts_dem_np2", ("liggghts_dem",), 2),
               ("dem_stub", "dem_stub", 0)]
    out = {}
    for rep in range(repeats):
        for tag, dem, ranks in configs:
            s = tyre_scene(f"{tag}_{rep}", dem)
            with bench_lock():
                la = load()
                total, log = run_attached(bin_dir, s, ranks) if ranks == 2 else run_launched(bin_dir, s)
            r = analyse(s)
            r.update({"run_s": total, "load_avg": la, "timing": parse_timing(log)})
            print(tag, rep, json.dumps(r), flush=True)
            out.setdefault(tag, []).append(r)
    return out


def bed(bin_dir, repeats):
    out = {}
    big = int(os.environ.get("SCALE_OUT_BIG", "1000000"))
    runs = [(1, 100000, 300, 60), (2, 100000, 300, 60), (2, big, 300, 60)]
    for rep in range(repeats):
        for ranks, n, settle, timed in runs:
            if n == big and rep > 0:
                continue  # once: several minutes
            with bench_lock():
                la = load()
                p = subprocess.run(["mpirun", "-np", str(ranks), os.path.join(bin_dir, "bench_lgd_bed"), str(n),
                                    str(settle), str(timed)], capture_output=True, text=True, env=MPI_ENV)
            line = [l for l in p.stdout.splitlines() if l.startswith("{")]
            if p.returncode or not line:
                raise RuntimeError(p.stderr[-1000:])
            r = json.loads(line[-1])
            r["load_avg"] = la
            print("bed", ranks, n, json.dumps(r), flush=True)
            out.setdefault(f"np{ranks}_n{n}", []).append(r)
    return out


def main():
    bin_dir = os.path.abspath(sys.argv[1])
    parts = [a for a in sys.argv[2:] if not a.startswith("--") and not a.isdigit()] or ["tyre", "bed"]
    repeats = int(sys.argv[sys.argv.index("--repeats") + 1]) if "--repeats" in sys.argv else 2
    os.makedirs(WORK, exist_ok=True)
    res = json.load(open(RESULTS)) if os.path.exists(RESULTS) else {}
    res["machine"] = {"cpus": os.cpu_count(), "uname": " ".join(os.uname()[2:5])}
    if "tyre" in parts:
        res["tyre"] = tyre(bin_dir, repeats)
    if "bed" in parts:
        res["bed"] = bed(bin_dir, repeats)
    with open(RESULTS, "w") as f:
        json.dump(res, f, indent=1)
    print("wrote", RESULTS)


if __name__ == "__main__":
    main()
