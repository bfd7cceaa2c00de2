"""Exceptions of the cosim package. Every message names what is wrong: the
key path, the array and its expected shape, or the participant."""


class CosimError(Exception):
    """Base of every error this package raises."""


class ProtocolError(CosimError):
    """A message that breaks PROTOCOL.md (framing, header, sequence)."""


class ArrayError(ProtocolError, ValueError):
    """An array missing from a message, or of the wrong dtype or shape,
    against the role table. The message names the array, its expected
    dtype and shape (with the sizes bound so far) and its meaning."""

    def __init__(self, message, array=None, expected=None):
        super().__init__(message)
        self.array, self.expected = array, expected


class ConfigError(CosimError, ValueError):
    """A participant's config section is wrong; the message starts with the
    key path (``processes.block.c: expected a number``)."""


class RunError(CosimError):
    """``cosim run`` (or sweep) ended with a non-zero exit code.

    Attributes: ``returncode``, ``stdout``, ``stderr``, ``output_dir``,
    ``participant`` (the failed participant's name, when cosim named one),
    ``reason`` (cosim's one-line reason)."""

    def __init__(self, message, returncode=None, stdout="", stderr="",
                 output_dir=None, participant=None, reason=None):
        super().__init__(message)
        self.returncode, self.stdout, self.stderr = returncode, stdout, stderr
        self.output_dir, self.participant, self.reason = output_dir, participant, reason


class SceneError(RunError):
    """Exit 1: a bad scene or usage (the message names the key path)."""


class ParticipantError(RunError):
    """Exit 3: a participant failed (crashed, went silent, sent an error)."""


class OutputError(RunError):
    """Exit 4: results.h5 could not be written completely."""


class Interrupted(RunError):
    """Exit 130: the run was interrupted (Ctrl-C, SIGTERM)."""


EXIT_ERRORS = {1: SceneError, 3: ParticipantError, 4: OutputError, 130: Interrupted}
