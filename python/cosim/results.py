"""A run's results.h5 (README "Output"): time series as named columns,
snapshots by step, meshes, the scene and the timing table.

    r = cosim.Results("runs/default")            # or .../results.h5
    r.series("coupler", "traction")["T_H"]      # a column, numpy
    r.timing["fem.compute"].sum()
    r.snapshot("dem", r.steps("dem")[-1])["x"]   # grain positions at the last output
    r.scene["time"]["dt"]
"""
import json
import os

import h5py

from . import traction
from .errors import CosimError

RESULTS_FILE = "results.h5"
COLUMNS_ATTR = "columns"
CONFIG_ATTR = "config"
SERIES, STEPS, MESH = "series", "steps", "mesh"
COUPLER, TIMING = "coupler", "timing"


def _text(v):
    return v.decode() if isinstance(v, bytes) else str(v)


class Table:
    """A 2-D dataset with named columns: ``table["T_H"]`` is a column,
    ``table.columns`` the names, ``table.array`` the rows (one per step)."""

    def __init__(self, name, columns, array):
        self.name, self.columns, self.array = name, list(columns), array

    def __getitem__(self, column):
        try:
            return self.array[:, self.columns.index(column)]
        except ValueError:
            raise KeyError(f"{self.name} has no column '{column}' (columns: "
                           f"{', '.join(self.columns)})") from None

    def __contains__(self, column):
        return column in self.columns

    def __len__(self):
        return len(self.array)

    def __iter__(self):
        return iter(self.columns)

    def keys(self):
        return list(self.columns)

    def items(self):
        return [(c, self[c]) for c in self.columns]

    def __repr__(self):
        return f"<Table {self.name}: {len(self)} rows x ({', '.join(self.columns)})>"


class Results:
    """Opens ``path`` (a results.h5, or the run's output dir) for reading."""

    def __init__(self, path):
        if os.path.isdir(path):
            path = os.path.join(path, RESULTS_FILE)
        try:
            self.file = h5py.File(path, "r")
        except OSError as e:
            raise CosimError(f"{path}: cannot read results ({e})") from None
        self.path = path

    def close(self):
        self.file.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def __repr__(self):
        return f"<Results {self.path}: {', '.join(self.processes)}>"

    @property
    def scene(self):
        """The scene the run used (after --set), as a dict."""
        return json.loads(_text(self.file.attrs[CONFIG_ATTR]))

    @property
    def attrs(self):
        """The file's root attributes (config, endpoints)."""
        return {k: _text(v) for k, v in self.file.attrs.items()}

    @property
    def processes(self):
        """The groups: every process of the scene and "coupler"."""
        return list(self.file.keys())

    def _group(self, process):
        if process not in self.file:
            raise KeyError(f"{self.path}: no process '{process}' (has: "
                           f"{', '.join(self.processes)})")
        return self.file[process]

    def tables(self, process=None):
        """(process, dataset) of every time series (2-D with columns)."""
        found = []
        for p in [process] if process else self.processes:
            for name, obj in self._group(p).items():
                if isinstance(obj, h5py.Dataset) and COLUMNS_ATTR in obj.attrs:
                    found.append((p, name))
        return found

    def series(self, process, dataset=SERIES):
        """The time series ``/<process>/<dataset>`` as a :class:`Table`."""
        g = self._group(process)
        ds = g.get(dataset)
        if not isinstance(ds, h5py.Dataset) or COLUMNS_ATTR not in ds.attrs:
            have = [d for p, d in self.tables(process)]
            raise KeyError(f"{self.path}: /{process} has no series '{dataset}' (has: "
                           f"{', '.join(have) or 'none'})")
        cols = [_text(c) for c in ds.attrs[COLUMNS_ATTR]]
        return Table(f"/{process}/{dataset}", cols, ds[()])

    def traction_summary(self, skip_travel=0.1, batch_time=None):
        """The steady travel of a tyre run as `cosim sweep` summarises it: the
        window and, per traction quantity, the mean, its 95 % interval
        (``_ci95``, batch means of at least batch_time s each, default
        scenario.dbp_window or 0.1 s: cosim.stats.interval), min and max."""
        return traction.summarise_run(self, skip_travel, batch_time)

    def dbp_curve(self, bin_width=traction.DBP_BIN_WIDTH, window=None):
        """A dbp-rig run's traction-slip curve: per slip bin the means of
        T_H, T_R, T_P, the load and the resistive force with 95 % intervals,
        the rows averaged over window s first (default scenario.dbp_window;
        0: unaveraged; cosim.traction.dbp_curve)."""
        return traction.dbp_curve(self, bin_width, window=window)

    @property
    def timing(self):
        """``/coupler/timing``: per step, each process's compute, transfer
        and waiting seconds, the coupler's mapping and output."""
        return self.series(COUPLER, TIMING)

    def steps(self, process):
        """The output steps with snapshots of ``process``, ascending."""
        g = self._group(process).get(STEPS)
        return sorted(int(k) for k in g.keys()) if g is not None else []

    def snapshot(self, process, step):
        """{name: array} of ``/<process>/steps/<step>/``; step -1 is the last."""
        steps = self.steps(process)
        if step < 0 and steps and -step <= len(steps):
            step = steps[step]
        if step not in steps:
            raise KeyError(f"{self.path}: /{process} has no snapshot at step {step} "
                           f"(steps: {_ranges(steps)})")
        g = self.file[f"{process}/{STEPS}/{step}"]
        return {k: v[()] for k, v in g.items()}

    def mesh(self, process):
        """{name: array} of ``/<process>/mesh/`` (written once from ready)."""
        g = self._group(process).get(MESH)
        return {k: v[()] for k, v in g.items()} if g is not None else {}

    def datasets(self):
        """Path of every dataset in the file (for a complete walk)."""
        found = []
        self.file.visititems(lambda n, o: found.append("/" + n)
                             if isinstance(o, h5py.Dataset) else None)
        return found


def _ranges(steps):
    if len(steps) > 6:
        return f"{steps[0]}, {steps[1]}, ..., {steps[-1]} ({len(steps)} in all)"
    return ", ".join(map(str, steps)) or "none"
