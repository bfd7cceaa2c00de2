"""bench/results/tire_soil.md from the timed runs of bench/tire_soil/run_paper.sh.

    PYTHONPATH=python /usr/bin/python3 bench/tire_soil/report.py WORK_DIR
        [--sweep LABEL=DIR]... [--sens NAME,NAME,...] [NAME...]

NAME (default: paper deep) are run dirs in WORK_DIR with NAME.time and NAME.log
beside them; a missing one is reported as not run. --sweep (repeatable): a
`cosim sweep` output dir (LABEL: its rig) whose summary.csv goes into the
report; all sweeps are drawn side by side, like seed 000 fig. 15, beside
their terramechanics reference (the sweep's reference.csv). --sens: timed runs
of one scene that differ in the coupling step or scheme; the first is the
reference, the finest step is taken as "exact" and each run's traction means
are compared with it over a common window (error against run time). Writes
bench/results/tire_soil.md (then bench/tire_soil/findings.md, hand-written,
appended as is), tire_soil.json, tire_soil_<NAME>.png, tire_soil_sweep.png,
tire_soil_sensitivity.png."""
import json
import math
import os
import re
import sys

import numpy as np

from cosim import Results
from cosim.sweep_cli import (QUANTITIES, DEFAULT_SKIP_TRAVEL_M, REFERENCE_FILE, SUMMARY_FILE, draw,
                              read_summary, summarise_run, travel_window)

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")
RESULTS = os.path.join(ROOT, "bench", "results")
SETTLED_RE = re.compile(r"bed of (\d+) grains settled in (\d+) steps \(([\d.]+) s\)")
LOOP_RE = re.compile(r"^Loop time .*?(?=^results:|\Z)", re.S | re.M)
SMOOTH_S = 5e-3  # running mean drawn over the raw rows
SLIP_KEY = "scenario.slip"
FINISHED_RE = re.compile(r"finished: (\d+) steps, t = ([\d.e+-]+) s, ([\d.]+) s wall")


def read_time(path):
    d = {}
    for line in open(path):
        k, _, v = line.partition(":")
        d[k.strip()] = v.strip()
    return d


def settle_seconds(run_dir):
    logs = os.path.join(run_dir, "logs")
    for f in sorted(os.listdir(logs)) if os.path.isdir(logs) else []:
        m = SETTLED_RE.search(open(os.path.join(logs, f), errors="replace").read())
        if m:
            return int(m.group(1)), int(m.group(2)), float(m.group(3))
    return None, None, math.nan


def one(work, name):
    run = os.path.join(work, name)
    if not os.path.exists(run + ".time"):
        return None
    t = read_time(run + ".time")
    log = open(run + ".log", errors="replace").read()
    loop = LOOP_RE.search(log)
    fin = FINISHED_RE.search(log)
    grains, settle_steps, settle_s = settle_seconds(run)
    res = {"name": name, "scene": t.get("scene"), "args": t.get("args", ""),
           "rc": int(t.get("rc", -1)),
           "wall_s": float(t.get("wall_s", "nan")), "load_before": t.get("load_before"),
           "load_after": t.get("load_after"), "loop_table": loop.group(0).strip() if loop else "",
           "steps": int(fin.group(1)) if fin else None, "grains": grains,
           "settle_steps": settle_steps, "settle_s": settle_s}
    if res["rc"] != 0 or not os.path.exists(os.path.join(run, "results.h5")):
        res["error"] = log.strip().splitlines()[-3:] if log.strip() else ["no log"]
        return res
    with Results(run) as r:
        tr = r.series("coupler", "traction")
        s = summarise_run(r, DEFAULT_SKIP_TRAVEL_M)
        sc = r.scene["scenario"]
        res["dt_us"] = 1e6 * r.scene["time"]["dt"]
        tim = r.timing
        res["loop_s"] = {c: float(tim[c].sum()) for c in tim.columns if c != "t"}
        speed = sc["omega"] * sc["radius"] * (1 - sc["slip"])
        res["travel_m"] = float((tr["t"][-1] - s["travel_start_s"]) * speed)
        res.update({k: v for k, v in s.items()})
        res["sinkage_force"] = sc["sinkage_force"]
        dem = r.series("soil")
        res["max_overlap_ratio"] = float(dem["max_overlap_ratio"].max())
        plot(r, tr, s, speed, os.path.join(RESULTS, f"tire_soil_{name}.png"), name)
    return res


def plot(r, tr, s, speed, path, name):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    x = (tr["t"] - s["travel_start_s"]) * speed
    fig, ax = plt.subplots(3, 1, figsize=(8, 8), sharex=True)
    k = max(1, len(x) // 2000)  # 2000 points per curve; 5 ms means for the eye
    n = max(1, int(round(SMOOTH_S / r.scene["time"]["dt"])))

    def smooth(v):
        return np.convolve(v, np.ones(n) / n, mode="same")
    for q, c in [("T_H", "tab:blue"), ("T_R", "tab:red"), ("T_P", "tab:green")]:
        ax[0].plot(x[::k], tr[q][::k], color=c, lw=0.4, alpha=0.35)
        ax[0].plot(x[::k], smooth(tr[q])[::k], color=c, lw=1.2, label=f"{q} (5 ms mean)")
    ax[0].set_ylabel("N")
    ax[0].legend(fontsize=7)
    ax[1].plot(x[::k], tr["vertical_load"][::k], lw=0.4, alpha=0.35)
    ax[1].plot(x[::k], smooth(tr["vertical_load"])[::k], lw=1.2, label="vertical load")
    ax[1].axhline(r.scene["scenario"]["sinkage_force"], color="k", ls=":", label="target")
    ax[1].set_ylabel("N")
    ax[1].legend(fontsize=7)
    ax[2].plot(x[::k], 1e3 * tr["sinkage"][::k], label="rim descent (from its start)")
    ax[2].set_ylabel("mm")
    ax[2].set_xlabel("travel (m); negative: sinkage phase")
    ax[2].legend(fontsize=7)
    for a in ax:
        a.axvline(DEFAULT_SKIP_TRAVEL_M, color="0.5", lw=0.8)
    ax[0].set_title(f"{name}: traction, load and sinkage (steady window right of the grey line)",
                    fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def table(res):
    rows = ["| quantity | mean | min | max |", "|---|---|---|---|"]
    for q in QUANTITIES:
        f = 1e3 if q == "sinkage" else 1
        u = "mm" if q == "sinkage" else "N"
        rows.append(f"| {q} ({u}) | {f * res[q + '_mean']:.2f} | {f * res[q + '_min']:.2f} | "
                    f"{f * res[q + '_max']:.2f} |")
    return rows


def sweep_section(label, d):
    notes = []
    rows = read_summary(os.path.join(d, SUMMARY_FILE), notes)
    head = list(rows[0]) if rows else []
    keep = [head[0]] + [c for c in head if c.endswith(("_mean", "_ci95", "_min", "_max"))
                        or c in ("travel_start_s", "window_t0_s", "window_t1_s")]
    md = [f"### rig: {label}", "", f"`cosim sweep` output `{os.path.basename(os.path.normpath(d))}`; "
          + "; ".join(n for n in notes if n.startswith("window")) + ".", "",
          "| " + " | ".join(keep) + " |", "|" + "---|" * len(keep)]

    def cell(v):
        return f"{v:.4g}" if isinstance(v, (int, float)) else json.dumps(v)
    md += ["| " + " | ".join(cell(r[c]) for c in keep) + " |" for r in rows]
    return md + [""]


def sweep_plot(sweeps, path):
    """Seed 000 fig. 15, one panel per rig (cosim.sweep_cli.draw), each point
    marked with its run's mean vertical load."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, len(sweeps), figsize=(6.5 * len(sweeps), 4.8), sharey=True,
                             squeeze=False)
    for ax, (label, d) in zip(axes[0], sweeps):
        rows = read_summary(os.path.join(d, SUMMARY_FILE))
        ref = os.path.join(d, REFERENCE_FILE)
        pos = draw(ax, SLIP_KEY, rows, ref if os.path.exists(ref) else None)
        for x, r in zip(pos, rows):
            ax.annotate(f"{r['vertical_load_mean']:.0f} N", (x, 0), textcoords="offset points",
                        xytext=(0, -22), ha="center", fontsize=7, color="0.35")
        ax.set_xlabel("slip s (grey: mean vertical load of the run)")
        ax.set_title(f"rig: {label}", fontsize=10)
    axes[0][0].set_ylabel("force (N)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


SENS_Q = ["T_H", "T_R", "T_P", "vertical_load"]


def sens_one(work, name):
    """One sensitivity run: its scheme, step, loop time and the traction
    series (None if it did not run)."""
    run = os.path.join(work, name)
    if not os.path.exists(run + ".time"):
        return None
    t = read_time(run + ".time")
    res = {"name": name, "args": t.get("args", ""), "rc": int(t.get("rc", -1)),
           "wall_s": float(t.get("wall_s", "nan")), "load": f"{t.get('load_before')} / {t.get('load_after')}"}
    if not os.path.exists(os.path.join(run, "results.h5")):
        return res
    with Results(run) as r:
        tr = r.series("coupler", "traction")
        res["scheme"] = r.scene["coupling"]["scheme"]
        res["dt"] = r.scene["time"]["dt"]
        res["t"], res["q"] = tr["t"].copy(), {q: tr[q].copy() for q in SENS_Q}
        res["loop_s"] = float(r.timing["wall"].sum())
        res["steps"] = len(r.timing["wall"])
        sc = r.scene["scenario"]
        res["start"] = float(travel_window(tr, r.scene, 0)[3])
        res["speed"] = sc["omega"] * sc["radius"] * (1 - sc["slip"])
    if res["rc"] != 0:
        log = open(run + ".log", errors="replace").read().strip().splitlines()
        res["error"] = next((l for l in log if "failed:" in l), log[-1] if log else "")
    return res


def window_means(r, t0, t1):
    m = (r["t"] >= t0) & (r["t"] <= t1 + 1e-12)
    return {q: float(r["q"][q][m].mean()) if m.any() else math.nan for q in SENS_Q}


def sens_section(work, names):
    """Finished runs and interrupted ones (exit 130: too slow to finish here)
    against the finest finished run, each over the window both cover: from
    0.1 m of the finest run's travel (or its travel start, if the other run
    ended before that) to the shorter run's end."""
    runs = [sens_one(work, n) for n in names]
    done = [r for r in runs if r and r["rc"] == 0 and "t" in r]
    usable = [r for r in runs if r and r["rc"] in (0, 130) and "t" in r]
    md = ["## How the figures move with the coupling step and scheme", ""]
    if not done:
        return md + ["No sensitivity run finished.", ""], {}
    exact = min(done, key=lambda r: (r["dt"], r["scheme"] != "implicit"))
    skip0 = exact["start"] + DEFAULT_SKIP_TRAVEL_M / exact["speed"]
    for r in usable:
        t1 = min(r["t"][-1], exact["t"][-1])
        t0 = skip0 if t1 > skip0 else exact["start"]
        r["window"] = (t0, t1)
        r["mean"], r["exact_mean"] = window_means(r, t0, t1), window_means(exact, t0, t1)
        r["ms"] = 1e3 * r["loop_s"] / r["steps"]
        r["loop_per_s"] = r["ms"] * 1e-3 / r["dt"]  # loop wall seconds per simulated second
    md += [f"Each run from the same saved bed, load rig, 5 % slip, timed alone under the lock. "
           f"Differences: against the finest finished run (`{exact['name']}`, {exact['scheme']}, "
           f"dt = {exact['dt'] * 1e6:g} µs) over the window both cover (from 0.1 m of travel, "
           "t = {:.3f} s, to the shorter run's end). Cost: the coupled loop's wall time per simulated "
           "second (the coupler's timing table).".format(skip0), "",
           "| run | scheme | dt (µs) | exit | load avg before / after | ms/step | loop s per simulated s | window (s) | " +
           " | ".join(f"{q} mean (N)" for q in SENS_Q) + " | " +
           " | ".join(f"Δ{q} (N)" for q in SENS_Q[:3]) + " |",
           "|" + "---|" * (8 + len(SENS_Q) + 3)]
    for r in runs:
        if r is None:
            continue
        if r not in usable:
            md.append(f"| {r['name']} | {r.get('scheme', '?')} | "
                      f"{r['dt'] * 1e6 if 'dt' in r else float('nan'):g} | {r['rc']} | {r['load']} | failed: "
                      f"{r.get('error', '')} |" + " |" * (len(SENS_Q) + 5))
            continue
        w = r["window"]
        md.append(f"| {r['name']} | {r['scheme']} | {r['dt'] * 1e6:g} | {r['rc']} | {r['load']} | {r['ms']:.2f} | "
                  f"{r['loop_per_s']:.0f} | {w[0]:.3f}–{w[1]:.3f} | " +
                  " | ".join(f"{r['mean'][q]:.2f}" for q in SENS_Q) + " | " +
                  " | ".join(f"{r['mean'][q] - r['exact_mean'][q]:+.2f}" for q in SENS_Q[:3]) + " |")
    sens_plot(usable, exact, os.path.join(RESULTS, "tire_soil_sensitivity.png"))
    md += ["", "![sensitivity](tire_soil_sensitivity.png)", ""]
    return md, {r["name"]: {k: v for k, v in r.items() if k not in ("t", "q")} for r in runs if r}


def sens_plot(ok, exact, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6.5, 4.2))
    for q, color in [("T_H", "tab:blue"), ("T_R", "tab:red"), ("T_P", "tab:green")]:
        for r in ok:
            if r is exact:
                continue
            err = abs(r["mean"][q] - r["exact_mean"][q])
            ax.scatter(r["loop_per_s"], err, color=color,
                       label=q if r is next(x for x in ok if x is not exact) else None)
            ax.annotate(f"{r['scheme']} {r['dt'] * 1e6:g} µs", (r["loop_per_s"], err), fontsize=6,
                        xytext=(3, 3), textcoords="offset points")
    ax.axvline(exact["loop_per_s"], color="0.6", lw=0.8, ls=":")
    ax.set_xscale("log")
    ax.set_xlabel("coupled loop wall time per simulated second (s; dotted: the finest run)")
    ax.set_ylabel(f"|mean - mean of {exact['name']}| (N)")
    ax.set_title("traction means: difference from the finest run against run time", fontsize=9)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main():
    args = sys.argv[1:]
    sweeps, sens = [], []
    while "--sweep" in args:
        i = args.index("--sweep")
        label, _, d = args[i + 1].partition("=")
        sweeps.append((label, d))
        del args[i:i + 2]
    if "--sens" in args:
        i = args.index("--sens")
        sens = args[i + 1].split(",")
        del args[i:i + 2]
    work = args[0]
    names = args[1:] or ["paper", "deep"]
    done = {n: one(work, n) for n in names}
    md = ["# The paper's tyre on soil at full scale: wall time and traction", "",
          "`bash bench/tire_soil/run_paper.sh build WORK paper` (and `SCENE=configs/tire_soil_paper_deep.json "
          "... deep`), then `PYTHONPATH=python /usr/bin/python3 bench/tire_soil/report.py WORK`. "
          "Each run: the bed generated and settled in the run, the tyre's sinkage at 0.1 m/s to the "
          "scene's load, then travel at 5 % slip (ω = 1.8 rad/s, r = 0.272 m: 0.465 m/s) to the end of the "
          "scene (0.5 m and a little more). One run each (timed under the shared benchmark lock), serial "
          "scheme at the run's coupling step (stated per run), `threads: auto` for the DEM. Raw numbers: "
          "`tire_soil.json`.", ""]
    for n in names:
        res = done[n]
        md.append(f"## {n}")
        md.append("")
        if res is None:
            md += ["**Not run** (no timed run in this report).", ""]
            continue
        md.append(f"Scene `{res['scene']}`{' with `' + res['args'] + '`' if res['args'] else ''}: "
                  f"{res['grains']} grains; load average before "
                  f"{res['load_before']}, after {res['load_after']} (2 cores, shared with other "
                  "jobs: the wall times are upper bounds for an idle machine).")
        md.append("")
        if "error" in res:
            md += [f"**Failed** (exit {res['rc']}) after {res['wall_s']:.0f} s:", "", "```"] + \
                  res["error"] + ["```", ""]
            continue
        rest = res["wall_s"] - res["settle_s"] - res["loop_s"]["wall"]
        md += [f"- coupling step {res['dt_us']:g} µs.",
               f"- total wall time: **{res['wall_s']:.0f} s ({res['wall_s'] / 60:.1f} min)**, of "
               f"which settling the bed {res['settle_s']:.0f} s ({res['settle_steps']} DEM steps), "
               f"the coupled loop {res['loop_s']['wall']:.0f} s ({res['steps']} steps, "
               f"{1e3 * res['loop_s']['wall'] / res['steps']:.2f} ms/step), the rest {rest:.0f} s "
               "(start-up: mesh, the tyre's initial static solve, handshake; closing the output).",
               f"- travel: {res['travel_m']:.3f} m from t = {res['travel_start_s']:.3f} s "
               f"(the load reached {res['sinkage_force']} N there); steady window from "
               f"{DEFAULT_SKIP_TRAVEL_M} m of travel, t = {res['window_t0_s']:.3f}–"
               f"{res['window_t1_s']:.3f} s ({res['window_rows']} steps).",
               f"- largest grain overlap in the run: {res['max_overlap_ratio']:.3f} of the radius.",
               "", "Per process (the coupler's loop-time table, printed at the end of the run):", "",
               "```", res["loop_table"], "```", ""]
        md += ["Traction over the steady window (`/coupler/traction`; T_R is negative: against the travel):",
               ""] + table(res) + ["", f"![{n}](tire_soil_{n}.png)", ""]
    if sweeps:
        md += ["## Slip sweep", ""]
        for label, d in sweeps:
            md += sweep_section(label, d)
        sweep_plot(sweeps, os.path.join(RESULTS, "tire_soil_sweep.png"))
        md += ["![sweep](tire_soil_sweep.png)", ""]
    sens_json = {}
    if sens:
        sens_md, sens_json = sens_section(work, sens)
        md += sens_md
    json.dump({"runs": done, "sensitivity": sens_json}, open(os.path.join(RESULTS, "tire_soil.json"), "w"),
              indent=1, default=str)
    findings = os.path.join(os.path.dirname(os.path.abspath(__file__)), "findings.md")
    if os.path.exists(findings):
        md += [open(findings).read().rstrip()]
    open(os.path.join(RESULTS, "tire_soil.md"), "w").write("\n".join(md) + "\n")
    print("wrote", os.path.join(RESULTS, "tire_soil.md"))


if __name__ == "__main__":
    main()
