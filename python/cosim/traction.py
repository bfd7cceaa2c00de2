"""The steady travel of a tyre run and its traction summary (used by
`cosim sweep`, cosim.Results.traction_summary and bench/tire_soil), and the
traction-slip curve of a dbp-rig run (scenario.rig = "dbp", coupler/README.md):
``/coupler/traction`` and ``/coupler/dbp`` -> rows binned by the measured slip,
each quantity's mean with its 95 % batch-means interval (cosim.stats); and
the curve across several such runs on different beds, bin by bin, with the
interval from the spread of the runs' bin means."""
import math

import numpy as np

from . import stats
from .errors import CosimError

QUANTITIES = ["T_H", "T_R", "T_P", "vertical_load", "sinkage"]
# the dbp curve: the traction row's quantities and the rig's resistive force
# sinkage (m, /coupler/traction) too: two convergence rows (bench/results/
# sand_calibration.md, stop 52) moved it by 7-8 % while the forces stayed in
# their intervals, so the curve gives it with its own interval
DBP_QUANTITIES = ["T_H", "T_R", "T_P", "vertical_load", "resistive_force", "sinkage"]
DBP_BIN_WIDTH = 0.02  # slip: ten points over 0-0.2, as fig. 15's slips are spaced
DBP_PHASE_RAMP = 2    # /coupler/dbp phase: 0 sinkage, 1 hold, 2 ramp
DBP_WINDOW_S = 0.1    # scenario.dbp_window's default (coupler.h CPL_DBP_WINDOW)


def travel_window(traction, scene, skip_travel):
    """(row mask, t0, t1, travel_start) of the steady travel of one run."""
    sc = scene.get("scenario", {})
    if sc.get("kind") != "tire_travel":
        raise CosimError("scenario.kind is not 'tire_travel': no traction to summarise")
    t, load = traction["t"], traction["vertical_load"]
    reached = np.nonzero(load >= sc["sinkage_force"])[0]
    if len(reached) == 0:
        return np.zeros(len(t), bool), math.nan, math.nan, math.nan
    start = t[reached[0]]
    speed = sc["omega"] * sc["radius"] * (1 - sc["slip"])
    t0 = start + (skip_travel / speed if speed > 0 else 0.0)
    mask = t >= t0
    return mask, t0, (t[-1] if mask.any() else math.nan), start


def batch_time(scene, given=None):
    """The shortest batch of an interval (s): given, else scenario.dbp_window
    (the scene's averaging time), else DBP_WINDOW_S."""
    if given is not None:
        return float(given)
    return float(scene.get("scenario", {}).get("dbp_window", DBP_WINDOW_S))


def batch_rows(scene, given=None):
    """batch_time in rows of the traction series (one per step, at least 1)."""
    return max(1, math.ceil(batch_time(scene, given) / float(scene["time"]["dt"]) - 1e-9))


def summarise_run(results, skip_travel, batch_s=None):
    """{column: value} of one run: the window and, of each quantity, the mean,
    its 95 % half-width by batch means of at least batch_time(scene, batch_s)
    each (stats.interval: nan when the window is too short to say), min and
    max."""
    tr = results.series("coupler", "traction")
    mask, t0, t1, start = travel_window(tr, results.scene, skip_travel)
    rows = batch_rows(results.scene, batch_s)
    row = {"travel_start_s": start, "window_t0_s": t0, "window_t1_s": t1,
           "window_rows": int(mask.sum()), "runs": 1}
    for q in QUANTITIES:
        v = tr[q][mask]
        row[f"{q}_mean"] = float(np.mean(v)) if len(v) else math.nan
        row[f"{q}_ci95"] = stats.interval(v, rows)["half"]
        row[f"{q}_min"] = float(np.min(v)) if len(v) else math.nan
        row[f"{q}_max"] = float(np.max(v)) if len(v) else math.nan
    if is_dbp(results.scene):
        # the window's means mix the slips the ramp swept: the curve is the answer
        row["dbp_curve"] = dbp_curve(results)
    return row


def is_dbp(scene):
    sc = scene.get("scenario", {})
    return sc.get("kind") == "tire_travel" and sc.get("rig") == "dbp"


def dbp_series(results):
    """{column: array} of a dbp run: /coupler/traction's columns and
    /coupler/dbp's (the same rows, one per step)."""
    if not is_dbp(results.scene):
        raise CosimError("scenario.rig is not 'dbp': the run has no /coupler/dbp")
    tr, db = results.series("coupler", "traction"), results.series("coupler", "dbp")
    out = {c: tr[c] for c in tr}
    out.update({c: db[c] for c in db})
    return out


def window_means(x, n, valid=None):
    """The centred running mean of x over n rows (n >= 1): row k holds the
    mean of rows k - n // 2 .. k - n // 2 + n - 1, nan where that window
    leaves the series (its first n // 2 and last n - 1 - n // 2 rows) or,
    given valid (a bool per row), holds a row that is not."""
    x = np.asarray(x, dtype=float)
    out = np.full(len(x), math.nan)
    ok = np.ones(len(x), bool) if valid is None else np.asarray(valid, bool)
    if n <= 1:
        return np.where(ok, x, math.nan)
    if len(x) < n:
        return out
    c = np.concatenate(([0.0], np.cumsum(np.where(ok, x, 0.0))))
    k = np.concatenate(([0], np.cumsum(ok)))
    h = n // 2
    full = (k[n:] - k[:-n]) == n
    out[h:len(x) - (n - 1 - h)] = np.where(full, (c[n:] - c[:-n]) / n, math.nan)
    return out


def window_rows(scene, window=None):
    """The curve's averaging window in rows of the series (one per step):
    window s, else scenario.dbp_window (batch_time); 0 gives 1 row, the
    rows unaveraged."""
    w = batch_time(scene, window)
    if not (w >= 0 and math.isfinite(w)):
        raise CosimError(f"the dbp curve's window: {w!r} s (scenario.dbp_window or window=) "
                         "is not a time >= 0")
    return max(1, int(round(w / float(scene["time"]["dt"]))))


def window_seconds(scene, window=None):
    """The window window_rows averages over, in s: 0 when it is one row."""
    n = window_rows(scene, window)
    return n * float(scene["time"]["dt"]) if n > 1 else 0.0


def dbp_curve(results, bin_width=DBP_BIN_WIDTH, phases=(DBP_PHASE_RAMP,), window=None):
    """The traction-slip curve of one dbp run: each row's slip and forces
    averaged over the window centred on it (window s, default
    scenario.dbp_window, the scene's averaging time: one lug passage for a
    lugged tyre, so every average holds whole passages), the rows of the
    given phases (default the ramp) binned by that averaged slip into bins
    of bin_width (edges at multiples of it); rows whose window leaves the
    series or reaches back before the travel are dropped. Why averaged: a
    lug's passage makes the pull, and so the carriage's speed and the slip,
    oscillate; rows binned by their instantaneous slip sort the passage's
    phases into different bins, and a bin the ramp crosses in less than a
    passage holds part of one (window=0: the rows unaveraged, the curve
    until stop 54). A linear trend of slip and force over the window is
    kept; the window blurs the curve over the slip the ramp moves in it. Per bin: slip_lo, slip_hi, rows, t0_s, t1_s
    (its first and last row's time), slip_mean, and per quantity of
    DBP_QUANTITIES and their ratio to the load (T_H/W, T_R/W, T_P/W with
    W = scenario.sinkage_force) the mean and its 95 % half-width
    (``_ci95``) by batch means over the bin's averaged rows in time order,
    each batch at least scenario.dbp_window long, so a bin needs
    stats.MIN_BATCHES windows of rows for an interval (stats.batch_means:
    nan for a bin too short to say, and nan when its fewest batches are
    still correlated, lag-1 above stats.BATCH_LAG1_MAX). The ramp moves the
    curve within a bin, so a bin's mean is the curve's average over it, and
    the trend inflates the batch spread (the interval errs wide)."""
    d = dbp_series(results)
    sc = results.scene["scenario"]
    load = float(sc["sinkage_force"])
    min_rows = batch_rows(results.scene)
    n = window_rows(results.scene, window)
    travel = d["phase"] >= 1  # before it the rows are zeros (no carriage yet)
    avg = {q: window_means(d[q], n, travel) for q in ("slip",) + tuple(DBP_QUANTITIES)}
    mask = np.isin(d["phase"], phases) & np.isfinite(avg["slip"])
    slip = avg["slip"][mask]
    if not len(slip):
        return []
    lo = math.floor(slip.min() / bin_width)
    hi = math.floor(slip.max() / bin_width)
    idx = np.floor(slip / bin_width).astype(int)
    rows = []
    for b in range(lo, hi + 1):
        sel = idx == b
        if not sel.any():
            continue
        t = d["t"][mask][sel]
        row = {"slip_lo": b * bin_width, "slip_hi": (b + 1) * bin_width,
               "rows": int(sel.sum()), "t0_s": float(t[0]), "t1_s": float(t[-1]),
               "slip_mean": float(slip[sel].mean())}
        for q in DBP_QUANTITIES:
            # batches of at least one window; none when still correlated
            bm = stats.interval(avg[q][mask][sel], min_rows)
            row[f"{q}_mean"], row[f"{q}_ci95"] = bm["mean"], bm["half"]
        for q in ("T_H", "T_R", "T_P"):
            row[f"{q}_W_mean"] = row[f"{q}_mean"] / load if load > 0 else math.nan
            row[f"{q}_W_ci95"] = row[f"{q}_ci95"] / load if load > 0 else math.nan
        rows.append(row)
    return rows


# the scene keys that decide what a dbp curve means: runs averaged across beds
# must agree on them (the bed's seed, the scheme, the solvers may differ)
DBP_SAME_KEYS = ("sinkage_force", "omega", "radius", "dbp_force_start", "dbp_force_rate",
                 "dbp_hold", "dbp_window", "carriage_mass")
BIN_EDGE_TOL = 1e-9  # of a bin width: two runs' bin edges are the same edge


def dbp_same_ramp(scenes, names):
    """A CosimError naming the key and the two runs whose scenario differs in
    a key of DBP_SAME_KEYS (their curves are not realisations of one curve)."""
    sc0 = scenes[0].get("scenario", {})
    for sc_all, name in zip(scenes[1:], names[1:]):
        sc = sc_all.get("scenario", {})
        for k in DBP_SAME_KEYS:
            if sc.get(k) != sc0.get(k):
                raise CosimError(f"{name}: scenario.{k} is {sc.get(k)!r}, {names[0]} has "
                                 f"{sc0.get(k)!r}: not realisations of one curve")


def dbp_curve_across(curves, load, bin_width=DBP_BIN_WIDTH):
    """The traction-slip curve of N independent dbp runs (different beds:
    `cosim sweep --repeat`), from each run's dbp_curve with bins of
    bin_width. Per slip bin that any run reaches (bins matched by their
    edges): runs (how many reach it), slip_mean (the mean of their bin slip
    means), and per quantity of DBP_QUANTITIES the mean of the runs' bin
    means with its 95 % half-width from their spread (stats.across_runs:
    Student t, runs - 1 degrees of freedom; nan where one run reaches the
    bin), the runs' min and max, and T_H, T_R, T_P over the load. Each run's
    bin mean counts once, however many rows it holds: a realisation is one
    bed's curve, independent of the others by construction."""
    bins = {}
    for k, curve in enumerate(curves):
        for c in curve:
            width = c["slip_hi"] - c["slip_lo"]
            if abs(width - bin_width) > BIN_EDGE_TOL * bin_width:
                raise CosimError(f"run {k + 1}: bins of {width:g} in slip, not {bin_width:g}")
            b = round(c["slip_lo"] / bin_width)
            if abs(c["slip_lo"] - b * bin_width) > BIN_EDGE_TOL * bin_width:
                raise CosimError(f"run {k + 1}: a bin edge at {c['slip_lo']:g}, not a "
                                 f"multiple of {bin_width:g}")
            bins.setdefault(b, []).append(c)
    rows = []
    for b in sorted(bins):
        cs = bins[b]
        row = {"slip_lo": b * bin_width, "slip_hi": (b + 1) * bin_width, "runs": len(cs),
               "slip_mean": float(np.mean([c["slip_mean"] for c in cs]))}
        for q in DBP_QUANTITIES:
            v = [c[f"{q}_mean"] for c in cs]
            a = stats.across_runs(v)
            row[f"{q}_mean"], row[f"{q}_ci95"] = a["mean"], a["half"]
            row[f"{q}_min"], row[f"{q}_max"] = float(np.min(v)), float(np.max(v))
        for q in ("T_H", "T_R", "T_P"):
            row[f"{q}_W_mean"] = row[f"{q}_mean"] / load if load > 0 else math.nan
            row[f"{q}_W_ci95"] = row[f"{q}_ci95"] / load if load > 0 else math.nan
        rows.append(row)
    return rows


DBP_ACROSS_COLUMNS = (["slip_lo", "slip_hi", "runs", "slip_mean"] +
                      [f"{q}_{st}" for q in DBP_QUANTITIES for st in ("mean", "ci95", "min", "max")] +
                      [f"{q}_W_{st}" for q in ("T_H", "T_R", "T_P") for st in ("mean", "ci95")])


DBP_CURVE_COLUMNS = (["slip_lo", "slip_hi", "rows", "t0_s", "t1_s", "slip_mean"] +
                     [f"{q}_{st}" for q in DBP_QUANTITIES for st in ("mean", "ci95")] +
                     [f"{q}_W_{st}" for q in ("T_H", "T_R", "T_P") for st in ("mean", "ci95")])


CURVE_HEADER = "# cosim dbp curve"  # the first line of a file write_dbp_curve wrote


def write_dbp_curve(path, curve, scene, runs=None, window=None):
    """The curve as CSV with # lines saying what it is: one run's
    (dbp_curve), or with runs (their names) the curve across them
    (dbp_curve_across); window: the one dbp_curve averaged over."""
    sc = scene["scenario"]
    cols = DBP_ACROSS_COLUMNS if runs else DBP_CURVE_COLUMNS
    w = window_seconds(scene, window) if "dt" in scene.get("time", {}) else None
    avg = ("" if w is None  # a scene of the curve alone: its window is not known here
           else f", each row's slip and forces averaged over the {w:.6g} s centred on it" if w
           else ", the rows unaveraged")
    with open(path, "w") as f:
        f.write(f"{CURVE_HEADER}: /coupler/traction and /coupler/dbp rows of the ramp "
                f"(phase 2) binned by the measured slip 1 - v / (omega radius){avg}\n")
        f.write(f"# ramp: {sc.get('dbp_force_start', 0)} N held {sc.get('dbp_hold', 0.2)} s, "
                f"then {sc['dbp_force_rate']} N/s; carriage "
                f"{sc.get('carriage_mass', 'rig_mass')} kg; load {sc['sinkage_force']} N\n")
        if runs:
            f.write(f"# across {len(runs)} runs (each bin: the mean of the runs' bin means; "
                    "ci95 from their spread, Student t, runs - 1 degrees of freedom; min, max: "
                    f"of the runs' bin means): {' '.join(runs)}\n")
        else:
            f.write("# ci95: half-width of the bin mean's 95 % interval, batch means over the "
                    "bin's rows (cosim.stats.batch_means); nan: too few rows\n")
        f.write("# units: N (T_H, T_R, T_P, vertical_load, resistive_force), m (sinkage), s, slip 1\n")
        f.write(",".join(cols) + "\n")
        for r in curve:
            f.write(",".join(f"{r[c]:.9g}" if isinstance(r[c], float) else str(r[c])
                             for c in cols) + "\n")


def read_dbp_curve(path):
    """A curve written by write_dbp_curve (one run's or across runs): (rows,
    load in N from its '# ramp:' line). A CosimError naming the file when it
    is not one."""
    load, rows = None, []
    with open(path) as f:
        lines = f.readlines()
    for line in lines:
        if line.startswith("# ramp:") and "; load " in line:
            try:
                load = float(line.rsplit("; load ", 1)[1].split()[0])
            except (IndexError, ValueError):
                pass
    body = [line for line in lines if not line.startswith("#")]
    if load is None or not body:
        raise CosimError(f"{path}: not a dbp curve (no '# ramp: ... load W N' line or no rows)")
    header = body[0].strip().split(",")
    need = ["slip_mean"] + [f"{q}_{st}" for q in ("T_H", "T_R", "T_P") for st in ("mean", "ci95")]
    missing = [c for c in need if c not in header]
    if missing:
        raise CosimError(f"{path}: not a dbp curve (no column {missing[0]})")
    for n, line in enumerate(body[1:], start=2):
        vals = line.strip().split(",")
        if vals == [""]:
            continue
        if len(vals) != len(header):
            raise CosimError(f"{path}: row {n} has {len(vals)} fields, the header {len(header)}")
        try:
            rows.append({k: float(v) for k, v in zip(header, vals)})
        except ValueError as e:
            raise CosimError(f"{path}: row {n}: {e}") from None
    return rows, load


CROSS_QUANTITIES = ("T_H", "T_R", "T_P")


def dbp_cross_check(curve, points, quantities=CROSS_QUANTITIES):
    """Slip-controlled runs against a dbp curve (issue 22's cross-check).

    For each point (a dict with 'slip' and q_mean, q_ci95: e.g. a `cosim
    sweep` summary row of the load rig) and quantity: the curve at the
    point's slip, linearly interpolated between the two bins whose mean slips
    bracket it (its mean, and its 95 % half-width interpolated the same way:
    the half-width of the interpolated mean when the two bins' errors are
    fully correlated, the widest case, since the bins come from the same
    runs), the difference point - curve and the half-width of the difference,
    sqrt(h_curve^2 + h_point^2) (independent runs; each h a Student-t 95 %
    half-width, so this is the normal approximation of the difference's).
    'agree' is |difference| <= that half-width: the two are the same curve
    within their intervals. No verdict (nan, agree None) when the slip lies
    outside the curve's bin means or either half-width is missing."""
    cs = sorted((c for c in curve if math.isfinite(c.get("slip_mean", math.nan))),
                key=lambda c: c["slip_mean"])
    xs = [c["slip_mean"] for c in cs]
    out = []
    for p in points:
        s = float(p["slip"])
        k = next((i for i in range(1, len(xs)) if xs[i - 1] <= s <= xs[i]), None)
        for q in quantities:
            if f"{q}_mean" not in p:
                continue
            row = {"slip": s, "quantity": q, "point_mean": float(p[f"{q}_mean"]),
                   "point_ci95": float(p.get(f"{q}_ci95", math.nan)), "curve_mean": math.nan,
                   "curve_ci95": math.nan, "difference": math.nan, "ci95": math.nan,
                   "agree": None}
            if k is not None:
                a, b = cs[k - 1], cs[k]
                w = (s - xs[k - 1]) / (xs[k] - xs[k - 1]) if xs[k] > xs[k - 1] else 0.0
                row["curve_mean"] = (1 - w) * a[f"{q}_mean"] + w * b[f"{q}_mean"]
                row["curve_ci95"] = (1 - w) * a[f"{q}_ci95"] + w * b[f"{q}_ci95"]
                row["difference"] = row["point_mean"] - row["curve_mean"]
                h = math.hypot(row["curve_ci95"], row["point_ci95"])
                if math.isfinite(h):
                    row["ci95"] = h
                    row["agree"] = bool(abs(row["difference"]) <= h)
            out.append(row)
    return out


CROSS_COLUMNS = ["slip", "quantity", "point_mean", "point_ci95", "curve_mean", "curve_ci95",
                 "difference", "ci95", "agree"]


def write_cross_check(path, rows, curve_name, points_name):
    """dbp_cross_check's rows as CSV, # lines saying what was compared."""
    with open(path, "w") as f:
        f.write(f"# cosim dbp cross-check: slip-controlled points ({points_name}) against the "
                f"dbp curve ({curve_name}) at the points' slips\n")
        f.write("# curve: linear between the two bins bracketing the slip (half-width likewise); "
                "ci95: sqrt(curve_ci95^2 + point_ci95^2); agree: |difference| <= ci95 "
                "(yes / no; empty: no verdict)\n")
        f.write(",".join(CROSS_COLUMNS) + "\n")
        for r in rows:
            vals = []
            for c in CROSS_COLUMNS:
                v = r[c]
                vals.append("" if v is None else ("yes" if v else "no") if isinstance(v, bool)
                            else f"{v:.9g}" if isinstance(v, float) else str(v))
            f.write(",".join(vals) + "\n")
