"""Writes a bed saved by cosim's DEM (x, v, omega, r) as a LIGGGHTS data file
(atom_style granular, with angular velocities), so both codes can start from the
same settled state. usage: h5_to_data.py BED.h5 L|LXxLY OUT [MARGIN]
(the data box is the walls' box widened by MARGIN on the sides, for moving meshes)"""
import sys
import h5py, numpy as np

f = h5py.File(sys.argv[1], "r")
Lx, Ly = (float(v) for v in sys.argv[2].split("x")) if "x" in sys.argv[2] else (float(sys.argv[2]),) * 2
out = sys.argv[3]
mg = float(sys.argv[4]) if len(sys.argv) > 4 else 0.0
x, v, w, r = f["x"][:], f["v"][:], f["omega"][:], f["r"][:]
n = len(r)
with open(out, "w") as o:
    o.write("bed from %s\n\n%d atoms\n1 atom types\n\n" % (sys.argv[1], n))
    o.write("%.17g %.17g xlo xhi\n%.17g %.17g ylo yhi\n0 %.17g zlo zhi\n\nAtoms\n\n" %
            (-mg, Lx + mg, -mg, Ly + mg, max(2.0, x[:, 2].max() + 0.1)))
    for i in range(n):
        o.write("%d 1 %.17g 2600 %.17g %.17g %.17g\n" % (i + 1, 2 * r[i], x[i, 0], x[i, 1], x[i, 2]))
    o.write("\nVelocities\n\n")
    for i in range(n):
        o.write("%d %.17g %.17g %.17g %.17g %.17g %.17g\n" % (i + 1, *v[i], *w[i]))
