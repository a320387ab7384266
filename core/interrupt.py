"""Ctrl-C between co-simulation steps, never inside an FMU call.

Python raises KeyboardInterrupt at the next bytecode, which may be inside an FMU's own Python
code (pythonfmu runs FMUs in the host's interpreter): escaping there, it becomes fmi2Fatal and
the next call on that instance crashes the host. While :func:`deferred_sigint` is active, SIGINT
only sets a flag; a master loop asks :meth:`Deferred.requested` between steps, stops cleanly
(instances freed, what was recorded kept and marked incomplete) and the command line exits 130.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from typing import Any, Iterator

__all__ = ["EXIT_INTERRUPTED", "Deferred", "deferred_sigint", "pending"]

#: exit code of a command stopped by SIGINT (128 + 2, as shells report it)
EXIT_INTERRUPTED = 130


class Deferred:
    """Whether SIGINT arrived while deferred (``requested``), and how often."""

    def __init__(self) -> None:
        self.count = 0

    @property
    def requested(self) -> bool:
        return self.count > 0

    def _handler(self, signum: int, frame: Any) -> None:
        self.count += 1
        if self.count >= 3:  # a third Ctrl-C: the user insists, stop at once
            raise KeyboardInterrupt


_ACTIVE: list[Deferred] = []


def pending() -> bool:
    """Whether a deferred SIGINT waits to be honoured (False when nothing is deferred)."""
    return bool(_ACTIVE) and _ACTIVE[-1].requested


@contextlib.contextmanager
def deferred_sigint() -> Iterator[Deferred]:
    """Defer SIGINT to the caller's next check (main thread only, and only where SIGINT is not
    ignored, as it is in the sweep's worker processes; elsewhere a no-op)."""
    if _ACTIVE and threading.current_thread() is threading.main_thread():
        yield _ACTIVE[-1]  # already deferred (e.g. by the command line): the same flag
        return
    state = Deferred()
    if (threading.current_thread() is not threading.main_thread()
            or signal.getsignal(signal.SIGINT) is signal.SIG_IGN):  # e.g. a pool worker
        yield state
        return
    previous = signal.signal(signal.SIGINT, state._handler)
    _ACTIVE.append(state)
    try:
        yield state
    finally:
        _ACTIVE.pop()
        signal.signal(signal.SIGINT, previous)
