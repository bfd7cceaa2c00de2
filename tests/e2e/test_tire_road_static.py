"""Scenario tire_road pressed quasi-statically onto the smooth road (issue 24's
test 1): the 165/65 R13 tread (fem_server) on a rim that sinks slowly until the
lug blocks (lug_block: linear springs, flat road) carry the load, then holds
still (omega 0) while the tread and the blocks settle. Checks:
(a) the coupled run: the total road force (the blocks' forces plus the
    coupler's penalty) equals the rim's reaction (fem_server "reaction": the
    load on the fixed DOFs) to 1e-6 once settled;
(b) the same tread pressed to the same rim height on a road solved in the
    FEM alone (fem_server "road": a penalty per unit area, f_i = k_area a_i
    depth_i), k_area the block's static stiffness per unit area (measured
    here from a stand-alone quasi-static block run: K / (nx dx ny dy)): each
    lug's block force against the FEM-alone penalty forces on that lug
    face's nodes, within 2 %.
The inflated lug face is not flat (its nodes' heights spread over 6 mm, the
band bulging between the fixed rim sides, against an approach of 0.1 mm): the
coupler sends each block its face's shape under its cells (scenario.lug_face
"shaped", the default; docs/tire-road.md "The face's shape"). A penalty is a
local law (each node's force from its own depth) and the block is one only
when its springs, not its elastic layer, set its compliance: here the layer
is made 10^4 times stiffer than the scene's (green E), so that both sides
solve the same contact problem, and the test checks that the block is local
(its tangent stiffness is its loaded springs' sum). With the scene's own
layer the block is not local and the comparison says how far the layer's
spreading moves a lug's force (docs/tire-road.md); `flat` as the first
argument runs the flat-face model (lug_face "flat") instead and then fails
(+129 % at the same rim height on the scene's layer)."""
import json
import os
import sys

import h5py
import numpy as np

from common import HERE, check, columns, done, run, scene

DT = 1.953125e-05          # s: the blocks' 51.2 kHz sampling step (configs/tire_road.json)
SINK_V = float(os.environ.get("SINK_V", 0.02))     # m/s: the slow ramp
END = float(os.environ.get("END_T", 0.75))          # s: ramp, then hold
LOAD = 300.0               # N: the scene's sinkage_force
GAP = 2e-4                 # m: the lowest inflated node above the road at the start
LUG_TOL = 7.5e-3           # m: scenario.lug_tolerance's default (coupler/scene.c)
FLAT = sys.argv[1:] == ["flat"]
STRICT = sys.argv[1:] == ["strict"]
LAYER_STIFFER = 1e4        # the local block: its layer this much stiffer than the scene's

base = json.load(open(os.path.join(HERE, "..", "..", "configs", "tire_road.json")))
procs = base["processes"]
# the 53.8 x 111.8 mm lug face; K_CELL N/m per cell: 4.4e8 N/m^3 per area, the flat model's
# (K = 2.63e6 N/m of its 8 x 15 block with the scene's layer, over the 5 998 mm^2 face)
CELL = float(os.environ.get("CELL", 3.3e-3))   # m: the cells' side
grid = {"nx": int(np.ceil(0.0561 / CELL - 1e-9)), "ny": int(np.ceil(0.1122 / CELL - 1e-9)),
        "dx": CELL, "dy": CELL}                # 56.1 x 112.2 mm at 3.3 mm: the face and its edge
K_CELL = 4.8e3 * (CELL / 3.3e-3) ** 2
if FLAT:
    grid, K_CELL = {"nx": 8, "ny": 15, "dx": 6.6e-3, "dy": 6.6e-3}, 8e5
for name in ("lug0", "lug1", "lug2"):
    procs[name]["grid"] = dict(grid)
    procs[name]["springs"] = {"kind": "linear", "k": K_CELL}
    if not FLAT:
        procs[name]["green"] = dict(procs[name]["green"],
                                    E=procs[name]["green"]["E"] * LAYER_STIFFER)
procs["fem"]["reaction"] = True
# a lug's centre at the bottom (the generated tread's lug 12 starts at 270 deg: turned by
# half a lug, 0.5 x 22.5 deg x lug_fraction 0.5), so that the face meets the road level
procs["fem"]["mesh"]["phase_deg"] = -5.625
press = dict(base["scenario"], sinkage_velocity=SINK_V, sinkage_force=LOAD, omega=0.0,
             slip=0.0, auto_gap=GAP, lug_face="flat" if FLAT else "shaped")


def series(path, name):
    with h5py.File(os.path.join(path, "results.h5"), "r") as f:
        return f[f"{name}/series"][()], columns(f[f"{name}/series"])


# 1. the block's static stiffness: the lug block alone, quasi-static (C = the
# time-summed g, contact_block README), pressed linearly on the flat road
blk = dict(procs["lug0"], exec="contact_block")
blk["solver"] = dict(blk["solver"], quasi_static=True)
st = scene("block_static", {"block": blk}, scenario={
    "kind": "indentation", "profile": "linear", "depth": 4e-4, "ramp_time": 20 * DT})
st["time"] = {"dt": DT, "end": 20 * DT}
rc, out, err = run(st, "--quiet", timeout=120)
check(rc == 0, f"the stand-alone static block runs ({err.strip()[-300:]})")
rows, cols = series(st["output"]["dir"], "block")
F, d = rows[:, cols.index("force")], rows[:, cols.index("d_road")]
K = F[-1] / d[-1]
check(np.allclose(F[1:] / d[1:], K, rtol=1e-9) and
      abs(rows[-1, cols.index("stiffness")] / K - 1) < 1e-6,
      f"the static block is linear: F = K d, K = {K:.6g} N/m (its tangent "
      f"{rows[-1, cols.index('stiffness')]:.6g})")

def lug_faces(x0, tri, tol):
    """The coupler's lug faces (coupler/scenario_lugs.c cpl_lugs_find): connected
    sets of surface triangles whose three nodes lie within tol of the outer
    radius, numbered by their smallest node; each node's weight a third of its
    top triangles' areas."""
    r = np.hypot(x0[:, 0], x0[:, 2])
    top = r >= r.max() - tol
    up = np.arange(len(x0))

    def root(i):
        while up[i] != i:
            up[i] = up[up[i]]
            i = up[i]
        return i
    w = np.zeros(len(x0))
    on = np.zeros(len(x0), bool)
    for t in tri[top[tri].all(axis=1)]:
        a, b, c = x0[t]
        w[t] += 0.5 * np.linalg.norm(np.cross(b - a, c - a)) / 3
        on[t] = True
        for k in t[1:]:
            p, q = root(t[0]), root(k)
            up[max(p, q)] = min(p, q)
    roots = sorted({root(i) for i in np.nonzero(on)[0]})
    return [(np.array([i for i in np.nonzero(on)[0] if root(i) == r0]), w) for r0 in roots]



def press_pair(refine):
    """The coupled press and the FEM-alone press to the same rim height on the
    tread meshed at `refine`: the relative difference of each served lug's
    block force and the FEM-alone penalty on its face (the largest)."""
    procs["fem"]["mesh"]["refine"] = refine
    print(f"-- tread mesh refine {refine}")
    # 2. the coupled run: pressed to the load, held
    cp = scene("tire_road_press", procs, scenario=press)
    cp["time"] = {"dt": DT, "end": END}
    cp["output"]["every"] = 10 ** 6   # the last step only
    cp["coupling"].update(step_timeout=60, handshake_timeout=120)
    rc, out, err = run(cp, "--quiet", timeout=1800)
    check(rc == 0, f"the coupled press runs ({err.strip()[-600:]})")
    fem, fc = series(cp["output"]["dir"], "fem")
    with h5py.File(os.path.join(cp["output"]["dir"], "results.h5"), "r") as f:
        lugs, lc = f["coupler/lugs"][()], columns(f["coupler/lugs"])
        tr, tc = f["coupler/traction"][()], columns(f["coupler/traction"])
        x_cp = f[f"fem/steps/{sorted(f['fem/steps'].keys(), key=int)[-1]}/x"][()]
    col = {c: lugs[:, i] for i, c in enumerate(lc)}
    road = col["road_penalty"] + sum(col[f"force{p}"] for p in range(3))
    react = fem[:, fc.index("reaction_z")]
    rel = np.abs(road - react) / np.abs(road).max()
    sink = tr[:, tc.index("sinkage")]
    k_stop = int(np.argmax(np.diff(sink) == 0)) + 1
    print(f"coupled: load {road[-1]:.6g} N, reaction {react[-1]:.6g} N, sinkage {sink[-1]:.6g} m "
          f"(held from step {k_stop}); |road - reaction| / load at 0.1, 0.2, 0.3 s of hold: " +
          ", ".join(f"{rel[min(len(rel) - 1, k_stop + int(t / DT))]:.3g}" for t in (0.1, 0.2, 0.3)) +
          f", at the end {rel[-1]:.3g}")
    for p in range(3):
        print(f"  lug{p}: lug {col[f'lug{p}'][-1]:.0f}, d {col[f'd{p}'][-1]:.6g} m, "
              f"force {col[f'force{p}'][-1]:.6g} N")
    check(rel[-1] <= 1e-6, f"the road's force is the rim's reaction to 1e-6 once settled "
          f"({rel[-1]:.3g})")
    served = [p for p in range(3) if col[f"lug{p}"][-1] >= 0]
    check(len(served) >= 1 and col["road_penalty"][-1] == 0,
          f"the load is on the lugs ({len(served)} served, penalty {col['road_penalty'][-1]:.3g} N)")
    for p in served:
        Fb, db = col[f"force{p}"][-1], col[f"d{p}"][-1]
        if FLAT:
            check(abs(Fb - K * db) <= 1e-6 * Fb, f"lug{p}: settled on the block's static law F = K d "
                  f"({Fb:.6g} N against {K * db:.6g} N)")
            continue
        bs, bc = series(cp["output"]["dir"], f"lug{p}")
        nc, kt = bs[-1, bc.index("contacts")], bs[-1, bc.index("stiffness")]
        check(nc > 0 and abs(kt / (nc * K_CELL) - 1) <= 1e-3,
              f"lug{p}: the block is local: its tangent stiffness {kt:.6g} N/m is its {nc:.0f} "
              f"loaded springs' {nc * K_CELL:.6g} N/m ({kt / (nc * K_CELL) - 1:+.2e})")


    # 3. the road in the FEM alone: the same tread, no lug process, its own road
    fem_alone = dict(procs["fem"], road={"z": base["scenario"]["road_z"], "k_area": 1.0,
                                     "quadrature": "nodes" if FLAT else "exact"})
    errors = []
    probe = scene("fem_road_probe", {"fem": fem_alone}, scenario=press)
    probe["time"] = {"dt": DT, "end": DT}
    rc, out, err = run(probe, "--quiet", timeout=300)
    check(rc == 0, f"a tire_road scene with the fem alone runs ({err.strip()[-300:]})")
    with h5py.File(os.path.join(probe["output"]["dir"], "results.h5"), "r") as f:
        x0, tri = f["fem/mesh/surface_x0"][()], f["fem/mesh/surface_tri"][()]
        node, area = f["fem/mesh/surface_node"][()], f["fem/mesh/road_area"][()]
    faces = lug_faces(x0, tri, LUG_TOL)
    check(len(faces) == 16, f"16 lug faces ({len(faces)})")
    j = int(col["lug0"][-1])
    A = faces[j][1][faces[j][0]].sum()
    A_grid = grid["nx"] * grid["dx"] * grid["ny"] * grid["dy"]
    k_area = K / A if FLAT else K / A_grid   # the flat model's K acts on the face's A
    print(f"lug {j}: face {A * 1e6:.1f} mm^2 (projected {area[faces[j][0]].sum() * 1e6:.1f}), block "
          f"grid {A_grid * 1e6:.1f} mm^2; k_area = {k_area:.6g} N/m^3")
    fem_alone["road"]["k_area"] = k_area
    alone = scene("fem_road_press", {"fem": fem_alone},
                  scenario=dict(press, sinkage_depth=float(sink[-1])))
    alone["time"] = {"dt": DT, "end": END}
    alone["output"]["every"] = 10 ** 6
    alone["coupling"].update(step_timeout=60, handshake_timeout=120)
    rc, out, err = run(alone, "--quiet", timeout=1800)
    check(rc == 0, f"the FEM-alone press runs ({err.strip()[-600:]})")
    fa, fac = series(alone["output"]["dir"], "fem")
    with h5py.File(os.path.join(alone["output"]["dir"], "results.h5"), "r") as f:
        ta = f["coupler/traction"][()]
        last = sorted(f["fem/steps"].keys(), key=int)[-1]
        fz = f[f"fem/steps/{last}/road_force"][()][:, 2]
    sink_a = ta[:, tc.index("sinkage")]
    check(sink_a[-1] == sink[-1], f"the same rim height: sinkage {sink_a[-1]!r} m against {sink[-1]!r} m")
    ra, qa = fa[:, fac.index("road_force")], fa[:, fac.index("reaction_z")]
    print(f"FEM alone: road {ra[-1]:.6g} N on {fa[-1, fac.index('road_contacts')]:.0f} nodes, "
          f"reaction {qa[-1]:.6g} N ({abs(ra[-1] - qa[-1]) / ra[-1]:.3g})")
    check(abs(ra[-1] - qa[-1]) <= 1e-6 * ra[-1], "FEM alone: the road's force is the rim's reaction "
          f"to 1e-6 ({abs(ra[-1] - qa[-1]) / ra[-1]:.3g})")
    f_node = fz[node]  # per surface node
    on_face = np.zeros(len(node), bool)
    for p in range(3):
        jp = int(col[f"lug{p}"][-1])
        if jp < 0:
            continue
        on_face[faces[jp][0]] = True
        Fb, Ff = col[f"force{p}"][-1], f_node[faces[jp][0]].sum()
        touching = int(np.count_nonzero(f_node[faces[jp][0]]))
        z_face = x_cp[node[faces[jp][0]], 2]
        print(f"lug {jp}: block {Fb:.6g} N, FEM-alone penalty on its face {Ff:.6g} N "
              f"({touching} of {len(faces[jp][0])} nodes touch), {Ff / Fb - 1:+.3%}; in the coupled "
              f"run its nodes lie {z_face.min() * 1e3:.3f} to {z_face.max() * 1e3:.3f} mm about the "
              f"road at a mean approach of {col[f'd{p}'][-1] * 1e3:.4f} mm")
        errors.append(Ff / Fb - 1)
    print(f"FEM alone off the served faces: {f_node[~on_face].sum():.6g} N")
    return max(errors, key=abs)


# the tread's mesh (REFINES=0.5,1 adds the mesh halved: 1 more minute)
REFINES = tuple(float(v) for v in os.environ.get("REFINES", "0.5").split(","))
for refine in REFINES:
    e = press_pair(refine)
    check(abs(e) <= 0.02 or (FLAT and not STRICT), f"refine {refine}: the block's force is the "
          f"FEM-alone face force within 2 % ({e:+.3%})")
procs["fem"]["mesh"]["refine"] = REFINES[0]

# 4. the lug processes swapped for stubs (stubs/lug_stub.c: F = K d, cop 0) by their exec:
# the same press to the load, each served stub's force K times its lug's approach
sw = scene("tire_road_stub", dict(procs, **{p: dict(procs[p], exec="lug_stub", stiffness=K)
                                            for p in ("lug0", "lug1", "lug2")}), scenario=press)
sw["time"] = {"dt": DT, "end": END}
sw["output"]["every"] = 10 ** 6
sw["coupling"].update(step_timeout=60, handshake_timeout=120)
rc, out, err = run(sw, "--quiet", timeout=900)
check(rc == 0, f"tire_road with lug_stub processes runs ({err.strip()[-300:]})")
with h5py.File(os.path.join(sw["output"]["dir"], "results.h5"), "r") as f:
    ls, lsc = f["coupler/lugs"][()], columns(f["coupler/lugs"])
    ts, tsc = f["coupler/traction"][()], columns(f["coupler/traction"])
cs = {c: ls[:, i] for i, c in enumerate(lsc)}
law = max(np.max(np.abs(cs[f"force{p}"] - K * np.maximum(cs[f"d{p}"], 0))) for p in range(3))
print(f"lug_stub: load {ts[-1, tsc.index('vertical_load')]:.6g} N, sinkage {ts[-1, tsc.index('sinkage')]:.6g} m, "
      f"max |F - K max(d, 0)| {law:.3g} N")
check(ts[:, tsc.index("vertical_load")].max() >= LOAD and law <= 1e-9 * LOAD,
      f"the stubs carry the load as F = K d ({law:.3g} N off)")
done()
