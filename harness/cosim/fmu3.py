"""FMI 3.0 Co-Simulation FMUs in the harness: fmpy's ``FMU3Slave`` behind the FMI 2.0 API the
masters and the compliance checks call.

The harness speaks fmpy's FMU2Slave API (``setupExperiment``, ``getReal``, raw
``fmi2GetReal(component, vr, n, values)``, ...). For an FMI 3.0 FMU, :class:`FMU3Adapter`
answers the same calls through fmpy's FMU3Slave, and :func:`fmi2_view` gives the model
description as the harness reads it:

- Float64 and Float32 variables read as ``type == "Real"`` (each read and written with its own
  call, fmi3GetFloat64 or fmi3GetFloat32); the independent variable ``time`` is left
  out (the masters keep time themselves);
- each element of a 2-D array ``K`` appears as a scalar ``K[i,j]`` with a *virtual* value
  reference (from :data:`VIRTUAL`); ``getReal``/``setReal`` read the whole array and write it
  back with the element changed (FMI 3.0 sets an array as a whole). The raw calls
  (``fmi2GetReal``/``fmi2SetReal``, the masters' hot path) pass an array of Float64 scalars'
  value references straight through, and take the element-wise path for one that names an
  array element or a Float32 (an array output such as the Reference-FMU StateSpace's ``y``);
- ``setupExperiment`` keeps the start and stop time for ``fmi3EnterInitializationMode``.

Statuses are FMI 3.0's (same numbers as FMI 2.0); fmpy raises ``FMICallException`` above
Warning as for FMI 2.0.
"""

from __future__ import annotations

import copy
from ctypes import byref, c_bool, c_double
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Sequence

from fmpy import read_model_description

from ...core.errors import DroneflyError
from .prototypes import FMU3Model, FMU3Slave

__all__ = ["INT_TYPES", "VIRTUAL", "Element", "FMU3Adapter", "fmi2_view", "read_view"]

#: first virtual value reference of an array element (FMI 3.0 references stay below it)
VIRTUAL = 1 << 30

#: the FMU3Slave ``get``/``set`` suffix of each FMI 3.0 integer type (an Enumeration is Int64)
INT_TYPES = {**{t: t for t in ("Int8", "UInt8", "Int16", "UInt16", "Int32", "UInt32", "Int64",
                              "UInt64")}, "Enumeration": "Int64"}


@dataclass(frozen=True)
class Element:
    """Where ``K[i,j]`` lives: the array's value reference, its size and the row-major index."""

    array_vr: int
    size: int
    index: int


class _View:
    """An FMI 3.0 model description as the FMI 2.0 harness reads it (see the module text)."""

    def __init__(self, md: Any, variables: list[Any]) -> None:
        self._md = md
        self.modelVariables = variables

    def __getattr__(self, name: str) -> Any:
        return getattr(self._md, name)


def fmi2_view(md: Any) -> tuple[Any, dict[int, Element]]:
    """The harness's view of an fmpy FMI 3.0 model description and its array elements."""
    out: list[Any] = []
    elements: dict[int, Element] = {}
    for v in md.modelVariables:
        if v.causality == "independent":
            continue
        kind = "Real" if v.type in ("Float64", "Float32") else v.type
        shape = tuple(_extent(md, d) for d in (v.dimensions or ()))
        if not shape:
            w = copy.copy(v)
            w.type = kind
            out.append(w)
            continue
        starts = str(v.start).split() if v.start is not None else None
        size = 1
        for d in shape:
            size *= d
        for k in range(size):
            idx, rest = [], k
            for d in reversed(shape):
                idx.append(rest % d + 1)
                rest //= d
            w = copy.copy(v)
            w.name = f"{v.name}[{','.join(str(i) for i in reversed(idx))}]"
            w.type = kind
            w.dimensions = []
            w.start = starts[k] if starts else None
            w.valueReference = VIRTUAL + len(elements)
            elements[w.valueReference] = Element(v.valueReference, size, k)
            out.append(w)
    return _View(md, out), elements


def _extent(md: Any, dim: Any) -> int:
    """The extent of an array dimension: its ``start``, or the start value of the structural
    parameter its ``valueReference`` names (FMI 3.0 section 2.4.7.2, ``<Dimension>``)."""
    if dim.start is not None:
        return int(dim.start)
    param = getattr(dim, "variable", None)
    if param is None:
        param = next((v for v in md.modelVariables if v.valueReference == dim.valueReference),
                     None)
    if param is None or param.start is None:
        raise DroneflyError(f"an array dimension names value reference {dim.valueReference}, "
                            "which is no variable with a start value")
    return int(param.start)


def read_view(path: str | Path) -> Any:
    """fmpy's model description of an FMU file; of an FMI 3.0 FMU, the harness's view."""

    md = read_model_description(str(path))
    return fmi2_view(md)[0] if str(md.fmiVersion).startswith("3") else md


class FMU3Adapter:
    """fmpy's FMU3Slave answering the FMU2Slave calls the harness makes (``model_exchange``:
    fmpy's FMU3Model, its value and FMU-state calls; ``model`` is the fmpy object)."""

    def __init__(self, md: Any, unzipdir: str, instance_name: str,
                 elements: dict[int, Element], model_exchange: bool = False) -> None:
        cls, interface = (FMU3Model, md.modelExchange) if model_exchange else \
            (FMU3Slave, md.coSimulation)
        self._s = cls(guid=md.guid, unzipDirectory=unzipdir,
                      modelIdentifier=interface.modelIdentifier, instanceName=instance_name)
        self.model = self._s
        self._elements = elements
        self._types = {v.valueReference: v.type for v in md.modelVariables}
        #: Float32 variables are read and written with fmi3Get/SetFloat32 (section 2.2.6.2)
        self._f32 = {vr for vr, kind in self._types.items() if kind == "Float32"}
        self._known: dict[int, tuple[Any, bool]] = {}  # raw vr arrays seen: (array, plain)
        self._experiment: tuple[float | None, float, float | None] = (None, 0.0, None)
        flags = (c_bool(), c_bool(), c_bool(), c_double())
        self._flags = flags
        self._flag_refs = tuple(byref(f) for f in flags)
        self._do_step = self._s.fmi3DoStep
        self._get64 = self._s.fmi3GetFloat64
        self._set64 = self._s.fmi3SetFloat64

    # -- life cycle ------------------------------------------------------------
    def instantiate(self, logMessage: Callable[..., None], loggingOn: bool = False) -> None:
        self._s.instantiate(loggingOn=loggingOn, logMessage=logMessage)

    @property
    def component(self) -> Any:
        return self._s.component

    def setupExperiment(self, tolerance: float | None = None, startTime: float = 0.0,
                        stopTime: float | None = None) -> None:
        self._experiment = (tolerance, startTime, stopTime)

    def enterInitializationMode(self) -> None:
        tol, start, stop = self._experiment
        self._s.enterInitializationMode(tolerance=tol, startTime=start, stopTime=stop)

    def exitInitializationMode(self) -> None:
        self._s.exitInitializationMode()

    def terminate(self) -> Any:
        return self._s.terminate()

    def reset(self) -> Any:
        return self._s.reset()

    def doStep(self, currentCommunicationPoint: float, communicationStepSize: float,
               noSetFMUStatePriorToCurrentPoint: bool = True) -> Any:
        return self._s.doStep(currentCommunicationPoint, communicationStepSize,
                              noSetFMUStatePriorToCurrentPoint)

    def step_ended(self) -> bool:
        """Whether the last raw step (:meth:`fmi2DoStep`) asked to end the run
        (terminateSimulation) or returned early (earlyReturn)."""
        return bool(self._flags[1].value or self._flags[2].value)

    def fmi2FreeInstance(self, component: Any) -> None:
        self._s.fmi3FreeInstance(component)

    def freeLibrary(self) -> None:
        self._s.freeLibrary()

    # -- raw calls of the masters' hot path (scalar value references) ----------
    def _plain(self, vr: Any, n: int) -> bool:
        """Whether the raw value-reference array ``vr`` names Float64 scalars only (no
        Float32, no array element): then the raw call passes it through. An array found
        plain is remembered (and kept alive, so that its id is not reused)."""
        if not self._f32 and not self._elements:
            return True
        known = self._known.get(id(vr))
        if known is not None and known[0] is vr:
            return known[1]
        plain = not any(v in self._f32 or v >= VIRTUAL for v in vr[:n])
        if len(self._known) > 256:
            self._known.clear()
        self._known[id(vr)] = (vr, plain)
        return plain

    def fmi2GetReal(self, c: Any, vr: Any, n: int, values: Any) -> int:
        if not self._plain(vr, n):
            values[:n] = self.getReal(list(vr[:n]))
            return 0  # a failed get raised FMICallException
        return self._get64(c, vr, n, values, n)

    def fmi2SetReal(self, c: Any, vr: Any, n: int, values: Any) -> int:
        if not self._plain(vr, n):
            self.setReal(list(vr[:n]), list(values[:n]))
            return 0
        return self._set64(c, vr, n, values, n)

    def fmi2DoStep(self, c: Any, t: float, h: float, no_set_prior: int) -> int:
        r = self._flag_refs
        return self._do_step(c, t, h, bool(no_set_prior), r[0], r[1], r[2], r[3])

    def fmi2GetBoolean(self, c: Any, vr: Any, n: int, values: Any) -> int:
        buf = (c_bool * n)()
        status = self._s.fmi3GetBoolean(c, vr, n, buf, n)
        values[:n] = [int(b) for b in buf]
        return status

    def fmi2SetBoolean(self, c: Any, vr: Any, n: int, values: Any) -> int:
        return self._s.fmi3SetBoolean(c, vr, n, (c_bool * n)(*[bool(x) for x in values[:n]]), n)

    def fmi2GetInteger(self, c: Any, vr: Any, n: int, values: Any) -> int:
        values[:n] = self.getInteger(list(vr[:n]))
        return 0  # a failed get raised FMICallException

    def fmi2SetInteger(self, c: Any, vr: Any, n: int, values: Any) -> int:
        self.setInteger(list(vr[:n]), list(values[:n]))
        return 0

    # -- Integer (any FMI 3.0 integer type, Enumeration) and String values -------
    def _int(self, vr: int) -> str:
        kind = INT_TYPES.get(self._types.get(vr, ""))
        if kind is None:
            raise DroneflyError(f"value reference {vr} is a {self._types.get(vr, 'unknown')} "
                                "variable, not an integer one")
        return kind

    def getInteger(self, vr: Sequence[int]) -> list[int]:
        return [int(getattr(self._s, f"get{self._int(v)}")([v])[0]) for v in vr]

    def setInteger(self, vr: Sequence[int], values: Sequence[int]) -> None:
        for v, x in zip(vr, values):
            getattr(self._s, f"set{self._int(v)}")([v], [int(x)])

    def getString(self, vr: Sequence[int]) -> list[str]:
        return self._s.getString(list(vr))

    def setString(self, vr: Sequence[int], values: Sequence[str]) -> None:
        self._s.setString(list(vr), [str(x) for x in values])

    # -- values by (possibly virtual) value reference ----------------------------
    def _split(self, vrs: Sequence[int]) -> bool:
        return any(v >= VIRTUAL for v in vrs)

    def _floats(self, vr: int) -> tuple[Callable[..., list[float]], Callable[..., None]]:
        if vr in self._f32:
            return self._s.getFloat32, self._s.setFloat32
        return self._s.getFloat64, self._s.setFloat64

    def getReal(self, vr: Sequence[int]) -> list[float]:
        if not self._f32 and not self._split(vr):
            return self._s.getFloat64(list(vr))
        out = []
        for v in vr:
            e = self._elements.get(v)
            get = self._floats(e.array_vr if e else v)[0]
            out.append(float(get([e.array_vr], e.size)[e.index] if e else get([v])[0]))
        return out

    def setReal(self, vr: Sequence[int], values: Sequence[float]) -> None:
        if not self._f32 and not self._split(vr):
            self._s.setFloat64(list(vr), [float(x) for x in values])
            return
        for v, x in zip(vr, values):
            e = self._elements.get(v)
            get, put = self._floats(e.array_vr if e else v)
            if e is None:
                put([v], [float(x)])
                continue
            whole = get([e.array_vr], e.size)
            whole[e.index] = float(x)
            put([e.array_vr], whole)

    def getBoolean(self, vr: Sequence[int]) -> list[bool]:
        return [bool(b) for b in self._s.getBoolean(list(vr))]

    def setBoolean(self, vr: Sequence[int], values: Sequence[bool]) -> None:
        self._s.setBoolean(list(vr), [bool(x) for x in values])

    # -- FMU state -----------------------------------------------------------------
    def getFMUstate(self) -> Any:
        return self._s.getFMUState()

    def setFMUstate(self, state: Any) -> None:
        self._s.setFMUState(state)

    def freeFMUstate(self, state: Any) -> None:
        self._s.freeFMUState(state)

    def serializeFMUstate(self, state: Any) -> bytes:
        return self._s.serializeFMUState(state)

    def deSerializeFMUstate(self, data: bytes) -> Any:
        return self._s.deserializeFMUState(data)

    def __getattr__(self, name: str) -> Any:
        if name.startswith("fmi3") or name in ("getFloat64", "setFloat64"):
            return getattr(self._s, name)
        raise AttributeError(f"{name}: an FMI 2.0 call with no FMI 3.0 counterpart in "
                             "dronefly's adapter (FMU3Adapter)")
