"""Coupled static check (issue 10): a layer of grains at rest on an elastic
slab. Real dem_server and fem_server, scenario "none" (the slab stays where
its mesh puts it), gravity on the grains only.

The slab is confined: bottom fixed, sides on rollers (x fixed on xmin/xmax,
y on ymin/ymax). Under a uniform pressure p its top sinks uniformly by
p h / M (M = E (1 - nu) / ((1 + nu)(1 - 2 nu)), uniaxial strain), which
TET4 reproduces exactly; by Betti's theorem (K symmetric) the area-weighted
mean deflection of its top under ANY vertical load of total W is then
W h / (M A), wherever the grains sit. So the grains' slab must show the
same mean deflection as the FEM static solve under a uniform pressure of
the same total weight (run here too: fem_server quasi-static alone) within
2 %, and at rest the force of the grains on the slab (the coupled mesh
wall's force, = the sum of the nodal forces the FEM gets) must equal their
weight within 0.1 %."""
import numpy as np

from common import check, done, h5, no_orphans, run, scene

E, NU, RHO_S = 1e6, 0.3, 1100.0
L, H = 0.1, 0.02
RHO_G, R, G = 2600.0, 0.0045, 9.81
M_OED = E * (1 - NU) / ((1 + NU) * (1 - 2 * NU))


def slab(mode, **extra):
    s = {"exec": "fem_server",
         "mesh": {"generate": "slab", "size": [L, L, H], "cells": [10, 10, 2]},
         "element": "tet4",
         "material": {"E": E, "nu": NU, "density": RHO_S, "damping": 3000},
         "fixed": [{"group": "zmin"},
                   {"group": "xmin", "components": "x"}, {"group": "xmax", "components": "x"},
                   {"group": "ymin", "components": "y"}, {"group": "ymax", "components": "y"}],
         "gravity": [0, 0, 0], "surface": "zmax", "mode": mode}
    s.update(extra)
    return s


def top_weights(x0, cells):
    """Consistent load of a unit pressure on the top (z = H): a third of
    each top triangle's area to each of its nodes (TET4 faces)."""
    w = np.zeros(len(x0))
    top = np.isclose(x0[:, 2], H)
    for c in cells:
        for f in ((0, 1, 2), (0, 1, 3), (0, 2, 3), (1, 2, 3)):
            tri = c[list(f)]
            if top[tri].all():
                a, b, cc = x0[tri]
                w[tri] += 0.5 * np.linalg.norm(np.cross(b - a, cc - a)) / 3
    return w


def mean_deflection(f, name, k):
    x0, cells = f[f"/{name}/mesh/x0"][:], f[f"/{name}/mesh/cells"][:]
    w = top_weights(x0, cells)
    u = f[f"/{name}/steps/{k}/u"][:]
    return (w * u[:, 2]).sum() / w.sum(), w.sum()


# 8 x 8 grains, one in each inner cell of the top, not touching each other
# (each rests on the slab alone), placed touching it at rest. Each sits
# inside one top triangle, at (0.2, 0.45) of its cell: >= 1.8 mm from the
# cell's diagonal whichever way it runs, >= 2 mm from its edges (the contact
# patch's radius is 0.4 mm). Over an edge, the slab's dimple would make the
# grain touch both triangles as faces and the contact switch between one and
# two forces: it chatters (measured: the load swinging by 12 % of the
# weight, undamped).
CELL = L / 10
grains = []
for i in range(1, 9):
    for j in range(1, 9):
        grains.append({"x": [CELL * (i + 0.2), CELL * (j + 0.45), H + R], "r": R,
                       "material": 0})
dem = {"exec": "dem_server",
       "materials": [{"density": RHO_G, "E": 5e6, "nu": 0.3, "restitution": 0.3, "friction": 0.5},
                     {"density": RHO_S, "E": E, "nu": NU, "restitution": 0.3, "friction": 0.5}],
       "particles": grains, "surface_material": 1, "gravity": [0, 0, -G]}
weight = len(grains) * RHO_G * 4 / 3 * np.pi * R ** 3 * G
A = L * L
want = -weight * H / (M_OED * A)

DT, END = 1e-4, 0.25
s = scene("slab_static", {"slab": slab("explicit"), "grains": dem}, scenario={"kind": "none"})
s["time"] = {"dt": DT, "end": END}
s["output"]["every"] = 500
s["coupling"] = {"scheme": "serial", "handshake_timeout": 60, "step_timeout": 30}
rc, out, err = run(s, "--quiet", timeout=300)
check(rc == 0, f"grains on the slab: run ok ({err[-400:]})")
no_orphans(s, "slab static")

# the FEM static solve under a uniform pressure of the same total weight
st = scene("slab_uniform", {"slab": slab("quasi_static", pressure={"group": "zmax",
                                                                   "value": weight / A})},
           scenario={"kind": "none"})
st["time"] = {"dt": DT, "end": 2 * DT}
st["output"]["every"] = 1
rc2, out2, err2 = run(st, "--quiet", timeout=120)
check(rc2 == 0, f"uniform pressure, static solve: run ok ({err2[-400:]})")
no_orphans(st, "slab uniform")

if rc == 0 and rc2 == 0:
    f, fs = h5(s), h5(st)
    k_end = int(round(END / DT))
    got, area = mean_deflection(f, "slab", k_end)
    static, _ = mean_deflection(fs, "slab", 2)
    u_top = fs["/slab/steps/2/u"][:][np.isclose(fs["/slab/mesh/x0"][:][:, 2], H), 2]
    print(f"weight {weight:.6g} N; mean top deflection: grains {got:.6g} m, FEM static under "
          f"uniform pressure {static:.6g} m (top nodes {u_top.min():.6g} .. {u_top.max():.6g}), "
          f"analytic W h/(M A) {want:.6g} m; rel. difference {abs(got / static - 1):.3g}")
    check(abs(area / A - 1) < 1e-12, "the top's weights cover its area")
    check(abs(static / want - 1) < 1e-9, "FEM static solve = the analytic uniaxial strain")
    check(abs(got / static - 1) < 0.02, "grains' slab deflection = FEM static within 2 %")
    wf = f["/grains/wall_forces"][:]
    cols = [c.decode() if isinstance(c, bytes) else str(c) for c in f["/grains/wall_forces"].attrs["columns"]]
    fz = wf[:, cols.index("wall0_Fz")]
    ke = f["/grains/series"][:, 1]
    tail = slice(int(0.8 * len(fz)), None)
    rest = fz[tail].mean()
    print(f"force on the slab over the last 20 %: {rest:.8g} N (weight {weight:.8g} N), rel. "
          f"{abs(-rest / weight - 1):.2g}; spread {np.ptp(fz[tail]) / weight:.2g} of the weight; "
          f"grains' kinetic energy at the end {ke[-1]:.3g} J")
    check(abs(-rest / weight - 1) < 1e-3, "the vertical force on the slab = the grains' weight "
          "within 0.1 %")
done()
