"""Settling-bed initial state (docs/dem-bench.md §3), written once as a
LIGGGHTS `atom_style granular` data file that both codes read: radii uniform
in [3.5, 7.8] mm, rho = 2600, a jittered 16 mm square lattice in an L x L box,
layers from z = 10 mm up, velocities uniform in +-0.05 m/s.
usage: gen_data.py N L OUT [SEED]"""
import sys
import numpy as np

n, L, out = int(sys.argv[1]), float(sys.argv[2]), sys.argv[3]
rng = np.random.default_rng(int(sys.argv[4]) if len(sys.argv) > 4 else 1)
pitch = 0.016
m = int(L / pitch)
per_layer = m * m
r = rng.uniform(3.5e-3, 7.8e-3, n)
k = np.arange(n)
layer, cell = k // per_layer, k % per_layer
ix, iy = cell % m, cell // m
jit = 0.45 * (pitch - 2 * r)
x = (ix + 0.5) * pitch + rng.uniform(-1, 1, n) * jit
y = (iy + 0.5) * pitch + rng.uniform(-1, 1, n) * jit
z = 0.010 + layer * pitch + rng.uniform(-1, 1, n) * jit
v = rng.uniform(-0.05, 0.05, (n, 3))
with open(out, "w") as f:
    f.write("settling bed, docs/dem-bench.md 3\n\n%d atoms\n1 atom types\n\n" % n)
    f.write("0 %.17g xlo xhi\n0 %.17g ylo yhi\n0 %.17g zlo zhi\n\nAtoms\n\n" % (L, L, max(2.0, z.max() + 0.1)))
    for i in range(n):
        f.write("%d 1 %.17g 2600 %.17g %.17g %.17g\n" % (i + 1, 2 * r[i], x[i], y[i], z[i]))
    f.write("\nVelocities\n\n")
    for i in range(n):
        f.write("%d %.17g %.17g %.17g 0 0 0\n" % (i + 1, v[i, 0], v[i, 1], v[i, 2]))
