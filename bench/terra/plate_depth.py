"""Plate pressure-sinkage curves of beds of different depth, compared (issue 22's depth criterion: the curve at
the tyre's contact pressure must not change when the bed is made deeper).

Each group is LABEL=FILE,FILE,... (plate records of `cosim_terra plate`, one per bed seed). Per run: the sinkage at
which each pressure of --pressures is first reached (3-row running mean of the 1 mm rows) and the pressure at each
sinkage of --sinkages; per group the mean over its runs and the Student-t 95 % half-width; each group against the
first (the reference) by the difference of the means and its Welch 95 % half-width (the beds differ, so unpaired;
a sinkage read from rows of dz carries dz^2/12 of rounding variance besides the spread).
Writes OUT.csv (every run and group) and OUT.png (each group's mean curve with its min-max band).

    /usr/bin/python3 bench/terra/plate_depth.py OUT LABEL=F1,F2,F3 LABEL=... [--pressures 25,50,75,100]
        [--sinkages 5,10,20]
"""
import argparse
import math
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from scipy import stats  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from plot_terra import read_record  # noqa: E402


def run_values(path, pressures, sinkages):
    meta, d = read_record(path)
    z, p = d["z"], d["p"]
    pm = np.convolve(p, np.ones(3) / 3, mode="same")
    pm[0], pm[-1] = p[0], p[-1]
    zs = []
    for q in pressures:
        hit = np.nonzero(pm >= q * 1e3)[0]
        zs.append(z[hit[0]] * 1e3 if hit.size else math.nan)
    ps = [float(np.interp(s * 1e-3, z, pm)) / 1e3 if z[-1] >= s * 1e-3 else math.nan for s in sinkages]
    return meta, z, pm, zs + ps


def mean_hw(v):
    v = np.asarray(v, float)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return math.nan, math.nan, 0
    if v.size == 1:
        return v[0], math.nan, 1
    return v.mean(), stats.t.ppf(0.975, v.size - 1) * v.std(ddof=1) / math.sqrt(v.size), v.size


def welch(a, b, quantum=0.0):
    """b's mean minus a's and its Welch 95 % half-width; quantum: the values' rounding step (a sinkage read
    from 1 mm rows), whose variance quantum^2 / 12 each sample carries besides the spread."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    a, b = a[np.isfinite(a)], b[np.isfinite(b)]
    if a.size < 2 or b.size < 2:
        return math.nan, math.nan
    q2 = quantum ** 2 / 12
    va, vb = (a.var(ddof=1) + q2) / a.size, (b.var(ddof=1) + q2) / b.size
    dof = (va + vb) ** 2 / (va ** 2 / (a.size - 1) + vb ** 2 / (b.size - 1)) if va + vb > 0 else a.size + b.size - 2
    return b.mean() - a.mean(), stats.t.ppf(0.975, dof) * math.sqrt(va + vb)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out")
    ap.add_argument("groups", nargs="+")
    ap.add_argument("--pressures", default="25,50,75,100", help="kPa")
    ap.add_argument("--sinkages", default="5,10,20", help="mm")
    a = ap.parse_args()
    pressures = [float(x) for x in a.pressures.split(",")]
    sinkages = [float(x) for x in a.sinkages.split(",")]
    names = [f"z_mm_at_{q:g}kPa" for q in pressures] + [f"p_kPa_at_{s:g}mm" for s in sinkages]
    groups = []

    def quantum(k):  # the sinkage columns are read from the records' rows (--dz, 1 mm by default)
        return dz_mm if k < len(pressures) else 0.0

    for g in a.groups:
        label, _, files = g.partition("=")
        groups.append((label, [run_values(f, pressures, sinkages) + (f,) for f in files.split(",")]))
    zrow = groups[0][1][0][1]
    dz_mm = float(zrow[1] - zrow[0]) * 1e3 if len(zrow) > 1 else 0.0
    fig, ax = plt.subplots(figsize=(7, 4.5))
    with open(a.out + ".csv", "w") as f:
        f.write("group,run,bed_m,grains," + ",".join(names) + "\n")
        for label, runs in groups:
            for meta, _, _, vals, path in runs:
                f.write(f"{label},{os.path.basename(path)},{meta.get('surface_z_m', '')},{meta.get('grains', '')},"
                        + ",".join(f"{v:.2f}" for v in vals) + "\n")
            stat = [mean_hw([r[3][k] for r in runs]) for k in range(len(names))]
            f.write(f"{label},mean,,," + ",".join(f"{m:.2f}" for m, _, _ in stat) + "\n")
            f.write(f"{label},ci95,,," + ",".join(f"{h:.2f}" for _, h, _ in stat) + "\n")
        ref_label, ref = groups[0]
        for label, runs in groups[1:]:
            diffs = [welch([r[3][k] for r in ref], [r[3][k] for r in runs], quantum(k)) for k in range(len(names))]
            f.write(f"{label} - {ref_label},difference,,," + ",".join(f"{d:.2f}" for d, _ in diffs) + "\n")
            f.write(f"{label} - {ref_label},welch95,,," + ",".join(f"{h:.2f}" for _, h in diffs) + "\n")
    print("| group | runs | bed (m) | " + " | ".join(names) + " |")
    print("|---|---|---|" + "---|" * len(names))
    for label, runs in groups:
        beds = [float(r[0].get("surface_z_m", "nan")) for r in runs]
        stat = [mean_hw([r[3][k] for r in runs]) for k in range(len(names))]
        print(f"| {label} | {len(runs)} | {min(beds):.3f}-{max(beds):.3f} | "
              + " | ".join(f"{m:.1f} ± {h:.1f}" if np.isfinite(h) else f"{m:.1f}" for m, h, _ in stat) + " |")
        zgrid = np.linspace(0, min(r[1][-1] for r in runs), 200)
        curves = np.array([np.interp(zgrid, r[1], r[2]) / 1e3 for r in runs])
        line, = ax.plot(zgrid * 1e3, curves.mean(axis=0), label=f"{label} ({len(runs)} beds)")
        ax.fill_between(zgrid * 1e3, curves.min(axis=0), curves.max(axis=0), color=line.get_color(), alpha=0.15)
    ref_label, ref = groups[0]
    for label, runs in groups[1:]:
        diffs = [welch([r[3][k] for r in ref], [r[3][k] for r in runs], quantum(k)) for k in range(len(names))]
        print(f"| {label} − {ref_label} | | | " + " | ".join(
            f"{d:+.1f} ± {h:.1f}{' (outside)' if abs(d) > h else ''}" for d, h in diffs) + " |")
    ax.set_xlabel("plate sinkage z (mm)")
    ax.set_ylabel("plate pressure p (kPa), 3-row mean")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(a.out + ".png", dpi=120)


if __name__ == "__main__":
    main()
