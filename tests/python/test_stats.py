"""cosim.stats: the 95 % intervals cover the true mean 95 ± 3 % of the time.

1. Batch means within a run: 1000 synthetic AR(1) series x_i = mu + phi
   (x_{i-1} - mu) + e_i (e_i ~ N(0, 1), started from the stationary law) of
   known mean mu, for phi = 0 (independent), 0.9 and 0.98 (a correlation time
   of 19 and 99 rows: the traction of a lug passage); the interval must hold
   mu in 95 ± 3 % of the trials, and its mean width must match the one the
   AR(1) law gives: 2 t sd(mean) with var(mean) -> sigma^2 / (n (1 - phi)^2)
   (within 15 %: the batches' own noise).
2. Across runs: 1000 sets of N = 3 independent run means (normal), covered
   in 95 ± 3 %.
3. Too short a window has no interval (nan), never a made-up one.
"""
import math
import os
import sys

import numpy as np
from scipy.signal import lfilter

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "e2e"))
from common import check, done  # noqa: E402
from cosim import stats  # noqa: E402

TRIALS = 1000
MU = 3.0
rng = np.random.default_rng(20261201)


def ar1(phi, n):
    """n rows of a stationary AR(1) of mean MU and unit innovations."""
    x_before = rng.normal() / math.sqrt(1 - phi * phi)  # the stationary variance 1 / (1 - phi^2)
    x, _ = lfilter([1.0], [1.0, -phi], rng.normal(size=n), zi=[phi * x_before])
    return x + MU


for phi, n in ((0.0, 2000), (0.9, 8000), (0.98, 20000)):
    hits, widths = 0, []
    for _ in range(TRIALS):
        r = stats.batch_means(ar1(phi, n))
        hits += abs(r["mean"] - MU) <= r["half"]
        widths.append(r["half"])
    cover = hits / TRIALS
    check(0.92 <= cover <= 0.98, f"AR(1) phi = {phi}, n = {n}: coverage {cover:.3f} in 0.95 ± 0.03")
    sd_mean = 1.0 / ((1 - phi) * math.sqrt(n))  # large-n law of the AR(1) mean
    want = 1.96 * sd_mean
    got = float(np.mean(widths))
    check(abs(got / want - 1) < 0.15, f"phi = {phi}: mean half-width {got:.4g} vs {want:.4g}")

hits = 0
for _ in range(TRIALS):
    means = MU + rng.normal(size=3)
    a = stats.across_runs(means)
    hits += abs(a["mean"] - MU) <= a["half"]
    check(a["runs"] == 3, "three runs counted")
cover = hits / TRIALS
check(0.92 <= cover <= 0.98, f"across 3 runs: coverage {cover:.3f} in 0.95 ± 0.03")

check(math.isnan(stats.batch_means(np.ones(20))["half"]), "20 rows: too short, no interval")
check(math.isnan(stats.across_runs([1.0])["half"]), "one run: no spread, no interval")
check(stats.batch_means(np.full(400, 2.5))["half"] == 0.0, "a constant series: zero width")
done()
