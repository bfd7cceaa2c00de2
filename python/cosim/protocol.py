"""The wire protocol (proto/PROTOCOL.md), in one place: message types, header
keys, limits, and the framing ``[topic] [JSON header] [array frame]...``.

What the protocol states as data -- the message types and their directions,
the arrays each role exchanges, the prefixes of participant-defined arrays --
comes from the role table (``cosim roles --json``, see :mod:`cosim.roles`);
the names below are the ones this package uses, and
:func:`cosim.roles.RoleTable.require` checks them against the table so that
a package older or newer than the coupler says so instead of misbehaving.
"""
import json
import os

import numpy as np
import zmq

from .errors import ProtocolError

VERSION = 1

# ---- message types (role table "messages"); direction: P -> C or C -> P
HELLO = "hello"            # P -> C: role, name, pid
WELCOME = "welcome"        # C -> P: config, run
READY = "ready"            # P -> C: role, rollback, series, snapshot
STEP = "step"              # C -> P: step, t, dt, output, iteration
DONE = "done"              # P -> C: step, t, iteration, compute_s
STOP = "stop"              # C -> P
BYE = "bye"                # P -> C
ERROR = "error"            # P -> C: message
CHECKPOINT = "checkpoint"  # C -> P: step
STATE = "state"            # P -> C: state.<x> arrays
RESTORE = "restore"        # C -> P: state.<x> arrays
RESTORED = "restored"      # P -> C
HEARTBEAT = "heartbeat"    # P -> C: step, phase, progress, what (never answered)
P_TO_C, C_TO_P = "participant->coupler", "coupler->participant"
USED_MESSAGES = {HELLO: P_TO_C, WELCOME: C_TO_P, READY: P_TO_C, STEP: C_TO_P,
                 DONE: P_TO_C, STOP: C_TO_P, BYE: P_TO_C, ERROR: P_TO_C,
                 CHECKPOINT: C_TO_P, STATE: P_TO_C, RESTORE: C_TO_P,
                 RESTORED: P_TO_C}
# Used only when the coupler's role table has it (liveness, PROTOCOL.md)
OPTIONAL_MESSAGES = {HEARTBEAT: P_TO_C}

# ---- header keys: fixed fields of every header, then type-specific ones
H_V, H_TYPE, H_STEP, H_T, H_ARRAYS = "v", "type", "step", "t", "arrays"
H_A_NAME, H_A_DTYPE, H_A_SHAPE = "name", "dtype", "shape"
H_ROLE = "role"            # hello, ready
H_NAME = "name"            # hello
H_PID = "pid"              # hello
H_HEARTBEAT_S = "heartbeat_s"  # hello: the longest the participant stays silent, s
H_PHASE = "phase"          # heartbeat: PHASE_*
H_PROGRESS = "progress"    # heartbeat: fraction done in [0, 1] (optional)
H_WHAT = "what"            # heartbeat: what it is doing (optional, <= WHAT_MAX chars)
H_CONFIG = "config"        # welcome: the participant's section of the scene
H_RUN = "run"              # welcome: run information (RUN_* keys)
H_DT = "dt"                # step
H_OUTPUT = "output"        # step: snapshot wanted
H_ITERATION = "iteration"  # step, done: 0, or the repeat n >= 1 of step k
H_COMPUTE_S = "compute_s"  # done: seconds the participant spent on the step
H_ROLLBACK = "rollback"    # ready: it can repeat a step
H_SERIES = "series"        # ready: {dataset: [column names]}
H_SNAPSHOT = "snapshot"    # ready: how to show snapshots (kind, geometry, ...)
H_MESSAGE = "message"      # error
H_COLUMNS = "columns"      # bus: coupler.timing, coupler.traction, ...
H_N_STEPS = "n_steps"      # bus: coupler.progress

# ---- liveness: a participant that promises heartbeat_s in its hello is never
# silent longer than that until its bye; it says what it does in each phase
HEARTBEAT_S = 1.0
PHASE_WELCOME, PHASE_INIT, PHASE_STEP = "welcome", "init", "step"
PHASE_STATE, PHASE_IDLE = "state", "idle"
WHAT_MAX = 63

# ---- keys of welcome.run
RUN_NAME, RUN_DT, RUN_T_END, RUN_N_STEPS = "name", "dt", "t_end", "n_steps"
RUN_OUTPUT_EVERY, RUN_OUTPUT_DIR, RUN_BUS = "output_every", "output_dir", "bus"
RUN_IDLE_TIMEOUT, RUN_SCHEME, RUN_ROLLBACK = "idle_timeout_s", "scheme", "rollback"
RUN_RESTART_STEP = "restart_step"  # > 0: the run restarts from this step's checkpoint

# ---- participant-defined arrays, by prefix (role table "prefixes")
A_SERIES = "series"   # done: the row of the "series" dataset
P_SERIES = "series."  # done: rows of further datasets
P_SNAP = "snap."      # done at output steps: snapshot arrays
P_MESH = "mesh."      # ready: written once
P_STATE = "state."    # state, restore: the participant's whole changing state
USED_PREFIXES = (A_SERIES, P_SERIES, P_SNAP, P_MESH, P_STATE)

# ---- bus topics the coupler publishes
TOPIC_PROGRESS = "coupler.progress"

# ---- environment: set by `cosim run` for what it launches, or by hand
ENV_LAUNCHED = "COSIM_LAUNCHED"   # started by cosim: exit when the launcher dies
ENV_EXE = "COSIM_EXE"             # the cosim binary (its role table)
ENV_ROLES = "COSIM_ROLES"         # or the role table as a JSON file
ENV_CURVE_FILE = "COSIM_CURVE_FILE"  # this client's CURVE key file (security.curve)
# ---- a CURVE key file: a JSON object of three Z85 keys, mode 0600
KEY_SERVER_PUBLIC, KEY_PUBLIC, KEY_SECRET = "server_public", "public", "secret"
ENV_ENDPOINT, ENV_NAME = "COSIM_ENDPOINT", "COSIM_NAME"
ENV_HANDSHAKE_TIMEOUT = "COSIM_HANDSHAKE_TIMEOUT"
HANDSHAKE_TIMEOUT_S = 30.0        # wait this long for welcome (as proto)
IDLE_TIMEOUT_S = 600.0            # when welcome.run does not say

# ---- limits of the framing
NAME_MAX = 47                     # topic, type and array names, bytes
MAX_ARRAYS = 64
MAX_NDIM = 3
MAX_FRAME_BYTES = 1 << 30
DTYPES = {"f8": np.dtype("<f8"), "i4": np.dtype("<i4"), "i8": np.dtype("<i8"),
          "u1": np.dtype("u1")}
DTYPE_NAMES = {dt: name for name, dt in DTYPES.items()}


class Message:
    """One decoded message: ``topic``, ``header`` (the JSON object) and
    ``arrays`` (name -> numpy array; read-only views of the received frames,
    no copy). ``type``, ``step`` and ``t`` are the header's fixed fields."""
    __slots__ = ("topic", "header", "arrays")

    def __init__(self, topic, header, arrays):
        self.topic, self.header, self.arrays = topic, header, arrays

    type = property(lambda self: self.header[H_TYPE])
    step = property(lambda self: self.header.get(H_STEP, 0))
    t = property(lambda self: self.header.get(H_T, 0.0))

    def __getitem__(self, name):
        return self.arrays[name]

    def __iter__(self):  # topic, header, arrays = msg
        return iter((self.topic, self.header, self.arrays))

    @property
    def row(self):
        """{column: value} of the "series" array when the header names its
        columns (coupler.timing, coupler.traction, ...), else None."""
        cols, row = self.header.get(H_COLUMNS), self.arrays.get(A_SERIES)
        if not isinstance(cols, list) or row is None or len(cols) != len(row):
            return None
        return dict(zip(cols, row.tolist()))

    def __repr__(self):
        shapes = ", ".join(f"{k}{list(v.shape)}" for k, v in self.arrays.items())
        return f"<Message {self.topic} {self.type} step={self.step} t={self.t:g} {shapes}>"


def check_name(name, what="array name"):
    """Names go into the JSON header verbatim: 1..47 bytes, plain."""
    raw = name.encode() if isinstance(name, str) else b""
    if not 0 < len(raw) <= NAME_MAX or any(c in name for c in '"\\') or \
            any(ord(c) < 0x20 for c in name):
        raise ProtocolError(f"{what} {name!r}: expected 1..{NAME_MAX} plain characters")


def wire_array(name, a):
    """``a`` as an array the wire can carry unchanged (C order, a protocol
    dtype, 1..3 dimensions), or ProtocolError naming it. Already-fitting
    arrays are returned as they are: no copy."""
    if not isinstance(a, np.ndarray):
        raise ProtocolError(f"array '{name}': expected a numpy array, got {type(a).__name__}")
    if a.dtype not in DTYPE_NAMES:
        raise ProtocolError(f"array '{name}': dtype {a.dtype} is not one of the protocol's "
                            f"(f8, i4, i8, u1)")
    if not 1 <= a.ndim <= MAX_NDIM:
        raise ProtocolError(f"array '{name}': {a.ndim} dimensions, expected 1..{MAX_NDIM}")
    if a.nbytes > MAX_FRAME_BYTES:
        raise ProtocolError(f"array '{name}': {a.nbytes} bytes exceeds the limit of "
                            f"{MAX_FRAME_BYTES}")
    return a if a.flags.c_contiguous else np.ascontiguousarray(a)


def encode(topic, type_, step=0, t=0.0, arrays=(), fields=None):
    """Frames of one message. ``arrays``: (name, ndarray) pairs already
    passed through :func:`wire_array`; the frames are the arrays themselves
    (send them with ``copy=False`` for zero copy)."""
    if len(arrays) > MAX_ARRAYS:
        raise ProtocolError(f"{len(arrays)} arrays, at most {MAX_ARRAYS} allowed")
    header = {H_V: VERSION, H_TYPE: type_, H_STEP: step, H_T: t,
              H_ARRAYS: [{H_A_NAME: n, H_A_DTYPE: DTYPE_NAMES[a.dtype],
                          H_A_SHAPE: list(a.shape)} for n, a in arrays]}
    if fields:
        header.update(fields)
    return [topic.encode(), json.dumps(header).encode()] + [a for _, a in arrays]


def curve_client(sockets, key_file):
    """Makes sockets CURVE clients with the keys of key_file (before they
    connect); the file must not be readable by others."""
    try:
        st = os.stat(key_file)
        with open(key_file) as f:
            keys = json.load(f)
    except (OSError, ValueError) as e:
        raise ProtocolError(f"CURVE key file {key_file}: {e}") from None
    if st.st_mode & 0o077:
        raise ProtocolError(f"CURVE key file {key_file}: readable by others "
                            f"(mode {st.st_mode & 0o777:o}); chmod 600 it")
    if not zmq.has("curve"):
        raise ProtocolError("this libzmq has no CURVE support")
    try:
        for sock in sockets:
            sock.curve_serverkey = keys[KEY_SERVER_PUBLIC].encode()
            sock.curve_publickey = keys[KEY_PUBLIC].encode()
            sock.curve_secretkey = keys[KEY_SECRET].encode()
    except (KeyError, AttributeError, zmq.ZMQError) as e:
        raise ProtocolError(f"CURVE key file {key_file}: expected {KEY_SERVER_PUBLIC}, "
                            f"{KEY_PUBLIC}, {KEY_SECRET} as 40-character Z85 keys ({e})") from None


_SNDMORE = int(zmq.SNDMORE)
ZERO_COPY_BYTES = 1 << 16  # below this, copying beats pyzmq's zero-copy bookkeeping


def send(sock, frames, flags=0, copy_all=False):
    """Sends frames as one message: arrays of 64 kB and more without a copy
    (the caller keeps them unchanged until the peer answers), the rest
    copied. ``copy_all`` for sockets whose messages may outlive the arrays
    (the bus)."""
    flags = int(flags)
    last = len(frames) - 1
    for i, f in enumerate(frames):
        big = not copy_all and isinstance(f, np.ndarray) and f.nbytes >= ZERO_COPY_BYTES
        sock.send(f, flags | (_SNDMORE if i < last else 0), copy=not big)


def _frame_bytes(f):
    return f.bytes if hasattr(f, "bytes") else bytes(f)


def _frame_buffer(f):
    return f.buffer if hasattr(f, "buffer") else f


def decode(frames):
    """A :class:`Message` from received frames (bytes or ``zmq.Frame`` from
    ``recv_multipart(copy=False)``: then the arrays are views of the frames).
    Rejects what PROTOCOL.md says a receiver rejects, naming the defect."""
    if len(frames) < 2:
        raise ProtocolError(f"message has {len(frames)} frame(s), need at least 2")
    topic = _frame_bytes(frames[0])
    if len(topic) > NAME_MAX:
        raise ProtocolError(f"topic longer than {NAME_MAX} bytes")
    try:
        h = json.loads(_frame_bytes(frames[1]))
    except ValueError:
        h = None
    if not isinstance(h, dict):
        raise ProtocolError("header is not a JSON object")
    v = h.get(H_V)
    if not isinstance(v, (int, float)) or isinstance(v, bool):
        raise ProtocolError("header.v: expected the protocol version number")
    if v != VERSION:
        raise ProtocolError(f"protocol version mismatch: peer speaks v{v}, this package "
                            f"speaks v{VERSION}")
    typ = h.get(H_TYPE)
    if not isinstance(typ, str) or not 0 < len(typ) <= NAME_MAX:
        raise ProtocolError("header.type: expected a non-empty string")
    for key in (H_STEP, H_T):
        if key in h and (not isinstance(h[key], (int, float)) or isinstance(h[key], bool)):
            raise ProtocolError(f"header.{key}: expected a number")
    specs = h.get(H_ARRAYS, [])
    if not isinstance(specs, list):
        raise ProtocolError("header.arrays: expected a list")
    if len(specs) > MAX_ARRAYS:
        raise ProtocolError(f"{len(specs)} arrays, at most {MAX_ARRAYS} allowed")
    if len(specs) != len(frames) - 2:
        raise ProtocolError(f"header lists {len(specs)} array(s) but {len(frames) - 2} "
                            f"array frame(s) arrived")
    arrays = {}
    for i, (spec, frame) in enumerate(zip(specs, frames[2:])):
        name, a = _decode_array(i, spec, _frame_buffer(frame))
        if name in arrays:
            raise ProtocolError(f"array '{name}' appears twice")
        arrays[name] = a
    return Message(topic.decode(errors="replace"), h, arrays)


def _decode_array(i, spec, buf):
    spec = spec if isinstance(spec, dict) else {}
    name, dtype, shape = spec.get(H_A_NAME), spec.get(H_A_DTYPE), spec.get(H_A_SHAPE)
    if not isinstance(name, str) or not 0 < len(name.encode()) <= NAME_MAX:
        raise ProtocolError(f"arrays[{i}].name: expected a string of 1..{NAME_MAX} chars")
    if dtype not in DTYPES:
        raise ProtocolError(f"arrays[{i}].dtype: expected one of f8, i4, i8, u1")
    if not isinstance(shape, list) or not 1 <= len(shape) <= MAX_NDIM:
        raise ProtocolError(f"arrays[{i}].shape: expected 1..{MAX_NDIM} dimensions")
    for d, e in enumerate(shape):
        if isinstance(e, bool) or not isinstance(e, (int, float)) or \
                not 0 <= e <= 10 ** 12 or e != int(e):
            raise ProtocolError(f"arrays[{i}].shape[{d}]: expected a count >= 0")
    shape = [int(e) for e in shape]
    dt = DTYPES[dtype]
    need = int(np.prod(shape, dtype=np.float64)) * dt.itemsize
    if need > MAX_FRAME_BYTES:
        raise ProtocolError(f"array '{name}': {need} bytes exceeds the limit of "
                            f"{MAX_FRAME_BYTES}")
    have = memoryview(buf).nbytes
    if need != have:
        raise ProtocolError(f"array '{name}' ({dtype}, shape {shape}) needs {need} bytes, "
                            f"frame has {have}")
    return name, np.frombuffer(buf, dtype=dt).reshape(shape)
