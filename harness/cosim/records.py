"""What a co-simulation run records: :class:`LoopRun` (signals over time, the failure that
stopped it early, the FMUs' messages) and :class:`StepFailure`; the masters' names and the
limit on the steps of a run.

Shared by the pair's :class:`~.master.Loop` and the system master
(:mod:`dronefly.harness.cosim.system_master`) that runs it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ...core.text import float_text, status_name

__all__ = ["MASTERS", "MAX_STEPS", "LoopRun", "StepFailure"]

MASTERS = ("gauss-seidel", "jacobi")
#: Communication steps per run at most: the recorded signals take 8 bytes per signal and step
#: (8 MB per recorded signal at the limit), and a run's time grows in proportion.
MAX_STEPS = 1_000_000


@dataclass(frozen=True)
class StepFailure:
    """Where a run stopped early."""

    fmu: str
    call: str
    time: float
    status: int
    message: str

    def __str__(self) -> str:
        return (f"{self.fmu}: {self.call} at t = {float_text(self.time)} s returned "
                f"{status_name(self.status, self.call)}"
                + (f" ({self.message})" if self.message else ""))


@dataclass
class LoopRun:
    """Recorded signals of one run: ``time`` (N,) s, ``signals`` (N, len(names))."""

    names: list[str]
    time: np.ndarray
    signals: np.ndarray
    failure: StepFailure | None = None
    messages: list[str] = field(default_factory=list)

    @property
    def complete(self) -> bool:
        return self.failure is None

    def column(self, name: str) -> np.ndarray:
        return self.signals[:, self.names.index(name)]

