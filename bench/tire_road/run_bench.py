#!/usr/bin/env python3
"""Scenario tire_road on the rough road (docs/tire-road.md): the coupled
instability and its cure, the 50 km/h revolution benchmark, and one lug
passage beside the stand-alone block. Writes bench/results/tire_road.json
(every number of the page) and bench/results/tire_road_passage.png; the page
bench/results/tire_road.md is written by hand from the json.

    /usr/bin/python3 bench/tire_road/run_bench.py [--bin build/bin] [--work DIR]
        [--parts stability,bench,passage]

stability  configs/tire_road_rough.json at 1x, 2x, 3x, 4x the block rate,
           quasi-static blocks, the thesis' 80 softened springs, k0 10.9x lower
           (the thesis' unscaled 1 mm value), a 4x heavier tread: per run the
           passage's peak, its chatter (steps whose force change reverses
           direction by more than 1 % of the peak on both sides) and the lug's
           largest step stiffness K (its series column 'stiffness') times dt^2.
bench      configs/tire_road_rough_50kmh.json once, under
           flock /tmp/cosim-bench.lock nice -n 0 (the machine is shared: the
           load average before and after is recorded): wall time of the whole
           process and of the coupled loop, the coupler's timing table, blocks
           in the footprint (during travel and after scenario.spin_up), each
           passage's impact speed (the face's approach rate at first force).
passage    the lug passage of the 4x rough run beside the stand-alone block
           (bench_block: the lug's grid, springs, adhesion and layer at the
           same rate) under the thesis' linear and quadratic indentations
           (seed 002 fig. 30) whose depth is set so the peak force equals the
           passage's, and the linear load-unload; peak, loading times, the
           work of loading and unloading (hysteresis) -> the PNG.
"""
import argparse
import json
import os
import re
import subprocess
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
RES = os.path.join(ROOT, "bench", "results")
sys.path.insert(0, os.path.join(ROOT, "python"))
from cosim.fig_road import lug_processes, passages  # noqa: E402
from cosim.results import Results  # noqa: E402

ROUGH = os.path.join(ROOT, "configs", "tire_road_rough.json")
FAST = os.path.join(ROOT, "configs", "tire_road_rough_50kmh.json")
LUGS = ("lug0", "lug1", "lug2")
BASE_RATE = 51200  # Hz, seed 002
CHATTER_FRAC = 0.01  # of the passage's peak: a reversal larger than this on both sides


def rate_sets(f):
    """--set arguments for f x the base rate (the layer evaluated at that rate, same memory)."""
    s = ["time.dt=%r" % (1.0 / (BASE_RATE * f)), "output.every=%d" % (512 * f)]
    for n in LUGS:
        s += ["processes.%s.green.rate=%d" % (n, BASE_RATE * f),
              "processes.%s.green.samples=%d" % (n, 256 * f)]
    return s


def lug_sets(key_value):
    return ["processes.%s.%s" % (n, key_value) for n in LUGS]


def cosim(binp, scene, out, sets, quiet=True, prefix=()):
    cmd = list(prefix) + [os.path.join(binp, "cosim"), "run", scene, "--overwrite",
                          "--set", "output.dir=" + out]
    for s in sets:
        cmd += ["--set", s]
    if quiet:
        cmd.append("--quiet")
    t0 = time.time()
    p = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
    wall = time.time() - t0
    if p.returncode:
        raise SystemExit("%s failed (%d):\n%s" % (" ".join(cmd), p.returncode, p.stderr[-2000:]))
    return wall, p.stdout


def chatter(F):
    dF = np.diff(F)
    pk = max(F.max(), 1e-12)
    rev = (dF[:-1] * dF[1:] < 0) & (np.minimum(abs(dF[:-1]), abs(dF[1:])) > CHATTER_FRAC * pk)
    return int(rev.sum())


def passage_stats(run):
    r = Results(run)
    L = r.series("coupler", "lugs")
    dt = r.scene["time"]["dt"]
    out = []
    for p, j, s in passages(L, len(lug_processes(r))):
        F = L["force%d" % p][s]
        if F.max() <= 0:
            continue
        K = r.series("lug%d" % p, "series")["stiffness"][s]
        pos = (F[1:] > 0) & (F[:-1] > 0)
        out.append({"lug": j, "process": p, "t0": float(L["t"][s][0]), "peak": float(F.max()),
                    "min": float(F.min()), "chatter": chatter(F),
                    "max_step_change_compressive": float(abs(np.diff(F))[pos].max()),
                    "K_max": float(K.max()), "K_dt2": float(K.max() * dt * dt)})
    return out


# ------------------------------------------------------------------ stability
def kcrit_element(h, f, zoh):
    """The block's own loop (docs/block-stability.md): the smallest stiffness K of ONE
    contact spring on the synthetic layer's self-term for which the stepping
    F(n) = K (1 - dt sum_{k>=1} g_k F(n-k)) / (1 + K dt g_0) grows, bisection over
    12 g-lengths (bench/block/run_bench.py's kcrit_table at element side h).
    Self-compliance of a uniformly loaded square of side h: 1.1222 / (E* h)."""
    E_star = 25e6 / (1 - 0.49 ** 2)
    S = 1.1222 / (E_star * h)
    dt, Q = 1.0 / (BASE_RATE * f), 255 * f + 1
    w, z = 2 * np.pi * 2000, 0.1
    wd = w * np.sqrt(1 - z * z)
    t = np.arange(Q + 1) * dt
    if zoh:
        s = 1 - np.exp(-z * w * t) * (np.cos(wd * t) + z * w / wd * np.sin(wd * t))
        g = np.diff(s) / dt * S
    else:
        g = (w * w / wd * np.exp(-z * w * t) * np.sin(wd * t))[:Q] * S

    def grows(K):
        N = 12 * Q
        F = np.zeros(N + Q)
        gr = g[1:][::-1] * dt
        for n in range(N):
            F[n + Q - 1] = K * (1 - np.dot(gr, F[n:n + Q - 1])) / (1 + K * dt * g[0])
            if not np.isfinite(F[n + Q - 1]) or abs(F[n + Q - 1]) > 1e4 / S:
                return True
        return abs(F[-Q:]).max() > 2 / S

    if not grows(1e11):
        return None
    lo, hi = 1e3, 1e11
    for _ in range(20):
        mid = np.sqrt(lo * hi)
        lo, hi = (lo, mid) if grows(mid) else (mid, hi)
    return hi


def kcrit_table():
    cells = {"thesis 1 mm": 1e-3, "tire_road_rough 3.3 mm": 3.3e-3,
             "50 km/h 0.825 x 1.547 mm (side sqrt(area))": np.sqrt(0.825e-3 * 1.546875e-3)}
    return [{"cell": k, "h": h, "point_x1": kcrit_element(h, 1, False),
             "zoh_x1": kcrit_element(h, 1, True)} for k, h in cells.items()]


def stiffest_spring(a):
    """k_max of the stand-alone lug block (tire_road_rough's section, base rate,
    ZOH) on a linear ramp to 0.4 mm: its own stepping at the lug's cells."""
    sc = json.load(open(ROUGH))
    sec = dict(sc["processes"]["lug0"], exec="contact_block",
               green=dict(sc["processes"]["lug0"]["green"], rate=BASE_RATE, samples=256),
               road={"kind": "random", "rms": 3e-5, "seed": 1})
    scene = {"name": "lug_alone_1x", "time": {"dt": 1.0 / BASE_RATE, "end": 0.025},
             "scenario": {"kind": "indentation", "profile": "linear", "depth": 4e-4,
                          "ramp_time": 0.025}, "processes": {"block": sec}}
    path = os.path.join(a.work, "alone_1x.json")
    json.dump(scene, open(path, "w"))
    csv = path + ".csv"
    subprocess.run([os.path.join(a.bin, "bench_block"), path, "--csv", csv], check=True,
                   capture_output=True, cwd=ROOT)
    d = np.genfromtxt(csv, delimiter=",", names=True)
    return {"k_max": float(d["k_max"].max()), "peak": float(d["force"].max()),
            "max_step_change": float(abs(np.diff(d["force"])).max()),
            "chatter": chatter(d["force"]), "K_max": float(d["stiffness"].max())}


def stability(a):
    variants = [
        ("1x (51.2 kHz)", rate_sets(1)), ("2x", rate_sets(2)), ("3x", rate_sets(3)),
        ("4x (the scene)", rate_sets(4)),
        ("1x, quasi-static blocks", rate_sets(1) + lug_sets("solver.quasi_static=true")),
        ("1x, thesis' 80 softened springs", rate_sets(1) + lug_sets('springs.soften={"count":80,"at":9e-6}')),
        ("1x, k0 3e5 and release 0.6 N (not area-scaled)",
         rate_sets(1) + lug_sets("springs.k0=3e5") + lug_sets("adhesion.release_force=0.6")),
        ("1x, tread density x4", rate_sets(1) + ["processes.fem.material.density=4400"]),
    ]
    rows = []
    for i, (name, sets) in enumerate(variants):
        out = os.path.join(a.work, "stab%d" % i)
        wall, _ = cosim(a.bin, ROUGH, out, sets, prefix=("nice", "-n", "10"))
        rows.append({"variant": name, "wall": wall, "passages": passage_stats(out)})
        print(name, rows[-1], flush=True)
    return {"stability": rows, "stability_load": os.getloadavg(), "kcrit": kcrit_table()}


# ---------------------------------------------------------------------- bench
def footprint(run):
    r = Results(run)
    L = r.series("coupler", "lugs")
    tr = r.series("coupler", "traction")
    n = len(lug_processes(r))
    k0 = int(np.nonzero(tr["vertical_load"] >= r.scene["scenario"]["sinkage_force"])[0][0])
    loaded = sum((L["force%d" % p][k0:] != 0).astype(int) for p in range(n))
    served = sum((L["lug%d" % p][k0:] >= 0).astype(int) for p in range(n))
    # the revolution after the spin-up, and each passage's impact speed: the face's
    # approach rate (d_k - d_{k-1}) / dt at its block's first nonzero force
    k1 = k0 + int(round(r.scene["scenario"].get("spin_up", 0) / r.scene["time"]["dt"]))
    rev = sum((L["force%d" % p][k1:] != 0).astype(int) for p in range(n))
    impact = []
    for p, j, s in passages(L, n):
        on = np.nonzero(L["force%d" % p][s] != 0)[0]
        if len(on) and on[0] > 0:
            d = L["d%d" % p][s]
            impact.append({"lug": j, "t": float(L["t"][s][on[0]]),
                           "speed": float((d[on[0]] - d[on[0] - 1]) / r.scene["time"]["dt"])})
    return {"travel_from": float(L["t"][k0]), "revolution_from": float(L["t"][min(k1, len(L["t"]) - 1)]),
            "rev_loaded_max": int(rev.max()) if len(rev) else 0,
            "rev_loaded_mean": float(rev.mean()) if len(rev) else 0.0, "impact": impact,
            "loaded_max": int(loaded.max()),
            "loaded_mean": float(loaded.mean()), "served_max": int(served.max()),
            "served_mean": float(served.mean()), "passages": passage_stats(run)}


def phases(r, T, fp):
    """Loop wall time of the sinkage, the spin-up, the revolution after it and the rest
    (the coupler's per-step timing 'wall', T, of the run r)."""
    t, w = T["t"], T["wall"]
    rev_end = fp["revolution_from"] + 2 * np.pi / r.scene["scenario"]["omega"]
    edges = [("sinkage", 0.0, fp["travel_from"]), ("spin_up", fp["travel_from"], fp["revolution_from"]),
             ("revolution", fp["revolution_from"], rev_end), ("rest", rev_end, np.inf)]
    return {name: {"from": float(lo), "to": float(min(hi, t[-1])), "steps": int(np.sum((t >= lo) & (t < hi))),
                   "wall_loop": float(np.sum(w[(t >= lo) & (t < hi)]))} for name, lo, hi in edges}


def summary(out, wall, stdout, before, after):
    """The bench entry of one finished run of the 50 km/h scene in out."""
    m = re.search(r"finished: (\d+) steps, t = ([\d.e+-]+) s, ([\d.]+) s wall", stdout)
    r = Results(out)
    T = r.series("coupler", "timing")
    per = {k: float(np.sum(T[k])) for k in T.keys() if k not in ("t",)}
    fp = footprint(out)
    return {"wall_process": wall, "steps": int(m.group(1)), "t_end": float(m.group(2)),
            "wall_loop": float(m.group(3)), "load_before": before, "load_after": after,
            "timing_sums": per, "stdout": stdout[-6000:], "footprint": fp, "phases": phases(r, T, fp)}


def bench(a):
    out = os.path.join(a.work, "bench50")
    before = open("/proc/loadavg").read().split()[:3]
    wall, stdout = cosim(a.bin, FAST, out, [], quiet=False,
                         prefix=("flock", "/tmp/cosim-bench.lock", "nice", "-n", "0"))
    after = open("/proc/loadavg").read().split()[:3]
    return {"bench": summary(out, wall, stdout, before, after)}


# -------------------------------------------------------------------- passage
def block_scene(a, lug, profile, depth, ramp, end, csv, hold=0.0, quasi=False):
    """bench_block on the lug's block section (the same cells, springs, adhesion, layer, rate)."""
    sc = json.load(open(ROUGH))
    sec = dict(sc["processes"]["lug0"])
    sec["exec"] = "contact_block"
    # the same height statistics, its highest point at 0 (first contact at d = 0: no overlap
    # at t = 0); another realisation than the part of the world road the lug met
    sec["road"] = {"kind": "random", "rms": sec["road"]["rms"], "seed": sec["road"]["seed"]}
    if quasi:
        sec["solver"] = dict(sec["solver"], quasi_static=True)
    scene = {"name": "lug_alone", "time": {"dt": sc["time"]["dt"], "end": end},
             "scenario": {"kind": "indentation", "profile": profile, "depth": depth,
                          "ramp_time": ramp, "hold_time": hold},
             "processes": {"block": sec}}
    path = csv + ".json"
    json.dump(scene, open(path, "w"))
    subprocess.run([os.path.join(a.bin, "bench_block"), path, "--csv", csv], check=True,
                   capture_output=True, cwd=ROOT)
    d = np.genfromtxt(csv, delimiter=",", names=True)
    return d["t"], d["d_road"], d["force"]


def works(d, F):
    """(work of loading, work given back in unloading) J, split at the peak force."""
    k = int(np.argmax(F))
    w_load = float(np.trapz(F[:k + 1], d[:k + 1]))
    w_unload = float(-np.trapz(F[k:], d[k:]))
    return w_load, w_unload


def passage(a):
    run = os.path.join(a.work, "stab3")  # the 4x rough run of the stability part
    r = Results(run)
    L = r.series("coupler", "lugs")
    p, j, s = [q for q in passages(L, len(lug_processes(r))) if L["force%d" % q[0]][q[2]].max() > 0][0]
    t, d, F = L["t"][s], L["d%d" % p][s], L["force%d" % p][s]
    on = np.nonzero(F != 0)[0]
    t, d, F = t[on[0]:on[-1] + 1] - t[on[0]], d[on[0]:on[-1] + 1], F[on[0]:on[-1] + 1]
    kp = int(np.argmax(F))
    t_load, peak = float(t[kp]), float(F[kp])
    d = d - d[0]  # indentation from first contact (the stand-alone road's highest point is at 0)
    res = {"coupled": {"lug": j, "peak": peak, "t_peak": t_load, "d_peak": float(d[kp]),
                       "t_contact": float(t[-1]), "d_last": float(d[-1]), "works": works(d, F), "min": float(F.min())}}
    curves = {"coupled": (t, d, F)}
    for prof in ("linear", "quadratic"):
        csv = os.path.join(a.work, "alone_%s.csv" % prof)
        tried = []  # (depth, peak, curve): the depth whose ramp of the passage's loading time
        D = float(d[kp])  # ends at the passage's peak force, by the secant method
        for it in range(10):
            c = block_scene(a, lug=j, profile=prof, depth=D, ramp=t_load, end=t_load, csv=csv)
            tried.append((D, float(c[2].max()), c))
            if abs(tried[-1][1] - peak) < 1e-3 * peak:
                break
            if len(tried) == 1:
                D *= peak / max(tried[-1][1], 1e-9)
            else:
                (d0, f0, _), (d1, f1, _) = tried[-2], tried[-1]
                D = d1 + (peak - f1) * (d1 - d0) / (f1 - f0)
        D, _, (tt, dd, FF) = min(tried, key=lambda q: abs(q[1] - peak))
        curves[prof] = (tt, dd, FF)
        res[prof] = {"depth": float(D), "peak": float(FF.max()), "works_load": works(dd, FF)[0],
                     "force_at_half_time": float(np.interp(0.5 * t_load, tt, FF)),
                     "force_at_coupled_d_half": float(np.interp(0.5 * d[kp], dd, FF))}
    # linear load and unload at the same rate back to the passage's last approach (the face
    # pulls away while bonded): the stand-alone hysteresis; its quasi-static twin
    D = res["linear"]["depth"]
    t_end = t_load * (2 - d[-1] / D)
    for key, q in (("linear_unload", False), ("linear_unload_qs", True)):
        tt, dd, FF = block_scene(a, lug=j, profile="load_hold_unload", depth=D, ramp=t_load,
                                 end=t_end, csv=os.path.join(a.work, key + ".csv"), quasi=q)
        curves[key] = (tt, dd, FF)
        res[key] = {"peak": float(FF.max()), "works": works(dd, FF), "min": float(FF.min())}
    res["coupled"]["force_at_half_time"] = float(np.interp(0.5 * t_load, t, F))
    res["coupled"]["force_at_d_half"] = float(F[np.nonzero(d >= 0.5 * d[kp])[0][0]])
    plot(curves, res)
    return {"passage": res, "alone_1x": stiffest_spring(a)}


def plot(c, res):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, (at, ad) = plt.subplots(1, 2, figsize=(12, 4.6))
    sty = {"coupled": ("k", "-", "lug passage, coupled (tire_road_rough, 4x)"),
           "linear": ("b", "--", "alone, linear to the same peak"),
           "quadratic": ("r", "-.", "alone, quadratic to the same peak"),
           "linear_unload": ("g", ":", "alone, linear load and unload"),
           "linear_unload_qs": ("0.5", "-", "alone, linear load and unload, quasi-static")}
    for k, (col, ls, lab) in sty.items():
        t, d, F = c[k]
        at.plot(1e3 * t, F, color=col, ls=ls, lw=1.2, label=lab)
        ad.plot(1e3 * d, F, color=col, ls=ls, lw=1.2, label=lab)
    at.set_xlabel("time from first contact (ms)")
    ad.set_xlabel("approach / indentation (mm)")
    for ax in (at, ad):
        ax.set_ylabel("block force (N)")
        ax.axhline(0, color="0.8", lw=0.6)
    at.legend(fontsize=7)
    at.set_title("force history (peak %.0f N)" % res["coupled"]["peak"], fontsize=9)
    ad.set_title("force against indentation: loading and unloading", fontsize=9)
    fig.tight_layout()
    fig.savefig(os.path.join(RES, "tire_road_passage.png"), dpi=110)
    plt.close(fig)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--bin", default=os.path.join(ROOT, "build", "bin"))
    ap.add_argument("--work", default="/tmp/cosim-bench-tire-road")
    ap.add_argument("--parts", default="stability,bench,passage")
    a = ap.parse_args()
    a.bin = os.path.abspath(a.bin)
    os.makedirs(a.work, exist_ok=True)
    path = os.path.join(RES, "tire_road.json")
    out = json.load(open(path)) if os.path.exists(path) else {}
    for part in a.parts.split(","):
        out.update({"stability": stability, "bench": bench, "passage": passage}[part](a))
        json.dump(out, open(path, "w"), indent=1)


if __name__ == "__main__":
    main()
