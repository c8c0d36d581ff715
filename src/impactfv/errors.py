"""Exceptions a user can meet, each mapped to a CLI exit code."""


class InputError(ValueError):
    """A problem with the user's input (case file, mesh file, values). CLI exit code 2.

    The message is one line naming the key path or file and what was expected.
    """


class SimulationError(RuntimeError):
    """A run that failed numerically (non-finite state, collapsed control volume). Exit 3."""

    def __init__(self, message, step=None, time=None, body=None, node=None):
        super().__init__(message)
        self.step, self.time, self.body, self.node = step, time, body, node


def printable(text) -> str:
    """``text`` with control characters (newlines, terminal escape codes) shown as escapes,
    so that a file name or title can never break a one-line message or the terminal."""
    return "".join(ch if ch.isprintable() else repr(ch)[1:-1] for ch in str(text))


class Interrupted(Exception):
    """The run was stopped by a signal after writing a checkpoint; CLI exit 128 + signum."""

    def __init__(self, signum, checkpoint):
        super().__init__(f"interrupted by signal {signum}; checkpoint written to {checkpoint}")
        self.signum = signum
        self.checkpoint = checkpoint
