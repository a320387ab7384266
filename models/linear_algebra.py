"""Plain-Python dense linear algebra for the FMUs' runtime: the matrix exponential.

The FMUs run inside any host that has a CPython 3 interpreter, with nothing but the standard
library (docs/fmi-limits.md, "What the host needs"). The zero-order hold of the linear plants
needs exp(M) of the augmented matrix M = [[A h, B h], [0, 0]] (at most 8 x 8) once per step
size; this module computes it with the scaling-and-squaring method and a diagonal Pade
approximant of degree 3, 5, 7, 9 or 13, chosen from the 1-norm of M (N. J. Higham, "The scaling
and squaring method for the matrix exponential revisited", SIAM J. Matrix Anal. Appl. 26(4),
2005, Algorithm 2.3 and Table 2.3). The tests cross-check it against ``scipy.linalg.expm``.

Matrices are sequences of rows (lists or tuples of floats). Every sum of products is
``math.fsum`` (correctly rounded; the plain sum where it overflows), every other operation plain float arithmetic in a fixed
order: the same bits on every machine and Python version (``sum`` of floats changed in 3.12),
independent of any BLAS.
Shipped inside every FMU; imports only the standard library.
"""

from __future__ import annotations

import math
from typing import List, Sequence

__all__ = ["Matrix", "expm", "hold_exponential", "hold_shift", "identity", "matmul", "norm1", "solve"]

#: a dense matrix as a list of rows
Matrix = List[List[float]]  # (typing.List: Python 3.8 hosts)

#: Higham (2005), Table 2.3: the largest 1-norm for which the [m/m] Pade approximant of degree
#: m has a backward error of at most the unit round-off 2**-53
_THETA = ((3, 1.495585217958292e-2), (5, 2.539398330063230e-1), (7, 9.504178996162932e-1),
          (9, 2.097847961257068e0))
_THETA13 = 5.371920351148152e0

#: coefficients b_0 ... b_m of the numerator p_m(x) = sum b_k x^k of the [m/m] Pade
#: approximant of exp(x), scaled to integers (the denominator is p_m(-x))
_PADE: dict[int, tuple[float, ...]] = {
    3: (120.0, 60.0, 12.0, 1.0),
    5: (30240.0, 15120.0, 3360.0, 420.0, 30.0, 1.0),
    7: (17297280.0, 8648640.0, 1995840.0, 277200.0, 25200.0, 1512.0, 56.0, 1.0),
    9: (17643225600.0, 8821612800.0, 2075673600.0, 302702400.0, 30270240.0, 2162160.0,
        110880.0, 3960.0, 90.0, 1.0),
    13: (64764752532480000.0, 32382376266240000.0, 7771770303897600.0, 1187353796428800.0,
         129060195264000.0, 10559470521600.0, 670442572800.0, 33522128640.0, 1323241920.0,
         40840800.0, 960960.0, 16380.0, 182.0, 1.0),
}


def _fsum(values: list[float]) -> float:
    """``math.fsum``, or the plain sum (inf or nan) where fsum refuses: an infinite or nan term,
    or an intermediate overflow (the exponential overflowing the float range)."""
    try:
        return math.fsum(values)
    except (OverflowError, ValueError):
        return sum(values, 0.0)


def identity(n: int) -> Matrix:
    """The n x n identity matrix."""
    return [[1.0 if i == j else 0.0 for j in range(n)] for i in range(n)]


def matmul(a: Sequence[Sequence[float]], b: Sequence[Sequence[float]]) -> Matrix:
    """The product ``a @ b`` (each entry the correctly rounded sum of the rounded products)."""
    cols = list(zip(*b))
    return [[_fsum([x * y for x, y in zip(row, col)]) for col in cols] for row in a]


def norm1(a: Sequence[Sequence[float]]) -> float:
    """The 1-norm of ``a``: the largest column sum of absolute values."""
    return max(_fsum([abs(x) for x in col]) for col in zip(*a))


def _combine(terms: Sequence[tuple[float, Sequence[Sequence[float]]]]) -> Matrix:
    """sum of c * M over the (c, M) pairs, entry by entry in the given order."""
    n, m = len(terms[0][1]), len(terms[0][1][0])
    return [[_fsum([c * M[i][j] for c, M in terms]) for j in range(m)] for i in range(n)]


def solve(a: Sequence[Sequence[float]], b: Sequence[Sequence[float]]) -> Matrix:
    """The solution X of ``a X = b`` by Gaussian elimination with partial pivoting.

    Parameters
    ----------
    a : (n, n) matrix
    b : (n, k) matrix

    Raises
    ------
    ZeroDivisionError
        ``a`` is singular to working precision (an exactly zero pivot).
    """
    n = len(a)
    lu = [list(map(float, row)) for row in a]
    x = [list(map(float, row)) for row in b]
    for k in range(n):
        p = max(range(k, n), key=lambda i: abs(lu[i][k]))
        if p != k:
            lu[k], lu[p] = lu[p], lu[k]
            x[k], x[p] = x[p], x[k]
        pivot = lu[k][k]
        rk, xk = lu[k], x[k]
        for i in range(k + 1, n):
            f = lu[i][k] / pivot
            if f != 0.0:
                ri, xi = lu[i], x[i]
                for j in range(k + 1, n):
                    ri[j] -= f * rk[j]
                for j in range(len(xi)):
                    xi[j] -= f * xk[j]
    for k in range(n - 1, -1, -1):
        rk, xk, pivot = lu[k], x[k], lu[k][k]
        for j in range(len(xk)):
            s = xk[j]
            for i in range(k + 1, n):
                s -= rk[i] * x[i][j]
            xk[j] = s / pivot
    return x


def _pade(a: Matrix, m: int) -> tuple[Matrix, Matrix]:
    """(U, V): the odd and even parts of p_m(a), so that r_m(a) = (V - U)^-1 (V + U)."""
    b = _PADE[m]
    n = len(a)
    eye = identity(n)
    a2 = matmul(a, a)
    if m < 13:
        powers = [eye, a2]  # a^0, a^2, a^4, ... up to a^(m-1)
        while len(powers) < (m + 1) // 2:
            powers.append(matmul(powers[-1], a2))
        u = matmul(a, _combine([(b[2 * k + 1], p) for k, p in enumerate(powers)]))
        v = _combine([(b[2 * k], p) for k, p in enumerate(powers)])
        return u, v
    a4 = matmul(a2, a2)
    a6 = matmul(a4, a2)
    inner_u = matmul(a6, _combine([(b[13], a6), (b[11], a4), (b[9], a2)]))
    u = matmul(a, _combine([(1.0, inner_u), (b[7], a6), (b[5], a4), (b[3], a2), (b[1], eye)]))
    inner_v = matmul(a6, _combine([(b[12], a6), (b[10], a4), (b[8], a2)]))
    v = _combine([(1.0, inner_v), (b[6], a6), (b[4], a4), (b[2], a2), (b[0], eye)])
    return u, v


def expm(a: Sequence[Sequence[float]]) -> Matrix:
    """The matrix exponential exp(a) of a square matrix of finite floats.

    Scaling and squaring with a [m/m] Pade approximant (Higham 2005, Algorithm 2.3): the
    smallest degree m in (3, 5, 7, 9) whose bound theta_m the 1-norm does not exceed, else
    degree 13 after scaling ``a`` by 2**-s so that its 1-norm is at most theta_13, and s
    squarings. The backward error is at most the unit round-off in exact arithmetic; the
    relative forward error is that times the condition number of exp at ``a``.

    Parameters
    ----------
    a : (n, n) matrix
        Finite entries (in the plants: A and B times the step, per wing beat times wing beats,
        so unit 1).

    Returns
    -------
    list of list of float
        exp(a); entries may be inf or nan where the exponential overflows the float range.

    Raises
    ------
    ValueError
        ``a`` is not square, or an entry is not finite.
    """
    rows = [list(map(float, row)) for row in a]
    n = len(rows)
    if n == 0 or any(len(row) != n for row in rows):
        raise ValueError(f"expm needs a square matrix, got rows of lengths "
                         f"{[len(row) for row in rows]}")
    if not all(map(math.isfinite, (x for row in rows for x in row))):
        raise ValueError("expm needs finite entries")
    norm = norm1(rows)
    for m, theta in _THETA:
        if norm <= theta:
            u, v = _pade(rows, m)
            return solve(_combine([(1.0, v), (-1.0, u)]), _combine([(1.0, v), (1.0, u)]))
    if math.isinf(norm):  # finite entries whose column sum overflows: bound it by n max|a|
        big = max(abs(x) for row in rows for x in row)
        s = math.ceil(math.log2(n) + math.log2(big) - math.log2(_THETA13))
    else:
        s = max(0, math.ceil(math.log2(norm / _THETA13))) if norm > _THETA13 else 0
    scaled = [[math.ldexp(x, -s) for x in row] for row in rows]
    u, v = _pade(scaled, 13)
    r = solve(_combine([(1.0, v), (-1.0, u)]), _combine([(1.0, v), (1.0, u)]))
    for _ in range(s):
        squared = matmul(r, r)
        if squared == r:  # a fixed point of squaring: every further squaring gives it again
            break  # (a stable exp(A h) for a huge h: e^(A h) underflown to 0, its integral at
            # -A^-1 B; up to a thousand squarings, a tenth of a second each time, saved)
        r = squared
        if not all(math.isfinite(x) for row in r for x in row):
            break  # overflowed: stays inf or nan (and fsum would only be slower)
    return r


#: the norms that choose the hold's scaling are taken of the entries times 2**-11, so that a
#: column of up to 2**11 finite entries sums to a finite float (2**11 * 2**1024 * 2**-11)
_NORM_SHIFT = -11


def _shifted_norm(a: Sequence[Sequence[float]]) -> float:
    """1-norm of ``a`` times 2**_NORM_SHIFT, finite for finite entries (under 2**11 rows)."""
    return max(_fsum([math.ldexp(abs(x), _NORM_SHIFT) for x in col]) for col in zip(*a))


def hold_shift(ah: Sequence[Sequence[float]], bh: Sequence[Sequence[float]]) -> int:
    """The least k >= 0 for which the 1-norm of B h 2**-k is at most theta_13 2**s_A, where
    s_A is the number of squarings that :func:`expm` takes for A h alone: B h scaled by
    2**-k no longer raises them (:func:`hold_exponential`). 0 where B h does not exceed that
    bound. Finite entries, under 2**11 rows."""
    cap = math.ldexp(_THETA13, _NORM_SHIFT)  # theta_13 2**s_A, shifted as the norms are
    norm_a, norm_b = _shifted_norm(ah), _shifted_norm(bh)
    while norm_a > cap:
        cap *= 2.0
    k = 0
    while norm_b > math.ldexp(cap, k):
        k += 1
    return k


def hold_exponential(ah: Sequence[Sequence[float]],
                     bh: Sequence[Sequence[float]]) -> tuple[Matrix, Matrix]:
    """The blocks Phi = exp(A h) and Gamma = (integral of exp(A s) over [0, h]) B of
    exp([[A h, B h], [0, 0]]): the zero-order hold of x' = A x + B u over a step h.

    :func:`expm` chooses its squarings from the 1-norm of the whole matrix. Where the columns
    of B h are far larger than those of A h, that norm would take more squarings than A h
    needs, and their rounding errors reach Phi (Phi 7.5e-8 off exp(10) for A = 0.5, B = 1e10,
    h = 20). Gamma is linear in B, so B h is scaled by 2**-k, the least k for which its 1-norm
    no longer raises the squarings that A h alone needs (it is at most theta_13 2**s_A), and
    Gamma is scaled back by 2**k: both exact in binary floating point (the scaled entries of B
    may lose bits only where they become subnormal). Where B h does not exceed that bound,
    k = 0 and the result is :func:`expm`'s of the augmented matrix, bit for bit. The native
    FMUs' ``fmu_expm_hold`` (native/expm.c) computes the same operations.

    Parameters
    ----------
    ah : (n, n) rows of float
        A h, finite (unit 1: per wing beat times wing beats in the plants).
    bh : (n, m) rows of float
        B h, finite, one row per row of ``ah``.

    Returns
    -------
    Phi, Gamma : list of list of float
        (n, n) and (n, m); entries may be inf or nan where the hold overflows the float range.

    Raises
    ------
    ValueError
        The blocks' shapes do not fit, or an entry is not finite.
    """
    n = len(ah)
    if n == 0 or len(bh) != n or any(len(row) != n for row in ah) or not bh[0] \
            or any(len(row) != len(bh[0]) for row in bh):
        raise ValueError(f"hold_exponential needs A h of n x n and B h of n x m, got rows of "
                         f"lengths {[len(row) for row in ah]} and {[len(row) for row in bh]}")
    if not all(map(math.isfinite, (x for rows in (ah, bh) for row in rows for x in row))):
        raise ValueError("expm needs finite entries")
    m, k = len(bh[0]), hold_shift(ah, bh)
    aug = [[float(x) for x in ah[i]] + [math.ldexp(float(x), -k) for x in bh[i]]
           for i in range(n)]
    aug += [[0.0] * (n + m) for _ in range(m)]
    e = expm(aug)
    return [row[:n] for row in e[:n]], [[_ldexp(x, k) for x in row[n:]] for row in e[:n]]


def _ldexp(x: float, k: int) -> float:
    """x 2**k, infinite where it overflows (as C's ldexp; Python's raises)."""
    try:
        return math.ldexp(x, k)
    except OverflowError:
        return math.copysign(math.inf, x)
