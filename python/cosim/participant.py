"""A participant in Python: what proto_participant_main does for C solvers.

    import cosim

    with cosim.Participant("block", configure=lambda cfg: cfg.number("c")) as p:
        c = p.params
        for step in p.steps():
            d = step["d_road"][0]
            step.done(force=c * max(d, 0.0) ** 1.5, series=[step.t_end, d])

The handshake (hello -> welcome -> ready), the step loop (step -> done until
stop -> bye), rollback for the implicit scheme and checkpoints (with
``save_state``/``load_state``), ``--check-config``, deadlines, dying with the
launcher, and checks of every request and reply against the role table. The
protocol itself is in :mod:`cosim.protocol`.
"""
import json
import math
import os
import sys
import threading
import time

import numpy as np
import zmq

from . import protocol as P
from .config import Config
from .errors import ArrayError, ConfigError, CosimError, ProtocolError
from .roles import Dims, RoleTable, as_wire

POLL_MS = 100       # between checks that the launcher is alive (and heartbeats due)
LINGER_MS = 2000    # a last message (error, bye) still leaves when we exit
BUS_HWM = 1000      # messages queued for the bus before dropping (as proto)
USAGE = """usage: {prog} --endpoint ENDPOINT --name NAME
       {prog} --check-config FILE|- [--name NAME]
A cosim {role} participant. Normally started by `cosim run`, which passes the
endpoint; start it by hand for `cosim run --attach`. --check-config validates
a config section (processes.NAME of a scene, as a JSON object), exit 0 if valid.
"""


def _parse_args(argv, role):
    args = {"--endpoint": os.environ.get(P.ENV_ENDPOINT), "--name": os.environ.get(P.ENV_NAME),
            "--check-config": None}
    prog = os.path.basename(argv[0]) if argv else "participant"
    i = 1
    while i < len(argv):
        opt = argv[i]
        if opt in ("-h", "--help"):
            print(USAGE.format(prog=prog, role=role), end="")
            sys.exit(0)
        if opt not in args or i + 1 >= len(argv):
            print(f"{prog}: unknown or incomplete option '{opt}'", file=sys.stderr)
            print(USAGE.format(prog=prog, role=role), end="", file=sys.stderr)
            sys.exit(2)
        args[opt] = argv[i + 1]
        i += 2
    if not args["--check-config"] and not args["--endpoint"]:
        print(f"{prog}: --endpoint is required", file=sys.stderr)
        sys.exit(2)
    return args["--endpoint"], args["--name"] or role, args["--check-config"]


class Step:
    """One step request: advance from ``t`` to ``t_end = t + dt`` (step
    ``k``), with the role table's inputs as read-only numpy views of the
    received frames (``step["d_road"]``). Answer with :meth:`done`."""

    def __init__(self, participant, msg, dt):
        self._p, self._msg = participant, msg
        self.k = int(msg.step)
        self.t = float(msg.t)
        self.dt = dt
        self.t_end = self.t + dt
        self.output = bool(msg.header.get(P.H_OUTPUT, False))
        self.iteration = int(msg.header.get(P.H_ITERATION, 0))
        self.inputs = msg.arrays
        self.replied = False
        self._t0 = time.perf_counter()

    def __getitem__(self, name):
        try:
            return self.inputs[name]
        except KeyError:
            raise KeyError(f"step {self.k}: no input '{name}' (this request has: "
                           f"{', '.join(self.inputs) or 'none'})") from None

    def __repr__(self):
        return (f"<Step k={self.k} t={self.t:g} dt={self.dt:g} output={self.output} "
                f"iteration={self.iteration}>")

    def done(self, series=None, snap=None, **arrays):
        """Replies to the step: the role table's outputs as keyword arguments
        (numpy arrays of the table's dtype and shape; lists and numbers are
        converted), ``series`` the row of the "series" dataset (or a dict
        {dataset: row} for several) and ``snap`` a dict of snapshot arrays,
        sent at output steps only. Arrays go out without a copy: do not
        change them before the next request arrives. Wrong or missing
        arrays raise ArrayError (also sent to the coupler)."""
        if self.replied:
            raise ProtocolError(f"step {self.k}: done() called twice")
        self._p._guarded(self._reply, series, snap, arrays)
        self.replied = True

    def _reply(self, series, snap, arrays):
        p = self._p
        compute = time.perf_counter() - self._t0
        out = p._checked(P.DONE, arrays, f"step {self.k}: ")
        out += p._series_arrays(series, self.k)
        if self.output and snap:
            out += p._prefixed(P.P_SNAP, snap, f"step {self.k}: snap")
        p._send(P.DONE, self.k, self.t_end, out,
                {P.H_ITERATION: self.iteration, P.H_COMPUTE_S: compute})


class Participant:
    """Connects to the coupler and does the handshake up to the welcome.

    role        "dem", "fem", "block" or "lug" (the role table's roles)
    configure   called with a :class:`cosim.Config` of this participant's
                section; raise ConfigError (or read keys with cfg.number(...)
                etc., whose errors name the key path); its return value is
                ``self.params``. Keys it did not read are errors, unless it
                calls ``cfg.ignore_rest()``. Also answers ``--check-config``.
    save_state  () -> {name: ndarray}, the whole changing state; with
    load_state  ({name: ndarray}) -> None: the participant can repeat a step
                (implicit scheme) and answer checkpoint/restore.
    argv        the command line (default sys.argv): --endpoint, --name,
                --check-config as ``cosim run`` passes them.
    roles       the role table (dict or JSON path; default: from cosim).
    """

    def __init__(self, role, configure=None, save_state=None, load_state=None,
                 argv=None, roles=None):
        self.role = role
        self._configure = configure
        self._save, self._load = save_state, load_state
        endpoint, self.name, check = _parse_args(sys.argv if argv is None else argv, role)
        self.key_path = f"processes.{self.name}"
        if check:
            sys.exit(self._check_config(check))
        self.table = RoleTable.load(roles)
        self.table.check_role(role)
        self._dims = Dims()
        self._error_sent = self._closed = self._ready_sent = False
        self.step = None  # the current Step
        self._series_cols = {}
        self._saved = None  # (k, {name: copy}) at the start of step k
        self._parent = os.getppid()
        # liveness (when the coupler's table has heartbeats): the main thread
        # sends them while it waits, a second thread while the user's code
        # runs; the lock keeps the socket to one thread at a time
        self._beats = self.table.has_message(P.HEARTBEAT)
        self._lock = threading.Lock()
        self._phase, self._progress, self._what = P.PHASE_WELCOME, None, None
        self._last_sent = self._last_progress = time.monotonic()
        self._stop = threading.Event()
        self._ctx = zmq.Context()
        self._sock = self._ctx.socket(zmq.DEALER)
        self._sock.setsockopt(zmq.LINGER, LINGER_MS)
        self._sock.setsockopt(zmq.RCVTIMEO, POLL_MS)
        self._sock.setsockopt(zmq.ROUTING_ID, self.name.encode())
        self._bus = None
        try:
            self._curve = os.environ.get(P.ENV_CURVE_FILE)
            if self._curve:
                P.curve_client([self._sock], self._curve)
            self._sock.connect(endpoint)
            hello = {P.H_ROLE: role, P.H_NAME: self.name, P.H_PID: os.getpid()}
            if self._beats:
                hello[P.H_HEARTBEAT_S] = P.HEARTBEAT_S
                threading.Thread(target=self._beat_loop, daemon=True).start()
            self._send(P.HELLO, fields=hello)
            self._handshake()
        except BaseException as e:
            self._report(e)
            self.close()
            raise

    # ---------------------------------------------------------- handshake
    def _check_config(self, source):
        try:
            text = sys.stdin.read() if source == "-" else open(source).read()
            section = json.loads(text)
            self._configured(section)
        except (ConfigError, OSError, ValueError) as e:
            print(e, file=sys.stderr)
            return 1
        except Exception as e:  # a configure() that fails otherwise: still name the section
            print(f"{self.key_path}: {type(e).__name__}: {e}", file=sys.stderr)
            return 1
        return 0

    def _configured(self, section, run=None):
        cfg = Config(section, self.key_path)
        cfg.run = run  # the welcome's run information (None under --check-config)
        params = self._configure(cfg) if self._configure else None
        cfg.finish()
        return params

    def _handshake(self):
        timeout = float(os.environ.get(P.ENV_HANDSHAKE_TIMEOUT, P.HANDSHAKE_TIMEOUT_S))
        w = self._wait(timeout, "waiting for welcome")
        if w.type != P.WELCOME:
            raise ProtocolError(f"expected '{P.WELCOME}', got '{w.type}'")
        self.welcome = w
        self._phase = P.PHASE_INIT
        self.config, self.run = w.header.get(P.H_CONFIG), w.header.get(P.H_RUN)
        if not isinstance(self.config, dict) or not isinstance(self.run, dict):
            raise ProtocolError("welcome lacks 'run' or 'config'")
        self.table.check(self.role, P.WELCOME, w.arrays, self._dims)
        self.dt = float(self.run.get(P.RUN_DT, 0))
        self.n_steps = int(self.run.get(P.RUN_N_STEPS, 0))
        self.output_dir = self.run.get(P.RUN_OUTPUT_DIR, ".")
        self.rollback_wanted = bool(self.run.get(P.RUN_ROLLBACK, False))
        self.restart_step = int(self.run.get(P.RUN_RESTART_STEP, 0))
        # 0: never give up on silence (a launched participant watches its launcher
        # instead; proto/PROTOCOL.md "welcome")
        self._idle = float(self.run.get(P.RUN_IDLE_TIMEOUT, P.IDLE_TIMEOUT_S)) or math.inf
        bus = self.run.get(P.RUN_BUS)
        if bus:
            self._bus = self._ctx.socket(zmq.PUB)
            self._bus.setsockopt(zmq.SNDHWM, BUS_HWM)
            self._bus.setsockopt(zmq.LINGER, 0)
            if self._curve:
                P.curve_client([self._bus], self._curve)
            self._bus.connect(bus)
        self.params = self._configured(self.config, self.run)

    @property
    def can_rollback(self):
        return self._save is not None and self._load is not None

    def ready(self, series=None, snapshot=None, mesh=None, **arrays):
        """Sends 'ready' (``steps()`` sends it without arrays if you do not):
        the role table's ready arrays as keyword arguments (fem:
        ``surface_x0``, ``surface_tri``); ``series`` {dataset: [column
        names]} (or a list: the columns of "series"); ``snapshot`` how the
        coupler shows snapshots in XDMF ({"kind", "geometry", "cells",
        "attributes"}); ``mesh`` {name: array} written once."""
        if self._ready_sent:
            raise ProtocolError("ready() called twice")
        if series is not None and not isinstance(series, dict):
            series = {P.A_SERIES: list(series)}
        self._series_cols = {k: list(v) for k, v in (series or {}).items()}
        for dataset in self._series_cols:
            self._guarded(P.check_name, dataset if dataset == P.A_SERIES
                          else P.P_SERIES + dataset, "series dataset")
        out = self._guarded(self._checked, P.READY, arrays, "")
        out += self._guarded(self._prefixed, P.P_MESH, mesh or {}, "ready: mesh")
        fields = {P.H_ROLE: self.role, P.H_ROLLBACK: self.can_rollback,
                  P.H_SERIES: self._series_cols}
        if snapshot is not None:
            fields[P.H_SNAPSHOT] = snapshot
        self._send(P.READY, arrays=out, fields=fields)
        self._ready_sent = True
        self._progress = self._what = None

    # ---------------------------------------------------------- the loop
    def steps(self):
        """Yields a :class:`Step` per step request until the coupler says
        stop; repeats (implicit scheme) and checkpoints are handled here."""
        if not self._ready_sent:
            self.ready()
        while True:
            s = self._guarded(self._next_step)
            if s is None:
                return
            self.step = s
            self._phase = P.PHASE_STEP
            yield s
            if not s.replied:
                self._guarded(self._fail, f"step {s.k}: the loop went on without step.done()")

    def _guarded(self, fn, *args):
        """Runs fn; an exception is sent to the coupler, then raised."""
        try:
            return fn(*args)
        except BaseException as e:
            self._report(e)
            raise

    @staticmethod
    def _fail(text):
        raise ProtocolError(text)

    def _next_step(self):
        """The next step request (checkpoints answered on the way), or None
        after stop."""
        while True:
            m = self._wait(self._idle, "waiting for a request")
            if m.type == P.STOP:
                self._send(P.BYE, m.step, m.t)
                self.close()
                return None
            if m.type == P.STEP:
                return self._begin_step(m)
            if m.type in (P.CHECKPOINT, P.RESTORE):
                self._state_request(m)
            else:
                raise ProtocolError(f"unexpected message '{m.type}' from the coupler")

    def _begin_step(self, m):
        dt = m.header.get(P.H_DT, self.dt)
        if isinstance(dt, bool) or not isinstance(dt, (int, float)) or not dt > 0:
            raise ProtocolError(f"step {m.step}: header field 'dt' must be a positive number")
        it = m.header.get(P.H_ITERATION, 0)
        if isinstance(it, bool) or not isinstance(it, (int, float)) or it < 0:
            raise ProtocolError(f"step {m.step}: header field 'iteration' must be a number >= 0")
        self.table.check(self.role, P.STEP, m.arrays, self._dims, f"step {m.step}: ")
        s = Step(self, m, float(dt))
        if s.iteration > 0:
            self._roll_back(s)
        elif self.rollback_wanted and self.can_rollback:
            state = self._save()
            self._state_arrays(state)  # checks names and dtypes
            self._saved = (s.k, {k: np.array(v, copy=True) for k, v in state.items()})
        return s

    def _roll_back(self, s):
        if not self.can_rollback or not self.rollback_wanted:
            why = ("the welcome did not announce rollback" if self.can_rollback else
                   "this participant cannot roll back (no save_state/load_state)")
            raise ProtocolError(f"the coupler asked for iteration {s.iteration} of step "
                                f"{s.k}, but {why}")
        if not self._saved or self._saved[0] != s.k:
            raise ProtocolError(f"iteration {s.iteration} of step {s.k} requested, but the "
                                f"saved state is that of step "
                                f"{self._saved[0] if self._saved else 'none'}")
        self._load({k: v.copy() for k, v in self._saved[1].items()})

    def _state_request(self, m):
        self._phase = P.PHASE_STATE
        if not self.can_rollback:
            raise ProtocolError(f"'{m.type}' requested, but this participant has no "
                                f"save_state/load_state")
        if m.type == P.CHECKPOINT:
            self._send(P.STATE, m.step, m.t, self._state_arrays(self._save()))
        else:
            n = len(P.P_STATE)
            self._load({k[n:]: v.copy() for k, v in m.arrays.items() if k.startswith(P.P_STATE)})
            self._saved = None
            self._send(P.RESTORED, m.step, m.t)

    # ---------------------------------------------------------- building replies
    def _checked(self, msg, given, where):
        """The role table's arrays of msg from the user's keyword arguments,
        checked (ArrayError names the array)."""
        specs = {s.name: s for s in self.table.specs(self.role, msg)}
        unknown = sorted(set(given) - set(specs))
        if unknown:
            raise ArrayError(f"{where}'{unknown[0]}' is not an array of role {self.role}'s "
                             f"{msg} message (the role table has: "
                             f"{', '.join(specs) or 'none'})", array=unknown[0])
        arrays = {n: as_wire(specs[n], v) for n, v in given.items()}
        self.table.check(self.role, msg, arrays, self._dims, where)
        return [(n, P.wire_array(n, a)) for n, a in arrays.items()]

    def _series_arrays(self, series, k):
        """The series rows of a done as arrays, checked against what ready
        declared: every declared dataset, each with its column count."""
        if not isinstance(series, dict):
            series = {} if series is None else {P.A_SERIES: series}
        for dataset in series:
            if dataset not in self._series_cols:
                raise ArrayError(f"step {k}: series '{dataset}' was not declared in "
                                 f"ready(series=...) (declared: "
                                 f"{', '.join(self._series_cols) or 'none'})", dataset)
        out = []
        for dataset, cols in self._series_cols.items():
            name = P.A_SERIES if dataset == P.A_SERIES else P.P_SERIES + dataset
            want = f"f8 [{len(cols)}] ({', '.join(cols)})"
            if dataset not in series:
                raise ArrayError(f"step {k}: missing series '{dataset}': expected {want}",
                                 name, want)
            row = series[dataset]
            if not isinstance(row, np.ndarray):
                try:
                    row = np.asarray(row, dtype=P.DTYPES["f8"])
                except (TypeError, ValueError):
                    row = np.asarray(row, dtype=object)
            if row.dtype != P.DTYPES["f8"] or row.shape != (len(cols),):
                raise ArrayError(f"step {k}: series '{dataset}': expected {want}, got "
                                 f"{row.dtype} {list(row.shape)}", name, want)
            out.append((name, P.wire_array(name, row)))
        return out

    def _prefixed(self, prefix, arrays, where):
        out = []
        for n, a in arrays.items():
            name = prefix + n
            P.check_name(name, f"{where} array name")
            out.append((name, P.wire_array(name, np.asarray(a))))
        return out

    def _state_arrays(self, state):
        if not isinstance(state, dict):
            raise ProtocolError("save_state() must return a dict of numpy arrays")
        return self._prefixed(P.P_STATE, state, "save_state()")

    # ---------------------------------------------------------- bus
    def publish(self, what, step=0, t=0.0, header=None, **arrays):
        """Publishes arrays on the run's bus as topic ``<name>.<what>``, type
        ``what``, with extra ``header`` fields (a copy is queued; dropped if
        monitors lag). No-op without a bus."""
        if not self._bus:
            return
        topic = f"{self.name}.{what}"
        P.check_name(topic, "topic")
        out = [(n, P.wire_array(n, np.asarray(a))) for n, a in arrays.items()]
        frames = P.encode(topic, what, step, t, out, header)
        try:
            P.send(self._bus, frames, zmq.NOBLOCK, copy_all=True)
        except zmq.Again:
            pass

    # ---------------------------------------------------------- sockets
    def _send(self, type_, step=0, t=0.0, arrays=(), fields=None, flags=0):
        frames = P.encode(self.name, type_, step, t, arrays, fields)
        with self._lock:
            P.send(self._sock, frames, flags)
            self._last_sent = time.monotonic()

    # ---------------------------------------------------------- liveness
    def progress(self, fraction=None, what=None):
        """Says how far a long init (before ready) or step is: ``fraction``
        in [0, 1], ``what`` a few words ("settling the bed"). `cosim run`
        shows init progress, and news restarts the coupler's deadline. Sent
        as a heartbeat when the coupler's protocol has them (else a no-op);
        at most ten a second."""
        if fraction is not None and not 0 <= fraction <= 1:
            raise ValueError(f"progress: fraction {fraction} is not in [0, 1]")
        if what is not None:
            what = "".join(c for c in str(what) if c.isprintable())[:P.WHAT_MAX]
        news = (fraction, what) != (self._progress, self._what)
        self._progress, self._what = fraction, what
        if self._beats and news and (time.monotonic() - self._last_progress > 0.1 or
                                     fraction in (0, 1)):
            with self._lock:
                self._beat()
            self._last_progress = time.monotonic()

    def _beat(self):
        """A heartbeat (the caller holds the lock)."""
        fields = {P.H_PHASE: self._phase}
        if self._progress is not None:
            fields[P.H_PROGRESS] = self._progress
        if self._what:
            fields[P.H_WHAT] = self._what
        step = self.step.k if self.step is not None else 0
        P.send(self._sock, P.encode(self.name, P.HEARTBEAT, step, 0.0, (), fields))
        self._last_sent = time.monotonic()

    def _beat_due(self):
        return self._beats and time.monotonic() - self._last_sent >= P.HEARTBEAT_S / 2

    def _beat_loop(self):
        """While the user's code runs (init, a step), the promise is kept
        from here; waiting for the coupler, _wait keeps it."""
        while not self._stop.wait(P.HEARTBEAT_S / 8):
            if self._beat_due() and self._lock.acquire(timeout=P.HEARTBEAT_S / 4):
                try:
                    if self._beat_due() and not self._closed:
                        self._beat()
                except zmq.ZMQError:
                    return
                finally:
                    self._lock.release()

    def _wait(self, timeout, what):
        """The next message from the coupler, decoded; ProtocolError on
        silence longer than timeout or when the launcher is gone."""
        until = time.monotonic() + timeout
        launched = os.environ.get(P.ENV_LAUNCHED)
        if self._ready_sent:
            self._phase = P.PHASE_IDLE
        while True:
            with self._lock:
                try:  # blocks up to POLL_MS (RCVTIMEO)
                    return P.decode(self._sock.recv_multipart(copy=False))
                except zmq.Again:
                    if self._beat_due():
                        self._beat()
            if time.monotonic() > until:
                raise ProtocolError(f"{what}: the coupler was silent for {timeout:.0f} s; "
                                    f"giving up")
            if launched and os.getppid() != self._parent:
                raise ProtocolError("the launcher died; exiting")

    def _report(self, e, where=""):
        """Sends the error to the coupler once (it names this participant)."""
        if self._error_sent or self._closed or isinstance(e, (GeneratorExit, SystemExit)):
            return
        text = where + (str(e) if isinstance(e, CosimError) else f"{type(e).__name__}: {e}")
        print(f"{self.name} ({self.role}): error: {text}", file=sys.stderr, flush=True)
        try:  # never blocks: there may be no coupler to take it
            self._send(P.ERROR, fields={P.H_MESSAGE: text}, flags=zmq.NOBLOCK)
            self._error_sent = True
        except zmq.ZMQError:
            pass

    def close(self):
        if self._closed:
            return
        self._stop.set()
        with self._lock:
            self._closed = True
        if self._bus:
            self._bus.close(0)
        self._sock.close()
        self._ctx.term()

    def __enter__(self):
        return self

    def __exit__(self, typ, e, tb):
        if e is not None and not isinstance(e, (KeyboardInterrupt, GeneratorExit, SystemExit)):
            s = self.step
            where = f"step {s.k} (t = {s.t:g} s): " if s and not s.replied else ""
            self._report(e, where)
        self.close()
        return False
