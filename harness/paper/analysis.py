"""Eigen-, modal, controllability and pole-placement analysis (Sects. 3.3-3.5).

Lateral matrices come from :mod:`dronefly.plant.model`; the longitudinal ones
from the printed A, B of Sect. 3.5 (:mod:`dronefly.harness.paper.values`).
All rates are non-dimensional, per wing beat (t+ = t n); controls in rad.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Iterable, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.signal import place_poles

from dronefly.errors import DroneflyError
from dronefly.lateral import eigen_order
from dronefly.plant import model

from dronefly.harness.paper import values as pv

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


def lateral_system(params: model.LateralParameters | None = None) -> tuple[Array, Array]:
    """A1 (4x4) and B1 (4x3) of Eq. (9), per wing beat and per wing beat per rad."""
    return model.system_matrices(params if params is not None else model.default_parameters())


def longitudinal_system() -> tuple[Array, Array]:
    """A (4x4) and B (4x4) of Sect. 3.5 as printed (state du+, dw+, dq+, dtheta)."""
    return (np.array([[float(t) for t in r] for r in pv.SECT35_A]),
            np.array([[float(t) for t in r] for r in pv.SECT35_B]))


def ordered_eigen(A: ArrayLike) -> tuple[NDArray[np.complex128], NDArray[np.complex128]]:
    """Eigenvalues and eigenvectors by descending real part, sigma + i omega before its conjugate."""
    w, V = np.linalg.eig(np.asarray(A, dtype=float))
    o = eigen_order(w)
    return w[o], V[:, o]


@dataclass(frozen=True)
class ModalConvention:
    """How the eigenvector matrix M = [eta_1, f eta_2, f eta_3, eta_4] is scaled (Eq. 14).

    Attributes
    ----------
    order : tuple of int
        Positions, in :func:`ordered_eigen` order, of the modes in M; a complex
        pair occupies two consecutive slots (the sigma + i omega eigenvector).
    norm : {"unit", "last"}
        "unit": each eigenvector has 2-norm 1 and a complex one is rotated so its
        largest-modulus component is real and positive (LAPACK ``geev``);
        "last": the last state component is 1 (Table 3: dgamma = 1).
    real_signs : tuple of int
        For "unit": sign of the largest-modulus component of each real eigenvector, in M order.
    pair_factor : float
        f, the factor of the real and imaginary parts of a complex pair (2 in Eq. 14).
    """

    order: tuple[int, ...]
    norm: str = "unit"
    real_signs: tuple[int, ...] = ()
    pair_factor: float = 2.0


#: The scaling that reproduces Eqs. (19)-(20): unit 2-norm, eta_1 with dgamma < 0.
LATERAL_CONVENTION = ModalConvention(order=(0, 1, 2, 3), real_signs=(-1, 1))
#: The scaling that reproduces Eq. (32): pair, fast subsidence, slow subsidence.
LONGITUDINAL_CONVENTION = ModalConvention(order=(0, 1, 3, 2), real_signs=(1, 1))


@dataclass(frozen=True)
class ModalForm:
    """Modal form, Eqs. (15)-(18): x = M xi, xi' = A_nn xi + B_n u."""

    M: Array
    A_nn: Array
    B_n: Array
    eigenvalues: NDArray[np.complex128]


def _normalise(v: NDArray[np.complex128], conv: ModalConvention, sign: int) -> NDArray[np.complex128]:
    if conv.norm == "last":
        return v / v[-1]
    v = v / np.linalg.norm(v)
    big = v[np.argmax(np.abs(v))]
    return v * (abs(big) / big) * (sign if abs(v.imag).max() == 0.0 else 1)


def modal_decomposition(A: ArrayLike, B: ArrayLike, conv: ModalConvention = LATERAL_CONVENTION) -> ModalForm:
    """M1, A_lnn = M1^-1 A M1 and B_ln = M1^-1 B (Eqs. 14, 17, 18).

    The columns of a complex pair eta_2 +/- i eta_3 are ``f Re(v), f Im(v)`` with v the
    eigenvector of sigma + i omega, which puts +omega at A_nn[1, 2] (0-based).
    """
    A = np.asarray(A, dtype=float)
    w, V = ordered_eigen(A)
    cols: list[Array] = []
    signs = iter(conv.real_signs)
    slot = 0
    while slot < len(conv.order):
        j = conv.order[slot]
        if abs(w[j].imag) > 0.0:
            v = _normalise(V[:, j], conv, 1)
            cols += [conv.pair_factor * v.real, conv.pair_factor * v.imag]
            slot += 2
        else:
            cols.append(_normalise(V[:, j], conv, next(signs, 1)).real)
            slot += 1
    M = np.column_stack(cols)
    Minv = np.linalg.inv(M)
    return ModalForm(M, Minv @ A @ M, Minv @ np.asarray(B, dtype=float), w[list(conv.order)])


def eigenvector_table(A: ArrayLike) -> tuple[NDArray[np.complex128], Array, Array]:
    """Table 3: eigenvectors of modes 1, 2 (sigma + i omega), 3 with dgamma = 1.

    Returns
    -------
    eigenvalues : (3,) complex ndarray
    magnitude : (4, 3) ndarray
        Moduli of the components (non-dimensional).
    phase_deg : (4, 3) ndarray
        Phases in degrees, wrapped to (-180, 180].
    """
    w, V = ordered_eigen(A)
    idx = [0, 1, 3]
    E = V[:, idx] / V[-1, idx]
    ph = np.degrees(np.angle(E))
    ph[ph <= -180.0 + 1e-9] += 360.0
    ph += 0.0  # no negative zero
    return w[idx], np.abs(E), ph


def input_index(name: str, names: Sequence[str] = model.CONTROL_NAMES) -> int:
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
    b = _column(B, u)
    t = validate_targets(targets, len(b))
    _check_controllable(A, b, repr(u))
    return -place_poles(np.asarray(A, float), b[:, None], t).gain_matrix[0]
