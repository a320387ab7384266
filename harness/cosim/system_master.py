"""A fixed-step co-simulation master for a system of any number of FMI 2.0 CS FMUs.

``gauss-seidel`` (default): at each communication point the outputs of the FMUs without
direct feedthrough are read, then the direct-feedthrough FMUs get their inputs and give their
outputs in a producer-before-consumer order (:mod:`.graph`), then every other FMU gets its
inputs, and all step. For a plant and a feedthrough controller this is u_k = K x_k.
``jacobi``: every FMU's outputs are read first (a feedthrough FMU answers from the inputs of
the previous point), then all inputs are set and all FMUs step: u_k = K x_(k-1).
Initialization propagates in the Gauss-Seidel order in both cases (``inputs0`` of
:meth:`SystemMaster.run` can give some inputs other values before the first step).

It is also the master of the plant/controller pair (:class:`dronefly.harness.cosim.master.Loop`
runs the pair's system here, in the pair's fixed order and on instances reused across runs).
Real, Integer and Boolean connections are supported. Parameter and input values are converted
to their variables' declared types when the master is made (and those of a run when it
starts), :mod:`.typed_values`. Any Real, Integer or Boolean variable can be recorded, as a pure
observer: every recorded variable is read together with the point's outputs, before the
inputs of the next step are set, and nothing is set at the last point. A recorded input is
the value set for the step from that point: its source's output of that point (read from the
output buffer, no call, when it is Real); an unconnected input is read itself. Without extra
names no call is added to a step.
In an algebraic loop (Jacobi), an input whose source is initialized later keeps its start or
given value at initialization. A failed call stops the run, naming the instance, the call and
the time; what was recorded is kept and the run is marked incomplete.
Every instance is terminated on every exit path, and freed unless the caller gave it.
"""

from __future__ import annotations

import contextlib
import math
from array import array
from typing import Any, Mapping, Sequence

import numpy as np
from fmpy.fmi1 import FMICallException

from ...core.interrupt import deferred_sigint
from .fmu import FMU, FMUError, Instance
from .graph import Order, check_connections, evaluation_order, feedthrough
from .plan import (RECORDABLE, Node, build_nodes, get_ops, put_ops, record_ops, split_sources,
                   start_ops)
from .records import MASTERS, MAX_STEPS, LoopRun, StepFailure
from .system import System, SystemSpecError
from .typed_values import SETTER, settable, typed_values

__all__ = ["SystemMaster", "call_name"]


class SystemMaster:
    """Open the FMUs of a :class:`System`, check it and co-simulate it.

    Parameters
    ----------
    system : System
        FMUs, connections, parameter values.
    master : str
        ``"gauss-seidel"`` or ``"jacobi"``; an algebraic loop is refused under Gauss-Seidel.
    fmus : mapping, optional
        Already opened :class:`FMU` objects of some instances, used instead of opening the
        system's files (and not closed by :meth:`close`).
    order : Order, optional
        The evaluation order instead of the one derived from the ModelStructures (no
        algebraic loop check): each instance exactly once, ``free`` ones read without their
        inputs set first.
    instance_names : mapping, optional
        The names the instances made in :meth:`run` are given (what an FMU may write in its
        messages); default: the system's instance names.

    Raises
    ------
    SystemSpecError, FMUError
        A connection that does not fit, an algebraic loop, an FMU that cannot be loaded.
    """

    def __init__(self, system: System, master: str = "gauss-seidel", *,
                 fmus: Mapping[str, FMU] | None = None, order: Order | None = None,
                 instance_names: Mapping[str, str] | None = None) -> None:
        if master not in MASTERS:
            raise SystemSpecError(f"master = {master!r}; choose one of {', '.join(MASTERS)}")
        self.system, self.master = system, master
        self.instance_names = {i: (instance_names or {}).get(i, i) for i in system.fmus}
        self.fmus: dict[str, FMU] = {}
        self._own: list[FMU] = []
        try:
            for inst, path in system.fmus.items():
                if fmus is not None and inst in fmus:
                    self.fmus[inst] = fmus[inst]
                else:
                    self.fmus[inst] = FMU(path)
                    self._own.append(self.fmus[inst])
            mds = {i: f.model_description for i, f in self.fmus.items()}
            check_connections(mds, system.connections)
            self.feedthrough = {i: feedthrough(md) for i, md in mds.items()}
            if order is None:
                order = evaluation_order(list(system.fmus), self.feedthrough,
                                         system.connections, allow_loops=master == "jacobi")
            elif sorted((*order.free, *order.chained)) != sorted(system.fmus):
                raise SystemSpecError(f"order {order} must name each instance of "
                                      f"{', '.join(system.fmus)} once")
            self.order = order
            self._settable = {i: settable(md) for i, md in mds.items()}
            self._values = self._typed(system.parameters)
            # what readers of ``system.parameters`` see (verdicts, sweeps): the typed values
            self.system = system.with_parameters(self._values)
        except BaseException:
            self.close()
            raise
        self.names = [f"{i}.{v.name}" for i, md in mds.items() for v in md.modelVariables
                      if v.causality == "output" and v.type in RECORDABLE]
        #: the outputs a run cannot record, by type (FMI 3.0's UInt32, Int64 and UInt64, and
        #: String and Binary: the records are doubles, and 32-bit integers are read)
        self.unrecordable = {f"{i}.{v.name}": v.type for i, md in mds.items()
                             for v in md.modelVariables
                             if v.causality == "output" and v.type not in RECORDABLE}

    def _typed(self, values: Mapping[str, Mapping[str, Any]]) -> dict[str, dict[str, Any]]:
        """``{instance: {name: value}}`` converted to the variables' declared types."""
        return {inst: typed_values(inst, self._settable[inst], given,
                                   self.system.fmus[inst].name)
                for inst, given in values.items()}

    def close(self) -> None:
        """Close the FMUs this master opened."""
        for f in self._own:
            f.close()

    def __enter__(self) -> "SystemMaster":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    # -------------------------------------------------------------------------------------
    def run(self, step_s: float, n_steps: int, *, record: Sequence[str] | None = None,
            values: Mapping[str, Mapping[str, Any]] | None = None,
            instances: Mapping[str, Instance] | None = None,
            inputs0: Mapping[str, Mapping[str, float]] | None = None,
            start_s: float | None = None) -> LoopRun:
        """Co-simulate ``n_steps`` steps of ``step_s`` seconds from ``start_s``.

        An FMU that ends the run (FMI 2.0: fmi2Discard with fmi2Terminated, 4.2.3; FMI 3.0:
        terminateSimulation or earlyReturn of fmi3DoStep) ends it there, as FMPy does: the
        last row is recorded at its last successful time, every instance is terminated and
        the run is complete.

        Parameters
        ----------
        step_s : float
            Communication step [s].
        n_steps : int
            Number of steps (1 to ``MAX_STEPS``).
        record : sequence of str, optional
            Variables ``instance.name`` to record, of any causality (outputs, inputs,
            parameters, calculated parameters, locals) and of type Real, Integer or Boolean
            (default: every output of these types), read with the outputs of each point. Inputs are
            recorded as set for the step from each point (their sources' outputs).
        values : mapping, optional
            ``{instance: {name: value}}`` for this run only, on top of the system's
            parameter values (e.g. other initial states).
        instances : mapping, optional
            ``{instance: Instance}`` of every instance, reused across runs: reset first
            (fmi2Reset), terminated at the end, not freed here. Default: instantiated and
            freed in this run.
        inputs0 : mapping, optional
            ``{instance: {input: value}}``: Real inputs set to these values at
            initialization instead of their sources' initial outputs (under Jacobi, what
            the FMU answers at the first point).
        start_s : float, optional
            Start time [s]; default: the system's (its SSP's DefaultExperiment startTime).

        A SIGINT (Ctrl-C) stops the run between two steps (never inside an FMU call): the
        instances are terminated (freed if made here) and ``KeyboardInterrupt`` is raised.
        """
        if not (math.isfinite(step_s) and step_s > 0.0):
            raise SystemSpecError(f"step = {step_s!r} s must be finite and > 0")
        if not 1 <= n_steps <= MAX_STEPS:
            raise SystemSpecError(f"n_steps = {n_steps!r} must be in 1..{MAX_STEPS}")
        params = {i: dict(v) for i, v in self._values.items()}
        for what, given in (("values", values), ("inputs0", inputs0),
                            ("instances", instances)):
            for inst in given or {}:
                if inst not in self.fmus:
                    raise SystemSpecError(f"{what} for instance {inst!r}, which the system "
                                          f"does not have (instances: {', '.join(self.fmus)})")
        for inst, extra in self._typed(values or {}).items():
            params.setdefault(inst, {}).update(extra)
        if instances is not None and set(instances) != set(self.fmus):
            raise SystemSpecError(f"instances must be given for every instance "
                                  f"({', '.join(self.fmus)})")
        for inst, given in (inputs0 or {}).items():
            for name in given:
                v = self.fmus[inst].variables.get(name)
                if v is None or v.causality != "input" or v.type != "Real":
                    raise SystemSpecError(f"inputs0: {inst}.{name} is not a Real input")
        names = list(self.names if record is None else record)
        nodes, every_out, where = build_nodes(self.fmus, self.system.connections, names)
        with contextlib.ExitStack() as stack:
            interrupt = stack.enter_context(deferred_sigint())
            for node in nodes.values():
                if instances is None:
                    node.inst = stack.enter_context(
                        node.fmu.instantiate(self.instance_names[node.name]))
                else:
                    node.inst = instances[node.name]
                    node.inst.slave.reset()
            start = self.system.start_s if start_s is None else float(start_s)
            if not math.isfinite(start):
                raise SystemSpecError(f"start = {start!r} s must be finite")
            return self._run(nodes, every_out, names, where, step_s, n_steps, params,
                             interrupt, inputs0 or {}, start)

    def _run(self, nodes: dict[str, Node], every_out: Any, names: Sequence[str],
             where: list[int], h: float, n_steps: int,
             parameters: Mapping[str, Mapping[str, Any]], interrupt: Any,
             inputs0: Mapping[str, Mapping[str, float]], start: float = 0.0) -> LoopRun:
        free = [nodes[i] for i in self.order.free]
        chained = [nodes[i] for i in self.order.chained]
        every = [nodes[i] for i in self.system.fmus]
        outs = np.frombuffer(every_out, dtype=np.float64)
        # the recorded values of each point appended to one array of doubles (a third of the
        # cost of assigning a row of a 2-D array): the bytes of the outputs in record order
        # when they lie in order, else a gather
        row = memoryview(every_out).cast("B")[8 * where[0]:8 * (where[0] + len(where))] if (
            where and where == list(range(where[0], where[0] + len(where)))) else None
        where_ix = np.array(where, dtype=np.intp)
        recorded = array("d")
        record = recorded.frombytes
        time = start + np.arange(n_steps + 1) * h
        fmi3 = [n for n in every if n.fmu.fmi_version == 3]  # their raw steps keep the flags
        keep = n_steps + 1
        run = LoopRun(list(names), time, np.full((0, len(names)), np.nan))
        who, call, t = every[0], "initialization", 0.0
        get, put = get_ops, put_ops  # the calls of a step, planned once per run
        jacobi = self.master == "jacobi"
        read = [op for n in (every if jacobi else free) for op in get(n)]
        if not jacobi:
            read += [op for n in chained for op in (*put(n), *get(n))]
        write = [op for n in (every if jacobi else free) for op in put(n)]
        if jacobi:  # Integer and Boolean sources read with the point's outputs, then set
            sources, write = split_sources(write)
            read += sources
        # other recorded variables: read with the point's outputs, before the next inputs
        # are set; a step stays read, record, write, step (no write at the last point)
        read += record_ops(nodes, every_out)
        steps = [(n, "fmi2DoStep", n.inst.slave.fmi2DoStep, n.inst.slave.component)
                 for n in every]
        try:
            for n in every:
                who, s, call = n, n.inst.slave, "fmi2SetupExperiment"
                s.setupExperiment(startTime=start, stopTime=start + n_steps * h)
                call = "fmi2EnterInitializationMode"
                s.enterInitializationMode()
                for name, value in parameters.get(n.name, {}).items():
                    call = f"fmi2Set{SETTER[n.types[name]]} of {name}"
                    getattr(s, f"set{SETTER[n.types[name]]}")([n.fmu.vr(name)], [value])
            ready: set[str] = set()  # initialized: their outputs can be read
            for n in (*free, *chained):
                for who, call, f, args in start_ops(n, inputs0.get(n.name), n in chained,
                                                    ready):
                    f(*args)
                who, call = n, "fmi2ExitInitializationMode"
                n.inst.slave.exitInitializationMode()
                for who, call, f, args in get(n):
                    f(*args)
                ready.add(n.name)
            for k in range(n_steps + 1):
                t = start + k * h
                if interrupt.count:  # Ctrl-C: stop between steps, never inside an FMU
                    for n in every:
                        with contextlib.suppress(FMICallException):
                            n.inst.slave.terminate()
                    raise KeyboardInterrupt  # ours are freed on the way out
                for who, call, f, args in read:
                    f(*args)
                record(outs[where_ix].tobytes() if row is None else row)
                if k == n_steps:
                    break
                for who, call, f, args in write:
                    f(*args)
                ended = None
                try:
                    for who, call, f, c in steps:
                        f(c, t, h, 1)
                except FMICallException as e:
                    ended = _terminated(who, e, t)
                    if ended is None:
                        raise
                if fmi3 and ended is None and any(n.inst.slave.step_ended() for n in fmi3):
                    ended = t + h
                if ended is not None:  # an FMU ended the run: its last row, then stop
                    for who, call, f, args in read:
                        f(*args)
                    record(outs[where_ix].tobytes() if row is None else row)
                    time[k + 1] = ended
                    keep = k + 2
                    break
            for n in every:
                who, call = n, "fmi2Terminate"
                n.inst.slave.terminate()
            rec = _signals(recorded, n_steps + 1, len(names))
            run.signals = rec
            if keep < len(time):
                run.time, run.signals = time[:keep], rec[:keep]
        except FMICallException as e:
            msgs = who.inst.messages
            run.failure = StepFailure(who.name, call_name(call, who.fmu.fmi_version), t,
                                      e.status, msgs[-1].message if msgs else "")
            for n in every:
                with contextlib.suppress(FMICallException):
                    n.inst.slave.terminate()
            rec = _signals(recorded, n_steps + 1, len(names))
            bad = np.isnan(rec).any(axis=1)
            keep = int(np.argmax(bad)) if bad.any() else len(rec)
            run.time, run.signals = time[:keep], rec[:keep]
        except (FMUError, OSError) as e:
            raise SystemSpecError(str(e)) from e
        run.messages = [m.message for n in every for m in n.inst.messages]
        return run


def _signals(recorded: "array[float]", rows: int, width: int) -> Any:
    """The recorded points as ``rows`` x ``width`` (rows not reached: NaN)."""
    rec = np.full((rows, width), np.nan)
    if width:
        got = np.frombuffer(recorded, dtype=np.float64).reshape(-1, width)
        rec[:len(got)] = got
    return rec


def _terminated(node: Node, e: Any, t: float) -> float | None:
    """The last successful time if ``e`` (from an FMI 2.0 fmi2DoStep from ``t``) is
    fmi2Discard with fmi2Terminated (FMI 2.0 4.2.3) after some progress, else None.

    A Discard without progress (the last successful time not after ``t``) is a refused step,
    a failure, also when the FMU says it terminated (pythonfmu 0.7.0 says so after every
    Discard)."""

    if node.fmu.fmi_version != 2 or e.status != 2:
        return None
    s = node.inst.slave
    try:
        if not s.getBooleanStatus(3):  # fmi2Terminated
            return None
        last = float(s.getRealStatus(2))  # fmi2LastSuccessfulTime
    except FMICallException:
        return None
    return last if last > t else None


#: FMI 2.0 calls of the master and their FMI 3.0 counterparts (fmi2SetupExperiment's start
#: and stop time go to fmi3EnterInitializationMode; an Integer is one of fmi3GetInt8 ...
#: fmi3GetUInt64, by the variable's type)
_FMI3_CALLS = {"fmi2SetupExperiment": "fmi3EnterInitializationMode",
               "fmi2GetReal": "fmi3GetFloat64", "fmi2SetReal": "fmi3SetFloat64",
               "fmi2GetInteger": "fmi3GetInt*", "fmi2SetInteger": "fmi3SetInt*"}


def call_name(call: str, fmi_version: int) -> str:
    """The name of the master's call ``call`` (said in FMI 2.0 terms) in the FMU's FMI
    version: ``fmi3DoStep``, not ``fmi2DoStep``, for an FMI 3.0 FMU."""
    if fmi_version != 3 or not call.startswith("fmi2"):
        return call
    head, _, rest = call.partition(" ")
    head = _FMI3_CALLS.get(head, "fmi3" + head[4:])
    return f"{head} {rest}" if rest else head
