"""The drawbar-pull rig, scenario.rig = "dbp" (coupler/README.md "Scenario keys"),
end to end with stubs (fem_stub, dem_stub: a constant force per node, ramped in
over 0.1 s).

1. stub: serial, parallel and implicit runs reach the end; /coupler/dbp has a
   row per step. Serial (the rim moves with the step's own force): every
   travel step's carriage momentum change equals the soil's impulse minus the
   resistance's, m_c (v_k - v_{k-1}) = dt (F_x,k - F_res,k), to round-off; the
   resistive force of each row is the law's exact mean over its step (hold,
   then the ramp); slip = 1 - v / (omega radius); the running means are the
   mean of the last dbp_window of rows (to the bins' 1/32). Parallel: the same
   balance with the last step's force. Python: Results.traction_summary()
   carries the curve, cosim.fig_dbp writes dbp_curve.csv (one row per slip
   bin) and dbp.png, and draws a terramechanics reference made for the run's
   load (one made for another load is refused).
   law: a soil with a known force-slip law (dem_stub drag_x on fem_stub's
   wheel: T_P = B s) is recovered row by row and in the binned curve.
   across: fig_dbp over three such soils (T_P = B s + a_k, offsets that
   average to zero): bin by bin the mean of the runs' bin means with the
   Student-t interval of their spread; two loads refused. sweep: `cosim
   sweep` of the dbp scene writes each value's curve across its runs.
2. restart: 2N steps straight equal N steps, a checkpoint in the ramp and a
   restart for N more, row for row in /coupler/dbp and /coupler/traction (the
   carriage, the ramp's clock and the running sums are in the checkpoint).
3. bad: each dbp key's bad value refused by `cosim run` and `cosim check`,
   naming the key."""
import csv
import json
import os
import subprocess
import sys

import numpy as np

from common import COSIM, HERE, check, columns, done, h5, no_orphans, run, scene

ROOT = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, os.path.join(ROOT, "python"))
import cosim  # noqa: E402
from cosim import traction  # noqa: E402

W, FZ, FX, RAMP, N_NODES = 20.0, 24.0, 2.5, 0.1, 25  # a 4 x 4 cell plane: 5 x 5 nodes
C_STUB = 70.0  # N s/m: the vertical rig damped (the stub's load does not fall as it rises)
OMEGA, RADIUS, SLIP0 = 1.8, 0.272, 0.05
M_C, HOLD, F0, RATE, WINDOW = 3.0, 0.05, -1.0, 40.0, 0.032
BALANCE_TOL = 1e-9  # relative to the step impulse: round-off of sums of ~25 forces, h5 f8 rows


def stub_scene(name, scheme, dt=1e-3):
    s = scene(name, {
        "fem": {"exec": "fem_stub",
                "surface": {"plane": {"size": [0.2, 0.16], "n": [4, 4], "z": -0.27}}},
        "dem": {"exec": "dem_stub", "force_per_node": [FX / N_NODES, 0.0, FZ / N_NODES],
                "ramp_time": RAMP}},
        scenario={"kind": "tire_travel", "rim_center": [0, 0, 0.3], "sinkage_velocity": 0.1,
                  "sinkage_force": W, "slip": SLIP0, "omega": OMEGA, "radius": RADIUS,
                  "rig": "dbp", "rig_damping": C_STUB, "carriage_mass": M_C,
                  "dbp_hold": HOLD, "dbp_force_start": F0, "dbp_force_rate": RATE,
                  "dbp_window": WINDOW})
    s["time"] = {"dt": dt, "end": 0.3}
    s["output"]["every"] = 100
    s["coupling"]["scheme"] = scheme
    return s


def table(s, name):
    t = h5(s)[f"/coupler/{name}"]
    return {c: t[:, i] for i, c in enumerate(columns(t))}


def law_mean(a, b):
    """The resistance law's mean over [a, b] of the travel clock."""
    integral = lambda tau: F0 * tau + 0.5 * RATE * np.maximum(tau - HOLD, 0) ** 2
    return (integral(b) - integral(a)) / (b - a)


def stub_part():
    for scheme in ("serial", "parallel", "implicit"):
        s = stub_scene(f"dbp_{scheme}", scheme)
        dt = s["time"]["dt"]
        rc, out, err = run(s, timeout=120)
        check(rc == 0, f"dbp {scheme}: run ok ({err[-300:]})")
        no_orphans(s, f"dbp {scheme}")
        if rc:
            continue
        check("dbp rig: carriage" in err, f"dbp {scheme}: the rig's parameters are logged")
        tr, db = table(s, "traction"), table(s, "dbp")
        n = round(s["time"]["end"] / dt)
        check(len(db["t"]) == n and len(tr["t"]) == n,
              f"dbp {scheme}: a row per step to the end ({len(db['t'])} of {n})")
        travel = np.nonzero(db["phase"] > 0)[0]
        check(len(travel) > 0 and db["phase"][-1] == 2, f"dbp {scheme}: the ramp reached")
        if not len(travel):
            continue
        k0 = int(travel[0])  # the release: the carriage at omega R (1 - slip)
        v = db["carriage_speed"]
        check(abs(v[k0] / (OMEGA * RADIUS * (1 - SLIP0)) - 1) < 1e-12,
              f"dbp {scheme}: released at omega R (1 - slip)")
        if scheme == "implicit":
            continue  # the rig is outside the iteration: its force is the last step's
        k = np.arange(k0 + 1, n)
        fx = tr["T_P"][k] if scheme == "serial" else tr["T_P"][k - 1]
        dv = M_C * (v[k] - v[k - 1])
        want = dt * (fx - db["resistive_force"][k])
        dev = np.abs(dv - want).max() / (dt * (np.abs(fx).max() + np.abs(db["resistive_force"]).max()))
        print(f"dbp {scheme}: {len(k)} carriage steps, impulse balance rel. dev {dev:.2g}; "
              f"slip {db['slip'][k0]:.4g} -> {db['slip'][-1]:.4g}, resistance "
              f"{db['resistive_force'][-1]:.4g} N")
        check(dev < BALANCE_TOL, f"dbp {scheme}: m_c dv = dt (F_x - F_res) each step ({dev:.2g})")
        if scheme != "serial":
            continue
        tau = (k - k0) * dt
        fr = law_mean(tau - dt, tau)
        check(np.allclose(db["resistive_force"][k], fr, rtol=1e-9, atol=1e-9 * RATE),
              "serial: F_res is the law's mean over each step (hold, then the ramp)")
        check(np.allclose(db["slip"][k], 1 - v[k] / (OMEGA * RADIUS), rtol=0, atol=1e-12),
              "serial: slip = 1 - v / (omega radius)")
        # running means: 32 bins of round(WINDOW / (dt 32)) = 1 step; the
        # window is 31 or 32 steps (1/32 of it); here bins of one step: 32
        j = n - 1
        win = db["T_P"][j - 31:j + 1] if "T_P" in db else tr["T_P"][j - 31:j + 1]
        check(abs(db["T_P_avg"][j] - win.mean()) < 1e-9 * np.abs(win).max(),
              f"serial: T_P_avg = the mean of the last dbp_window ({db['T_P_avg'][j]:.9g} "
              f"vs {win.mean():.9g})")
        check(abs(db["slip_avg"][j] - db["slip"][j - 31:j + 1].mean()) < 1e-12,
              "serial: slip_avg over the window")
        python_part(s)


def curve_unaveraged(d):
    with cosim.Results(d) as r:
        return r.dbp_curve(window=0)


def python_part(s):
    """The summary and the figure carry the curve."""
    d = s["output"]["dir"]
    with cosim.Results(d) as r:
        summ = r.traction_summary()
        curve = r.dbp_curve()
    check(isinstance(summ.get("dbp_curve"), list) and len(summ["dbp_curve"]) == len(curve) > 0,
          f"traction_summary of a dbp run carries the curve ({len(curve)} bins)")
    db = table(s, "dbp")
    ramp = db["phase"] == traction.DBP_PHASE_RAMP
    # rows averaged over the window centred on them: the last n - 1 - n // 2 rows have none
    # (the hold before the ramp is longer than half a window)
    n = round(WINDOW / s["time"]["dt"])
    check(sum(c["rows"] for c in curve) == int(ramp.sum()) - (n - 1 - n // 2),
          f"the curve's bins hold every ramp row once but the last {n - 1 - n // 2} (their "
          f"window of {n} rows leaves the run)")
    raw = curve_unaveraged(d)
    check(sum(c["rows"] for c in raw) == int(ramp.sum()),
          "unaveraged (window 0), every ramp row once")
    widths = {round(c["slip_hi"] - c["slip_lo"], 12) for c in curve}
    check(widths == {traction.DBP_BIN_WIDTH}, f"bins of {traction.DBP_BIN_WIDTH} in slip")
    batch = round(WINDOW / s["time"]["dt"])  # rows per batch: one dbp_window
    for c in curve:
        check(c["slip_lo"] <= c["slip_mean"] < c["slip_hi"], f"bin {c['slip_lo']:.3g}: its mean "
              "slip inside it")
        if c["rows"] < cosim.stats.MIN_BATCHES * batch:
            check(np.isnan(c["T_P_ci95"]), f"bin {c['slip_lo']:.3g}: {c['rows']} rows, fewer "
                  f"than {cosim.stats.MIN_BATCHES} windows: no interval")
        check(abs(c["T_P_mean"] - FX) < 1e-9, f"bin {c['slip_lo']:.3g}: T_P = the stub's {FX} N")
    rc = subprocess.run([sys.executable, "-m", "cosim.fig_dbp", d], capture_output=True,
                        text=True, cwd=os.path.join(ROOT, "python"), timeout=120)
    check(rc.returncode == 0, f"cosim.fig_dbp ran ({rc.stderr[-300:]})")
    png, csvp = os.path.join(d, "dbp.png"), os.path.join(d, "dbp_curve.csv")
    check(os.path.getsize(png) > 10000 if os.path.exists(png) else False, "dbp.png written")
    if os.path.exists(csvp):
        with open(csvp) as f:
            rows = list(csv.DictReader(line for line in f if not line.startswith("#")))
        check(len(rows) == len(curve) and "T_P_ci95" in rows[0] and "T_P_W_mean" in rows[0],
              f"dbp_curve.csv: a row per bin with intervals and ratios to the load ({len(rows)})")
    else:
        check(False, "dbp_curve.csv written")
    bad = subprocess.run([sys.executable, "-m", "cosim.fig_dbp", d, "--bin-width", "0"],
                         capture_output=True, text=True, cwd=os.path.join(ROOT, "python"))
    check(bad.returncode != 0 and "--bin-width" in bad.stderr, "fig_dbp: a bad --bin-width named")
    reference_part(d, s["scenario"]["sinkage_force"])


def reference_part(d, load):
    """fig_dbp --reference: a `cosim terra curve` record for the run's load is
    drawn; one made for another load is refused, naming both loads."""
    params = os.path.join(ROOT, "bench", "results", "tire_soil_terra_params_deep.json")
    refs = {}
    for w in (load, 2 * load):
        refs[w] = os.path.join(d, f"ref_W{w:g}.csv")
        rc = subprocess.run([COSIM, "terra", "curve", "--params", params, "--radius", str(RADIUS),
                             "--width", "0.165", "--load", str(w), "--slips", "0:0.3:0.05",
                             "--out", refs[w]], capture_output=True, text=True, timeout=60)
        check(rc.returncode == 0, f"cosim terra curve at {w:g} N ({rc.stderr[-300:]})")
    png = os.path.join(d, "dbp_ref.png")
    rc = subprocess.run([sys.executable, "-m", "cosim.fig_dbp", d, "--png", png, "--reference",
                         refs[load]], capture_output=True, text=True,
                        cwd=os.path.join(ROOT, "python"), timeout=120)
    check(rc.returncode == 0 and os.path.getsize(png) > 10000,
          f"fig_dbp --reference at the run's {load:g} N drew {png} ({rc.stderr[-300:]})")
    bad = subprocess.run([sys.executable, "-m", "cosim.fig_dbp", d, "--png", png + ".bad.png",
                          "--reference", refs[2 * load]], capture_output=True, text=True,
                         cwd=os.path.join(ROOT, "python"), timeout=120)
    check(bad.returncode == 1 and f"{2 * load:g} N" in bad.stderr and f"{load:g} N" in bad.stderr
          and not os.path.exists(png + ".bad.png"),
          f"fig_dbp: a reference for {2 * load:g} N refused for a {load:g} N run ({bad.stderr.strip()})")


# A known force-slip law (dem_stub drag_x on fem_stub's wheel): every node gets
# fx0 - c v_x, and the wheel's nodes move at v_x = V - omega R cos(phi_i), so the
# soil's pull on the wheel is T_P = N fx0 + c (omega R sum cos(phi_i) - N V); with
# fx0 = c omega R (1 - mean cos(phi_i)) that is T_P = B s, B = c N omega R, for the
# slip s = 1 - V / (omega R). The rig's measured curve must recover it.
LAW_N = (8, 2)  # wheel cells: 9 x 3 nodes at phi = pi (i / 8 - 1/2)
LAW_B = 10.0    # N per unit slip: the ramp (-1 .. 5.8 N) sweeps the slip from 0 to 0.2


def law_coefficients():
    nx, ny = LAW_N
    phi = np.pi * (np.arange(nx + 1) / nx - 0.5)
    n = (nx + 1) * (ny + 1)
    c = LAW_B / (n * OMEGA * RADIUS)
    fx0 = c * OMEGA * RADIUS * (1 - np.cos(phi).mean())
    return n, c, fx0


def law_scene(name, scheme):
    s = stub_scene(name, scheme)
    n, c, fx0 = law_coefficients()
    s["processes"]["fem"]["surface"] = {"wheel": {"radius": RADIUS, "width": 0.165, "n": list(LAW_N)}}
    s["processes"]["dem"].update(force_per_node=[fx0, 0.0, FZ / n], drag_x=c)
    return s


def law_part():
    """The rig on a soil with a known force-slip law T_P = B s recovers it:
    row by row (a step's force comes from the wheel's velocity the step
    starts with: the slip of the row before, to round-off) and in the binned
    curve (each bin's mean T_P = B x its mean slip, within B x the slip's
    largest change over one step), over a slip range of several bins."""
    for scheme in ("serial", "parallel"):
        s = law_scene(f"dbp_law_{scheme}", scheme)
        rc, out, err = run(s, timeout=120)
        check(rc == 0, f"law {scheme}: run ok ({err[-300:]})")
        no_orphans(s, f"dbp law {scheme}")
        if rc:
            continue
        tr, db = table(s, "traction"), table(s, "dbp")
        k = np.nonzero(db["phase"] == traction.DBP_PHASE_RAMP)[0][1:]
        slip = db["slip"]
        dev = np.abs(tr["T_P"][k] - LAW_B * slip[k - 1]).max()
        check(dev < 1e-9 * LAW_B, f"law {scheme}: T_P = B s of the step's start, row by row "
              f"(largest deviation {dev:.3g} N)")
        step = np.abs(np.diff(slip[k])).max()
        with cosim.Results(s["output"]["dir"]) as r:
            curve = traction.dbp_curve(r)
        worst = max(abs(c["T_P_mean"] - LAW_B * c["slip_mean"]) for c in curve)
        span = max(c["slip_mean"] for c in curve) - min(c["slip_mean"] for c in curve)
        print(f"law {scheme}: slip {slip[k[0]]:.3g} .. {slip[k[-1]]:.3g} in {len(curve)} bins; "
              f"bins' |T_P - B s| up to {worst:.3g} N (one step moves the slip {step:.2g})")
        check(len(curve) >= 8 and span > 0.15, f"law {scheme}: the ramp sweeps the slip over "
              f"{len(curve)} bins, {span:.3g} (the test bites)")
        check(worst <= LAW_B * step * (1 + 1e-9), f"law {scheme}: each bin's T_P is B x its mean "
              f"slip within B x one step's slip change ({worst:.3g} against {LAW_B * step:.3g} N)")


ACROSS_OFFSETS = (-0.6, 0.0, 0.6)  # N added to T_P: three "beds" of one law, T_P = B s + a_k


def across_part():
    """fig_dbp over several runs (realisations on different beds): three soils
    T_P = B s + a_k whose offsets a_k average to zero. Bin by bin the curve
    across them is the mean of the runs' own bin means (and, the law being
    linear, B x the mean slip within B x one step's slip change), with the
    Student-t interval of their spread; runs of another load are refused."""
    n, c, fx0 = law_coefficients()
    dirs, curves = [], []
    for k, a in enumerate(ACROSS_OFFSETS):
        s = law_scene(f"dbp_across_{k}", "serial")
        s["processes"]["dem"]["force_per_node"][0] = fx0 + a / n
        rc, out, err = run(s, timeout=120)
        check(rc == 0, f"across: run {k} ok ({err[-300:]})")
        if rc:
            return
        dirs.append(s["output"]["dir"])
        with cosim.Results(dirs[-1]) as r:
            curves.append(traction.dbp_curve(r))
    slips = table(s, "dbp")["slip"]
    out_dir = dirs[0] + "_across"
    rc = subprocess.run([sys.executable, "-m", "cosim.fig_dbp", *dirs, "--out", out_dir],
                        capture_output=True, text=True, cwd=os.path.join(ROOT, "python"), timeout=120)
    check(rc.returncode == 0, f"fig_dbp over {len(dirs)} runs ({rc.stderr[-300:]})")
    csvp = os.path.join(out_dir, "dbp_curve.csv")
    if not os.path.exists(csvp):
        check(False, "across: dbp_curve.csv written")
        return
    check(os.path.getsize(os.path.join(out_dir, "dbp.png")) > 10000, "across: dbp.png drawn")
    with open(csvp) as f:
        rows = list(csv.DictReader(line for line in f if not line.startswith("#")))
    step = np.abs(np.diff(slips[table(s, "dbp")["phase"] == traction.DBP_PHASE_RAMP])).max()
    t2 = cosim.stats._t(2)
    full = 0
    for row in rows:
        lo = float(row["slip_lo"])
        mine = [b for cv in curves for b in cv if abs(b["slip_lo"] - lo) < 1e-12]
        v = np.array([b["T_P_mean"] for b in mine])
        check(int(row["runs"]) == len(mine) >= 1, f"bin {lo:.3g}: runs {row['runs']} = the runs "
              f"that reach it ({len(mine)})")
        check(abs(float(row["T_P_mean"]) - v.mean()) < 1e-9 * LAW_B,
              f"bin {lo:.3g}: T_P = the mean of the runs' bin means")
        if len(mine) < len(dirs):
            continue
        full += 1
        half = t2 * v.std(ddof=1) / np.sqrt(3)
        check(abs(float(row["T_P_ci95"]) - half) < 1e-9 * LAW_B and half > 0.5,
              f"bin {lo:.3g}: ci95 {float(row['T_P_ci95']):.4g} = t_2 s / sqrt 3 of the runs' "
              f"means ({half:.4g})")
        dev = abs(float(row["T_P_mean"]) - LAW_B * float(row["slip_mean"]))
        check(dev <= LAW_B * step * (1 + 1e-9), f"bin {lo:.3g}: the offsets cancel: T_P = B x "
              f"the mean slip within B x one step ({dev:.3g} against {LAW_B * step:.3g} N)")
    check(full >= 6, f"across: {full} bins reached by all three runs (the test bites)")
    other = law_scene("dbp_across_load", "serial")
    other["scenario"]["sinkage_force"] = 2 * W
    rc_o, _, err = run(other, timeout=120)
    check(rc_o == 0, f"across: a run at {2 * W:g} N ({err[-300:]})")
    bad = subprocess.run([sys.executable, "-m", "cosim.fig_dbp", dirs[0], other["output"]["dir"],
                          "--out", out_dir + "_bad"], capture_output=True, text=True,
                         cwd=os.path.join(ROOT, "python"), timeout=120)
    check(bad.returncode == 1 and "scenario.sinkage_force" in bad.stderr
          and not os.path.exists(out_dir + "_bad"),
          f"fig_dbp: runs of two loads refused, naming the key ({bad.stderr.strip()[-200:]})")
    bad = subprocess.run([sys.executable, "-m", "cosim.fig_dbp", *dirs], capture_output=True,
                         text=True, cwd=os.path.join(ROOT, "python"), timeout=120)
    check(bad.returncode != 0 and "--out" in bad.stderr, "fig_dbp: several runs need --out")


def sweep_part():
    """`cosim sweep` of a dbp scene writes, per swept value, the curve across
    its runs: here one run per value, so each bin is that run's own bin."""
    from common import scratch, write
    s = law_scene("dbp_sweep", "serial")
    path, out = write(s), os.path.join(scratch("cosim-dbp-sweep-"), "sw")
    rc = subprocess.run([COSIM, "sweep", path, "--values", "scenario.dbp_force_rate=40,30",
                         "--out", out], capture_output=True, text=True, timeout=300)
    check(rc.returncode == 0, f"sweep of a dbp scene ({rc.stderr[-300:]})")
    for rate in (40, 30):
        d = os.path.join(out, f"dbp_scenario.dbp_force_rate={rate}")
        run_dir = os.path.join(out, f"scenario.dbp_force_rate={rate}")
        csvp = os.path.join(d, "dbp_curve.csv")
        if not (os.path.exists(csvp) and os.path.isdir(run_dir)):
            check(False, f"sweep: {csvp} and {run_dir}")
            continue
        with open(csvp) as f:
            rows = list(csv.DictReader(line for line in f if not line.startswith("#")))
        with cosim.Results(run_dir) as r:
            own = traction.dbp_curve(r)
        check(len(rows) == len(own) > 5 and all(
            int(a["runs"]) == 1 and abs(float(a["T_P_mean"]) - b["T_P_mean"]) < 1e-9 * LAW_B
            for a, b in zip(rows, own)), f"sweep rate {rate}: {d} holds the run's curve, one run per bin")
        check(os.path.getsize(os.path.join(d, "dbp.png")) > 10000, f"sweep rate {rate}: dbp.png")


def restart_part():
    n = 151  # the travel starts near step 84, the ramp near 134: the checkpoint is in it
    a = stub_scene("dbp_straight", "serial")
    a["scenario"]["dbp_window"] = 0.1  # bins of 3 steps: the checkpoint falls inside one
    b = json.loads(json.dumps(a))
    b["output"]["dir"] += "_restarted"
    b["checkpoint"] = {"every": n}
    rc, out, err = run(a, timeout=120)
    check(rc == 0, f"restart: 2N straight ({err[-300:]})")
    half = json.loads(json.dumps(b))
    half["time"]["end"] = n * 1e-3
    rc, out, err = run(half, timeout=120)
    check(rc == 0 and os.path.exists(os.path.join(b["output"]["dir"], f"checkpoint_{n}.h5")),
          f"restart: N steps and checkpoint_{n}.h5 ({err[-300:]})")
    rc, out, err = run(b, "--restart", "latest", timeout=120)
    check(rc == 0, f"restart: N more from the checkpoint ({err[-300:]})")
    no_orphans(b, "dbp restart")
    if rc:
        return
    for name in ("dbp", "traction"):
        x, y = h5(a)[f"/coupler/{name}"][()], h5(b)[f"/coupler/{name}"][()]
        check(x.shape == y.shape and np.array_equal(x, y),
              f"restart: /coupler/{name} bit for bit ({x.shape} vs {y.shape})")
    db = table(a, "dbp")
    check(db["phase"][n - 1] == 2 and db["T_P_avg"][n - 1] != 0,
          "restart: the checkpoint falls in the ramp with running sums (the test bites)")


def bad_part():
    base = stub_scene("dbp_bad", "serial")
    cases = [({"dbp_force_rate": None}, "scenario.dbp_force_rate"),
             ({"dbp_force_rate": "fast"}, "scenario.dbp_force_rate"),
             ({"carriage_mass": -1}, "scenario.carriage_mass"),
             ({"carriage_mass": 0}, "scenario.carriage_mass"),
             ({"dbp_hold": -0.1}, "scenario.dbp_hold"),
             ({"dbp_force_start": "push"}, "scenario.dbp_force_start"),
             ({"dbp_window": 0}, "scenario.dbp_window"),
             ({"dbp_window": 1e-4}, "scenario.dbp_window"),  # < dt
             ({"omega": 0}, "scenario.omega"),
             ({"rig": "drawbar"}, "scenario.rig"),
             ({"dbp_windw": 0.1}, "dbp_windw")]
    for change, named in cases:
        s = json.loads(json.dumps(base))
        for key, value in change.items():
            if value is None:
                del s["scenario"][key]
            else:
                s["scenario"][key] = value
        for cmd in ("run", "check"):
            rc, out, err = run(s, cmd=cmd, timeout=60)
            check(rc != 0 and named in err, f"cosim {cmd}: {change} refused naming {named} "
                  f"(rc {rc}: {err.strip()[-200:]})")
    # the dbp keys are read (and checked) in the other rigs too
    s = json.loads(json.dumps(base))
    s["scenario"].update(rig="load", dbp_window=-1)
    rc, out, err = run(s, cmd="check", timeout=60)
    check(rc != 0 and "scenario.dbp_window" in err, "load rig: a bad dbp key still refused")
    s["scenario"].update(dbp_window=0.1)
    del s["scenario"]["dbp_force_rate"]
    rc, out, err = run(s, cmd="check", timeout=60)
    check(rc == 0, f"load rig: dbp_force_rate not needed ({err.strip()[-200:]})")


parts = sys.argv[1:] or ["stub", "law", "across", "sweep", "restart", "bad"]
if "law" in parts:
    law_part()
if "across" in parts:
    across_part()
if "sweep" in parts:
    sweep_part()
if "stub" in parts:
    stub_part()
if "restart" in parts:
    restart_part()
if "bad" in parts:
    bad_part()
done()
