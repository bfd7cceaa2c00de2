#!/usr/bin/python3
"""Plots every time series of a run's results.h5 into PNGs beside it.

    /usr/bin/python3 tools/plot_run.py runs/NAME/results.h5 [--out DIR]

One PNG per dataset (/dem/series, /coupler/traction, ...), one panel per
column against t. Prints the files it wrote."""
import argparse
import os

import h5py
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def series_datasets(f):
    found = []

    def visit(name, obj):
        if isinstance(obj, h5py.Dataset) and "columns" in obj.attrs and obj.ndim == 2:
            found.append(name)

    f.visititems(visit)
    return found


def plot(ds, path):
    cols = [c.decode() if isinstance(c, bytes) else str(c) for c in ds.attrs["columns"]]
    data = ds[:]
    n = len(cols) - 1
    if n < 1 or len(data) == 0:
        return False
    ncol = 2 if n > 3 else 1
    nrow = (n + ncol - 1) // ncol
    fig, axes = plt.subplots(nrow, ncol, figsize=(6 * ncol, 1.9 * nrow + 0.6), squeeze=False, sharex=True)
    for i in range(n):
        ax = axes[i // ncol][i % ncol]
        ax.plot(data[:, 0], data[:, i + 1], lw=0.8)
        ax.set_ylabel(cols[i + 1], fontsize=8)
        ax.grid(alpha=0.3)
    for j in range(n, nrow * ncol):
        axes[j // ncol][j % ncol].axis("off")
    for ax in axes[-1]:
        ax.set_xlabel(cols[0])
    fig.suptitle(ds.name, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return True


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("results")
    ap.add_argument("--out", help="folder for the PNGs (default: plots/ beside results.h5)")
    a = ap.parse_args()
    out = a.out or os.path.join(os.path.dirname(os.path.abspath(a.results)), "plots")
    os.makedirs(out, exist_ok=True)
    with h5py.File(a.results, "r") as f:
        for name in series_datasets(f):
            path = os.path.join(out, name.strip("/").replace("/", "_") + ".png")
            if plot(f[name], path):
                print("plot:", path)


if __name__ == "__main__":
    main()
