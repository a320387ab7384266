"""Longitudinal gains designed with the paper's method (Sect. 3.5 prints none).

The longitudinal motion (A, B of Sect. 3.5) has an unstable oscillatory pair
sigma +/- i omega = 0.0481 +/- 0.0976i per wing beat, which Sect. 3.5 says delta_phibar
and/or delta_alpha_2 control. Four designs, by coefficient matching of the closed-loop
characteristic polynomial (Eqs. 25-26, as the paper does for Eq. 27), the fast and slow
subsidence roots kept:

- targets ``neutral`` (a): the pair moved onto the imaginary axis, +/- i omega (neutral,
  as Eq. 27 moves the lateral lambda_1 to 0); ``mirror`` (b): to -sigma +/- i omega;
- inputs ``delta_phibar`` alone, or ``delta_phibar`` and ``delta_alpha_2`` together.

With one input the gains are unique. With two, every gain matrix K = w k^T (both inputs
driven by one feedback signal k x+, in the fixed ratio w) places the same roots by the
same coefficient matching on the column B w; the direction w (|w| = 1) is chosen to
minimise the Frobenius norm of K, the least gain for the same roots. scipy's
``place_poles`` cross-checks each design on the same input column (for one input the
gains are unique, so the two must agree), and its multi-input (KNV) design on both
columns is reported beside it for comparison.

Rates are per wing beat; gains are rad per unit of x+ = (du/U, dw/U, dq/n, dtheta).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
from numpy.typing import NDArray
from scipy.linalg import expm
from scipy.optimize import minimize_scalar
from scipy.signal import place_poles

from .analysis import AnalysisInputError, coefficient_matching_gains, ordered_eigen
from ...models.longitudinal_interface import CONTROL_NAMES, STATE_NAMES
from ...models.longitudinal_dynamics import default_parameters, system_matrices

__all__ = ["INPUT_SETS", "TARGETS", "LongitudinalDesign", "design", "designs", "peak_controls",
           "targets"]

Array = NDArray[np.float64]

TARGETS = ("neutral", "mirror")
INPUT_SETS: tuple[tuple[str, ...], ...] = (("delta_phibar",), ("delta_phibar", "delta_alpha_2"))


def targets(kind: str, A: Array) -> NDArray[np.complex128]:
    """Closed-loop targets: the unstable pair moved (``neutral`` or ``mirror``), the rest kept."""
    w, _ = ordered_eigen(A)
    pair, rest = w[:2], w[2:]
    if not (pair[0].real > 0 and abs(pair[0].imag) > 0 and np.isclose(pair[0], pair[1].conj())):
        raise AnalysisInputError(f"the longitudinal A has no unstable oscillatory pair "
                                 f"(eigenvalues {np.round(w, 5).tolist()})")
    if kind == "neutral":
        moved = 1j * pair.imag
    elif kind == "mirror":
        moved = -pair.real + 1j * pair.imag
    else:
        raise AnalysisInputError(f"targets {kind!r}: choose one of {', '.join(TARGETS)}")
    return np.concatenate([moved, rest])


@dataclass(frozen=True)
class LongitudinalDesign:
    """One design: the full gain matrix (rows = controls in B's order, columns = x+)."""

    targets: str
    inputs: tuple[str, ...]
    K: Array  # (4, 4)
    direction: Array  # w over ``inputs``
    eigenvalues: NDArray[np.complex128]  # eig(A + B K), sorted
    target_eigenvalues: NDArray[np.complex128]
    place_poles_K: Array  # scipy on the same column B w
    knv_K: Array | None  # scipy's multi-input design on the input columns (None: one input)
    peak_control_rad: Array  # (4 states,) max over time and controls after x+(0) = e_j

    def as_dict(self) -> dict:
        """JSON-ready summary."""
        def cx(z: Sequence[complex]) -> list[list[float]]:
            return [[float(np.real(v)), float(np.imag(v))] for v in z]
        return {"targets": self.targets, "inputs": list(self.inputs), "K": self.K.tolist(),
                "direction": self.direction.tolist(), "eigenvalues": cx(self.eigenvalues),
                "target_eigenvalues": cx(self.target_eigenvalues),
                "place_poles_max_abs_difference": float(np.max(np.abs(self.place_poles_K
                                                                      - self.K))),
                "gain_norm": float(np.linalg.norm(self.K)),
                "knv_gain_norm": None if self.knv_K is None else float(np.linalg.norm(self.knv_K)),
                "peak_control_rad": dict(zip(STATE_NAMES, self.peak_control_rad.tolist()))}


def peak_controls(A: Array, B: Array, K: Array, t_end_wb: float = 300.0,
                  dt_wb: float = 0.05) -> Array:
    """max_t max_i |u_i(t)| of x' = (A + B K) x, u = K x, from x(0) = e_j, for each j.

    Exact on a grid of ``dt_wb`` wing beats (matrix exponential), up to ``t_end_wb``.
    """
    Phi = expm((A + B @ K) * dt_wb)
    X = np.eye(len(A))  # column j: the state from e_j
    peak = np.max(np.abs(K @ X), axis=0)
    for _ in range(int(round(t_end_wb / dt_wb))):
        X = Phi @ X
        peak = np.maximum(peak, np.max(np.abs(K @ X), axis=0))
    return peak


def _rank_one(A: Array, B: Array, cols: list[int], t: NDArray[np.complex128],
              theta: float) -> tuple[Array, Array]:
    w = np.array([np.cos(theta), np.sin(theta)])
    k = coefficient_matching_gains(A, B[:, cols] @ w, t)
    return w, k


def design(kind: str, inputs: Sequence[str], A: Array | None = None,
           B: Array | None = None) -> LongitudinalDesign:
    """One longitudinal design (see the module docstring).

    Raises
    ------
    AnalysisInputError
        Unknown targets or inputs, or an input set the design does not cover.
    """
    if A is None or B is None:
        A, B = system_matrices(default_parameters())
    inputs = (inputs,) if isinstance(inputs, str) else tuple(inputs)  # a str is one name
    unknown = [u for u in inputs if u not in CONTROL_NAMES]
    if unknown or not 1 <= len(inputs) <= 2 or len(set(inputs)) < len(inputs):
        raise AnalysisInputError(f"inputs {list(inputs)!r}: one or two different ones of "
                                 f"{', '.join(CONTROL_NAMES)}")
    t = targets(kind, A)
    cols = [CONTROL_NAMES.index(u) for u in inputs]
    if len(cols) == 1:
        w, k = np.ones(1), coefficient_matching_gains(A, B, t, cols[0])
        knv = None
    else:
        def norm(theta: float) -> float:
            return float(np.linalg.norm(_rank_one(A, B, cols, t, theta)[1]))
        grid = np.linspace(0.0, np.pi, 181)[:-1]
        best = grid[int(np.argmin([norm(th) for th in grid]))]
        step = grid[1] - grid[0]
        res = minimize_scalar(norm, bounds=(best - step, best + step), method="bounded",
                              options={"xatol": 1e-12})
        w, k = _rank_one(A, B, cols, t, float(res.x))
        knv = np.zeros((len(CONTROL_NAMES), len(A)))
        knv[cols] = -place_poles(A, B[:, cols], t).gain_matrix
    K = np.zeros((len(CONTROL_NAMES), len(A)))
    for i, c in enumerate(cols):
        K[c] = w[i] * k
    b = B[:, cols] @ w
    pp = np.zeros_like(K)
    k_pp = -place_poles(A, b[:, None], t).gain_matrix[0]
    for i, c in enumerate(cols):
        pp[c] = w[i] * k_pp
    ev = np.linalg.eigvals(A + B @ K)
    order = np.lexsort((-ev.imag, -ev.real))
    return LongitudinalDesign(kind, inputs, K, w, ev[order], t, pp, knv,
                              peak_controls(A, B, K))


def designs() -> list[LongitudinalDesign]:
    """The four designs: (neutral, mirror) x (delta_phibar alone, with delta_alpha_2)."""
    A, B = system_matrices(default_parameters())
    return [design(kind, inputs, A, B) for inputs in INPUT_SETS for kind in TARGETS]
