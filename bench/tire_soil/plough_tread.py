"""The tread's surface and the scene's soil for bench/dem's plough harness: the
grains' compute of a coupled tyre run against dem_server's own code on the
same bed with the same tread surface moving through it (issue 21's 1.2x).

From a coupled run (RUN/results.h5, the scene it ran) writes
  OUT/tread.txt    the tread's coupled surface for bench_plough: the tet
                   mesh's boundary faces without the rim (inner radius) and
                   the two sides, i.e. fem_server's "outer" group, at the
                   first snapshot (inflated, world frame), moved up to the
                   rim's height at t = 0;
  OUT/model.json   the scene's soil section with the coupling step as "dt"
                   (without its particles: bench_plough adds one);
and prints the bench_plough command that repeats the run's kinematic rig:
descent at the rig's sinkage velocity until the run's load first reached
sinkage_force, then travel at V = omega r (1 - slip) turning at omega.
The rigid tread does not deform, so the contact differs from the run's in
detail; the count of awake grains per step, printed by both, says how close.
usage: plough_tread.py SCENE.json RUN_DIR OUT_DIR [BED.h5]"""
import json
import os
import sys

import h5py
import numpy as np


def outer_faces(x0, cells, axis_r, band_r, half_w, tol=1e-9):
    """Boundary faces of a tet mesh, oriented away from their tet, without
    the faces on the inner radius and the band's sides (y = +-half_w, radius
    up to band_r = inner radius + wall): fem_gen.c's tread "outer" group,
    which keeps the lugs' side faces."""
    faces = {}
    for t, c in enumerate(cells):
        for drop in range(4):
            f = tuple(int(c[i]) for i in range(4) if i != drop)
            key = tuple(sorted(f))
            faces.setdefault(key, []).append((f, int(c[drop])))
    out = []
    for key, owners in faces.items():
        if len(owners) != 1:
            continue
        (f, opp), = owners
        idx = np.array(f)
        r = np.hypot(x0[idx, 0], x0[idx, 2])
        side = np.all(np.abs(np.abs(x0[idx, 1]) - half_w) < tol) and np.all(r < band_r + 1e-6)
        if np.all(np.abs(r - axis_r) < 1e-6) or side:
            continue
        a, b, c = x0[f[0]], x0[f[1]], x0[f[2]]
        n = np.cross(b - a, c - a)
        if np.dot(n, x0[opp] - a) > 0:
            f = (f[0], f[2], f[1])
        out.append(f)
    return np.array(out, dtype=np.int64)


def main():
    if len(sys.argv) not in (4, 5):
        sys.exit(__doc__)
    scene_path, run, out = sys.argv[1:4]
    scene = json.load(open(scene_path))
    os.makedirs(out, exist_ok=True)
    f = h5py.File(os.path.join(run, "results.h5"), "r")
    x0, cells = f["tyre/mesh/x0"][:], f["tyre/mesh/cells"][:]
    r0 = np.hypot(x0[:, 0], x0[:, 2])
    tyre = next(p for p in scene["processes"].values() if p.get("exec") == "fem_server")
    tri = outer_faces(x0, cells, r0.min(), r0.min() + float(tyre["mesh"]["wall"]), np.abs(x0[:, 1]).max())
    used = np.unique(tri)
    remap = -np.ones(len(x0), dtype=np.int64)
    remap[used] = np.arange(len(used))
    tri = remap[tri]
    steps = sorted(f["tyre/steps"].keys(), key=int)
    k1 = int(steps[0])
    sc = scene["scenario"]
    dt = float(scene["time"]["dt"])
    trac = f["coupler/traction"]
    cols = [c.decode() if isinstance(c, bytes) else c for c in trac.attrs["columns"]]
    tr = trac[:]
    sink = tr[:, cols.index("sinkage")]
    load = tr[:, cols.index("vertical_load")]
    vs = float(sc["sinkage_velocity"])
    ctr_xy = [float(sc["rim_center"][0]), float(sc["rim_center"][1])]
    i1 = k1 - 1  # the row of step k1 (rows start at step 1)
    x_all = f["tyre/steps/%d/x" % k1][:]
    x = x_all[used]
    # the rim (inner radius) nodes are rigid on the rim: their mean is its centre
    rim = np.abs(r0 - r0.min()) < 1e-6
    cz1 = float(x_all[rim, 2].mean())
    cz0 = cz1 + float(sink[i1])
    x[:, 2] += float(sink[i1])
    first = int(np.argmax(load >= float(sc["sinkage_force"])))
    if load[first] < float(sc["sinkage_force"]):
        sys.exit("the run never reached sinkage_force: no travel to repeat")
    ndesc = first + 1
    nsteps = len(tr)
    omega, radius, slip = float(sc["omega"]), float(sc["radius"]), float(sc["slip"])
    vx = omega * radius * (1 - slip)
    with open(os.path.join(out, "tread.txt"), "w") as m:
        m.write("centre %.17g %.17g %.17g\nnodes %d\n" % (ctr_xy[0], ctr_xy[1], cz0, len(used)))
        for p in x:
            m.write("%.17g %.17g %.17g\n" % tuple(p))
        m.write("triangles %d\n" % len(tri))
        for t in tri:
            m.write("%d %d %d\n" % tuple(t))
    soil = next(p for p in scene["processes"].values() if p.get("exec") == "dem_server")
    model = {k: v for k, v in soil.items() if k not in ("exec", "notes", "particles")}
    model["dt"] = dt  # bench_plough puts in the particles (the bed's replace them)
    json.dump(model, open(os.path.join(out, "model.json"), "w"), indent=2)
    bed = sys.argv[4] if len(sys.argv) == 5 else "BED.h5"
    print("tread: %d nodes, %d triangles; rim centre at t = 0 z = %.6f m (rim nodes' mean at step %d + sinkage)"
          % (len(used), len(tri), cz0, k1))
    print("descent %d steps at %g m/s (load first %.1f N at sinkage %.5f m), travel %d steps at %.6f m/s, omega %g"
          % (ndesc, vs, load[first], sink[first], nsteps - ndesc, vx, omega))
    print("PLOUGH_MODEL=%s bench_plough %s %s 1 %d %g %d %.17g %g 0 0 1"
          % (os.path.join(out, "model.json"), bed, os.path.join(out, "tread.txt"), ndesc, vs,
             nsteps - ndesc, vx, omega))


if __name__ == "__main__":
    main()
