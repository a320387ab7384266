"""Stabilising single-input designs beyond the paper (Sect. 3.4).

For each lateral control input alone, gains that move the unstable lambda_1 to a
chosen negative value (the other eigenvalues kept, Eqs. 25-26) and an LQR design,
with the peak control after a roll disturbance computed by simulation of the
closed loop x' = (A1 + b k) x, u = k x (non-dimensional time, per wing beat).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Iterable

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.linalg import expm, solve_continuous_are

from dronefly.plant import model

from .analysis import (AnalysisInputError, closed_loop_matrix, coefficient_matching_gains,
                       eigenvector_table, input_index, ordered_eigen)

__all__ = ["Design", "DisturbanceResponse", "lqr_gains", "move_lambda1_gains",
           "peak_control", "stabilising_designs"]

Array = NDArray[np.float64]


@dataclass(frozen=True)
class DisturbanceResponse:
    """Closed-loop response to an initial state (simulated on a fixed grid).

    Attributes
    ----------
    peak_control_rad : float
        max |u(t+)| over the horizon, rad.
    peak_time : float
        t+ of the peak, wing beats.
    final_state_norm : float
        |x(t_end)| (non-dimensional).
    """

    peak_control_rad: float
    peak_time: float
    final_state_norm: float

    @property
    def peak_control_deg(self) -> float:
        """Peak control in degrees."""
        return math.degrees(self.peak_control_rad)


@dataclass(frozen=True)
class Design:
    """One single-input design: gains k (u = k x, rad per unit state) and its response."""

    method: str
    input: str
    gains: Array
    closed_loop_eigenvalues: NDArray[np.complex128]
    roll: DisturbanceResponse
    mode1: DisturbanceResponse

    def as_dict(self) -> dict:
        """JSON-ready summary."""
        ev = self.closed_loop_eigenvalues
        resp = {n: {"peak_control_rad": r.peak_control_rad, "peak_control_deg": r.peak_control_deg,
                    "peak_time_wingbeats": r.peak_time, "final_state_norm": r.final_state_norm}
                for n, r in (("roll", self.roll), ("mode1", self.mode1))}
        return {"method": self.method, "input": self.input, "gains": self.gains.tolist(),
                "closed_loop_eigenvalues": [[z.real, z.imag] for z in ev], "response": resp}


def peak_control(A: ArrayLike, b: ArrayLike, k: ArrayLike, x0: ArrayLike,
                 t_end: float = 100.0, dt: float = 0.05) -> DisturbanceResponse:
    """Simulate x' = (A + b k) x from x0 exactly on a grid of ``dt`` wing beats.

    Raises
    ------
    AnalysisInputError
        If ``t_end`` or ``dt`` is not finite and positive.
    """
    for name, v in (("t_end", t_end), ("dt", dt)):
        if not (math.isfinite(v) and v > 0.0):
            raise AnalysisInputError(f"{name} = {v!r} must be finite and > 0")
    k = np.asarray(k, float)
    Phi = expm(closed_loop_matrix(A, b, k) * dt)
    x = np.asarray(x0, float).copy()
    best, t_best = abs(k @ x), 0.0
    for i in range(1, int(round(t_end / dt)) + 1):
        x = Phi @ x
        u = abs(k @ x)
        if u > best:
            best, t_best = u, i * dt
    return DisturbanceResponse(float(best), t_best, float(np.linalg.norm(x)))


def move_lambda1_gains(A: ArrayLike, B: ArrayLike, u: str, lambda1: float) -> Array:
    """Gains that move lambda_1 (the unstable root) to ``lambda1`` and keep the others."""
    if not (math.isfinite(lambda1) and lambda1 < 0.0):
        raise AnalysisInputError(f"lambda1 = {lambda1!r} must be finite and < 0")
    w, _ = ordered_eigen(A)
    return coefficient_matching_gains(A, B, [lambda1, *w[1:]], u)


def lqr_gains(A: ArrayLike, B: ArrayLike, u: str, q: Iterable[float] = (1.0, 1.0, 1.0, 1.0),
              r: float = 1.0) -> Array:
    """LQR gains for one input: minimise the integral of x'Qx + r u^2, Q = diag(q); u = k x."""
    b = np.asarray(B, float)[:, input_index(u)][:, None]
    Q = np.diag(np.asarray(list(q), float))
    if not (math.isfinite(r) and r > 0.0) or not np.all(np.isfinite(Q)) or np.any(np.diag(Q) < 0):
        raise AnalysisInputError(f"LQR weights q = {np.diag(Q).tolist()}, r = {r!r} must be finite, "
                                 "q >= 0, r > 0")
    P = solve_continuous_are(np.asarray(A, float), b, Q, np.array([[r]]))
    return -(b.T @ P)[0] / r


def stabilising_designs(lambda1: float = -0.1, gamma0: float = 0.5,
                        params: model.LateralParameters | None = None,
                        extra: dict[str, Array] | None = None) -> list[Design]:
    """Designs for each input alone (move lambda_1, LQR), plus ``extra`` gains for dPhi_a.

    Each design is simulated from a pure roll disturbance x0 = (0, 0, 0, gamma0) and from
    the paper's mode-1 disturbance x0 = gamma0 eta_1 (Table 3 eigenvector, dgamma = 1).
    """
    if not math.isfinite(gamma0) or gamma0 == 0.0:
        raise AnalysisInputError(f"gamma0 = {gamma0!r} must be finite and nonzero")
    A, B = model.system_matrices(params if params is not None else model.default_parameters())
    _, mag, ph = eigenvector_table(A)
    eta1 = mag[:, 0] * np.cos(np.radians(ph[:, 0]))
    x_roll, x_mode = np.array([0.0, 0.0, 0.0, gamma0]), gamma0 * eta1
    todo = [(f"lambda1 -> {lambda1:g}", u, move_lambda1_gains(A, B, u, lambda1))
            for u in model.CONTROL_NAMES]
    todo += [("LQR Q=I, R=1", u, lqr_gains(A, B, u)) for u in model.CONTROL_NAMES]
    todo += [(label, model.CONTROL_NAMES[0], np.asarray(k, float)) for label, k in (extra or {}).items()]
    out = []
    for method, u, k in todo:
        b = B[:, input_index(u)]
        ev = np.linalg.eigvals(closed_loop_matrix(A, b, k))
        out.append(Design(method, u, k, ev[np.lexsort((-ev.imag, -ev.real))],
                          peak_control(A, b, k, x_roll), peak_control(A, b, k, x_mode)))
    return out
