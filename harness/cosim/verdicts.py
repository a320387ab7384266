"""Per-axis stability verdicts of a co-simulated system, identified from its own runs.

A *plant* of a system is an instance whose every Real output ``x`` has a ``x_start``
parameter and which has the reference scales ``n`` [Hz] and ``U`` [m/s] (both of the
project's linear plants, and any FMU with that interface). Its state is made
non-dimensional by the unit of each output: m/s by U, rad/s by n, rad as it is (the
non-dimensionalisation of both axes, end of Sect. 2.1).

For each plant, runs of the whole system from x+_0 = e_j of that plant (every other plant
at its zero state) give the one-step transition F of its states as the system closes the
loop, fitted by :func:`dronefly.harness.cosim.identification.identify`; its eigenvalues are
the closed-loop rates, and their dominant real part the verdict. The axes being decoupled,
each plant's runs show its own loop. Where the plant's inputs are driven by one controller
with gains ``K[i,j]`` (the project's controllers) the verdict is cross-checked against the
exact sampled-data loop at the same step and against eig(A + B K) of the continuous loop.

The open loop (:func:`open_loop_verdicts`) is identified the same way, from runs of the same
system with those gains ``K[i,j]`` of the controller that drives the plant set to zero, and
cross-checked against eig(A); a plant whose inputs are not driven by one controller with
gains gets the reason instead (:class:`NotIdentified`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ...models.lateral_interface import sort_eigenvalues
from .calculated import calculated_matrix
from .identification import Identification, identify, rates_from_transition, sampled_closed_loop
from .master import CoSimError
from .system_master import SystemMaster

__all__ = ["AxisVerdict", "NotIdentified", "PlantInfo", "axis_verdicts", "find_plants",
           "open_loop_verdicts"]

_UNIT_SCALE = {"m/s": "U", "rad/s": "n", "rad": "1"}


@dataclass(frozen=True)
class PlantInfo:
    """A plant instance of a system: its states, scale vector and, if known, A, B and K."""

    instance: str
    model: str
    states: tuple[str, ...]
    scale: np.ndarray
    n_hz: float
    A: np.ndarray | None = None
    B: np.ndarray | None = None
    K: np.ndarray | None = None  # rows = the plant's inputs, columns = its states (x+)
    controller: str | None = None
    gains: tuple[str, ...] = ()  # the controller's parameters K[i,j] read into K


@dataclass(frozen=True)
class AxisVerdict:
    """What the runs established about one plant's loop."""

    plant: PlantInfo
    identification: Identification
    continuous: np.ndarray | None  # eig(A + B K) (open loop: eig(A)), per wing beat
    sampled: np.ndarray | None  # exact sampled-data loop at the step, per wing beat

    @property
    def verdict(self) -> str:
        return self.identification.verdict

    def to_json(self) -> dict[str, Any]:
        def cx(z: Any) -> Any:
            return None if z is None else [[float(v.real), float(v.imag)] for v in z]
        dev = (None if self.sampled is None or len(self.sampled) != len(
            self.identification.eigenvalues) else float(np.max(np.abs(
                self.sampled - self.identification.eigenvalues))))
        return {"instance": self.plant.instance, "model": self.plant.model,
                "controller": self.plant.controller, "verdict": self.verdict,
                "eigenvalues_per_wingbeat": cx(self.identification.eigenvalues),
                "dominant_growth_rate_per_wingbeat":
                    self.identification.dominant_growth_rate,
                "continuous_eigenvalues_per_wingbeat": cx(self.continuous),
                "sampled_data_eigenvalues_per_wingbeat": cx(self.sampled),
                "max_deviation_from_sampled_data": dev}


@dataclass(frozen=True)
class NotIdentified:
    """A plant whose open loop was not identified, and why (no gains to zero)."""

    plant: PlantInfo
    reason: str

    verdict = None

    def to_json(self) -> dict[str, Any]:
        return {"instance": self.plant.instance, "verdict": None, "reason": self.reason}


def _start(md: Any) -> dict[str, Any]:
    return {v.name: v.start for v in md.modelVariables}


def find_plants(master: SystemMaster) -> list[PlantInfo]:
    """The plants of a system (see the module text), with A, B and K where they can be read."""
    out = []
    conns = master.system.connections
    for inst, fmu in master.fmus.items():
        md = fmu.model_description
        starts = _start(md)
        outs = [v for v in md.modelVariables if v.causality == "output" and v.type == "Real"]
        if not outs or any(f"{v.name}_start" not in starts for v in outs) \
                or "n" not in starts or "U" not in starts:
            continue
        if any(v.unit not in _UNIT_SCALE for v in outs):
            continue
        values = {**starts, **master.system.parameters.get(inst, {})}
        n, U = float(values["n"]), float(values["U"])
        table = {"U": U, "n": n, "1": 1.0}
        scale = np.array([table[_UNIT_SCALE[v.unit]] for v in outs])
        states = tuple(v.name for v in outs)
        inputs = [v.name for v in md.modelVariables if v.causality == "input"]
        given = master.system.parameters.get(inst, {})
        A = calculated_matrix(fmu, "A", len(states), len(states), given)
        B = calculated_matrix(fmu, "B", len(states), len(inputs), given)
        K, ctrl, gains = _gains(master, inst, states, inputs, conns)
        out.append(PlantInfo(inst, md.modelName, states, scale, n, A, B, K, ctrl, gains))
    return out


def _gains(master: SystemMaster, plant: str, states: tuple[str, ...], inputs: list[str],
           conns: Any) -> tuple[np.ndarray | None, str | None, tuple[str, ...]]:
    """K over the plant's inputs x states from the one controller that closes its loop, the
    controller, and the names of the gains read (every column of each row that drives the
    plant)."""
    feeds = {c.input: c for c in conns if c.target == plant}
    sources = {c.source for c in feeds.values()}
    if len(sources) != 1:
        return None, None, ()
    ctrl = sources.pop()
    fmu = master.fmus[ctrl]
    values = {**_start(fmu.model_description), **master.system.parameters.get(ctrl, {})}
    sensed = {c.input: c.output for c in conns if c.source == plant and c.target == ctrl}
    c_inputs = [v.name for v in fmu.model_description.modelVariables if v.causality == "input"]
    c_outputs = [v.name for v in fmu.model_description.modelVariables
                 if v.causality == "output" and v.type == "Real"]
    K = np.zeros((len(inputs), len(states)))
    read = []
    for a, name in enumerate(inputs):
        if name not in feeds:
            continue
        row = c_outputs.index(feeds[name].output)
        for col, c_in in enumerate(c_inputs):
            key = f"K[{row + 1},{col + 1}]"
            if key not in values:
                return None, ctrl, ()
            read.append(key)
            if c_in in sensed:
                K[a, states.index(sensed[c_in])] += float(values[key])
    return K, ctrl, tuple(read)


def axis_verdicts(master: SystemMaster, step_wb: float, n_steps: int = 20) -> list[AxisVerdict]:
    """Identify every plant's loop from runs of the whole system (see the module text).

    A system without plants gives an empty list.

    Raises
    ------
    CoSimError
        An identification run failed (the message says where).
    """
    plants = find_plants(master)
    return [_verdict(master, p, plants, step_wb, n_steps, False) for p in plants]


def open_loop_verdicts(master: SystemMaster, step_wb: float,
                       n_steps: int = 20) -> list[AxisVerdict | NotIdentified]:
    """Every plant's open loop: its runs with the gains of its controller set to zero.

    As :func:`axis_verdicts`, in runs where every gain ``K[i,j]`` the verdicts read for the
    plant (each column of every controller output that drives it) is 0; ``continuous`` is
    then eig(A). A plant with no connected input is run as it is; one whose inputs come from
    several instances, or from a controller without gains ``K[i,j]``, is
    :class:`NotIdentified`.

    Raises
    ------
    CoSimError
        An identification run failed (the message says where).
    """
    plants = find_plants(master)
    out: list[AxisVerdict | NotIdentified] = []
    for p in plants:
        sources = sorted({c.source for c in master.system.connections
                          if c.target == p.instance})
        if len(sources) > 1:
            out.append(NotIdentified(p, f"the inputs of {p.instance} come from "
                                        f"{len(sources)} instances ({', '.join(sources)}), "
                                        "not one controller with gains K[i,j]"))
        elif sources and not p.gains:
            out.append(NotIdentified(p, f"{sources[0]} has no gains K[i,j] for the inputs of "
                                        f"{p.instance} to set to zero"))
        else:
            out.append(_verdict(master, p, plants, step_wb, n_steps, True))
    return out


def _verdict(master: SystemMaster, p: PlantInfo, plants: list[PlantInfo], step_wb: float,
             n_steps: int, open_loop: bool) -> AxisVerdict:
    zero = {q.instance: {f"{s}_start": 0.0 for s in q.states} for q in plants}
    if open_loop and p.controller is not None:
        zero[p.controller] = {**zero.get(p.controller, {}), **dict.fromkeys(p.gains, 0.0)}
    jacobi = master.master == "jacobi"
    h = step_wb / p.n_hz
    runs = []
    for e in np.eye(len(p.states)):
        values = {**zero, p.instance: {**zero[p.instance], **{
            f"{s}_start": float(v) for s, v in zip(p.states, e * p.scale)}}}
        r = master.run(h, n_steps, record=[f"{p.instance}.{s}" for s in p.states],
                       values=values)
        if not r.complete:
            raise CoSimError(f"{'open-loop ' if open_loop else ''}identification run of "
                             f"{p.instance} failed: {r.failure}")
        xs = r.signals / p.scale
        # Jacobi: the controller's first answer is to x_0 itself (initialization runs in
        # Gauss-Seidel order), so x_(-1) = x_0
        runs.append(np.vstack([xs[:1], xs]) if jacobi else xs)
    ident = identify(runs, step_wb, delay=jacobi)
    cont = sampled = None
    K = p.K
    if open_loop and p.A is not None:
        K = np.zeros((0 if p.B is None else p.B.shape[1], len(p.A)))
    if p.A is not None and K is not None and (p.B is not None or not K.size):
        k = len(p.A)
        B = np.zeros((k, 0)) if p.B is None else p.B
        cont = np.array(sort_eigenvalues(np.linalg.eigvals(p.A + B @ K)), dtype=complex)
        sampled = rates_from_transition(sampled_closed_loop(p.A, B, K, step_wb, jacobi), step_wb)
    return AxisVerdict(p, ident, cont, sampled)
