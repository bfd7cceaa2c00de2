"""The tyre test rig of scenario tire_travel (coupler/README.md "Scenario
keys"): rig "load" and rim_center [x, y, "auto"].

1. Analytic, with stubs (every scheme): dem_stub gives a force that ramps
   linearly in time to a constant F0 > W (= sinkage_force) while the rim
   sinks at constant speed, so the load over the rim height is a straight
   line of slope k = (F0 / ramp_time) / sinkage_velocity: the rig must
   measure that k, take the default mass W / 9.81, and then rise from rest
   as m v' = F(t) - W - c v (F still ramping to F0 > W; a fine RK4
   solution), to first order in dt (semi-implicit Euler; parallel and
   implicit take the last step's load).
2. Bad values are refused naming the key; "auto" with a dem that does not
   report the bed's top is refused naming the participant.
3. The small default scene (configs/default.json: dem_server + fem_server)
   placed with rim_center "auto" and run in the load rig: the lowest tread
   node starts auto_gap above the height at which the tread, lowered, first
   touches a grain (recomputed here from the first snapshot and the tread's
   boundary triangles: between the exact touch of the triangles' x-y boxes
   and that touch with the boxes grown by one grid cell, dem_bed_touch.c),
   and no grain touches the tread before it has sunk auto_gap;
   the rim's height follows the rig's discrete equation step by step with
   the load the coupler measured; the mean vertical load during travel is
   within 10 % of sinkage_force."""
import json
import os
import re
import sys

import numpy as np

from common import HERE, check, columns, done, h5, no_orphans, run, scene

ROOT = os.path.dirname(os.path.dirname(HERE))
G = 9.81


def touch_height(x, r, xs, cells, grow):
    """The lowest tread node's height when the tread (nodes xs, tets cells),
    lowered straight down, first touches a grain (x, r): each boundary
    triangle's lowest vertex against the tops of the grains whose disk's
    x-y box (grown by `grow`) meets the triangle's x-y box."""
    faces = np.sort(np.concatenate([cells[:, [0, 1, 2]], cells[:, [0, 1, 3]],
                                    cells[:, [0, 2, 3]], cells[:, [1, 2, 3]]]), axis=1)
    uniq, count = np.unique(faces, axis=0, return_counts=True)
    tri = xs[uniq[count == 1]]  # [n, 3 vertices, 3]
    tlo, thi, tz = tri[:, :, :2].min(axis=1), tri[:, :, :2].max(axis=1), tri[:, :, 2].min(axis=1)
    zlow, best = xs[:, 2].min(), -np.inf
    for i in range(len(r)):
        g = r[i] + grow
        hit = ((tlo[:, 0] <= x[i, 0] + g) & (thi[:, 0] >= x[i, 0] - g) &
               (tlo[:, 1] <= x[i, 1] + g) & (thi[:, 1] >= x[i, 1] - g))
        if hit.any():
            best = max(best, x[i, 2] + r[i] - (tz[hit].min() - zlow))
    return best


def traction(s):
    f = h5(s)
    t = f["/coupler/traction"]
    return {c: t[:, i] for i, c in enumerate(columns(t))}


# ------------------------------------------------------------ 1. analytic
W, F0, RAMP, VS, N_NODES = 20.0, 24.0, 0.1, 0.1, 25  # a 4 x 4 cell plane: 5 x 5 nodes
C_STUB = 70.0  # N s/m: about half of critical on this stub's k and default m


def stub_scene(name, scheme, dt):
    s = scene(name, {
        "fem": {"exec": "fem_stub",
                "surface": {"plane": {"size": [0.2, 0.16], "n": [4, 4], "z": -0.27}}},
        "dem": {"exec": "dem_stub", "force_per_node": [0.0, 0.0, F0 / N_NODES],
                "ramp_time": RAMP}},
        scenario={"kind": "tire_travel", "rim_center": [0, 0, 0.3], "sinkage_velocity": VS,
                  "sinkage_force": W, "slip": 0.05, "omega": 1.8, "radius": 0.272,
                  "rig": "load", "rig_damping": C_STUB})
    s["time"] = {"dt": dt, "end": 0.4}
    s["output"]["every"] = 100
    s["coupling"]["scheme"] = scheme
    return s


def rise(t0, times, m, c):
    """v(t) of m v' = F(t) - W - c v from rest at t0, F(t) = F0 min(t / RAMP, 1)
    (the force still ramps when it passes W): RK4 on a fine grid."""
    h = 1e-6
    out, v, t = [], 0.0, t0
    acc = lambda t, v: (F0 * min(t / RAMP, 1.0) - W - c * v) / m
    for target in times:
        while t < target - 1e-12:
            step = min(h, target - t)
            k1 = acc(t, v)
            k2 = acc(t + step / 2, v + step / 2 * k1)
            k3 = acc(t + step / 2, v + step / 2 * k2)
            k4 = acc(t + step, v + step * k3)
            v += step / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
            t += step
        out.append(v)
    return np.array(out)


def analytic_part():
    m = W / G
    k = (F0 / RAMP) / VS
    c = C_STUB
    errs = {}
    for scheme, dt in (("serial", 1e-3), ("parallel", 1e-3), ("implicit", 1e-3),
                       ("serial", 5e-4)):
        s = stub_scene(f"rig_{scheme}", scheme, dt)
        rc, out, err = run(s, timeout=120)
        check(rc == 0, f"stub rig {scheme}: run ok ({err[-300:]})")
        no_orphans(s, f"stub rig {scheme}")
        if rc:
            continue
        got = re.search(r"load rig: soil stiffness k = ([0-9.e+-]+) N/m.*mass ([0-9.e+-]+) kg, "
                        r"damping ([0-9.e+-]+) N s/m", err)
        check(got is not None, f"stub rig {scheme}: the rig's parameters are logged")
        if got:
            kk, mm, cc = (float(x) for x in got.groups())
            check(abs(kk / k - 1) < 1e-6, f"{scheme}: measured stiffness {kk} = {k} (the slope "
                  "of the ramp over the sinkage)")
            check(abs(mm / m - 1) < 1e-9 and cc == c,
                  f"{scheme}: default mass {mm} = W/g, damping {cc} as given")
        tr = traction(s)
        t, z = tr["t"], -tr["sinkage"]
        start = int(np.nonzero(tr["vertical_load"] >= W)[0][0])
        # the load the rim reacts to: serial the step's own, parallel/implicit the last step's
        v = np.diff(z) / dt
        vt = rise(t[start], t[start + 1:], m, c)
        e = np.abs(v[start:] - vt).max() / ((F0 - W) / c)
        errs[(scheme, dt)] = e
        print(f"stub rig {scheme} dt {dt}: rim velocity against the analytic rise, max error "
              f"{e:.3g} of the terminal velocity {(F0 - W) / c:.4g} m/s")
        check(e < 0.05, f"{scheme} dt {dt}: the rig rises as m z'' = F0 - W - c z' ({e:.3g})")
    if ("serial", 1e-3) in errs and ("serial", 5e-4) in errs:
        ratio = errs[("serial", 1e-3)] / errs[("serial", 5e-4)]
        print(f"error ratio dt / (dt/2): {ratio:.3g}")
        check(1.6 < ratio < 2.4, f"first order in dt (ratio {ratio:.3g})")


# ------------------------------------------------------------ 2. bad input
def bad_part():
    base = stub_scene("rig_bad", "serial", 1e-3)
    cases = [("rig", "bouncy", "scenario.rig"),
             ("rig_mass", -1, "scenario.rig_mass"),
             ("rig_damping", -2, "scenario.rig_damping"),
             ("auto_gap", "x", "scenario.auto_gap"),
             ("rim_center", [0, 0, "top"], "scenario.rim_center[2]"),
             ("rim_center", ["auto", 0, 0.3], "scenario.rim_center[0]"),
             ("sinkage_force", 0, "scenario.rig_mass")]
    for key, value, named in cases:
        s = json.loads(json.dumps(base))
        s["scenario"][key] = value
        rc, out, err = run(s, timeout=60)
        check(rc != 0 and named in err, f"scenario.{key} = {value!r} refused naming {named} "
              f"(rc {rc}: {err.strip()[-200:]})")
    s = json.loads(json.dumps(base))
    s["scenario"]["rim_center"] = [0, 0, "auto"]
    rc, out, err = run(s, timeout=60)
    check(rc != 0 and "bed_top" in err and "'dem'" in err,
          f"\"auto\" with a dem that reports no bed_top: refused naming it ({err.strip()[-300:]})")
    no_orphans(s, "auto with dem_stub")


# ------------------------------------------------------------ 3. the default scene
def scene_part():
    with open(os.path.join(ROOT, "configs", "default.json")) as f:
        cfg = json.load(f)
    s = scene("rig_default", cfg["processes"], scenario=cfg["scenario"])
    s["time"] = dict(cfg["time"], end=0.33)
    s["coupling"] = dict(cfg["coupling"], handshake_timeout=300)
    sc = s["scenario"]
    sc["rim_center"][2] = "auto"
    sc["rig"] = "load"
    out_every = 200
    s["output"]["every"] = out_every
    # the default scene's soft grains (E = 5 MPa) under the lug tips reach
    # overlaps of ~0.5 of a radius at 80 N (issue 10; measured 0.43-0.50 in
    # both rigs): the default stop at 0.5 is a guard against instability, not
    # a property of the rig tested here
    s["processes"]["dem"]["max_overlap_ratio"] = 0.75
    rc, out, err = run(s, timeout=600)
    check(rc == 0, f"default scene, load rig, auto height: run ok ({err[-400:]})")
    no_orphans(s, "default scene rig")
    if rc:
        return
    got = re.search(r'bed top ([0-9.e+-]+) m, rim height ([0-9.e+-]+) m', err)
    check(got is not None, "the auto height is logged")
    top, z0 = (float(x) for x in got.groups())
    f = h5(s)
    tr = traction(s)
    dt = s["time"]["dt"]
    # auto: recompute the bed top from the first snapshot (grains at rest
    # before the tread reaches them) and the lowest tread node
    k1 = out_every
    x = f[f"/dem/steps/{k1}/x"][:]
    r = f[f"/dem/steps/{k1}/r"][:]
    xs = f[f"/fem/steps/{k1}/x"][:]
    cells = f["/fem/mesh/cells"][:]
    # the tread as it stands at step k1 (it sank rigidly by v k1 dt; its
    # inflation moves the nodes by far less than the tolerance below)
    exact = touch_height(x, r, xs, cells, 0.0)
    coarse = touch_height(x, r, xs, cells, r.max())  # one cell: the largest radius
    low = xs[:, 2].min() + sc["sinkage_velocity"] * k1 * dt  # back to t = 0
    print(f"auto: bed top {top:.6g} m reported, the first touch from the snapshot at step {k1} "
          f"{exact:.6g} m (boxes grown by a cell: {coarse:.6g}); the 95th percentile of the grain "
          f"tops {np.percentile(x[:, 2] + r, 95):.6g} m; lowest tread node at t = 0: {low:.6g} m")
    check(exact - 2e-4 <= top <= coarse + 2e-4, "the reported bed top is where the lowered "
          "tread first touches a grain (between the exact touch and one cell coarser)")
    check(abs(low - (top + 0.002)) < 2e-4, "the lowest tread node starts auto_gap above it")
    tr0 = traction(s)
    first = int(np.nonzero(tr0["vertical_load"] > 0)[0][0])
    check(first * dt * sc["sinkage_velocity"] >= 0.002 - 2e-4, f"no grain touches the tread "
          f"before it has sunk auto_gap (first load at step {first}: "
          f"{first * dt * sc['sinkage_velocity'] * 1e3:.3g} mm)")
    # the rig's discrete equation, step by step, with the loads the coupler measured
    load, z = tr["vertical_load"], z0 - tr["sinkage"]
    start = int(np.nonzero(load >= sc["sinkage_force"])[0][0])
    got = re.search(r"mass ([0-9.e+-]+) kg, damping ([0-9.e+-]+) N s/m", err)
    m, c = (float(v) for v in got.groups())
    check(abs(m * G / sc["sinkage_force"] - 1) < 1e-9 and c == 0,
          f"default rig: the dead weight's mass {m} kg, no damper ({c})")
    W0 = sc["sinkage_force"]
    v = np.diff(z) / dt  # v[j]: set in row j + 1 from that row's load (serial)
    pred = (v[start:-1] + dt * (load[start + 2:] - W0) / m) / (1 + dt * c / m)
    dev = np.abs(v[start + 1:] - pred).max() / max(np.abs(v[start + 1:]).max(), 1e-30)
    # (z from a column of sinkage values ~1e-2 m: its differences are exact to ~1e-11)
    check(abs(v[start - 1]) < 1e-9 and dev < 1e-8,
          f"the rim height follows m z'' = F - W - c z' step by step (rel. dev {dev:.2g})")
    L = load[start + 1:]
    n_travel = len(L)
    print(f"load rig: {n_travel} travel steps, vertical load mean {L.mean():.2f} N, min "
          f"{L.min():.2f}, max {L.max():.2f} (target {W0} N); sinkage {tr['sinkage'][start]:.4g}"
          f" -> {tr['sinkage'][-1]:.4g} m; max overlap ratio {f['/dem/series'][:, 3].max():.3g}")
    check(n_travel > 2000, f"the travel lasted {n_travel} steps")
    check(abs(L.mean() / W0 - 1) < 0.10, f"mean vertical load during travel {L.mean():.2f} N "
          f"within 10 % of the target {W0} N")


parts = sys.argv[1:] or ["analytic", "bad", "scene"]
if "analytic" in parts:
    analytic_part()
if "bad" in parts:
    bad_part()
if "scene" in parts:
    scene_part()
done()
