"""Reading a participant's config section with errors that name the key path
(``processes.block.c: expected a number``), like proto's proto_cfg_*: every
key read is remembered, and a key nobody read is an error ("unknown key")
unless the participant says it ignores the rest."""
import numpy as np

from .errors import ConfigError

EXEC_KEY = "exec"  # every section has it: the participant itself


class Config:
    """A JSON object (a participant's section, or a sub-object of it)."""

    def __init__(self, section, path):
        if not isinstance(section, dict):
            raise ConfigError(f"{path}: expected an object")
        self.data, self.path = section, path
        self._read = {EXEC_KEY}
        self._children = []
        self._ignoring = False
        self.run = None  # a participant's section: the welcome's run information

    def _fail(self, key, what):
        raise ConfigError(f"{self.path}.{key}: {what}")

    def _get(self, key, default, required):
        self._read.add(key)
        if key in self.data and self.data[key] is not None:
            return self.data[key], True
        if required:
            return None, False
        return default, None

    def __contains__(self, key):
        return key in self.data

    def get(self, key, default=None):
        """The raw JSON value (marks the key as read)."""
        self._read.add(key)
        return self.data.get(key, default)

    def number(self, key, default=None, min=None, max=None, required=None):
        """A number in [min, max]; required when no default is given."""
        v, found = self._get(key, default, default is None if required is None else required)
        if found is False:
            self._fail(key, "expected a number")
        if found and (isinstance(v, bool) or not isinstance(v, (int, float))):
            self._fail(key, f"expected a number, got {v!r}")
        if found and ((min is not None and v < min) or (max is not None and v > max)):
            want = (f"in [{min:g}, {max:g}]" if min is not None and max is not None else
                    f">= {min:g}" if min is not None else f"<= {max:g}")
            self._fail(key, f"must be {want}, got {v:g}")
        return float(v) if v is not None else v

    def integer(self, key, default=None, min=None, max=None):
        v = self.number(key, default, min, max)
        if v is not None and v != int(v):
            self._fail(key, f"expected an integer, got {v}")
        return int(v) if v is not None else v

    def string(self, key, default=None, choices=None):
        v, found = self._get(key, default, default is None)
        if found is False or (found and not isinstance(v, str)):
            self._fail(key, "expected a string")
        if choices and v not in choices:
            self._fail(key, f"expected one of {', '.join(choices)}, got {v!r}")
        return v

    def boolean(self, key, default=None):
        v, found = self._get(key, default, default is None)
        if found is False or (found and not isinstance(v, bool)):
            self._fail(key, "expected true or false")
        return v

    def array(self, key, dtype="f8", shape=None, default=None):
        """A nested JSON list as a numpy array; ``shape`` may use None for
        any size: ``shape=(None, 3)``."""
        v, found = self._get(key, default, default is None)
        if found is False:
            self._fail(key, f"expected a list{_shape_text(shape)}")
        try:
            a = np.array(v, dtype=dtype)
        except (TypeError, ValueError):
            self._fail(key, f"expected a list of numbers{_shape_text(shape)}")
        if shape is not None and (a.ndim != len(shape) or any(
                w is not None and w != g for w, g in zip(shape, a.shape))):
            self._fail(key, f"expected shape{_shape_text(shape)}, got {list(a.shape)}")
        return a

    def section(self, key, required=True):
        """A sub-object as a Config (None if absent and not required)."""
        v, found = self._get(key, None, required)
        if found is False:
            self._fail(key, "expected an object")
        if v is None:
            return None
        child = Config(v, f"{self.path}.{key}")
        self._children.append(child)
        return child

    def ignore_rest(self):
        """Accept the keys not read (a stand-in for another solver); returns
        their names, to be logged."""
        self._ignoring = True
        return sorted(set(self.data) - self._read)

    def finish(self):
        """ConfigError for the first key nobody read (recursively)."""
        if not self._ignoring:
            for key in self.data:
                if key not in self._read:
                    self._fail(key, "unknown key")
        for c in self._children:
            c.finish()


def _shape_text(shape):
    if shape is None:
        return ""
    return " [" + ", ".join("*" if d is None else str(d) for d in shape) + "]"
