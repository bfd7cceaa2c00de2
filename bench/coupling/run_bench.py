#!/usr/bin/python3
"""Coupling benchmark (bench/results/coupling.md):

  paper  the paper-scale tyre in contact: the settled 21 812-grain bed
         (bench/dem/paper_bed.json) under the full 165/65 R13 tread
         (refine 1, 23 808 tets), >= 500 coupled steps in contact; ms per
         step and its split per process (/coupler/timing) for the serial,
         parallel and implicit schemes, with 1 or 2 OpenMP threads per
         process. Runs alternate, the minimum of the repeats is kept.
  wp     work-precision of the coupling on the small tyre scene
         (configs/default.json, its bed settled once and loaded from a
         file): mean T_H, T_R and vertical load over the travel phase,
         against a reference run (implicit, dt/4), versus wall time, for
         the three schemes at three coupling steps.
  report writes bench/results/coupling.md and the PNGs from the JSON.

Usage: run_bench.py BUILD_DIR WORK_DIR [beds] [paper] [wp] [report]
Times are measured: run it under `flock /tmp/cosim-bench.lock` on a quiet
machine (the report records the load average)."""
import json
import os
import subprocess
import sys
import time

import h5py
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
BUILD, WORK = os.path.abspath(sys.argv[1]), os.path.abspath(sys.argv[2])
BIN = os.path.join(BUILD, "bin")
RESULTS = os.path.join(ROOT, "bench", "results")
RAW = os.path.join(RESULTS, "coupling.json")
os.makedirs(WORK, exist_ok=True)

GRAIN = {"density": 2600, "E": 5e6, "nu": 0.3, "restitution": 0.5, "friction": 0.6}
RUBBER = {"density": 1100, "E": 20e6, "nu": 0.45, "restitution": 0.5, "friction": 0.8}
TREAD_MAT = {"E": 20e6, "nu": 0.45, "density": 1100, "damping": 50}


def load_raw():
    return json.load(open(RAW)) if os.path.exists(RAW) else {}


def save_raw(raw):
    json.dump(raw, open(RAW, "w"), indent=1, sort_keys=True)


def cosim_run(scene, name, env=None, timeout=7200):
    path = os.path.join(WORK, name + ".json")
    json.dump(scene, open(path, "w"), indent=1)
    e = dict(os.environ)
    e.update(env or {})
    t0 = time.time()
    p = subprocess.run([os.path.join(BIN, "cosim"), "run", path, "--quiet"], cwd=WORK,
                       capture_output=True, text=True, timeout=timeout, env=e)
    if p.returncode != 0:
        raise RuntimeError(f"{name}: exit {p.returncode}\n{p.stdout[-2000:]}\n{p.stderr[-3000:]}")
    return time.time() - t0, p.stdout


def columns(ds):
    return [c.decode() if isinstance(c, bytes) else str(c) for c in ds.attrs["columns"]]


def load_avg():
    return open("/proc/loadavg").read().split()[:3]


# ------------------------------------------------------------------ beds

def beds():
    """The paper's bed (21 812 grains, 1 x 1 m) and the small scene's bed,
    settled once and saved, so every run starts from the same grains."""
    if not os.path.exists(os.path.join(WORK, "paper_bed.h5")):
        s = json.load(open(os.path.join(ROOT, "bench", "dem", "paper_bed.json")))
        s["output"]["dir"] = os.path.join(WORK, "runs", "paper_bed")
        print("settling the paper bed ...", flush=True)
        cosim_run(s, "paper_bed")
    if not os.path.exists(os.path.join(WORK, "small_bed.h5")):
        s = json.load(open(os.path.join(ROOT, "configs", "default.json")))
        s["time"]["end"] = s["time"]["dt"]
        s["output"]["dir"] = os.path.join(WORK, "runs", "small_bed")
        s["bus"] = {}
        s["processes"]["dem"]["particles"]["save"] = "small_bed.h5"
        print("settling the small bed ...", flush=True)
        cosim_run(s, "small_bed")


def bed_top(path):
    with h5py.File(path, "r") as f:
        x, r = f["x"][:], f["r"][:]
    return float((x[:, 2] + r).max())


# ----------------------------------------------------------------- paper

PAPER_DT, PAPER_STEPS, PAPER_SKIP = 5e-5, 800, 300  # timing over steps 300..800


def paper_scene(scheme, threads, key):
    top = bed_top(os.path.join(WORK, "paper_bed.h5"))
    # the tread's lowest point 0.5 mm above the highest grain: it touches
    # within 100 steps at 0.1 m/s and sinks further for the rest of the run
    rim_z = top + 0.272 + 5e-4
    return {"name": "paper_tyre",
            "time": {"dt": PAPER_DT, "end": PAPER_STEPS * PAPER_DT},
            "output": {"dir": os.path.join(WORK, "runs", f"paper_{key}"),
                       "every": 1000000},
            "coupling": {"scheme": scheme, "handshake_timeout": 1200, "step_timeout": 300},
            "scenario": {"kind": "tire_travel", "rim_center": [0.5, 0.5, rim_z],
                         "sinkage_velocity": 0.1, "sinkage_force": 1e4, "slip": 0.05,
                         "omega": 1.8, "radius": 0.272},
            "processes": {
                "tyre": {"exec": "fem_server", "mesh": {"generate": "tread", "refine": 1, "lugs": 32},
                         "element": "tet4", "material": TREAD_MAT, "fixed": {"group": "rim"},
                         "pressure": {"group": "inner", "value": 2e5}},
                "soil": {"exec": "dem_server", "materials": [GRAIN, RUBBER],
                         "particles": {"file": os.path.join(WORK, "paper_bed.h5")},
                         "walls": [{"type": "box", "lo": [0, 0, 0], "hi": [1, 1, 1], "open_top": True}],
                         "surface_material": 1, "gravity": [0, 0, -9.81], "threads": threads,
                         "overlap_tolerance": 0.05}}}  # a settled bed has small overlaps


def timing_summary(out_dir):
    with h5py.File(os.path.join(out_dir, "results.h5"), "r") as f:
        tim = f["/coupler/timing"][:]
        cols = columns(f["/coupler/timing"])
        load = f["/coupler/traction"][:, 4]
        it = f["/coupler/series"][:, 2]
    w = slice(PAPER_SKIP, None)
    res = {c: float(tim[w, i].mean()) for i, c in enumerate(cols) if c != "t"}
    res["steps"] = int(tim[w].shape[0])
    res["steps_in_contact"] = int((load[w] > 0).sum())
    res["mean_load"] = float(load[w].mean())
    res["iterations"] = float(it[w].mean())
    return res


# (scheme, OpenMP threads per process, OpenMP wait policy). libgomp's default
# waiting spins after each parallel region: with two processes taking turns
# on two cores, the spinning threads of one steal the cores of the other.
PAPER_CONFIGS = [("serial", 2, "active"), ("serial", 2, "passive"), ("serial", 1, "passive"),
                 ("parallel", 1, "passive"), ("parallel", 2, "passive"), ("implicit", 1, "passive")]


def config_key(scheme, threads, wait):
    return f"{scheme}_{threads}" + ("_spin" if wait == "active" else "")


def paper(repeats=2):
    raw = load_raw()
    runs = {config_key(*c): [] for c in PAPER_CONFIGS}
    for rep in range(repeats):
        for scheme, threads, wait in PAPER_CONFIGS:
            key = config_key(scheme, threads, wait)
            env = {"OMP_NUM_THREADS": str(threads), "OMP_WAIT_POLICY": wait}
            wall, _ = cosim_run(paper_scene(scheme, threads, key), f"paper_{key}", env=env)
            res = timing_summary(os.path.join(WORK, "runs", f"paper_{key}"))
            res["run_wall_s"] = wall
            runs[key].append(res)
            print(key, rep, f"{1e3 * res['wall']:.2f} ms/step", "contact steps", res["steps_in_contact"],
                  flush=True)
    best = {k: min(v, key=lambda r: r["wall"]) for k, v in runs.items()}
    for k, c in zip(runs, PAPER_CONFIGS):
        best[k]["scheme"], best[k]["threads"], best[k]["wait"] = c
    raw["paper"] = {"configs": best, "all": runs, "load_avg": load_avg(),
                    "dt": PAPER_DT, "steps": PAPER_STEPS, "skip": PAPER_SKIP}
    save_raw(raw)


# -------------------------------------------------------------------- wp

WP_DTS = [1e-4, 5e-5, 2.5e-5]
WP_REF_DT = 1.25e-5  # dt/4 of the scene's 5e-5
WP_T_TRAVEL = 0.3    # travel (from t = 0.28 s) averaged from here to the end


def small_scene(scheme, dt, tag):
    s = json.load(open(os.path.join(ROOT, "configs", "default.json")))
    s["time"]["dt"] = dt
    s["output"] = {"dir": os.path.join(WORK, "runs", f"wp_{tag}"), "every": 1000000}
    s["bus"] = {}
    s["coupling"]["scheme"] = scheme
    s["processes"]["dem"]["particles"] = {"file": os.path.join(WORK, "small_bed.h5")}
    s["processes"]["dem"]["overlap_tolerance"] = 0.05  # a settled bed has small overlaps
    # one DEM step for all runs, that of the reference: the runs differ only in
    # how often the processes exchange (the coupling step), not in the DEM's
    # own integration (a different DEM step is another granular realization)
    s["processes"]["dem"]["dt"] = WP_REF_DT
    return s


SINK_GRID = np.arange(0.15, 0.2751, 1e-3)  # sinkage with contact, before travel
SINK_WINDOW = 5e-3                        # moving average over 5 ms


def sink_load(tr, cols):
    """Vertical load during the sinkage (prescribed rim motion, same in every
    run until the load reaches 80 N), averaged over 5 ms, on a 1 ms grid."""
    t, load = tr[:, 0], tr[:, cols.index("vertical_load")]
    return [float(load[(t > g - SINK_WINDOW) & (t <= g)].mean()) for g in SINK_GRID]


def wp_metrics(out_dir):
    with h5py.File(os.path.join(out_dir, "results.h5"), "r") as f:
        tr = f["/coupler/traction"][:]
        cols = columns(f["/coupler/traction"])
        cs = f["/coupler/series"][:]
    w = tr[:, 0] >= WP_T_TRAVEL
    return {c: float(tr[w, cols.index(c)].mean()) for c in ("T_H", "T_R", "vertical_load")} | \
        {"iterations": float(cs[:, 2].mean()), "unconverged": int((cs[:, 3] == 0).sum()),
         "steps": int(cs.shape[0]), "sink_load": sink_load(tr, cols)}


def wp_noise():
    """The reference again with a 100x tighter tolerance: its difference to
    the reference is what the DEM's chaos alone makes of a tiny change (the
    error floor of these metrics)."""
    raw = load_raw()
    s = small_scene("implicit", WP_REF_DT, "noise")
    s["coupling"]["implicit"] = {"tolerance": 1e-8}
    wall, _ = cosim_run(s, "wp_noise", env={"OMP_NUM_THREADS": "1"})
    raw["wp"]["noise"] = wp_metrics(os.path.join(WORK, "runs", "wp_noise")) | {"wall": wall}
    save_raw(raw)


def wp_refresh():
    """Recomputes the metrics from the runs already made (no timing)."""
    raw = load_raw()
    W = raw["wp"]
    W["reference"] |= wp_metrics(os.path.join(WORK, "runs", "wp_ref"))
    for r in W["rows"]:
        if "failed" not in r:
            r |= wp_metrics(os.path.join(WORK, "runs", f"wp_{r['scheme']}_{r['dt']:g}"))
    save_raw(raw)


def wp():
    raw = load_raw()
    ref_tag = "ref"
    old = raw.get("wp", {})
    if old.get("reference", {}).get("dem_dt") == WP_REF_DT:  # the same reference run
        ref = old["reference"]
    else:
        wall, _ = cosim_run(small_scene("implicit", WP_REF_DT, ref_tag), f"wp_{ref_tag}",
                            env={"OMP_NUM_THREADS": "1"})
        ref = wp_metrics(os.path.join(WORK, "runs", f"wp_{ref_tag}")) | {"wall": wall,
                                                                       "dem_dt": WP_REF_DT}
    print("reference", ref, flush=True)
    rows = []
    for dt in WP_DTS:
        for scheme in ("serial", "parallel", "implicit"):
            tag = f"{scheme}_{dt:g}"
            try:
                wall, _ = cosim_run(small_scene(scheme, dt, tag), f"wp_{tag}",
                                    env={"OMP_NUM_THREADS": "1"})
            except RuntimeError as e:  # a run that stops is a result too
                why = [ln for ln in str(e).splitlines() if "failed:" in ln]
                rows.append({"scheme": scheme, "dt": dt, "failed": why[0] if why else str(e)[-300:]})
                print(rows[-1], flush=True)
                continue
            m = wp_metrics(os.path.join(WORK, "runs", f"wp_{tag}"))
            rows.append({"scheme": scheme, "dt": dt, "wall": wall} | m)
            print(rows[-1], flush=True)
    raw["wp"] = {"reference": ref, "ref_dt": WP_REF_DT, "rows": rows, "t_travel": WP_T_TRAVEL,
                 "load_avg": load_avg()} | ({"noise": old["noise"]} if "noise" in old else {})
    save_raw(raw)


# ---------------------------------------------------------------- report

def report():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    raw = load_raw()
    md = ["# Coupling schemes: time per step, where it goes, work–precision", "",
          "`/usr/bin/python3 bench/coupling/run_bench.py build WORK beds paper wp report` "
          "(under `flock /tmp/cosim-bench.lock`). Raw numbers: `coupling.json`.", ""]
    if "paper" in raw:
        P = raw["paper"]
        C = P["configs"]
        ref_key = min((k for k in C if C[k]["scheme"] == "serial"), key=lambda k: C[k]["wall"])
        ser = C[ref_key]["wall"]
        md += ["## Paper-scale tyre in contact",
               "",
               f"Settled 21 812-grain bed (bench/dem/paper_bed.json, 1 × 1 m box) under the full "
               f"165/65 R13 tread (refine 1: 23 808 TET4, 32 lugs, inflated, rim fixed), coupling "
               f"step {P['dt'] * 1e6:g} µs, {P['steps']} steps; means over steps "
               f"{P['skip']}–{P['steps']} (the tread in contact, sinking at 0.1 m/s). Minimum of "
               f"{min(len(v) for v in P['all'].values())} alternated runs per configuration; load average "
               f"{' '.join(P['load_avg'])} at the end. 2 cores.", "",
               f"| scheme | OpenMP threads / process, waiting | ms / step | × best serial ({ref_key}) | "
               "tyre compute | soil compute | transfer (both) | coupler mapping + output | overhead | iterations |",
               "|---|---|---|---|---|---|---|---|---|---|"]
        for key, r in C.items():
            scheme, thr = r["scheme"], f"{r['threads']}, {r['wait']}"
            tc, sc = r["tyre.compute"], r["soil.compute"]
            tf = r["tyre.transfer"] + r["soil.transfer"]
            cm = r["coupler.mapping"] + r["coupler.output"]
            crit = tc + sc if scheme == "serial" else max(tc, sc)
            over = r["wall"] - crit
            md.append(f"| {scheme} | {thr} | {1e3 * r['wall']:.2f} | {r['wall'] / ser:.2f} | "
                      f"{1e3 * tc:.2f} | {1e3 * sc:.2f} | {1e3 * tf:.3f} | {1e3 * cm:.3f} | "
                      f"{100 * over / r['wall']:.1f} % | {r['iterations']:.2f} |")
        md += ["", "Per step: compute = the participant's own time in its step (sum over the "
               "implicit scheme's iterations); transfer = request sent → reply received minus "
               "compute (encode, decode, sockets); overhead = wall − compute on the critical path "
               "(serial: tyre + soil; parallel, implicit: the larger of the two, per step), i.e. "
               "transfer + coupler + imbalance.", ""]
        sp, s1 = C.get("serial_2"), C.get("serial_1")
        par = min((C[k] for k in C if C[k]["scheme"] == "parallel"), key=lambda r: r["wall"])
        imp = C.get("implicit_1")
        if sp and s1 and imp and "serial_2_spin" in C:
            dem_share = s1["soil.compute"] / (s1["soil.compute"] + s1["tyre.compute"])
            per_it = imp["soil.compute"] / imp["iterations"]
            md += ["### Findings", "",
                   f"- **parallel vs serial**: {1e3 * par['wall']:.2f} vs {1e3 * ser:.2f} ms per step "
                   f"({par['wall'] / ser:.2f}×; goal ≤ 0.6×: **not met**). The grains take "
                   f"{100 * dem_share:.0f} % of a serial step's compute (soil {1e3 * s1['soil.compute']:.2f} ms, "
                   f"tyre {1e3 * s1['tyre.compute']:.2f} ms, one thread each): running both at once can hide "
                   f"at most the tyre's share, so the bound is {dem_share:.2f}× of the serial step with "
                   f"one thread each on 2 cores; the DEM "
                   f"itself gains little from a second thread ({1e3 * s1['soil.compute']:.2f} → "
                   f"{1e3 * sp['soil.compute']:.2f} ms).",
                   f"- **coupling overhead** (transfer + encode + coupler): serial "
                   f"{100 * (1 - (s1['tyre.compute'] + s1['soil.compute']) / s1['wall']):.1f} % (1 thread), "
                   f"{100 * (1 - (sp['tyre.compute'] + sp['soil.compute']) / sp['wall']):.1f} % (2 threads) "
                   f"of the step (goal < 5 %: **not met**): it is the transfer of the surface arrays "
                   f"(positions, velocities and forces of every surface node, both ways, every step: "
                   f"{1e3 * (s1['tyre.transfer'] + s1['soil.transfer']):.2f} ms); the coupler's own work "
                   f"is {1e3 * (s1['coupler.mapping'] + s1['coupler.output']):.3f} ms. Sending only the "
                   f"nodes in contact (sparse forces, as Chrono does) is the next step.",
                   f"- **OpenMP waiting**: with libgomp's default (spinning) wait, two processes taking "
                   f"turns on 2 cores with 2 threads each run {C['serial_2_spin']['wall'] / sp['wall']:.1f}× "
                   f"slower: the idle process's threads spin on the cores the other needs. `cosim run` "
                   f"therefore starts participants with OMP_WAIT_POLICY=passive unless it is set.",
                   f"- **implicit**: {imp['iterations']:.2f} iterations per step; the soil's compute per "
                   f"iteration is {1e3 * per_it:.2f} ms against {1e3 * par['soil.compute']:.2f} ms for a "
                   f"step without rollback (inferred: the state copy at each step start and the "
                   f"{imp['iterations'] - 1:.1f} restores, dem_state_export/import of 21 812 grains with "
                   f"their contact lists and springs, cost "
                   f"{1e3 * (imp['soil.compute'] - imp['iterations'] * par['soil.compute']) / imp['iterations']:.1f} ms "
                   f"each, about a step). {imp['wall'] / ser:.1f}× the serial step.", ""]
        fig, ax = plt.subplots(figsize=(8, 4))
        keys = list(C)
        for i, key in enumerate(keys):
            r = C[key]
            parts = [("tyre compute", r["tyre.compute"]), ("soil compute", r["soil.compute"]),
                     ("transfer", r["tyre.transfer"] + r["soil.transfer"]),
                     ("coupler", r["coupler.mapping"] + r["coupler.output"])]
            bottom = 0
            for j, (lab, v) in enumerate(parts):
                ax.bar(i - 0.2, 1e3 * v, 0.35, bottom=bottom, color=f"C{j}", label=lab if i == 0 else None)
                bottom += 1e3 * v
            ax.bar(i + 0.2, 1e3 * r["wall"], 0.35, color="0.6", label="wall per step" if i == 0 else None)
        ax.set_xticks(range(len(keys)), [f"{C[k]['scheme']}\n{C[k]['threads']} thr, {C[k]['wait']}"
                                         for k in keys], fontsize=8)
        ax.set_ylabel("ms per coupled step")
        ax.set_title("paper-scale tyre in contact: time per step (stacked: summed over processes)")
        ax.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(os.path.join(RESULTS, "coupling_paper.png"), dpi=120)
        md += ["![time per step](coupling_paper.png)", ""]
    if "wp" in raw:
        W = raw["wp"]
        ref = W["reference"]
        md += ["## Work–precision on the small tyre scene", "",
               f"configs/default.json (2 181 grains, coarse tread), its bed settled once; DEM step "
               f"{W['ref_dt']:g} s in every run (the coupling step sub-steps it), 1 thread per process. "
               f"Metrics: mean T_H, T_R and vertical load over t ≥ {W['t_travel']} s (travel), and "
               f"the vertical load during the sinkage before it (5 ms means, 0.15–0.275 s, RMS); "
               f"error against the "
               f"reference run (implicit, dt = {W['ref_dt']:g} s: T_H = {ref['T_H']:.4g} N, "
               f"T_R = {ref['T_R']:.4g} N, load = {ref['vertical_load']:.4g} N). Load average "
               f"{' '.join(W['load_avg'])}.", "",
               "| scheme | dt (s) | wall (s) | iterations / step | steps not converged | T_H err | T_R err | load err | sinkage load err |",
               "|---|---|---|---|---|---|---|---|---|"]
        if "noise" in W:
            W["noise"]["scheme"], W["noise"]["dt"] = "implicit, tolerance 1e-8 (noise floor)", W["ref_dt"]
        rows = W["rows"] + ([W["noise"]] if "noise" in W else [])
        for r in rows:
            if "failed" in r:
                md.append(f"| {r['scheme']} | {r['dt']:g} | stopped: {r['failed'].split('failed: ', 1)[-1][:220]} "
                          f"| | | | | |")
                continue
            e = {m: abs(r[m] - ref[m]) / max(abs(ref[m]), 1e-30) for m in ("T_H", "T_R", "vertical_load")}
            a, b = np.array(r["sink_load"]), np.array(ref["sink_load"])
            e["sink_load"] = float(np.sqrt(np.mean((a - b) ** 2)) / np.sqrt(np.mean(b ** 2)))
            r["err"] = e
            md.append(f"| {r['scheme']} | {r['dt']:g} | {r['wall']:.1f} | {r['iterations']:.2f} | "
                      f"{r['unconverged']} of {r['steps']} | {100 * e['T_H']:.2f} % | {100 * e['T_R']:.2f} % | {100 * e['vertical_load']:.2f} % | "
                      f"{100 * e['sink_load']:.2f} % |")
        def sink_errs(scheme):
            return ", ".join(f"{100 * r['err']['sink_load']:.2g} %" if "err" in r else "stopped"
                             for r in W["rows"] if r["scheme"] == scheme)
        noise = W.get("noise", {}).get("err", {})
        md += ["", "### Findings", "",
               f"- The travel-phase means (T_H, T_R, load over 0.2 s of travel) are dominated by the "
               f"grains' chaos: the reference run repeated with a 100× tighter tolerance differs from "
               f"it by {100 * noise.get('T_H', float('nan')):.0f} %, {100 * noise.get('T_R', float('nan')):.0f} % "
               f"and {100 * noise.get('vertical_load', float('nan')):.0f} %; the schemes cannot be "
               f"ranked by them.",
               f"- The vertical load during the sinkage (before the travel) is reproducible to "
               f"{100 * noise.get('sink_load', float('nan')):.2g} % (noise floor) and measures the "
               f"coupling: errors at dt = 1e-4, 5e-5, 2.5e-5 s: serial {sink_errs('serial')}; "
               f"parallel {sink_errs('parallel')}; implicit {sink_errs('implicit')}. Serial converges "
               f"to the floor by dt = 5e-5 s. The parallel scheme's one-step force lag injects energy "
               f"(negative damping, docs/coupling-schemes.md §1): at 5e-5 s the tread's kinetic energy grew from 2e-6 J to "
               f"0.6 J (serial: 2e-5 J) and its load curve left the others'; at 2.5e-5 s it stayed "
               f"stable. The implicit scheme removes the lag but, here, is not more "
               f"accurate than serial (whose grains see the surface of the last step and whose tread "
               f"gets the forces of the same step: no lag) and costs 4–5× its wall time.",
               ""]
        fig, axs = plt.subplots(1, 4, figsize=(15, 3.6))
        for ax, m in zip(axs, ("T_H", "T_R", "vertical_load", "sink_load")):
            for j, scheme in enumerate(("serial", "parallel", "implicit")):
                rr = [r for r in W["rows"] if r["scheme"] == scheme and "failed" not in r]
                ax.loglog([r["wall"] for r in rr], [max(r["err"][m], 1e-6) for r in rr], "o-",
                          color=f"C{j}", label=scheme)
                for r in rr:
                    ax.annotate(f"{r['dt']:g}", (r["wall"], max(r["err"][m], 1e-6)), fontsize=6)
            if "noise" in W and "err" in W["noise"]:
                ax.axhline(max(W["noise"]["err"][m], 1e-6), ls="--", color="0.5",
                           label="noise floor (reference, tolerance 1e-8)")
            ax.set_xlabel("wall time (s)")
            ax.set_ylabel(f"relative error of mean {m}" if m != "sink_load" else "RMS error, sinkage load")
            ax.set_title(m)
        axs[3].legend(fontsize=7, loc="upper right")
        fig.tight_layout()
        fig.savefig(os.path.join(RESULTS, "coupling_wp.png"), dpi=120)
        md += ["", "![work-precision](coupling_wp.png)", ""]
    open(os.path.join(RESULTS, "coupling.md"), "w").write("\n".join(md) + "\n")
    save_raw(raw)


parts = sys.argv[3:] or ["beds", "paper", "wp", "report"]
for p in parts:
    {"beds": beds, "paper": paper, "wp": wp, "wp_noise": wp_noise, "wp_refresh": wp_refresh,
     "report": report}[p]()
