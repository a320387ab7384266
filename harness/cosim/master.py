"""A small fixed-step co-simulation master for a plant/controller FMU pair.

Variables are connected by name: every controller input is driven by the plant
output of the same name, every plant input by the controller output of the same
name. Two orderings:

``gauss-seidel`` (default)
    At each communication point the controller's inputs are set from the
    plant's outputs at that point, its outputs (direct feedthrough) are read and
    set on the plant, then both FMUs step: u_k = K x_k, held over the step.
``jacobi``
    Both FMUs are fed the values read at the previous point, so the plant sees
    the controller's response to x_(k-1): u_k = K x_(k-1). Before the first
    step the controller is fed the plant's initial outputs (or ``u_source0``).

Every instance is terminated and freed on every exit path.
"""

from __future__ import annotations

import contextlib
import math
from ctypes import c_double, c_uint
from typing import Any, Mapping, Sequence

import numpy as np

from dronefly.errors import DroneflyError
from dronefly.interrupt import deferred_sigint

from dronefly.harness.cosim.fmu import FMU, FMUError, Instance
from dronefly.harness.cosim.records import LoopRun, StepFailure

__all__ = ["MASTERS", "MAX_STEPS", "CoSimError", "Loop", "LoopRun", "StepFailure", "connect_by_name",
           "step_count"]

MASTERS = ("gauss-seidel", "jacobi")
#: Communication steps per run at most: the recorded signals take 8 bytes per signal and step
#: (about 56 MB here) and a run about 15 s.
MAX_STEPS = 1_000_000


class _Interrupted(Exception):
    """SIGINT arrived during a run (raised between steps, turned into KeyboardInterrupt)."""


class CoSimError(DroneflyError):
    """Bad co-simulation set-up (names the offending value)."""


def step_count(stop: float, step: float, unit: str = "wing beats") -> int:
    """Whole communication steps of ``step`` that fit in ``stop`` (never past it).

    Raises
    ------
    CoSimError
        Non-finite or non-positive values, a stop shorter than one step, or more than
        :data:`MAX_STEPS` steps.
    """
    for label, v in (("step", step), ("stop", stop)):
        if not (math.isfinite(v) and v > 0.0):
            raise CoSimError(f"{label} = {v!r} {unit} must be finite and > 0")
    ratio = stop / step * (1.0 + 1e-12)
    if not math.isfinite(ratio) or ratio > MAX_STEPS + 1:
        raise CoSimError(f"stop / step = {stop!r} / {step!r} = {ratio:.3g} communication steps "
                         f"exceeds the limit of {MAX_STEPS}")
    n = math.floor(ratio)
    if n < 1:
        raise CoSimError(f"stop = {stop!r} is shorter than one step ({step!r}) ({unit})")
    if n > MAX_STEPS:
        raise CoSimError(f"stop / step = {stop!r} / {step!r} = {n} communication steps exceeds "
                         f"the limit of {MAX_STEPS}")
    return n


def _names(md: Any, causality: str) -> list[str]:
    return [v.name for v in md.modelVariables if v.causality == causality]


def connect_by_name(plant_md: Any, controller_md: Any,
                    where: tuple[str, str] = ("", "")) -> list[tuple[str, str, str, str]]:
    """Connections of a plant/controller pair by variable name.

    Every controller input is driven by the plant output of that name, every plant input by
    the controller output of that name. Returns (source element, variable, target element,
    variable) with elements ``"plant"`` and ``"controller"``, controller inputs first.

    Raises
    ------
    CoSimError
        An input has no output of that name on the other side (the message names it and,
        if given, where the other FMU is).
    """
    p_out, c_out = set(_names(plant_md, "output")), set(_names(controller_md, "output"))
    cons = []
    for name in _names(controller_md, "input"):
        if name not in p_out:
            raise CoSimError(f"controller input {name!r} has no plant output of that name"
                             + (f" ({where[0]})" if where[0] else ""))
        cons.append(("plant", name, "controller", name))
    for name in _names(plant_md, "input"):
        if name not in c_out:
            raise CoSimError(f"plant input {name!r} has no controller output of that name"
                             + (f" ({where[1]})" if where[1] else ""))
        cons.append(("controller", name, "plant", name))
    return cons


class Loop:
    """A plant/controller pair connected by name.

    Parameters
    ----------
    plant, controller : FMU
        Extracted FMUs (see :class:`harness.cosim.fmu.FMU`).

    Raises
    ------
    CoSimError
        A controller input has no plant output of the same name, or a plant input no
        controller output (the message names the variable).
    """

    def __init__(self, plant: FMU, controller: FMU) -> None:
        self.plant, self.controller = plant, controller
        self.states = plant.names("output")
        self.controls = plant.names("input")
        connect_by_name(plant.model_description, controller.model_description,
                        where=(str(plant.path), str(controller.path)))
        self.sensed = controller.names("input")  # subset of states, controller order
        self.names = [*self.states, *self.controls]

    def run(self, step_s: float, n_steps: int, *, master: str = "gauss-seidel",
            plant_start: Mapping[str, float] | None = None,
            controller_params: Mapping[str, float] | None = None,
            u_source0: Sequence[float] | None = None,
            instances: tuple[Instance, Instance] | None = None) -> LoopRun:
        """Co-simulate ``n_steps`` communication steps of ``step_s`` seconds from t = 0.

        ``plant_start`` and ``controller_params`` are set in initialization mode.
        ``u_source0`` (Jacobi only) is what the controller is fed before the first step
        (default: the plant's initial outputs). ``instances`` lets a caller reuse
        instances across runs (they are reset first and not freed here).
        """
        if master not in MASTERS:
            raise CoSimError(f"master = {master!r}; choose one of {', '.join(MASTERS)}")
        if not (math.isfinite(step_s) and step_s > 0.0):
            raise CoSimError(f"step = {step_s!r} s must be finite and > 0")
        if not 1 <= n_steps <= MAX_STEPS:
            raise CoSimError(f"n_steps = {n_steps!r} must be in 1..{MAX_STEPS}")
        if instances is None:
            with self.plant.instantiate() as p, self.controller.instantiate() as c:
                return self._run(p, c, step_s, n_steps, master, plant_start, controller_params,
                                 u_source0)
        p, c = instances
        p.slave.reset()
        c.slave.reset()
        return self._run(p, c, step_s, n_steps, master, plant_start, controller_params, u_source0)

    # -------------------------------------------------------------------------
    def _run(self, p: Instance, c: Instance, step: float, n_steps: int, master: str,
             plant_start: Mapping[str, float] | None,
             controller_params: Mapping[str, float] | None,
             u_source0: Sequence[float] | None) -> LoopRun:
        from fmpy.fmi1 import FMICallException

        ns, nu = len(self.states), len(self.controls)
        rec = np.full((n_steps + 1, ns + nu), np.nan)
        time = np.arange(n_steps + 1) * step
        run = LoopRun(self.names, time, rec)
        # preallocated ctypes buffers: plant outputs -> controller inputs -> plant inputs
        y_vr = (c_uint * ns)(*p.vrs(self.states))
        s_vr = (c_uint * len(self.sensed))(*c.vrs(self.sensed))
        s_idx = [self.states.index(n) for n in self.sensed]
        u_vr_c = (c_uint * nu)(*c.vrs(self.controls))
        u_vr_p = (c_uint * nu)(*p.vrs(self.controls))
        y = (c_double * ns)()
        ys = (c_double * len(self.sensed))()
        u = (c_double * nu)()
        who, call, t = p, "initialization", 0.0
        interrupt_scope = contextlib.ExitStack()
        interrupt = interrupt_scope.enter_context(deferred_sigint())
        try:
            for inst, values in ((p, plant_start), (c, controller_params)):
                who = inst
                inst.slave.setupExperiment(startTime=0.0, stopTime=n_steps * step)
                inst.slave.enterInitializationMode()
                for name, value in (values or {}).items():
                    if isinstance(value, bool):
                        inst.slave.setBoolean([inst.fmu.vr(name)], [value])
                    else:
                        inst.slave.setReal([inst.fmu.vr(name)], [float(value)])
            who = p
            p.slave.exitInitializationMode()
            who, call = p, "fmi2GetReal"
            p.slave.fmi2GetReal(p.slave.component, y_vr, ns, y)
            if master == "jacobi" and u_source0 is not None:
                ys[:] = [float(v) for v in u_source0]
            else:
                ys[:] = [y[i] for i in s_idx]
            who, call = c, "fmi2SetReal"
            c.slave.fmi2SetReal(c.slave.component, s_vr, len(ys), ys)
            c.slave.exitInitializationMode()
            pg, ps, pd, pc = (p.slave.fmi2GetReal, p.slave.fmi2SetReal, p.slave.fmi2DoStep,
                              p.slave.component)
            cg, cs, cd, cc = (c.slave.fmi2GetReal, c.slave.fmi2SetReal, c.slave.fmi2DoStep,
                              c.slave.component)
            gauss = master == "gauss-seidel"
            nsense = len(self.sensed)
            if sorted(self.sensed) == sorted(self.states):  # no gather: y feeds c as it is
                s_vr = (c_uint * ns)(*c.vrs(self.states))
                ys = y
                s_idx = []
            for k in range(n_steps + 1):
                t = k * step
                if interrupt.count:  # Ctrl-C: stop between steps, never inside an FMU
                    raise _Interrupted
                who, call = p, "fmi2GetReal"
                pg(pc, y_vr, ns, y)
                if gauss:
                    if s_idx:
                        ys[:] = [y[i] for i in s_idx]
                    who, call = c, "fmi2SetReal"
                    cs(cc, s_vr, nsense, ys)
                    who, call = c, "fmi2GetReal"
                    cg(cc, u_vr_c, nu, u)
                else:  # controller still holds the previous point's inputs
                    who, call = c, "fmi2GetReal"
                    cg(cc, u_vr_c, nu, u)
                    if s_idx:
                        ys[:] = [y[i] for i in s_idx]
                    who, call = c, "fmi2SetReal"
                    cs(cc, s_vr, nsense, ys)
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
            for inst in (p, c):
                who, call = inst, "fmi2Terminate"
                inst.slave.terminate()
        except FMICallException as e:
            last = who.messages[-1].message if who.messages else ""
            run.failure = StepFailure(who.fmu.name, call, t, e.status, last)
            for inst in (p, c):  # terminate what can be terminated; freeing follows anyway
                try:
                    inst.slave.terminate()
                except FMICallException:
                    pass
            keep = int(np.argmax(np.isnan(rec).any(axis=1))) if np.isnan(rec).any() else len(rec)
            run.time, run.signals = time[:keep], rec[:keep]
        except _Interrupted:
            for inst in (p, c):
                try:
                    inst.slave.terminate()
                except FMICallException:
                    pass
            raise KeyboardInterrupt from None  # the instances are freed on the way out
        except (FMUError, OSError) as e:
            raise CoSimError(str(e)) from e
        finally:
            interrupt_scope.close()
        run.messages = [m.message for inst in (p, c) for m in inst.messages]
        return run
