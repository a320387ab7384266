"""Check family: runtime semantics of an FMU (``dronefly check``).

``call-sequence``, ``start-values``, ``dependencies``, ``reset``, ``two-instances``, ``state``,
``reference``: each is ``check(ctx) -> detail`` for FMI 2.0 and 3.0 alike (see
:mod:`.rules` for the rule each enforces, :mod:`.driver` for the calls).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import Any

import fmpy
import numpy as np
from fmpy.fmi1 import FMICallException
from fmpy.util import read_csv, read_ref_opt_file, validate_result, validate_signal

from .driver import (KINDS, Context, Run, Var, bounded, do_step, excite, initialize, read_now, reader,
                     run_steps, same, whole_run, write)
from .reference import REFERENCES
from .reference import check_reference as cross_check
from .rules import CheckFailed, CheckSkipped, require, status_name

__all__ = ["check_call_sequence", "check_dependencies", "check_reference", "check_reset",
           "check_start_values", "check_state", "check_two_instances"]


def check_call_sequence(ctx: Context) -> str:
    with ctx.instantiate("check") as inst:
        whole = whole_run(ctx, inst)
    data = whole.rows
    bad = [v.name for j, v in enumerate(ctx.outputs) if not np.isfinite(data[:, j]).all()]
    if bad:
        msg = f"non-finite values returned with OK: {', '.join(bad[:5])}"
        require(not ctx.ours, msg)
        ctx.warnings.append(msg)
    if ctx.ours and ctx.outputs:
        require(float(np.ptp(data)) > 0.0, "outputs do not respond to the inputs")
    steps = len(data) - 1
    if whole.ended_at is not None:
        return (f"{steps} steps of {ctx.step:.6g} s; the FMU ended the run at "
                f"t = {whole.ended_at:.6g} s (before the stop time {ctx.stop:.6g} s)")
    end = ctx.start + steps * ctx.step
    short = ("" if end >= ctx.stop * (1 - 1e-12) - 1e-300 else
             f" (the stop time {ctx.stop:.6g} s is not a whole number of steps)")
    return f"{steps} steps of {ctx.step:.6g} s to {end:.6g} s{short}"


def _exact(ctx: Context) -> list[tuple[Var, float, bool]]:
    """(variable, declared start, is Float32) of every variable with initial exact."""
    md3 = ctx.fmu.model_description3
    f32 = ({v.valueReference for v in md3.modelVariables if v.type == "Float32"}
           if md3 is not None else set())
    out = []
    for v in ctx.fmu.model_description.modelVariables:
        if v.type not in KINDS or v.start is None or v.causality == "independent":
            continue
        initial = v.initial or ("exact" if v.variability == "constant" else None)
        if initial != "exact" or v.type == "Enumeration" and not str(v.start).strip():
            continue
        text = str(v.start).strip()
        if KINDS[v.type] == "Boolean":
            value = 1.0 if text in ("true", "1") else 0.0
        else:
            value = float(text)
        element = ctx.fmu.elements.get(v.valueReference)
        base = element.array_vr if element else v.valueReference
        out.append((Var(v.name, KINDS[v.type], v.valueReference, v), value, base in f32))
    return out


def check_start_values(ctx: Context) -> str:
    exact = _exact(ctx)
    if not exact:
        raise CheckSkipped("no variable with initial=\"exact\"")
    with ctx.instantiate("check") as inst:
        initialize(ctx, inst)
        held = read_now(inst, [v for v, _, _ in exact])
    wrong = []
    for (v, declared, f32), x in zip(exact, held):
        # the declared text and the value the FMU holds differ at most by the writer's
        # decimal-to-binary rounding: a few ulp of a double, or one of a Float32
        tol = 1e-6 if f32 else 4 * np.finfo(float).eps
        if not (x == declared or abs(x - declared) <= tol * abs(declared)):
            wrong.append(f"{v.name}: declared start {declared!r}, holds {x!r}")
    require(not wrong, "; ".join(wrong[:5]) + (" ..." if len(wrong) > 5 else ""))
    return f"{len(exact)} variable(s) with initial=\"exact\" hold their start values"


def _declared(ctx: Context, which: str = "initialUnknowns",
              pool: list[Var] | None = None) -> dict[str, set[str] | None]:
    """Unknown name (as in ``pool``, default ``ctx.outputs``) -> the input names it is declared
    to depend on, in ModelStructure ``which`` (``initialUnknowns``, ``outputs`` or
    ``derivatives``; None: not declared, on every one)."""
    md = ctx.fmu.model_description3 or ctx.fmu.model_description
    pool = ctx.outputs if pool is None else pool

    def members(name: str, pool: list[Var]) -> list[str]:
        return [v.name for v in pool if v.name == name or v.name.startswith(name + "[")]

    out: dict[str, set[str] | None] = {}
    for unknown in getattr(md, which) or []:
        deps = unknown.dependencies
        names = (None if deps is None else
                 {n for d in deps for n in members(d.name, ctx.inputs)})
        for o in members(unknown.variable.name, pool):
            out[o] = names
    return out


def _derivatives(ctx: Context) -> list[Var]:
    """The derivatives of the continuous states (ModelStructure Derivatives), as variables."""
    md = ctx.fmu.model_description3 or ctx.fmu.model_description
    names = {d.variable.name for d in md.derivatives or []}
    return [Var(v.name, "Real", v.valueReference, v)
            for v in ctx.fmu.model_description.modelVariables
            if v.type == "Real" and (v.name in names or v.name.split("[")[0] in names)]


def _nudged(var: Var, x: float) -> float | None:
    """A small change of an input (a real by 1e-3 of its size, at least 1e-3; an integer or a
    boolean as :func:`_perturbed`): the Step Mode probe compares how outputs respond to it over
    two step sizes, so its size does not matter, and a small one stays where the FMU accepts
    it."""
    if var.kind != "Real":
        return _perturbed(var, x)
    delta = 1e-3 * max(1.0, abs(x))
    for d in (delta, -delta):
        y = bounded(var, x + d)
        if y != x:
            return y
    return None


def _perturbed(var: Var, x: float) -> float | None:
    if var.kind == "Boolean":
        return 0.0 if x else 1.0
    if var.var.type == "Enumeration":
        return None
    for delta in (1.0, -1.0, 0.5, -0.5):
        y = bounded(var, x + delta)
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


#: the two small communication steps of the Step Mode probe, in units of the run's step: an
#: output that follows an input directly differs by O(1) between two continuations with
#: different inputs, whatever the step; one that follows it through a state differs by O(h)
_PROBE_STEPS = (1e-3, 1e-4)
#: the ratio of the two differences above which the difference does not shrink with the step
#: (O(1)): 1 for a direct dependency, 0.1 for one through a state (the steps' ratio)
_DIRECT = 0.5


def _lies(declared: dict[str, set[str] | None], seen: dict[str, set[str]], where: str,
          which: str) -> list[str]:
    out = []
    for o, deps in declared.items():
        if deps is None:
            continue
        for u in sorted(seen.get(o, set()) - deps):
            what = "no dependency" if not deps else f"dependencies on {', '.join(sorted(deps))}"
            out.append(f"{o} (declared in {which} with {what} among the inputs) changed when "
                       f"only {u} was set, {where}")
    return out


def _probe(inst: Any, inputs: list[Var], unknowns: list[Var], seen: dict[str, set[str]],
           tried: set[str]) -> None:
    """Each of ``inputs`` moved alone and put back, the ``unknowns`` read before and after: the
    inputs that moved each unknown are added to ``seen``, the inputs moved to ``tried``. The
    instance must be in a mode where a get after a set is allowed."""
    read = reader(unknowns)
    before = read(inst)
    for u in inputs:
        x = read_now(inst, [u])[0]
        p = _perturbed(u, x)
        if p is None:
            continue
        tried.add(u.name)
        write(inst, u, p)
        after = read(inst)
        write(inst, u, x)
        for o, a, b in zip(unknowns, before, after):
            if _moved(a, b):
                seen[o.name].add(u.name)


def _initialization_probe(ctx: Context, declared: dict[str, set[str] | None]
                          ) -> tuple[dict[str, set[str]], set[str]]:
    """Which inputs move which outputs in Initialization Mode (set, get in any order)."""
    seen: dict[str, set[str]] = {o.name: set() for o in ctx.outputs}
    tried: set[str] = set()
    with ctx.instantiate("check") as inst:
        s = inst.slave
        ctx.event(call=f"{ctx.fmi}EnterInitializationMode(startTime={ctx.start!r})")
        s.setupExperiment(startTime=ctx.start, stopTime=ctx.stop)
        s.enterInitializationMode()
        _probe(inst, ctx.inputs, [o for o in ctx.outputs if o.name in declared], seen, tried)
        s.exitInitializationMode()
        s.terminate()
    return seen, tried


def _step_probe(ctx: Context, declared: dict[str, set[str] | None]) -> dict[str, set[str]]:
    """Which inputs move which outputs directly in Step Mode: from one saved FMU state, two
    continuations over a small step, one with the input as it was and one with it moved, at
    two step sizes; a difference that does not shrink with the step (O(1), not O(h)) is a
    direct dependency. Only the outputs declared independent of some input are probed."""
    seen: dict[str, set[str]] = {o: set() for o in declared}
    outs = [o for o in ctx.outputs if declared.get(o.name) is not None]
    read = reader(outs)
    with ctx.instantiate("check") as inst:
        s = inst.slave
        initialize(ctx, inst)
        t = ctx.start
        excite(ctx, inst, 0)
        if do_step(ctx, inst, t, ctx.step):
            raise CheckSkipped("the FMU ended the run after one step")
        t += ctx.step
        state = s.getFMUstate()
        try:
            refused = []
            for u in ctx.inputs:
                x = read_now(inst, [u])[0]
                p = _nudged(u, x)
                if p is None or all(u.name in (declared[o.name] or ()) for o in outs):
                    continue
                diffs = []
                try:
                    for frac in _PROBE_STEPS:
                        h = frac * ctx.step
                        rows = []
                        for value in (x, p):
                            s.setFMUstate(state)
                            write(inst, u, value)
                            do_step(ctx, inst, t, h)
                            rows.append(read(inst))
                        diffs.append(rows)
                except FMICallException as e:  # a step the FMU refuses: this input not probed
                    refused.append(f"{u.name} ({ctx.fmi}DoStep: "
                                   f"{status_name(e.status, ctx.fmu.fmi_version)})")
                    continue
                for j, o in enumerate(outs):
                    (a1, b1), (a2, b2) = ([r[0][j], r[1][j]] for r in diffs)
                    if _moved(a2, b2) and abs(b2 - a2) > _DIRECT * abs(b1 - a1):
                        seen[o.name].add(u.name)
        finally:
            s.setFMUstate(state)
            s.freeFMUstate(state)
    if refused:
        ctx.warnings.append("not probed in Step Mode (a step refused): " + ", ".join(refused))
    return seen


def _initial_part(ctx: Context, initial: dict[str, set[str] | None]
                  ) -> tuple[list[str], list[str]]:
    """(lies, what was done) of the InitialUnknowns probed in Initialization Mode."""
    if not initial:
        return [], []
    seen, tried = _initialization_probe(ctx, initial)
    lies = _lies(initial, seen, "in Initialization Mode", "InitialUnknowns")
    unseen = [f"{o} on {u}" for o, deps in initial.items() if deps is not None
              for u in sorted((deps & tried) - seen.get(o, set()))]
    if unseen:
        ctx.warnings.append("declared dependencies not seen (a dependency may be "
                            "conditional, e.g. on a gain that is zero): "
                            + ", ".join(unseen[:6]) + (" ..." if len(unseen) > 6 else ""))
    n = sum(deps is not None for deps in initial.values())
    return lies, [f"{n} output(s) with declared initial dependencies, {len(tried)} input(s) "
                  "set one at a time in Initialization Mode"]


def _continuous_time_probe(ctx: Context, unknowns: list[Var]
                           ) -> tuple[dict[str, set[str]], set[str]]:
    """Which inputs move which ``unknowns`` (outputs, derivatives) through Model Exchange, where
    a get after a set is allowed (FMI 2.0 3.2.3, FMI 3.0 3.2.3): each continuous input moved
    alone in Continuous-Time Mode, then each discrete input (settable in Event Mode only) moved
    alone in Event Mode; the unknowns read after the set, the input put back."""
    seen: dict[str, set[str]] = {o.name: set() for o in unknowns}
    tried: set[str] = set()
    continuous = [u for u in ctx.inputs if u.var.variability == "continuous"]
    discrete = [u for u in ctx.inputs if u.var.variability != "continuous"]
    with ctx.instantiate("check") as inst:
        initialize(ctx, inst)
        if getattr(inst.slave, "terminated", False):
            raise CheckSkipped("the FMU asked to terminate at its initialization")
        _probe(inst, continuous, unknowns, seen, tried)
        if discrete:
            ctx.event(call=f"{ctx.fmi}EnterEventMode()")
            inst.slave.enter_event_mode()
            _probe(inst, discrete, unknowns, seen, tried)
            ctx.event(call=f"the event iteration, {ctx.fmi}EnterContinuousTimeMode()")
            inst.slave.leave_event_mode()
        ctx.event(call=f"{ctx.fmi}Terminate()")
        inst.slave.terminate()
    return seen, tried


def _dependencies_me(ctx: Context) -> str:
    """The dependencies through Model Exchange: InitialUnknowns in Initialization Mode,
    Outputs and Derivatives after a set of one input (continuous inputs in Continuous-Time
    Mode, discrete ones in Event Mode)."""
    if not ctx.inputs:
        raise CheckSkipped("no inputs")
    initial = _declared(ctx, "initialUnknowns")
    derivatives = _derivatives(ctx)
    declared = {which: {o: d for o, d in _declared(ctx, which, pool).items() if d is not None}
                for which, pool in (("outputs", ctx.outputs), ("derivatives", derivatives))}
    unknowns = [v for v in ctx.outputs if v.name in declared["outputs"]] + \
        [v for v in derivatives if v.name in declared["derivatives"]]
    if not initial and not unknowns:
        raise CheckSkipped("no output among the ModelStructure InitialUnknowns, and no "
                           "Outputs or Derivatives dependencies declared")
    lies, parts = _initial_part(ctx, initial)
    if unknowns and not lies:
        seen, tried = _continuous_time_probe(ctx, unknowns)
        for which, name in (("outputs", "Outputs"), ("derivatives", "Derivatives")):
            lies += _lies(declared[which], seen, "through Model Exchange (set, then get: "
                          "continuous inputs in Continuous-Time Mode, discrete ones in Event "
                          "Mode)", name)
        parts.append(f"{len(declared['outputs'])} output(s) and {len(declared['derivatives'])} "
                     f"derivative(s) with declared dependencies, {len(tried)} input(s) set one at "
                     "a time (continuous ones in Continuous-Time Mode, discrete ones in Event "
                     "Mode)")
    require(not lies, "; ".join(lies[:4]) + (" ..." if len(lies) > 4 else ""))
    return "; ".join(parts) + ": no undeclared dependency"


def check_dependencies(ctx: Context) -> str:
    # In Initialization Mode the importer may set inputs and get outputs in any order, the FMU
    # evaluating its equations in between (FMI 2.0 4.2.4, FMI 3.0 Initialization Mode): the
    # InitialUnknowns are tested there. In Step Mode a get after a set without a step is not
    # allowed: the Outputs' dependencies are tested by two continuations from one saved FMU
    # state over a small step (where the FMU can save its state).
    # Through Model Exchange a get after a set is allowed in Continuous-Time Mode (continuous
    # inputs) and Event Mode (any input): the Outputs and the Derivatives are probed there
    # (:func:`_dependencies_me`).
    if ctx.interface == "me":
        return _dependencies_me(ctx)
    if not ctx.inputs or not ctx.outputs:
        raise CheckSkipped("no inputs or no outputs")
    initial = _declared(ctx, "initialUnknowns")
    outputs = _declared(ctx, "outputs")
    can_probe = bool(ctx.fmu.model_description.coSimulation.canGetAndSetFMUstate)
    probed = {o: d for o, d in outputs.items() if d is not None}
    if not initial and not (can_probe and probed):
        raise CheckSkipped("no output among the ModelStructure InitialUnknowns, and no Outputs "
                           "dependencies to probe in Step Mode" + ("" if can_probe else
                           " (canGetAndSetFMUstate is not declared)"))
    lies, parts = _initial_part(ctx, initial)
    if can_probe and probed and not lies:
        lies += _lies(outputs, _step_probe(ctx, outputs), "in Step Mode (two continuations "
                      "from one saved FMU state differ by O(1), not O(h), over a small step)",
                      "Outputs")
        parts.append(f"{len(probed)} output(s) with declared Outputs dependencies probed in "
                     "Step Mode from a saved FMU state")
    elif probed and not can_probe:
        parts.append("Outputs dependencies not probed in Step Mode (canGetAndSetFMUstate is not "
                     "declared)")
    require(not lies, "; ".join(lies[:4]) + (" ..." if len(lies) > 4 else ""))
    return "; ".join(parts) + ": no undeclared dependency"


def check_reset(ctx: Context) -> str:
    with ctx.instantiate("check") as inst:
        first = whole_run(ctx, inst)
        ctx.event(call=f"{ctx.fmi}Reset()")
        inst.slave.reset()
        second = whole_run(ctx, inst)
    reset = f"{ctx.fmi}Reset"
    if first.ended_at != second.ended_at:
        def end(r: Run) -> str:
            return f"t = {r.ended_at:.6g} s" if r.ended_at is not None else "the stop time"

        raise CheckFailed(f"the run after {reset} differs from the first: the FMU ended it at "
                           f"{end(second)}, the first at {end(first)}")
    require(same(first.rows, second.rows), f"the run after {reset} differs from the first")
    return f"identical after {reset}"


def check_two_instances(ctx: Context) -> str:
    if ctx.caps.canBeInstantiatedOnlyOncePerProcess:
        raise CheckSkipped("canBeInstantiatedOnlyOncePerProcess is declared")
    with ctx.instantiate("single") as one:
        initialize(ctx, one)
        ref = run_steps(ctx, one).rows
    with ctx.instantiate("left") as a, ctx.instantiate("right") as b:
        initialize(ctx, a)
        initialize(ctx, b)
        ra, rb = [read_now(a, ctx.outputs)], [read_now(b, ctx.outputs)]
        ended = [False, False]
        for k in range(len(ref) - 1):
            for j, (inst, rec) in enumerate(((a, ra), (b, rb))):
                if not ended[j]:
                    excite(ctx, inst, k)
                    ended[j] = do_step(ctx, inst, ctx.start + k * ctx.step, ctx.step)
                    rec.append(read_now(inst, ctx.outputs))
    require(same(np.array(ra), ref) and same(np.array(rb), ref),
             "interleaved instances differ from a single run")
    return "independent"


def check_state(ctx: Context) -> str:
    cs = ctx.caps
    if not cs.canGetAndSetFMUstate:
        raise CheckSkipped("canGetAndSetFMUstate is not declared")
    half = ctx.n // 2
    parts = []
    with ctx.instantiate("check") as inst:
        s = inst.slave
        initialize(ctx, inst)
        if run_steps(ctx, inst, range(half)).ended_at is not None:
            raise CheckSkipped(f"the FMU ended the run before t = "
                               f"{ctx.start + half * ctx.step:.6g} s")
        state = s.getFMUstate()
        blob = s.serializeFMUstate(state) if cs.canSerializeFMUstate else None
        cont = run_steps(ctx, inst, range(half, ctx.n)).rows
        s.setFMUstate(state)
        again = run_steps(ctx, inst, range(half, ctx.n)).rows
        require(same(cont, again), f"continuation after {ctx.fmi}SetFMUstate differs")
        parts.append("get/set")
        if blob is not None:
            restored = s.deSerializeFMUstate(blob)
            s.setFMUstate(restored)
            third = run_steps(ctx, inst, range(half, ctx.n)).rows
            s.freeFMUstate(restored)
            require(same(cont, third),
                     f"continuation after {ctx.fmi}DeSerializeFMUstate differs")
            parts.append(f"serialized ({len(blob)} bytes)")
        s.freeFMUstate(state)
    return (f"bit-for-bit continuation from t = {ctx.start + half * ctx.step:.6g} s: "
            + ", ".join(parts))


def reference_files(ctx: Context) -> tuple[Path, Path | None, Path | None] | None:
    """(reference CSV, inputs CSV or None, .opt or None) of the run to compare: the options'
    (``--ref``, ``--in``), or the cross-check layout beside the FMU (``<Model>_ref.csv``,
    ``<Model>_in.csv``, ``<Model>_ref.opt``, Model the FMU file's name); None if neither."""
    folder, stem = ctx.fmu.path.parent, ctx.fmu.path.stem
    if ctx.options.ref is not None:
        ref = Path(ctx.options.ref)
    elif (folder / f"{stem}_ref.csv").is_file():
        ref = folder / f"{stem}_ref.csv"
    else:
        return None
    inputs = (Path(ctx.options.inputs) if ctx.options.inputs is not None
              else folder / f"{stem}_in.csv" if ctx.options.ref is None
              and (folder / f"{stem}_in.csv").is_file() else None)
    opt = ref.with_name(ref.name[: -len("_ref.csv")] + "_ref.opt") \
        if ref.name.endswith("_ref.csv") else None
    return ref, inputs, opt if opt is not None and opt.is_file() else None


def _against_reference(ctx: Context, ref: Path, inputs: Path | None, opt: Path | None) -> str:
    reference = read_csv(str(ref))
    names = list(reference.dtype.names[1:])
    known = {v.name for v in ctx.fmu.model_description.modelVariables}
    unknown = [n for n in names if n not in known]
    require(not unknown, f"{ref.name}: {', '.join(unknown[:4])} name no variable of the FMU")
    t_ref = np.asarray(reference[reference.dtype.names[0]], float)
    o = read_ref_opt_file(str(opt)) if opt is not None else {}
    start = float(o.get("StartTime", t_ref[0]))
    stop = float(o.get("StopTime", t_ref[-1]))
    step = float(o.get("StepSize", (t_ref[-1] - t_ref[0]) / max(len(t_ref) - 1, 1)))
    ctx.event(call=f"fmpy.simulate_fmu(start_time={start!r}, stop_time={stop!r}, "
                   f"output_interval={step!r})")
    result = fmpy.simulate_fmu(str(ctx.fmu.path), fmi_type="CoSimulation", start_time=start,
                               stop_time=stop, output_interval=step, output=names,
                               input=read_csv(str(inputs)) if inputs is not None else None)
    outliers = float(validate_result(result, reference, stop_time=stop))
    worst = []
    for name in names:
        _, _, _, out = validate_signal(t=result["time"], y=result[name], t_ref=t_ref.copy(),
                                       y_ref=reference[name])
        if np.any(out):
            k = int(np.argmax(out))
            worst.append(f"{name} at t = {float(result['time'][k]):.6g} s: "
                         f"{float(result[name][k]):.6g}")
    source = f"{ref.name}" + (f" with {inputs.name}" if inputs is not None else "")
    require(outliers == 0.0, f"{outliers:.1%} of the samples outside FMPy's validation band "
                             f"of {source} (first outside: {'; '.join(worst[:3])})")
    return f"{len(names)} output(s) within FMPy's validation band of {source}"


def check_reference(ctx: Context) -> str:
    files = reference_files(ctx)
    if files is not None:
        return _against_reference(ctx, *files)
    if not ctx.ours:
        raise CheckSkipped("no reference result (--ref FILE.csv, or <Model>_ref.csv beside "
                           "the FMU)")
    if ctx.fmu.name not in REFERENCES:
        raise CheckSkipped("no reference result for this model")
    r = cross_check(ctx.fmu.name, ctx.fmu.path)
    require(r.passed, f"{r.cross_check_outliers:.1%} outliers, max relative error "
                      f"{r.max_rel_error:.2e}")
    return f"cross-check: no outliers, max relative error {r.max_rel_error:.1e}"
