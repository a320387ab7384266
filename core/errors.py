"""The one base class of the project's input errors.

Every error that means "the input was not acceptable" (a bad parameter, file,
option or set-up) derives from :class:`DroneflyError`, itself a ``ValueError``,
so callers can catch one class. The command line maps exactly these (and
``OSError`` on files) to exit code 2 with a one-line message; any other
exception is a bug and is reported as one.

Shipped inside the FMUs (the model and the controller law raise subclasses),
so it imports nothing.
"""

from __future__ import annotations

__all__ = ["CrossCheckError", "DroneflyError"]


class DroneflyError(ValueError):
    """Bad input: the message names the variable and its value."""


class CrossCheckError(DroneflyError):
    """A run's own cross-check contradicts the answer it would give (a verdict, a number):
    the message says which check and by how much. The command line exits 1 on it."""
