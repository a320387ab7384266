"""SIGINT delivered at a known point of a run, for the tests of Ctrl-C (never after a delay).

:class:`SigintAtCheck` sends SIGINT to this process the ``k``-th time a master asks whether
Ctrl-C came (it asks between steps; a deferred SIGINT only sets the flag it reads), so the
interrupt lands in the middle of the run whatever the machine's speed. :func:`sigint_after_chunk`
sends it when the sweep has finished its first chunk of cases. Run as a script, it is the
command line with one of them installed: ``python sigint_at.py cosim ...`` or ``... sweep ...``.
"""

from __future__ import annotations

import os
import signal
import sys
from typing import Any

from dronefly.core import interrupt

__all__ = ["SigintAtCheck", "install_at_check", "sigint_after_chunk"]


def _ctrl_c() -> None:
    os.kill(os.getpid(), signal.SIGINT)


class SigintAtCheck(interrupt.Deferred):
    """A deferred SIGINT whose ``at``-th read of its count sends SIGINT (reads counted over
    every instance)."""

    at = 50
    reads = 0

    @property  # type: ignore[override]
    def count(self) -> int:
        SigintAtCheck.reads += 1
        if SigintAtCheck.reads == SigintAtCheck.at:
            _ctrl_c()
        return self.__dict__.get("n", 0)

    @count.setter
    def count(self, value: int) -> None:
        self.__dict__["n"] = value


def install_at_check(monkeypatch: Any, at: int) -> None:
    """Make :func:`dronefly.core.interrupt.deferred_sigint` use :class:`SigintAtCheck` (``at``-th read)."""
    monkeypatch.setattr(SigintAtCheck, "at", at)
    monkeypatch.setattr(SigintAtCheck, "reads", 0)
    monkeypatch.setattr(interrupt, "Deferred", SigintAtCheck)


def sigint_after_chunk(run_sweep: Any) -> Any:
    """``run_sweep`` that sends SIGINT once its first chunk of cases is finished."""

    def run(*args: Any, on_chunk: Any = None, **kwargs: Any) -> Any:
        sent = []

        def chunk_done(done: int, total: int) -> None:
            if on_chunk is not None:
                on_chunk(done, total)
            if not sent:  # once: the chunks that finish after it must not send more
                sent.append(done)
                _ctrl_c()

        return run_sweep(*args, on_chunk=chunk_done, **kwargs)

    return run


if __name__ == "__main__":
    # as from a terminal: a background test run may have started this process with SIGINT ignored
    signal.signal(signal.SIGINT, signal.default_int_handler)
    from dronefly.cli.app import main
    from dronefly.harness.sweep import run as sweep_run

    if sys.argv[1] == "sweep":
        sweep_run.run_sweep = sigint_after_chunk(sweep_run.run_sweep)
    else:
        interrupt.Deferred = SigintAtCheck
    sys.exit(main(sys.argv[1:]))
