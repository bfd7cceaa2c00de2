#!/usr/bin/python3
"""Plots and tables of the virtual soil tests (bench/terra/run_terra.sh).

usage: plot_terra.py RESULTS_DIR [SET...]
Reads RESULTS_DIR/terra/*.csv (records), soil_*.json (fits per packing),
RESULTS_DIR/terra_params_*.json and terra_reference_*.csv; writes
RESULTS_DIR/terra_*.png and prints the markdown tables of terra.md. SETs:
deep, paper (run_terra.sh's deep/paper plates with the fine/coarse shear
box), sand (its sand stages); default deep and paper."""
import glob
import json
import math
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def read_record(path):
    """A terra record: '# key: value' lines, a header, rows (terra/ter_io.c)."""
    meta, cols, rows = {}, None, []
    with open(path) as f:
        for line in f:
            line = line.strip()
            if not line:
                continue
            if line.startswith("#"):
                k, _, v = line[1:].partition(":")
                meta[k.strip()] = v.strip()
            elif cols is None:
                cols = line.split(",")
            else:
                rows.append([float(x) for x in line.split(",")])
    data = np.array(rows) if rows else np.zeros((0, len(cols)))
    return meta, {c: data[:, i] for i, c in enumerate(cols)}


def fits(res, bed):
    return [json.load(open(p)) for p in sorted(glob.glob(os.path.join(res, "terra", f"soil_{bed}_s*.json")))]


STYLES = ["-", "--", ":"]
WIDTH_COLORS = {"0.060": "tab:blue", "0.110": "tab:orange", "0.165": "tab:green"}


def plot_plates(res, bed, soil_fits):
    fig, ax = plt.subplots(1, 2, figsize=(11, 4.2))
    for path in sorted(glob.glob(os.path.join(res, "terra", f"plate_{bed}_b*_s*.csv"))):
        meta, d = read_record(path)
        b = path.split("_b")[1][:5]
        seed = int(meta["seed"])
        for a in ax:
            a.plot(1e3 * d["z"], d["p"] / 1e3, STYLES[(seed - 1) % 3], color=WIDTH_COLORS.get(b, "k"), lw=1,
                   label=f"b = {b} m" if seed == 1 else None)
    for k, f in enumerate(soil_fits):  # fitted k_eq z^n, shared n, per packing
        pf = f["plate_fit"]
        z = np.linspace(pf["z_min"], pf["z_max"], 50)
        for pl in pf["plates"]:
            b = "%.3f" % pl["width"]
            for a in ax:
                a.plot(1e3 * z, pl["k_eq"] * z ** pf["n_shared"] / 1e3, color="k", lw=0.8, ls=STYLES[k % 3],
                       alpha=0.6, label="fit k_eq z^n" if (k == 0 and b == "0.060" and a is ax[0]) else None)
    ax[0].set(xlabel="sinkage z [mm]", ylabel="plate pressure p [kPa]", title=f"plate sinkage, {bed} bed")
    ax[1].set(xscale="log", yscale="log", xlabel="z [mm]", ylabel="p [kPa]", title="log-log (fit range)")
    ax[1].set_ylim(bottom=0.1)
    ax[0].legend(fontsize=8)
    fig.text(0.5, 0.005, "packings: seed 1 solid, 2 dashed, 3 dotted", ha="center", fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(res, f"terra_plates_{bed}.png"), dpi=110)
    plt.close(fig)


SIG_COLORS = {"2500": "tab:blue", "5000": "tab:orange", "10000": "tab:green", "20000": "tab:red",
              "50000": "tab:purple", "100000": "tab:brown"}


def plot_shear(res, soil, soil_fits):
    fig, ax = plt.subplots(1, 3, figsize=(15, 4.2))
    for path in sorted(glob.glob(os.path.join(res, "terra", f"shear_{soil}_sig*_s*.csv"))):
        meta, d = read_record(path)
        sig = path.split("_sig")[1].split("_")[0]
        seed = int(meta["seed"])
        c = SIG_COLORS.get(sig, "k")
        ax[0].plot(1e3 * d["j"], d["tau"] / 1e3, STYLES[(seed - 1) % 3], color=c, lw=1,
                   label=f"sigma_n = {float(sig) / 1e3:g} kPa" if seed == 1 else None)
        ax[1].plot(1e3 * d["j"], 1e3 * d["dilation"], STYLES[(seed - 1) % 3], color=c, lw=1)
    jmax = max(ax[0].get_xlim()[1], 1e-3) * 1e-3  # m: the records' travel
    for k, f in enumerate(soil_fits):
        for t in f["mohr_coulomb"]["tests"]:
            j = np.linspace(0, jmax, 100)
            ax[0].plot(1e3 * j, t["tau_f_fit"] * (1 - np.exp(-j / t["K"])) / 1e3, color="k", lw=0.7,
                       ls=STYLES[k], alpha=0.6)
        sig = np.array([t["sigma"] for t in f["mohr_coulomb"]["tests"]])
        tau = np.array([t["tau_plateau"] for t in f["mohr_coulomb"]["tests"]])
        ax[2].plot(sig / 1e3, tau / 1e3, "osd"[k % 3], mfc="none", label=f"packing {k + 1}")
        s = np.linspace(0, 1.1 * sig.max(), 10)
        mc = f["mohr_coulomb"]
        ax[2].plot(s / 1e3, (mc["c"] + s * math.tan(math.radians(mc["phi_deg"]))) / 1e3, ls=STYLES[k], color="k",
                   lw=0.8, label=f"c = {mc['c']:.0f} Pa, phi = {mc['phi_deg']:.1f} deg")
    xmax = ax[0].get_xlim()[1]
    ax[0].set(xlabel="shear displacement j [mm]", ylabel="tau [kPa]", title=f"direct shear, {soil} grains",
              xlim=(0, xmax))
    ax[0].legend(fontsize=8)
    ax[1].set(xlabel="j [mm]", ylabel="platen rise [mm]", title="dilation (< 0: contraction)", xlim=(0, xmax))
    ax[2].set(xlabel="sigma_n on the shear plane [kPa]", ylabel="tau (plateau) [kPa]", title="Mohr-Coulomb",
              xlim=(0, None), ylim=(0, None))
    ax[2].legend(fontsize=8)
    fig.text(0.5, 0.005, "packings: seed 1 solid, 2 dashed, 3 dotted; black: Janosi-Hanamoto fits", ha="center",
             fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(res, f"terra_shear_{soil}.png"), dpi=110)
    plt.close(fig)


def plot_checks(res):
    pairs = [("plate_deep_b0.110_s1.csv", "check_plate_deep_b0.110_half_speed.csv", "half speed (0.01 m/s)"),
             ("plate_deep_b0.165_s1.csv", "check_plate_deep_b0.165_big_box.csv", "container 0.825 m (walls 2 b)"),
             ("plate_deep_b0.110_s1.csv", "check_plate_deep_b0.110_2E.csv", "grains 2 E")]
    have = [p for p in pairs if all(os.path.exists(os.path.join(res, "terra", f)) for f in p[:2])]
    if not have:
        return
    fig, ax = plt.subplots(1, len(have) + 1, figsize=(4.2 * (len(have) + 1), 3.8))
    for a, (ref, chk, what) in zip(ax, have):
        for f, lab in ((ref, "as measured"), (chk, what)):
            _, d = read_record(os.path.join(res, "terra", f))
            a.plot(1e3 * d["z"], d["p"] / 1e3, label=lab)
        a.set(xlabel="z [mm]", ylabel="p [kPa]", title=ref.replace(".csv", ""))
        a.legend(fontsize=8)
    sh = os.path.join(res, "terra", "check_shear_fine_sig5000_half_speed.csv")
    if os.path.exists(sh):
        a = ax[-1]
        for f, lab in (("shear_fine_sig5000_s1.csv", "0.02 m/s"), (os.path.basename(sh), "0.01 m/s")):
            _, d = read_record(os.path.join(res, "terra", f))
            a.plot(1e3 * d["j"], d["tau"] / d["sigma"], label=lab)
        a.set(xlabel="j [mm]", ylabel="tau / sigma", title="shear, fine, 5 kPa: speed")
        a.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(res, "terra_checks.png"), dpi=110)
    plt.close(fig)


def plot_reference(res, bed):
    files = sorted(glob.glob(os.path.join(res, f"terra_reference_{bed}_W*.csv")),
                   key=lambda p: float(p.split("_W")[1][:-4]))
    if not files:
        return
    fig, ax = plt.subplots(1, len(files), figsize=(5 * len(files), 4), squeeze=False)
    for a, path in zip(ax[0], files):
        meta, d = read_record(path)
        s = 100 * d["s"]
        for q, c, lab in (("DP", "tab:blue", "DP = F_t - R"), ("T_over_r", "tab:green", "T/r (Shinone's T_H)"),
                          ("F_t", "tab:olive", "F_t"), ("R", "tab:red", "R")):
            a.plot(s, d[q], color=c, label=lab)
            a.fill_between(s, d[q + "_lo"], d[q + "_hi"], color=c, alpha=0.2, lw=0)
        a.axhline(0, color="k", lw=0.5)
        a.set(xlabel="slip [%]", ylabel="force [N]",
              title=f"{bed} bed, W = {float(meta['load_N']):g} N, z(0) = {1e3 * d['z'][0]:.0f} mm")
        a.legend(fontsize=8)
    fig.text(0.5, 0.005, "rigid wheel r = 0.272 m, b = 0.165 m; band: min..max over the packings' parameter sets",
             ha="center", fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(res, f"terra_reference_{bed}.png"), dpi=110)
    plt.close(fig)


def tables(res, bed, soil_fits):
    params = os.path.join(res, f"terra_params_{bed}.json")
    if not soil_fits or (len(soil_fits) > 1 and not os.path.exists(params)):
        return
    P = json.load(open(params)) if len(soil_fits) > 1 else None
    print(f"\n### {bed} bed\n")
    print("| packing | n | k_c [N/m^(n+1)] | k_phi [N/m^(n+2)] | k_eq(0.165) | c [Pa] | phi [deg] | K [mm] | "
          "n per plate (0.06/0.11/0.165) | rms ln p |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for k, f in enumerate(soil_fits):
        s, pf = f["soil"], f["plate_fit"]
        keq = s["k_c"] / 0.165 + s["k_phi"]
        nown = "/".join("%.2f" % p["n_own"] for p in pf["plates"])
        print(f"| {k + 1} | {s['n']:.3f} | {s['k_c']:.4g} | {s['k_phi']:.4g} | {keq:.4g} | {s['c']:.0f} | "
              f"{s['phi_deg']:.1f} | {1e3 * s['K']:.2f} | {nown} | {pf['rms_log_p']:.3f} |")
    if P:  # two or more packings: their mean and spread (combine)
        m, sd = P["soil"], P["std"]
        keq = m["k_c"] / 0.165 + m["k_phi"]
        print(f"| **mean ± std** | {m['n']:.3f} ± {sd['n']:.3f} | {m['k_c']:.4g} ± {sd['k_c']:.2g} | "
              f"{m['k_phi']:.4g} ± {sd['k_phi']:.2g} | {keq:.4g} | {m['c']:.0f} ± {sd['c']:.0f} | "
              f"{m['phi_deg']:.1f} ± {sd['phi_deg']:.1f} | {1e3 * m['K']:.2f} ± {1e3 * sd['K']:.2f} | | |")
    print("\n| packing | sigma [kPa] | tau plateau [kPa] | tau peak [kPa] | tau_f fit [kPa] | K [mm] |")
    print("|---|---|---|---|---|---|")
    for k, f in enumerate(soil_fits):
        for t in f["mohr_coulomb"]["tests"]:
            print(f"| {k + 1} | {t['sigma'] / 1e3:.2f} | {t['tau_plateau'] / 1e3:.3f} | {t['tau_peak'] / 1e3:.3f} | "
                  f"{t['tau_f_fit'] / 1e3:.3f} | {1e3 * t['K']:.2f} |")
    for path in sorted(glob.glob(os.path.join(res, f"terra_reference_{bed}_W*.csv"))):
        meta, d = read_record(path)
        print(f"\nW = {meta['load_N']} N:\n")
        print("| s | z [mm] | DP [N] (band) | T/r [N] (band) | F_t [N] | R [N] | T [N m] |")
        print("|---|---|---|---|---|---|---|")
        for i in range(len(d["s"])):
            if round(100 * d["s"][i]) % 5:
                continue
            print(f"| {d['s'][i]:.2f} | {1e3 * d['z'][i]:.1f} | {d['DP'][i]:.1f} ({d['DP_lo'][i]:.1f}..{d['DP_hi'][i]:.1f})"
                  f" | {d['T_over_r'][i]:.1f} ({d['T_over_r_lo'][i]:.1f}..{d['T_over_r_hi'][i]:.1f}) | "
                  f"{d['F_t'][i]:.1f} | {d['R'][i]:.1f} | {d['T'][i]:.2f} |")


SETS = {"deep": "fine", "paper": "coarse", "sand": "sand"}  # plate bed: its shear box's grains


def main():
    res = sys.argv[1] if len(sys.argv) > 1 else "bench/results"
    names = sys.argv[2:] or ["deep", "paper"]
    bad = [n for n in names if n not in SETS]
    if bad:
        sys.exit(f"plot_terra.py: unknown set {', '.join(bad)} (known: {', '.join(SETS)})")
    for bed, soil in ((n, SETS[n]) for n in names):
        sf = fits(res, bed)
        plot_plates(res, bed, sf)
        plot_shear(res, soil, sf)
        plot_reference(res, bed)
        tables(res, bed, sf)
    plot_checks(res)


if __name__ == "__main__":
    main()
