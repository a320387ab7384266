"""Thin, safe access to co-simulation FMUs through fmpy's FMU2Slave API.

FMI 2.0 FMUs run in fmpy's FMU2Slave; FMI 3.0 FMUs in fmpy's FMU3Slave behind the same API
(:mod:`.fmu3`: arrays appear as scalar elements, Float64 and Float32 as Real).

An :class:`FMU` is read and extracted once; :meth:`FMU.instantiate` gives
:class:`Instance` objects whose log messages are captured in
``Instance.messages`` and which are freed on every exit path (use them as
context managers).
"""

from __future__ import annotations

import re
import shutil
import tempfile
import zipfile
from ctypes import byref
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping, Sequence

import fmpy
from fmpy import platform, platform_tuple, sharedLibraryExtension
from fmpy.fmi1 import calloc, free
from fmpy.fmi2 import (fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                       fmi2CallbackFunctions, fmi2CallbackLoggerTYPE)
from fmpy.logging import addLoggerProxy

from ...core.errors import DroneflyError
from .exchange import MEStepper
from .fmu3 import FMU3Adapter, fmi2_view
from .prototypes import FMU2Model, FMU2Slave

__all__ = ["FMU", "FMUError", "Instance", "LogMessage", "check_archive", "column_units",
           "start_values", "variable_unit"]

# fmpy's native logger proxy keeps ONE Python logger per process (the last one
# installed), so every instance shares one dispatcher that routes messages by
# instance name; live instance names are kept unique.
_LIVE: dict[str, "Instance"] = {}
_DISPATCH: Any = None


def _dispatch(env: Any, instance: bytes, status: int, category: bytes, message: bytes) -> None:
    def _s(b: bytes | None) -> str:
        return b.decode("utf-8", "replace") if b else ""

    name = _s(instance)
    target = _LIVE.get(name)
    if target is not None:
        target.messages.append(LogMessage(name, int(status), _s(category), _s(message)))


def _unique(name: str) -> str:
    if name not in _LIVE:
        return name
    k = 2
    while f"{name}#{k}" in _LIVE:
        k += 1
    return f"{name}#{k}"


class FMUError(DroneflyError):
    """An FMU file is missing, corrupt, or not an FMI 2.0 / 3.0 co-simulation FMU."""


@dataclass(frozen=True)
class LogMessage:
    instance: str
    status: int
    category: str
    message: str


def start_values(md: Any) -> dict[str, float]:
    """Start values of the Real variables of an fmpy model description, by name."""
    return {v.name: float(v.start) for v in md.modelVariables
            if v.type == "Real" and v.start is not None}


def variable_unit(v: Any) -> str:
    """A variable's unit as its model description declares it (its own or its type's);
    ``"1"`` for one without (a number, a count, a flag)."""
    unit = getattr(v, "unit", None)
    if unit is None and getattr(v, "declaredType", None) is not None:
        unit = getattr(v.declaredType, "unit", None)
    return unit or "1"


def column_units(names: Sequence[str], fmus: Mapping[str, "FMU"],
                 bare: str | None = None) -> dict[str, str]:
    """The unit of each column of a run's CSV, ``time`` [s] first: ``instance.NAME`` from
    that instance's FMU, a bare ``NAME`` from the FMU ``bare`` (the pair's plant)."""
    out = {"time": "s"}
    for name in names:
        inst, dot, var = name.partition(".")
        if not (dot and inst in fmus):
            inst, var = bare, name
        v = fmus[inst].variables.get(var) if inst in fmus else None
        out[name] = "1" if v is None else variable_unit(v)
    return out


def check_archive(path: Path, require_binary: bool = True) -> None:
    """Refuse an FMU that could not be loaded safely, before anything of it is loaded.

    Checks that the file is a zip with a modelDescription.xml of FMI version 2.0 or 3.0, a
    co-simulation binary for this platform (unless ``require_binary`` is false), and, for a
    pythonfmu FMU (``slavemodule.txt``, also nested ones), the Python module it names:
    pythonfmu crashes the host on a missing one. Raises :class:`FMUError` with one line
    naming what is missing.
    """

    try:
        with zipfile.ZipFile(path) as z:
            names = set(z.namelist())
            head = z.read("modelDescription.xml")[:4096].decode("utf-8", "replace")
            modules = {n: z.read(n).decode("utf-8", "replace").strip()
                       for n in names if n.endswith("resources/slavemodule.txt")}
    except (zipfile.BadZipFile, OSError) as e:
        raise FMUError(f"{str(path)!r} is not an FMU (not a zip archive: {e})") from e
    except KeyError:
        raise FMUError(f"{str(path)!r} is not an FMU (no modelDescription.xml)") from None
    version = re.search(r'fmiVersion\s*=\s*"([^"]*)"', head)
    if version is None or version.group(1) not in ("2.0", "3.0"):
        found = version.group(1) if version else "unknown"
        raise FMUError(f"{str(path)!r} is an FMI {found} FMU; dronefly co-simulates FMI 2.0 "
                       "and 3.0 co-simulation FMUs")
    ident = re.search(r'<CoSimulation[^>]*modelIdentifier\s*=\s*"([^"]*)"', head)
    if ident is not None and require_binary:
        folder = platform if version.group(1) == "2.0" else platform_tuple
        lib = f"binaries/{folder}/{ident.group(1)}{sharedLibraryExtension}"
        if lib not in names:
            raise FMUError(f"{str(path)!r} has no binary for this platform ({lib} is missing)")
    for txt, module in modules.items():
        folder = txt[: -len("slavemodule.txt")]
        if f"{folder}{module}.py" not in names:
            raise FMUError(f"{str(path)!r} is incomplete: {folder}{module}.py, named in {txt}, "
                           "is missing (the FMU's Python sources)")


def _one_line(e: Exception) -> str:
    """fmpy's error in one line, every problem it lists kept: ``Failed to validate
    modelDescription.xml: - a; - b`` becomes ``modelDescription.xml: a; b``."""
    lines = [ln.strip() for ln in str(e).strip().splitlines() if ln.strip()]
    if not lines:
        return repr(e)
    head, items = lines[0], [ln.lstrip("- ").strip() for ln in lines[1:]]
    if head.startswith("Failed to validate ") and items:
        what = head[len("Failed to validate "):].rstrip(":")
        return f"{what} breaks {len(items)} rule(s): " + "; ".join(items)
    return "; ".join([head, *items])


class FMU:
    """An FMI 2.0 CS FMU, read and extracted once.

    Parameters
    ----------
    path : str or Path
        The ``.fmu`` file.
    validate : bool
        Refuse a modelDescription.xml that fmpy's validation finds problems in (default);
        ``dronefly check`` reads it unvalidated and lists every problem in its own checks.
    require_binary : bool
        Refuse an FMU without a binary for this platform (default).
    require_cosim : bool
        Refuse an FMU without a Co-Simulation interface (default); ``dronefly check`` also
        checks one with Model Exchange only.

    Raises
    ------
    FMUError
        Missing file, not a zip, no valid modelDescription.xml (every problem fmpy names, in
        one line), no co-simulation (``require_cosim`` false: neither co-simulation nor model
        exchange).
    """

    def __init__(self, path: str | Path, validate: bool = True,
                 require_binary: bool = True, require_cosim: bool = True) -> None:
        self.path = Path(path)
        if not self.path.is_file():
            raise FMUError(f"FMU file {str(self.path)!r} " + (
                "is a folder, not an FMU file" if self.path.is_dir() else "does not exist"))
        check_archive(self.path, require_binary=require_binary)
        try:
            self.model_description = fmpy.read_model_description(str(self.path),
                                                                  validate=validate)
        except Exception as e:  # fmpy lists its problems one a line: every one kept
            raise FMUError(f"{str(self.path)!r} is not a readable FMU: {_one_line(e)}") from e
        md = self.model_description
        if md.coSimulation is None and (require_cosim or md.modelExchange is None):
            raise FMUError(f"{str(self.path)!r} is not a co-simulation FMU ("
                           + ("model exchange only)" if md.modelExchange is not None
                              else "neither co-simulation nor model exchange)"))
        #: 2 or 3; for FMI 3.0, ``model_description`` is the harness's view of
        #: ``model_description3`` (see :mod:`.fmi3`)
        self.fmi_version = 3 if md.fmiVersion.startswith("3") else 2
        self.model_description3: Any = None
        self.elements: dict[int, Any] = {}
        if self.fmi_version == 3:
            self.model_description3 = md
            self.model_description, self.elements = fmi2_view(md)
            md = self.model_description
        self.name = md.modelName
        self.variables = {v.name: v for v in md.modelVariables}
        self._unzipdir: str | None = tempfile.mkdtemp(prefix=f"dronefly_{self.name}_")
        try:
            fmpy.extract(str(self.path), self._unzipdir)
        except Exception as e:
            self.close()
            raise FMUError(f"cannot extract {str(self.path)!r}: {e}") from e

    def vr(self, name: str) -> int:
        """Value reference of a variable (raises :class:`FMUError` naming it)."""
        try:
            return self.variables[name].valueReference
        except KeyError:
            raise FMUError(f"FMU {self.name!r} ({self.path}) has no variable {name!r}") from None

    def start_values(self) -> dict[str, float]:
        """Start values of the Real variables, by name (see :func:`start_values`)."""
        return start_values(self.model_description)

    def names(self, causality: str) -> list[str]:
        return [v.name for v in self.model_description.modelVariables if v.causality == causality]

    def instantiate(self, instance_name: str | None = None, logging: bool = True,
                    interface: str = "cs") -> "Instance":
        """An instance through the Co-Simulation (``"cs"``) or the Model Exchange (``"me"``)
        interface; a Model Exchange one answers the same calls (:mod:`.exchange`)."""
        if self._unzipdir is None:
            raise FMUError(f"FMU {self.name!r} is closed")
        return Instance(self, instance_name or self.name, logging, interface=interface)

    def close(self) -> None:
        """Delete the extracted files."""
        if self._unzipdir is not None:
            shutil.rmtree(self._unzipdir, ignore_errors=True)
            self._unzipdir = None

    def __enter__(self) -> "FMU":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


@dataclass
class Instance:
    """One instantiated slave; ``slave`` is the fmpy ``FMU2Slave`` (``interface`` ``"me"``: a
    :class:`.exchange.MEStepper` answering its calls through Model Exchange)."""

    fmu: FMU
    name: str
    logging: bool = True
    messages: list[LogMessage] = field(default_factory=list)
    interface: str = "cs"

    def __post_init__(self) -> None:
        self.name = _unique(self.name)
        if self.fmu.fmi_version == 3:
            self._instantiate3()
            return
        global _DISPATCH
        if _DISPATCH is None:
            _DISPATCH = fmi2CallbackLoggerTYPE(_dispatch)
        md = self.fmu.model_description
        me = self.interface == "me"
        cls, interface = (FMU2Model, md.modelExchange) if me else (FMU2Slave, md.coSimulation)
        self.slave = cls(guid=md.guid, unzipDirectory=self.fmu._unzipdir,
                         modelIdentifier=interface.modelIdentifier, instanceName=self.name)
        cb = fmi2CallbackFunctions()
        cb.logger = _DISPATCH
        cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        cb.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        try:
            addLoggerProxy(byref(cb))
        except Exception:  # pragma: no cover - fmpy without the proxy
            pass
        self._callbacks = cb  # keep the ctypes structure alive as long as the instance
        self._register(callbacks=cb, loggingOn=self.logging)
        if me:
            self.slave = MEStepper(self.slave, self.slave, 2, md.numberOfContinuousStates,
                                   md.numberOfEventIndicators,
                                   bool(md.modelExchange.needsCompletedIntegratorStep))

    def _register(self, **instantiate_args: Any) -> None:
        """Call the slave's instantiate; the instance is live (freed at exit) if it succeeds."""
        self._freed = False
        _LIVE[self.name] = self
        try:
            self.slave.instantiate(**instantiate_args)
        except Exception as e:
            self._freed = True
            _LIVE.pop(self.name, None)
            raise FMUError(f"cannot instantiate {self.fmu.name!r}: {e}") from e

    def _instantiate3(self) -> None:
        md = self.fmu.model_description3
        me = self.interface == "me"
        self.slave: Any = FMU3Adapter(md, str(self.fmu._unzipdir), self.name, self.fmu.elements,
                                      model_exchange=me)

        def log(env: Any, status: int, category: bytes, message: bytes) -> None:
            self.messages.append(LogMessage(self.name, int(status), (category or b"").decode(
                "utf-8", "replace"), (message or b"").decode("utf-8", "replace")))

        self._register(logMessage=log, loggingOn=self.logging)
        if me:
            self.slave = MEStepper(self.slave.model, self.slave, 3, None, None)

    def vrs(self, names: Sequence[str]) -> list[int]:
        return [self.fmu.vr(n) for n in names]

    def free(self) -> None:
        """Terminate (if possible) and free; safe to call twice."""
        if not self._freed:
            self._freed = True
            try:
                self.slave.fmi2FreeInstance(self.slave.component)
            finally:
                self.slave.freeLibrary()
                if _LIVE.get(self.name) is self:
                    del _LIVE[self.name]

    def __enter__(self) -> "Instance":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.free()
