"""The flapping insect's own trim: the wing kinematics whose periodic orbit does not drift.

The quasi-steady trim (``QuasiSteadyModel.trim``) balances the cycle-averaged forces of the
hovering insect at rest; the flapping insect on its periodic orbit at those kinematics drifts
slowly (docs/averaging.md: 5.66 mm/s forward and 38.57 mm/s down), because its body moves
within the beat and the wings' speed through the air with it. Its own trim is the pair
(delta_Phi, delta_phibar), stroke amplitude and mean stroke angle, whose orbit's mean velocity
over the beat is zero: Newton's method on the position change over one beat of the periodic
orbit (north and down; east is 0 by symmetry), the Jacobian by central differences of the
controls, each evaluation a periodic orbit (:func:`~dronefly.models.flapping.periodic_orbit`).
An analysis: the FMU's default (the quasi-steady trim) is unchanged; its inputs delta_Phi and
delta_phibar take these values.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ...models.flapping import (FlappingError, FlappingModel, Floquet, PeriodicOrbit, monodromy,
                                periodic_orbit)
from ...models.quasisteady import CONTROLS

__all__ = ["FlappingTrim", "flapping_trim", "orbit_drift"]

#: the trimmed controls and where they stand in the seven (CONTROLS)
_TRIMMED = ("delta_Phi", "delta_phibar")
_AT = tuple(CONTROLS.index(n) for n in _TRIMMED)


def _controls(a: Sequence[float]) -> tuple[float, ...]:
    c = [0.0] * len(CONTROLS)
    for i, v in zip(_AT, a):
        c[i] = float(v)
    return tuple(c)


def orbit_drift(model: FlappingModel, control: Sequence[float],
                jacobian: np.ndarray | None = None) -> tuple[PeriodicOrbit, np.ndarray]:
    """The periodic orbit with ``control`` (the seven controls [rad], held) and its drift:
    the position change over one beat, north and down, in U t_w (the mean velocity over U)."""
    orbit = periodic_orbit(model, control, jacobian=jacobian)
    x = model.beat(model.state_from_z(orbit.z0), control, control)
    return orbit, np.array([x[10], x[12]]) / model.period


@dataclass
class FlappingTrim:
    """The own trim: the controls, the orbit, the drift of each Newton iterate [mm/s] and the
    lateral Floquet exponents there and at the quasi-steady trim's kinematics."""

    controls: tuple[float, ...]  # the seven controls [rad], CONTROLS order
    orbit: PeriodicOrbit
    drift_mm_per_s: list[float]  # max |mean drift| of each iterate, the start's first
    lateral_exponents: list[complex]  # at the own trim, per wing beat
    lateral_exponents_qs_trim: list[complex]  # at the quasi-steady trim's kinematics
    tol_mm_per_s: float  # the drift accepted

    def text(self) -> str:
        m = self.orbit.model
        c = dict(zip(CONTROLS, self.controls))
        Phi = math.degrees(m.qs.geometry.Phi_rad)
        phibar = math.degrees(m.trim.phibar)
        z = self.orbit.z0
        osc = self.orbit.oscillation()

        def fmt(values: Sequence[complex]) -> str:
            return ", ".join(f"{v.real:+.4f}{v.imag:+.4f}i" if abs(v.imag) > 1e-12
                             else f"{v.real:+.4f}" for v in values)

        return "\n".join([
            f"own trim (Newton on delta_Phi and delta_phibar, the orbit's mean drift as the "
            f"residual): {len(self.drift_mm_per_s) - 1} steps, drift "
            f"{self.drift_mm_per_s[0]:.2f} mm/s -> below {self.tol_mm_per_s:.0e} mm/s",
            f"delta_Phi {c['delta_Phi']:+.5f} rad (stroke amplitude "
            f"{Phi + math.degrees(c['delta_Phi']):.3f} deg against {Phi:.3f}), delta_phibar "
            f"{c['delta_phibar']:+.5f} rad (mean stroke angle "
            f"{phibar + math.degrees(c['delta_phibar']):.3f} deg against {phibar:.3f})",
            f"start of the beat: du+ {z[0]:+.5f}, dw+ {z[2]:+.5f}, dq+ {z[4]:+.5f}, theta "
            f"{math.degrees(z[7]):+.4f} deg",
            f"oscillation within the beat (peak to peak): x {osc['x_pp_um']:.1f} um, z "
            f"{osc['z_pp_um']:.2f} um, pitch {osc['theta_pp_deg']:.3f} deg",
            "lateral Floquet exponents per wing beat: " + fmt(self.lateral_exponents)
            + " (at the quasi-steady trim's kinematics: "
            + fmt(self.lateral_exponents_qs_trim) + ")",
        ])


def _lateral(model: FlappingModel, orbit: PeriodicOrbit) -> list[complex]:
    M = Floquet.of(model, orbit).monodromy
    idx = [1, 3, 5, 6]  # v, p, r, phi
    mu = np.linalg.eigvals(M[np.ix_(idx, idx)])
    lam = np.log(mu.astype(complex)) / model.period
    return sorted(lam, key=lambda v: (-v.real, -v.imag))


def flapping_trim(model: FlappingModel | None = None, tol: float = 1e-12, max_iter: int = 8,
                  step_rad: float = 1e-4) -> FlappingTrim:
    """The flapping insect's own trim (see the module text).

    Parameters
    ----------
    model : FlappingModel, optional
        Default ``FlappingModel()`` (the FMU's).
    tol : float
        Largest |drift| accepted, in U t_w per beat (mean velocity over U).
    max_iter : int
        Newton steps at most.
    step_rad : float
        The central differences' step in the controls [rad].

    Raises
    ------
    FlappingError
        The drift is not below ``tol`` after ``max_iter`` steps.
    """
    model = model or FlappingModel()
    twin = FlappingModel(model.qs, model.steps_per_beat, averaged=True)
    J = monodromy(twin, np.zeros(8))
    a = np.zeros(len(_TRIMMED))
    orbit, r = orbit_drift(model, _controls(a), J)
    qs_orbit = orbit
    mm_per_s = model.U * 1e3
    history = [float(np.max(np.abs(r))) * mm_per_s]
    for _ in range(max_iter):
        if np.max(np.abs(r)) < tol:
            break
        D = np.column_stack([
            (orbit_drift(model, _controls(a + step_rad * e), J)[1]
             - orbit_drift(model, _controls(a - step_rad * e), J)[1]) / (2 * step_rad)
            for e in np.eye(len(a))])
        a = a - np.linalg.solve(D, r)
        orbit, r = orbit_drift(model, _controls(a), J)
        history.append(float(np.max(np.abs(r))) * mm_per_s)
    if not np.max(np.abs(r)) < tol:
        raise FlappingError(f"own trim: drift {list(r)!r} (U t_w per beat) not below "
                            f"tol = {tol!r} after max_iter = {max_iter!r} Newton steps "
                            f"(delta_Phi, delta_phibar = {list(a)!r} rad)")
    return FlappingTrim(_controls(a), orbit, history, _lateral(model, orbit),
                        _lateral(model, qs_orbit), tol * mm_per_s)
