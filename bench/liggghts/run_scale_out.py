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
       run_scale_out.py report       (bench/results/scale_out.md from the JSON)
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
SAMPLES = os.path.join(WORK, "samples.jsonl")  # every run, appended: runs can be split and resumed
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


def record(part, key, r):
    with open(SAMPLES, "a") as f:
        f.write(json.dumps({"part": part, "key": key, "result": r}) + "\n")


def samples():
    out = {}
    if os.path.exists(SAMPLES):
        for line in open(SAMPLES):
            d = json.loads(line)
            out.setdefault(d["part"], {}).setdefault(d["key"], []).append(d["result"])
    return out


def tyre(bin_dir, repeats):
    paper_bed(bin_dir)
    have = samples().get("tyre", {})
    configs = [("dem_server_1t", ("dem_server", 1), 0), ("dem_server_2t", ("dem_server", 2), 0),
               ("liggghts_dem_np1", ("liggghts_dem",), 1), ("liggghts_dem_np2", ("liggghts_dem",), 2),
               ("dem_stub", "dem_stub", 0)]
    for rep in range(repeats):
        for tag, dem, ranks in configs:
            if len(have.get(tag, [])) > rep:
                continue
            s = tyre_scene(f"{tag}_{rep}", dem)
            with bench_lock():
                la = load()
                total, log = run_attached(bin_dir, s, ranks) if ranks == 2 else run_launched(bin_dir, s)
            r = analyse(s)
            r.update({"run_s": total, "load_avg": la, "timing": parse_timing(log)})
            print(tag, rep, json.dumps(r), flush=True)
            record("tyre", tag, r)


def bed(bin_dir, repeats):
    have = samples().get("bed", {})
    big = int(os.environ.get("SCALE_OUT_BIG", "1000000"))
    runs = [(1, 100000, 300, 60), (2, 100000, 300, 60), (2, big, 300, 60)]
    for rep in range(repeats):
        for ranks, n, settle, timed in runs:
            if n == big and rep > 1:
                continue  # twice: minutes each
            if len(have.get(f"np{ranks}_n{n}", [])) > rep:
                continue
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
            record("bed", f"np{ranks}_n{n}", r)


# ------------------------------------------------------------------ report

def best(runs, key="ms_per_step"):
    return min(runs, key=lambda r: r[key])


def fmt(x, nd=1):
    return f"{x:.{nd}f}" if x is not None else "—"


# Assumptions of the paper estimate (stated in the report).
CORES_PER_NODE = 32        # a common dual-socket node
NET_FACTOR = 2.0           # inter-node halo exchange against shared memory
CHUTE_1, CHUTE_4 = 0.155391, 0.0451259  # LAMMPS chute, 32 000 grains, 100 steps, 1 and 4 ranks
CHUTE_COMM4 = 0.0041343    # its Comm time on 4 ranks
DEEP_GRAINS = 4 * 21812    # the paper's 0.14 m bed: about four times the grains (issue 10)
DEEP_STEPS = round((0.020 / 0.1 + 0.5 / (1.8 * 0.272 * 0.95)) / 5e-5)  # sinkage 20 mm at 0.1 m/s, 0.5 m travel


def comm_model(bed_runs):
    """Per-rank compute cost c (s per particle-step) and the communication
    fraction f(n) = f0 (n0/n)^(1/3) (halo / volume) from the -np 2 bed runs."""
    big = best(bed_runs["np2_big"])
    n0 = big["grains"] / 2
    loop = big["ms_liggghts_loop"]
    f0 = big["ms_comm"] / max(loop - big["ms_comm"], 1e-12)
    c = (loop - big["ms_comm"]) * 1e-3 / n0
    over = (big["ms_per_step"] - loop) * 1e-3  # run-call set-up, walls, summary per step
    return c, f0, n0, over, big


def dem_step(n, ranks, c, f0, n0, over_per_grain, fixed, nodes):
    per = n / ranks
    f = f0 * (n0 / per) ** (1 / 3) * (NET_FACTOR if nodes > 1 else 1.0)
    return per * c * (1 + f) + per * over_per_grain + fixed


def report():
    res = json.load(open(RESULTS))
    tyre_runs, bed_runs = res.get("tyre", {}), res.get("bed", {})
    for k in list(bed_runs):  # the biggest -np 2 bed, whatever its size
        if k.startswith("np2_n") and int(k[5:]) >= 500000:
            bed_runs["np2_big"] = bed_runs[k]
    L = ["# Scale-out: liggghts_dem (LIGGGHTS over MPI) against dem_server", "",
         "Generated by `bench/liggghts/run_scale_out.py` (data: `scale_out.json`); every timed run held",
         "`/tmp/cosim-bench.lock`; the machine (2 cores) was shared with other jobs, so each figure is the",
         "fastest of alternated repeats and the load average at its start is listed.", ""]
    if tyre_runs:
        stub = best(tyre_runs["dem_stub"])["ms_per_step"]
        L += ["## The paper's bed with the tyre (coupled, 21 812 grains, 23 808 TET4, 600 steps)", "",
              "`bench/liggghts/paper_tyre.json`: the settled paper bed (`bench/dem/paper_bed.json`), the paper's",
              "tyre sinking at 0.2 m/s from touching the bed, serial scheme, one DEM step (5e-5 s) per coupling",
              "step; ms per coupled step over steps 100–600 (the grains are in contact throughout). `dem_stub`",
              "(no grains) measures the FEM and the coupler alone; the DEM share is the difference.", "",
              "| DEM | ms per coupled step | DEM share (− dem_stub) | load avg | mean load N | mean T_H N | samples |",
              "|---|---|---|---|---|---|---|"]
        names = {"dem_server_1t": "dem_server, 1 thread", "dem_server_2t": "dem_server, 2 threads",
                 "liggghts_dem_np1": "liggghts_dem, -np 1", "liggghts_dem_np2": "liggghts_dem, -np 2 (attached)",
                 "dem_stub": "dem_stub (FEM + coupler only)"}
        for tag, name in names.items():
            if tag not in tyre_runs:
                continue
            b = best(tyre_runs[tag])
            share = b["ms_per_step"] - stub if tag != "dem_stub" else None
            L.append(f"| {name} | {fmt(b['ms_per_step'], 2)} | {fmt(share, 2)} | {b['load_avg']:.1f} | "
                     f"{b['load_mean_N']:.1f} | {b['T_H_mean']:.2f} | "
                     f"{' '.join(fmt(r['ms_per_step'], 1) for r in tyre_runs[tag])} |")
        L += ["", "liggghts_dem's own split (rank 0, ms per coupled step, from its log; fastest run):", "",
              "| ranks | participant | LIGGGHTS loop | pair | neighbour lists | communication | walls, meshes, integration | `run` call set-up | surface (nodes, activity rule) | nodal/wall forces | summary | broadcast to ranks |",
              "|---|---|---|---|---|---|---|---|---|---|---|---|"]
        for tag, ranks in (("liggghts_dem_np1", 1), ("liggghts_dem_np2", 2)):
            if tag not in tyre_runs:
                continue
            t = best(tyre_runs[tag])["timing"]
            if not t:
                continue
            L.append(f"| {ranks} | {t['participant']:.2f} | {t['loop']:.2f} | {t['pair']:.2f} | {t['neigh']:.2f} | "
                     f"{t['comm']:.2f} | {t['rest']:.2f} | {t['liggghts_runs'] - t['loop']:.2f} | {t['surface']:.2f} | "
                     f"{t['forces']:.2f} | {t['summary']:.2f} | {t['broadcast']:.2f} |")
        L.append("")
    if bed_runs:
        L += ["## Large beds under MPI (`bench_lgd_bed`)", "",
              "The paper's three layers scaled to N grains in a box, one DEM step per `lgd_step` (as in a coupled",
              "run: the series row every step), 300 steps after placing (the layers land and touch), then timed.",
              "Memory: resident sets of all ranks; the bed itself lives on rank 0 only (`lgd_model_from_json`).", "",
              "| ranks | grains | ms per step | LIGGGHTS loop ms | pair | comm | summary | ns per particle-step per rank | start-up s | RSS after start MB (all ranks) | bytes per grain | load avg |",
              "|---|---|---|---|---|---|---|---|---|---|---|---|"]
        for k, runs in sorted(bed_runs.items()):
            if k == "np2_big":
                continue
            b = best(runs)
            per = (b["mem_open_mb"] - b["mem_start_mb"]) * 1048576 / b["grains"]
            L.append(f"| {b['ranks']} | {b['grains']} | {b['ms_per_step']:.1f} | {b['ms_liggghts_loop']:.1f} | "
                     f"{b['ms_pair']:.1f} | {b['ms_comm']:.1f} | {b['ms_summary']:.1f} | "
                     f"{b['ns_per_particle_step_per_rank']:.0f} | {b['t_model_s'] + b['t_open_s']:.1f} | "
                     f"{b['mem_open_mb']:.0f} | {per:.0f} | {b['load_avg']:.1f} |")
        L.append("")
    if tyre_runs and "np2_big" in bed_runs:
        c, f0, n0, over, big = comm_model(bed_runs)
        over_g = over / n0
        t_np1 = best(tyre_runs["liggghts_dem_np1"])["timing"]
        fem = best(tyre_runs["dem_stub"])["ms_per_step"] * 1e-3
        fixed = (t_np1["surface"] + t_np1["broadcast"]) * 1e-3  # per coupled step, does not shrink with ranks
        eff4 = CHUTE_1 / (4 * CHUTE_4)
        L += ["## Paper estimate: more nodes", "",
              f"Measured per-rank cost (the {big['grains']:,}-grain bed, -np 2): c = {c * 1e9:.0f} ns per particle-step",
              f"of LIGGGHTS' own work, communication {f0 * 100:.1f} % of it at {n0:,.0f} grains per rank, and",
              f"{over_g * 1e9:.0f} ns per grain and step outside LIGGGHTS' loop (series row, checks, plane-wall forces).",
              "Model: t(P) = (N/P)·c·(1 + f(N/P)) + (N/P)·that + fixed, with the halo-exchange fraction",
              "f(n) = f0·(n0/n)^(1/3) (halo over volume) and ×" + f"{NET_FACTOR:g} between nodes (assumed); fixed =",
              f"surface update and broadcast to the ranks ({fixed * 1e3:.2f} ms per step on the paper tyre: the activity",
              "rule runs on every rank), plus the FEM and coupler for coupled scenes (measured with dem_stub:",
              f"{fem * 1e3:.2f} ms per step). Nodes of {CORES_PER_NODE} cores, one rank per core.", "",
              "Published strong scaling of the same engine (LIGGGHTS is LAMMPS' MPI domain decomposition and",
              "communication with granular models): LAMMPS' granular chute benchmark, 32 000 grains, 100 steps,",
              f"{CHUTE_1:.4f} s on 1 rank and {CHUTE_4:.4f} s on 4 (`bench/log.15Jul25.chute.fixed.g++.1`, `.4` in the",
              f"LAMMPS repository): {eff4 * 100:.0f} % efficiency at 8 000 grains per rank, Comm {CHUTE_COMM4 / CHUTE_4 * 100:.0f} % of the step. The",
              f"model gives f = {f0 * (n0 / 8000) ** (1 / 3) * 100:.0f} % at 8 000 grains per rank on one node, in line with it.",
              "Static domain decomposition leaves the load imbalance of a bed whose contacts concentrate under",
              "the tyre (Berger, Kloss, Kohlmeyer, Pirker 2015, Powder Technol. 278:234, doi 10.1016/j.powtec.2015.03.019);",
              "a bed's grains are spread evenly over the footprint, so the grain count per rank stays balanced.", "",
              "| scene | ranks (nodes) | DEM ms per step | + FEM, coupler | steps | wall time |",
              "|---|---|---|---|---|---|"]
        for name, n, coupled, steps in (("deep paper scene (87 248 grains, tyre)", DEEP_GRAINS, True, DEEP_STEPS),
                                        ("10^7-grain bed, tyre, same travel", 10_000_000, True, DEEP_STEPS)):
            for ranks, nodes in ((2, 1), (4 * CORES_PER_NODE, 4), (16 * CORES_PER_NODE, 16)):
                d = dem_step(n, ranks, c, f0, n0, over_g, fixed, nodes)
                tot = d + (fem if coupled else 0)
                L.append(f"| {name} | {ranks} ({nodes}) | {d * 1e3:.2f} | {tot * 1e3:.2f} | {steps:,} | "
                         f"{tot * steps / 3600:.2f} h |")
        mem = (big["mem_open_mb"] - big["mem_start_mb"]) * 1048576 / big["grains"]
        L += ["", f"Memory: {mem:.0f} bytes per grain measured ⇒ 10^7 grains need about {mem * 1e7 / 2**30:.1f} GiB in all",
              f"({mem * 1e7 / 2**30 / 4:.1f} GiB per node on 4 nodes), plus the bed file's reader on rank 0 during start-up.",
              "The deep scene stops gaining from ranks early: at a few hundred grains per rank the fixed costs",
              "(the FEM, the surface update, the per-step exchanges) dominate; one node is its right size. A",
              "10^7-grain bed keeps ~20 000–80 000 grains per rank on 4–16 nodes, where the engine is efficient.", ""]
    out = os.path.join(ROOT, "bench", "results", "scale_out.md")
    with open(out, "w") as f:
        f.write("\n".join(L))
    print("wrote", out)


def main():
    if sys.argv[1:2] == ["report"]:
        report()
        return
    bin_dir = os.path.abspath(sys.argv[1])
    parts = [a for a in sys.argv[2:] if not a.startswith("--") and not a.isdigit()] or ["tyre", "bed"]
    repeats = int(sys.argv[sys.argv.index("--repeats") + 1]) if "--repeats" in sys.argv else 4
    os.makedirs(WORK, exist_ok=True)
    if "tyre" in parts:
        tyre(bin_dir, repeats)
    if "bed" in parts:
        bed(bin_dir, repeats)
    res = samples()
    res["machine"] = {"cpus": os.cpu_count(), "uname": " ".join(os.uname()[2:5])}
    with open(RESULTS, "w") as f:
        json.dump(res, f, indent=1)
    print("wrote", RESULTS)


if __name__ == "__main__":
    main()
