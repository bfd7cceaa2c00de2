"""A terramechanics reference record (`cosim terra curve`, terra/README.md
"Files and how to call the reference"): read it, draw it beside a DEM-FEM
traction curve (the sweep's fig. 15 and the dbp rig's figure)."""
import numpy as np


def read_reference(path):
    """A terra record (``# key: value`` lines, then a header) as a numpy
    record array (genfromtxt would take the first comment line for the names)."""
    with open(path) as f:
        body = [l for l in f if not l.startswith("#")]
    return np.genfromtxt(body, delimiter=",", names=True)


def draw_reference(ax, ref, label="terramechanics", band=False):
    """A terra record's T/r, DP and T/r − DP dashed over its slip s, in the
    colours of T_H, T_P and |T_R|; with band, the min..max over its packings
    (the _lo/_hi columns) faint where it has one."""
    s, names = ref["s"], ref.dtype.names
    for col, name, color in [("T_over_r", "T/r", "tab:blue"), ("DP", "DP", "tab:green")]:
        ax.plot(s, ref[col], "--", color=color, label=f"{label} {name}")
        lo, hi = f"{col}_lo", f"{col}_hi"
        if band and lo in names and hi in names and np.any(ref[hi] > ref[lo]):
            ax.fill_between(s, ref[lo], ref[hi], color=color, alpha=0.1, lw=0)
    ax.plot(s, ref["T_over_r"] - ref["DP"], "--", color="tab:red", label=f"{label} T/r − DP")
