"""FMI 2.0 co-simulation slave base shared by the project's FMUs.

pythonfmu 0.7.0 provides the C wrapper and :class:`pythonfmu.Fmi2Slave`; this
module replaces the parts that the FMI 2.0 standard and our users need and
pythonfmu does not give: a declarative variable table with units, display
units and ModelStructure dependencies; a model description that passes
``fmpy validate`` (generated from it by :mod:`dronefly.modeldescription`, which
the FMUs do not ship); value storage by value reference; full-state get/set and
serialisation (:mod:`.state`); the FMI 2.0 co-simulation state machine;
and error containment (no Python exception ever reaches the wrapper, where it
would become fmi2Fatal).

pythonfmu 0.7.0 lets a Python slave return a non-OK status only from doStep
(False = fmi2Discard); every other call returns fmi2OK unless an exception
escapes, which is fmi2Fatal and corrupts the instance. So a call that the
standard answers with fmi2Error (a call in the wrong state, an unknown value
reference, a value that may not be set) is logged at once with status
fmi2Error, changes nothing, and the next doStep is refused with the same
message (the standard's error state allows no doStep). ``docs/fmi-limits.md``
lists these calls.

Every logged message passes through :meth:`SlaveBase._report`, which escapes
``%`` (the importer's logger treats the message as a printf format) and any
character that is not UTF-8.

Each FMU ships its own copy of this module inside a content-addressed package,
so it must import nothing from the project but relative siblings.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar, Iterable, Sequence

from pythonfmu import Fmi2Slave
from pythonfmu.enums import Fmi2Status

from .host import finalize_at_exit, inside_fmpy_container, leave_sys_path
from .state import (get_fmu_state, set_fmu_state, snapshot, state_from_bytes,
                    state_to_bytes)
from .values import (get_boolean, get_integer, get_real, get_string, set_boolean, set_integer,
                     set_real, set_string)
from .vars import UNITS, Var

__all__ = ["UNITS", "SlaveBase", "Var"]

_MODES = ("instantiated", "initialization", "stepping", "terminated")
#: FMI 2.0 CS call-sequence table (section 4.2.4): the states in which each call is allowed
#: ("stepping" = stepComplete). Calls not listed are allowed in every state.
_ALLOWED = {
    "fmi2SetupExperiment": ("instantiated",),
    "fmi2EnterInitializationMode": ("instantiated",),
    "fmi2ExitInitializationMode": ("initialization",),
    "fmi2Terminate": ("stepping",),
    "fmi2DoStep": ("stepping",),
    "fmi2Get": ("initialization", "stepping", "terminated"),
}


class SlaveBase(Fmi2Slave):
    """Variable storage, model description and error containment.

    Subclasses define ``MODEL_NAME``, ``MODEL_DESCRIPTION``, ``VARIABLES``,
    ``DEFAULT_EXPERIMENT`` (start, stop, step in s) and implement
    :meth:`_refresh` (validate and rebuild after parameters or inputs
    changed; raise ``ValueError`` naming the bad value) and :meth:`_advance`
    (one communication step; validates the inputs, which change every step).
    An FMU with direct feedthrough also implements :meth:`_update_outputs`,
    which fmi2GetReal/fmi2GetBoolean call after any value was set.
    Boolean variables are stored in the same value-reference table.
    """

    MODEL_NAME: ClassVar[str]
    MODEL_DESCRIPTION: ClassVar[str]
    VARIABLES: ClassVar[tuple[Var, ...]]
    DEFAULT_EXPERIMENT: ClassVar[tuple[float, float, float]]
    GENERATION_TOOL: ClassVar[str] = "dronefly-fmu (pythonfmu 0.7.0 wrapper)"
    UNITS: ClassVar[dict[str, tuple[dict[str, int], dict[str, float]]]] = UNITS
    #: outputs depend on inputs within a time instant (Modelica block semantics)
    DIRECT_FEEDTHROUGH: ClassVar[bool] = False
    MODES: ClassVar[tuple[str, ...]] = _MODES
    log_categories = {
        "logStatusWarning": "Messages with status fmi2Warning.",
        "logStatusDiscard": "Messages with status fmi2Discard (refused steps).",
        "logStatusError": "Messages with status fmi2Error (rejected values).",
    }

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.modelName = self.MODEL_NAME
        vars_ = self.VARIABLES
        self._vr = {v.name: i for i, v in enumerate(vars_)}
        self._real: list[Any] = [v.start if v.start is not None else 0.0 for v in vars_]
        self._mode = "instantiated"
        self._time = 0.0
        self._stop_time: float | None = None
        self._pending: list[str] = []
        self._dirty = True
        self._stale = True  # a value was set since the last _update_outputs
        self._initialized = False
        self._types = tuple(v.type for v in vars_)
        self._settable = {
            (mode, kind): frozenset(i for i, v in enumerate(vars_)
                                    if v.type == kind and self._may_set(v, mode))
            for mode in _MODES for kind in ("Real", "Boolean")
        }
        self._param_vrs = frozenset(i for i, v in enumerate(vars_) if v.causality == "parameter")
        self._n_vars = len(vars_)
        self._fmu_id = self._class_fmu_id()
        # The wrapper puts the resources folder at the front of sys.path on every
        # instantiation; the FMU's package is imported by then, so take it out again.
        leave_sys_path(self.resources)
        self._mute = inside_fmpy_container(self.resources)
        finalize_at_exit(self.resources, self.MODEL_NAME)

    # -- subclass hooks ---------------------------------------------------
    def _refresh(self) -> None:  # pragma: no cover - abstract
        raise NotImplementedError

    def _advance(self, t: float, h: float) -> None:  # pragma: no cover - abstract
        raise NotImplementedError

    def _initialize(self) -> None:
        """Compute initial unknowns on leaving initialization mode."""
        self._refresh()

    def _update_outputs(self) -> None:
        """Recompute direct-feedthrough outputs from the current inputs and parameters.

        Called lazily by fmi2GetReal/fmi2GetBoolean when a value was set since
        the last call. Raise ``ValueError`` naming the bad value to keep the
        last outputs; the message is logged with status fmi2Error. The default
        does nothing: outputs change only in doStep.
        """

    def _extra_state(self) -> dict[str, Any]:
        return {}

    def _restore_extra_state(self, state: dict[str, Any]) -> None:
        pass

    # -- helpers ------------------------------------------------------------
    @staticmethod
    def _may_set(v: Var, mode: str) -> bool:
        if v.causality == "input":
            return mode != "terminated"
        if v.causality == "parameter":
            if v.variability == "tunable":
                return mode != "terminated"
            return mode in ("instantiated", "initialization")
        return False

    def _value(self, name: str) -> Any:
        return self._real[self._vr[name]]

    def _values(self, names: Iterable[str]) -> list[Any]:
        r, vr = self._real, self._vr
        return [r[vr[n]] for n in names]

    def _set_values(self, names: Iterable[str], values: Iterable[Any]) -> None:
        r, vr = self._real, self._vr
        for n, x in zip(names, values):
            r[vr[n]] = x

    def _report(self, msg: str, status: Fmi2Status) -> None:
        """Log ``msg``: ``%`` escaped for the printf-style logger, valid UTF-8 guaranteed."""
        if self._mute:
            return
        text = f"{self.instance_name}: {msg}".replace("%", "%%")
        self.log(text.encode("utf-8", "backslashreplace").decode("utf-8"), status)

    def _in_state(self, call: str, name: str | None = None) -> bool:
        """Whether ``call`` is allowed now; if not, log an error (naming the call as ``name``)
        and keep it for doStep."""
        if self._mode in _ALLOWED[call]:
            return True
        msg = (f"{name or call} is not allowed in state {self._mode!r} (FMI 2.0 co-simulation "
               f"call sequence: only in {', '.join(_ALLOWED[call])}); ignored")
        if call != "fmi2DoStep" and call != "fmi2Get":
            self._pending.append(msg)
        self._report(msg, Fmi2Status.error)
        return False

    def _refuse(self, msg: str) -> bool:
        self._report(msg, Fmi2Status.discard)
        return False

    def _update_if_stale(self) -> None:
        self._stale = False
        try:
            self._update_outputs()
        except BaseException as e:  # getters cannot fail: keep the outputs, say why
            self._report(f"outputs keep their last valid values: {e}", Fmi2Status.error)

    @staticmethod
    def _check_finite(names: Sequence[str], values: Sequence[float]) -> None:
        for n, x in zip(names, values):
            if not math.isfinite(x):
                raise ValueError(f"{n} = {x!r} is not finite")

    # -- FMI calls ----------------------------------------------------------
    def setup_experiment(self, start_time: float, stop_time: float | None = None,
                         tolerance: float | None = None) -> None:
        try:
            if not self._in_state("fmi2SetupExperiment"):
                return
            bad = [f"{name} = {value!r}" for name, value in (("startTime", start_time),
                                                             ("stopTime", stop_time))
                   if value is not None and not math.isfinite(value)]
            if stop_time is not None and not bad and stop_time < start_time:
                bad.append(f"stopTime = {stop_time!r} < startTime = {start_time!r}")
            if bad:
                msg = f"fmi2SetupExperiment: {', '.join(bad)} refused; times must be finite"
                self._pending.append(msg)
                self._report(msg, Fmi2Status.error)
                return
            self._time = float(start_time)
            self._stop_time = None if stop_time is None else float(stop_time)
        except BaseException as e:  # never let an exception reach the wrapper
            self._report(f"fmi2SetupExperiment failed: {e!r}", Fmi2Status.error)

    def _enter(self, call: str, mode: str) -> None:
        """Go to ``mode`` if ``call`` is allowed now (else logged and ignored)."""
        try:
            if self._in_state(call):
                self._mode = mode
        except BaseException as e:  # never let an exception reach the wrapper
            self._pending.append(f"{call} failed: {e!r}")

    def enter_initialization_mode(self) -> None:
        self._enter("fmi2EnterInitializationMode", "initialization")

    def exit_initialization_mode(self) -> None:
        if not self._in_state("fmi2ExitInitializationMode"):
            return
        self._mode = "stepping"
        try:
            self._initialize()
            self._initialized = True
            self._dirty = False
        except BaseException as e:  # retried, and reported, by every doStep until fixed
            self._report(f"initialization: {e}", Fmi2Status.error)

    def terminate(self) -> None:
        self._enter("fmi2Terminate", "terminated")

    def do_step(self, current_time: float, step_size: float) -> bool:
        try:
            if self._mode != "stepping":
                return self._refuse(f"fmi2DoStep is not allowed in state {self._mode!r} (FMI 2.0 "
                                    "co-simulation call sequence: only after "
                                    "fmi2ExitInitializationMode and before fmi2Terminate)")
            if self._pending:
                msg = "; ".join(self._pending)
                self._pending.clear()
                return self._refuse(f"step refused at t = {current_time!r} s: {msg}")
            end = current_time + step_size
            # x - x == 0 is false exactly for inf and nan (cheaper than math.isfinite here)
            if not (current_time - current_time == 0.0 and end - end == 0.0
                    and step_size > 0.0):
                if not math.isfinite(current_time):
                    return self._refuse(f"currentCommunicationPoint = {current_time!r} s must be "
                                        "finite")
                return self._refuse(f"communicationStepSize = {step_size!r} s must be finite and "
                                    f"> 0, with a finite end (from {current_time!r} s)")
            # float accumulation of the master's time: relative to the times, never to the step
            last = self._time
            tol = 1e-9 * (abs(current_time) + abs(last)) + 1e-300
            if not (abs(current_time - last) <= tol):
                return self._refuse(
                    f"currentCommunicationPoint = {current_time!r} s does not continue "
                    f"from the last communication point {self._time!r} s")
            stop = self._stop_time
            if stop is not None and end > stop + tol:
                return self._refuse(f"a step of {step_size!r} s from {current_time!r} s goes "
                                    f"past stopTime = {stop!r} s (fmi2SetupExperiment)")
            if not self._initialized:
                self._initialize()
                self._initialized = True
                self._dirty = False
            elif self._dirty:
                self._refresh()
                self._dirty = False
            self._advance(current_time, step_size)
            self._time = end
            return True
        except ValueError as e:
            return self._refuse(f"step refused at t = {current_time!r} s: {e}")
        except KeyboardInterrupt:  # Ctrl-C landed in this FMU's code: refuse, never Fatal
            return self._refuse(f"step from t = {current_time!r} s interrupted (SIGINT); "
                                "nothing changed")
        except BaseException as e:  # never let an exception reach the wrapper
            return self._refuse(f"internal error at t = {current_time!r} s: {e!r}")

    # value access and FMU state: functions of .values and .state, bound
    # here as methods (mixin classes would lengthen the MRO, and pythonfmu's findClass leaks
    # memory per MRO entry on every instantiation)
    get_real = get_real
    get_boolean = get_boolean
    get_integer = get_integer
    get_string = get_string
    set_real = set_real
    set_boolean = set_boolean
    set_integer = set_integer
    set_string = set_string
    _get_fmu_state = get_fmu_state
    _set_fmu_state = set_fmu_state
    _snapshot = snapshot

    @classmethod
    def _class_fmu_id(cls) -> str:
        """Model name and content-addressed package: which FMU and build a state belongs to."""
        fmu_id = cls.__dict__.get("_FMU_ID")
        if fmu_id is None:  # one string per class, shared by all its instances and states
            fmu_id = f"{cls.MODEL_NAME}@{cls.__module__.split('.')[0]}"
            cls._FMU_ID = fmu_id
        return fmu_id

    @classmethod
    def _fmu_state_to_bytes(cls, state: Any) -> bytes:
        return state_to_bytes(state, cls._class_fmu_id())

    @classmethod
    def _fmu_state_from_bytes(cls, data: bytes) -> Any:
        return state_from_bytes(data, cls._class_fmu_id())
