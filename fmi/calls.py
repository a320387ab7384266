"""The co-simulation lifecycle of :class:`dronefly.fmi.SlaveBase`, for both FMI versions.

Functions of the slave (``self``), bound as methods in ``SlaveBase``: the call-sequence
table, experiment setup, initialization, termination and the communication step. The FMI
version only changes names and one status: the slave class says which through
``FMI`` (``"fmi2"`` or ``"fmi3"``: the prefix of the call names in messages), ``FMI_TEXT``
(``"FMI 2.0"``) and ``ILLEGAL_STATUS``, the status of a step refused for an illegal call or an
illegal argument (a step size that is not > 0, a communication point that is not finite or
does not continue, a step past the stop time): FMI 3.0 2.2.4 asks for fmi3Error, which
pythonfmu3 can return; pythonfmu 0.7.0 can only return fmi2Discard from doStep. Either way
the instance is unchanged. A step refused for a bad value (a NaN input) is always Discard.

Shipped inside every FMU with the rest of :mod:`dronefly.fmi`; imports only the standard library
and pythonfmu.
"""

from __future__ import annotations

import math
from typing import Any

from pythonfmu.enums import Fmi2Status

__all__ = ["ALLOWED", "MODES", "do_step_status", "enter", "exit_initialization_mode",
           "in_state", "refuse", "setup_experiment", "step_refused"]

MODES = ("instantiated", "initialization", "stepping", "terminated")
#: co-simulation call-sequence table (FMI 2.0 section 4.2.4, FMI 3.0 section 4.2): the states
#: in which each call is allowed ("stepping" = stepComplete / Step Mode). Calls not listed are
#: allowed in every state.
ALLOWED = {
    "SetupExperiment": ("instantiated",),
    "EnterInitializationMode": ("instantiated",),
    "ExitInitializationMode": ("initialization",),
    "Terminate": ("stepping",),
    "DoStep": ("stepping",),
    "Get": ("initialization", "stepping", "terminated"),
}
_OK = int(Fmi2Status.ok)


def in_state(self: Any, call: str, name: str | None = None) -> bool:
    """Whether ``call`` (a key of :data:`ALLOWED`) is allowed now; if not, log an error
    (naming the call as ``name``) and keep it for doStep."""
    if self._mode in ALLOWED[call]:
        return True
    msg = (f"{name or self.FMI + call} is not allowed in state {self._mode!r} ({self.FMI_TEXT} "
           f"co-simulation call sequence: only in {', '.join(ALLOWED[call])}); ignored")
    if call != "DoStep" and call != "Get":
        self._pending.append(msg)
    self._report(msg, Fmi2Status.error)
    return False


def refuse(self: Any, msg: str, status: Any = Fmi2Status.discard) -> int:
    """Log why a step is refused; the status it is refused with."""
    self._report(msg, status)
    return int(status)


def setup_experiment(self: Any, start_time: float, stop_time: float | None = None,
                     tolerance: float | None = None) -> None:
    try:
        if not self._in_state("SetupExperiment"):
            return
        bad = [f"{name} = {value!r}" for name, value in (("startTime", start_time),
                                                         ("stopTime", stop_time))
               if value is not None and not math.isfinite(value)]
        if stop_time is not None and not bad and stop_time < start_time:
            bad.append(f"stopTime = {stop_time!r} < startTime = {start_time!r}")
        if bad:
            msg = f"{self.FMI}SetupExperiment: {', '.join(bad)} refused; times must be finite"
            self._pending.append(msg)
            self._report(msg, Fmi2Status.error)
            return
        self._time = float(start_time)
        self._stop_time = None if stop_time is None else float(stop_time)
    except BaseException as e:  # never let an exception reach the wrapper
        self._report(f"{self.FMI}SetupExperiment failed: {e!r}", Fmi2Status.error)


def enter(self: Any, call: str, mode: str) -> None:
    """Go to ``mode`` if ``call`` is allowed now (else logged and ignored)."""
    try:
        if self._in_state(call):
            self._mode = mode
    except BaseException as e:  # never let an exception reach the wrapper
        self._pending.append(f"{self.FMI}{call} failed: {e!r}")


def exit_initialization_mode(self: Any) -> None:
    if not self._in_state("ExitInitializationMode"):
        return
    self._mode = "stepping"
    try:
        self._initialize()
        self._initialized = True
        self._dirty = False
    except BaseException as e:  # retried, and reported, by every doStep until fixed
        self._report(f"initialization: {e}", Fmi2Status.error)


def do_step_status(self: Any, current_time: float, step_size: float) -> int:
    """One communication step; the FMI status (0 OK, 2 Discard, 3 Error), refusals logged."""
    try:
        if self._mode != "stepping":
            return self._refuse(f"{self.FMI}DoStep is not allowed in state {self._mode!r} "
                                f"({self.FMI_TEXT} co-simulation call sequence: only after "
                                f"{self.FMI}ExitInitializationMode and before "
                                f"{self.FMI}Terminate)", self.ILLEGAL_STATUS)
        if self._pending:
            msg = "; ".join(self._pending)
            self._pending.clear()
            return self._refuse(f"step refused at t = {current_time!r} s: {msg}",
                                self.ILLEGAL_STATUS)
        end = current_time + step_size
        # x - x == 0 is false exactly for inf and nan (cheaper than math.isfinite here)
        if not (current_time - current_time == 0.0 and end - end == 0.0
                and step_size > 0.0):
            if not math.isfinite(current_time):
                return self._refuse(f"currentCommunicationPoint = {current_time!r} s must be "
                                    "finite", self.ILLEGAL_STATUS)
            return self._refuse(f"communicationStepSize = {step_size!r} s must be finite and "
                                f"> 0, with a finite end (from {current_time!r} s)",
                                self.ILLEGAL_STATUS)
        # float accumulation of the master's time: relative to the times, never to the step
        last, stop = self._time, self._stop_time
        if current_time != last or stop is not None:  # (else both checks pass)
            tol = 1e-9 * (abs(current_time) + abs(last)) + 1e-300
            if not (abs(current_time - last) <= tol):
                return self._refuse(
                    f"currentCommunicationPoint = {current_time!r} s does not continue "
                    f"from the last communication point {self._time!r} s", self.ILLEGAL_STATUS)
            if stop is not None and end > stop + tol:
                return self._refuse(f"a step of {step_size!r} s from {current_time!r} s goes "
                                    f"past stopTime = {stop!r} s ({self.FMI}SetupExperiment)",
                                    self.ILLEGAL_STATUS)
        if not self._initialized:
            self._initialize()
            self._initialized = True
            self._dirty = False
        elif self._dirty:
            self._refresh()
            self._dirty = False
        self._advance(current_time, step_size)
        self._time = end
        return _OK
    except BaseException as e:  # never let an exception reach the wrapper
        return step_refused(self, e, current_time)


def step_refused(self: Any, error: BaseException, current_time: float) -> int:
    """Log why the step from ``current_time`` raised ``error``; the status it is refused with
    (Discard). A ValueError names a bad value; anything else is an internal error."""
    try:
        if isinstance(error, ValueError):
            return self._refuse(f"step refused at t = {current_time!r} s: {error}")
        if isinstance(error, KeyboardInterrupt):  # Ctrl-C landed in this FMU's code
            return self._refuse(f"step from t = {current_time!r} s interrupted (SIGINT); "
                                "nothing changed")
        return self._refuse(f"internal error at t = {current_time!r} s: {error!r}")
    except BaseException:  # never let an exception reach the wrapper
        return int(Fmi2Status.discard)
