"""Model Exchange FMUs stepped through the Co-Simulation calls the harness makes.

:class:`MEStepper` wraps fmpy's ``FMU2Model`` (FMI 2.0) or an :class:`.fmu3.FMU3Adapter` over
``FMU3Model`` (FMI 3.0) and answers ``setupExperiment``, ``enterInitializationMode``,
``exitInitializationMode``, ``doStep``, ``reset`` and the FMU-state calls as a Co-Simulation
slave would, so that code written for Co-Simulation drives the Model Exchange interface through
its own state machine (FMI 2.0 3.2.3, FMI 3.0 3.2):

- ``exitInitializationMode`` runs the event iteration (fmi2NewDiscreteStates /
  fmi3UpdateDiscreteStates until no new iteration is needed, at most
  :data:`MAX_EVENT_ITERATIONS`) and enters Continuous-Time Mode;
- ``doStep(t, h)`` integrates from ``t`` to ``t + h`` with FMPy's CVODE solver. CVODE
  continues across communication points; it is restarted at ``t`` after initialization, after
  an event, where the FMU state was saved or restored (``getFMUstate``, ``setFMUstate``,
  ``reset``) and where ``t`` is not where the last step ended: so a run is a function of the
  FMU's state where it (re)started, and a restored FMU state continues bit for bit as the
  original did after it was saved. It stops at time events (nextEventTime), state events (a root of the
  event indicators) and step events (fmi2CompletedIntegratorStep), each handled in Event Mode
  with the event iteration; it returns FMI 3.0's ``(eventHandlingNeeded, terminateSimulation,
  earlyReturn, lastSuccessfulTime)``, terminateSimulation when the FMU asked to end the run;
- ``enter_event_mode`` and ``leave_event_mode`` take the instance into Event Mode between
  steps and back (the event iteration on the way out), for a caller that sets discrete inputs;
- an FMU state saved with ``getFMUstate`` keeps the next event time with the FMU's own state
  (the serialized form: 10 bytes of it before the FMU's).

Values, states and the rest pass through to the wrapped object.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass
from typing import Any

from fmpy.sundials import CVodeSolver

from ...core.errors import DroneflyError

__all__ = ["MAX_EVENT_ITERATIONS", "EventIterationError", "MEStepper"]

#: event iterations at one time instant after which the iteration is taken not to terminate
MAX_EVENT_ITERATIONS = 1000
#: CVODE's relative tolerance (FMPy's default for Model Exchange)
_RTOL = 1e-5
_HEADER = struct.Struct("<d??")  # the next event time, whether defined, terminated


#: events within one communication step after which the FMU is taken to chatter
_MAX_EVENTS_PER_STEP = 10000


def _reached(t: float, end: float) -> bool:
    """Whether time ``t`` is at ``end`` (or past it), up to round-off of the step sums."""
    return t >= end or math.isclose(t, end, rel_tol=1e-12, abs_tol=1e-300)


class EventIterationError(DroneflyError):
    """The event iteration of a Model Exchange FMU did not terminate."""


class _NoInput:
    """The solver's input hook: the host sets the inputs itself, between steps."""

    def apply(self, *args: Any, **kwargs: Any) -> None:
        return None


@dataclass
class _Saved:
    """An FMU state of the wrapped FMU with the stepper's event bookkeeping."""

    inner: Any
    next_event: float | None
    terminated: bool


class MEStepper:
    """A Model Exchange instance answering the Co-Simulation calls (see the module text).

    Parameters
    ----------
    raw : fmpy FMU2Model or FMU3Model
        The instantiated Model Exchange model (its event and continuous-state calls).
    values : Any
        What answers the value and FMU-state calls: ``raw`` itself (FMI 2.0) or the
        :class:`.fmu3.FMU3Adapter` around it (FMI 3.0).
    fmi_version : int
        2 or 3.
    nx, nz : int
        Continuous states and event indicators (None: asked of the FMU, FMI 3.0).
    needs_completed_integrator_step : bool
        The FMU's ``needsCompletedIntegratorStep`` (FMI 3.0: always called).
    """

    interface = "me"

    def __init__(self, raw: Any, values: Any, fmi_version: int, nx: int | None,
                 nz: int | None, needs_completed_integrator_step: bool = True) -> None:
        self._raw = raw
        self._values = values
        self._v = fmi_version
        self._nx, self._nz = nx, nz
        self._completed = needs_completed_integrator_step or fmi_version == 3
        self._update = raw.newDiscreteStates if fmi_version == 2 else raw.updateDiscreteStates
        self._solver: CVodeSolver | None = None
        self._fresh = True  # restart CVODE at the next step
        self._last_end: float | None = None
        self._next_event: float | None = None
        self.terminated = False
        self.iterations = 0  # of the last event iteration

    def __getattr__(self, name: str) -> Any:
        return getattr(self._values, name)

    # -- the state machine -------------------------------------------------------------------
    def setupExperiment(self, tolerance: float | None = None, startTime: float = 0.0,
                        stopTime: float | None = None) -> None:
        self._values.setupExperiment(tolerance=tolerance, startTime=startTime,
                                     stopTime=stopTime)

    def enterInitializationMode(self) -> None:
        self._values.enterInitializationMode()

    def exitInitializationMode(self) -> None:
        self._values.exitInitializationMode()
        self._fresh = True
        self._event_iteration()
        if not self.terminated:
            self._raw.enterContinuousTimeMode()

    def _event_iteration(self) -> None:
        self._next_event = None
        for k in range(1, MAX_EVENT_ITERATIONS + 1):
            needed, terminate, _, _, defined, t_next = self._update()[:6]
            if terminate:
                self.terminated = True
            if not needed or terminate:
                self.iterations = k
                self._next_event = float(t_next) if defined else None
                return
        raise EventIterationError(
            f"the event iteration did not terminate in {MAX_EVENT_ITERATIONS} iterations "
            f"(fmi{self._v}{'NewDiscreteStates' if self._v == 2 else 'UpdateDiscreteStates'} "
            "asked for another each time)")

    def enter_event_mode(self) -> None:
        """From Continuous-Time Mode into Event Mode (fmi2EnterEventMode / fmi3EnterEventMode),
        where inputs of any variability may be set and the unknowns read after them."""
        self._raw.enterEventMode()

    def leave_event_mode(self) -> None:
        """From Event Mode back to Continuous-Time Mode: the event iteration, then
        fmi2EnterContinuousTimeMode / fmi3EnterContinuousTimeMode unless the FMU asked to
        terminate; CVODE restarts at the next step."""
        self._event_iteration()
        self._fresh = True
        if not self.terminated:
            self._raw.enterContinuousTimeMode()

    def reset(self) -> Any:
        self._next_event, self.terminated, self._fresh = None, False, True
        return self._values.reset()

    def terminate(self) -> Any:
        return self._values.terminate()

    # -- integration -------------------------------------------------------------------------
    def _solver_at(self, t: float) -> CVodeSolver:
        raw = self._raw
        if self._solver is None:
            if self._nx is None:
                self._nx = raw.getNumberOfContinuousStates()
            if self._nz is None:
                self._nz = raw.getNumberOfEventIndicators()
            self._solver = CVodeSolver(
                nx=self._nx, nz=self._nz, get_x=raw.getContinuousStates,
                set_x=raw.setContinuousStates,
                get_dx=raw.getDerivatives if self._v == 2 else raw.getContinuousStateDerivatives,
                get_z=raw.getEventIndicators, get_nominals=raw.getNominalsOfContinuousStates,
                set_time=raw.setTime, input=_NoInput(), startTime=t, relativeTolerance=_RTOL)
        if self._fresh or self._last_end is None or not _reached(t, self._last_end) \
                or not _reached(self._last_end, t):
            self._solver.reset(t)  # a fresh start at t
            self._fresh = False
        return self._solver

    def doStep(self, currentCommunicationPoint: float, communicationStepSize: float,
               noSetFMUStatePriorToCurrentPoint: bool = True) -> tuple[bool, bool, bool, float]:
        t = float(currentCommunicationPoint)
        end = t + float(communicationStepSize)
        if self.terminated:
            return False, True, False, t
        raw = self._raw
        solver = self._solver_at(t)
        for _ in range(_MAX_EVENTS_PER_STEP):
            if _reached(t, end):
                self._last_end = end
                return False, False, False, end
            due = self._next_event
            if due is not None and (due <= t or _reached(t, due)):  # a time event now
                state_event, step_event, time_event = False, False, True
            else:
                stop = end if due is None or due > end else due
                state_event, _, t = solver.step(t, stop)
                raw.setTime(t)
                time_event = due is not None and _reached(t, due)
                step_event, terminate = (raw.completedIntegratorStep() if self._completed
                                         else (False, False))
                if terminate:
                    self.terminated = True
                    return False, True, False, t
            if state_event or time_event or step_event:
                raw.enterEventMode()
                self._event_iteration()
                if self.terminated:
                    return False, True, False, t
                raw.enterContinuousTimeMode()
                solver.reset(t)
        raise EventIterationError(f"more than {_MAX_EVENTS_PER_STEP} events in the step from "
                                  f"t = {currentCommunicationPoint!r} s to {end!r} s")

    # -- FMU state: the FMU's and the next event time ----------------------------------------
    def getFMUstate(self) -> _Saved:
        self._fresh = True  # the original continues from a restart too, as a restored one
        return _Saved(self._values.getFMUstate(), self._next_event, self.terminated)

    def setFMUstate(self, state: _Saved) -> None:
        self._values.setFMUstate(state.inner)
        self._next_event, self.terminated = state.next_event, state.terminated
        self._fresh = True

    def freeFMUstate(self, state: _Saved) -> None:
        self._values.freeFMUstate(state.inner)

    def serializeFMUstate(self, state: _Saved) -> bytes:
        head = _HEADER.pack(state.next_event if state.next_event is not None else 0.0,
                            state.next_event is not None, state.terminated)
        return head + bytes(self._values.serializeFMUstate(state.inner))

    def deSerializeFMUstate(self, data: bytes) -> _Saved:
        t_next, defined, terminated = _HEADER.unpack(data[:_HEADER.size])
        inner = self._values.deSerializeFMUstate(data[_HEADER.size:])
        return _Saved(inner, t_next if defined else None, terminated)
