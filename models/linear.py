"""Exact zero-order-hold stepping of x' = A x + B u, shared by the linear plants.

Both linear plants (lateral, Eq. 9; longitudinal, Sect. 3.5) are 4-state linear
systems in non-dimensional time; each builds A and B from its own parameters
and steps with :class:`ZohModel`.

What the FMUs run (:meth:`ZohModel.step_list`, :meth:`ZohModel.transition_rows`) is plain
Python: the matrix exponential is :func:`dronefly.models.linear_algebra.expm`. The analyses' API
(:func:`discretize_zoh`, :meth:`ZohModel.transition`, :meth:`ZohModel.step`, the arrays
:attr:`ZohModel.A` and :attr:`ZohModel.B`, :meth:`ZohModel.eigenvalues`) returns numpy arrays
and imports numpy (and scipy) only when called; an FMU never calls it.
"""

from __future__ import annotations

import math
from dataclasses import fields, replace
from operator import mul
from types import ModuleType
from typing import TYPE_CHECKING, Any, Callable, List, Sequence, Tuple, TypeVar

from ..core.errors import DroneflyError
from .axes import dot
from .lateral_interface import sort_eigenvalues
from .linear_algebra import expm, hold_exponential, hold_shift, norm1

if TYPE_CHECKING:
    import numpy as np
    from numpy.typing import NDArray

    Array = NDArray[np.float64]

__all__ = ["ModelParameterError", "PlantParameters", "Rows", "Stepper", "ZohModel", "as_arrays",
           "discretize_zoh", "finite_rows", "zoh_rows"]

#: a matrix as a tuple of rows of floats
Rows = Tuple[Tuple[float, ...], ...]  # (typing.Tuple: Python 3.8 hosts)
#: (x, u) -> [row . (x; u) for row in [Phi, Gamma]], the step of one step size
Product = Callable[[Sequence[float], Sequence[float]], List[float]]
#: (x, value table) -> the next x (its scaled values written to the table), or None if a value
#: is not finite
Stepper = Callable[[Sequence[float], List[float]], "List[float] | None"]
_P = TypeVar("_P", bound="PlantParameters")


class ModelParameterError(DroneflyError):
    """A model parameter is not finite or not physical."""


class PlantParameters:
    """What the linear plants' parameter sets (frozen dataclasses) share: their names, the
    check that every value is finite (then :meth:`check_physical`), and a changed copy."""

    @classmethod
    def names(cls) -> tuple[str, ...]:
        """The parameter names, in the order of the fields."""
        return tuple(f.name for f in fields(cls))  # type: ignore[arg-type]

    def validate(self) -> None:
        """Raise :class:`ModelParameterError` naming the first bad value."""
        for name in self.names():
            value = getattr(self, name)
            if not math.isfinite(value):
                raise ModelParameterError(f"{name} = {value!r} is not finite")
        self.check_physical()

    def check_physical(self) -> None:
        """Raise :class:`ModelParameterError` for finite values that are not physical."""

    def with_values(self: _P, **changes: float) -> _P:
        """A copy with ``changes`` (parameter name -> value); not validated."""
        return replace(self, **changes)  # type: ignore[type-var]


def _numpy() -> ModuleType:
    """numpy, for the analyses' API only: what the FMUs run is standard-library Python."""
    import numpy  # the FMU runtime needs no numpy: imported when an analysis asks for arrays

    return numpy


def as_arrays(*matrices: Any) -> "tuple[Array, ...]":
    """Each matrix (rows of floats) as a float numpy array, for the analyses."""
    np = _numpy()
    return tuple(np.array(M, dtype=float) for M in matrices)


def _rows(M: Any) -> Rows:
    """A matrix (rows of numbers, or a 2-D array) as a tuple of rows of floats."""
    return tuple(tuple(float(x) for x in row) for row in M)


def _product_of(rows: Rows) -> Product:
    """The function ``(x, u) -> [row . (x; u) for row in rows]``.

    Parameters
    ----------
    rows : nested tuple of float
        The rows of [Phi, Gamma]; each holds the state and then the control columns.

    Returns
    -------
    callable
        ``product(x, u)``: a list of one float per row. For the plants' shapes (4 states and 3
        or 4 controls: :func:`_unrolled`) each row is summed left to right as written out,
        ``a0 x0 + a1 x1 + ... + a6 u2``, the same floats on every Python; otherwise each is
        :func:`dronefly.models.axes.dot` of the row and the concatenation of ``x`` and ``u``
        (the same floats up to Python 3.11; ``math.sumprod`` from 3.12).
    """
    unrolled = _unrolled(rows)
    if unrolled is not None:
        return unrolled[0]

    def product(x: Sequence[float], u: Sequence[float]) -> List[float]:
        xu = [*x, *u]
        return [dot(row, xu) for row in rows]

    return product


def _stepper(rows: Rows, scale: Sequence[float], inputs: range, outputs: range) -> Stepper:
    """:func:`_product_of` fused with reading the controls from and writing the scaled state to a
    value table, with a finiteness check.

    Parameters
    ----------
    rows : nested tuple of float
        The rows of [Phi, Gamma].
    scale : sequence of float
        The output of each state per unit of state.
    inputs, outputs : range
        The rows of the value table holding the controls and receiving the outputs (step 1).

    Returns
    -------
    callable
        ``stepper(x, r)``: the next state (the product's floats for ``u = r[inputs]``), after
        setting ``r[outputs] = [x1[i] * scale[i] for i ...]``; or None, changing nothing, if any
        of ``u``, ``y`` is not finite (detected from their plain sum, so also if that sum alone
        overflows: the caller then checks each value).
    """
    scale = tuple(map(float, scale))
    unrolled = _unrolled(rows)
    if unrolled is not None and len(inputs) == len(rows[0]) - 4 and len(outputs) == 4:
        return unrolled[1](scale, inputs.start, outputs.start)
    controls, states = slice(inputs.start, inputs.stop), slice(outputs.start, outputs.stop)

    def stepper(x: Sequence[float], r: List[float]) -> "List[float] | None":
        u = r[controls]
        xu = [*x, *u]
        x1 = [dot(row, xu) for row in rows]
        y = list(map(mul, x1, scale))
        total = sum(u) + sum(y)
        if total - total != 0.0:
            return None
        r[states] = y
        return x1

    return stepper


def _unrolled(rows: Rows) -> "tuple[Product, Callable[[tuple[float, ...], int, int], Stepper]] | None":
    """The product and a maker of the fused stepper of :func:`_stepper` for the plants' shapes,
    [Phi, Gamma] of 4 states and 3 or 4 controls, written out as straight-line arithmetic on
    locals (no list, no call inside a step: a third of the cost of the general product); None
    for any other shape.

    The stepper detects a value that is not finite from the sum of the outputs alone: every
    control enters every row (with a coefficient 0.0 too, as 0 * inf and 0 * nan are nan), so a
    control that is not finite makes every output so.

    Two copies, 4 x 3 and 4 x 4, kept on purpose: one generic version is either a loop (the
    general closure: several times the cost of a step) or source generated and run with exec (the
    same cost, but exec is reserved to :func:`dronefly.models.rigid_body._make_functions`, see
    its module); so each shape the plants use is written out once."""
    if len(rows) != 4 or len({len(row) for row in rows}) != 1:
        return None
    if len(rows[0]) == 7:
        return _unrolled_4x3(rows)
    if len(rows[0]) == 8:
        return _unrolled_4x4(rows)
    return None


def _unrolled_4x3(rows: Rows) -> "tuple[Product, Callable[[tuple[float, ...], int, int], Stepper]]":
    """:func:`_unrolled` for 4 states and 3 controls (the lateral plant)."""
    ((a00, a01, a02, a03, a04, a05, a06), (a10, a11, a12, a13, a14, a15, a16),
     (a20, a21, a22, a23, a24, a25, a26), (a30, a31, a32, a33, a34, a35, a36)) = rows

    def product(x: Sequence[float], u: Sequence[float]) -> List[float]:
        x0, x1, x2, x3 = x
        u0, u1, u2 = u
        return [a00 * x0 + a01 * x1 + a02 * x2 + a03 * x3 + a04 * u0 + a05 * u1 + a06 * u2,
                a10 * x0 + a11 * x1 + a12 * x2 + a13 * x3 + a14 * u0 + a15 * u1 + a16 * u2,
                a20 * x0 + a21 * x1 + a22 * x2 + a23 * x3 + a24 * u0 + a25 * u1 + a26 * u2,
                a30 * x0 + a31 * x1 + a32 * x2 + a33 * x3 + a34 * u0 + a35 * u1 + a36 * u2]

    def make(scale: tuple[float, ...], u_row: int, y_row: int) -> Stepper:
        s0, s1, s2, s3 = scale
        i0, i1, i2 = u_row, u_row + 1, u_row + 2
        o0, o1, o2, o3 = y_row, y_row + 1, y_row + 2, y_row + 3

        def stepper(x: Sequence[float], r: List[float]) -> "List[float] | None":
            x0, x1, x2, x3 = x
            u0 = r[i0]
            u1 = r[i1]
            u2 = r[i2]
            n0 = a00 * x0 + a01 * x1 + a02 * x2 + a03 * x3 + a04 * u0 + a05 * u1 + a06 * u2
            n1 = a10 * x0 + a11 * x1 + a12 * x2 + a13 * x3 + a14 * u0 + a15 * u1 + a16 * u2
            n2 = a20 * x0 + a21 * x1 + a22 * x2 + a23 * x3 + a24 * u0 + a25 * u1 + a26 * u2
            n3 = a30 * x0 + a31 * x1 + a32 * x2 + a33 * x3 + a34 * u0 + a35 * u1 + a36 * u2
            y0 = n0 * s0
            y1 = n1 * s1
            y2 = n2 * s2
            y3 = n3 * s3
            total = y0 + y1 + y2 + y3  # (a control that is not finite makes every y so)
            if total - total != 0.0:
                return None
            r[o0] = y0
            r[o1] = y1
            r[o2] = y2
            r[o3] = y3
            return [n0, n1, n2, n3]

        return stepper

    return product, make


def _unrolled_4x4(rows: Rows) -> "tuple[Product, Callable[[tuple[float, ...], int, int], Stepper]]":
    """:func:`_unrolled` for 4 states and 4 controls (the longitudinal plant)."""
    ((a00, a01, a02, a03, a04, a05, a06, a07), (a10, a11, a12, a13, a14, a15, a16, a17),
     (a20, a21, a22, a23, a24, a25, a26, a27), (a30, a31, a32, a33, a34, a35, a36, a37)) = rows

    def product(x: Sequence[float], u: Sequence[float]) -> List[float]:
        x0, x1, x2, x3 = x
        u0, u1, u2, u3 = u
        return [a00 * x0 + a01 * x1 + a02 * x2 + a03 * x3 + a04 * u0 + a05 * u1 + a06 * u2
                + a07 * u3,
                a10 * x0 + a11 * x1 + a12 * x2 + a13 * x3 + a14 * u0 + a15 * u1 + a16 * u2
                + a17 * u3,
                a20 * x0 + a21 * x1 + a22 * x2 + a23 * x3 + a24 * u0 + a25 * u1 + a26 * u2
                + a27 * u3,
                a30 * x0 + a31 * x1 + a32 * x2 + a33 * x3 + a34 * u0 + a35 * u1 + a36 * u2
                + a37 * u3]

    def make(scale: tuple[float, ...], u_row: int, y_row: int) -> Stepper:
        s0, s1, s2, s3 = scale
        i0, i1, i2, i3 = u_row, u_row + 1, u_row + 2, u_row + 3
        o0, o1, o2, o3 = y_row, y_row + 1, y_row + 2, y_row + 3

        def stepper(x: Sequence[float], r: List[float]) -> "List[float] | None":
            x0, x1, x2, x3 = x
            u0 = r[i0]
            u1 = r[i1]
            u2 = r[i2]
            u3 = r[i3]
            n0 = (a00 * x0 + a01 * x1 + a02 * x2 + a03 * x3 + a04 * u0 + a05 * u1 + a06 * u2
                  + a07 * u3)
            n1 = (a10 * x0 + a11 * x1 + a12 * x2 + a13 * x3 + a14 * u0 + a15 * u1 + a16 * u2
                  + a17 * u3)
            n2 = (a20 * x0 + a21 * x1 + a22 * x2 + a23 * x3 + a24 * u0 + a25 * u1 + a26 * u2
                  + a27 * u3)
            n3 = (a30 * x0 + a31 * x1 + a32 * x2 + a33 * x3 + a34 * u0 + a35 * u1 + a36 * u2
                  + a37 * u3)
            y0 = n0 * s0
            y1 = n1 * s1
            y2 = n2 * s2
            y3 = n3 * s3
            total = y0 + y1 + y2 + y3  # (a control that is not finite makes every y so)
            if total - total != 0.0:
                return None
            r[o0] = y0
            r[o1] = y1
            r[o2] = y2
            r[o3] = y3
            return [n0, n1, n2, n3]

        return stepper

    return product, make


def finite_rows(A: "list[list[float]]", B: "list[list[float]]", error: type,
                why: str) -> "tuple[Rows, Rows]":
    """``A`` and ``B`` as :data:`Rows`, or ``error`` naming the first entry that is not finite.

    ``why`` ends the message: the parameters that may have overflowed.
    """
    for label, M in (("A", A), ("B", B)):
        for i, row in enumerate(M):
            for j, x in enumerate(row):
                if not math.isfinite(x):
                    raise error(f"{label}[{i + 1},{j + 1}] = {x!r} is not finite: the "
                                f"parameters overflow {why}")
    return tuple(map(tuple, A)), tuple(map(tuple, B))


def zoh_rows(A: Sequence[Sequence[float]], B: Sequence[Sequence[float]],
             h: float) -> tuple[Rows, Rows]:
    """Exact zero-order-hold discretisation over a step ``h``, in plain Python.

    Parameters
    ----------
    A : (n, n) rows of float
        System matrix, per unit of time.
    B : (n, m) rows of float
        Control matrix, per unit of time per unit of control.
    h : float
        Step, in the time unit of A (wing beats for the plants).

    Returns
    -------
    Phi, Gamma : tuple of rows
        x[k+1] = Phi x[k] + Gamma u[k]: the blocks of exp([[A h, B h], [0, 0]])
        (:func:`dronefly.models.linear_algebra.hold_exponential`); entries may be inf or nan
        where exp(A h) overflows.
    """
    Phi, Gamma = hold_exponential([[float(x) * h for x in row] for row in A],
                                  [[float(x) * h for x in row] for row in B])
    return tuple(map(tuple, Phi)), tuple(map(tuple, Gamma))


def discretize_zoh(A: "Array", B: "Array", h: float) -> "tuple[Array, Array]":
    """Exact zero-order-hold discretisation over a step ``h`` (same time unit as A), for the
    analyses (numpy arrays; ``scipy.linalg.expm``).

    Returns ``(Phi, Gamma)`` with x[k+1] = Phi x[k] + Gamma u[k], from the
    matrix exponential of the augmented matrix [[A, B], [0, 0]] h, with B h scaled as
    :func:`dronefly.models.linear_algebra.hold_exponential` scales it.
    """
    from scipy.linalg import expm as scipy_expm  # the analyses' API only, as :func:`_numpy`

    np = _numpy()
    n, m = B.shape
    aug = np.zeros((n + m, n + m))
    aug[:n, :n] = A * h
    aug[:n, n:] = B * h
    k = hold_shift(aug[:n, :n].tolist(), aug[:n, n:].tolist()) if np.all(np.isfinite(aug)) \
        else 0
    aug[:n, n:] = np.ldexp(aug[:n, n:], -k)  # B h no larger than A h needs (hold_exponential)
    e = scipy_expm(aug)
    return e[:n, :n].copy(), np.ldexp(e[:n, n:], k)


class ZohModel:
    """x' = A x + B u with exact stepping for piecewise-constant controls.

    Parameters
    ----------
    A : (n, n) rows of float or ndarray
        System matrix, per unit of time (wing beats for the plants).
    B : (n, m) rows of float or ndarray
        Control matrix.

    Notes
    -----
    The (Phi, Gamma) pair is cached per step size, so a fixed communication
    step costs one matrix exponential in total. ``A_rows`` and ``B_rows`` are the matrices
    as tuples of rows (what the FMUs use); ``A`` and ``B`` the same as numpy arrays.
    """

    _CACHE_SIZE = 16
    #: how messages name the system matrix (the paper's symbol)
    A_NAME = "A"
    B_NAME = "B"

    def __init__(self, A: Any, B: Any) -> None:
        self.A_rows, self.B_rows = _rows(A), _rows(B)
        self._rows_cache: dict[float, tuple[Rows, Rows]] = {}
        self._cache: dict[float, tuple[Any, Any]] = {}
        self._products: dict[float, Product | bool] = {}  # False: overflows

    @property
    def A(self) -> "Array":
        """The system matrix as a numpy array (a new array per access)."""
        return as_arrays(self.A_rows)[0]

    @property
    def B(self) -> "Array":
        """The control matrix as a numpy array (a new array per access)."""
        return as_arrays(self.B_rows)[0]

    def transition_rows(self, h: float) -> tuple[Rows, Rows]:
        """(Phi, Gamma) for a step of ``h`` as tuples of rows (cached; :func:`zoh_rows`)."""
        hit = self._rows_cache.get(h)
        if hit is None:
            if len(self._rows_cache) >= self._CACHE_SIZE:
                self._rows_cache.pop(next(iter(self._rows_cache)))
            hit = self._rows_cache[h] = zoh_rows(self.A_rows, self.B_rows, h)
        return hit

    def transition(self, h: float) -> "tuple[Array, Array]":
        """(Phi, Gamma) for a step of ``h`` as numpy arrays (cached; the same numbers as
        :meth:`transition_rows`)."""
        hit = self._cache.get(h)
        if hit is None:
            if len(self._cache) >= self._CACHE_SIZE:
                self._cache.pop(next(iter(self._cache)))
            Phi, Gamma = as_arrays(*self.transition_rows(h))
            hit = self._cache[h] = (Phi, Gamma)
        return hit

    def step(self, x: "Array", u: "Array", h: float) -> "Array":
        """State after a step of ``h`` with the control held at ``u`` (numpy arrays)."""
        Phi, Gamma = self.transition(h)
        return Phi @ x + Gamma @ u

    def step_list(self, x: list[float], u: list[float], h: float) -> list[float]:
        """:meth:`step` on plain lists, for the FMUs' doStep.

        The rows of [Phi, Gamma] applied to (x; u) (:func:`_product_of`, kept per step size).

        Raises
        ------
        ValueError
            The hold of ``h`` overflows (exp(A h), or only Gamma where B h is too large) and
            the state or the controls are not zero (the zero state stays zero).
        """
        product = self._products.get(h)
        if product is None:
            product = self._product(h)
        if product is False:  # Phi or Gamma overflows: only the zero solution is representable
            if not any(x) and not any(u):
                return [0.0] * len(x)
            if all(math.isfinite(v) for row in self.transition_rows(h)[0] for v in row):
                raise ValueError(
                    f"a step of {h!r} wing beats overflows the hold of the controls (Gamma = "
                    f"the integral of exp({self.A_NAME} s) over the step, times "
                    f"{self.B_NAME}; exp({self.A_NAME} h) is finite, {self.B_NAME} h too large "
                    f"for the float range), so only the zero state has a representable result; "
                    f"take shorter steps or smaller control derivatives")
            growth = self._growth_rate(h)
            raise ValueError(
                f"a step of {h!r} wing beats overflows exp({self.A_NAME} h) (fastest growth "
                f"{growth:.4f} per wing beat; exp({growth * h:.0f}) is beyond the float "
                f"range), so only the zero state has a representable result; take steps of at "
                f"most {math.log(1e300) / max(growth, 1e-300):.0f} wing beats")
        return product(x, u)

    def stepper(self, h: float, scale: Sequence[float], inputs: range,
                outputs: range) -> "Stepper | None":
        """The step of ``h`` for the FMUs' doStep, on a value table: the controls read from
        rows ``inputs``, the state times ``scale`` written to rows ``outputs``
        (:func:`_stepper`; the state as :meth:`step_list` gives it). None where
        exp(A h) overflows (then :meth:`step_list` decides). Not cached: the caller keeps it."""
        Phi, Gamma = self.transition_rows(h)
        M = tuple(p + g for p, g in zip(Phi, Gamma))
        if not all(math.isfinite(x) for row in M for x in row):
            return None
        return _stepper(M, scale, inputs, outputs)

    def _growth_rate(self, h: float) -> float:
        """The fastest growth per unit of time of exp(A t), for the message of a step of ``h``
        that overflows: log ||exp(A t)||_1 / t at the longest t = t0 2^k < h that does not
        overflow (which tends to the largest real part of A's eigenvalues as t grows), from
        t0 = 700 / ||A||_1, where ||exp(A t0)|| <= e^700 is finite: a few exponentials."""
        norm = norm1(self.A_rows)
        if not norm > 0.0:
            return 0.0
        t, rate = min(h, 700.0 / norm), math.inf
        while True:
            e = norm1(expm([[x * t for x in row] for row in self.A_rows]))
            if not math.isfinite(e):
                return rate
            rate = math.log(e) / t if e > 0.0 else rate
            if t >= h:
                return rate
            t = min(2.0 * t, h)

    def _product(self, h: float) -> Product | bool:
        """The product of [Phi, Gamma] for a step of ``h`` (cached); False if it overflows."""
        Phi, Gamma = self.transition_rows(h)
        M = tuple(p + g for p, g in zip(Phi, Gamma))
        if len(self._products) >= self._CACHE_SIZE:
            self._products.pop(next(iter(self._products)))
        finite = all(math.isfinite(x) for row in M for x in row)
        product = _product_of(M) if finite else False
        self._products[h] = product
        return product

    def eigenvalues(self) -> "Array":
        """Eigenvalues of A, sorted by descending real part, then imaginary part (numpy)."""
        np = _numpy()
        return np.array(sort_eigenvalues(np.linalg.eigvals(self.A)))
