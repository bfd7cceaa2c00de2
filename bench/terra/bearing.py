"""The virtual plate's failure pressure against the bearing capacity of a square surface footing
(Terzaghi 1943; N_q from Prandtl and Reissner, N_gamma by Vesic 1973, Meyerhof 1963 and Hansen 1970;
shape factors s_q = 1 + tan(phi), s_gamma = 0.6 and depth factor d_q = 1 + 2 tan(phi) (1 - sin(phi))^2 D/B
of De Beer 1970 and Hansen 1970; c = 0: the grains have no cohesion):

    q_ult = gamma D N_q s_q d_q + 0.5 gamma B N_gamma s_gamma

with D the plate's sinkage, gamma the bed's unit weight under the plate (the CSV's bulk density times g).
Before the soil fails the plate's pressure lies below q_ult(D); once it fails in general shear the plate
punches on at q_ult(D), rising with D through the N_q term. So the check is the ratio p / q_ult over a window of
sinkage where the plate has failed (--window, in plate widths; default 0.125-0.375 B): its mean, least and
largest value. A floor within the failure zone shows as a ratio that climbs through the window.
Also printed: the depth below the plate of a strip footing's Prandtl log-spiral zone (Vesic's wedge angle
45 + phi/2), which the floor must lie below for the failure not to feel it.

    /usr/bin/python3 bench/terra/bearing.py PLATE.csv... [--phi 37.2,34.6] [--window 0.125,0.375]
"""
import argparse
import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from plot_terra import read_record  # noqa: E402

G = 9.81


def read_plate(path):
    meta, d = read_record(path)
    return meta, d["z"], d["p"]


def factors(phi_deg):
    t = math.tan(math.radians(phi_deg))
    nq = math.exp(math.pi * t) * math.tan(math.radians(45 + phi_deg / 2)) ** 2
    return t, nq, {"Vesic": 2 * (nq + 1) * t,
                   "Meyerhof": (nq - 1) * math.tan(math.radians(1.4 * phi_deg)),
                   "Hansen": 1.5 * (nq - 1) * t}


def q_ult(phi_deg, b, d, gamma, n_gamma):
    t, nq, ng = factors(phi_deg)
    sq, sg = 1 + t, 0.6
    dq = 1 + 2 * t * (1 - math.sin(math.radians(phi_deg))) ** 2 * min(d / b, 1.0)
    return gamma * d * nq * sq * dq + 0.5 * gamma * b * ng[n_gamma] * sg


def zone_depth(phi_deg, b):
    t = math.tan(math.radians(phi_deg))
    a0 = math.radians(45 + phi_deg / 2)
    th = np.linspace(0, math.pi / 2, 2001)
    return float((b / 2 / math.cos(a0) * np.exp(th * t) * np.sin(a0 + th)).max())


def ratios(z, p, b, gamma, phi, n_gamma, window):
    sel = (z >= window[0] * b) & (z <= window[1] * b)
    r = np.array([pi / q_ult(phi, b, zi, gamma, n_gamma) for zi, pi in zip(z[sel], p[sel])])
    return (np.nan,) * 4 if r.size == 0 else (r.mean(), r.min(), r.max(), r[-1] / r[0])


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("plates", nargs="+")
    ap.add_argument("--phi", default="37.2,34.6", help="peak friction angles (deg) to compare with")
    ap.add_argument("--window", default="0.125,0.375", help="sinkage window, in plate widths")
    a = ap.parse_args()
    phis = [float(x) for x in a.phi.split(",")]
    window = [float(x) for x in a.window.split(",")]
    print("plate,bed_m,seed,B_m,gamma_N_m3,p_at_window_start_kPa,p_at_window_end_kPa," + ",".join(
        f"{m}_phi{phi:g}_{k}" for phi in phis for m in ("Vesic", "Meyerhof", "Hansen")
        for k in ("mean", "min", "max", "end_over_start")) + "," +
        ",".join(f"zone_depth_phi{phi:g}_m" for phi in phis))
    for path in a.plates:
        head, z, p = read_plate(path)
        b = float(head["width_m"])
        gamma = float(head["bulk_density_kg_m3"]) * G
        sel = (z >= window[0] * b) & (z <= window[1] * b)
        cols = [os.path.basename(path), head["surface_z_m"], head["seed"], f"{b:g}", f"{gamma:.0f}",
                f"{p[sel][0] / 1e3:.1f}" if sel.any() else "nan", f"{p[sel][-1] / 1e3:.1f}" if sel.any() else "nan"]
        cols += [f"{v:.2f}" for phi in phis for m in ("Vesic", "Meyerhof", "Hansen")
                 for v in ratios(z, p, b, gamma, phi, m, window)]
        cols += [f"{zone_depth(phi, b):.3f}" for phi in phis]
        print(",".join(cols))


if __name__ == "__main__":
    main()
