"""Pieces of the fuzz (:mod:`.fuzzcases`): one FMI call with its status and messages recorded.

Runs in the fuzz's child process, through fmpy's low-level API.
"""

from __future__ import annotations

import math
import tempfile
from typing import Any, Callable

from fmpy.fmi1 import FMICallException

from ..cosim.fmu import FMU, Instance

__all__ = ["BAD_VALUES", "status_of", "DISCARD", "ERROR", "FATAL", "LOGGING", "OK", "PRINTED", "STATES", "WARNING",
           "Case", "Printed", "experiment", "instantiate", "reals", "to_state"]

OK, WARNING, DISCARD, ERROR, FATAL = range(5)
BAD_VALUES = (math.nan, math.inf, -math.inf, 1e308, -1e308)
STATES = ("instantiated", "initialization", "stepping", "terminated")


class Printed:
    """What the FMU's binary writes to the process's standard output (fd 1): some binaries
    (FMPy's container) report errors there instead of through the FMI logger."""

    def __init__(self) -> None:
        self.file = tempfile.TemporaryFile()
        self.seen = 0

    def new(self) -> bytes:
        self.file.seek(self.seen)
        data = self.file.read()
        self.seen += len(data)
        return data


PRINTED = Printed()
#: whether instances are created with logging on (the logger must then never crash the host)
LOGGING = [True]


def instantiate(fmu: FMU, name: str) -> Instance:
    return fmu.instantiate(name, logging=LOGGING[0])


class Case:
    """Statuses and problems of one case; ``call`` runs one FMI call and records its status."""

    def __init__(self, name: str, inst: Instance, ours: bool) -> None:
        self.name, self.inst, self.ours = name, inst, ours
        self.statuses: list[int] = []
        self.problems: list[str] = []

    def call(self, fname: str, *args: Any) -> Any:
        before = len(self.inst.messages)
        PRINTED.new()
        try:
            out = getattr(self.inst.slave, fname)(*args)
            self.statuses.append(OK)
            return out
        except FMICallException as e:
            self.statuses.append(int(e.status))
            if e.status == FATAL:
                self.problems.append(f"{fname} returned fmi2Fatal")
            elif not self.inst.messages[before:] and not PRINTED.new() and self.inst.logging:
                self.problems.append(f"{fname} returned status {e.status} without a log message")
            return None

    def logged(self, since: int, *fragments: str) -> None:
        """Require (for our FMUs, logging on) an error/discard message naming a fragment."""
        if not self.ours or not self.inst.logging:
            return
        texts = [m.message for m in self.inst.messages[since:] if m.status >= DISCARD]
        if not any(f in t for t in texts for f in fragments):
            self.problems.append(f"no error message naming {' or '.join(fragments)} "
                                 f"(got {texts[-2:]})")

    def result(self) -> dict[str, Any]:
        return {"case": self.name, "statuses": sorted(set(self.statuses)),
                "problems": self.problems}


def status_of(call: Callable[[], Any]) -> int:
    """The FMI status of ``call()``: 0 (OK) if it returns, else the status it raised."""
    try:
        call()
    except FMICallException as e:
        return int(e.status)
    return 0


def experiment(fmu: FMU) -> tuple[float, float]:
    de = fmu.model_description.defaultExperiment
    stop = float(de.stopTime) if de is not None and de.stopTime is not None else 1.0
    step = float(de.stepSize) if de is not None and de.stepSize is not None else stop / 100
    return stop, step


def to_state(c: Case, state: str) -> None:
    """Bring a fresh instance into ``state`` with legal calls."""
    if state == "instantiated":
        return
    c.call("setupExperiment", None, 0.0)
    c.call("enterInitializationMode")
    if state == "initialization":
        return
    c.call("exitInitializationMode")
    if state == "terminated":
        c.call("terminate")


def reals(fmu: FMU, *causalities: str) -> list[Any]:
    return [v for v in fmu.model_description.modelVariables
            if v.type == "Real" and v.causality in causalities]
