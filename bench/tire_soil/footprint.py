"""The tyre's footprint on the grains and its mean contact pressure, from a run's snapshots.

A face of the tread's outer surface (the faces of tyre/mesh/cells that belong to one cell only) is in contact
when a grain's surface lies within 0.1 of the mean radius of one of its seven sample points (corners, edge
midpoints, centroid), at a snapshot step that has both tyre/steps/N/x and soil/steps/N/x. The contact points
are rasterised on a --cell grid in x-y; each y row is filled from its first to its last contact cell, so the
grooves between the lugs count as under a plate (the footprint a plate test is compared with); its area
divides the vertical load of /coupler/traction at that step. The contact cells alone (the lugs' tops and
flanks that touch) give the pressure on what touches.

    /usr/bin/python3 bench/tire_soil/footprint.py RUN_DIR/results.h5... [--from STEP] [--cell 0.005]
"""
import argparse
import os

import h5py
import numpy as np
from scipy.spatial import cKDTree

TOUCH = 0.1  # gap (mean grain radii) within which a face's sample point counts as touching: the points lie up to
#             half a face (a few mm) from where a grain presses, so a gap of 0.6 mm misses none


def outer_faces(cells):
    faces = np.sort(np.concatenate([cells[:, [0, 1, 2]], cells[:, [0, 1, 3]], cells[:, [0, 2, 3]],
                                    cells[:, [1, 2, 3]]]), axis=1)
    uniq, count = np.unique(faces, axis=0, return_counts=True)
    return uniq[count == 1]


def contact_points(x_tread, faces, xg, rg):
    near = xg[:, 2] < x_tread[:, 2].min() + 0.15
    xg, rg = xg[near], rg[near]
    p = x_tread[faces]
    pts = np.concatenate([p.mean(axis=1), p[:, 0], p[:, 1], p[:, 2], (p[:, 0] + p[:, 1]) / 2,
                          (p[:, 1] + p[:, 2]) / 2, (p[:, 0] + p[:, 2]) / 2])
    tol = TOUCH * rg.mean()
    d, j = cKDTree(xg).query(pts, k=8, distance_upper_bound=rg.max() + tol)
    ok = np.isfinite(d)
    jj = np.where(ok, j, 0)
    return pts[np.any(ok & (d < rg[jj] + tol), axis=1)]


def footprint(q, cell):
    ix = np.floor(q[:, 0] / cell).astype(int)
    iy = np.floor(q[:, 1] / cell).astype(int)
    filled = sum((ix[iy == y].max() - ix[iy == y].min() + 1) for y in np.unique(iy)) * cell * cell
    touched = len(set(zip(ix.tolist(), iy.tolist()))) * cell * cell
    return filled, touched, (ix.max() - ix.min() + 1) * cell, (iy.max() - iy.min() + 1) * cell


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("results", nargs="+")
    ap.add_argument("--from", dest="start", type=int, default=20000, help="first snapshot step (the travel)")
    ap.add_argument("--cell", type=float, default=0.005, help="raster cell (m)")
    a = ap.parse_args()
    print("run,step,load_N,sinkage_mm,length_m,width_m,footprint_m2,p_mean_kPa,contact_m2,p_contact_kPa")
    means = []
    for path in a.results:
        with h5py.File(path, "r") as f:
            faces = outer_faces(f["tyre/mesh/cells"][:])
            traction = f["coupler/traction"][:]
            dt = traction[1, 0] - traction[0, 0]
            first = round(traction[0, 0] / dt)  # the step of the first row (a restart or a branch starts later)
            steps = sorted(int(k) for k in f["tyre/steps"] if k in f["soil/steps"] and int(k) >= a.start)
            for s in steps:
                q = contact_points(f[f"tyre/steps/{s}/x"][:], faces, f[f"soil/steps/{s}/x"][:],
                                   f[f"soil/steps/{s}/r"][:])
                if len(q) == 0:
                    continue
                area, touched, length, width = footprint(q, a.cell)
                load, sink = traction[s - first, 4], traction[s - first, 5]
                means.append((load / area, load / touched))
                print(f"{os.path.basename(os.path.dirname(os.path.abspath(path)))},{s},{load:.1f},{sink * 1e3:.2f},"
                      f"{length:.3f},{width:.3f},{area:.5f},{load / area / 1e3:.2f},{touched:.5f},"
                      f"{load / touched / 1e3:.2f}")
    if means:
        m = np.array(means) / 1e3
        print(f"# {len(m)} snapshots: mean pressure over the footprint {m[:, 0].mean():.1f} kPa "
              f"({m[:, 0].min():.1f}-{m[:, 0].max():.1f}); over the contact cells {m[:, 1].mean():.1f} kPa "
              f"({m[:, 1].min():.1f}-{m[:, 1].max():.1f})")


if __name__ == "__main__":
    main()
