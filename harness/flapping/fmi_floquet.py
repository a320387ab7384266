"""Floquet analysis through FMI: the periodic orbit and the monodromy matrix of any co-simulation
FMU that can get and set its state, by finite differences of its one-period map.

The FMU's state is reached through its interface only. Its states are the outputs ``x`` that
have a start parameter ``x_start`` (the project's convention for every plant), less the neutral
ones (position and heading, whose multipliers are 1 by symmetry). One evaluation of the
one-period map: ``fmi2SetFMUstate`` back to the state saved in Initialization Mode (right after
``fmi2EnterInitializationMode``), the start values set, ``fmi2ExitInitializationMode``, steps
over one period, the state outputs read. So every evaluation starts from the same FMU state,
whatever the one before did, and no fmi2Reset or re-instantiation is needed.

On it: Newton's method for the periodic orbit (the fixed point of the map; the chord method with
the monodromy matrix at the first guess) and the monodromy matrix at the orbit by central
differences, step ``rel_step`` times each state's scale (U for velocities, n for rates, 1 for
angles). The Floquet exponents are log(mu) of its eigenvalues, per wing beat (1/n) when the FMU
has a parameter ``n``, else per period.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from ..builder.build import ensure_fmu
from ...core.errors import DroneflyError
from ...core.interrupt import checkpoint
from ...models.flapping import FlappingModel, averaged_exponents
from ...models.lateral_interface import sort_eigenvalues
from ...models.shooting import shooting
from ..cosim.fmu import FMU

__all__ = ["NEUTRAL", "FmiFloquet", "FmiPeriodicMap", "floquet_analysis", "floquet_text",
           "fmi_floquet"]

#: states left out: neutral by symmetry (a shift of position or heading is a periodic orbit too)
NEUTRAL: tuple[str, ...] = ("psi", "x_earth", "y_earth", "z_earth")


class FmiPeriodicMap:
    """The one-period map of an FMU's states, through FMI 2.0 get/set FMU state.

    Parameters
    ----------
    path : str or Path
        The FMU (FMI 2.0 co-simulation, canGetAndSetFMUstate).
    period_s : float, optional
        The period [s]; default 1/n from the FMU's parameter ``n`` (one wing beat).
    steps : int
        Communication steps per period.
    starts : mapping, optional
        Start values of other parameters (held in every evaluation).
    """

    def __init__(self, path: str | Path, period_s: float | None = None, steps: int = 1,
                 starts: Mapping[str, float] | None = None) -> None:
        self.fmu = FMU(path)
        md = self.fmu.model_description
        cs = md.coSimulation
        if not getattr(cs, "canGetAndSetFMUstate", False):
            raise DroneflyError(f"{self.fmu.name}: cannot get and set its FMU state "
                                "(canGetAndSetFMUstate is not true)")
        params = set(self.fmu.names("parameter"))
        self.states = [o for o in self.fmu.names("output")
                       if f"{o}_start" in params and o not in NEUTRAL]
        if not self.states:
            raise DroneflyError(f"{self.fmu.name}: no output x with a parameter x_start")
        start = self.fmu.start_values()
        self.n = float(start["n"]) if "n" in start else None
        if period_s is None:
            if self.n is None:
                raise DroneflyError(f"{self.fmu.name}: no parameter n; give the period")
            period_s = 1.0 / self.n
        if not (math.isfinite(period_s) and period_s > 0.0):
            raise DroneflyError(f"period {period_s!r} s must be finite and > 0")
        self.period_s = float(period_s)
        self.steps = int(steps)
        self.beats_per_period = self.period_s * self.n if self.n else 1.0
        units = {v.name: (v.declaredType.unit if v.declaredType is not None and v.unit is None
                          else v.unit) for v in md.modelVariables}
        U = float(start.get("U", 1.0))
        n = self.n or 1.0
        self.scales = np.array([U if units.get(s) == "m/s" else n if units.get(s) == "rad/s"
                                else 1.0 for s in self.states])
        self.evaluations = 0
        self._starts = dict(starts or {})
        self._inst = self.fmu.instantiate("floquet", logging=False)
        s = self._inst.slave
        s.setupExperiment(startTime=0.0)
        s.enterInitializationMode()
        self._init_state = s.getFMUstate()
        self._vr_start = [self.fmu.vr(f"{x}_start") for x in self.states]
        self._vr_out = [self.fmu.vr(x) for x in self.states]
        self._vr_other = [self.fmu.vr(k) for k in self._starts]

    def __call__(self, x: Sequence[float]) -> np.ndarray:
        """The states one period after starting from ``x`` (SI, :attr:`states` order)."""
        s = self._inst.slave
        s.setFMUstate(self._init_state)
        if self._vr_other:
            s.setReal(self._vr_other, list(self._starts.values()))
        s.setReal(self._vr_start, [float(v) for v in x])
        s.exitInitializationMode()
        h = self.period_s / self.steps
        for k in range(self.steps):
            checkpoint()  # Ctrl-C: between steps, never inside the FMU
            s.doStep(currentCommunicationPoint=k * h, communicationStepSize=h)
        self.evaluations += 1
        return np.array(s.getReal(self._vr_out))

    def monodromy(self, x: Sequence[float], rel_step: float = 1e-6) -> np.ndarray:
        """Central differences of the map about ``x``."""
        x = np.asarray(x, dtype=float)
        cols = []
        for j in range(len(x)):
            dx = np.zeros(len(x))
            dx[j] = rel_step * self.scales[j]
            cols.append((self(x + dx) - self(x - dx)) / (2.0 * dx[j]))
        return np.column_stack(cols)

    def close(self) -> None:
        try:
            self._inst.free()
        finally:
            self.fmu.close()

    def __enter__(self) -> "FmiPeriodicMap":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


@dataclass
class FmiFloquet:
    """The orbit's start, the monodromy matrix and the Floquet exponents through FMI."""

    states: list[str]
    period_s: float
    orbit_start: np.ndarray
    residuals: list[float]
    monodromy: np.ndarray
    exponents: list[complex]  # per wing beat (or per period without n), project's order
    evaluations: int

    def to_json(self) -> dict[str, object]:
        return {"period_s": self.period_s, "states": self.states,
                "orbit_start": dict(zip(self.states, map(float, self.orbit_start))),
                "newton_residuals": self.residuals,
                "floquet_exponents": [[float(z.real), float(z.imag)] for z in self.exponents],
                "evaluations": self.evaluations}


def fmi_floquet(path: str | Path, period_s: float | None = None, *, steps: int = 1,
                tol: float = 1e-12, max_iter: int = 30, rel_step: float = 1e-6,
                jacobian: np.ndarray | None = None) -> FmiFloquet:
    """The periodic orbit (Newton from the zero state, residual below ``tol`` of each state's
    scale) and its Floquet exponents, through FMI.

    ``jacobian``: an approximation of the monodromy matrix for the Newton steps (in the FMU's
    state order and SI units); by default the central-difference one at the zero state.
    """
    with FmiPeriodicMap(path, period_s, steps) as F:
        x = np.zeros(len(F.states))
        M0 = F.monodromy(x, rel_step) if jacobian is None else np.asarray(jacobian, dtype=float)
        x, residuals = shooting(F, x, M0, tol, max_iter, F.scales)
        M = F.monodromy(x, rel_step)
        mu = np.linalg.eigvals(M)
        lam = sort_eigenvalues(np.log(mu.astype(complex)) / F.beats_per_period)
        return FmiFloquet(F.states, F.period_s, x, residuals, M, lam, F.evaluations)


def floquet_analysis(plant: str | Path | None = None, period_s: float | None = None,
                     steps: int = 1, build: str | Path = "build") -> dict[str, object]:
    """``dronefly floquet``: the Floquet exponents of ``plant`` through FMI (default: the
    flapping drone fly, built into ``build`` if missing or out of date) and, for the flapping
    plant, the averaged model's eigenvalues beside them (per wing beat).

    Returns the JSON of the command: ``period_s``, ``floquet_exponents`` and
    ``averaged_eigenvalues`` as [re, im] pairs (the latter empty for another FMU), ``states``,
    ``orbit_start``, ``newton_residuals``, ``evaluations`` and ``plant``.
    """
    if plant is None:
        plant, _ = ensure_fmu("DroneFlyFlapping", build)
    result = fmi_floquet(plant, period_s, steps=steps)
    out = {"plant": str(plant), **result.to_json(), "averaged_eigenvalues": []}
    with FMU(plant) as f:
        name = f.name
    if name == "DroneFlyFlapping":
        avg = averaged_exponents(FlappingModel())
        out["averaged_eigenvalues"] = [[float(z.real), float(z.imag)]
                                       for z in sort_eigenvalues([*avg["lateral"],
                                                                  *avg["longitudinal"]])]
    return out


def floquet_text(result: Mapping[str, object]) -> str:
    """The command's table: each exponent beside its nearest averaged eigenvalue."""
    lines = [f"{result['plant']}: period {result['period_s']:.6g} s, states "
             + ", ".join(result["states"]),  # type: ignore[arg-type]
             f"periodic orbit: Newton residual {result['newton_residuals'][-1]:.1e} "  # type: ignore[index]
             f"({result['evaluations']} periods simulated)",
             "Floquet exponents per wing beat" + (
                 "   averaged model   error" if result["averaged_eigenvalues"] else "")]
    avg = [complex(*z) for z in result["averaged_eigenvalues"]]  # type: ignore[union-attr]
    for re_, im in result["floquet_exponents"]:  # type: ignore[union-attr]
        z = complex(re_, im)
        row = f"  {z.real:+.6f}{z.imag:+.6f}i"
        if avg:
            a = min(avg, key=lambda w: abs(w - z))
            row += f"   {a.real:+.6f}{a.imag:+.6f}i   {100 * abs(z - a) / abs(a):.2f} %"
        lines.append(row)
    return "\n".join(lines)
