"""How far the averaged model is from hover as a periodic orbit: the report.

The wing-beat-resolved model (:mod:`dronefly.models.flapping`) hovers on a periodic orbit;
:mod:`dronefly.models.flapping.orbit` finds it by shooting and gives its Floquet exponents
log(mu) per wing beat, per axis (the monodromy splits exactly into a lateral block (v, p, r,
phi) and a longitudinal one (u, w, q, theta)): what the eigenvalues of the averaged model claim
to be. This module sets them beside the eigenvalues of the other models.

Beside them, per axis:

- ``averaged``: the same model with the forces replaced by their cycle average (the same
  rigid body, mass and inertias from the Sect. 2.4 data, no wing inertia): the eigenvalues the
  averaged theory gives for the same insect. The difference in per cent is the measured error of
  the averaged model;
- ``quasi_steady``: the eigenvalues of the quasi-steady derivatives in the paper's linear
  model (the paper's m+, inertias, g+; :func:`dronefly.harness.aero.beside_paper.eigenvalues`);
- ``paper``: Eq. (12)'s lateral A and Sect. 3.5's longitudinal A.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from ...core.text import complex_text
from ...models.flapping import (AXES, Floquet, FlappingModel, PeriodicOrbit, averaged_monodromy,
                                block_exponents, periodic_orbit)
from ..aero.beside_paper import derivative_table, eigenvalues

__all__ = ["FloquetReport", "convergence", "convergence_rows", "floquet_report", "readme_paragraph"]


def _power(M: np.ndarray, p: float) -> np.ndarray:
    """M**p for a matrix with no eigenvalue on the negative real axis (real result)."""
    w, V = np.linalg.eig(M)
    return np.real(V @ np.diag(w.astype(complex) ** p) @ np.linalg.inv(V))


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

    def pairs(self) -> dict[str, list[tuple[complex, complex]]]:
        """(Floquet exponent, averaged eigenvalue) per axis, each eigenvalue with its nearest
        exponent, in the averaged eigenvalues' order."""
        return {axis: list(zip(_paired(self.floquet[axis], ev), ev))
                for axis, ev in self.averaged.items()}

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
            f"residual {_bound(self.orbit.residuals[-1])} (wing-beat map minus start)",
            f"start of the beat: du+ {self.orbit.z0[0]:+.5f}, dw+ {self.orbit.z0[2]:+.5f}, "
            f"dq+ {self.orbit.z0[4]:+.5f}, theta {math.degrees(self.orbit.z0[7]):+.4f} deg",
            f"oscillation within the beat (peak to peak): x {o['x_pp_um']:.1f} um, "
            f"z {o['z_pp_um']:.2f} um, pitch {o['theta_pp_deg']:.3f} deg; "
            "y, roll and yaw " + ("< 1e-9 (symmetric)" if max(
                o['y_pp_um'], o['phi_pp_deg'], o['psi_pp_deg']) < 1e-9 else
                f"{max(o['y_pp_um'], o['phi_pp_deg'], o['psi_pp_deg']):.3g}"),
            f"mean drift on the orbit: {o['x_drift_mm_per_s']:.2f} mm/s forward, "
            f"{o['z_drift_mm_per_s']:.2f} mm/s down",
        ]
        err = self.error_pct()
        for axis in AXES:
            lines.append("")
            lines.append(f"{axis} per wing beat")
            lines.append("  Floquet exponents (flapping): "
                         + ", ".join(complex_text(z) for z in _paired(self.floquet[axis],
                                                               self.averaged[axis])))
            for who in ("averaged", "quasi_steady", "paper"):
                label = {"averaged": "averaged model (same body)",
                         "quasi_steady": "quasi-steady derivatives, paper's inertias",
                         "paper": "paper"}[who]
                lines.append(f"  {label}: " + ", ".join(complex_text(z) for z in getattr(self, who)[axis]))
            lines.append("  error of the averaged model: "
                         + ", ".join(f"{e:.1f} %" for e in err[axis]))
        return "\n".join(lines)


def _bound(value: float) -> str:
    return "< 1e-12" if value < 1e-12 else f"{value:.0e}"


def floquet_report(model: FlappingModel | None = None) -> FloquetReport:
    """The periodic orbit of ``model`` (default: the flapping drone fly), its Floquet exponents
    and the eigenvalues beside them."""
    model = model or FlappingModel()
    M_avg = averaged_monodromy(model)
    orbit = periodic_orbit(model, jacobian=M_avg)
    fl = Floquet.of(model, orbit)
    table = derivative_table(model.qs)
    qs_values = {r.parameter: r.quasi_steady for r in table}
    paper_values = {r.parameter: r.paper for r in table}
    return FloquetReport(
        steps_per_beat=model.steps_per_beat, orbit=orbit, oscillation=orbit.oscillation(),
        floquet=block_exponents(fl.monodromy, model.period),
        averaged=block_exponents(M_avg, model.period),
        quasi_steady=eigenvalues(qs_values), paper=eigenvalues(paper_values),
        multipliers=list(fl.multipliers))


def convergence_rows(factors: Sequence[float] = (1.0, 2.0, 4.0, 8.0),
                     steps_per_beat: int = 20) -> list[tuple[float, float, float]]:
    """The averaging experiment: the wing beat ``factor`` times faster with the forces at each
    phase unchanged (the averaged model is the same); per factor the largest error of the
    Floquet exponents against the averaged eigenvalues, lateral and longitudinal, per cent."""
    base = FlappingModel(steps_per_beat=steps_per_beat)
    M_avg = averaged_monodromy(base)
    avg = block_exponents(M_avg, 1.0)
    rows = []
    for s in factors:
        m = FlappingModel(base.qs, steps_per_beat, frequency_factor=s)
        # the averaged map over the shorter period: the Newton steps' Jacobian
        M_s = M_avg if s == 1.0 else _power(M_avg, 1.0 / s)
        fl = block_exponents(Floquet.of(m, periodic_orbit(m, jacobian=M_s)).monodromy, m.period)
        errs = {axis: max(_pct(f, a) for f, a in zip(_paired(fl[axis], avg[axis]), avg[axis]))
                for axis in AXES}
        rows.append((float(s), errs["lateral"], errs["longitudinal"]))
    return rows


def convergence(rows: Sequence[tuple[float, float, float]] | None = None,
                steps_per_beat: int = 20) -> str:
    """:func:`convergence_rows` as a table."""
    rows = convergence_rows(steps_per_beat=steps_per_beat) if rows is None else rows
    lines = [f"frequency factor  lateral error  longitudinal error  ({steps_per_beat} steps "
             "per period)"]
    lines += [f"{s:16g}  {a:11.2f} %  {b:16.2f} %" for s, a, b in rows]
    return "\n".join(lines)


def readme_paragraph(report: FloquetReport, without_inertia: FloquetReport,
           rows: Sequence[tuple[float, float, float]]) -> str:
    """The answer in three sentences (docs/averaging.md, README)."""
    o, o0 = report.oscillation, without_inertia.oscillation
    err = report.error_pct()
    all_err = [e for v in err.values() for e in v]
    return (
        f"Hover is a periodic orbit: the body moves {o['x_pp_um']:.1f} micrometres fore and aft "
        f"and pitches {o['theta_pp_deg']:.3f} deg per wing beat ({o0['x_pp_um']:.1f} and "
        f"{o0['theta_pp_deg']:.3f} without wing inertia). The averaged model's eigenvalues are "
        f"{min(all_err):.1f} to {max(all_err):.1f} % off the Floquet exponents (lateral "
        f"instability {report.averaged['lateral'][0].real:+.4f} averaged, "
        f"{report.floquet['lateral'][0].real:+.4f} flapping); every mode keeps its type and "
        f"stability. With the wing beat {rows[-1][0]:g} times faster the error falls to "
        f"{max(rows[-1][1:]):.2f} %, as 1/frequency.")
