"""``dronefly check``: a co-simulation compliance suite for FMI 2.0 and FMI 3.0 FMUs.

Each check enforces one rule of the FMI standard and names it (:data:`RULES`: the rule and
its section of FMI 2.0 and of FMI 3.0). A check is run under a *profile*:

* ``standard``: the FMI standard alone; the default for any FMU that dronefly did not
  write. Where the standard leaves the FMU free (what it does with a NaN input, the wording
  of its log, whether it detects corrupt serialized state), nothing is demanded.
* ``dronefly``: the stricter promises of the project's own FMUs (a NaN input refused with
  Discard and a logged message naming the value; every refusal logged in our wording; the
  instance continues after a refused step; corrupt states refused; outputs that respond to
  the inputs; the fuzz), with the standard's other checks. Chosen automatically for FMUs
  whose ``generationTool`` is dronefly's.

Checks (FMI 3.0 FMUs run the same ones through fmpy's FMU3Slave, plus those of
:mod:`.fmi3checks`):

* ``validate``: fmpy's validation (schema, names, combinations, units, ModelStructure).
* ``call-sequence``: instantiate, initialize, step to the stop time, terminate, free; a run
  the FMU ends itself (fmi2Discard with fmi2Terminated, or fmi3DoStep's terminateSimulation /
  earlyReturn) ends there, cleanly. A non-finite output returned with OK is a warning.
* ``start-values``: every variable with initial="exact" holds its declared start value after
  initialization (nothing was set).
* ``dependencies``: in Initialization Mode, an output declared (InitialUnknowns) without a
  dependency on an input does not change when only that input is set; a declared dependency
  never seen is a warning. (Step Mode forbids a get after a set without a step.)
* ``reset``: a run after fmi2Reset / fmi3Reset equals the first run, bit for bit.
* ``two-instances``: two instances stepped side by side give the single run's result.
* ``state``: where declared, get/set and serialize/deserialize of the FMU state reproduce the
  continuation bit for bit.
* ``bad-input``: a non-positive step size and a communication point that does not continue
  (standard: not Fatal, OK is a warning, FMI 3.0 asks fmi3Error with a logged message for an
  illegal argument it detects; then fmi2Reset / fmi3Reset recovers the instance, the only
  call allowed after Error; dronefly: Discard with a message naming the value, a NaN input
  too, and the instance continues).
* ``reference``: for the project's FMUs (dronefly profile), the FMI cross-check reference
  result.
* ``logger-format``: FMI 2.0: printf directives in the instance name do not crash a
  printf-style logger.

A check returns its detail line, raises :class:`CheckSkipped` (not applicable) or fails
(``AssertionError`` or an FMI call that raised). The checks run in this process;
:mod:`.suite` runs them in a child process (so a crashing FMU is a failed check) and adds
the fuzz.
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any, Callable, Iterator

import numpy as np
from fmpy.fmi1 import FMICallException
from fmpy.validation import validate_fmu

from ...core.interrupt import pending
from ..cosim.fmu import FMU, FMUError, Instance
from .fmi3checks import FMI3_CHECKS, FMI3_PROFILES, FMI3_RULES
from .fuzzkit import status_of
from .reference import REFERENCES, check_reference

__all__ = ["CHECK_NAMES", "PROFILES", "RULES", "CheckOptions", "CheckResult", "CheckSkipped",
           "FMUReport", "experiment", "profile_for", "rule_of", "run_checks"]

#: the profiles a check can run under (see the module text)
PROFILES = ("standard", "dronefly")

#: the rule each check enforces: ``{name: (FMI 2.0 rule, FMI 3.0 rule, dronefly profile's
#: stricter promise or "")}``
RULES: dict[str, tuple[str, str, str]] = {
    "validate": (
        "FMI 2.0 2.2 (FMI Description Schema): modelDescription.xml is schema-valid and "
        "consistent (2.2.7 causality/variability/initial, 2.2.8 ModelStructure)",
        "FMI 3.0 2.4 (FMI Description Schema): modelDescription.xml is schema-valid and "
        "consistent", ""),
    "call-sequence": (
        "FMI 2.0 4.2.4 (state machine of the calling sequence): instantiate, initialize, "
        "fmi2DoStep to the stop time, terminate, free succeed; 4.2.3: a slave may end the run "
        "(fmi2Discard with fmi2Terminated)",
        "FMI 3.0 4.2 (fmi3DoStep): the calling sequence succeeds; terminateSimulation and "
        "earlyReturn end the run", "outputs are finite and respond to the inputs"),
    "start-values": (
        "FMI 2.0 2.2.7 (initial = \"exact\"): the variable is initialized with its start value",
        "FMI 3.0 2.4.7 (initial = \"exact\"): the variable is initialized with its start value",
        ""),
    "dependencies": (
        "FMI 2.0 2.2.8 (ModelStructure InitialUnknowns dependencies): in Initialization Mode "
        "an output depends only on the inputs listed (\"\": on none); tested there because "
        "4.2.4 forbids a get after a set without a step in Step Mode",
        "FMI 3.0 2.4.8 (ModelStructure InitialUnknown dependencies): in Initialization Mode an "
        "output depends only on the inputs listed; tested there because Step Mode forbids a "
        "get after a set without a step", ""),
    "reset": (
        "FMI 2.0 2.1.6 (fmi2Reset): the FMU goes into the same state as after fmi2Instantiate",
        "FMI 3.0 2.3 (FMU states, fmi3Reset): the FMU goes into the same state as after "
        "instantiation", ""),
    "two-instances": (
        "FMI 2.0 2.1.5 (fmi2Instantiate): instances are independent unless "
        "canBeInstantiatedOnlyOncePerProcess",
        "FMI 3.0 (fmi3Instantiate*): instances are independent unless "
        "canBeInstantiatedOnlyOncePerProcess", ""),
    "state": (
        "FMI 2.0 2.1.8 (Getting and Setting the Complete FMU State): a restored state "
        "continues as the original did",
        "FMI 3.0 2.2.6.4 (Getting and Setting the Complete FMU State): a restored state "
        "continues as the original did", ""),
    "bad-input": (
        "FMI 2.0 4.2.2 (fmi2DoStep: communicationStepSize > 0, the communication point "
        "continues the last) and 2.1.3 (after fmi2Error only fmi2Reset, fmi2FreeInstance or "
        "fmi2SetFMUstate)",
        "FMI 3.0 4.2 (fmi3DoStep arguments) and 2.2.4 (after fmi3Error only fmi3Reset, "
        "fmi3FreeInstance or fmi3SetFMUState)",
        "a NaN input and bad arguments answered Discard with a logged message naming the value; "
        "the instance continues"),
    "reference": (
        "FMI cross-check rules (the project's FMUs: reference results)",
        "FMI cross-check rules (the project's FMUs: reference results)", ""),
    "logger-format": (
        "FMI 2.0 2.1.5 (fmi2CallbackLogger): message is a printf format string, so text the "
        "FMU does not mean as a directive (an instance name with %) must reach it escaped (%%)",
        "FMI 3.0 (fmi3LogMessageCallback): message is plain text, no format: not applicable",
        ""),
}
CHECK_NAMES = tuple(RULES)  # in order; FMI 3.0 adds fmi3checks' too

_FMI2_TERMINATED = 3  # fmi2StatusKind fmi2Terminated
_FMI2_LAST_SUCCESSFUL_TIME = 2  # fmi2StatusKind fmi2LastSuccessfulTime


@dataclass(frozen=True)
class CheckResult:
    """One check on one FMU: passed, failed or skipped (``skipped`` implies ``passed``)."""

    name: str
    passed: bool
    detail: str = ""
    rule: str = ""
    skipped: bool = False
    warning: str = ""
    duration_s: float = 0.0

    @property
    def status(self) -> str:
        """``"passed"``, ``"failed"`` or ``"skipped"``."""
        return "skipped" if self.skipped else "passed" if self.passed else "failed"


@dataclass(frozen=True)
class CheckOptions:
    """What to check and how.

    Parameters
    ----------
    profile : {None, "standard", "dronefly"}
        None: ``"dronefly"`` for the project's FMUs, ``"standard"`` for any other.
    stop_time, step : float or None
        The run's stop time and communication step (s); None: the default experiment's.
    only, skip : tuple of str
        Run only these checks / not these (names of :data:`CHECK_NAMES`, the FMI 3.0 ones,
        ``fuzz``).
    """

    profile: str | None = None
    stop_time: float | None = None
    step: float | None = None
    only: tuple[str, ...] = ()
    skip: tuple[str, ...] = ()

    def wants(self, name: str) -> bool:
        """Whether check ``name`` is selected."""
        return (not self.only or name in self.only) and name not in self.skip


@dataclass
class FMUReport:
    path: Path
    checks: list[CheckResult] = field(default_factory=list)
    output: str = ""  # what the FMU's binaries printed while being checked
    profile: str = ""
    skipped: str = ""  # why the FMU was not checked at all
    duration_s: float = 0.0

    @property
    def passed(self) -> bool:
        """No check failed, and something was checked (or the FMU was skipped with a reason)."""
        if self.skipped:
            return all(c.passed for c in self.checks)
        return bool(self.checks) and all(c.passed for c in self.checks)


class CheckSkipped(Exception):
    """A check does not apply to this FMU (the message says why)."""


class _CheckFailed(AssertionError):
    pass


def _require(cond: bool, msg: str) -> None:
    if not cond:
        raise _CheckFailed(msg)


def profile_for(fmu: FMU) -> str:
    """The default profile of an FMU: ``"dronefly"`` if dronefly generated it."""
    tool = fmu.model_description.generationTool or ""
    return "dronefly" if tool.startswith("dronefly-fmu") else "standard"


# -- the run ---------------------------------------------------------------------------------
_KINDS = {"Real": "Real", "Integer": "Integer", "Enumeration": "Integer", "Boolean": "Boolean",
          **{t: "Integer" for t in ("Int8", "UInt8", "Int16", "UInt16", "Int32", "UInt32",
                                    "Int64", "UInt64")}}


@dataclass(frozen=True)
class _Var:
    name: str
    kind: str  # Real, Integer, Boolean
    vr: int
    var: Any


class _Context:
    """One FMU under one profile: its experiment, variables, instances and the call log."""

    def __init__(self, fmu: FMU, options: CheckOptions,
                 on_event: Callable[[dict], None] | None) -> None:
        self.fmu = fmu
        self.options = options
        self.profile = options.profile or profile_for(fmu)
        self.on_event = on_event
        self.warnings: list[str] = []
        self.instances: list[Instance] = []
        self.fatal: str | None = None  # the check in which the FMU returned Fatal
        self.fmi = f"fmi{fmu.fmi_version}"
        self.start, self.stop, self.step, self.n = experiment(fmu.model_description, options)
        vs = [v for v in fmu.model_description.modelVariables if v.type in _KINDS]
        self.inputs = [_Var(v.name, _KINDS[v.type], v.valueReference, v) for v in vs
                       if v.causality == "input"]
        self.outputs = [_Var(v.name, _KINDS[v.type], v.valueReference, v) for v in vs
                        if v.causality == "output"]
        self.read_outputs = _reader(self.outputs)
        self.real_inputs = [v for v in self.inputs if v.kind == "Real"]
        self.input_base = [float(v.var.start) if v.var.start is not None else 0.0
                            for v in self.real_inputs]

    @property
    def ours(self) -> bool:
        return self.profile == "dronefly"

    def event(self, **row: Any) -> None:
        if self.on_event is not None:
            self.on_event(row)

    def instantiate(self, name: str) -> Instance:
        self.event(call=f"{self.fmi}Instantiate(instanceName={name!r})")
        inst = self.fmu.instantiate(name)
        if self.on_event is not None:
            inst.messages = _Tee(inst.messages, self.on_event)
        self.instances.append(inst)
        return inst

    def log_tail(self, k: int = 3) -> str:
        """The last ``k`` messages the FMU logged (those above OK first)."""
        msgs = [m for i in self.instances for m in getattr(i, "messages", ())]
        # after a Fatal the FMU may have corrupted what it delivered (pythonfmu frees its
        # objects and goes on using them): each message is read on its own, none hides the rest
        status = [getattr(m, "status", None) for m in msgs]
        bad = [m for m, st in zip(msgs, status) if not isinstance(st, int) or st > 0] or msgs
        return "; ".join(f"{getattr(m, 'category', '') or 'log'}: "
                         f"{str(getattr(m, 'message', '')).strip()}" for m in bad[-k:])


def experiment(md: Any, options: CheckOptions) -> tuple[float, float, float, int]:
    """The run the checks make: start, stop and step (s), and the number of whole steps
    that end at or before the stop time (never past it: FMI 2.0 4.2.2).

    ``options.stop_time`` / ``options.step`` replace the default experiment's (of the model
    description ``md``). Raises :class:`FMUError` naming the values if the run has no step:
    the caller says whose values they are (the user's options: bad input; the FMU's default
    experiment: a failed check).
    """
    de = md.defaultExperiment
    start = float(de.startTime) if de is not None and de.startTime is not None else 0.0
    stop = (options.stop_time if options.stop_time is not None
            else float(de.stopTime) if de is not None and de.stopTime is not None
            else start + 1.0)
    if stop <= start:
        raise FMUError(f"stop time {float(stop)!r} s is not after the start time "
                       f"{float(start)!r} s")
    step = (options.step if options.step is not None
            else float(de.stepSize) if de is not None and de.stepSize is not None
            else (stop - start) / 100)
    n = int(math.floor((stop - start) / step * (1 + 1e-12)))
    if n < 1:
        raise FMUError(f"step {float(step)!r} s is longer than the run from {float(start)!r} s "
                       f"to {float(stop)!r} s")
    return start, stop, step, n


class _Tee(list):
    """The messages of an instance, each also passed on as it arrives (the child's log)."""

    def __init__(self, items: list, sink: Callable[[dict], None]) -> None:
        super().__init__(items)
        self._sink = sink

    def append(self, m: Any) -> None:
        super().append(m)
        self._sink({"log": f"[{m.status}] {m.category}: {m.message}"[:500]})


def _init(ctx: _Context, inst: Instance) -> None:
    s = inst.slave
    ctx.event(call=f"{ctx.fmi}EnterInitializationMode(startTime={ctx.start!r}, "
                   f"stopTime={ctx.stop!r})")
    s.setupExperiment(startTime=ctx.start, stopTime=ctx.stop)
    s.enterInitializationMode()
    s.exitInitializationMode()


def _named(vars_: list[_Var]) -> str:
    shown = ", ".join(f"{v.name} (value reference {v.vr})" for v in vars_[:4])
    return shown + (f" and {len(vars_) - 4} more" if len(vars_) > 4 else "")


def _reader(vars_: list[_Var]) -> Callable[[Instance], list[float]]:
    """A function reading the values of ``vars_`` from an instance (each kind with its own
    get call) as floats; a refused get fails naming the variables."""

    groups = []
    for kind, getter in (("Real", "getReal"), ("Integer", "getInteger"),
                         ("Boolean", "getBoolean")):
        idx = [k for k, v in enumerate(vars_) if v.kind == kind]
        if idx:
            groups.append((getter, idx, [vars_[k].vr for k in idx]))
    if len(groups) == 1 and groups[0][0] == "getReal" and len(groups[0][1]) == len(vars_):
        vrs = groups[0][2]

        def read_reals(inst: Instance) -> list[float]:
            try:
                return inst.slave.getReal(vrs)
            except FMICallException as e:
                raise _CheckFailed(f"{str(e).rstrip('.')} reading {_named(vars_)}") from None

        return read_reals

    def read(inst: Instance) -> list[float]:
        out = [0.0] * len(vars_)
        for getter, idx, vrs in groups:
            try:
                got = getattr(inst.slave, getter)(vrs)
            except FMICallException as e:
                raise _CheckFailed(f"{str(e).rstrip('.')} reading "
                                   f"{_named([vars_[k] for k in idx])}") from None
            for k, x in zip(idx, got):
                out[k] = float(x)
        return out

    return read


def _read(inst: Instance, vars_: list[_Var]) -> list[float]:
    """The values of ``vars_`` now (see :func:`_reader`)."""
    return _reader(vars_)(inst)


def _write(inst: Instance, var: _Var, value: float) -> None:
    s = inst.slave
    try:
        if var.kind == "Real":
            s.setReal([var.vr], [float(value)])
        elif var.kind == "Integer":
            s.setInteger([var.vr], [int(value)])
        else:
            s.setBoolean([var.vr], [bool(value)])
    except FMICallException as e:
        raise _CheckFailed(f"{str(e).rstrip('.')} setting {_named([var])} = {value!r}") from None


def _bounded(var: _Var, x: float) -> float:
    lo = getattr(var.var, "min", None)
    hi = getattr(var.var, "max", None)
    if lo is not None:
        x = max(x, float(lo))
    if hi is not None:
        x = min(x, float(hi))
    return x


def _excite(ctx: _Context, inst: Instance, k: int) -> None:
    """Real inputs at step k: start + 0.01 sin(0.3 k + j) for input j, within min/max."""
    real = ctx.real_inputs
    if real:
        inst.slave.setReal([v.vr for v in real],
                           [_bounded(v, b + 0.01 * math.sin(0.3 * k + j))
                            for j, (v, b) in enumerate(zip(real, ctx.input_base))])


def _do_step(ctx: _Context, inst: Instance, t: float, h: float) -> bool:
    """One step; True if the FMU ended the run (terminate requested, early return)."""

    if ctx.on_event is not None:
        ctx.on_event({"call": f"{ctx.fmi}DoStep(currentCommunicationPoint={t!r}, "
                              f"communicationStepSize={h!r})"})
    s = inst.slave
    if ctx.fmu.fmi_version == 3:
        _, terminate, early, _ = s.doStep(currentCommunicationPoint=t, communicationStepSize=h)
        return bool(terminate or early)
    try:
        s.doStep(currentCommunicationPoint=t, communicationStepSize=h)
    except FMICallException as e:
        # fmi2Discard with fmi2Terminated after some progress: the FMU ended the run (FMI
        # 2.0 4.2.3); without progress it is a refused step (pythonfmu 0.7.0 says
        # "terminated" after every Discard)
        if e.status == 2 and s.getBooleanStatus(_FMI2_TERMINATED) and \
                s.getRealStatus(_FMI2_LAST_SUCCESSFUL_TIME) > t:
            return True
        raise
    return False


@dataclass
class _Run:
    rows: np.ndarray
    ended_at: float | None  # the time the FMU ended the run at, if it did


def _run(ctx: _Context, inst: Instance, steps: range | None = None) -> _Run:
    """Step on the grid start + k step, recording every output after each step; the
    inputs follow :func:`_excite`."""
    read = ctx.read_outputs
    rows = [read(inst)]
    for k in steps if steps is not None else range(ctx.n):
        _excite(ctx, inst, k)
        t = ctx.start + k * ctx.step
        ended = _do_step(ctx, inst, t, ctx.step)
        rows.append(read(inst))
        if ended:
            return _Run(np.array(rows), t + ctx.step)
    return _Run(np.array(rows), None)


def _whole_run(ctx: _Context, inst: Instance) -> _Run:
    _init(ctx, inst)
    run = _run(ctx, inst)
    ctx.event(call=f"{ctx.fmi}Terminate()")
    inst.slave.terminate()
    return run


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    return a.shape == b.shape and bool(np.array_equal(a, b, equal_nan=True))


# -- the checks ------------------------------------------------------------------------------
def _check_validate(ctx: _Context) -> str:
    problems = validate_fmu(str(ctx.fmu.path))
    _require(not problems, "; ".join(problems[:5]) + (" ..." if len(problems) > 5 else ""))
    return "no problems"


def _check_call_sequence(ctx: _Context) -> str:
    with ctx.instantiate("check") as inst:
        run = _whole_run(ctx, inst)
    data = run.rows
    bad = [v.name for j, v in enumerate(ctx.outputs) if not np.isfinite(data[:, j]).all()]
    if bad:
        msg = f"non-finite values returned with OK: {', '.join(bad[:5])}"
        _require(not ctx.ours, msg)
        ctx.warnings.append(msg)
    if ctx.ours and ctx.outputs:
        _require(float(np.ptp(data)) > 0.0, "outputs do not respond to the inputs")
    steps = len(data) - 1
    if run.ended_at is not None:
        return (f"{steps} steps of {ctx.step:.6g} s; the FMU ended the run at "
                f"t = {run.ended_at:.6g} s (before the stop time {ctx.stop:.6g} s)")
    end = ctx.start + steps * ctx.step
    short = ("" if end >= ctx.stop * (1 - 1e-12) - 1e-300 else
             f" (the stop time {ctx.stop:.6g} s is not a whole number of steps)")
    return f"{steps} steps of {ctx.step:.6g} s to {end:.6g} s{short}"


def _exact(ctx: _Context) -> list[tuple[_Var, float, bool]]:
    """(variable, declared start, is Float32) of every variable with initial exact."""
    md3 = ctx.fmu.model_description3
    f32 = ({v.valueReference for v in md3.modelVariables if v.type == "Float32"}
           if md3 is not None else set())
    out = []
    for v in ctx.fmu.model_description.modelVariables:
        if v.type not in _KINDS or v.start is None or v.causality == "independent":
            continue
        initial = v.initial or ("exact" if v.variability == "constant" else None)
        if initial != "exact" or v.type == "Enumeration" and not str(v.start).strip():
            continue
        text = str(v.start).strip()
        if _KINDS[v.type] == "Boolean":
            value = 1.0 if text in ("true", "1") else 0.0
        else:
            value = float(text)
        element = ctx.fmu.elements.get(v.valueReference)
        base = element.array_vr if element else v.valueReference
        out.append((_Var(v.name, _KINDS[v.type], v.valueReference, v), value, base in f32))
    return out


def _check_start_values(ctx: _Context) -> str:
    exact = _exact(ctx)
    if not exact:
        raise CheckSkipped("no variable with initial=\"exact\"")
    with ctx.instantiate("check") as inst:
        _init(ctx, inst)
        held = _read(inst, [v for v, _, _ in exact])
    wrong = []
    for (v, declared, f32), x in zip(exact, held):
        # the declared text and the value the FMU holds differ at most by the writer's
        # decimal-to-binary rounding: a few ulp of a double, or one of a Float32
        tol = 1e-6 if f32 else 4 * np.finfo(float).eps
        if not (x == declared or abs(x - declared) <= tol * abs(declared)):
            wrong.append(f"{v.name}: declared start {declared!r}, holds {x!r}")
    _require(not wrong, "; ".join(wrong[:5]) + (" ..." if len(wrong) > 5 else ""))
    return f"{len(exact)} variable(s) with initial=\"exact\" hold their start values"


def _declared(ctx: _Context) -> dict[str, set[str] | None]:
    """Output name (as in ``ctx.outputs``) -> the input names its initial value is declared
    to depend on (ModelStructure InitialUnknowns; None: not declared, on every one)."""
    md = ctx.fmu.model_description3 or ctx.fmu.model_description

    def members(name: str, pool: list[_Var]) -> list[str]:
        return [v.name for v in pool if v.name == name or v.name.startswith(name + "[")]

    out: dict[str, set[str] | None] = {}
    for unknown in md.initialUnknowns or []:
        deps = unknown.dependencies
        names = (None if deps is None else
                 {n for d in deps for n in members(d.name, ctx.inputs)})
        for o in members(unknown.variable.name, ctx.outputs):
            out[o] = names
    return out


def _perturbed(var: _Var, x: float) -> float | None:
    if var.kind == "Boolean":
        return 0.0 if x else 1.0
    if var.var.type == "Enumeration":
        return None
    for delta in (1.0, -1.0, 0.5, -0.5):
        y = _bounded(var, x + delta)
        if y != x:
            return y
    return None


#: the change of an output that counts as round-off, in units of its magnitude: an output that
#: does not depend on an input may still be computed through it (a + d - d, a mean of two
#: angles that both move by d) and differ in its last bits; a real dependency moves it by far
#: more when the input changes by a whole unit (:func:`_perturbed`)
_ROUND_OFF = 4 * sys.float_info.epsilon


def _moved(a: float, b: float) -> bool:
    """Whether an output read as ``a`` and then as ``b`` changed by more than round-off
    (integers and booleans: changed at all; NaN equals NaN; an infinity is a change)."""
    if a == b or (math.isnan(a) and math.isnan(b)):
        return False
    if not (math.isfinite(a) and math.isfinite(b)):
        return True
    return abs(a - b) > _ROUND_OFF * max(abs(a), abs(b))


def _check_dependencies(ctx: _Context) -> str:
    # In Initialization Mode the importer may set inputs and get outputs in any order, the FMU
    # evaluating its equations in between (FMI 2.0 4.2.4, FMI 3.0 Initialization Mode); in
    # Step Mode a get after a set without a step is not allowed, so the dependencies are
    # tested here, against the InitialUnknowns that declare them for these values.
    declared = _declared(ctx)
    if not ctx.inputs or not ctx.outputs:
        raise CheckSkipped("no inputs or no outputs")
    if not declared:
        raise CheckSkipped("no output among the ModelStructure InitialUnknowns")
    seen: dict[str, set[str]] = {o.name: set() for o in ctx.outputs}
    tried: set[str] = set()
    with ctx.instantiate("check") as inst:
        s = inst.slave
        ctx.event(call=f"{ctx.fmi}EnterInitializationMode(startTime={ctx.start!r})")
        s.setupExperiment(startTime=ctx.start, stopTime=ctx.stop)
        s.enterInitializationMode()
        outs = [o for o in ctx.outputs if o.name in declared]
        read = _reader(outs)
        before = read(inst)
        for u in ctx.inputs:
            x = _read(inst, [u])[0]
            p = _perturbed(u, x)
            if p is None:
                continue
            tried.add(u.name)
            _write(inst, u, p)
            after = read(inst)
            _write(inst, u, x)
            for o, a, b in zip(outs, before, after):
                if _moved(a, b):
                    seen[o.name].add(u.name)
        s.exitInitializationMode()
        s.terminate()
    lies, unseen = [], []
    for o, deps in declared.items():
        if deps is None:
            continue
        for u in sorted(seen.get(o, set()) - deps):
            what = "no dependency" if not deps else f"dependencies on {', '.join(sorted(deps))}"
            lies.append(f"{o} (declared with {what} among the inputs) changed when only {u} was "
                        "set, in Initialization Mode")
        unseen += [f"{o} on {u}" for u in sorted((deps & tried) - seen.get(o, set()))]
    _require(not lies, "; ".join(lies[:4]) + (" ..." if len(lies) > 4 else ""))
    if unseen:
        ctx.warnings.append("declared dependencies not seen (a dependency may be conditional, "
                            "e.g. on a gain that is zero): " + ", ".join(unseen[:6])
                            + (" ..." if len(unseen) > 6 else ""))
    n = sum(deps is not None for deps in declared.values())
    return (f"{n} output(s) with declared initial dependencies, {len(tried)} input(s) set one "
            "at a time in Initialization Mode: no undeclared dependency")


def _check_reset(ctx: _Context) -> str:
    with ctx.instantiate("check") as inst:
        first = _whole_run(ctx, inst)
        ctx.event(call=f"{ctx.fmi}Reset()")
        inst.slave.reset()
        second = _whole_run(ctx, inst)
    reset = f"{ctx.fmi}Reset"
    if first.ended_at != second.ended_at:
        def end(r: _Run) -> str:
            return f"t = {r.ended_at:.6g} s" if r.ended_at is not None else "the stop time"

        raise _CheckFailed(f"the run after {reset} differs from the first: the FMU ended it at "
                           f"{end(second)}, the first at {end(first)}")
    _require(_same(first.rows, second.rows), f"the run after {reset} differs from the first")
    return f"identical after {reset}"


def _check_two_instances(ctx: _Context) -> str:
    if ctx.fmu.model_description.coSimulation.canBeInstantiatedOnlyOncePerProcess:
        raise CheckSkipped("canBeInstantiatedOnlyOncePerProcess is declared")
    with ctx.instantiate("single") as one:
        _init(ctx, one)
        ref = _run(ctx, one).rows
    with ctx.instantiate("left") as a, ctx.instantiate("right") as b:
        _init(ctx, a)
        _init(ctx, b)
        ra, rb = [_read(a, ctx.outputs)], [_read(b, ctx.outputs)]
        ended = [False, False]
        for k in range(len(ref) - 1):
            for j, (inst, rec) in enumerate(((a, ra), (b, rb))):
                if not ended[j]:
                    _excite(ctx, inst, k)
                    ended[j] = _do_step(ctx, inst, ctx.start + k * ctx.step, ctx.step)
                    rec.append(_read(inst, ctx.outputs))
    _require(_same(np.array(ra), ref) and _same(np.array(rb), ref),
             "interleaved instances differ from a single run")
    return "independent"


def _check_state(ctx: _Context) -> str:
    cs = ctx.fmu.model_description.coSimulation
    if not cs.canGetAndSetFMUstate:
        raise CheckSkipped("canGetAndSetFMUstate is not declared")
    half = ctx.n // 2
    parts = []
    with ctx.instantiate("check") as inst:
        s = inst.slave
        _init(ctx, inst)
        if _run(ctx, inst, range(half)).ended_at is not None:
            raise CheckSkipped(f"the FMU ended the run before t = "
                               f"{ctx.start + half * ctx.step:.6g} s")
        state = s.getFMUstate()
        blob = s.serializeFMUstate(state) if cs.canSerializeFMUstate else None
        cont = _run(ctx, inst, range(half, ctx.n)).rows
        s.setFMUstate(state)
        again = _run(ctx, inst, range(half, ctx.n)).rows
        _require(_same(cont, again), f"continuation after {ctx.fmi}SetFMUstate differs")
        parts.append("get/set")
        if blob is not None:
            restored = s.deSerializeFMUstate(blob)
            s.setFMUstate(restored)
            third = _run(ctx, inst, range(half, ctx.n)).rows
            s.freeFMUstate(restored)
            _require(_same(cont, third),
                     f"continuation after {ctx.fmi}DeSerializeFMUstate differs")
            parts.append(f"serialized ({len(blob)} bytes)")
        s.freeFMUstate(state)
    return (f"bit-for-bit continuation from t = {ctx.start + half * ctx.step:.6g} s: "
            + ", ".join(parts))


_STATUS_NAMES = ("OK", "Warning", "Discard", "Error", "Fatal", "Pending")
#: the rule that forbids any call after Fatal, the checker's own calls included
_FATAL_RULE = {"fmi2": "FMI 2.0 2.1.3", "fmi3": "FMI 3.0 2.2.3"}


def _expect_discard(ctx: _Context, inst: Instance, t: float, h: float, fragment: str,
                    named: bool = True) -> None:
    before = len(inst.messages)
    ctx.event(call=f"{ctx.fmi}DoStep(currentCommunicationPoint={t!r}, "
                   f"communicationStepSize={h!r})")
    status = status_of(lambda: inst.slave.doStep(currentCommunicationPoint=t,
                                                  communicationStepSize=h))
    _require(status != 0, f"{fragment}: {ctx.fmi}DoStep returned OK")
    _require(status in (2, 3), f"{fragment}: {ctx.fmi}DoStep returned "
                               f"{ctx.fmi}{_STATUS_NAMES[status]}")
    if named:
        logged = " ".join(m.message for m in inst.messages[before:])
        _require(fragment in logged, f"{fragment}: not named in the log ({logged!r})")


def _bad_input_ours(ctx: _Context) -> str:
    # Messages that name the value are this project's requirement of its own FMU code; a
    # wrapper made by other tools (fmpy's container binary) is held to the statuses only.
    named = (ctx.fmu.model_description.generationTool or "").startswith("dronefly-fmu")
    cases = 0
    step = ctx.step
    with ctx.instantiate("check") as inst:
        s = inst.slave
        _init(ctx, inst)
        t = ctx.start
        for u in (v for v in ctx.inputs if v.kind == "Real"):
            good = s.getReal([u.vr])
            s.setReal([u.vr], [math.nan])
            _expect_discard(ctx, inst, t, step, f"{u.name} = nan", named)
            s.setReal([u.vr], good)
            _do_step(ctx, inst, t, step)
            t += step
            cases += 1
        for h in (0.0, -step):
            _expect_discard(ctx, inst, t, h, f"communicationStepSize = {h!r}", named)
            cases += 1
        _expect_discard(ctx, inst, t + 10 * step, step,
                        f"currentCommunicationPoint = {t + 10 * step!r}", named)
        cases += 1
        _do_step(ctx, inst, t, step)
    how = ("with a logged message naming the value" if named
           else "(messages not checked: not our code)")
    return f"{cases} cases refused {how}; the instance recovered"


def _bad_input_standard(ctx: _Context) -> str:
    cases = []
    with ctx.instantiate("check") as inst:
        s = inst.slave
        for what, t, h in (("communicationStepSize = 0.0", ctx.start, 0.0),
                           (f"communicationStepSize = {-ctx.step!r}", ctx.start, -ctx.step),
                           (f"currentCommunicationPoint = {ctx.start + 10 * ctx.step!r} (the "
                            f"last was {ctx.start!r})", ctx.start + 10 * ctx.step, ctx.step)):
            _init(ctx, inst)
            before = len(inst.messages)
            status = status_of(lambda: _do_step(ctx, inst, t, h))
            _require(status != 4, f"{what}: {ctx.fmi}DoStep returned Fatal")
            if status == 0:
                ctx.warnings.append(f"{what}: {ctx.fmi}DoStep returned OK")
            if ctx.fmu.fmi_version == 3 and status == 2:
                # FMI 3.0 2.2.4: "When detecting illegal arguments ... the FMU must return
                # fmi3Error" (our own FMUs answer Discard: the dronefly profile's promise)
                raise _CheckFailed(f"{what}: fmi3DoStep detected an illegal argument and "
                                   "returned fmi3Discard; FMI 3.0 2.2.4 requires fmi3Error")
            if ctx.fmu.fmi_version == 3 and status == 3:
                _require(len(inst.messages) > before,
                         f"{what}: fmi3Error without a logged message (FMI 3.0 2.2.4: the FMU "
                         "must call logMessage before returning fmi3Error, logging on)")
            cases.append(f"{what}: {_STATUS_NAMES[status]}")
            # after Error the standard allows only reset, free or setting a state
            ctx.event(call=f"{ctx.fmi}Reset()")
            try:
                s.reset()
            except FMICallException as e:
                raise _CheckFailed(f"{what}: {ctx.fmi}Reset after it returned "
                                   f"{ctx.fmi}{_STATUS_NAMES[e.status]}") from None
        _init(ctx, inst)
        _do_step(ctx, inst, ctx.start, ctx.step)
    return "; ".join(cases) + f"; {ctx.fmi}Reset recovered the instance"


def _check_bad_input(ctx: _Context) -> str:
    return _bad_input_ours(ctx) if ctx.ours else _bad_input_standard(ctx)


_PRINTF = "%s%s%s%s%n"


def _check_logger_format(ctx: _Context) -> str:
    if ctx.fmu.fmi_version != 2:
        raise CheckSkipped("FMI 3.0's log message is plain text, not a format")
    with ctx.instantiate(_PRINTF) as inst:
        s = inst.slave
        # calls that make an FMU log (an unknown value reference, a bad step size) with
        # printf directives in the instance name: a crash here is the finding; after each
        # refusal fmi2Reset (after fmi2Error nothing else is allowed)
        for what, call in ((f"fmi2GetReal(vr=[{2 ** 31 - 1}])", lambda: s.getReal([2 ** 31 - 1])),
                           ("fmi2DoStep(communicationStepSize=0.0)",
                            lambda: s.doStep(currentCommunicationPoint=ctx.start,
                                             communicationStepSize=0.0))):
            _init(ctx, inst)
            ctx.event(call=f"{what} of instance {_PRINTF!r}")
            if status_of(call) != 0:
                s.reset()
            else:
                s.terminate()
                s.reset()
    return (f"instance {_PRINTF!r}, {len(inst.messages)} messages logged through a printf-style "
            "logger, no crash")


def _check_reference(ctx: _Context) -> str:
    if not ctx.ours:
        raise CheckSkipped("reference results are the project's FMUs' (dronefly profile)")

    if ctx.fmu.name not in REFERENCES:
        raise CheckSkipped("no reference result for this model")
    r = check_reference(ctx.fmu.name, ctx.fmu.path)
    _require(r.passed, f"{r.cross_check_outliers:.1%} outliers, max relative error "
                       f"{r.max_rel_error:.2e}")
    return f"cross-check: no outliers, max relative error {r.max_rel_error:.1e}"


_CHECKS: list[tuple[str, Callable[[_Context], str]]] = [
    ("validate", _check_validate),
    ("call-sequence", _check_call_sequence),
    ("start-values", _check_start_values),
    ("dependencies", _check_dependencies),
    ("reset", _check_reset),
    ("two-instances", _check_two_instances),
    ("state", _check_state),
    ("bad-input", _check_bad_input),
    ("reference", _check_reference),
    ("logger-format", _check_logger_format),  # last: a crash leaves no other check out
]


def rule_of(name: str, fmi_version: int, profile: str) -> str:
    """The rule line of check ``name`` (with the dronefly profile's promise if it adds one)."""

    r2, r3, ours = {**RULES, **FMI3_RULES}.get(name, ("", "", ""))
    rule = r3 if fmi_version == 3 else r2
    return rule + (f"; dronefly profile: {ours}" if ours and profile == "dronefly" else "")


def _iter_checks(ctx: _Context) -> Iterator[tuple[str, Callable[[_Context], str]]]:
    for name, fn in _CHECKS:
        yield name, fn
    if ctx.fmu.fmi_version == 3:
        for name, fn in FMI3_CHECKS:
            if ctx.profile in FMI3_PROFILES[name]:
                yield name, (lambda c, fn=fn: fn(c.fmu, c))


def run_checks(path: Path, progress: Callable[[dict], None] | None = None,
               options: CheckOptions | None = None) -> FMUReport:
    """Every selected check on one FMU, in this process.

    ``progress`` is called with ``{"begin": name}`` before each check, the result (as a
    dict) after it, and, while it runs, ``{"call": ...}`` before each FMI call that may not
    return and ``{"log": ...}`` for each message the FMU logs.
    """
    options = options or CheckOptions()
    report = FMUReport(path)
    t0 = time.perf_counter()
    try:
        fmu = FMU(path)
    except FMUError as e:
        report.checks.append(CheckResult("load", False, str(e), rule="FMI 2.0 / 3.0 FMU archive"))
        if progress:
            progress(asdict(report.checks[-1]))
        return report
    with fmu:
        try:
            ctx = _Context(fmu, options, progress)
        except FMUError as e:  # the stop time and step asked for do not fit this FMU
            report.checks.append(CheckResult("experiment", False, str(e),
                                             rule="FMI 2.0 4.2.2 / FMI 3.0 4.2: steps within "
                                                  "the experiment"))
            if progress:
                progress(asdict(report.checks[-1]))
            return report
        report.profile = ctx.profile
        if progress:
            progress({"profile": ctx.profile})
        for name, fn in _iter_checks(ctx):
            if not options.wants(name):
                continue
            if pending():  # Ctrl-C between two checks (in-process runs)
                raise KeyboardInterrupt
            if progress:
                progress({"begin": name})
            result = _one(ctx, name, fn) if ctx.fatal is None else CheckResult(
                name, True, f"not run: the FMU returned {ctx.fmi}Fatal in {ctx.fatal}, after "
                f"which no function of any of its instances may be called ({_FATAL_RULE[ctx.fmi]})",
                rule_of(name, fmu.fmi_version, ctx.profile), skipped=True)
            report.checks.append(result)
            if progress:
                progress(asdict(result))
        ran = {c.name for c in report.checks}
        for name in options.only:  # selected by name, but not for this FMU: said why
            if name in ran or name == "fuzz" or not options.wants(name):
                continue
            why = (f"{name} is an FMI 3.0 check; this FMU is FMI 2.0" if fmu.fmi_version == 2
                   else f"{name} is the dronefly profile's check (--profile dronefly runs it); "
                        f"this FMU is checked under the {ctx.profile} profile")
            result = CheckResult(name, True, f"not applicable: {why}",
                                 rule_of(name, fmu.fmi_version, ctx.profile), skipped=True)
            report.checks.append(result)
            if progress:
                progress(asdict(result))
    report.duration_s = time.perf_counter() - t0
    return report


def _one(ctx: _Context, name: str, fn: Callable[[_Context], str]) -> CheckResult:
    ctx.warnings, ctx.instances = [], []
    rule = rule_of(name, ctx.fmu.fmi_version, ctx.profile)
    t0 = time.perf_counter()
    try:
        result = CheckResult(name, True, fn(ctx), rule)
    except CheckSkipped as e:
        result = CheckResult(name, True, f"not applicable: {e}", rule, skipped=True)
    except AssertionError as e:  # _CheckFailed, Fmi3CheckFailed
        result = CheckResult(name, False, str(e), rule)
    except Exception as e:  # an FMI call failed: that is a finding, not a crash
        result = CheckResult(name, False, f"{type(e).__name__}: {e}".rstrip("."), rule)
        if getattr(e, "status", None) == 4:
            ctx.fatal = name
    finally:
        for inst in ctx.instances if ctx.fatal is None else ():  # nothing after a Fatal
            try:
                inst.free()
            except Exception:
                pass
    if not result.passed:
        try:
            tail = ctx.log_tail()
        except Exception as e:  # after a Fatal the FMU may have corrupted the process
            tail = f"(its log cannot be read: {type(e).__name__})"
        if tail:
            result = replace(result, detail=f"{result.detail} (the FMU logged: {tail})")
    return replace(result, warning="; ".join(ctx.warnings),
                   duration_s=round(time.perf_counter() - t0, 6))
