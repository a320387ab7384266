"""The plain-Python matrix exponential (models/linear_algebra.py) follows Higham's algorithm
step by step, written against the mutants that survived tests/test_expm.py (docs/mutation.md).

Oracle: N. J. Higham, "The scaling and squaring method for the matrix exponential revisited",
SIAM J. Matrix Anal. Appl. 26(4), 2005: Algorithm 2.3 takes the [m/m] Pade approximant of the
smallest degree m in (3, 5, 7, 9) with ||A||_1 <= theta_m, evaluated with pi_m = 2, 3, 4, 5
matrix products (Table 2.2), else degree 13 (pi_13 = 6 products) after scaling A by 2**-s,
s = ceil(log2(||A||_1 / theta_13)), and s squarings. A wrong degree, a wrong s or a wrong
evaluation scheme changes the number of products while the result stays within round-off
(which the accuracy tests of test_expm.py allow): the products are counted here. Plain Python
and closed forms only (no numpy: fast, so that a mutant costs seconds).
"""

from __future__ import annotations

import math
import sys

import pytest

from dronefly.models import linear_algebra as la

#: Higham (2005), Table 2.3 (theta_m) and Table 2.2 (pi_m: products to evaluate r_m)
THETA = {3: 1.495585217958292e-2, 5: 2.539398330063230e-1, 7: 9.504178996162932e-1,
         9: 2.097847961257068e0, 13: 5.371920351148152e0}
PI = {3: 2, 5: 3, 7: 4, 9: 5, 13: 6}


def _counting(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    calls = [0]
    real = la.matmul

    def matmul(a, b):
        calls[0] += 1
        return real(a, b)

    monkeypatch.setattr(la, "matmul", matmul)
    return calls


def _diag(*values: float) -> list[list[float]]:
    return [[v if i == j else 0.0 for j in range(len(values))] for i, v in enumerate(values)]


@pytest.mark.parametrize("m", [3, 5, 7, 9, 13])
@pytest.mark.parametrize("where", [0.0, 0.5, 1.0])
def test_expm_takes_the_pade_degree_of_higham_table_2_3(monkeypatch, m, where):
    """A 1-norm just above the bound below theta_m (the next float), half way to theta_m and at
    theta_m (the bound is inclusive): degree m, pi_m products, no squaring; the result is e^a."""
    below = max([t for k, t in THETA.items() if k < m], default=0.0)
    norm = {0.0: math.nextafter(below, math.inf), 0.5: (below + THETA[m]) / 2,
            1.0: THETA[m]}[where]
    calls = _counting(monkeypatch)
    e = la.expm(_diag(norm, -norm / 2))
    assert calls[0] == PI[m]
    # backward error <= u ||A||, and cond(exp, a) = |a| (< 6): relative error 32 u max(1, |a|)
    tol = 32 * 2.0 ** -53 * max(1.0, norm)
    assert math.isclose(e[0][0], math.exp(norm), rel_tol=tol)
    assert math.isclose(e[1][1], math.exp(-norm / 2), rel_tol=tol)
    assert e[0][1] == e[1][0] == 0.0


@pytest.mark.parametrize("norm", [5.5, 10.75, 20.0, 300.0, 1400.0])
def test_expm_scales_by_the_smallest_power_of_two_of_algorithm_2_3(monkeypatch, norm):
    """||A||_1 > theta_13: s = ceil(log2(||A||_1 / theta_13)) squarings after the degree-13
    approximant's 6 products; the result of a diagonal matrix is e^a on the diagonal (or inf
    where e^a overflows, after the squaring that overflowed: no further squaring)."""
    s = math.ceil(math.log2(norm / THETA[13]))
    calls = _counting(monkeypatch)
    a = -norm if norm > 700 else norm / 2  # e^a inside the float range
    e = la.expm(_diag(-norm, a))
    assert calls[0] == PI[13] + s
    # cond(exp, a) = |a|; each squaring doubles the relative error of the scaled approximant
    assert math.isclose(e[1][1], math.exp(a), rel_tol=64 * 2.0 ** -53 * max(1.0, abs(a)))


def test_expm_stops_squaring_at_a_fixed_point(monkeypatch):
    """||A||_1 = 2^20: s = 18 and the scaled diagonal is -4; the k-th squaring is
    e^(-4 * 2^k), which underflows to 0 at k = 8 (4 * 2^8 = 1024 > 1075 ln 2 = 745.1, the
    exponent of the smallest subnormal); the 9th squaring gives 0 again, a fixed point: no
    further product. The zero-order hold of a stable plant over a huge step, exp([[-h, h],
    [0, 0]]) = [[e^-h, 1 - e^-h], [0, 1]], is [[0, 1], [0, 1]] for h = 1e300 (s = 995) after
    a few dozen squarings."""
    s = math.ceil(math.log2(2.0 ** 20 / THETA[13]))
    k = next(k for k in range(s + 1) if 4 * 2.0 ** k > 1075 * math.log(2))
    assert (s, k) == (18, 8)
    calls = _counting(monkeypatch)
    assert la.expm(_diag(-2.0 ** 20, -2.0 ** 20)) == [[0.0, 0.0], [0.0, 0.0]]
    assert calls[0] == PI[13] + k + 1
    calls[0] = 0
    (e00, e01), bottom = la.expm([[-1e300, 1e300], [0.0, 0.0]])
    # the integral block is 1 to a few units of round-off: the fixed point inherits the scaled
    # approximant's error (backward error 2^-53 on an entry of size 1, Higham 2005)
    assert e00 == 0.0 and bottom == [0.0, 1.0] and abs(e01 - 1.0) <= 8 * 2.0 ** -53
    assert calls[0] < PI[13] + 100 < PI[13] + math.ceil(math.log2(2e300 / THETA[13]))


def test_expm_stops_squaring_once_the_result_overflows(monkeypatch):
    """exp(1e5) overflows: s = 15, and the scaled exponential e^(1e5 / 2^15) = e^3.05 overflows
    at the 8th squaring (3.05 * 2^8 = 781 > log(max float) = 709.8); after it, no further product."""
    s = math.ceil(math.log2(1e5 / THETA[13]))
    k = next(k for k in range(s + 1) if 1e5 / 2.0 ** s * 2.0 ** k > math.log(sys.float_info.max))
    assert (s, k) == (15, 8)
    calls = _counting(monkeypatch)
    e = la.expm([[1e5]])
    assert e == [[math.inf]]
    assert calls[0] == PI[13] + k


@pytest.mark.parametrize("a, b, x", [
    # the multiplier f = a[1][0] / a[0][0] is -1 (pivoting keeps the first row on a tie)
    ([[2.0, 1.0], [-2.0, 3.0]], [[4.0], [4.0]], [[1.0], [2.0]]),
    # f = 1 and f = 0 (a row that needs no elimination)
    ([[2.0, 1.0], [2.0, 3.0]], [[4.0], [8.0]], [[1.0], [2.0]]),
    ([[2.0, 1.0, 0.0], [0.0, 1.0, 1.0], [4.0, 0.0, 1.0]], [[3.0], [3.0], [6.0]],
     [[1.0], [1.0], [2.0]]),
])
def test_solve_eliminates_every_multiplier(a, b, x):
    """Gaussian elimination on small integers whose solution is exact in floating point
    (checked by the product a x = b, exact too)."""
    assert la.matmul(a, x) == b
    assert la.solve(a, b) == x


def test_sums_that_overflow_are_infinite_rather_than_an_error():
    """math.fsum raises OverflowError where finite terms sum beyond the float range, ValueError
    for inf - inf: the product and the norm give inf and nan instead (IEEE 754 arithmetic)."""
    assert la.matmul([[1e308, 1e308]], [[1.0], [1.0]]) == [[math.inf]]
    assert la.norm1([[1e308], [1e308]]) == math.inf
    nan = la.matmul([[math.inf, -math.inf]], [[1.0], [1.0]])[0][0]
    assert math.isnan(nan)


def test_expm_refuses_an_empty_matrix_as_not_square():
    with pytest.raises(ValueError, match="square"):
        la.expm([])


def test_expm_of_entries_whose_norm_overflows_is_computed():
    """Finite entries whose 1-norm overflows the float range (a column of two 1e308): scaled by
    n max|a| instead. The oracle: N is nilpotent (N^2 = 0), so exp(N) = I + N exactly, and so
    is every squaring of I + N / 2^s in floating point ((I + M)^2 = I + 2 M, exact doublings)."""
    n = [[0.0, 0.0, 1e308], [0.0, 0.0, 1e308], [0.0, 0.0, 0.0]]
    assert la.norm1(n) == math.inf
    assert la.expm(n) == [[1.0, 0.0, 1e308], [0.0, 1.0, 1e308], [0.0, 0.0, 1.0]]
