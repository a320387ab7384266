"""The checks ``dronefly check`` adds for FMI 3.0 Co-Simulation FMUs.

The FMI 2.0 checks of :mod:`.checker` run on an FMI 3.0 FMU through fmpy's FMU3Slave (see
:mod:`dronefly.harness.cosim.fmi3`); these add what FMI 3.0 says differently:

* ``state-machine``: fmi3DoStep before initialization and after fmi3Terminate returns
  fmi3Error (FMI 3.0 2.2.4: a function called where the state machine does not allow it),
  never fmi3Fatal, and fmi3Reset recovers (after fmi3Error only reset, free or setting a
  state are allowed). In the dronefly profile also: the log names the state in our wording,
  a step after a value that may not be set (an output, the independent variable) is refused,
  an unknown value reference is answered NaN with a logged error.
* ``discard`` (dronefly profile): a NaN on an input makes the next step fmi3Discard, not
  fmi3Error; the instance continues. The standard does not require an FMU to refuse NaN.
* ``state-refusal`` (dronefly profile): corrupt serialized state bytes are refused (logged)
  when set, and the instance is unchanged. The standard does not require an FMU to detect
  corrupt bytes.

Each check takes the FMU and the checker's context (its ``profile``) and returns its detail
line or raises :class:`Fmi3CheckFailed`.
"""

from __future__ import annotations

import math
from ctypes import c_double as _f64, c_uint32 as _u32
from typing import Any, Callable

from .fuzzkit import status_of

__all__ = ["FMI3_CHECKS", "FMI3_PROFILES", "FMI3_RULES", "Fmi3CheckFailed", "check_discard",
           "check_state_machine", "check_state_refusal"]

_ERROR, _DISCARD, _FATAL = 3, 2, 4
_NAMES = ("fmi3OK", "fmi3Warning", "fmi3Discard", "fmi3Error", "fmi3Fatal")


class Fmi3CheckFailed(AssertionError):
    """An FMI 3.0 requirement is not met (the message says which)."""


def _require(cond: bool, msg: str) -> None:
    if not cond:
        raise Fmi3CheckFailed(msg)


def _experiment(fmu: Any) -> tuple[float, float]:
    de = fmu.model_description.defaultExperiment
    start = float(de.startTime) if de is not None and de.startTime is not None else 0.0
    step = float(de.stepSize) if de is not None and de.stepSize is not None else 1e-3
    return start, step


def _names(fmu: Any, causality: str) -> list[str]:
    return [v.name for v in fmu.model_description.modelVariables
            if v.causality == causality and v.type == "Real"]


def _init(inst: Any, start: float) -> None:
    inst.slave.setupExperiment(startTime=start)
    inst.slave.enterInitializationMode()
    inst.slave.exitInitializationMode()


def _expect(inst: Any, call: Callable[[], Any], status: int, fragment: str, what: str) -> None:
    before = len(inst.messages)
    got = status_of(call)
    _require(got != _FATAL, f"{what}: fmi3Fatal")
    _require(got == status, f"{what}: {_NAMES[got]}, expected {_NAMES[status]}")
    logged = " ".join(m.message for m in inst.messages[before:])
    _require(fragment in logged, f"{what}: {fragment!r} not in the log ({logged[:200]!r})")


def _step(inst: Any, t: float, h: float) -> Callable[[], Any]:
    return lambda: inst.slave.doStep(currentCommunicationPoint=t, communicationStepSize=h)


def check_state_machine(fmu: Any, ctx: Any = None) -> str:
    if ctx is not None and getattr(ctx, "profile", "dronefly") != "dronefly":
        return _state_machine_standard(fmu)
    start, h = _experiment(fmu)
    outputs = _names(fmu, "output")
    time_vr = [v.valueReference for v in fmu.model_description3.modelVariables
               if v.causality == "independent"]
    cases = 0
    with fmu.instantiate("check") as inst:
        s = inst.slave
        _expect(inst, _step(inst, start, h), _ERROR, "not allowed in state 'instantiated'",
                "fmi3DoStep before initialization")
        _init(inst, start)
        nan = s.getFloat64([2 ** 30 - 1])
        _require(len(nan) == 1 and math.isnan(nan[0])
                 and "valueReference" in inst.messages[-1].message,
                 "an unknown value reference is not answered NaN with a logged error")
        cases += 2
        for name, vr in ([(outputs[0], fmu.vr(outputs[0]))] if outputs else []) + \
                        [("time", v) for v in time_vr]:
            s.fmi3SetFloat64(s.component, (_u32 * 1)(vr), 1, (_f64 * 1)(0.5), 1)
            _expect(inst, _step(inst, start, h), _ERROR, f"{name} = 0.5 rejected",
                    f"a step after setting {name}")
            cases += 1
        _require(status_of(_step(inst, start, h)) == 0, "no recovery after the refused step")
        s.terminate()
        _expect(inst, _step(inst, start + h, h), _ERROR, "not allowed in state 'terminated'",
                "fmi3DoStep after fmi3Terminate")
        s.reset()
        _init(inst, start)
        for k in range(3):
            _require(status_of(_step(inst, start + k * h, h)) == 0, "no run after fmi3Reset")
        cases += 2
    return f"{cases} illegal calls answered fmi3Error with a logged message, none Fatal; " \
           "recovered by fmi3Reset"


def _state_machine_standard(fmu: Any) -> str:
    start, h = _experiment(fmu)
    with fmu.instantiate("check") as inst:
        s = inst.slave
        for when, prepare in (("before initialization", lambda: None),
                              ("after fmi3Terminate", lambda: (_init(inst, start),
                                                               s.terminate()))):
            prepare()
            before = len(inst.messages)
            got = status_of(_step(inst, start, h))
            _require(got != _FATAL, f"fmi3DoStep {when}: fmi3Fatal")
            _require(got == _ERROR, f"fmi3DoStep {when}: {_NAMES[got]}, expected fmi3Error")
            # 2.2.4: "Function logMessage must be called by the FMU with further information
            # before returning this status" (logging is on)
            _require(len(inst.messages) > before, f"fmi3DoStep {when}: fmi3Error without a "
                                                  "logged message")
            s.reset()  # after fmi3Error: fmi3Reset, fmi3FreeInstance or fmi3SetFMUState only
        _init(inst, start)
        for k in range(3):
            _require(status_of(_step(inst, start + k * h, h)) == 0, "no run after fmi3Reset")
    return "fmi3DoStep before initialization and after fmi3Terminate: fmi3Error with a logged " \
           "message, none Fatal; recovered by fmi3Reset"


def check_discard(fmu: Any, ctx: Any = None) -> str:
    start, h = _experiment(fmu)
    inputs = _names(fmu, "input")
    if not inputs:
        return "no Float64 inputs: not applicable"
    with fmu.instantiate("check") as inst:
        _init(inst, start)
        vr = [fmu.vr(inputs[0])]
        good = inst.slave.getReal(vr)
        inst.slave.setReal(vr, [math.nan])
        _expect(inst, _step(inst, start, h), _DISCARD, f"{inputs[0]} = nan", "a NaN input")
        inst.slave.setReal(vr, good)
        _require(status_of(_step(inst, start, h)) == 0, "no step after the discarded one")
    return f"{inputs[0]} = nan: fmi3Discard, then the step works"


def check_state_refusal(fmu: Any, ctx: Any = None) -> str:
    start, h = _experiment(fmu)
    outputs = _names(fmu, "output")
    runs = []
    for corrupt in (False, True):
        with fmu.instantiate("check") as inst:
            s = inst.slave
            _init(inst, start)
            _require(status_of(_step(inst, start, h)) == 0, "first step failed")
            if corrupt:
                blob = bytearray(s.serializeFMUstate(s.getFMUstate()))
                blob[-2] ^= 0xFF
                before = len(inst.messages)
                state = s.deSerializeFMUstate(bytes(blob))
                _require(status_of(lambda: s.setFMUstate(state)) != _FATAL,
                         "fmi3SetFMUState of corrupt bytes: fmi3Fatal")
                logged = " ".join(m.message for m in inst.messages[before:])
                _require("refused" in logged, f"corrupt state not refused in the log ({logged!r})")
            _require(status_of(_step(inst, start + h, h)) == 0, "the step after failed")
            runs.append(s.getReal([fmu.vr(n) for n in outputs]))
    _require(runs[0] == runs[1], "the instance changed after a refused state")
    return "corrupt serialized state refused (logged), the instance unchanged"


#: (name, check) added to the FMI 2.0 checks for FMI 3.0 FMUs
FMI3_CHECKS: list[tuple[str, Callable[..., str]]] = [
    ("state-machine", check_state_machine),
    ("discard", check_discard),
    ("state-refusal", check_state_refusal),
]

#: the profiles each FMI 3.0 check runs under
FMI3_PROFILES: dict[str, tuple[str, ...]] = {
    "state-machine": ("standard", "dronefly"),
    "discard": ("dronefly",),
    "state-refusal": ("dronefly",),
}

#: the rule of each: (FMI 2.0 rule (none), FMI 3.0 rule, the dronefly profile's promise)
FMI3_RULES: dict[str, tuple[str, str, str]] = {
    "state-machine": (
        "", "FMI 3.0 2.2.4 (status returned by functions) and 2.3 (FMU states): a call not "
            "allowed in the current state returns fmi3Error; after it fmi3Reset recovers",
        "our log wording names the state; refused sets and unknown value references"),
    "discard": ("", "dronefly profile only: a NaN input answered fmi3Discard (the standard "
                    "leaves it to the FMU)", "a NaN input answered fmi3Discard"),
    "state-refusal": ("", "dronefly profile only: corrupt serialized state refused (the "
                          "standard does not require detecting it)",
                      "corrupt serialized state refused, the instance unchanged"),
}
