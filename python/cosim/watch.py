"""``cosim watch RUN_DIR|ENDPOINT [--http 127.0.0.1:8080]``: a live web page of a run.

The page is fed by the run's monitor bus (a :class:`cosim.Monitor`), so it works
for a local run, an attached remote one and over CURVE: the progress and ETA
(``coupler.progress``), each process's compute / transfer / waiting share (summed
from the ``coupler.timing`` rows received), a chart of every series on the bus
(the traction first) and the latest snapshot as a picture (watch_render.py).
When a run dir's run has ended -- or it had ended before the page was opened --
the page shows the final state read from its results.h5 (:class:`cosim.Results`).

The HTTP server (the standard library's ThreadingHTTPServer) answers GET only:
a page never controls the run. It binds to 127.0.0.1 unless told otherwise;
from another host use an SSH tunnel (python/README.md "Watching a run").
"""
import argparse
import json
import math
import os
import sys
import threading
import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from urllib.parse import parse_qs, urlsplit

import numpy as np

from . import protocol as P
from . import watch_render
from .errors import CosimError
from .monitor import ENDPOINTS_FILE, EP_PID, Monitor, _alive
from .results import COLUMNS_ATTR, RESULTS_FILE, Results

DEFAULT_HTTP = "127.0.0.1:8080"
MAX_ROWS = 1 << 17      # rows kept per series (~1 MB per column); then every other is dropped
PLOT_POINTS = 1000      # rows per chart sent to the page: evenly spaced, first and last kept
REFRESH_S = 0.5         # the page's state is rebuilt at most this often (the page polls at 1 s)
WAIT_S = 30.0           # how long to wait for a live run's endpoints.json
CLOSE_WAIT_S = 60.0     # after the bus's end: how long the coupler may take to exit (closing
                        # results.h5; HDF5 refuses a reader while the writer holds its lock)
CLOSE_POLL_S = 0.05
WEB_DIR = os.path.join(os.path.dirname(os.path.abspath(__file__)), "web")
STATIC = {"/": ("index.html", "text/html; charset=utf-8"),
          "/watch.js": ("watch.js", "text/javascript; charset=utf-8"),
          "/watch.css": ("watch.css", "text/css; charset=utf-8"),
          "/vendor/uPlot.iife.min.js": ("vendor/uPlot.iife.min.js",
                                        "text/javascript; charset=utf-8"),
          "/vendor/uPlot.min.css": ("vendor/uPlot.min.css", "text/css; charset=utf-8")}
SHARE_PARTS = ("compute", "transfer", "waiting")  # timing columns <name>.<part> (PROTOCOL.md)
STATUS_WAITING, STATUS_LIVE = "waiting", "live"   # for the bus / receiving it
STATUS_ENDED, STATUS_FINAL = "ended", "final"     # bus over / final state from results.h5


class Rows:
    """The rows of one series received so far, in a growing array (no per-row
    Python objects): ``columns`` the names, ``received`` rows in all, their
    running ``sums`` and the ``last`` one; kept: ``n`` rows of ``array``, every
    ``stride``-th one received -- past MAX_ROWS every other kept row is dropped
    and the stride doubles, so a run of any length costs bounded memory."""

    def __init__(self, columns):
        self.columns, self.n, self.received, self.stride = list(columns), 0, 0, 1
        self.array = np.empty((64, len(self.columns)))
        self.sums, self.last = np.zeros(len(self.columns)), None

    @classmethod
    def of(cls, columns, array):
        r = cls(columns)
        a = np.array(array, dtype=float).reshape(-1, len(r.columns))
        r.received, r.sums = len(a), a.sum(axis=0)
        r.last = a[-1].copy() if len(a) else None
        while len(a) > r.stride * MAX_ROWS:
            r.stride *= 2
        r.array = a[::r.stride].copy()
        r.n = len(r.array)
        return r

    def add(self, row):
        self.sums += row
        self.last = np.array(row, dtype=float)
        self.received += 1
        if (self.received - 1) % self.stride:
            return
        if self.n == MAX_ROWS:  # keep rows 0, 2, 4, ... of those kept
            half = self.array[:self.n:2].copy()
            self.n = len(half)
            self.array[:self.n] = half
            self.stride *= 2
            if (self.received - 1) % self.stride:
                return
        if self.n == len(self.array):
            self.array = np.concatenate([self.array, np.empty_like(self.array)])
        self.array[self.n] = row
        self.n += 1

    def kept(self):
        """(row numbers, rows) kept, the last row received always among them."""
        idx = np.arange(self.n) * self.stride
        if not self.received or idx[-1] == self.received - 1:
            return idx, self.array[:self.n]
        return (np.append(idx, self.received - 1),
                np.concatenate([self.array[:self.n], self.last[None, :]]))


def _finite(values):
    """JSON has no NaN/inf: they become null."""
    return [v if math.isfinite(v) else None for v in values]


def table_key(topic, array_name):
    """``<name>.series`` with array ``series.<dataset>`` -> ``<name>/<dataset>``: the
    path of the same rows in results.h5 (the coupler's topics ``coupler.<dataset>``)."""
    proc, _, what = topic.partition(".")
    if array_name.startswith(P.P_SERIES):
        what = array_name[len(P.P_SERIES):]
    return f"{proc}/{what}"


class WatchState:
    """What the page shows, filled by the bus thread and read by the HTTP
    threads under one lock; ``version`` counts the changes."""

    def __init__(self, source):
        self.lock = threading.Lock()
        self.source, self.status, self.error = source, STATUS_WAITING, None
        self.progress, self.tables, self.snapshots = {}, {}, {}
        self.version, self._page, self._page_at = 0, None, 0.0
        self._png, self._png_key = None, None

    # ---- filled from the bus
    def add(self, m):
        with self.lock:
            self.version += 1
            self.status = STATUS_LIVE
            if m.topic == P.TOPIC_PROGRESS:
                self.progress = {k: m.header.get(k) for k in
                                 ("step", "t", "n_steps", "steps_per_s", "eta_s")}
            elif m.type == "snapshot":
                snap = {k[len(P.P_SNAP):] if k.startswith(P.P_SNAP) else k: np.array(v)
                        for k, v in m.arrays.items()}
                self.snapshots[m.topic.partition(".")[0]] = (m.step, m.t, snap)
            else:
                self._add_rows(m)

    def _add_rows(self, m):
        for name, a in m.arrays.items():
            if name != P.A_SERIES and not name.startswith(P.P_SERIES):
                continue
            rows = np.asarray(a, dtype=float).reshape(-1, a.shape[-1] if a.ndim else 1)
            key = table_key(m.topic, name)
            t = self.tables.get(key)
            if t is None or len(t.columns) != rows.shape[1]:
                cols = m.header.get(P.H_COLUMNS) if name == P.A_SERIES else None
                if not cols or len(cols) != rows.shape[1]:  # participants' rows come bare
                    cols = [f"c{i}" for i in range(rows.shape[1])]
                t = self.tables[key] = Rows(cols)
            for r in rows:
                t.add(r)

    def set_status(self, status, error=None):
        with self.lock:
            self.version += 1
            self.status, self.error = status, error or self.error

    # ---- the final state
    def load_results(self, path):
        """Every series and the last snapshots of results.h5; the progress
        from its rows and the scene's time.end / time.dt."""
        with Results(path) as r:
            tables = {f"{p}/{d}": Rows.of([c.decode() if isinstance(c, bytes) else str(c)
                                           for c in r.file[p][d].attrs[COLUMNS_ATTR]],
                                          r.file[p][d][()]) for p, d in r.tables()}
            snaps = {}
            for p in r.processes:
                steps = r.steps(p)
                if steps:
                    s = r.snapshot(p, steps[-1])
                    snaps[p] = (steps[-1], None, s)
            scene = r.scene
        with self.lock:
            self.version += 1
            # the file's rows replace the bus's; topics not written to it stay (dem's summary)
            self.tables = {**self.tables, **tables}
            self.status, self.error = STATUS_FINAL, None
            self.snapshots = snaps or self.snapshots
            self.progress = self._final_progress(scene)

    def _final_progress(self, scene):
        t = self.tables.get("coupler/series")
        p = dict(self.progress)
        tm = scene.get("time", {})
        if tm.get("dt") and tm.get("end") is not None:
            p["n_steps"] = round(tm["end"] / tm["dt"])
        if t is not None and t.received:
            p["step"], p["t"] = t.received, float(t.last[0])
        p["eta_s"] = 0.0
        return p

    # ---- read by the page
    def page(self, seen=None):
        """The JSON of /api/state, rebuilt at most every REFRESH_S; only the
        version when ``seen`` (the page's version) is still the latest."""
        with self.lock:
            now = time.monotonic()
            if self._page is None or (self._page[0] != self.version and
                                      now - self._page_at > REFRESH_S):
                body = json.dumps(self._build(), allow_nan=False).encode()
                self._page, self._page_at = (self.version, body), now
            if seen == str(self._page[0]):
                return json.dumps({"version": self._page[0], "unchanged": True}).encode()
            return self._page[1]

    def _build(self):
        return {"version": self.version, "status": self.status, "source": self.source,
                "error": self.error, "progress": self.progress,
                "shares": self._shares(), "tables": {k: _chart(t) for k, t in
                                                     self.tables.items()},
                "snapshot": self._snap_key()}

    def _shares(self):
        """{process: {compute, transfer, waiting}} fractions of the process's
        total over the timing rows received (all of them after the end)."""
        t = self.tables.get("coupler/timing")
        if t is None or not t.received:
            return {}
        sums = dict(zip(t.columns, t.sums.tolist()))
        out = {}
        for c in t.columns:
            name, _, part = c.rpartition(".")
            if part == SHARE_PARTS[0] and name != "coupler":
                parts = {q: sums.get(f"{name}.{q}", 0.0) for q in SHARE_PARTS}
                total = sum(parts.values())
                out[name] = {q: (v / total if total > 0 else 0.0) for q, v in parts.items()}
                out[name]["seconds"] = total
        return {"rows": t.received, "processes": out}

    def _snap_key(self):
        return ",".join(f"{p}:{s[0]}" for p, s in sorted(self.snapshots.items()))

    def png(self):
        """The latest snapshots as a PNG (rendered once per snapshot key)."""
        with self.lock:
            key, snaps = self._snap_key(), dict(self.snapshots)
            if key == self._png_key:
                return self._png
        try:
            png = watch_render.snapshot_png(snaps) if snaps else None
        except (ValueError, IndexError, TypeError) as e:  # arrays of unexpected shapes
            png = None
            self.set_status(self.status, error=f"snapshot {key}: cannot draw it ({e})")
        with self.lock:
            self._png, self._png_key = png, key
        return png


def _chart(t):
    """A table as the page's chart: decimated columns (first and last row
    kept) and the last row in full."""
    rows, a = t.kept()
    pick = np.unique(np.linspace(0, len(a) - 1, min(len(a), PLOT_POINTS)).round().astype(int))
    return {"columns": t.columns, "rows": t.received, "index": rows[pick].tolist(),
            "data": [_finite(a[pick, j].tolist()) for j in range(len(t.columns))],
            "last": _finite(t.last.tolist()) if t.received else None}


# ---- the bus thread
class _Streams(Monitor):
    """A Monitor on a bus endpoint that also connects to the snapshot stream."""

    def __init__(self, endpoint, snapshots=None, **kw):
        super().__init__(endpoint, **kw)
        if snapshots:
            self._sub.connect(snapshots)


def run_is_over(run_dir):
    """True when ``run_dir`` holds a finished run: results.h5, and the pid of its
    endpoints.json is no longer alive."""
    try:
        with open(os.path.join(run_dir, ENDPOINTS_FILE)) as f:
            pid = json.load(f).get(EP_PID)
    except (OSError, ValueError):
        return False  # not written yet: the Monitor waits for it
    return os.path.exists(os.path.join(run_dir, RESULTS_FILE)) and \
        (pid is None or not _alive(int(pid)))


def _from_bus(state, source, snapshots, key_file, wait):
    if "://" in source:
        mon = _Streams(source, snapshots, wait=wait, key_file=key_file)
    else:
        mon = Monitor(source, wait=wait, key_file=key_file)
    with mon:
        state.set_status(STATUS_LIVE)
        for m in mon:
            state.add(m)


def follow(state, source, snapshots=None, key_file=None, wait=WAIT_S):
    """Feeds ``state`` from the bus until the run ends, then (a run dir) from
    its results.h5 -- also when the bus could not be followed (a run without
    one, or ended before the page started), if the results are there."""
    run_dir = source if "://" not in source else None
    try:
        if run_dir is None or not run_is_over(run_dir):
            _from_bus(state, source, snapshots, key_file, wait)
        state.set_status(STATUS_ENDED)
    except CosimError as e:
        state.set_status(STATUS_ENDED, error=str(e))
    if run_dir is not None:  # the bus ends before the coupler has closed the file
        until = time.monotonic() + CLOSE_WAIT_S
        while not run_is_over(run_dir) and time.monotonic() < until:
            time.sleep(CLOSE_POLL_S)
    if run_dir is not None and os.path.exists(os.path.join(run_dir, RESULTS_FILE)):
        try:
            state.load_results(run_dir)
        except (CosimError, OSError, KeyError) as e:
            state.set_status(STATUS_ENDED, error=f"{run_dir}/{RESULTS_FILE}: {e}")


# ---- HTTP (GET only)
class Handler(BaseHTTPRequestHandler):
    state = None  # set by serve()

    def do_GET(self):
        url = urlsplit(self.path)
        path = url.path
        if path == "/api/state":  # ?v=VERSION: what the page has; unchanged -> a short answer
            seen = parse_qs(url.query).get("v", [None])[0]
            return self._send(200, "application/json", self.state.page(seen))
        if path == "/api/snapshot.png":
            png = self.state.png()
            return self._send(200, "image/png", png) if png else \
                self._send(404, "text/plain", b"no snapshot yet")
        if path in STATIC:
            name, ctype = STATIC[path]
            with open(os.path.join(WEB_DIR, name), "rb") as f:
                return self._send(200, ctype, f.read())
        self._send(404, "text/plain", f"no page {path}".encode())

    def _send(self, code, ctype, body):
        self.send_response(code)
        self.send_header("Content-Type", ctype)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.end_headers()
        try:
            self.wfile.write(body)
        except (BrokenPipeError, ConnectionResetError):
            pass  # the page went away (or replaced a picture it was loading)

    def log_message(self, *args):  # quiet: the terminal shows the URL only
        pass


def parse_http(text):
    host, sep, port = text.rpartition(":")
    if not sep or not port.isdigit() or not host:
        raise CosimError(f"--http {text}: expected HOST:PORT (e.g. {DEFAULT_HTTP})")
    return host, int(port)


def serve(source, http=DEFAULT_HTTP, snapshots=None, key_file=None, wait=WAIT_S,
          out=sys.stdout):
    """Serves the page of ``source`` (a run dir or a bus endpoint) until
    interrupted; prints its URL first."""
    state = WatchState(source)
    handler = type("WatchHandler", (Handler,), {"state": state})
    try:
        server = ThreadingHTTPServer(parse_http(http), handler)
    except OSError as e:
        raise CosimError(f"--http {http}: cannot listen ({e})") from None
    server.daemon_threads = True
    threading.Thread(target=follow, args=(state, source, snapshots, key_file, wait),
                     daemon=True).start()
    host, port = server.server_address[:2]
    print(f"cosim watch: {source} on http://{host}:{port}/", file=out, flush=True)
    try:
        server.serve_forever()
    finally:
        server.server_close()


def main(argv):
    ap = argparse.ArgumentParser(prog="cosim watch", description="A live web page of a run, "
                                 "fed by its monitor bus (GET only: it never controls the run).")
    ap.add_argument("source", metavar="RUN_DIR|ENDPOINT",
                    help="a run's output.dir (live or ended), or its bus_monitor endpoint")
    ap.add_argument("--http", default=DEFAULT_HTTP, metavar="HOST:PORT",
                    help=f"where the page listens (default {DEFAULT_HTTP}; port 0: any)")
    ap.add_argument("--snapshots", metavar="ENDPOINT",
                    help="with an ENDPOINT: the run's bus_snapshots endpoint too")
    ap.add_argument("--key-file", help="with an ENDPOINT of a CURVE run: the monitors' "
                    "key file (a run dir's endpoints.json names it)")
    ap.add_argument("--wait", type=float, default=WAIT_S,
                    help=f"seconds to wait for a live run's endpoints.json (default {WAIT_S:g})")
    a = ap.parse_args(argv)
    serve(a.source, a.http, a.snapshots, a.key_file, a.wait)
    return 0
