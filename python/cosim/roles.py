"""The role table: which arrays each role (dem, fem, block, lug) exchanges in each
message, with dtype, shape (symbolic ``n`` surface nodes, ``m`` triangles),
units and meaning. Declared once, in the C sources (proto/roles.c); this
module reads it from ``cosim roles --json`` and checks arrays against it the
way proto_role_check does, with the same messages.

Where the table comes from, first found:
  1. the ``roles`` argument: a dict, or the path of a JSON file;
  2. $COSIM_ROLES, the path of such a file (``cosim roles --json > roles.json``);
  3. ``$COSIM_EXE roles --json`` (``cosim run`` sets COSIM_EXE for what it
     launches: the table of the very coupler that runs the scene);
  4. ``cosim roles --json`` with ``cosim`` found on PATH.
"""
import json
import os
import shutil
import subprocess

import numpy as np

from . import protocol as P
from .errors import ArrayError, CosimError, ProtocolError

WHEN_SURFACE = "with_surface"
# "<name>_index" rows (proto/PROTOCOL.md "Sparse exchange") are optional: this
# package sends and expects the dense form (its fem says no "sparse" in ready,
# its dem gives no "reach"), so the coupler never sends it the sparse one
WHEN_INDEX = "sparse_index"
_cache = {}


def cosim_executable(cosim=None):
    """The cosim binary: ``cosim`` if given, else $COSIM_EXE, else on PATH."""
    exe = cosim or os.environ.get(P.ENV_EXE) or shutil.which("cosim")
    if not exe or not os.access(exe, os.X_OK):
        tried = cosim or os.environ.get(P.ENV_EXE) or "'cosim' on PATH"
        raise CosimError(f"the cosim executable was not found (tried {tried}); put the "
                         f"build's bin/ on PATH or set {P.ENV_EXE}=/path/to/cosim")
    return exe


class ArraySpec:
    """One row of the table."""
    __slots__ = ("name", "dtype", "shape", "units", "when", "meaning")

    def __init__(self, row):
        self.name, self.units, self.meaning = row["name"], row["units"], row["meaning"]
        self.dtype = P.DTYPES[row["dtype"]]
        self.shape = tuple(row["shape"])  # ints, or "n" / "m" / "k" / "c"
        self.when = row["when"]


class Dims:
    """The symbolic sizes as one conversation bound them (None: unbound)."""

    def __init__(self):
        self.sizes = {}
        self.surface = False

    def want(self, spec):
        """'[n=25, 3]' (or '[n, 3]' while n is unbound)."""
        parts = [str(d) if isinstance(d, int) else
                 (f"{d}={self.sizes[d]}" if d in self.sizes else d) for d in spec.shape]
        return "[" + ", ".join(parts) + "]"


class RoleTable:
    def __init__(self, data):
        try:
            self.version = data["version"]
            self.messages = {m["type"]: m["direction"] for m in data["messages"]}
            self.prefixes = dict(data["prefixes"])
            self.roles = {role: {msg: [ArraySpec(r) for r in rows] for msg, rows in msgs.items()}
                          for role, msgs in data["roles"].items()}
        except (KeyError, TypeError) as e:
            raise CosimError(f"the role table is not what this package reads (missing {e})")
        self.require()

    @classmethod
    def load(cls, roles=None, cosim=None):
        """The table from a dict, a JSON file, or the cosim binary (cached)."""
        if isinstance(roles, dict):
            return cls(roles)
        roles = roles or os.environ.get(P.ENV_ROLES)
        if roles:
            with open(roles) as f:
                return cls(json.load(f))
        exe = cosim_executable(cosim)
        if exe not in _cache:
            p = subprocess.run([exe, "roles", "--json"], capture_output=True, text=True)
            if p.returncode != 0:
                raise CosimError(f"{exe} roles --json failed: {p.stderr.strip()}")
            _cache[exe] = cls(json.loads(p.stdout))
        return _cache[exe]

    def require(self):
        """The names this package uses exist in the table with the
        directions it assumes (else the coupler speaks another protocol)."""
        if self.version != P.VERSION:
            raise ProtocolError(f"the role table is protocol v{self.version}; this package "
                                f"speaks v{P.VERSION}")
        for typ, direction in P.OPTIONAL_MESSAGES.items():
            if self.messages.get(typ, direction) != direction:
                raise ProtocolError(f"the role table's message '{typ}' is not {direction}")
        for typ, direction in P.USED_MESSAGES.items():
            if self.messages.get(typ) != direction:
                raise ProtocolError(f"the role table has no message '{typ}' ({direction}): "
                                    f"this package does not match the coupler")
        for prefix in P.USED_PREFIXES:
            if prefix not in self.prefixes:
                raise ProtocolError(f"the role table has no array prefix '{prefix}'")

    def has_message(self, typ):
        return typ in self.messages

    def check_role(self, role):
        if role not in self.roles:
            raise CosimError(f"unknown role '{role}' (the role table has: "
                             f"{', '.join(sorted(self.roles))})")

    def specs(self, role, msg):
        return self.roles.get(role, {}).get(msg, [])

    def names(self, role, msg):
        return [s.name for s in self.specs(role, msg)]

    def check(self, role, msg, arrays, dims, where=""):
        """Checks the arrays of message ``msg`` of ``role`` (name -> ndarray)
        against the table, binding n and m; ArrayError names the first
        missing or wrong array (as proto_role_check)."""
        specs = self.specs(role, msg)
        if msg in (P.WELCOME, P.READY) and any(
                s.when == WHEN_SURFACE and s.name in arrays for s in specs):
            dims.surface = True
        for s in specs:
            if s.when == WHEN_INDEX or (s.when == WHEN_SURFACE and not dims.surface):
                continue
            a = arrays.get(s.name)
            if a is None or not self._fits(s, a, dims):
                raise self.error(role, msg, s, a, dims, where)

    @staticmethod
    def _fits(s, a, dims):
        if a.dtype != s.dtype or a.ndim != len(s.shape):
            return False
        bound = dict(dims.sizes)
        for want, got in zip(s.shape, a.shape):
            if isinstance(want, int):
                if got != want:
                    return False
            elif bound.setdefault(want, got) != got:
                return False
        dims.sizes = bound
        return True

    @staticmethod
    def error(role, msg, s, a, dims, where=""):
        want = dims.want(s)
        expected = f"{P.DTYPE_NAMES[s.dtype]} {want}"
        if a is None:
            text = f"{where}{msg} (role {role}): missing array '{s.name}': expected {expected} ({s.meaning})"
        else:
            got = f"{P.DTYPE_NAMES.get(a.dtype, str(a.dtype))} {list(a.shape)}"
            text = (f"{where}{msg} (role {role}): wrong shape or dtype of array '{s.name}': "
                    f"expected {expected} ({s.meaning}), got {got}")
        return ArrayError(text, array=s.name, expected=expected)


def as_wire(spec, value):
    """What the user gave for a table array, as the array to send: numpy
    arrays must already have the table's dtype (no silent conversion);
    lists, tuples and Python numbers are converted if they hold numbers of
    the right kind (a number stands for a one-element array). The shape is
    checked by RoleTable.check."""
    if isinstance(value, np.ndarray):
        return value
    a = np.asarray(value)
    kind_ok = a.dtype.kind in ("iub" if spec.dtype.kind in "iu" else "iuf")
    if not kind_ok:
        return a  # RoleTable.check names it
    if spec.dtype.kind in "iu" and a.size and (a.min() < np.iinfo(spec.dtype).min or
                                                a.max() > np.iinfo(spec.dtype).max):
        return a
    a = a.astype(spec.dtype)
    if a.ndim == 0 and spec.shape == (1,):
        a = a.reshape(1)
    return a
