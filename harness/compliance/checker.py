"""``dronefly check``: a co-simulation compliance suite for FMI 2.0 and FMI 3.0 FMUs.

FMI 3.0 FMUs run the same checks through fmpy's FMU3Slave, plus those of :mod:`.fmi3checks`.

Checks, each reported as passed or failed with a reason:

* ``validate``: fmpy's validation (XSD schema, names, causality/variability/initial
  combinations, units, ModelStructure): no problems.
* ``call-sequence``: instantiate, setupExperiment, initialization, steps to the
  default experiment's stop time, terminate, free (all statuses OK).
* ``reset``: fmi2Reset and a second run give the same result, bit for bit.
* ``two-instances``: two instances stepped side by side give the single run's result.
* ``state``: get/set FMU state and serialize/deserialize round trips reproduce the
  continuation bit for bit.
* ``bad-input``: a NaN on every input, a non-positive step size and a communication
  point that does not continue are refused (fmi2Discard) with a logged message
  naming the value, and the next valid step works.
* ``reference``: for the project's FMUs, the FMI cross-check reference result.
* ``fuzz``: a short run of the fuzz (:mod:`.fuzz`: bad values, the call-sequence table,
  corrupt states, printf characters, random calls, instance churn; logging on and off): no
  crash, no fmi2Fatal, and for the project's FMUs every refusal logged and harmless.

The checks run in this process; :mod:`.suite` runs them in a child process (so a crashing
FMU is a failed check) and adds the fuzz.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from dronefly.harness.cosim.fmu import FMU, FMUError, Instance

__all__ = ["CHECK_NAMES", "CheckResult", "FMUReport", "run_checks"]


@dataclass(frozen=True)
class CheckResult:
    name: str
    passed: bool
    detail: str = ""


@dataclass
class FMUReport:
    path: Path
    checks: list[CheckResult] = field(default_factory=list)
    output: str = ""  # what the FMU's binaries printed while being checked

    @property
    def passed(self) -> bool:
        return bool(self.checks) and all(c.passed for c in self.checks)


class _CheckFailed(AssertionError):
    pass


def _require(cond: bool, msg: str) -> None:
    if not cond:
        raise _CheckFailed(msg)


def _experiment(fmu: FMU) -> tuple[float, float, float]:
    de = fmu.model_description.defaultExperiment
    start = float(de.startTime) if de is not None and de.startTime is not None else 0.0
    stop = float(de.stopTime) if de is not None and de.stopTime is not None else start + 1.0
    step = (float(de.stepSize) if de is not None and de.stepSize is not None
            else (stop - start) / 100)
    return start, stop, step


def _init(inst: Instance, start: float, stop: float) -> None:
    s = inst.slave
    s.setupExperiment(startTime=start, stopTime=stop)
    s.enterInitializationMode()
    s.exitInitializationMode()


def _outputs(inst: Instance) -> list[float]:
    return inst.slave.getReal(inst.vrs(_real_outputs(inst.fmu)))


def _real_outputs(fmu: FMU) -> list[str]:
    return [v.name for v in fmu.model_description.modelVariables
            if v.causality == "output" and v.type == "Real"]


def _real_inputs(fmu: FMU) -> list[str]:
    return [v.name for v in fmu.model_description.modelVariables
            if v.causality == "input" and v.type == "Real"]


def _excite(inst: Instance, k: int) -> None:
    """Inputs at step k: 0.01 sin(0.3 k + j) for input j."""
    in_vr = inst.vrs(_real_inputs(inst.fmu))
    if in_vr:
        inst.slave.setReal(in_vr, [0.01 * math.sin(0.3 * k + j) for j in range(len(in_vr))])


def _run(inst: Instance, start: float, stop: float, step: float,
         steps: range | None = None) -> np.ndarray:
    """Step from ``start`` and record the Real outputs at every communication point.

    The inputs follow a fixed small excitation (:func:`_excite`), so that every
    comparison below compares a non-trivial trajectory.
    """
    n = int(round((stop - start) / step))
    rows = [_outputs(inst)]
    for k in steps if steps is not None else range(n):
        _excite(inst, k)
        inst.slave.doStep(currentCommunicationPoint=start + k * step, communicationStepSize=step)
        rows.append(_outputs(inst))
    return np.array(rows)


def _check_validate(fmu: FMU) -> str:
    from fmpy.validation import validate_fmu

    problems = validate_fmu(str(fmu.path))
    _require(not problems, "; ".join(problems[:5]) + (" ..." if len(problems) > 5 else ""))
    return "no problems"


def _whole_run(inst: Instance, fmu: FMU) -> np.ndarray:
    """Initialize, run the default experiment, terminate: the recorded outputs."""
    start, stop, step = _experiment(fmu)
    _init(inst, start, stop)
    data = _run(inst, start, stop, step)
    inst.slave.terminate()
    return data


def _check_call_sequence(fmu: FMU) -> str:
    with fmu.instantiate("check") as inst:
        data = _whole_run(inst, fmu)
    _require(bool(np.isfinite(data).all()), "non-finite outputs")
    _require(float(np.ptp(data)) > 0.0, "outputs do not respond to the inputs")
    _, stop, step = _experiment(fmu)
    return f"{len(data) - 1} steps of {step:.6g} s to {stop:.6g} s"


def _check_reset(fmu: FMU) -> str:
    with fmu.instantiate("check") as inst:
        first = _whole_run(inst, fmu)
        inst.slave.reset()
        second = _whole_run(inst, fmu)
    reset = f"fmi{fmu.fmi_version}Reset"
    _require(np.array_equal(first, second), f"the run after {reset} differs")
    return f"identical after {reset}"


def _check_two_instances(fmu: FMU) -> str:
    start, stop, step = _experiment(fmu)
    n = int(round((stop - start) / step))
    with fmu.instantiate("single") as one:
        _init(one, start, stop)
        ref = _run(one, start, stop, step)
    with fmu.instantiate("left") as a, fmu.instantiate("right") as b:
        _init(a, start, stop)
        _init(b, start, stop)
        ra, rb = [_outputs(a)], [_outputs(b)]
        for k in range(n):
            for inst, rec in ((a, ra), (b, rb)):
                _excite(inst, k)
                inst.slave.doStep(currentCommunicationPoint=start + k * step,
                                  communicationStepSize=step)
                rec.append(_outputs(inst))
    _require(np.array_equal(np.array(ra), ref) and np.array_equal(np.array(rb), ref),
             "interleaved instances differ from a single run")
    return "independent"


def _check_state(fmu: FMU) -> str:
    cs = fmu.model_description.coSimulation
    if not (cs.canGetAndSetFMUstate and cs.canSerializeFMUstate):
        return "not declared (canGetAndSetFMUstate/canSerializeFMUstate false): not applicable"
    start, stop, step = _experiment(fmu)
    n = int(round((stop - start) / step))
    half = n // 2
    with fmu.instantiate("check") as inst:
        s = inst.slave
        _init(inst, start, stop)
        _run(inst, start, stop, step, range(half))
        state = s.getFMUstate()
        blob = s.serializeFMUstate(state)
        cont = _run(inst, start, stop, step, range(half, n))
        s.setFMUstate(state)
        again = _run(inst, start, stop, step, range(half, n))
        restored = s.deSerializeFMUstate(blob)
        s.setFMUstate(restored)
        third = _run(inst, start, stop, step, range(half, n))
        s.freeFMUstate(restored)
        s.freeFMUstate(state)
    _require(np.array_equal(cont, again), "continuation after fmi2SetFMUstate differs")
    _require(np.array_equal(cont, third), "continuation after fmi2DeSerializeFMUstate differs")
    return f"bit-for-bit continuation from t = {start + half * step:.6g} s ({len(blob)} bytes)"


def _expect_discard(inst: Instance, t: float, h: float, fragment: str, named: bool = True) -> None:
    from fmpy.fmi1 import FMICallException

    before = len(inst.messages)
    try:
        inst.slave.doStep(currentCommunicationPoint=t, communicationStepSize=h)
    except FMICallException as e:
        _require(e.status in (2, 3), f"{fragment}: doStep returned status {e.status}")
    else:
        raise _CheckFailed(f"{fragment}: doStep returned OK")
    if named:
        logged = " ".join(m.message for m in inst.messages[before:])
        _require(fragment in logged, f"{fragment}: not named in the log ({logged!r})")


def _check_bad_input(fmu: FMU) -> str:
    start, stop, step = _experiment(fmu)
    inputs = _real_inputs(fmu)
    # Messages that name the value are this project's requirement of its own FMU code; a
    # wrapper made by other tools (fmpy's container binary) is held to the FMI statuses only.
    named = (fmu.model_description.generationTool or "").startswith("dronefly-fmu")
    cases = 0
    with fmu.instantiate("check") as inst:
        s = inst.slave
        _init(inst, start, stop)
        t = start
        for name in inputs:
            vr = [fmu.vr(name)]
            good = s.getReal(vr)
            s.setReal(vr, [math.nan])
            _expect_discard(inst, t, step, f"{name} = nan", named)
            s.setReal(vr, good)
            s.doStep(currentCommunicationPoint=t, communicationStepSize=step)
            t += step
            cases += 1
        for h, what in ((0.0, "communicationStepSize = 0.0"), (-step, f"communicationStepSize = {-step!r}")):
            _expect_discard(inst, t, h, what, named)
            cases += 1
        _expect_discard(inst, t + 10 * step, step, f"currentCommunicationPoint = {t + 10 * step!r}",
                        named)
        cases += 1
        s.doStep(currentCommunicationPoint=t, communicationStepSize=step)
    how = "with a logged message naming the value" if named else "(messages not checked: not our code)"
    return f"{cases} cases refused {how}; the instance recovered"


def _check_reference(fmu: FMU) -> str:
    from dronefly.harness.compliance.reference import REFERENCES, check_reference

    if fmu.name not in REFERENCES:
        return "no reference result for this model (skipped)"
    r = check_reference(fmu.name, fmu.path)
    _require(r.passed, f"{r.cross_check_outliers:.1%} outliers, max relative error "
                       f"{r.max_rel_error:.2e}")
    return f"cross-check: no outliers, max relative error {r.max_rel_error:.1e}"


_CHECKS: list[tuple[str, Callable[[FMU], str]]] = [
    ("validate", _check_validate),
    ("call-sequence", _check_call_sequence),
    ("reset", _check_reset),
    ("two-instances", _check_two_instances),
    ("state", _check_state),
    ("bad-input", _check_bad_input),
    ("reference", _check_reference),
]
CHECK_NAMES = tuple(name for name, _ in _CHECKS)  # in order; FMI 3.0 adds fmi3checks' too


def run_checks(path: Path, progress: Callable[[dict], None] | None = None) -> FMUReport:
    """Every check of this module on one FMU, in this process; ``progress`` is called with
    ``{"begin": name}`` before and the result (as a dict) after each check."""
    report = FMUReport(path)
    try:
        fmu = FMU(path)
    except FMUError as e:
        report.checks.append(CheckResult("load", False, str(e)))
        if progress:
            progress(asdict(report.checks[-1]))
        return report
    from dronefly.harness.compliance.fmi3checks import FMI3_CHECKS

    with fmu:
        for name, fn in _CHECKS + (FMI3_CHECKS if fmu.fmi_version == 3 else []):
            if progress:
                progress({"begin": name})
            try:
                result = CheckResult(name, True, fn(fmu))
            except AssertionError as e:  # _CheckFailed, Fmi3CheckFailed
                result = CheckResult(name, False, str(e))
            except Exception as e:  # an FMI call failed: that is a finding, not a crash
                result = CheckResult(name, False, f"{type(e).__name__}: {e}")
            report.checks.append(result)
            if progress:
                progress(asdict(result))
    return report
