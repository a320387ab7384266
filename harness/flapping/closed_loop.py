"""The paper's controller on the flapping insect: lateral feedback sampled once per wing beat.

The controller reads the lateral state x+ = (dv+, dp+, dr+, dgamma) at the start of each wing
beat (as flies do: their sensing and their wing kinematics are per wing beat) and sets
delta_Phi_a = k x+ for that beat (:class:`dronefly.models.flapping.Flight`: the controls are
taken at the beat's start). Two gain sets: Eq. (27), designed by the paper on its CFD
derivatives, and the paper's method (coefficient matching, moving the unstable root onto the
imaginary axis) applied to the quasi-steady averaged model
(:func:`dronefly.harness.aero.beside_paper.closed_loop`, ``matched_gains``).

Closed-loop exponents per wing beat, three ways:

- ``flapping``: from the wing-beat map linearised about the periodic orbit, z' = M z + G0 u + G1
  u_prev (M the monodromy matrix; G0, G1 central differences in the control of this beat and of
  the last one: a beat's stroke starts from the rear reversal the last beat reached, and its
  downstroke angle is the last beat's), with u = k x+: the exponents of the sampled loop;
- ``averaged, sampled``: the same for the averaged twin (the same body, the forces of the
  beat's controls averaged over the cycle, so G1 = 0);
- ``averaged, continuous``: the quasi-steady A and B with the paper's inertias in continuous
  time (the paper's own form).

And a run: the flapping insect from the orbit with a roll of 0.1 rad, 30 wing beats in the loop.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ...core.text import complexes_text
from ...models.feedback import PAPER_GAINS_EQ27
from ...models.flapping import (FlappingModel, Flight, Floquet, PeriodicOrbit, monodromy,
                                periodic_orbit)
from ...models.lateral_interface import sort_eigenvalues
from ...models.rigid_body import euler_from_quaternion, gamma_from_quaternion
from ..aero.beside_paper import closed_loop as qs_closed_loop
from ..aero.beside_paper import derivative_table

__all__ = ["ClosedLoopReport", "closed_loop_report", "lateral_state"]

#: the lateral coordinates among the reduced ones (v, p, r, phi)
_LAT = (1, 3, 5, 6)
#: the largest |delta_Phi_a| the controller commands [rad] (Sect. 3.6's control box)
U_MAX = 0.4


def lateral_state(x: Sequence[float]) -> np.ndarray:
    """x+ = (dv+, dp+, dr+, dgamma) of a 13-value state."""
    return np.array([x[1], x[3], x[5], gamma_from_quaternion(x[6:10])])


def _selector(theta0: float) -> np.ndarray:
    """d x+ / d z at the orbit (gamma = asin(sin(phi) cos(theta)))."""
    S = np.zeros((4, 8))
    S[0, 1] = S[1, 3] = S[2, 5] = 1.0
    S[3, 6] = math.cos(theta0)
    return S


def _control_maps(model: FlappingModel, z0: np.ndarray,
                  step: float = 1e-6) -> tuple[np.ndarray, np.ndarray]:
    """(G0, G1): d(z after the beat)/d(delta_Phi_a of this beat, of the last one)."""
    x0 = model.state_from_z(z0)

    def f(prev: float, now: float) -> np.ndarray:
        cp, cn = (prev,) + (0.0,) * 6, (now,) + (0.0,) * 6
        return model.z_from_state(model.beat(x0, cp, cn))

    G0 = (f(0.0, step) - f(0.0, -step)) / (2 * step)
    G1 = (f(step, 0.0) - f(-step, 0.0)) / (2 * step)
    return G0, G1


def _exponents(M: np.ndarray, G0: np.ndarray, G1: np.ndarray, S: np.ndarray,
               k: Sequence[float]) -> list[complex]:
    """Per-wing-beat exponents of z' = (M + G0 k S) z + G1 k S z_prev, lateral block."""
    kS = np.asarray(k) @ S
    idx = list(_LAT)
    A11 = (M + np.outer(G0, kS))[np.ix_(idx, idx)]
    A12 = np.outer(G1, kS)[np.ix_(idx, idx)]
    n = len(idx)
    big = np.block([[A11, A12], [np.eye(n), np.zeros((n, n))]])
    mu = np.linalg.eigvals(big)
    mu = mu[np.abs(mu) > 1e-9]  # the memory's zero modes
    return sort_eigenvalues(np.log(mu.astype(complex)))


@dataclass
class _Run:
    gamma: list[float]  # at the beats' starts
    u: list[float]
    roll_pp_last_deg: float  # roll angle's swing within the last beat
    states: list[list[float]]  # x+ = (dv+, dp+, dr+, dgamma) at the beats' starts


def _run(model: FlappingModel, orbit: PeriodicOrbit, k: Sequence[float], beats: int,
         roll0: float, samples: int = 10) -> _Run:
    z = np.array(orbit.z0, dtype=float)
    z[6] += roll0
    flight = Flight(model, model.state_from_z(z))
    x = flight.y
    gammas, us, roll, states = [], [], [], []
    for b in range(beats):
        xl = lateral_state(x)
        u = float(np.clip(np.dot(k, xl), -U_MAX, U_MAX))
        states.append([float(v) for v in xl])
        gammas.append(float(xl[3]))
        us.append(u)
        flight.set_controls((u,) + (0.0,) * 6)
        roll = []
        for j in range(1, samples + 1):
            x = flight.advance_to(b + j / samples)
            roll.append(euler_from_quaternion(x[6:10])[0])
    xl = lateral_state(x)
    states.append([float(v) for v in xl])
    gammas.append(float(xl[3]))
    return _Run(gammas, us, math.degrees(max(roll) - min(roll)), states)


@dataclass
class ClosedLoopReport:
    """Closed-loop exponents per wing beat and the recovery runs, per gain set."""

    steps_per_beat: int
    gains: dict[str, list[float]]
    flapping: dict[str, list[complex]]
    averaged_sampled: dict[str, list[complex]]
    averaged_continuous: dict[str, list[complex]]
    runs: dict[str, _Run]
    orbit: PeriodicOrbit | None = None  # the flapping insect's, the loops' linearisation point

    def text(self) -> str:
        lines = [f"lateral feedback on delta_Phi_a, sampled once per wing beat "
                 f"({self.steps_per_beat} Runge-Kutta steps per beat)"]
        for name, k in self.gains.items():
            r = self.runs[name]
            lines += [
                "",
                f"{name}: k = " + ", ".join(f"{g:+.4f}" for g in k),
                "  flapping, sampled: " + complexes_text(self.flapping[name]),
                "  averaged, sampled: " + complexes_text(self.averaged_sampled[name]),
                "  averaged, continuous: " + complexes_text(self.averaged_continuous[name]),
                f"  from a 0.1 rad roll: gamma {r.gamma[10]:+.4f} rad after 10 wing beats, "
                f"{r.gamma[20]:+.4f} after 20, {r.gamma[-1]:+.4f} after {len(r.gamma) - 1}; "
                f"largest |delta_Phi_a| {max(map(abs, r.u)):.4f} rad; roll swing within the "
                f"last beat {r.roll_pp_last_deg:.4f} deg",
            ]
        return "\n".join(lines)


def closed_loop_report(steps_per_beat: int = 20, beats: int = 30,
                       roll0: float = 0.1) -> ClosedLoopReport:
    """Eq. (27) and the quasi-steady design on the flapping insect and its averaged twin."""
    model = FlappingModel(steps_per_beat=steps_per_beat)
    twin = FlappingModel(model.qs, steps_per_beat, averaged=True)
    M_avg = monodromy(twin, np.zeros(8))
    orbit = periodic_orbit(model, jacobian=M_avg)
    M = Floquet.of(model, orbit).monodromy
    G0, G1 = _control_maps(model, orbit.z0)
    A0, A1 = _control_maps(twin, np.zeros(8))
    S, S_avg = _selector(orbit.z0[7]), _selector(0.0)
    qs = {r.parameter: r.quasi_steady for r in derivative_table(model.qs)}
    design = qs_closed_loop(qs)
    gains = {"Eq. (27)": list(PAPER_GAINS_EQ27),
             "quasi-steady design": list(design["matched_gains"])}
    continuous = {"Eq. (27)": list(design["qs_A_qs_B"]),
                  "quasi-steady design": list(design["matched_eigenvalues"])}
    return ClosedLoopReport(
        steps_per_beat, gains,
        {n: _exponents(M, G0, G1, S, k) for n, k in gains.items()},
        {n: _exponents(M_avg, A0, A1, S_avg, k) for n, k in gains.items()},
        continuous, {n: _run(model, orbit, k, beats, roll0) for n, k in gains.items()}, orbit)
