"""The steady travel of a tyre run and its traction summary (used by
`cosim sweep`, cosim.Results.traction_summary and bench/tire_soil)."""
import math

import numpy as np

from . import stats
from .errors import CosimError

QUANTITIES = ["T_H", "T_R", "T_P", "vertical_load", "sinkage"]


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


def summarise_run(results, skip_travel):
    """{column: value} of one run: the window and, of each quantity, the mean,
    its 95 % half-width by batch means (stats.batch_means), min and max."""
    tr = results.series("coupler", "traction")
    mask, t0, t1, start = travel_window(tr, results.scene, skip_travel)
    row = {"travel_start_s": start, "window_t0_s": t0, "window_t1_s": t1,
           "window_rows": int(mask.sum()), "runs": 1}
    for q in QUANTITIES:
        v = tr[q][mask]
        row[f"{q}_mean"] = float(np.mean(v)) if len(v) else math.nan
        row[f"{q}_ci95"] = stats.batch_means(v)["half"]
        row[f"{q}_min"] = float(np.min(v)) if len(v) else math.nan
        row[f"{q}_max"] = float(np.max(v)) if len(v) else math.nan
    return row
