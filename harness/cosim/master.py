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

Every instance is terminated and freed on every exit path (instances a caller gives to
:meth:`Loop.run` are reset, terminated and left to the caller).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, Mapping, Sequence

from ...core.errors import DroneflyError
from .fmu import FMU, FMUError, Instance
from .graph import Order
from .records import MASTERS, MAX_STEPS, LoopRun, StepFailure
from .system import System, SystemSpecError
from .system_master import SystemMaster

__all__ = ["MASTERS", "MAX_STEPS", "CoSimError", "Loop", "LoopRun", "StepFailure", "connect_by_name",
           "step_count"]

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
    """A plant/controller pair connected by name, run on the system master.

    Parameters
    ----------
    plant, controller : FMU
        Extracted FMUs (see :class:`harness.cosim.fmu.FMU`); the system master uses them as
        they are (they stay the caller's to close).

    Raises
    ------
    CoSimError
        A controller input has no plant output of the same name, or a plant input no
        controller output (the message names the variable); a connection of different types
        or units.
    """

    def __init__(self, plant: FMU, controller: FMU) -> None:
        self.plant, self.controller = plant, controller
        self.states = plant.names("output")
        self.controls = plant.names("input")
        connect_by_name(plant.model_description, controller.model_description,
                        where=(str(plant.path), str(controller.path)))
        self.sensed = controller.names("input")  # subset of states, controller order
        self.names = [*self.states, *self.controls]
        self.system = System.by_name({"plant": plant, "controller": controller})
        self._record = [*(f"plant.{s}" for s in self.states),
                        *(f"controller.{u}" for u in self.controls)]
        self._masters: dict[str, Any] = {}
        self.master("gauss-seidel")  # checks the connections' types and units

    def master(self, master: str = "gauss-seidel") -> Any:
        """The :class:`SystemMaster` of the pair under ``master`` (made once)."""

        if master not in self._masters:
            try:
                self._masters[master] = SystemMaster(
                    self.system, master, fmus={"plant": self.plant, "controller": self.controller},
                    order=Order(free=("plant",), chained=("controller",)),
                    instance_names={"plant": self.plant.name,
                                    "controller": self.controller.name})
            except SystemSpecError as e:
                raise CoSimError(str(e)) from e
        return self._masters[master]

    def run(self, step_s: float, n_steps: int, *, master: str = "gauss-seidel",
            plant_start: Mapping[str, float] | None = None,
            controller_params: Mapping[str, float] | None = None,
            u_source0: Sequence[float] | None = None,
            instances: tuple[Instance, Instance] | None = None,
            record: Sequence[str] = ()) -> LoopRun:
        """Co-simulate ``n_steps`` communication steps of ``step_s`` seconds from t = 0.

        ``plant_start`` and ``controller_params`` are set in initialization mode.
        ``u_source0`` (Jacobi only) is what the controller is fed before the first step
        (default: the plant's initial outputs). ``instances`` lets a caller reuse
        instances across runs (they are reset first and not freed here). The recorded
        names are :attr:`names` (the plant's outputs, then its inputs), then ``record``:
        more variables ``plant.NAME`` or ``controller.NAME`` of any causality and of type
        Real, Integer or Boolean (see :meth:`SystemMaster.run`). A failure names the FMU
        (its model name), the call and the time.
        """

        if master not in MASTERS:
            raise CoSimError(f"master = {master!r}; choose one of {', '.join(MASTERS)}")
        if not (math.isfinite(step_s) and step_s > 0.0):
            raise CoSimError(f"step = {step_s!r} s must be finite and > 0")
        if not 1 <= n_steps <= MAX_STEPS:
            raise CoSimError(f"n_steps = {n_steps!r} must be in 1..{MAX_STEPS}")
        inputs0 = None
        if master == "jacobi" and u_source0 is not None:
            if len(u_source0) != len(self.sensed):
                raise CoSimError(f"u_source0 has {len(u_source0)} values; the controller has "
                                 f"{len(self.sensed)} inputs ({', '.join(self.sensed)})")
            inputs0 = {"controller": dict(zip(self.sensed, u_source0))}
        sm = self.master(master)
        try:
            run = sm.run(step_s, n_steps, record=[*self._record, *record],
                         values={"plant": dict(plant_start or {}),
                                 "controller": dict(controller_params or {})},
                         instances=None if instances is None else dict(
                             zip(("plant", "controller"), instances)),
                         inputs0=inputs0)
        except (SystemSpecError, FMUError, OSError) as e:
            raise CoSimError(str(e)) from e
        run.names = [*self.names, *record]
        if run.failure is not None:  # named by the FMU, as the pair's messages always were
            fmu = {"plant": self.plant, "controller": self.controller}[run.failure.fmu]
            run.failure = dataclasses.replace(run.failure, fmu=fmu.name)
        return run
