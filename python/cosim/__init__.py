"""cosim from Python: write a participant, watch a run, read its results.

    cosim.Participant(role, ...)   a solver process speaking the protocol
    cosim.Monitor(source, topics)  the messages of a running scene's bus
    cosim.Results(path)            a run's results.h5 as named columns
    cosim.run(scene, set={...})    `cosim run` with its exit codes as exceptions
    cosim.sweep(scene, values)     one run per value
    cosim.stats                    95 % intervals: batch means, across runs
    cosim.read_summary(path)       a `cosim sweep` summary.csv / runs.csv as rows

See python/README.md; the protocol is proto/PROTOCOL.md.
"""
from .config import Config
from .errors import (ArrayError, ConfigError, CosimError, Interrupted, OutputError,
                     ParticipantError, ProtocolError, RunError, SceneError)
from .monitor import Monitor
from .participant import Participant, Step
from .protocol import Message
from .results import Results, Table
from .roles import RoleTable
from . import stats
from .runner import run, sweep
from .sweep_cli import read_summary

__all__ = ["Participant", "Step", "Config", "Monitor", "Message", "Results", "Table",
           "RoleTable", "run", "sweep", "stats", "read_summary", "CosimError", "ProtocolError", "ArrayError",
           "ConfigError", "RunError", "SceneError", "ParticipantError", "OutputError",
           "Interrupted"]
__version__ = "0.1.0"
