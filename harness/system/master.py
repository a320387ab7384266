"""A fixed-step co-simulation master for a system of any number of FMI 2.0 CS FMUs.

``gauss-seidel`` (default): at each communication point the outputs of the FMUs without
direct feedthrough are read, then the direct-feedthrough FMUs get their inputs and give their
outputs in a producer-before-consumer order (:mod:`.graph`), then every other FMU gets its
inputs, and all step. For a plant and a feedthrough controller this is u_k = K x_k.
``jacobi``: every FMU's outputs are read first (a feedthrough FMU answers from the inputs of
the previous point), then all inputs are set and all FMUs step: u_k = K x_(k-1).
Initialization propagates in the Gauss-Seidel order in both cases.

Real, Integer and Boolean connections are supported. A failed call stops the run, naming the
instance, the call and the time; what was recorded is kept and the run is marked incomplete.
Every instance is terminated and freed on every exit path.
"""

from __future__ import annotations

import contextlib
import math
from ctypes import c_double, c_int, c_uint
from typing import Any, Mapping, Sequence

import numpy as np

from dronefly.interrupt import deferred_sigint

from dronefly.harness.cosim.fmu import FMU, FMUError
from dronefly.harness.cosim.master import MASTERS, MAX_STEPS
from dronefly.harness.cosim.records import LoopRun, StepFailure
from dronefly.harness.system.description import System, SystemSpecError
from dronefly.harness.system.graph import check_connections, evaluation_order, feedthrough

__all__ = ["SystemMaster"]


class _Node:
    """One instance's buffers: its Real outputs, and where each of its inputs comes from."""

    def __init__(self, name: str, fmu: FMU, outputs: list[str]) -> None:
        self.name, self.fmu = name, fmu
        self.types = {v.name: v.type for v in fmu.model_description.modelVariables}
        self.out_names = outputs
        self.out_vr = (c_uint * len(outputs))(*[fmu.vr(n) for n in outputs])
        self.out = (c_double * len(outputs))()
        self.at = 0  # where ``out`` starts in the buffer of every output (see ``place``)
        self.in_real: list[tuple[int, "_Node", int]] = []  # (vr, source node, source index)
        self.in_other: list[tuple[str, int, "_Node", int]] = []  # (type, vr, node, index)
        self.inst: Any = None

    def place(self, every_out: Any, at: int) -> None:
        """Make ``out`` a view of ``every_out`` from ``at`` on (one buffer for all outputs)."""
        self.at = at
        self.out = (c_double * len(self.out_names)).from_buffer(every_out, 8 * at)

    def finish(self, every_out: Any) -> None:
        """Input buffers; inputs that are one run of ``every_out`` read it in place (no copy)."""
        real = sorted(self.in_real, key=lambda r: r[1].at + r[2])
        where = [node.at + i for _, node, i in real]
        if where and where == list(range(where[0], where[0] + len(where))):
            self.in_real = real
            self.in_buf = (c_double * len(real)).from_buffer(every_out, 8 * where[0])
            self.in_src: list[tuple[Any, int]] = []
        else:
            self.in_buf = (c_double * len(self.in_real))()
            self.in_src = [(node.out, i) for _, node, i in self.in_real]
        self.in_vr = (c_uint * len(self.in_real))(*[vr for vr, _, _ in self.in_real])


_Op = tuple[_Node, str, Any, tuple]  # one call of a step: node, FMI call, function, arguments


class SystemMaster:
    """Open the FMUs of a :class:`System`, check it and co-simulate it.

    Parameters
    ----------
    system : System
        FMUs, connections, parameter values.
    master : str
        ``"gauss-seidel"`` or ``"jacobi"``; an algebraic loop is refused under Gauss-Seidel.

    Raises
    ------
    SystemSpecError, FMUError
        A connection that does not fit, an algebraic loop, an FMU that cannot be loaded.
    """

    def __init__(self, system: System, master: str = "gauss-seidel") -> None:
        if master not in MASTERS:
            raise SystemSpecError(f"master = {master!r}; choose one of {', '.join(MASTERS)}")
        self.system, self.master = system, master
        self.fmus: dict[str, FMU] = {}
        try:
            for inst, path in system.fmus.items():
                self.fmus[inst] = FMU(path)
            mds = {i: f.model_description for i, f in self.fmus.items()}
            check_connections(mds, system.connections)
            self.feedthrough = {i: feedthrough(md) for i, md in mds.items()}
            self.order = evaluation_order(list(system.fmus), self.feedthrough,
                                          system.connections, allow_loops=master == "jacobi")
            self._check_values(mds)
        except BaseException:
            self.close()
            raise
        self.names = [f"{i}.{v.name}" for i, md in mds.items() for v in md.modelVariables
                      if v.causality == "output" and v.type == "Real"]

    def _check_values(self, mds: Mapping[str, Any],
                      parameters: Mapping[str, Mapping[str, Any]] | None = None) -> None:
        for inst, values in (self.system.parameters if parameters is None
                             else parameters).items():
            settable = {v.name: v for v in mds[inst].modelVariables
                        if v.causality in ("parameter", "input")
                        and v.variability in ("fixed", "tunable", "continuous", "discrete")}
            for name in values:
                if name not in settable:
                    raise SystemSpecError(f"{inst}.{name}: no parameter or input of that name "
                                          f"in {self.system.fmus[inst].name}")

    def close(self) -> None:
        for f in self.fmus.values():
            f.close()

    def __enter__(self) -> "SystemMaster":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    # -------------------------------------------------------------------------------------
    def run(self, step_s: float, n_steps: int, *, record: Sequence[str] | None = None,
            values: Mapping[str, Mapping[str, Any]] | None = None) -> LoopRun:
        """Co-simulate ``n_steps`` steps of ``step_s`` seconds from t = 0.

        Parameters
        ----------
        step_s : float
            Communication step [s].
        n_steps : int
            Number of steps (1 to ``MAX_STEPS``).
        record : sequence of str, optional
            Real outputs ``instance.name`` to record (default: every Real output).
        values : mapping, optional
            ``{instance: {name: value}}`` for this run only, on top of the system's
            parameter values (e.g. other initial states).

        A SIGINT (Ctrl-C) stops the run between two steps (never inside an FMU call): the
        instances are freed and ``KeyboardInterrupt`` is raised.
        """
        if not (math.isfinite(step_s) and step_s > 0.0):
            raise SystemSpecError(f"step = {step_s!r} s must be finite and > 0")
        if not 1 <= n_steps <= MAX_STEPS:
            raise SystemSpecError(f"n_steps = {n_steps!r} must be in 1..{MAX_STEPS}")
        params = {i: dict(v) for i, v in self.system.parameters.items()}
        for inst, extra in (values or {}).items():
            if inst not in self.fmus:
                raise SystemSpecError(f"values for instance {inst!r}, which the system does "
                                      f"not have (instances: {', '.join(self.fmus)})")
            params.setdefault(inst, {}).update(extra)
        self._check_values({i: self.fmus[i].model_description for i in self.fmus}, params)
        names = list(self.names if record is None else record)
        nodes, every_out = self._nodes(names)
        with contextlib.ExitStack() as stack:
            interrupt = stack.enter_context(deferred_sigint())
            for node in nodes.values():
                node.inst = stack.enter_context(node.fmu.instantiate(node.name))
            return self._run(nodes, every_out, names, step_s, n_steps, params, interrupt)

    def _nodes(self, names: Sequence[str]) -> tuple[dict[str, _Node], Any]:
        wanted: dict[str, list[str]] = {i: [] for i in self.fmus}
        for c in self.system.connections:
            if self.fmus[c.source].variables[c.output].type == "Real" and \
                    c.output not in wanted[c.source]:
                wanted[c.source].append(c.output)
        for full in names:
            inst, _, var = full.partition(".")
            v = self.fmus.get(inst) and self.fmus[inst].variables.get(var)
            if not v or v.causality != "output" or v.type != "Real":
                raise SystemSpecError(f"cannot record {full!r}: not a Real output of an instance")
            if var not in wanted[inst]:
                wanted[inst].append(var)
        nodes = {i: _Node(i, f, wanted[i]) for i, f in self.fmus.items()}
        for c in self.system.connections:
            src, dst = nodes[c.source], nodes[c.target]
            kind = src.types[c.output]
            vr = dst.fmu.vr(c.input)
            if kind == "Real":
                dst.in_real.append((vr, src, src.out_names.index(c.output)))
            else:
                dst.in_other.append((kind, vr, src, src.fmu.vr(c.output)))
        every_out = (c_double * sum(len(n.out_names) for n in nodes.values()))()
        at = 0
        for n in nodes.values():
            n.place(every_out, at)
            at += len(n.out_names)
        for n in nodes.values():
            n.finish(every_out)
        return nodes, every_out

    def _run(self, nodes: dict[str, _Node], every_out: Any, names: Sequence[str], h: float,
             n_steps: int, parameters: Mapping[str, Mapping[str, Any]],
             interrupt: Any) -> LoopRun:
        from fmpy.fmi1 import FMICallException

        free = [nodes[i] for i in self.order.free]
        chained = [nodes[i] for i in self.order.chained]
        every = [nodes[i] for i in self.system.fmus]
        outs = np.frombuffer(every_out, dtype=np.float64)
        where = [nodes[n.partition(".")[0]].at + nodes[n.partition(".")[0]].out_names.index(
            n.partition(".")[2]) for n in names]
        # one view of the outputs in record order when they lie in order, else a gather
        row = outs[where[0]:where[0] + len(where)] if where and where == list(
            range(where[0], where[0] + len(where))) else None
        where_ix = np.array(where, dtype=np.intp)
        rec = np.full((n_steps + 1, len(names)), np.nan)
        time = np.arange(n_steps + 1) * h
        run = LoopRun(list(names), time, rec)
        who, call, t = every[0], "initialization", 0.0
        # the calls of a step, planned once per run: (node, FMI call, function, arguments)
        def get(n: _Node) -> list[_Op]:
            s = n.inst.slave
            return [(n, "fmi2GetReal", s.fmi2GetReal, (s.component, n.out_vr, len(n.out), n.out))
                    ] if len(n.out) else []

        def put(n: _Node) -> list[_Op]:
            s, ops = n.inst.slave, []
            if n.in_src:  # inputs from scattered outputs: copied first
                ops.append((n, "fmi2SetReal", _gather, (n.in_buf, n.in_src)))
            if len(n.in_buf):
                ops.append((n, "fmi2SetReal", s.fmi2SetReal,
                            (s.component, n.in_vr, len(n.in_buf), n.in_buf)))
            for kind, vr, src, svr in n.in_other:
                value = (c_int * 1)()  # fmi2Integer and fmi2Boolean are both int
                ss = src.inst.slave
                ops.append((src, f"fmi2Get{kind}", getattr(ss, f"fmi2Get{kind}"),
                            (ss.component, (c_uint * 1)(svr), 1, value)))
                ops.append((n, f"fmi2Set{kind}", getattr(s, f"fmi2Set{kind}"),
                            (s.component, (c_uint * 1)(vr), 1, value)))
            return ops

        jacobi = self.master == "jacobi"
        read = [op for n in (every if jacobi else free) for op in get(n)]
        if not jacobi:
            read += [op for n in chained for op in (*put(n), *get(n))]
        write = [op for n in (every if jacobi else free) for op in put(n)]
        steps = [(n, "fmi2DoStep", n.inst.slave.fmi2DoStep, n.inst.slave.component)
                 for n in every]
        try:
            for n in every:
                who, s = n, n.inst.slave
                s.setupExperiment(startTime=0.0, stopTime=n_steps * h)
                s.enterInitializationMode()
                for name, value in parameters.get(n.name, {}).items():
                    kind = n.types[name]
                    getattr(s, f"set{kind}")([n.fmu.vr(name)], [value])
            for n in (*free, *chained):
                for who, call, f, args in (put(n) if n in chained else []):
                    f(*args)
                who, call = n, "fmi2ExitInitializationMode"
                n.inst.slave.exitInitializationMode()
                for who, call, f, args in get(n):
                    f(*args)
            for k in range(n_steps + 1):
                t = k * h
                if interrupt.count:  # Ctrl-C: stop between steps, never inside an FMU
                    for n in every:
                        with contextlib.suppress(FMICallException):
                            n.inst.slave.terminate()
                    raise KeyboardInterrupt  # the instances are freed on the way out
                for who, call, f, args in read:
                    f(*args)
                rec[k] = outs[where_ix] if row is None else row
                if k == n_steps:
                    break
                for who, call, f, args in write:
                    f(*args)
                for who, call, f, c in steps:
                    f(c, t, h, 1)
            for n in every:
                who, call = n, "fmi2Terminate"
                n.inst.slave.terminate()
        except FMICallException as e:
            msgs = who.inst.messages
            run.failure = StepFailure(who.name, call, t, e.status,
                                      msgs[-1].message if msgs else "")
            for n in every:
                with contextlib.suppress(FMICallException):
                    n.inst.slave.terminate()
            bad = np.isnan(rec).any(axis=1)
            keep = int(np.argmax(bad)) if bad.any() else len(rec)
            run.time, run.signals = time[:keep], rec[:keep]
        except (FMUError, OSError) as e:
            raise SystemSpecError(str(e)) from e
        run.messages = [m.message for n in every for m in n.inst.messages]
        return run


def _gather(buf: Any, src: list[tuple[Any, int]]) -> None:
    """Copy the values of inputs whose sources are not one run of the outputs into ``buf``."""
    buf[:] = [b[i] for b, i in src]
