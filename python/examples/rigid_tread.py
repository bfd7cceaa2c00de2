#!/usr/bin/python3
"""A rigid tread in Python (role "fem"): a measured tread surface that
follows the rim, x = R X0 + c, v = v_rim + omega × (x - c), and records the
grains' force on it. It stands in for fem_server or fem_stub:

    cosim run configs/stub_tire.json --set processes.fem.exec=python/examples/rigid_tread.py

The surface (rim frame) is, as in fem_stub, "surface": {"plane": {"size":
[lx, ly], "n": [nx, ny], "z": z0}}, or measured data: "surface": {"file":
"scan.npz"} with arrays nodes [n,3] (m) and triangles [m,3], or "file":
"scan.csv" with x,y,z per line (triangulated as a grid when "grid": [nx, ny]
says how the points are ordered). Other keys are named and ignored.
"""
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
import numpy as np  # noqa: E402

import cosim  # noqa: E402

# without "surface": a tread-sized patch at the bottom of the 165/65 R13 tyre
DEFAULT_PLANE = {"size": [0.2, 0.165], "n": [8, 8], "z": -0.272}


def grid_triangles(nx, ny):
    """Two triangles per cell of an (nx+1) x (ny+1) point grid, x fastest,
    normals down (-z: the tread faces the soil), as fem_stub."""
    j, i = np.mgrid[0:ny, 0:nx]
    a = (j * (nx + 1) + i).ravel()
    b, d = a + 1, a + nx + 1
    return np.stack([np.stack([a, d, b], 1), np.stack([b, d, d + 1], 1)], 1) \
        .reshape(-1, 3).astype(np.int32)


def plane(cfg):
    (lx, ly), (nx, ny) = cfg.array("size", shape=(2,)), cfg.array("n", "i4", shape=(2,))
    z = cfg.number("z", 0.0)
    if min(lx, ly) <= 0 or min(nx, ny) < 1:
        raise cosim.ConfigError(f"{cfg.path}: size must be positive and n at least 1")
    y, x = np.mgrid[0:ny + 1, 0:nx + 1]
    nodes = np.stack([lx * (x / nx - 0.5), ly * (y / ny - 0.5), np.full(x.shape, z)], -1)
    return nodes.reshape(-1, 3), grid_triangles(nx, ny)


def measured(cfg):
    path = cfg.string("file")
    grid = cfg.array("grid", "i4", shape=(2,), default=[0, 0])
    try:
        if path.endswith(".npz"):
            data = np.load(path)
            return data["nodes"].astype(np.float64), data["triangles"].astype(np.int32)
        nodes = np.loadtxt(path, delimiter=",", ndmin=2)
    except (OSError, KeyError, ValueError) as e:
        raise cosim.ConfigError(f"{cfg.path}.file: cannot read {path}: {e}")
    if nodes.shape[1] != 3 or len(nodes) != (grid[0] + 1) * (grid[1] + 1):
        raise cosim.ConfigError(f"{cfg.path}.grid: {len(nodes)} points of {nodes.shape[1]} "
                                f"values do not form a grid of {grid[0]} x {grid[1]} cells")
    return nodes, grid_triangles(*grid)


def configure(cfg):
    surf = cfg.section("surface", required=False)
    if surf is None:
        nodes, tris = plane(cosim.Config(DEFAULT_PLANE, f"{cfg.path}.surface.plane"))
    elif "plane" in surf:
        nodes, tris = plane(surf.section("plane"))
    else:
        nodes, tris = measured(surf)
    ignored = cfg.ignore_rest()
    if ignored:
        print(f"rigid_tread: ignoring {len(ignored)} keys: {', '.join(ignored)}")
    return nodes, tris


with cosim.Participant("fem", configure=configure, save_state=dict,
                       load_state=lambda s: None) as p:
    X0, tris = p.params
    x, v, r = np.empty_like(X0), np.empty_like(X0), np.empty_like(X0)
    p.ready(surface_x0=X0, surface_tri=tris,
            series=["t", "force_x", "force_y", "force_z", "n_nodes"],
            snapshot={"kind": "tri3", "geometry": "x", "cells": "tri", "attributes": ["v"]},
            mesh={"tri": tris})
    for step in p.steps():
        np.matmul(X0, step["rim_R"].T, out=r)        # R X0, rows of X0
        np.add(r, step["rim_c"], out=x)
        w, vr = step["rim_omega"], step["rim_v"]         # v = v_rim + w x r
        for a, (b, c) in enumerate(((1, 2), (2, 0), (0, 1))):
            np.multiply(r[:, c], w[b], out=v[:, a])
            v[:, a] -= w[c] * r[:, b]
            v[:, a] += vr[a]
        F = step["nodal_force"].sum(axis=0)
        step.done(x=x, v=v, series=[step.t_end, *F, len(X0)], snap={"x": x, "v": v})
