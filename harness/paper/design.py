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

from ...models import lateral_dynamics
from ...models import lateral_interface
from ...models.lateral_interface import sort_eigenvalues
from . import printed as pv
from .analysis import (LONGITUDINAL_CONVENTION, AnalysisInputError, ModalConvention,
                       ackermann_gains, characteristic_affine, closed_loop_matrix,
                       coefficient_matching_gains, controllability, eigenvector_table, input_index,
                       lateral_system, longitudinal_system, modal_decomposition, ordered_eigen,
                       parse_targets, place_poles_gains)

__all__ = ["Design", "DisturbanceResponse", "analysis_report", "lqr_gains", "move_lambda1_gains",
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
                        params: lateral_dynamics.LateralParameters | None = None,
                        extra: dict[str, Array] | None = None) -> list[Design]:
    """Designs for each input alone (move lambda_1, LQR), plus ``extra`` gains for dPhi_a.

    Each design is simulated from a pure roll disturbance x0 = (0, 0, 0, gamma0) and from
    the paper's mode-1 disturbance x0 = gamma0 eta_1 (Table 3 eigenvector, dgamma = 1).
    """
    if not math.isfinite(gamma0) or gamma0 == 0.0:
        raise AnalysisInputError(f"gamma0 = {gamma0!r} must be finite and nonzero")
    A, B = lateral_dynamics.system_matrices(params if params is not None else lateral_dynamics.default_parameters())
    _, mag, ph = eigenvector_table(A)
    eta1 = mag[:, 0] * np.cos(np.radians(ph[:, 0]))
    x_roll, x_mode = np.array([0.0, 0.0, 0.0, gamma0]), gamma0 * eta1
    todo = [(f"lambda1 -> {lambda1:g}", u, move_lambda1_gains(A, B, u, lambda1))
            for u in lateral_interface.CONTROL_NAMES]
    todo += [("LQR Q=I, R=1", u, lqr_gains(A, B, u)) for u in lateral_interface.CONTROL_NAMES]
    todo += [(label, lateral_interface.CONTROL_NAMES[0], np.asarray(k, float)) for label, k in (extra or {}).items()]
    out = []
    for method, u, k in todo:
        b = B[:, input_index(u)]
        ev = np.linalg.eigvals(closed_loop_matrix(A, b, k))
        out.append(Design(method, u, k, np.array(sort_eigenvalues(ev), dtype=complex),
                          peak_control(A, b, k, x_roll), peak_control(A, b, k, x_mode)))
    return out


def _cx(z: Iterable[complex]) -> list[list[float]]:
    return [[float(np.real(v)), float(np.imag(v))] for v in z]


def analysis_report(targets: str | None = None, design_input: str = "delta_Phi_a",
                    lambda1: float = -0.1, gamma0: float = 0.5) -> dict:
    """Computed matrices, eigenvalues, controllability and designs, JSON-ready.

    Parameters
    ----------
    targets : str, optional
        Comma-separated closed-loop eigenvalues (per wing beat) for an extra design
        with ``design_input`` (see :func:`~dronefly.harness.paper.analysis.parse_targets`).
    design_input : str
        Control input of that design (one of ``lateral_interface.CONTROL_NAMES``).
    lambda1, gamma0 : float
        Target of the lambda_1 designs (per wing beat) and the roll disturbance (rad).

    Raises
    ------
    AnalysisInputError
        Bad input name, non-finite or non-conjugate targets, uncontrollable input.
    """

    u = input_index(design_input)
    custom = None if targets is None else parse_targets(targets)
    A, B = lateral_system()
    w, _ = ordered_eigen(A)
    _, mag, ph = eigenvector_table(A)
    mf = modal_decomposition(A, B)
    m3 = modal_decomposition(A, B, ModalConvention((0, 1, 2, 3), norm="last"))
    c0, G = characteristic_affine(A, B[:, 0])
    Al, Bl = longitudinal_system()
    ml = modal_decomposition(Al, Bl, LONGITUDINAL_CONVENTION)
    k27 = np.array([float(t) for t in pv.EQ27_GAINS])
    out: dict = {
        "lateral": {"A1": A.tolist(), "B1": B.tolist(), "eigenvalues": _cx(w),
                    "eigenvectors_table3": {"magnitude": mag.tolist(), "phase_deg": ph.tolist()},
                    "modal_eq20_convention": {"M1": mf.M.tolist(), "A_lnn": mf.A_nn.tolist(),
                                              "B_ln": mf.B_n.tolist()},
                    "modal_table3_convention": {"M1": m3.M.tolist(), "B_ln": m3.B_n.tolist()},
                    "controllability": controllability(A, B, lateral_interface.CONTROL_NAMES, mf),
                    "eq24_b": B[:, 0].tolist(),
                    "eq26": {"c0 (b, c, d, e at k = 0)": c0.tolist(), "G (d coeffs / d k_j)": G.tolist()}},
        "longitudinal": {"A": Al.tolist(), "B": Bl.tolist(), "eigenvalues": _cx(ordered_eigen(Al)[0]),
                         "controls": list(pv.LONGITUDINAL_CONTROLS), "M": ml.M.tolist(),
                         "A_nn": ml.A_nn.tolist(), "B_n": ml.B_n.tolist(),
                         "controllability": controllability(Al, Bl, pv.LONGITUDINAL_CONTROLS, ml)},
        "designs": [d.as_dict() for d in stabilising_designs(lambda1, gamma0,
                                                              extra={"Eq. (27) as printed": k27})],
    }
    if custom is not None:
        k = coefficient_matching_gains(A, B, custom, u)
        distinct = len({complex(z) for z in custom}) == len(custom)
        b = B[:, u]
        eta1 = mag[:, 0] * np.cos(np.radians(ph[:, 0]))
        roll = peak_control(A, b, k, np.array([0.0, 0.0, 0.0, gamma0]))
        mode = peak_control(A, b, k, gamma0 * eta1)
        out["custom_design"] = {
            "input": design_input, "targets": _cx(custom), "gains": k.tolist(),
            "gains_ackermann": ackermann_gains(A, B, custom, u).tolist(),
            "gains_place_poles": place_poles_gains(A, B, custom, u).tolist() if distinct else None,
            "closed_loop_eigenvalues": _cx(np.linalg.eigvals(closed_loop_matrix(A, b, k))),
            "char_poly_error": float(np.max(np.abs(np.poly(closed_loop_matrix(A, b, k))
                                                   - np.real(np.poly(custom))))),
            "peak_control_deg": {"roll": roll.peak_control_deg, "mode1": mode.peak_control_deg},
            "note": "" if distinct else (
                "repeated targets: placed by coefficient matching and Ackermann (the closed-loop "
                "characteristic polynomial equals the target one, char_poly_error); scipy's "
                "place_poles cannot place a target more often than rank(b) = 1 and is skipped. "
                "The computed eigenvalues of a repeated root scatter around it by about "
                "eps^(1/multiplicity): numerical sensitivity, not a wrong design.")}
    return out
