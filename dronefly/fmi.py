"""FMI 2.0 co-simulation slave base shared by the project's FMUs.

pythonfmu 0.7.0 provides the C wrapper and :class:`pythonfmu.Fmi2Slave`; this
module replaces the parts that the FMI 2.0 standard and our users need and
pythonfmu does not give: a declarative variable table with units, display
units and ModelStructure dependencies; a model description that passes
``fmpy validate`` (generated from it by :mod:`dronefly.modeldescription`, which
the FMUs do not ship); value storage by value reference; full-state get/set and
serialisation; and error containment (no Python exception ever reaches the
wrapper, where it would become fmi2Fatal).

Each FMU ships its own copy of this module inside a content-addressed package,
so it must import nothing from the project but relative siblings.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import Any, ClassVar, Iterable, Sequence

from pythonfmu import Fmi2Slave
from pythonfmu.enums import Fmi2Status

__all__ = ["UNITS", "SlaveBase", "Var"]

_DEG = 180.0 / math.pi

#: unit name -> (base-unit exponents, {display unit: factor})
UNITS: dict[str, tuple[dict[str, int], dict[str, float]]] = {
    "1": ({}, {}),
    "s": ({"s": 1}, {}),
    "Hz": ({"s": -1}, {}),
    "m/s": ({"m": 1, "s": -1}, {}),
    "rad": ({"rad": 1}, {"deg": _DEG}),
    "rad/s": ({"rad": 1, "s": -1}, {"deg/s": _DEG}),
}

_MODES = ("instantiated", "initialization", "stepping", "terminated")


@dataclass(frozen=True)
class Var:
    """One scalar variable of an FMU's interface.

    ``dependencies`` is for outputs and calculated parameters: a tuple of the
    names of the knowns the value depends on (``()`` = none), or ``None`` for
    "all knowns" (the attribute is then omitted).
    """

    name: str
    causality: str
    variability: str
    description: str
    unit: str | None = "1"
    display_unit: str | None = None
    start: float | bool | None = None
    initial: str | None = None
    type: str = "Real"
    dependencies: tuple[str, ...] | None = None
    initial_dependencies: tuple[str, ...] | None = None


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
        self.log(f"{self.instance_name}: {msg}", status)

    def _refuse(self, msg: str) -> bool:
        self._report(msg, Fmi2Status.discard)
        return False

    def _update_if_stale(self) -> None:
        self._stale = False
        try:
            self._update_outputs()
        except Exception as e:  # getters cannot fail: keep the outputs, say why
            self._report(f"outputs keep their last valid values: {e}", Fmi2Status.error)

    def _reject(self, vr: int, value: Any, why: str) -> None:
        name = self.VARIABLES[vr].name if 0 <= vr < len(self.VARIABLES) else f"valueReference {vr}"
        msg = f"{name} = {value!r} rejected: {why}"
        self._pending.append(msg)
        self._report(msg, Fmi2Status.error)

    @staticmethod
    def _check_finite(names: Sequence[str], values: Sequence[float]) -> None:
        for n, x in zip(names, values):
            if not math.isfinite(x):
                raise ValueError(f"{n} = {x!r} is not finite")

    # -- FMI calls ----------------------------------------------------------
    def setup_experiment(self, start_time: float, stop_time: float | None = None,
                         tolerance: float | None = None) -> None:
        self._time = float(start_time)
        self._stop_time = stop_time

    def enter_initialization_mode(self) -> None:
        self._mode = "initialization"

    def exit_initialization_mode(self) -> None:
        self._mode = "stepping"
        try:
            self._initialize()
            self._initialized = True
            self._dirty = False
        except Exception as e:  # retried, and reported, by every doStep until fixed
            self._report(f"initialization: {e}", Fmi2Status.error)

    def terminate(self) -> None:
        self._mode = "terminated"

    def do_step(self, current_time: float, step_size: float) -> bool:
        try:
            if self._mode != "stepping":
                return self._refuse(f"doStep in mode {self._mode!r}: initialization not completed")
            if self._pending:
                msg = "; ".join(self._pending)
                self._pending.clear()
                return self._refuse(f"step refused at t = {current_time!r} s: {msg}")
            if not (math.isfinite(step_size) and step_size > 0.0):
                return self._refuse(f"communicationStepSize = {step_size!r} must be finite and > 0")
            tol = 1e-9 * max(abs(current_time), step_size)
            if not (abs(current_time - self._time) <= tol):
                return self._refuse(
                    f"currentCommunicationPoint = {current_time!r} s does not continue "
                    f"from the last communication point {self._time!r} s")
            stop = self._stop_time
            if stop is not None and current_time + step_size > stop + tol:
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
            self._time = current_time + step_size
            return True
        except ValueError as e:
            return self._refuse(f"step refused at t = {current_time!r} s: {e}")
        except Exception as e:  # never let an exception reach the wrapper
            return self._refuse(f"internal error at t = {current_time!r} s: {e!r}")

    def get_real(self, vrs: list[int]) -> list[float]:
        if self._stale:
            self._update_if_stale()
        r = self._real
        try:
            return [r[i] for i in vrs]  # the wrapper converts with PyFloat_AsDouble
        except Exception:
            self._bad_get(vrs, "Real")
            return [float(r[i]) if 0 <= i < len(r) else math.nan for i in vrs]

    def get_boolean(self, vrs: list[int]) -> list[bool]:
        if self._stale:
            self._update_if_stale()
        r, types = self._real, self._types
        if any(not 0 <= i < len(r) or types[i] != "Boolean" for i in vrs):
            self._bad_get(vrs, "Boolean")
        return [bool(r[i]) if 0 <= i < len(r) else False for i in vrs]

    def set_real(self, vrs: list[int], values: list[float]) -> None:
        self._set(vrs, values, "Real")

    def set_boolean(self, vrs: list[int], values: list[bool]) -> None:
        self._set(vrs, [bool(x) for x in values], "Boolean")

    def _set(self, vrs: list[int], values: list[Any], kind: str) -> None:
        try:
            ok = self._settable[(self._mode, kind)]
            r = self._real
            for i, x in zip(vrs, values):
                if i in ok:
                    r[i] = x
                else:
                    self._reject(i, x, self._why_not_settable(i, kind))
            # outputs follow sets only before initialization ends or with direct feedthrough
            if self.DIRECT_FEEDTHROUGH or not self._initialized:
                self._stale = True
            if not self._dirty and not self._param_vrs.isdisjoint(vrs):
                self._dirty = True
        except Exception as e:
            self._pending.append(f"set{kind} failed: {e!r}")

    def _why_not_settable(self, vr: int, kind: str) -> str:
        if not 0 <= vr < len(self._types):
            return "no such variable"
        if self._types[vr] != kind:
            return f"is a {self._types[vr]} variable, not {kind}"
        return f"not settable in mode {self._mode!r}"

    def _bad_get(self, vrs: list[int], kind: str) -> None:
        """Log reads of unknown or wrongly typed variables (a getter cannot fail)."""
        for i in vrs:
            if not (0 <= i < len(self._types)) or self._types[i] != kind:
                what = (f"valueReference {i}" if not 0 <= i < len(self._types)
                        else f"{self.VARIABLES[i].name} (a {self._types[i]} variable)")
                self._report(f"fmi2Get{kind} of {what}: not a {kind} variable of this FMU",
                             Fmi2Status.error)

    def get_integer(self, vrs: list[int]) -> list[int]:
        self._bad_get(vrs, "Integer")
        return [0 for _ in vrs]

    def get_string(self, vrs: list[int]) -> list[str]:
        self._bad_get(vrs, "String")
        return ["" for _ in vrs]

    def set_integer(self, vrs: list[int], values: list[int]) -> None:
        for i, x in zip(vrs, values):
            self._reject(i, x, "this FMU has no Integer variables")

    def set_string(self, vrs: list[int], values: list[str]) -> None:
        for i, x in zip(vrs, values):
            self._reject(i, x, "this FMU has no String variables")

    # -- FMU state ----------------------------------------------------------
    def _get_fmu_state(self) -> dict[str, Any]:
        return {
            "real": list(self._real),
            "mode": self._mode,
            "time": self._time,
            "stop_time": self._stop_time,
            "pending": list(self._pending),
            "dirty": self._dirty,
            "initialized": self._initialized,
            "extra": self._extra_state(),
        }

    def _set_fmu_state(self, state: dict[str, Any]) -> None:
        try:
            self._real = list(state["real"])
            self._mode = state["mode"]
            self._time = state["time"]
            self._stop_time = state["stop_time"]
            self._pending = list(state["pending"])
            self._restore_extra_state(state["extra"])
            self._initialized = state["initialized"]
            self._dirty = True  # the next doStep rebuilds from the restored values
            self._stale = True
        except Exception as e:
            self._dirty = True
            self._stale = True
            self._pending.append(f"fmi2SetFMUstate: {e!r}")

    @staticmethod
    def _fmu_state_to_bytes(state: dict[str, Any]) -> bytes:
        # repr-exact floats; NaN/Inf inputs survive as JSON extensions
        return json.dumps(state, separators=(",", ":")).encode("utf-8")

    @staticmethod
    def _fmu_state_from_bytes(data: bytes) -> dict[str, Any]:
        return json.loads(data.decode("utf-8"))
