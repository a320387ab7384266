"""Hover as a periodic orbit, and how far the averaged model is from it.

The wing-beat-resolved model (:mod:`dronefly.models.flapping`) hovers on a periodic orbit:
:meth:`FlappingModel.periodic_orbit` finds it by shooting. Its monodromy matrix (central
differences of the wing-beat map about the orbit's start, in the reduced coordinates u, v, w,
p, q, r, phi, theta; position and heading are neutral) has the multipliers mu; the Floquet
exponents log(mu) per wing beat are what the eigenvalues of the averaged model claim to be.
The orbit is left-right symmetric, so the monodromy splits exactly into a lateral block
(v, p, r, phi) and a longitudinal one (u, w, q, theta).

Beside them, per axis:

- ``averaged``: the same model with the forces replaced by their cycle average (the same
  rigid body, mass and inertias from the Sect. 2.4 data, no wing inertia): the eigenvalues the
  averaged theory gives for the same insect. The difference in per cent is the measured error of
  the averaged model;
- ``quasi_steady``: the eigenvalues of the quasi-steady derivatives in the paper's linear
  model (the paper's m+, inertias, g+; :func:`dronefly.harness.aero.compare.eigenvalues`);
- ``paper``: Eq. (12)'s lateral A and Sect. 3.5's longitudinal A.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from ...models.flapping import Floquet, FlappingModel, PeriodicOrbit
from ...models.lateral import sort_eigenvalues
from ..aero.compare import derivative_table, eigenvalues

__all__ = ["AXES", "FloquetReport", "averaged_exponents", "convergence", "floquet_report"]

#: the reduced coordinates of each axis (indices into dronefly.models.flapping.Z_NAMES)
AXES: dict[str, tuple[int, ...]] = {"lateral": (1, 3, 5, 6), "longitudinal": (0, 2, 4, 7)}


def _block_exponents(M: np.ndarray, period: float) -> dict[str, list[complex]]:
    """log(eig) / period of each axis' block of a monodromy matrix, in the project's order."""
    out = {}
    for axis, idx in AXES.items():
        mu = np.linalg.eigvals(M[np.ix_(idx, idx)])
        out[axis] = sort_eigenvalues(np.log(mu.astype(complex)) / period)
    return out


def averaged_exponents(model: FlappingModel) -> dict[str, list[complex]]:
    """Eigenvalues per wing beat of the averaged twin of ``model`` (same aerodynamics, rigid
    body and grid): log of the eigenvalues of its exact one-beat map about the trimmed hover."""
    twin = FlappingModel(model.qs, model.steps_per_beat, averaged=True)
    return _block_exponents(twin.monodromy(np.zeros(8)), twin.period)


def _pct(a: complex, b: complex) -> float:
    return 100.0 * abs(a - b) / abs(b)


def _paired(values: Sequence[complex], reference: Sequence[complex]) -> list[complex]:
    """``values`` reordered to pair each reference value with its nearest (greedy)."""
    left = list(values)
    out = []
    for r in reference:
        j = min(range(len(left)), key=lambda i: abs(left[i] - r))
        out.append(left.pop(j))
    return out


@dataclass
class FloquetReport:
    """The orbit, its Floquet exponents and the eigenvalues beside them (per wing beat)."""

    steps_per_beat: int
    orbit: PeriodicOrbit
    oscillation: dict[str, float]
    floquet: dict[str, list[complex]]
    averaged: dict[str, list[complex]]
    quasi_steady: dict[str, list[complex]]
    paper: dict[str, list[complex]]
    multipliers: list[complex] = field(default_factory=list)

    def error_pct(self) -> dict[str, list[float]]:
        """|Floquet exponent - averaged eigenvalue| / |averaged eigenvalue|, per cent, each
        exponent paired with its nearest eigenvalue, in the averaged eigenvalues' order."""
        return {axis: [_pct(f, a) for f, a in zip(_paired(self.floquet[axis], ev), ev)]
                for axis, ev in self.averaged.items()}

    def to_json(self) -> dict[str, object]:
        def cx(values: Sequence[complex]) -> list[list[float]]:
            return [[float(complex(z).real), float(complex(z).imag)] for z in values]

        return {
            "period_s": 1.0 / self.orbit.model.n * self.orbit.model.period,
            "steps_per_beat": self.steps_per_beat,
            "orbit_start": {n: float(v) for n, v in zip(
                ("u", "v", "w", "p", "q", "r", "phi", "theta"), self.orbit.z0)},
            "newton_residuals": self.orbit.residuals,
            "oscillation": self.oscillation,
            "floquet_exponents": cx([*self.floquet["lateral"], *self.floquet["longitudinal"]]),
            "averaged_eigenvalues": cx([*self.averaged["lateral"],
                                        *self.averaged["longitudinal"]]),
            "by_axis": {axis: {"floquet": cx(self.floquet[axis]),
                               "averaged": cx(self.averaged[axis]),
                               "quasi_steady": cx(self.quasi_steady[axis]),
                               "paper": cx(self.paper[axis]),
                               "error_pct": self.error_pct()[axis]} for axis in AXES},
        }

    def text(self) -> str:
        o = self.oscillation
        lines = [
            f"periodic orbit ({self.steps_per_beat} Runge-Kutta steps per wing beat): Newton "
            f"residual {_bound(self.orbit.residuals[-1])} after {len(self.orbit.residuals) - 1} "
            "steps",
            f"start of the beat: du+ {self.orbit.z0[0]:+.5f}, dw+ {self.orbit.z0[2]:+.5f}, "
            f"dq+ {self.orbit.z0[4]:+.5f}, theta {math.degrees(self.orbit.z0[7]):+.4f} deg",
            f"oscillation within the beat (peak to peak): x {o['x_pp_um']:.1f} um, "
            f"z {o['z_pp_um']:.2f} um, pitch {o['theta_pp_deg']:.3f} deg; "
            f"y, roll, yaw {max(o['y_pp_um'], o['phi_pp_deg'], o['psi_pp_deg']):.1g}",
            f"mean drift on the orbit: {o['x_drift_mm_per_s']:.2f} mm/s forward, "
            f"{o['z_drift_mm_per_s']:.2f} mm/s down",
        ]
        err = self.error_pct()
        for axis in AXES:
            lines.append("")
            lines.append(f"{axis} per wing beat")
            lines.append("  Floquet exponents (flapping): "
                         + ", ".join(_fmt(z) for z in _paired(self.floquet[axis],
                                                               self.averaged[axis])))
            for who in ("averaged", "quasi_steady", "paper"):
                label = {"averaged": "averaged model (same body)",
                         "quasi_steady": "quasi-steady derivatives, paper's inertias",
                         "paper": "paper"}[who]
                lines.append(f"  {label}: " + ", ".join(_fmt(z) for z in getattr(self, who)[axis]))
            lines.append("  error of the averaged model: "
                         + ", ".join(f"{e:.1f} %" for e in err[axis]))
        return "\n".join(lines)


def _bound(value: float) -> str:
    return "< 1e-12" if value < 1e-12 else f"{value:.0e}"


def _fmt(z: complex) -> str:
    z = complex(z)
    if abs(z.imag) < 1e-12:
        return f"{z.real:+.4f}"
    return f"{z.real:+.4f}{z.imag:+.4f}i"


def floquet_report(model: FlappingModel | None = None) -> FloquetReport:
    """The periodic orbit of ``model`` (default: the flapping drone fly), its Floquet exponents
    and the eigenvalues beside them."""
    model = model or FlappingModel()
    orbit = model.periodic_orbit()
    fl = Floquet.of(model, orbit)
    qs_values = {r.parameter: r.quasi_steady for r in derivative_table(model.qs)}
    paper_values = {r.parameter: r.paper for r in derivative_table(model.qs)}
    return FloquetReport(
        steps_per_beat=model.steps_per_beat, orbit=orbit, oscillation=orbit.oscillation(),
        floquet=_block_exponents(fl.monodromy, model.period),
        averaged=averaged_exponents(model),
        quasi_steady=eigenvalues(qs_values), paper=eigenvalues(paper_values),
        multipliers=list(fl.multipliers))


def convergence(factors: Sequence[float] = (1.0, 2.0, 4.0, 8.0),
                steps_per_beat: int = 20) -> str:
    """The averaging experiment: the wing beat ``factor`` times faster with the forces at each
    phase unchanged (the averaged model is the same); the largest error of the Floquet
    exponents against the averaged eigenvalues per axis, which falls as the factor grows."""
    base = FlappingModel(steps_per_beat=steps_per_beat)
    avg = averaged_exponents(base)
    lines = [f"frequency factor  lateral error  longitudinal error  ({steps_per_beat} steps "
             "per period)"]
    for s in factors:
        m = FlappingModel(base.qs, steps_per_beat, frequency_factor=s)
        fl = _block_exponents(Floquet.of(m, m.periodic_orbit()).monodromy, m.period)
        errs = {axis: max(_pct(f, a) for f, a in zip(_paired(fl[axis], avg[axis]), avg[axis]))
                for axis in AXES}
        lines.append(f"{s:16g}  {errs['lateral']:11.2f} %  {errs['longitudinal']:16.2f} %")
    return "\n".join(lines)
