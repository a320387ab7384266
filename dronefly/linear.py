"""Exact zero-order-hold stepping of x' = A x + B u, shared by the linear plants.

Both linear plants (lateral, Eq. 9; longitudinal, Sect. 3.5) are 4-state linear
systems in non-dimensional time; each builds A and B from its own parameters
and steps with :class:`ZohModel`.
"""

from __future__ import annotations

import math
from typing import Callable, Sequence

import numpy as np
from numpy.typing import NDArray
from scipy.linalg import expm

from .lateral import sort_eigenvalues

__all__ = ["ZohModel", "discretize_zoh"]

Array = NDArray[np.float64]
#: (x, u) -> [row . (x; u) for row in [Phi, Gamma]], the step of one step size
Product = Callable[[Sequence[float], Sequence[float]], list[float]]


def _straight_line_product(rows: tuple[tuple[float, ...], ...], n_states: int) -> Product:
    """The function ``(x, u) -> [row . (x; u) for row in rows]`` as straight-line arithmetic.

    Parameters
    ----------
    rows : nested tuple of float
        The rows of [Phi, Gamma]; each holds ``n_states`` state and then the control columns.
    n_states : int
        Length of ``x``.

    Returns
    -------
    callable
        ``product(x, u)``: a list of one float per row.

    Notes
    -----
    Each row is one expression ``0.0 + c0 * x0 + c1 * x1 + ...``: the same products, added
    in the same order from the same start as ``sum(map(operator.mul, row, x + u))``
    (:func:`dronefly.axes.dot` before Python 3.12), so bit-identical to it, at about a
    third of its cost for the plants' 4 x 7 and 4 x 8 (no loop, no call per row). The
    coefficients are closure variables of the generated function (never printed into its
    source, so any float is exact, inf and nan too).
    """
    width = len(rows[0])
    xs = [f"x{j}" for j in range(width)]
    coefficients = [f"c{i}_{j}" for i in range(len(rows)) for j in range(width)]
    terms = [" + ".join(["0.0", *(f"c{i}_{j} * {xs[j]}" for j in range(width))])
             for i in range(len(rows))]
    source = (f"def bind({', '.join(coefficients)}):\n"
              f"    def product(x, u):\n"
              f"        {', '.join(xs[:n_states])}, = x\n"
              f"        {', '.join(xs[n_states:])}, = u\n"
              f"        return [{', '.join(terms)}]\n"
              f"    return product\n")
    namespace: dict[str, Callable[..., Product]] = {}
    exec(compile(source, "<dronefly.linear product>", "exec"), namespace)
    return namespace["bind"](*(c for row in rows for c in row))


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
        self._products: dict[float, Product | bool] = {}  # False: overflows

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

        Same arithmetic as ``Phi @ x + Gamma @ u`` on the rows of [Phi, Gamma], compiled
        once per step size into straight-line Python (:func:`_straight_line_product`); at
        this size plain Python is several times faster than building numpy arrays per call.

        Raises
        ------
        ValueError
            exp(A h) overflows and the state is not zero (the zero state stays zero).
        """
        product = self._products.get(h)
        if product is None:
            product = self._product(h)
        if product is False:  # exp(A h) overflows: only the zero solution is representable
            if not any(x) and not any(u):
                return [0.0] * len(x)
            growth = float(np.max(np.real(np.linalg.eigvals(self.A))))
            raise ValueError(
                f"a step of {h!r} wing beats overflows exp({self.A_NAME} h) (fastest growth "
                f"{growth:.4f} per wing beat; exp({growth * h:.0f}) is beyond the float "
                f"range), so only the zero state has a representable result; take steps of at "
                f"most {math.log(1e300) / max(growth, 1e-300):.0f} wing beats")
        return product(x, u)

    def _product(self, h: float) -> Product | bool:
        """The product of [Phi, Gamma] for a step of ``h`` (cached); False if it overflows."""
        with np.errstate(all="ignore"):
            Phi, Gamma = self.transition(h)
            M = np.hstack([Phi, Gamma])
        if len(self._products) >= self._CACHE_SIZE:
            self._products.pop(next(iter(self._products)))
        product = (_straight_line_product(tuple(map(tuple, M.tolist())), Phi.shape[1])
                   if np.all(np.isfinite(M)) else False)
        self._products[h] = product
        return product

    def eigenvalues(self) -> Array:
        """Eigenvalues of A, sorted by descending real part, then imaginary part."""
        return np.array(sort_eigenvalues(np.linalg.eigvals(self.A)))
