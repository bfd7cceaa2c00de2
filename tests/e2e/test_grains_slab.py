"""Grains hitting a free elastic slab (docs/coupling-schemes.md §4, test T1):
real dem_server and fem_server, nothing fixed, no gravity, no damping, so
the total momentum of grains + slab is conserved. The processes are named
freely ("grains", "slab").

1. serial, no sub-steps: the same bits as an independent coupler running
   the ordering cosim had before its schemes became data (ref_coupler.py).
2. Momentum through the interface, for several sub-step ratios on both
   sides and each scheme: after the contact, |P - P0| <= 1e-12 |P0| (the
   dem returns the step's impulse/dt, the fem applies it in every
   sub-step). Angular momentum: the coupling exchanges impulses at nodes
   that move within a step (O(dt), docs/coupling-schemes.md §2); here the residual is
   dominated by the slab itself: a small-strain (linear) FEM does not
   conserve angular momentum once it deforms (sum of u x K u, second order
   in the deformation), so it drifts while the slab vibrates freely after
   the contact. Checked: the error after the contact is of the size of that
   free drift (measured ~2e-3 of L0 at 1 m/s impacts, ~10x less at 0.1 m/s),
   and independent of dt.
3. parallel differs from serial by the one-step lag of the force only
   (measured and printed).
4. (argument "implicit") implicit: every step reaches the tolerance,
   IQN-ILS in fewer iterations than the plain fixed-point iteration,
   momentum as above for several sub-step ratios; the difference to serial
   is printed."""
import json
import os
import subprocess
import sys

import numpy as np

from common import BIN, COSIM, check, done, h5, no_orphans, run, scene
import ref_coupler

RHO_G, RHO_S, R_G = 2600.0, 1100.0, 0.006
GRAINS = [{"x": [0.030, 0.030, 0.02731], "v": [0.3, 0.1, -1.0], "r": R_G},
          {"x": [0.015, 0.040, 0.03437], "v": [-0.2, 0.3, -1.2], "r": R_G},
          {"x": [0.045, 0.020, 0.04059], "v": [0.1, -0.4, -0.9], "r": R_G}]


def sections(dt, dem_sub, fem_sub):
    slab = {"exec": "fem_server",
            "mesh": {"generate": "slab", "size": [0.06, 0.06, 0.02], "cells": [6, 6, 2]},
            "element": "tet4", "material": {"E": 2e6, "nu": 0.3, "density": RHO_S, "damping": 0},
            "initial_static": False, "surface": "zmax", "dt_sub": dt / fem_sub}
    grains = {"exec": "dem_server",
              "materials": [{"density": RHO_G, "E": 5e6, "nu": 0.3, "restitution": 0.5, "friction": 0.6},
                            {"density": RHO_S, "E": 2e6, "nu": 0.3, "restitution": 0.5, "friction": 0.8}],
              "particles": [dict(g, material=0) for g in GRAINS],
              "surface_material": 1, "gravity": [0, 0, 0], "dt": dt / dem_sub}
    return grains, slab


def run_case(scheme, dt, dem_sub, fem_sub, end=0.04):
    grains, slab = sections(dt, dem_sub, fem_sub)
    s = scene(f"slab_{scheme}_{dem_sub}_{fem_sub}", {"slab": slab, "grains": grains})
    s["time"] = {"dt": dt, "end": end}
    s["output"]["every"] = int(round(5e-4 / dt))
    s["coupling"] = {"scheme": scheme, "handshake_timeout": 30, "step_timeout": 30}
    rc, out, err = run(s, "--quiet", timeout=120)
    check(rc == 0, f"{scheme} {dem_sub}/{fem_sub}: run ok ({err[-400:]})")
    no_orphans(s, f"slab {scheme}")
    return s, err


def momenta(s):
    """P and L about the origin (grain spin included) at each output step."""
    f = h5(s)
    x0, cells = f["/slab/mesh/x0"][:], f["/slab/mesh/cells"][:]
    m = np.zeros(len(x0))
    for c in cells:  # TET4 lumped mass: rho V / 4 per node (row sum)
        a, b, cc, d = x0[c]
        m[c] += RHO_S * abs(np.linalg.det(np.array([b - a, cc - a, d - a]))) / 24
    contacts = f["/grains/series"][:, 2]  # per step
    last_contact = int(np.nonzero(contacts)[0][-1]) + 1 if contacts.any() else 0
    out = []
    for k in sorted(int(x) for x in f["/slab/steps"]):
        vs, xs = f[f"/slab/steps/{k}/v"][:], f[f"/slab/steps/{k}/x"][:]
        g = {a: f[f"/grains/steps/{k}/{a}"][:] for a in ("x", "v", "omega", "r")}
        mg = RHO_G * 4 / 3 * np.pi * g["r"] ** 3
        P = (m[:, None] * vs).sum(0) + (mg[:, None] * g["v"]).sum(0)
        spin = ((0.4 * mg * g["r"] ** 2)[:, None] * g["omega"]).sum(0)
        L = (m[:, None] * np.cross(xs, vs)).sum(0) + (mg[:, None] * np.cross(g["x"], g["v"])).sum(0) + spin
        out.append((k, P, L, last_contact))
    return out


mg0 = RHO_G * 4 / 3 * np.pi * R_G ** 3
P0 = sum(mg0 * np.array(g["v"]) for g in GRAINS)
L0 = sum(mg0 * np.cross(g["x"], g["v"]) for g in GRAINS)

DT = 1e-4


AFTER = 10  # steps


def after_contact(rows):
    """Output rows from AFTER steps past the last step that counted a
    contact: the count is that of the step's last sub-step (the next step
    may still have forces in earlier sub-steps); the parallel scheme delivers
    the last force one step late; the implicit scheme carries its converged
    defect (below the tolerance) into the next step, where the iteration
    shrinks it again: measured 4e-4, 4e-11, 2e-12, 2e-15 of P0 in the first
    four steps after the contact (tolerance 1e-6)."""
    return [r for r in rows if r[0] >= r[3] + AFTER]


def implicit_part():
    """The implicit scheme repeats steps: every process must roll back.
    Exit code 77 (ctest: skipped) if dem_server cannot. It reaches its
    tolerance in every step; IQN-ILS in fewer iterations than the plain
    fixed-point iteration (constant relaxation 1); momentum as above."""
    runs = {}
    for accel, relax, ds, fs in (("iqn-ils", 0.5, 5, 3), ("constant", 1.0, 5, 3),
                                 ("iqn-ils", 0.5, 1, 1), ("iqn-ils", 0.5, 2, 4)):
        grains, slab = sections(DT, ds, fs)
        sc = scene(f"slab_implicit_{accel}_{ds}_{fs}", {"slab": slab, "grains": grains})
        sc["time"] = {"dt": DT, "end": 0.04}
        sc["output"]["every"] = 5
        sc["coupling"]["scheme"] = "implicit"
        sc["coupling"]["implicit"] = {"acceleration": accel, "relaxation": relax}
        rc, out, err = run(sc, "--quiet", timeout=300)
        no_orphans(sc, "slab implicit")
        if rc == 1 and "participant 'grains'" in err and "cannot roll back" in err:
            print("SKIPPED: dem_server has no state_save/state_load yet (dem_state_export, issue 9)")
            sys.exit(77)
        check(rc == 0, f"implicit {accel}: run ok ({err[-300:]})")
        rows = after_contact(momenta(sc))
        dP = max(np.linalg.norm(P - P0) for _, P, _, _ in rows) / np.linalg.norm(P0)
        cs = h5(sc)["/coupler/series"][:]
        runs[(accel, ds, fs)] = (sc, cs)
        print(f"implicit {accel} dem {ds} / fem {fs}: |dP|/|P0| = {dP:.2e}, iterations per step "
              f"mean {cs[:, 2].mean():.2f}, max {cs[:, 2].max():.0f}")
        check(dP <= 1e-12, f"implicit {accel} {ds}/{fs}: linear momentum conserved to 1e-12 ({dP:.2g})")
        check(np.all(cs[:, 3] == 1), f"implicit {accel} {ds}/{fs}: every step reached the tolerance")
    it_iqn = runs[("iqn-ils", 5, 3)][1][:, 2].sum()
    it_fp = runs[("constant", 5, 3)][1][:, 2].sum()
    check(it_iqn < it_fp, f"IQN-ILS needs fewer iterations ({it_iqn:.0f}) than the plain fixed-point "
          f"iteration ({it_fp:.0f})")
    # implicit vs serial: the difference the lagged surface motion makes
    ser = h5(run_case("serial", DT, 5, 3)[0])["/slab/series"][:]
    imp = h5(runs[("iqn-ils", 5, 3)][0])["/slab/series"][:]
    diff = np.abs(imp[:, 1] - ser[:, 1]).max() / np.abs(ser[:, 1]).max()
    print(f"implicit vs serial (5/3 sub-steps): max difference of the slab's strain energy {diff:.2e} of its maximum")
    check(0 < diff < 0.5, "implicit differs from serial by a fraction of the signal")


def explicit_part():
    # 1. serial without sub-steps = the pre-schedule ordering, bit for bit
    s, _ = run_case("serial", DT, 1, 1, end=0.01)
    grains, slab = sections(DT, 1, 1)
    ref_dem, ref_fem = ref_coupler.run(BIN, grains, slab, DT, 100)
    f = h5(s)
    check(np.array_equal(f["/grains/series"][:], ref_dem) and np.array_equal(f["/slab/series"][:], ref_fem),
          "serial without sub-steps: the same bits as the independent reference coupler")
    check(f["/grains/series"][:, 2].max() > 0, "the grains touched the slab in the compared run")

    # 2. momentum after the contact, several sub-step ratios, each scheme
    results = {}
    for scheme, ratios in (("serial", [(1, 1), (5, 3), (3, 1), (1, 4)]),
                           ("parallel", [(1, 1), (5, 3)])):
        for ds, fs in ratios:
            s, _ = run_case(scheme, DT, ds, fs)
            rows = after_contact(momenta(s))
            check(len(rows) >= 3, f"{scheme} {ds}/{fs}: the contact ended ({len(rows)} output steps after it)")
            dP = max(np.linalg.norm(P - P0) for _, P, _, _ in rows) / np.linalg.norm(P0)
            dL = max(np.linalg.norm(L - L0) for _, _, L, _ in rows) / np.linalg.norm(L0)
            Ls = np.array([L for _, _, L, _ in rows])
            drift = np.linalg.norm(Ls.max(0) - Ls.min(0)) / np.linalg.norm(L0)
            results[(scheme, ds, fs)] = (dP, dL, drift)
            print(f"{scheme:8s} dem {ds} / fem {fs} sub-steps: |dP|/|P0| = {dP:.2e}, "
                  f"|dL|/|L0| = {dL:.2e} (free drift after contact {drift:.2e})")
            check(dP <= 1e-12, f"{scheme} {ds}/{fs}: linear momentum conserved to 1e-12 ({dP:.2g})")
            check(dL < 10 * drift,
                  f"{scheme} {ds}/{fs}: angular momentum error ({dL:.2g}) of the size of the "
                  f"slab's own drift in free vibration ({drift:.2g})")
    # the angular residual does not shrink with dt: it is not the coupling's O(dt)
    s2, _ = run_case("serial", DT / 2, 5, 3)
    rows = after_contact(momenta(s2))
    dL_half = max(np.linalg.norm(L - L0) for _, _, L, _ in rows) / np.linalg.norm(L0)
    print(f"serial dt/2: |dL|/|L0| = {dL_half:.2e}")
    check(0.5 < dL_half / results[("serial", 5, 3)][1] < 2, "angular residual independent of dt")

    # 3. parallel vs serial: the force reaches the slab one step late
    ser = h5(run_case("serial", DT, 1, 1, end=0.01)[0])["/slab/series"][:]
    par = h5(run_case("parallel", DT, 1, 1, end=0.01)[0])["/slab/series"][:]
    diff = np.abs(par[:, 1] - ser[:, 1]).max() / np.abs(ser[:, 1]).max()
    print(f"parallel vs serial: max difference of the slab's strain energy {diff:.2e} of its maximum")
    check(0 < diff < 0.5, "parallel differs from serial, by the lag (a fraction of the signal)")


if len(sys.argv) > 1 and sys.argv[1] == "implicit":
    implicit_part()
else:
    explicit_part()
done()
