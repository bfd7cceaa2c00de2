"""How many beds the sand scene's curve needs for every 95 % half-width of T_H, T_R,
T_P from 0 to 40 % slip (bins of 0.05) to be <= 0.05 of the load (issue 22's headline).

From two four-bed sweeps' curves (cosim.fig_dbp CSVs): per bin and quantity the spread of
the run means, sd = half-width * 2 / t(0.975, 3), pooled over the sweeps (6 dof); then,
by simulation, an N-bed sweep's 24 half-widths t(0.975, N-1) * s / sqrt(N), each s drawn
as sd * sqrt(chi2(N-1) / (N-1)) (normal run means; the 24 taken as independent, the pooled
sd as the truth: both approximations, stated where the numbers are quoted).
    PYTHONPATH=python /usr/bin/python3 bench/tire_soil/beds_needed.py [CURVE_A.csv CURVE_B.csv [LOAD_N]]"""
import sys

import numpy as np
from scipy import stats

from cosim.traction import read_dbp_curve

QUANTITIES = ("T_H", "T_R", "T_P")
BIN = 0.05


def half_widths(path):
    rows, _ = read_dbp_curve(path)
    return {round(r["slip_lo"] / BIN): {q: r[q + "_ci95"] for q in QUANTITIES} for r in rows}


def main():
    args = sys.argv[1:]
    a = args[0] if args else "bench/results/tire_soil_sand_dbp4box_curve.csv"
    b = args[1] if len(args) > 1 else "bench/results/tire_soil_sand_dbp4s51_curve.csv"
    limit = 0.05 * (float(args[2]) if len(args) > 2 else 1000.0)
    curves = [half_widths(a), half_widths(b)]
    t3 = stats.t.ppf(0.975, 3)
    sd = np.array([np.sqrt(np.mean([(c[k][q] * 2 / t3) ** 2 for c in curves]))
                   for k in range(round(0.4 / BIN)) for q in QUANTITIES])
    print(f"spread of the run means over {len(sd)} bin quantities: median {np.median(sd):.0f} N, "
          f"largest {sd.max():.0f} N; limit {limit:.0f} N")
    rng = np.random.default_rng(1)
    for n in (3, 4, 5, 6, 8):
        tn = stats.t.ppf(0.975, n - 1)
        s = sd[None, :] * np.sqrt(rng.chisquare(n - 1, size=(20000, len(sd))) / (n - 1))
        largest = (tn * s / np.sqrt(n)).max(axis=1)
        print(f"{n} beds: largest of the {len(sd)} half-widths, median {np.median(largest):.0f} N; "
              f"P(every one <= {limit:.0f} N) = {(largest <= limit).mean():.2f}")


if __name__ == "__main__":
    main()
