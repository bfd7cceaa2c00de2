"""A tread-like wheel mesh for the ploughing benchmark: a band of radius R and
width W with `lugs` raised blocks (height h, 40 % of the pitch), closed by two
side rings, n_theta x n_y cells (2 * n_theta * (n_y + 2) triangles; 1000 x 10:
24 000), its lowest point `gap` above the bed top (98th percentile of the
grains' tops in BED.h5), centred at (cx, cy). Writes MESH.txt for bench_plough
("centre x y z", "nodes N" + rows, "triangles M" + rows) and MESH.stl for LIGGGHTS.
usage: wheel.py BED.h5 OUT_PREFIX [n_theta n_y R W h lugs cx cy gap]"""
import sys
import h5py
import numpy as np

bed, prefix = sys.argv[1], sys.argv[2]
a = [float(v) for v in sys.argv[3:]]
nt, ny = (int(a[0]), int(a[1])) if len(a) >= 2 else (1000, 10)
R, W, h, lugs, cx, cy, gap = (a[2:9] if len(a) >= 9 else [0.27, 0.15, 0.015, 16, 0.3, 0.5, 0.003])
x = h5py.File(bed, "r")["x"][:]
r = h5py.File(bed, "r")["r"][:]
top = float(np.percentile(x[:, 2] + r, 98))
cz = top + gap + R + h
th = 2 * np.pi * np.arange(nt) / nt
lug = ((th * lugs / (2 * np.pi)) % 1.0) < 0.4
rad = R + h * lug
ys = np.linspace(-W / 2, W / 2, ny + 1)
nodes = []
for y in ys:  # band: ring j at y, node (j, k)
    for k in range(nt):
        nodes.append((cx + rad[k] * np.sin(th[k]), cy + y, cz - rad[k] * np.cos(th[k])))
rin = R - 0.06
for y in (ys[0], ys[-1]):  # inner rings of the two sides
    for k in range(nt):
        nodes.append((cx + rin * np.sin(th[k]), cy + y, cz - rin * np.cos(th[k])))
tris = []
ring = lambda j, k: j * nt + (k % nt)
for j in range(ny):
    for k in range(nt):
        a0, a1, b0, b1 = ring(j, k), ring(j, k + 1), ring(j + 1, k), ring(j + 1, k + 1)
        tris += [(a0, a1, b1), (a0, b1, b0)]
for side, j in ((ny + 1, 0), (ny + 2, ny)):
    for k in range(nt):
        o0, o1, i0, i1 = ring(j, k), ring(j, k + 1), ring(side, k), ring(side, k + 1)
        tris += [(o0, i1, o1), (o0, i0, i1)]
nodes = np.array(nodes)
with open(prefix + ".txt", "w") as f:
    f.write("centre %.17g %.17g %.17g\n" % (cx, cy, cz))
    f.write("nodes %d\n" % len(nodes))
    for p in nodes:
        f.write("%.17g %.17g %.17g\n" % tuple(p))
    f.write("triangles %d\n" % len(tris))
    for t in tris:
        f.write("%d %d %d\n" % t)
with open(prefix + ".stl", "w") as f:
    f.write("solid wheel\n")
    for t in tris:
        p = nodes[list(t)]
        n = np.cross(p[1] - p[0], p[2] - p[0])
        n /= np.linalg.norm(n)
        f.write(" facet normal %.9g %.9g %.9g\n  outer loop\n" % tuple(n))
        for q in p:
            f.write("   vertex %.17g %.17g %.17g\n" % tuple(q))
        f.write("  endloop\n endfacet\n")
    f.write("endsolid wheel\n")
print("wheel: %d nodes, %d triangles, centre (%.4f, %.4f, %.4f), bed top %.4f" % (len(nodes), len(tris), cx, cy, cz, top))
