"""Check family: the FMU's binary as a host links and calls it (``dronefly check``).

``binary``: the shared library of the Co-Simulation interface (for this platform)

* exports every function the declared interface and capabilities require (FMI 2.0 2.1.1, 4.2;
  FMI 3.0 2.2.1, 4.2): the common and Co-Simulation functions, the FMU state functions where
  ``canGetAndSetFMUstate`` / ``canSerializeFMUstate`` are declared, the directional derivative
  where ``providesDirectionalDerivative`` is;
* answers ``fmi2GetVersion`` "2.0" and ``fmi2GetTypesPlatform`` "default" (FMI 2.0 2.1.4),
  ``fmi3GetVersion`` "3.0";

and, for ``logger-format`` (:mod:`.refusals`, the last check: a crash there leaves no other
check out), :func:`logger_passes_back`: what the host gave it reaches its logger, FMI 2.0 the
``componentEnvironment`` of the callbacks and the instance name (2.1.5), FMI 3.0 the
``instanceEnvironment`` (fmi3Instantiate).

``check(ctx) -> detail``, FMI 2.0 and 3.0 alike.
"""

from __future__ import annotations

import ctypes
import os
from pathlib import Path
from xml.etree import ElementTree
from typing import Any

from fmpy import platform, platform_tuple, sharedLibraryExtension
from fmpy.fmi1 import calloc, free
from fmpy.fmi2 import (fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                       fmi2CallbackFunctions, fmi2CallbackLoggerTYPE)
from fmpy.fmi3 import (fmi3InstanceEnvironment, fmi3IntermediateUpdateCallback,
                       fmi3LogMessageCallback, fmi3ValueReference)

from ..cosim.prototypes import FMU2Slave, FMU3Slave
from .driver import Context
from .fuzzkit import status_of
from .rules import CheckSkipped, require

__all__ = ["check_binary", "declares_directional", "logger_passes_back", "required_functions"]

_FMI2_COMMON = ("GetTypesPlatform", "GetVersion", "SetDebugLogging", "Instantiate",
                "FreeInstance", "SetupExperiment", "EnterInitializationMode",
                "ExitInitializationMode", "Terminate", "Reset", "GetReal", "GetInteger",
                "GetBoolean", "GetString", "SetReal", "SetInteger", "SetBoolean", "SetString")
_FMI2_CS = ("SetRealInputDerivatives", "GetRealOutputDerivatives", "DoStep", "CancelStep",
            "GetStatus", "GetRealStatus", "GetIntegerStatus", "GetBooleanStatus",
            "GetStringStatus")
_FMI3_TYPES = ("Float32", "Float64", "Int8", "UInt8", "Int16", "UInt16", "Int32", "UInt32",
               "Int64", "UInt64", "Boolean", "String", "Binary")
_FMI3_COMMON = ("GetVersion", "SetDebugLogging", "FreeInstance", "EnterInitializationMode",
                "ExitInitializationMode", "Terminate", "Reset", "EnterConfigurationMode",
                "ExitConfigurationMode", *(f"{a}{t}" for t in _FMI3_TYPES for a in ("Get", "Set")))
_FMI3_CS = ("InstantiateCoSimulation", "DoStep", "EnterStepMode")
_FMI2_ME = ("EnterEventMode", "NewDiscreteStates", "EnterContinuousTimeMode",
            "CompletedIntegratorStep", "SetTime", "SetContinuousStates", "GetDerivatives",
            "GetEventIndicators", "GetContinuousStates", "GetNominalsOfContinuousStates")
_FMI3_ME = ("InstantiateModelExchange", "EnterEventMode", "UpdateDiscreteStates",
            "EnterContinuousTimeMode", "CompletedIntegratorStep", "SetTime",
            "SetContinuousStates", "GetContinuousStateDerivatives", "GetEventIndicators",
            "GetContinuousStates", "GetNominalsOfContinuousStates",
            "GetNumberOfEventIndicators", "GetNumberOfContinuousStates")
#: a value the host passes as its environment, to be handed back to the logger
_SENTINEL = 0x5EED


def required_functions(md: Any, fmi_version: int, interface: str = "cs",
                       directional: bool | None = None) -> list[str]:
    """The functions the Co-Simulation (``"cs"``) or Model Exchange (``"me"``) interface of
    ``md`` (FMPy's model description of the FMU's own version) requires its binary to export.

    ``directional``: whether the interface declares the directional derivative, where ``md``
    does not say (FMPy's FMI 3.0 interface objects have no ``providesDirectionalDerivatives``:
    :func:`declares_directional` reads it); None: ``md``'s attribute."""
    me = interface == "me"
    cs = md.modelExchange if me else md.coSimulation
    if fmi_version == 2:
        names = [*_FMI2_COMMON, *(_FMI2_ME if me else _FMI2_CS)]
        state = ("GetFMUstate", "SetFMUstate", "FreeFMUstate")
        serial = ("SerializedFMUstateSize", "SerializeFMUstate", "DeSerializeFMUstate")
    else:
        names = [*_FMI3_COMMON, *(_FMI3_ME if me else _FMI3_CS)]
        state = ("GetFMUState", "SetFMUState", "FreeFMUState")
        serial = ("SerializedFMUStateSize", "SerializeFMUState", "DeserializeFMUState")
    if cs.canGetAndSetFMUstate:
        names += state
    if cs.canSerializeFMUstate:
        names += serial
    if directional is None:
        directional = bool(getattr(cs, "providesDirectionalDerivative", False)
                           or getattr(cs, "providesDirectionalDerivatives", False))
    if directional:
        names.append("GetDirectionalDerivative")
    return [f"fmi{fmi_version}{n}" for n in names]


def declares_directional(ctx: Context, interface: str = "cs") -> bool | None:
    """FMI 3.0: whether the interface's element of modelDescription.xml declares
    ``providesDirectionalDerivatives`` (xs:boolean: "true" or "1"), which FMPy's model
    description leaves out (it copies FMI 2.0's ``providesDirectionalDerivative``); FMI 2.0:
    None (FMPy's attribute says it)."""
    if ctx.fmu.fmi_version != 3:
        return None
    root = ElementTree.parse(Path(ctx.fmu._unzipdir, "modelDescription.xml")).getroot()
    element = root.find("ModelExchange" if interface == "me" else "CoSimulation")
    return element is not None and element.get("providesDirectionalDerivatives") in ("true", "1")


def _library(ctx: Context, interface: str = "cs") -> Path:
    md = ctx.fmu.model_description
    ident = (md.modelExchange if interface == "me" else md.coSimulation).modelIdentifier
    folder = platform if ctx.fmu.fmi_version == 2 else platform_tuple
    return Path(ctx.fmu._unzipdir, "binaries", folder, ident + sharedLibraryExtension)


def check_binary(ctx: Context) -> str:
    v = ctx.fmu.fmi_version
    md = ctx.fmu.model_description3 or ctx.fmu.model_description
    # each declared interface's library (one file where they share the model identifier)
    libraries: dict[Path, list[str]] = {}
    for interface in ctx.interfaces:
        libraries.setdefault(_library(ctx, interface), []).extend(
            n for n in required_functions(md, v, interface, declares_directional(ctx, interface))
            if n not in libraries.get(_library(ctx, interface), []))
    path = next(iter(libraries))
    if not path.is_file():
        raise CheckSkipped(f"no binary {path.name} for this platform")
    missing, problems = [], []
    for lib_path, required in libraries.items():
        if not lib_path.is_file():
            problems.append(f"no binary {lib_path.name} for this platform beside {path.name}")
            continue
        ctx.event(call=f"dlopen({lib_path.name})")
        found = ctypes.CDLL(str(lib_path), mode=os.RTLD_LAZY | os.RTLD_LOCAL)
        missing += [n for n in required if not hasattr(found, n)]
    lib = ctypes.CDLL(str(path), mode=os.RTLD_LAZY | os.RTLD_LOCAL)
    if missing:
        problems.append(f"not exported: {', '.join(missing)}")
    versions = [("fmi2GetVersion", "2.0"), ("fmi2GetTypesPlatform", "default")] if v == 2 \
        else [("fmi3GetVersion", "3.0")]
    for name, want in versions:
        if hasattr(lib, name):
            fn = getattr(lib, name)
            fn.restype, fn.argtypes = ctypes.c_char_p, []
            ctx.event(call=f"{name}()")
            got = fn()
            text = got.decode("utf-8", "replace") if got is not None else None
            if text != want:
                problems.append(f"{name}() returned {text!r}, not {want!r}")
    if missing:  # FMPy binds every function: a host cannot use such a binary
        ctx.unusable = ("its binary lacks functions a host binds (the finding is reported "
                        "under binary)")
    require(not problems, "; ".join(problems))
    n = sum(len(names) for names in libraries.values())
    return f"{n} required functions exported; {', '.join(w for w, _ in versions)} right"


def logger_passes_back(ctx: Context) -> tuple[str, int]:
    """(the problem or "", how many messages logged) of an instance whose logger checks what it
    is given: FMI 2.0 the componentEnvironment and instance name the host passed, FMI 3.0 the
    instanceEnvironment. The FMU is made to log by a step of size 0 after initialization."""
    return _logger_passes_back(ctx)


def _logger_passes_back(ctx: Context) -> tuple[str, int]:
    """(the problem or "", how many messages) of an instance whose logger checks what it gets."""
    name = "dronefly binary check"
    got: list[tuple[Any, str | None]] = []
    md = ctx.fmu.model_description3 or ctx.fmu.model_description
    ident = md.coSimulation.modelIdentifier
    if ctx.fmu.fmi_version == 2:
        def logger(env: Any, instance: bytes | None, status: int, category: bytes,
                   message: bytes) -> None:
            got.append((env, instance.decode("utf-8", "replace") if instance else None))

        cb = fmi2CallbackFunctions()
        cb.logger = fmi2CallbackLoggerTYPE(logger)
        cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        cb.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        cb.componentEnvironment = _SENTINEL
        slave: Any = FMU2Slave(guid=md.guid, unzipDirectory=ctx.fmu._unzipdir,
                               modelIdentifier=ident, instanceName=name)
        ctx.event(call=f"fmi2Instantiate(instanceName={name!r}, componentEnvironment="
                       f"{_SENTINEL:#x})")
        slave.instantiate(callbacks=cb, loggingOn=True)
        try:
            slave.setupExperiment(startTime=ctx.start, stopTime=ctx.stop)
            slave.enterInitializationMode()
            slave.exitInitializationMode()
            ctx.event(call="fmi2DoStep(communicationStepSize=0.0)")
            status_of(lambda: slave.doStep(currentCommunicationPoint=ctx.start,
                                           communicationStepSize=0.0))
        finally:
            slave.fmi2FreeInstance(slave.component)
            slave.freeLibrary()
        wrong_env = [e for e, _ in got if e != _SENTINEL]
        wrong_name = [n for _, n in got if n != name]
        problems = []
        if wrong_env:
            problems.append(f"the logger got componentEnvironment {wrong_env[0]!r}, not the "
                            f"{_SENTINEL:#x} the host passed")
        if wrong_name:
            problems.append(f"the logger got instance name {wrong_name[0]!r}, not {name!r}")
        return "; ".join(problems), len(got)

    def log3(env: Any, status: int, category: bytes, message: bytes) -> None:
        got.append((env, None))

    slave = FMU3Slave(guid=md.instantiationToken, unzipDirectory=ctx.fmu._unzipdir,
                      modelIdentifier=ident, instanceName=name)
    callback = fmi3LogMessageCallback(log3)
    update = fmi3IntermediateUpdateCallback()
    resources = os.path.join(ctx.fmu._unzipdir, "resources") + os.path.sep
    ctx.event(call=f"fmi3InstantiateCoSimulation(instanceName={name!r}, instanceEnvironment="
                   f"{_SENTINEL:#x})")
    slave.component = slave.fmi3InstantiateCoSimulation(
        name.encode(), md.instantiationToken.encode(), resources.encode(), False, True, False,
        False, (fmi3ValueReference * 0)(), 0, fmi3InstanceEnvironment(_SENTINEL), callback,
        update)
    require(bool(slave.component), "fmi3InstantiateCoSimulation returned NULL")
    try:
        slave.enterInitializationMode(startTime=ctx.start, stopTime=ctx.stop)
        slave.exitInitializationMode()
        ctx.event(call="fmi3DoStep(communicationStepSize=0.0)")
        status_of(lambda: slave.doStep(currentCommunicationPoint=ctx.start,
                                       communicationStepSize=0.0))
    finally:
        slave.freeInstance()
        slave.freeLibrary()
    wrong = [e for e, _ in got if e != _SENTINEL]
    return (f"the logger got instanceEnvironment {wrong[0]!r}, not the {_SENTINEL:#x} the "
            "host passed" if wrong else ""), len(got)
