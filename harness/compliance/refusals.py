"""Check family: refusals, the calls an FMU must refuse or survive (``dronefly check``).

``bad-input``, ``logger-format``, ``state-machine`` (FMI 3.0), ``discard`` and
``state-refusal`` (FMI 3.0, dronefly profile): each is ``check(ctx) -> detail`` for FMI 2.0
and 3.0 alike; the checks for one version only say so with :class:`CheckSkipped`. No check
makes a call the standard forbids (an unknown value reference, a call after Fatal): a crash
after such a call would be the checker's doing, not the FMU's.
"""

from __future__ import annotations

import math
from ctypes import c_double as _f64, c_uint32 as _u32
from typing import Any, Callable

from fmpy.fmi1 import FMICallException

from ..cosim.fmu import Instance
from .binary import logger_passes_back
from .driver import Context, do_step, initialize, step_status
from .fuzzkit import status_of
from .rules import STATUS_NAMES, CheckFailed, CheckSkipped, require, status_name

__all__ = ["check_bad_input", "check_discard", "check_logger_format", "check_state_machine",
           "check_state_refusal"]

_DISCARD, _ERROR, _FATAL = 2, 3, 4


def _expect_discard(ctx: Context, inst: Instance, t: float, h: float, fragment: str,
                    named: bool = True) -> None:
    before = len(inst.messages)
    ctx.event(call=f"{ctx.fmi}DoStep(currentCommunicationPoint={t!r}, "
                   f"communicationStepSize={h!r})")
    status = status_of(lambda: inst.slave.doStep(currentCommunicationPoint=t,
                                                  communicationStepSize=h))
    require(status != 0, f"{fragment}: {ctx.fmi}DoStep returned {ctx.fmi}OK")
    require(status in (2, 3), f"{fragment}: {ctx.fmi}DoStep returned "
                              f"{status_name(status, ctx.fmu.fmi_version)}")
    if named:
        logged = " ".join(m.message for m in inst.messages[before:])
        require(fragment in logged, f"{fragment}: not named in the log ({logged!r})")


def _bad_input_ours(ctx: Context) -> str:
    # Messages that name the value are this project's requirement of its own FMU code; a
    # wrapper made by other tools (fmpy's container binary) is held to the statuses only.
    named = (ctx.fmu.model_description.generationTool or "").startswith("dronefly-fmu")
    cases = 0
    step = ctx.step
    with ctx.instantiate("check") as inst:
        s = inst.slave
        initialize(ctx, inst)
        t = ctx.start
        for u in (v for v in ctx.inputs if v.kind == "Real"):
            good = s.getReal([u.vr])
            s.setReal([u.vr], [math.nan])
            _expect_discard(ctx, inst, t, step, f"{u.name} = nan", named)
            s.setReal([u.vr], good)
            do_step(ctx, inst, t, step)
            t += step
            cases += 1
        for h in (0.0, -step):
            _expect_discard(ctx, inst, t, h, f"communicationStepSize = {h!r}", named)
            cases += 1
        _expect_discard(ctx, inst, t + 10 * step, step,
                        f"currentCommunicationPoint = {t + 10 * step!r}", named)
        cases += 1
        do_step(ctx, inst, t, step)
    how = ("with a logged message naming the value" if named
           else "(messages not checked: not our code)")
    return f"{cases} cases refused {how}; the instance recovered"


def _bad_input_standard(ctx: Context) -> str:
    cases = []
    with ctx.instantiate("check") as inst:
        s = inst.slave
        for what, t, h in (("communicationStepSize = 0.0", ctx.start, 0.0),
                           (f"communicationStepSize = {-ctx.step!r}", ctx.start, -ctx.step),
                           (f"currentCommunicationPoint = {ctx.start + 10 * ctx.step!r} (the "
                            f"last was {ctx.start!r})", ctx.start + 10 * ctx.step, ctx.step)):
            initialize(ctx, inst)
            before = len(inst.messages)
            status = status_of(lambda: do_step(ctx, inst, t, h))
            require(status != 4, f"{what}: {ctx.fmi}DoStep returned {ctx.fmi}Fatal")
            if status == 0:
                ctx.warnings.append(f"{what}: {ctx.fmi}DoStep returned {ctx.fmi}OK")
            if ctx.fmu.fmi_version == 3 and status == 2:
                # FMI 3.0 2.2.4: "When detecting illegal arguments ... the FMU must return
                # fmi3Error" (our own FMUs answer Discard: the dronefly profile's promise)
                raise CheckFailed(f"{what}: fmi3DoStep detected an illegal argument and "
                                  "returned fmi3Discard; FMI 3.0 2.2.4 requires fmi3Error")
            if ctx.fmu.fmi_version == 3 and status == 3:
                require(len(inst.messages) > before,
                        f"{what}: fmi3Error without a logged message (FMI 3.0 2.2.4: the FMU "
                        "must call logMessage before returning fmi3Error, logging on)")
            cases.append(f"{what}: {STATUS_NAMES[status]}")
            # after Error the standard allows only reset, free or setting a state: the FMU
            # must accept the reset (a refusal is this check's finding, under its rule)
            ctx.event(call=f"{ctx.fmi}Reset()")
            try:
                s.reset()
            except FMICallException as e:
                allowed = "2.1.3" if ctx.fmu.fmi_version == 2 else "2.2.4"
                raise CheckFailed(
                    f"{what}: {ctx.fmi}DoStep returned {status_name(status, ctx.fmu.fmi_version)}"
                    f", then {ctx.fmi}Reset, the call FMI {ctx.fmu.fmi_version}.0 {allowed} "
                    f"allows after it, returned {status_name(e.status, ctx.fmu.fmi_version)}"
                ) from None
        initialize(ctx, inst)
        do_step(ctx, inst, ctx.start, ctx.step)
    return "; ".join(cases) + f"; {ctx.fmi}Reset recovered the instance"


def check_bad_input(ctx: Context) -> str:
    return _bad_input_ours(ctx) if ctx.ours else _bad_input_standard(ctx)


_PRINTF = "%s%s%s%s%n"


def check_logger_format(ctx: Context) -> str:
    # 1. what the host passed reaches the logger (FMI 2.0: componentEnvironment and the
    # instance name; FMI 3.0: instanceEnvironment): an FMU that logs nothing is not judged
    problem, logged = logger_passes_back(ctx)
    require(not problem, problem)
    passed = ("componentEnvironment and instance name" if ctx.fmu.fmi_version == 2
              else "instanceEnvironment")
    back = (f"{logged} message(s) carry the {passed} the host passed" if logged else
            f"the FMU logged nothing when a step of size 0 was refused: the {passed} its logger "
            "gets not checked")
    if not logged:
        ctx.warnings.append(back)
    if ctx.fmu.fmi_version != 2:
        return f"{back}; the message is plain text in FMI 3.0 (no printf format)"
    # 2. legal calls that make an FMU log, with printf directives in the instance name: a few
    # steps and a step of size 0 (which the FMU may refuse); then the instance is freed (no
    # reset: whether the FMU accepts fmi2Reset after fmi2Error is bad-input's rule). No call
    # the standard forbids (an unknown value reference): a crash there is no printf defect
    with ctx.instantiate(_PRINTF) as inst:
        initialize(ctx, inst)
        for k in range(min(3, ctx.n)):
            if step_status(ctx, inst, ctx.start + k * ctx.step, ctx.step) != 0:
                break
        else:
            step_status(ctx, inst, ctx.start + min(3, ctx.n) * ctx.step, 0.0)
        printed = len(inst.messages)
    return (f"{back}; instance {_PRINTF!r}, {printed} messages logged through a printf-style "
            "logger, no crash")


# -- FMI 3.0 ---------------------------------------------------------------------------------
def _fmi3_only(ctx: Context) -> None:
    if ctx.fmu.fmi_version != 3:
        raise CheckSkipped("an FMI 3.0 check; this FMU is FMI 2.0")


def _step(inst: Any, t: float, h: float) -> Callable[[], Any]:
    return lambda: inst.slave.doStep(currentCommunicationPoint=t, communicationStepSize=h)


def _expect(ctx: Context, inst: Any, call: Callable[[], Any], status: int, fragment: str,
            what: str) -> None:
    before = len(inst.messages)
    got = status_of(call)
    require(got != _FATAL, f"{what}: fmi3Fatal")
    require(got == status, f"{what}: {status_name(got, 3)}, expected {status_name(status, 3)}")
    logged = " ".join(m.message for m in inst.messages[before:])
    require(fragment in logged, f"{what}: {fragment!r} not in the log ({logged[:200]!r})")


def _reals(vars_: list) -> list:
    return [v for v in vars_ if v.kind == "Real"]


def check_state_machine(ctx: Context) -> str:
    _fmi3_only(ctx)
    if not ctx.ours:
        return _state_machine_standard(ctx)
    start, h = ctx.start, ctx.step
    outputs = _reals(ctx.outputs)
    time_vr = [v.valueReference for v in ctx.fmu.model_description3.modelVariables
               if v.causality == "independent"]
    cases = 0
    with ctx.instantiate("check") as inst:
        s = inst.slave
        _expect(ctx, inst, _step(inst, start, h), _ERROR, "not allowed in state 'instantiated'",
                "fmi3DoStep before initialization")
        initialize(ctx, inst)
        nan = s.getFloat64([2 ** 30 - 1])  # the dronefly profile's promise, not the standard's
        require(len(nan) == 1 and math.isnan(nan[0])
                and "valueReference" in inst.messages[-1].message,
                "an unknown value reference is not answered NaN with a logged error")
        cases += 2
        for name, vr in ([(outputs[0].name, outputs[0].vr)] if outputs else []) + \
                        [("time", v) for v in time_vr]:
            s.fmi3SetFloat64(s.component, (_u32 * 1)(vr), 1, (_f64 * 1)(0.5), 1)
            _expect(ctx, inst, _step(inst, start, h), _ERROR, f"{name} = 0.5 rejected",
                    f"a step after setting {name}")
            cases += 1
        require(status_of(_step(inst, start, h)) == 0, "no recovery after the refused step")
        s.terminate()
        _expect(ctx, inst, _step(inst, start + h, h), _ERROR,
                "not allowed in state 'terminated'", "fmi3DoStep after fmi3Terminate")
        s.reset()
        initialize(ctx, inst)
        for k in range(3):
            require(status_of(_step(inst, start + k * h, h)) == 0, "no run after fmi3Reset")
        cases += 2
    return f"{cases} illegal calls answered fmi3Error with a logged message, none Fatal; " \
           "recovered by fmi3Reset"


def _state_machine_standard(ctx: Context) -> str:
    start, h = ctx.start, ctx.step
    with ctx.instantiate("check") as inst:
        s = inst.slave

        def terminated() -> None:
            initialize(ctx, inst)
            s.terminate()

        for when, prepare in (("before initialization", lambda: None),
                              ("after fmi3Terminate", terminated)):
            prepare()
            before = len(inst.messages)
            got = status_of(_step(inst, start, h))
            require(got != _FATAL, f"fmi3DoStep {when}: fmi3Fatal")
            require(got == _ERROR, f"fmi3DoStep {when}: {status_name(got, 3)}, expected "
                                   "fmi3Error")
            # 2.2.4: "Function logMessage must be called by the FMU with further information
            # before returning this status" (logging is on)
            require(len(inst.messages) > before, f"fmi3DoStep {when}: fmi3Error without a "
                                                 "logged message")
            s.reset()  # after fmi3Error: fmi3Reset, fmi3FreeInstance or fmi3SetFMUState only
        initialize(ctx, inst)
        for k in range(3):
            require(status_of(_step(inst, start + k * h, h)) == 0, "no run after fmi3Reset")
    return "fmi3DoStep before initialization and after fmi3Terminate: fmi3Error with a logged " \
           "message, none Fatal; recovered by fmi3Reset"


def check_discard(ctx: Context) -> str:
    _fmi3_only(ctx)
    inputs = _reals(ctx.inputs)
    if not inputs:
        raise CheckSkipped("no Float64 inputs")
    u = inputs[0]
    with ctx.instantiate("check") as inst:
        initialize(ctx, inst)
        good = inst.slave.getReal([u.vr])
        inst.slave.setReal([u.vr], [math.nan])
        _expect(ctx, inst, _step(inst, ctx.start, ctx.step), _DISCARD, f"{u.name} = nan",
                "a NaN input")
        inst.slave.setReal([u.vr], good)
        require(status_of(_step(inst, ctx.start, ctx.step)) == 0,
                "no step after the discarded one")
    return f"{u.name} = nan: fmi3Discard, then the step works"


def check_state_refusal(ctx: Context) -> str:
    _fmi3_only(ctx)
    start, h = ctx.start, ctx.step
    outputs = [v.vr for v in _reals(ctx.outputs)]
    runs = []
    for corrupt in (False, True):
        with ctx.instantiate("check") as inst:
            s = inst.slave
            initialize(ctx, inst)
            require(status_of(_step(inst, start, h)) == 0, "first step failed")
            if corrupt:
                blob = bytearray(s.serializeFMUstate(s.getFMUstate()))
                blob[-2] ^= 0xFF
                before = len(inst.messages)
                state = s.deSerializeFMUstate(bytes(blob))
                require(status_of(lambda: s.setFMUstate(state)) != _FATAL,
                        "fmi3SetFMUState of corrupt bytes: fmi3Fatal")
                logged = " ".join(m.message for m in inst.messages[before:])
                require("refused" in logged, f"corrupt state not refused in the log ({logged!r})")
            require(status_of(_step(inst, start + h, h)) == 0, "the step after failed")
            runs.append(s.getReal(outputs))
    require(runs[0] == runs[1], "the instance changed after a refused state")
    return "corrupt serialized state refused (logged), the instance unchanged"
