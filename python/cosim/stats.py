"""Confidence intervals of means: within one run by batch means, across runs
by the spread of the run means.

A run's traction series is autocorrelated (a lug passes every few hundred
steps), so the sample variance over n rows says nothing about the mean's
error. Non-overlapping batch means (Law & Kelton 2000, §9.5.3; Schmeiser
1982): cut the window into b batches of m rows; when m is long against the
correlation time the batch means are nearly independent and normal, and

    x̄ ± t_{b-1, 0.975} · s_b / √b

is a 95 % interval of the mean (s_b: the standard deviation of the batch
means). The batch size is chosen from the data: start with
``MAX_BATCHES`` batches and double the batch size (halve b) while the lag-1
autocorrelation of the batch means exceeds ``BATCH_LAG1_MAX``, down to
``MIN_BATCHES`` (Fishman & Yarberry 1997 "LBatch" in its simplest form). A
window too short for ``MIN_BATCHES`` batches of ``MIN_BATCH_ROWS`` rows has
no interval (nan): the run is too short to say.

Across N independent realisations (different beds) the run means are
independent by construction: x̄ ± t_{N-1, 0.975} · s / √N.
"""
import math

import numpy as np
from scipy import stats as _st

LEVEL = 0.95
MAX_BATCHES = 32      # start: enough degrees of freedom that t_{b-1} is near the normal's
MIN_BATCHES = 8       # fewer leaves t_{b-1} too wide (t_7 = 2.36) and s_b too noisy
MIN_BATCH_ROWS = 4    # a batch of fewer rows is no average
BATCH_LAG1_MAX = 0.2  # batch means this correlated at lag 1 are taken as dependent


def _t(dof):
    return float(_st.t.ppf(0.5 + LEVEL / 2, dof))


def lag1(x):
    """Lag-1 autocorrelation of x (0 for fewer than 3 values or no spread)."""
    x = np.asarray(x, float)
    if len(x) < 3:
        return 0.0
    d = x - x.mean()
    den = float(d @ d)
    return float(d[1:] @ d[:-1]) / den if den > 0 else 0.0


def batch_means(x, max_batches=MAX_BATCHES, min_batches=MIN_BATCHES):
    """{mean, half (95 % half-width, nan when too short), batches, batch_rows,
    lag1} of the mean of the series x by non-overlapping batch means. Rows
    left over at the end of the window (n mod m) are dropped from the batches
    but not from the mean."""
    x = np.asarray(x, float)
    n = len(x)
    out = {"mean": float(x.mean()) if n else math.nan, "half": math.nan,
           "batches": 0, "batch_rows": 0, "lag1": math.nan}
    b = min(max_batches, n // MIN_BATCH_ROWS)
    while b >= min_batches:
        m = n // b
        means = x[:b * m].reshape(b, m).mean(axis=1)
        r = lag1(means)
        if r <= BATCH_LAG1_MAX or b // 2 < min_batches:
            out.update(half=_t(b - 1) * float(means.std(ddof=1)) / math.sqrt(b),
                       batches=b, batch_rows=m, lag1=r)
            return out
        b //= 2
    return out


def interval(x, min_rows=MIN_BATCH_ROWS):
    """batch_means(x) with every batch at least min_rows rows long (a length
    that covers the series' correlation time, e.g. a lug's passage), and no
    interval (half nan) when the batch means are still correlated at the
    fewest batches (lag-1 above BATCH_LAG1_MAX): the window is too short
    against the correlation time, and an interval would be too narrow."""
    n = len(np.asarray(x))
    bm = batch_means(x, max_batches=min(MAX_BATCHES, n // max(int(min_rows), MIN_BATCH_ROWS)))
    if not bm["lag1"] <= BATCH_LAG1_MAX:
        bm["half"] = math.nan
    return bm


def across_runs(means):
    """{mean, half, runs} of independent run means (half nan for one run)."""
    v = np.asarray([m for m in means if not math.isnan(m)], float)
    n = len(v)
    half = _t(n - 1) * float(v.std(ddof=1)) / math.sqrt(n) if n >= 2 else math.nan
    return {"mean": float(v.mean()) if n else math.nan, "half": half, "runs": n}
