"""Scene dicts with ``--set``-style key paths applied (``a.b[1].c``), as
``cosim run --set`` does: used by the runner (the settle run's time.dt) and by
the sweep's beds (each point's scene). Imports only cosim.errors."""
import copy
import re

from .errors import CosimError


def _path_tokens(key):
    """'a.b[1].c' -> ['a', 'b', 1, 'c'] (the --set key paths of cosim run)."""
    out = []
    for part in key.split("."):
        m = re.fullmatch(r"([^\[\]]*)((?:\[\d+\])*)", part)
        if not m or not m.group(1):
            raise CosimError(f"--set {key}: bad key path")
        out.append(m.group(1))
        out += [int(i) for i in re.findall(r"\[(\d+)\]", m.group(2))]
    return out


def apply_sets(scene, sets):
    """A copy of the scene dict with each {key.path: value} set (objects made
    on the way, as cosim run's --set)."""
    s = copy.deepcopy(scene)
    for key, value in sets.items():
        node, toks = s, _path_tokens(key)
        for t, nxt in zip(toks, toks[1:]):
            if isinstance(t, int):
                node = node[t]
            else:
                node = node.setdefault(t, [] if isinstance(nxt, int) else {})
        node[toks[-1]] = copy.deepcopy(value)
    return s
