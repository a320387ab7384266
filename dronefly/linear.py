"""Exact zero-order-hold stepping of x' = A x + B u, shared by the linear plants.

Both linear plants (lateral, Eq. 9; longitudinal, Sect. 3.5) are 4-state linear
systems in non-dimensional time; each builds A and B from its own parameters
and steps with :class:`ZohModel`.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray
from scipy.linalg import expm

from .axes import dot
from .lateral import sort_eigenvalues

__all__ = ["ZohModel", "discretize_zoh"]

Array = NDArray[np.float64]


def discretize_zoh(A: Array, B: Array, h: float) -> tuple[Array, Array]:
    """Exact zero-order-hold discretisation over a step ``h`` (same time unit as A).

    Returns ``(Phi, Gamma)`` with x[k+1] = Phi x[k] + Gamma u[k], from the
    matrix exponential of the augmented matrix [[A, B], [0, 0]] h.
    """
    n, m = B.shape
    aug = np.zeros((n + m, n + m))
    aug[:n, :n] = A * h
    aug[:n, n:] = B * h
    e = expm(aug)
    return e[:n, :n].copy(), e[:n, n:].copy()


class ZohModel:
    """x' = A x + B u with exact stepping for piecewise-constant controls.

    Parameters
    ----------
    A : (n, n) ndarray
        System matrix, per unit of time (wing beats for the plants).
    B : (n, m) ndarray
        Control matrix.

    Notes
    -----
    The (Phi, Gamma) pair is cached per step size, so a fixed communication
    step costs one matrix exponential in total.
    """

    _CACHE_SIZE = 16
    #: how messages name the system matrix (the paper's symbol)
    A_NAME = "A"

    def __init__(self, A: Array, B: Array) -> None:
        self.A, self.B = A, B
        self._cache: dict[float, tuple[Array, Array]] = {}
        self._rows: dict[float, tuple[tuple[float, ...], ...] | None] = {}

    def transition(self, h: float) -> tuple[Array, Array]:
        """(Phi, Gamma) for a step of ``h`` (cached)."""
        hit = self._cache.get(h)
        if hit is None:
            if len(self._cache) >= self._CACHE_SIZE:
                self._cache.pop(next(iter(self._cache)))
            hit = self._cache[h] = discretize_zoh(self.A, self.B, h)
        return hit

    def step(self, x: Array, u: Array, h: float) -> Array:
        """State after a step of ``h`` with the control held at ``u``."""
        Phi, Gamma = self.transition(h)
        return Phi @ x + Gamma @ u

    def step_list(self, x: list[float], u: list[float], h: float) -> list[float]:
        """:meth:`step` on plain lists, for the FMUs' doStep.

        Same arithmetic as ``Phi @ x + Gamma @ u`` on the rows of [Phi, Gamma]; at this
        size plain Python is several times faster than building numpy arrays per call.

        Raises
        ------
        ValueError
            exp(A h) overflows and the state is not zero (the zero state stays zero).
        """
        rows = self._rows.get(h)
        if rows is None:
            with np.errstate(all="ignore"):
                Phi, Gamma = self.transition(h)
                M = np.hstack([Phi, Gamma])
            if len(self._rows) >= self._CACHE_SIZE:
                self._rows.pop(next(iter(self._rows)))
            rows = self._rows[h] = (tuple(map(tuple, M.tolist()))
                                    if np.all(np.isfinite(M)) else None)
        if rows is None:  # exp(A h) overflows: only the zero solution is representable
            if not any(x) and not any(u):
                return [0.0] * len(x)
            growth = float(np.max(np.real(np.linalg.eigvals(self.A))))
            raise ValueError(
                f"a step of {h!r} wing beats overflows exp({self.A_NAME} h) (fastest growth "
                f"{growth:.4f} per wing beat; exp({growth * h:.0f}) is beyond the float "
                f"range), so only the zero state has a representable result; take steps of at "
                f"most {math.log(1e300) / max(growth, 1e-300):.0f} wing beats")
        xu = x + u
        return [dot(r, xu) for r in rows]

    def eigenvalues(self) -> Array:
        """Eigenvalues of A, sorted by descending real part, then imaginary part."""
        return np.array(sort_eigenvalues(np.linalg.eigvals(self.A)))
