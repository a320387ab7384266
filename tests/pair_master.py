"""A dedicated pair master: an oracle of tests/test_system.py and the baseline of
``benchmarks/run.py``, which compares the system master (``harness.cosim.master.Loop`` is a
thin adapter onto it) with this in the same run.

Fresh instances per run, a failed call raises. Gauss-Seidel (the benchmark's baseline): the
per-step work is that of a master written for exactly one plant and one controller (the
Ctrl-C check, the bookkeeping of which instance and call run, plant outputs -> controller
inputs -> controller outputs -> plant inputs, then both step, through the same preallocated
ctypes buffers). Jacobi (an oracle of tests/test_system.py, not timed): the controller's
outputs read before its inputs are set (u_k = K x_(k-1)), its inputs at
initialization the plant's initial outputs or ``u_source0``.
"""

from __future__ import annotations

from ctypes import c_double, c_uint
from typing import Any, Mapping, Sequence

import numpy as np

from dronefly.core.interrupt import deferred_sigint

from dronefly.harness.cosim.records import LoopRun

__all__ = ["PairMaster"]


class PairMaster:
    """The dedicated pair master (one plant, one controller).

    Parameters
    ----------
    plant, controller : FMU
        Extracted FMUs (:class:`dronefly.harness.cosim.fmu.FMU`), connected by name.
    ordering : str
        ``"gauss-seidel"`` (default, the benchmark's) or ``"jacobi"``.
    """

    def __init__(self, plant: Any, controller: Any, ordering: str = "gauss-seidel") -> None:
        if ordering not in ("gauss-seidel", "jacobi"):
            raise ValueError(f"ordering = {ordering!r}; choose gauss-seidel or jacobi")
        self.ordering = ordering
        self.plant, self.controller = plant, controller
        self.states, self.controls = plant.names("output"), plant.names("input")
        self.sensed = controller.names("input")
        self.names = [*self.states, *self.controls]

    def run(self, step: float, n_steps: int,
            plant_start: Mapping[str, float] | None = None,
            u_source0: Sequence[float] | None = None) -> LoopRun:
        """Co-simulate ``n_steps`` steps of ``step`` s from t = 0 on fresh instances;
        ``u_source0``: the controller's inputs at initialization (Jacobi only; default the
        plant's initial outputs)."""
        if u_source0 is not None and self.ordering != "jacobi":
            raise ValueError("u_source0 is for the Jacobi ordering")
        with self.plant.instantiate() as p, self.controller.instantiate() as c, \
                deferred_sigint() as interrupt:
            return self._run(p, c, step, n_steps, plant_start or {}, interrupt, u_source0)

    def _run(self, p: Any, c: Any, step: float, n_steps: int,
             plant_start: Mapping[str, float], interrupt: Any,
             u_source0: Sequence[float] | None = None) -> LoopRun:
        ns, nu = len(self.states), len(self.controls)
        rec = np.full((n_steps + 1, ns + nu), np.nan)
        run = LoopRun(self.names, np.arange(n_steps + 1) * step, rec)
        y_vr = (c_uint * ns)(*p.vrs(self.states))
        s_vr = (c_uint * ns)(*c.vrs(self.states))  # the controller senses every state
        u_vr_c = (c_uint * nu)(*c.vrs(self.controls))
        u_vr_p = (c_uint * nu)(*p.vrs(self.controls))
        y, u = (c_double * ns)(), (c_double * nu)()
        for inst, values in ((p, plant_start), (c, {})):
            inst.slave.setupExperiment(startTime=0.0, stopTime=n_steps * step)
            inst.slave.enterInitializationMode()
            for name, value in values.items():
                inst.slave.setReal([inst.fmu.vr(name)], [float(value)])
        p.slave.exitInitializationMode()
        p.slave.fmi2GetReal(p.slave.component, y_vr, ns, y)
        c.slave.fmi2SetReal(c.slave.component, s_vr, ns,
                            y if u_source0 is None else (c_double * ns)(*u_source0))
        c.slave.exitInitializationMode()
        pg, ps, pd, pc = (p.slave.fmi2GetReal, p.slave.fmi2SetReal, p.slave.fmi2DoStep,
                          p.slave.component)
        cg, cs, cd, cc = (c.slave.fmi2GetReal, c.slave.fmi2SetReal, c.slave.fmi2DoStep,
                          c.slave.component)
        if self.ordering == "jacobi":  # decided once per run: the Gauss-Seidel loop stays minimal
            for k in range(n_steps + 1):
                t = k * step
                if interrupt.count:
                    raise KeyboardInterrupt
                pg(pc, y_vr, ns, y)
                cg(cc, u_vr_c, nu, u)  # answered from the previous point's inputs
                cs(cc, s_vr, ns, y)
                rec[k, :ns] = y
                rec[k, ns:] = u
                if k == n_steps:
                    break
                ps(pc, u_vr_p, nu, u)
                pd(pc, t, step, 1)
                cd(cc, t, step, 1)
        else:
            for k in range(n_steps + 1):
                t = k * step
                if interrupt.count:
                    raise KeyboardInterrupt
                who, call = p, "fmi2GetReal"
                pg(pc, y_vr, ns, y)
                who, call = c, "fmi2SetReal"
                cs(cc, s_vr, ns, y)
                who, call = c, "fmi2GetReal"
                cg(cc, u_vr_c, nu, u)
                rec[k, :ns] = y
                rec[k, ns:] = u
                if k == n_steps:
                    break
                who, call = p, "fmi2SetReal"
                ps(pc, u_vr_p, nu, u)
                who, call = p, "fmi2DoStep"
                pd(pc, t, step, 1)
                who, call = c, "fmi2DoStep"
                cd(cc, t, step, 1)
            del who, call  # named a failure in the pair master; here only the cost is kept
        for inst in (p, c):
            inst.slave.terminate()
        run.messages = [m.message for inst in (p, c) for m in inst.messages]
        return run
