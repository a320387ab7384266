"""Eigen-, modal, controllability and pole-placement analysis (Sects. 3.3-3.5).

Lateral matrices come from :mod:`dronefly.models.lateral_dynamics`; the longitudinal ones
from the printed A, B of Sect. 3.5 (:mod:`dronefly.models.longitudinal_dynamics`). The
modal form lives in :mod:`dronefly.harness.paper.modal` (re-exported here).
All rates are non-dimensional, per wing beat (t+ = t n); controls in rad.
"""

from __future__ import annotations

import math
from typing import Iterable, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ...core.errors import DroneflyError
from ...models import lateral_dynamics
from ...models import lateral_interface
from ...models.longitudinal_dynamics import A_SECT35, B_SECT35

from .modal import (LATERAL_CONVENTION, LONGITUDINAL_CONVENTION, ModalConvention, ModalForm,
    eigenvector_table, modal_decomposition, ordered_eigen)

__all__ = [
    "AnalysisInputError", "LATERAL_CONVENTION", "LONGITUDINAL_CONVENTION", "ModalConvention",
    "ModalForm", "UncontrollableError", "ackermann_gains", "characteristic_affine",
    "char_coefficients", "closed_loop_matrix", "coefficient_matching_gains", "controllability",
    "eigenvector_table", "input_index", "kalman_rank", "lateral_system", "longitudinal_system",
    "modal_decomposition", "ordered_eigen", "parse_targets", "place_poles_gains",
    "validate_targets",
]

Array = NDArray[np.float64]


class AnalysisInputError(DroneflyError):
    """Bad input to the analysis (the message names the value)."""


class UncontrollableError(AnalysisInputError):
    """The chosen control input cannot place the requested eigenvalues."""


def lateral_system(params: lateral_dynamics.LateralParameters | None = None) -> tuple[Array, Array]:
    """A1 (4x4) and B1 (4x3) of Eq. (9), per wing beat and per wing beat per rad."""
    return lateral_dynamics.system_matrices(params if params is not None else lateral_dynamics.default_parameters())


def longitudinal_system() -> tuple[Array, Array]:
    """A (4x4) and B (4x4) of Sect. 3.5 as printed (state du+, dw+, dq+, dtheta)."""
    return np.array(A_SECT35, dtype=float), np.array(B_SECT35, dtype=float)


def input_index(name: str, names: Sequence[str] = lateral_interface.CONTROL_NAMES) -> int:
    """Column of the control ``name`` in B (raises :class:`AnalysisInputError`)."""
    if name not in names:
        raise AnalysisInputError(f"input {name!r} is not one of {', '.join(names)}")
    return list(names).index(name)


def kalman_rank(A: ArrayLike, B: ArrayLike, rtol: float = 1e-9) -> tuple[int, Array]:
    """Rank and singular values of [B, AB, ..., A^(n-1) B]."""
    A, B = np.asarray(A, float), np.asarray(B, float).reshape(len(A), -1)
    blocks = [B]
    for _ in range(len(A) - 1):
        blocks.append(A @ blocks[-1])
    s = np.linalg.svd(np.hstack(blocks), compute_uv=False)
    return int(np.sum(s > rtol * s[0])) if s[0] > 0 else 0, s


def controllability(A: ArrayLike, B: ArrayLike, names: Sequence[str], modal: ModalForm,
                    rtol: float = 1e-9) -> dict[str, dict]:
    """Kalman rank and per-mode PBH test for each input alone and for all together.

    Returns, per input set, ``kalman_rank`` and ``modes``: for each eigenvalue the
    smallest singular value of [lambda I - A, B] (PBH; 0 = uncontrollable mode) and
    the modal input magnitude |B_n row| (the pair's two rows combined).
    """
    A, B = np.asarray(A, float), np.asarray(B, float)
    n = len(A)
    sets = {nm: [i] for i, nm in enumerate(names)} | {"all": list(range(len(names)))}
    out: dict[str, dict] = {}
    for label, cols in sets.items():
        rank, _ = kalman_rank(A, B[:, cols], rtol)
        modes, slot = [], 0
        while slot < n:
            lam = complex(modal.eigenvalues[slot])
            rows = [slot, slot + 1] if lam.imag != 0.0 else [slot]
            s = np.linalg.svd(np.hstack([lam * np.eye(n) - A, B[:, cols]]), compute_uv=False)
            mag = float(np.linalg.norm(modal.B_n[np.ix_(rows, cols)]) / math.sqrt(len(rows)))
            modes.append({"eigenvalue": [lam.real, lam.imag], "pbh_min_singular_value": float(s[-1]),
                          "controllable": bool(s[-1] > rtol * s[0]), "modal_input_magnitude": mag})
            slot += len(rows)
        out[label] = {"kalman_rank": rank, "controllable": rank == n, "modes": modes}
    return out


def closed_loop_matrix(A: ArrayLike, b: ArrayLike, k: ArrayLike) -> Array:
    """Eq. (24): A1' = A1 + b k for the feedback u = k x (Eq. 22)."""
    return np.asarray(A, float) + np.outer(np.asarray(b, float), np.asarray(k, float))


def char_coefficients(A: ArrayLike) -> Array:
    """(b, c, d, e) of lambda^4 + b lambda^3 + c lambda^2 + d lambda + e (Eq. 25)."""
    return np.real(np.poly(np.asarray(A, float)))[1:]


def characteristic_affine(A: ArrayLike, b: ArrayLike) -> tuple[Array, Array]:
    """Eq. (26) as affine maps: coefficients(k) = c0 + G k (exact, because b k is rank 1).

    Returns
    -------
    c0 : (n,) ndarray
        Coefficients at k = 0.
    G : (n, n) ndarray
        G[:, j] = coefficients(e_j) - c0.
    """
    c0 = char_coefficients(A)
    n = len(c0)
    G = np.column_stack([char_coefficients(closed_loop_matrix(A, b, np.eye(n)[j])) - c0
                         for j in range(n)])
    return c0, G


#: Largest target eigenvalue magnitude, per wing beat; the open-loop modes are below 1.
_MAX_TARGET = 1e3


def parse_targets(text: str) -> NDArray[np.complex128]:
    """Comma-separated eigenvalues ('-0.1, -0.089+0.057j, ...'; 'i' accepted for 'j')."""
    out = []
    for tok in (t.strip() for t in text.split(",")):
        try:
            out.append(complex(tok.replace(" ", "").replace("i", "j")))
        except ValueError:
            raise AnalysisInputError(f"target {tok!r} is not a finite (complex) number") from None
    return validate_targets(out)


def validate_targets(targets: Iterable[complex], n: int = 4, rtol: float = 1e-9) -> NDArray[np.complex128]:
    """Check that ``targets`` are n finite values closed under complex conjugation."""
    t = np.asarray(list(targets), dtype=complex)
    if t.shape != (n,):
        raise AnalysisInputError(f"need {n} target eigenvalues, got {t.size}: {t.tolist()}")
    for z in t:
        if not (math.isfinite(z.real) and math.isfinite(z.imag)):
            raise AnalysisInputError(f"target eigenvalue {z} is not finite")
        if abs(z) > _MAX_TARGET:
            raise AnalysisInputError(f"target eigenvalue {z} exceeds {_MAX_TARGET:g} per wing beat "
                                     "in magnitude (the gains would overflow)")
    scale = max(1.0, float(np.abs(t).max()))
    free = list(t)
    for z in t:
        if z.imag > 0.0:
            match = [i for i, y in enumerate(free) if abs(y - z.conjugate()) <= rtol * scale]
            if not match:
                raise AnalysisInputError(f"target eigenvalue {z} has no conjugate {z.conjugate()} "
                                         "among the targets (not closed under conjugation)")
            free.pop(match[0])
    return t


def _column(B: ArrayLike, u: int | str) -> Array:
    B = np.asarray(B, float)
    return B[:, input_index(u) if isinstance(u, str) else u] if B.ndim == 2 else B


def _check_controllable(A: ArrayLike, b: Array, label: str) -> None:
    rank, s = kalman_rank(A, b)
    if rank < len(b):
        raise UncontrollableError(f"input {label} is not controllable: Kalman rank {rank} < {len(b)} "
                                  f"(smallest singular value {s[-1]:.3g})")


def coefficient_matching_gains(A: ArrayLike, B: ArrayLike, targets: Iterable[complex],
                               u: int | str = 0) -> Array:
    """The paper's method (Eqs. 25-26): solve c0 + G k = poly(targets) for k (u = k x)."""
    b = _column(B, u)
    t = validate_targets(targets, len(b))
    _check_controllable(A, b, repr(u))
    c0, G = characteristic_affine(A, b)
    return np.linalg.solve(G, np.real(np.poly(t))[1:] - c0)


def ackermann_gains(A: ArrayLike, B: ArrayLike, targets: Iterable[complex], u: int | str = 0) -> Array:
    """Ackermann's formula, k = -e_n^T C^-1 p(A), for u = k x."""
    A, b = np.asarray(A, float), _column(B, u)
    t = validate_targets(targets, len(b))
    _check_controllable(A, b, repr(u))
    C = np.column_stack([np.linalg.matrix_power(A, i) @ b for i in range(len(b))])
    p = np.real(np.poly(t))
    pA = sum(c * np.linalg.matrix_power(A, len(b) - i) for i, c in enumerate(p))
    return -np.linalg.solve(C.T, np.eye(len(b))[-1]) @ pA


def place_poles_gains(A: ArrayLike, B: ArrayLike, targets: Iterable[complex], u: int | str = 0) -> Array:
    """:func:`scipy.signal.place_poles` cross-check, returned as k for u = k x."""
    from scipy.signal import place_poles  # 0.8 s to import: only for this cross-check

    b = _column(B, u)
    t = validate_targets(targets, len(b))
    _check_controllable(A, b, repr(u))
    return -place_poles(np.asarray(A, float), b[:, None], t).gain_matrix[0]
