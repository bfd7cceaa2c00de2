"""cosim.traction.dbp_curve's averaging window (stop 54): each row's slip and
forces averaged over the window centred on it before the rows are binned by
slip, so that a bin the ramp crosses in less than a lug's passage still holds
whole passages.

1. window_means: the centred mean of n rows, nan where the window leaves the
   series, the rows themselves for n = 1, all nan for a series shorter than n.
2. A synthetic dbp run (one row per step, the ramp throughout): the slip
   rises linearly, T_P = B s + A sin(2 pi t / P + phi), a lug passage of
   period P that the ramp crosses a bin of 0.02 in 0.8 P. Averaged over one
   passage (window = P) every bin's T_P is B x its slip to round-off; the rows
   unaveraged (window = 0) miss it by more than A / 10 in some bin (the test
   bites); T_H, T_R follow alike. The scene's scenario.dbp_window is the
   default window.
3. A window of a whole number of passages is as good; one of w = 0.9 P leaves
   at most the amplitude of the passage's mean over w,
   A |sin(pi w / P)| / (pi w / P) (0.11 A).
4. Rows before the travel (phase 0: /coupler/dbp holds zeros there, the
   slip too, while the forces are the sinkage's) are not averaged into the ramp's: the ramp starting right after them, its first
   half window of rows is dropped and the law holds as before.
5. A window below 0 or nan is refused, naming it.
"""
import math
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "e2e"))
from common import check, done  # noqa: E402
from cosim import traction  # noqa: E402
from cosim.errors import CosimError  # noqa: E402

DT, P = 1e-4, 0.05            # s: the step, the lug passage (500 rows)
B, A, TH0 = 400.0, 30.0, 100.0  # N per unit slip, the passage's amplitude, T_H at zero slip (N)
RATE, S0 = 0.5, -0.02         # slip per s of the ramp, the slip at t = 0
LOAD, END = 1000.0, 1.0       # N, s
ROUND_OFF = 1e-9              # N: sums of ~1e4 rows of ~100 N


class FakeRun:
    """What dbp_curve reads of a Results: the scene, /coupler/traction and
    /coupler/dbp (one row per step)."""

    def __init__(self, window, before=0.0):
        t = np.arange(round(END / DT) + 1) * DT
        slip = S0 + RATE * t
        wave = A * np.sin(2 * np.pi * t / P + 0.7)
        tp = B * slip + wave
        th = TH0 + 0.5 * B * slip + 0.5 * wave
        self.tables = {
            "traction": {"t": t, "T_H": th, "T_R": tp - th, "T_P": tp,
                         "vertical_load": np.full(len(t), LOAD), "sinkage": np.full(len(t), 0.03)},
            "dbp": {"t": t, "phase": np.full(len(t), float(traction.DBP_PHASE_RAMP)),
                    "slip": slip, "resistive_force": tp}}
        if before > 0:  # no travel yet: /coupler/dbp's columns 0 (cpl_dbp_row), the forces not
            off = t < before
            for c, v in self.tables["dbp"].items():
                if c != "t":
                    v[off] = 0.0
        self.scene = {"time": {"dt": DT, "end": END},
                      "scenario": {"kind": "tire_travel", "rig": "dbp", "sinkage_force": LOAD,
                                   "dbp_window": window}}

    def series(self, process, name):
        assert process == "coupler"
        return self.tables[name]


def worst(curve, q="T_P"):
    """The largest |bin mean - the law at the bin's mean slip| (N)."""
    law = {"T_P": lambda s: B * s, "T_H": lambda s: TH0 + 0.5 * B * s,
           "T_R": lambda s: -TH0 + 0.5 * B * s}[q]
    return max(abs(c[f"{q}_mean"] - law(c["slip_mean"])) for c in curve)


def part_window_means():
    x = np.arange(10.0) ** 2
    m = traction.window_means(x, 4)
    want = [np.mean(x[k - 2:k + 2]) for k in range(2, 9)]
    check(np.all(np.isnan(m[:2])) and np.isnan(m[9]) and np.allclose(m[2:9], want),
          "window_means: the centred mean of 4 rows (rows k-2..k+1), nan at both ends")
    m3 = traction.window_means(x, 3)
    check(np.isnan(m3[0]) and np.isnan(m3[9]) and np.allclose(m3[1:9], [np.mean(x[k - 1:k + 2]) for k in range(1, 9)]),
          "window_means: an odd window is centred on its row")
    check(np.array_equal(traction.window_means(x, 1), x), "window_means: one row is the row")
    check(np.all(np.isnan(traction.window_means(x[:3], 4))), "window_means: a series shorter than the window: all nan")


def part_law():
    run = FakeRun(P)
    rows_per_bin = 0.02 / RATE / DT
    check(rows_per_bin < P / DT, f"the ramp crosses a bin in {rows_per_bin:.0f} rows, less than a "
          f"passage ({P / DT:.0f}): the case the window is for")
    avg = traction.dbp_curve(run, 0.02)
    raw = traction.dbp_curve(run, 0.02, window=0)
    check(len(avg) >= 20 and len(raw) >= 20, f"the ramp sweeps {len(avg)} bins (the test bites)")
    e_avg, e_raw = worst(avg), worst(raw)
    print(f"T_P against B s: averaged over a passage {e_avg:.3g} N, unaveraged {e_raw:.3g} N (A = {A} N)")
    check(e_avg <= ROUND_OFF * B, f"averaged over one passage every bin's T_P is B x its slip ({e_avg:.3g} N)")
    check(e_raw > A / 10, f"unaveraged some bin misses it by more than A / 10 ({e_raw:.3g} N): the test bites")
    for q in ("T_H", "T_R"):
        e = worst(avg, q)
        check(e <= ROUND_OFF * B, f"{q} alike, averaged ({e:.3g} N)")
    explicit = traction.dbp_curve(run, 0.02, window=P)
    same = lambda c: [(r["rows"], r["slip_mean"], r["T_P_mean"], r["T_H_mean"]) for r in c]
    check(same(explicit) == same(avg), "the default window is the scene's scenario.dbp_window")
    first = min(c["t0_s"] for c in avg)
    check(abs(first - P / 2) <= DT * 1.01, f"the first half window is dropped (first row at {first:.4g} s)")
    check(abs(avg[0]["T_P_W_mean"] - avg[0]["T_P_mean"] / LOAD) < 1e-15, "ratios to the load kept")


def part_other_windows():
    run = FakeRun(P)
    two = worst(traction.dbp_curve(run, 0.02, window=2 * P))
    check(two <= ROUND_OFF * B, f"two passages: as exact ({two:.3g} N)")
    w = 0.9 * P
    short = worst(traction.dbp_curve(run, 0.02, window=w))
    bound = A * abs(math.sin(math.pi * w / P)) / (math.pi * w / P)
    check(short <= bound * (1 + 1e-6), f"0.9 of a passage: within the mean's amplitude {bound:.3g} N "
          f"({short:.3g})")


def part_before_travel():
    start = 0.3
    run = FakeRun(P, before=start)
    curve = traction.dbp_curve(run, 0.02)
    e = worst(curve)
    first = min(c["t0_s"] for c in curve)
    check(e <= ROUND_OFF * B, f"zeros before the travel are not averaged in ({e:.3g} N)")
    check(abs(first - (start + P / 2)) <= DT * 1.01, f"the ramp's first half window is dropped "
          f"(first row at {first:.4g} s, the travel from {start} s)")
    raw = traction.dbp_curve(run, 0.02, window=0)
    check(min(c["t0_s"] for c in raw) >= start - DT / 2, "unaveraged: the ramp's rows only")


def part_bad_window():
    for w in (-0.01, math.nan):
        try:
            traction.dbp_curve(FakeRun(P), 0.02, window=w)
            check(False, f"window {w}: refused")
        except CosimError as e:
            check("window" in str(e), f"window {w}: refused, naming it ({e})")


part_window_means()
part_law()
part_other_windows()
part_before_travel()
part_bad_window()
done()
