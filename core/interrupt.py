"""Ctrl-C between co-simulation steps, never inside an FMU call.

Python raises KeyboardInterrupt at the next bytecode, which may be inside an FMU's own Python
code (pythonfmu runs FMUs in the host's interpreter): escaping there, it becomes fmi2Fatal and
the next call on that instance crashes the host. While :func:`deferred_sigint` is active, SIGINT
only sets a flag; a master loop asks :meth:`Deferred.requested` between steps, stops cleanly
(instances freed, what was recorded kept and marked incomplete) and the command line exits 130.
Loops that wait or compute between FMU calls call :func:`checkpoint` (it raises
``KeyboardInterrupt`` when a SIGINT waits). Code that runs no FMU at all takes SIGINT at once
(:func:`sigint_at_once`): there is no FMU to protect, so nothing to wait for.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from typing import Any, Iterator

__all__ = ["EXIT_INTERRUPTED", "Deferred", "checkpoint", "deferred_sigint", "pending",
           "sigint_at_once"]

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


def checkpoint() -> None:
    """Raise ``KeyboardInterrupt`` if a deferred SIGINT waits: the call of a loop between its
    steps (an FMU step, a sweep chunk, an FMU checked), where stopping is safe."""
    if pending():
        raise KeyboardInterrupt


@contextlib.contextmanager
def sigint_at_once() -> Iterator[Deferred]:
    """SIGINT raises ``KeyboardInterrupt`` at once (Python's default) inside the block: for code
    that runs no FMU (analyses of the model alone), where no FMU call can be cut in two.

    Yields a :class:`Deferred` that stays unrequested (the same shape as
    :func:`deferred_sigint`). Where SIGINT is ignored (a pool worker) it stays ignored.
    """
    state = Deferred()
    if (threading.current_thread() is not threading.main_thread()
            or signal.getsignal(signal.SIGINT) is signal.SIG_IGN):
        yield state
        return
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        yield state
    finally:
        signal.signal(signal.SIGINT, previous)


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
