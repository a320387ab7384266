"""The driver of ``dronefly check``: one FMU under one profile, its experiment, variables,
instances, calls and the log of what it was asked (:class:`Context`).

FMI 2.0 and 3.0 FMUs are driven through the same calls (:mod:`dronefly.harness.cosim.fmu3`
presents an FMI 3.0 FMU behind fmpy's FMU2Slave API); every check takes a :class:`Context`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np
from fmpy.fmi1 import FMICallException

from ..cosim.fmu import FMU, FMUError, Instance
from .fuzzkit import status_of
from .rules import CheckFailed, CheckOptions

__all__ = ["KINDS", "Context", "Run", "Tee", "Var", "bounded", "do_step", "excite", "experiment",
           "initialize", "named", "profile_for", "read_now", "reader", "run_steps", "same", "step_status",
           "whole_run", "write"]

_FMI2_TERMINATED = 3  # fmi2StatusKind fmi2Terminated
_FMI2_LAST_SUCCESSFUL_TIME = 2  # fmi2StatusKind fmi2LastSuccessfulTime


def profile_for(fmu: FMU) -> str:
    """The default profile of an FMU: ``"dronefly"`` if dronefly generated it."""
    tool = fmu.model_description.generationTool or ""
    return "dronefly" if tool.startswith("dronefly-fmu") else "standard"


KINDS = {"Real": "Real", "Integer": "Integer", "Enumeration": "Integer", "Boolean": "Boolean",
         **{t: "Integer" for t in ("Int8", "UInt8", "Int16", "UInt16", "Int32", "UInt32",
                                   "Int64", "UInt64")}}


@dataclass(frozen=True)
class Var:
    name: str
    kind: str  # Real, Integer, Boolean
    vr: int
    var: Any


class Context:
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
        #: why the FMU cannot run here (no binary for this platform), or None
        self.cannot_run: str | None = None
        #: why a host cannot use the FMU's binary (found by the binary check), or None
        self.unusable: str | None = None
        #: the checks that failed so far, by name (what a later check depends on)
        self.failed: set[str] = set()
        self.fmi = f"fmi{fmu.fmi_version}"
        #: the interface the running check drives: ``"cs"`` (Co-Simulation) or ``"me"`` (Model
        #: Exchange, through :class:`..cosim.exchange.MEStepper`); set by the runner
        self.interface = "cs"
        md = fmu.model_description
        #: the interfaces the FMU declares
        self.interfaces = tuple(i for i, e in (("cs", md.coSimulation), ("me", md.modelExchange))
                                if e is not None)
        self.start, self.stop, self.step, self.n = experiment(fmu.model_description, options)
        vs = [v for v in fmu.model_description.modelVariables if v.type in KINDS]
        self.inputs = [Var(v.name, KINDS[v.type], v.valueReference, v) for v in vs
                       if v.causality == "input"]
        self.outputs = [Var(v.name, KINDS[v.type], v.valueReference, v) for v in vs
                        if v.causality == "output"]
        self.read_outputs = reader(self.outputs)
        self.real_inputs = [v for v in self.inputs if v.kind == "Real"]
        self.input_base = [float(v.var.start) if v.var.start is not None else 0.0
                            for v in self.real_inputs]
        #: value reference -> the start of the Real input (what :func:`excite` moves it about)
        self.input_start = dict(zip((v.vr for v in self.real_inputs), self.input_base))

    @property
    def ours(self) -> bool:
        return self.profile == "dronefly"

    @property
    def caps(self) -> Any:
        """The capability flags of the interface the check drives (fmpy's CoSimulation or
        ModelExchange element)."""
        md = self.fmu.model_description
        return md.modelExchange if self.interface == "me" else md.coSimulation

    @property
    def excited(self) -> list[Var]:
        """The Real inputs the runs move (:func:`excite`): through Model Exchange the
        continuous ones (a discrete input is set in Event Mode only: FMI 2.0 3.2.3)."""
        if self.interface == "me":
            return [v for v in self.real_inputs if v.var.variability == "continuous"]
        return self.real_inputs

    def event(self, **row: Any) -> None:
        if self.on_event is not None:
            self.on_event(row)

    def instantiate(self, name: str) -> Instance:
        kind = " through Model Exchange" if self.interface == "me" else ""
        self.event(call=f"{self.fmi}Instantiate(instanceName={name!r}){kind}")
        inst = self.fmu.instantiate(name, interface=self.interface)
        if self.on_event is not None:
            inst.messages = Tee(inst.messages, self.on_event)
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


class Tee(list):
    """The messages of an instance, each also passed on as it arrives (the child's log)."""

    def __init__(self, items: list, sink: Callable[[dict], None]) -> None:
        super().__init__(items)
        self._sink = sink

    def append(self, m: Any) -> None:
        super().append(m)
        self._sink({"log": f"[{m.status}] {m.category}: {m.message}"[:500]})


def initialize(ctx: Context, inst: Instance) -> None:
    s = inst.slave
    ctx.event(call=f"{ctx.fmi}EnterInitializationMode(startTime={ctx.start!r}, "
                   f"stopTime={ctx.stop!r})")
    s.setupExperiment(startTime=ctx.start, stopTime=ctx.stop)
    s.enterInitializationMode()
    s.exitInitializationMode()


def named(vars_: list[Var]) -> str:
    shown = ", ".join(f"{v.name} (value reference {v.vr})" for v in vars_[:4])
    return shown + (f" and {len(vars_) - 4} more" if len(vars_) > 4 else "")


def reader(vars_: list[Var]) -> Callable[[Instance], list[float]]:
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
                raise CheckFailed(f"{str(e).rstrip('.')} reading {named(vars_)}") from None

        return read_reals

    def read(inst: Instance) -> list[float]:
        out = [0.0] * len(vars_)
        for getter, idx, vrs in groups:
            try:
                got = getattr(inst.slave, getter)(vrs)
            except FMICallException as e:
                raise CheckFailed(f"{str(e).rstrip('.')} reading "
                                   f"{named([vars_[k] for k in idx])}") from None
            for k, x in zip(idx, got):
                out[k] = float(x)
        return out

    return read


def read_now(inst: Instance, vars_: list[Var]) -> list[float]:
    """The values of ``vars_`` now (see :func:`reader`)."""
    return reader(vars_)(inst)


def write(inst: Instance, var: Var, value: float) -> None:
    s = inst.slave
    try:
        if var.kind == "Real":
            s.setReal([var.vr], [float(value)])
        elif var.kind == "Integer":
            s.setInteger([var.vr], [int(value)])
        else:
            s.setBoolean([var.vr], [bool(value)])
    except FMICallException as e:
        raise CheckFailed(f"{str(e).rstrip('.')} setting {named([var])} = {value!r}") from None


def bounded(var: Var, x: float) -> float:
    lo = getattr(var.var, "min", None)
    hi = getattr(var.var, "max", None)
    if lo is not None:
        x = max(x, float(lo))
    if hi is not None:
        x = min(x, float(hi))
    return x


def excite(ctx: Context, inst: Instance, k: int) -> None:
    """Real inputs at step k: start + 0.01 sin(0.3 k + j) for input j, within min/max."""
    real = ctx.excited
    if real:
        base = ctx.input_start
        inst.slave.setReal([v.vr for v in real],
                           [bounded(v, base[v.vr] + 0.01 * math.sin(0.3 * k + j))
                            for j, v in enumerate(real)])


def do_step(ctx: Context, inst: Instance, t: float, h: float) -> bool:
    """One step; True if the FMU ended the run (terminate requested, early return)."""

    s = inst.slave
    if ctx.on_event is not None:
        what = (f"{ctx.fmi}DoStep" if inst.interface == "cs" else
                "Model Exchange step (CVODE, events)")
        ctx.on_event({"call": f"{what}(currentCommunicationPoint={t!r}, "
                              f"communicationStepSize={h!r})"})
    if ctx.fmu.fmi_version == 3 or inst.interface == "me":
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
class Run:
    rows: np.ndarray
    ended_at: float | None  # the time the FMU ended the run at, if it did


def run_steps(ctx: Context, inst: Instance, steps: range | None = None) -> Run:
    """Step on the grid start + k step, recording every output after each step; the
    inputs follow :func:`excite`."""
    read = ctx.read_outputs
    rows = [read(inst)]
    for k in steps if steps is not None else range(ctx.n):
        excite(ctx, inst, k)
        t = ctx.start + k * ctx.step
        ended = do_step(ctx, inst, t, ctx.step)
        rows.append(read(inst))
        if ended:
            return Run(np.array(rows), t + ctx.step)
    return Run(np.array(rows), None)


def whole_run(ctx: Context, inst: Instance) -> Run:
    initialize(ctx, inst)
    run = run_steps(ctx, inst)
    ctx.event(call=f"{ctx.fmi}Terminate()")
    inst.slave.terminate()
    return run


def same(a: np.ndarray, b: np.ndarray) -> bool:
    return a.shape == b.shape and bool(np.array_equal(a, b, equal_nan=True))


def step_status(ctx: Context, inst: Instance, t: float, h: float) -> int:
    """The status of one fmi2DoStep / fmi3DoStep (0 OK ... 4 Fatal), the call logged."""
    ctx.event(call=f"{ctx.fmi}DoStep(currentCommunicationPoint={t!r}, "
                   f"communicationStepSize={h!r})")
    return status_of(lambda: inst.slave.doStep(currentCommunicationPoint=t,
                                                communicationStepSize=h))
