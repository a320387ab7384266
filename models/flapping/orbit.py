"""Hover as a periodic orbit and its Floquet analysis, in the model: the orbit by shooting with
the wing-beat map (:func:`periodic_orbit`, :func:`orbit_start`), the body's motion on it
(:class:`PeriodicOrbit`), the monodromy matrix and the Floquet multipliers and exponents
(:func:`monodromy`, :class:`Floquet`), per axis (:data:`AXES`, :func:`block_exponents`), and
those of the averaged twin (:func:`averaged_monodromy`, :func:`averaged_exponents`).

The wing-beat map is taken in the reduced coordinates :data:`Z_NAMES` (u, v, w, p, q, r, phi,
theta; position and heading are neutral). The orbit is left-right symmetric, so the monodromy
splits exactly into a lateral block (v, p, r, phi) and a longitudinal one (u, w, q, theta).
The report that sets these beside the quasi-steady derivatives and the paper is
:mod:`dronefly.harness.flapping.floquet`; the same analysis through FMI,
:mod:`dronefly.harness.flapping.fmi_floquet`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..lateral_interface import sort_eigenvalues
from ..rigid_body import euler_from_quaternion
from ..shooting import ShootingError, shooting
from .flight import Flight
from .model import Z_NAMES, FlappingError, FlappingModel

__all__ = ["AXES", "Floquet", "PeriodicOrbit", "averaged_exponents", "averaged_monodromy",
           "block_exponents", "monodromy", "orbit_start", "periodic_orbit"]

#: the reduced coordinates of each axis (indices into :data:`Z_NAMES`)
AXES: dict[str, tuple[int, ...]] = {"lateral": (1, 3, 5, 6), "longitudinal": (0, 2, 4, 7)}


def monodromy(model: FlappingModel, z: Sequence[float], control: Sequence[float] | None = None,
              step: float = 1e-6) -> np.ndarray:
    """d(z after one beat)/d(z at its start), central differences of the wing-beat map
    (:meth:`FlappingModel.z_map`; ``step`` in the reduced coordinates' units): an (8, 8)
    array."""
    z = np.asarray(z, dtype=float)
    cols = []
    for j in range(len(z)):
        dz = np.zeros(len(z))
        dz[j] = step
        cols.append((model.z_map(z + dz, control) - model.z_map(z - dz, control)) / (2 * step))
    return np.column_stack(cols)


def periodic_orbit(model: FlappingModel, control: Sequence[float] | None = None,
                   tol: float = 1e-12, max_iter: int = 30, step: float = 1e-6,
                   samples: int | None = None,
                   jacobian: np.ndarray | None = None) -> "PeriodicOrbit":
    """Hover as a periodic orbit: Newton's method on the state at the start of a beat
    (:func:`~dronefly.models.shooting.shooting` with the wing-beat map), from the trimmed
    hover's state 0, to a residual below ``tol``.

    The Jacobian is kept for every step (the chord method: the wing-beat map is nearly
    linear over the orbit's offset): ``jacobian``, an approximation of the monodromy
    matrix (the averaged model's serves), or by default the central-difference one at the
    start.

    Raises
    ------
    FlappingError
        The residual is not below ``tol`` after ``max_iter`` steps.
    """
    z = np.zeros(len(Z_NAMES))
    M = monodromy(model, z, control, step) if jacobian is None else np.asarray(jacobian)
    try:
        z, history = shooting(lambda x: model.z_map(x, control), z, M, tol, max_iter)
    except ShootingError as e:
        raise FlappingError(str(e)) from e
    return PeriodicOrbit(model, z, control, history, samples or 200)


def orbit_start(model: FlappingModel | None = None) -> np.ndarray:
    """The start of the flapping insect's periodic orbit at the averaged trim's kinematics
    (:func:`periodic_orbit`, the averaged twin's monodromy as the Newton Jacobian): the reduced
    state (u+, v+, w+, p+, q+, r+, phi, theta) at a beat's start.

    ``model`` defaults to ``FlappingModel()``, the model of the ``DroneFlyFlapping`` FMU.
    """
    model = model or FlappingModel()
    twin = FlappingModel(model.qs, model.steps_per_beat, averaged=True)
    return periodic_orbit(model, jacobian=monodromy(twin, np.zeros(8))).z0


@dataclass
class PeriodicOrbit:
    """The periodic orbit: its start (reduced coordinates), the Newton residuals, and the
    body's motion within the beat."""

    model: FlappingModel
    z0: np.ndarray
    control: Sequence[float] | None
    residuals: list
    samples: int

    def trajectory(self) -> np.ndarray:
        """The 13-value state at ``samples`` + 1 equally spaced phases of one beat."""
        flight = Flight(self.model, self.model.state_from_z(self.z0), self.control)
        return np.array([flight.advance_to(j / self.samples) for j in range(self.samples + 1)])

    def oscillation(self) -> dict[str, float]:
        """Peak-to-peak excursions within the beat: the position (micrometres, the mean drift
        over the beat removed) and the attitude (deg), and the mean drift velocity [mm/s]."""
        X = self.trajectory()
        m = self.model
        L_um = m.U / m.n * 1e6  # U t_w in micrometres
        tau = np.linspace(0.0, 1.0, len(X))
        out: dict[str, float] = {}
        for i, name in zip((10, 11, 12), ("x", "y", "z")):
            drift = X[-1, i] - X[0, i]
            pos = X[:, i] - X[0, i] - drift * tau
            out[f"{name}_pp_um"] = float((pos.max() - pos.min()) * L_um)
            out[f"{name}_drift_mm_per_s"] = float(drift / m.period * m.U * 1e3)
        eul = np.array([euler_from_quaternion(x[6:10]) for x in X])
        for i, name in enumerate(("phi", "theta", "psi")):
            out[f"{name}_pp_deg"] = float(np.degrees(eul[:, i].max() - eul[:, i].min()))
        out["theta_mean_deg"] = float(np.degrees(eul[:-1, 1].mean()))
        return out


@dataclass
class Floquet:
    """Floquet multipliers of the periodic orbit and the exponents log(mu) per wing beat,
    beside the averaged model's eigenvalues in the same coordinates."""

    monodromy: np.ndarray
    multipliers: np.ndarray
    exponents: np.ndarray

    @classmethod
    def of(cls, model: FlappingModel, orbit: PeriodicOrbit, step: float = 1e-6) -> "Floquet":
        """The monodromy matrix about ``orbit``'s start (:func:`monodromy`), its eigenvalues
        mu and the exponents log(mu) per wing beat of the insect, largest real part first."""
        M = monodromy(model, orbit.z0, orbit.control, step)
        mu = np.linalg.eigvals(M)
        lam = np.log(mu.astype(complex)) / model.period  # per wing beat of the insect
        order = sorted(range(len(lam)), key=lambda i: (-lam[i].real, -lam[i].imag))
        return cls(M, mu[order], lam[order])


def block_exponents(M: np.ndarray, period: float) -> dict[str, list[complex]]:
    """log(eig) / period of each axis' block (:data:`AXES`) of a monodromy matrix, in the
    project's order: exponents per wing beat of the insect (``period`` in its wing beats)."""
    out = {}
    for axis, idx in AXES.items():
        mu = np.linalg.eigvals(M[np.ix_(idx, idx)])
        out[axis] = sort_eigenvalues(np.log(mu.astype(complex)) / period)
    return out


def averaged_monodromy(model: FlappingModel) -> np.ndarray:
    """The monodromy matrix of the averaged twin of ``model`` (same aerodynamics, rigid body,
    grid and period) about the trimmed hover: its exact map over one period (reduced
    coordinates)."""
    twin = FlappingModel(model.qs, model.steps_per_beat, averaged=True,
                         frequency_factor=1.0 / model.period)
    return monodromy(twin, np.zeros(8))


def averaged_exponents(model: FlappingModel) -> dict[str, list[complex]]:
    """Eigenvalues per wing beat of the averaged twin of ``model``: the logarithms of the
    eigenvalues of its map over one period, over the period."""
    return block_exponents(averaged_monodromy(model), model.period)
