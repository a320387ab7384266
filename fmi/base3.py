"""The FMI 3.0 side of :class:`dronefly.fmi.SlaveBase`, for pythonfmu3's C wrapper.

:func:`fmi3_class` turns any FMU class of the project into its FMI 3.0 Co-Simulation
slave: :class:`Fmi3Side` first in the MRO, the model class (and with it the whole slave
base: storage, lifecycle, states, error containment) behind it. Nothing of a model is
written twice; the FMI 3.0 variables are the scalar table regrouped by
:mod:`.table3` (``time``, 2-D arrays).

What pythonfmu3 0.3.4's wrapper (``PySlaveInstance.cpp``, ``fmi_functions.cpp``) asks of
the class and how this side answers:

- ``fmi3DoStep``: the returned object's ``status`` is the call's status. A step refused
  for an illegal call (wrong state, a value that may not be set) is fmi3Error; one refused
  for a bad value (non-finite input, parameter out of range, state overflow) fmi3Discard.
- fmi3Set*/fmi3Get*/fmi3SetFMUState: every Python exception is fmi3Fatal and the wrapper
  has no other status, so these never raise: an illegal argument is logged at once with
  status fmi3Error (the call still returns fmi3OK) and the next fmi3DoStep returns
  fmi3Error naming it, as the FMI 2.0 side does.
- ``fmi3EnterInitializationMode`` drops startTime, stopTime and the tolerance (they never
  reach Python): the first fmi3DoStep's currentCommunicationPoint is taken as the start, and
  steps past the stop time are not refused.
- log messages need a ``debug`` attribute (pythonfmu 0.7.0's LogMsg has none) and are not
  printf formats;
- its binary releases its interpreter guard twice at process exit, as pythonfmu's does: the
  guard is released from an exit handler, as for FMI 2.0.

Shipped inside every FMI 3.0 FMU; imports only the standard library and its siblings.
"""

from __future__ import annotations

import ctypes
import math
from typing import Any, ClassVar

from pythonfmu.enums import Fmi2Status

from .calls import do_step_status
from .host import binary_folder3, finalize_at_exit
from .table3 import Var3, fmi3_table
from .access import set_rows

__all__ = ["Fmi3Side", "fmi3_class"]



class _LogMsg:
    """A message as pythonfmu3's wrapper reads it."""

    __slots__ = ("status", "category", "msg", "debug")

    def __init__(self, status: int, category: str, msg: str, debug: bool) -> None:
        self.status, self.category, self.msg, self.debug = status, category, msg, debug


class _StepResult:
    """What fmi3DoStep returns: its status; never terminateSimulation."""

    __slots__ = ("status", "terminateSimulation")

    def __init__(self, status: int) -> None:
        self.status = status
        self.terminateSimulation = False


_RESULTS = {s: _StepResult(s) for s in (0, 1, 2, 3)}


class Fmi3Side:
    """FMI 3.0 value access, doStep and logging over a :class:`SlaveBase` model class."""

    FMI: ClassVar[str] = "fmi3"
    FMI_TEXT: ClassVar[str] = "FMI 3.0"
    TYPE_NAMES: ClassVar[dict[str, str]] = {"Real": "Float64", "Boolean": "Boolean",
                                            "Integer": "Int32", "String": "String"}
    STATE_API: ClassVar[str] = "FMUState"
    ILLEGAL_STATUS: ClassVar[Fmi2Status] = Fmi2Status.error
    PRINTF_LOGGER: ClassVar[bool] = False
    GENERATION_TOOL: ClassVar[str] = "dronefly-fmu (pythonfmu3 0.3.4 wrapper)"
    #: the FMI 3.0 variables (index = value reference) and, per value reference, the scalar
    #: row of a Float64 / Boolean scalar (None otherwise): set by :func:`fmi3_class`
    TABLE3: ClassVar[tuple[Var3, ...]]
    _FLOAT_ROW: ClassVar[tuple[int | None, ...]]

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self._t0_known = False
        # pythonfmu3's binary has pythonfmu's double release of its interpreter guard at exit
        # (:func:`.host.finalize_at_exit`; "corrupted double-linked list" in about 1 of 10
        # Ecos runs of build/fmi3/DroneFlyHover.ssp), but lives in the FMI 3.0 platform folder
        # (binaries/x86_64-linux here): the folder of the library actually loaded
        finalize_at_exit(self.resources, self.MODEL_NAME,
                         binary_folder3(self.resources, self.MODEL_NAME))

    # -- logging --------------------------------------------------------------
    def log(self, msg: str, status: Any = Fmi2Status.ok, category: str | None = None,
            debug: bool = False) -> None:
        if category is None:
            category = f"logStatus{Fmi2Status(status).name.capitalize()}"
            if category not in self.log_categories:
                category = "logAll"
        self.log_queue.append(_LogMsg(int(status), category, msg, debug))

    # -- doStep ---------------------------------------------------------------
    def do_step(self, current_time: float, step_size: float) -> _StepResult:
        if not self._t0_known and self._mode == "stepping" and math.isfinite(current_time):
            self._time = float(current_time)  # pythonfmu3 never passes the start time
            self._t0_known = True
        return _RESULTS[do_step_status(self, current_time, step_size)]

    def _extra_state(self) -> dict[str, Any]:
        return {"model": super()._extra_state(), "t0_known": self._t0_known}

    def _restore_extra_state(self, state: dict[str, Any]) -> None:
        super()._restore_extra_state(state["model"])
        self._t0_known = bool(state["t0_known"])

    # -- values ---------------------------------------------------------------
    def get_float64(self, vrs: list[int]) -> list[float]:
        try:  # the hot path: scalars by a table lookup, anything else by _read3
            if self._stale:
                self._update_if_stale()
            if self._mode == "instantiated" or min(vrs) < 0:
                raise IndexError
            r, rows = self._real, self._FLOAT_ROW
            return [r[rows[v]] for v in vrs]  # None (array, time, Boolean) raises TypeError
        except BaseException:
            return self._read3(vrs, "Real", float, math.nan)

    def get_boolean(self, vrs: list[int]) -> list[bool]:
        return self._read3(vrs, "Boolean", bool, False)

    def set_float64(self, vrs: list[int], values: list[float]) -> None:
        self._write3(vrs, values, "Real")

    def set_boolean(self, vrs: list[int], values: list[bool]) -> None:
        self._write3(vrs, values, "Boolean")

    def get_int32(self, vrs: list[int]) -> list[int]:
        return self._read3(vrs, "Integer", int, 0)

    def get_int64(self, vrs: list[int]) -> list[int]:
        return self._read3(vrs, "Int64", int, 0)

    def get_uint64(self, vrs: list[int]) -> list[Any]:
        return [ctypes.c_uint64(0) for _ in self._read3(vrs, "UInt64", int, 0)]

    def get_string(self, vrs: list[int]) -> list[str]:
        return self._read3(vrs, "String", str, "")

    def set_int32(self, vrs: list[int], values: list[int]) -> None:
        self._write3(vrs, values, "Integer")

    def set_int64(self, vrs: list[int], values: list[int]) -> None:
        self._write3(vrs, values, "Int64")

    def set_uint64(self, vrs: list[int], values: list[int]) -> None:
        self._write3(vrs, values, "UInt64")

    def set_string(self, vrs: list[int], values: list[str]) -> None:
        self._write3(vrs, values, "String")

    def _kind3(self, vr: int) -> tuple[str, Var3 | None]:
        """The FMI 3.0 type of a value reference ("" if there is no such variable)."""
        table = self.TABLE3
        if not 0 <= vr < len(table):
            return "", None
        e = table[vr]
        return ("Real" if not e.indices else e.var.type), e

    def _type_name(self, kind: str) -> str:
        return self.TYPE_NAMES.get(kind, kind)

    def _read3(self, vrs: list[int], kind: str, convert: Any, fallback: Any) -> list[Any]:
        """Values of ``vrs`` (arrays row-major); wrong ones logged, answered with ``fallback``."""
        call = f"fmi3Get{self._type_name(kind)}"
        try:
            if self._mode == "instantiated":
                self._in_state("Get", call)
            if self._stale:
                self._update_if_stale()
            out: list[Any] = []
            r = self._real
            for vr in vrs:
                have, e = self._kind3(vr)
                if e is None or have != kind:
                    what = (f"valueReference {vr & 0xFFFFFFFF}" if e is None
                            else f"{e.name} (a {self._type_name(have)} variable)")
                    self._report(f"{call} of {what}: not a {self._type_name(kind)} variable "
                                 "of this FMU", Fmi2Status.error)
                    out.append(fallback)
                elif not e.indices:
                    out.append(float(self._time))
                else:
                    out.extend(convert(r[i]) for i in e.indices)
            return out
        except BaseException as e:  # a getter cannot fail: log, answer the fallback
            self._report(f"{call} failed: {e!r}", Fmi2Status.error)
            return [fallback for _ in vrs]

    def _write3(self, vrs: list[int], values: list[Any], kind: str) -> None:
        """Set ``vrs`` from ``values`` (arrays take their size in values, row-major)."""
        call = f"fmi3Set{self._type_name(kind)}"
        try:
            rows: list[int] = []
            vals: list[Any] = []
            at = 0
            for vr in vrs:
                have, e = self._kind3(vr)
                size = len(e.indices) if e is not None and e.indices else 1
                chunk = list(values[at:at + size])
                at += size
                why = ("no such variable" if e is None
                       else "the independent variable cannot be set" if not e.indices
                       else f"is a {self._type_name(have)} variable, not {self._type_name(kind)}"
                       if have != kind
                       else f"{size} values needed, {len(chunk)} given" if len(chunk) != size
                       else None)
                if why is None:
                    rows.extend(e.indices)  # type: ignore[union-attr]
                    vals.extend(chunk)
                    continue
                name = e.name if e is not None else f"valueReference {vr & 0xFFFFFFFF}"
                msg = f"{call}: {name} = {chunk[0] if len(chunk) == 1 else chunk!r} rejected: {why}"
                self._pending.append(msg)
                self._report(msg, Fmi2Status.error)
            if rows or vals:
                set_rows(self, rows, vals, kind)
        except BaseException as e:  # never let an exception reach the wrapper
            msg = f"{call} failed: {e!r}"
            self._pending.append(msg)
            self._report(msg, Fmi2Status.error)


def fmi3_class(model: type) -> type:
    """The FMI 3.0 slave class of a :class:`~dronefly.fmi.SlaveBase` subclass (same name)."""
    table = fmi3_table(model.VARIABLES)
    rows = tuple(e.indices[0] if not e.dims and e.indices and e.var.type == "Real" else None
                 for e in table)
    return type(model.__name__, (Fmi3Side, model), {
        "__module__": model.__module__, "__qualname__": model.__qualname__,
        "__doc__": f"FMI 3.0 Co-Simulation slave of {model.__name__}: {model.__doc__}",
        "TABLE3": table, "_FLOAT_ROW": rows,
    })
