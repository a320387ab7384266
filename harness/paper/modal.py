"""Eigenvalues, eigenvectors and the modal form (Sect. 3.3, Eqs. 14-20, Table 3; Eqs. 31-32).

x = M xi turns x' = A x + B u into xi' = A_nn xi + B_n u. How the eigenvector matrix M
is scaled (:class:`ModalConvention`) decides the printed numbers of B_n; the two
conventions below reproduce Eqs. (19)-(20) and Eq. (32). Re-exported by
:mod:`dronefly.harness.paper.analysis`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ...models.lateral_interface import eigen_order

__all__ = ["LATERAL_CONVENTION", "LONGITUDINAL_CONVENTION", "ModalConvention", "ModalForm",
           "eigenvector_table", "modal_decomposition", "ordered_eigen"]

Array = NDArray[np.float64]


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
