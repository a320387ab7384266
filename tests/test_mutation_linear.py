"""Independent oracles for models/linear.py (the plants' exact zero-order-hold stepping),
written against the mutants that survived the other tests (docs/mutation.md).

The straight-line products and steppers are checked entry by entry in exact arithmetic: every
value a small integer, so each product and each left-to-right sum is exact in floats and equals
the row . (x; u) of Fractions; the step itself against scipy's expm (test_expm.py has the
matrix exponential's own oracles)."""

from __future__ import annotations

import math
import re
from fractions import Fraction

import numpy as np
import pytest
from scipy.linalg import expm as scipy_expm

from dronefly.models import linear


def _rows(n_states: int, n_controls: int) -> linear.Rows:
    """Rows of distinct integers >= 2 with signs mixed (a * x and a / x differ, and so do
    a + b and a - b for every term)."""
    width = n_states + n_controls
    return tuple(tuple(float((2 + i * width + j) * (-1) ** (i + j)) for j in range(width))
                 for i in range(n_states))


def _exact(rows, x, u):
    """row . (x; u) in Fractions: the definition of the product."""
    xu = [Fraction(v) for v in (*x, *u)]
    return [float(sum(Fraction(a) * v for a, v in zip(row, xu))) for row in rows]


# distinct integers, none 0 or +-1; (x, u) of 4 states and 3 or 4 controls (the plants' shapes,
# written out), and general shapes, among them those whose rows are as long as the plants'
# (3 x 4: 7 columns, 5 x 3: 8) or that have 4 rows (4 x 2)
_X = (3.0, -5.0, 7.0, 11.0, -2.0)
_SHAPES = [(4, 3), (4, 4), (2, 1), (3, 2), (4, 2), (3, 4), (5, 3)]


@pytest.mark.parametrize("n, m", _SHAPES)
def test_the_product_is_each_rows_dot_with_x_and_u(n, m):
    rows = _rows(n, m)
    x, u = _X[:n], (13.0, -17.0, 19.0, -23.0)[:m]
    assert linear._product_of(rows)(x, u) == _exact(rows, x, u)


@pytest.mark.parametrize("n, m", _SHAPES)
def test_the_stepper_reads_its_controls_and_writes_its_scaled_outputs(n, m):
    """The value table: controls in rows 5.., outputs to rows 20.. (each times its scale, a
    power of two: exact); every other row keeps its marker value."""
    rows = _rows(n, m)
    x, u = _X[:n], (13.0, -17.0, 19.0, -23.0)[:m]
    scale = (2.0, 0.5, 4.0, 0.25, 8.0)[:n]
    r = [1000.0 + i for i in range(30)]
    r[5:5 + m] = u
    before = list(r)
    stepper = linear._stepper(rows, scale, range(5, 5 + m), range(20, 20 + n))
    want = _exact(rows, x, u)
    assert stepper(x, r) == want
    assert r[20:20 + n] == [w * s for w, s in zip(want, scale)]
    assert r[:20] == before[:20] and r[20 + n:] == before[20 + n:]


@pytest.mark.parametrize("n, m", _SHAPES)
@pytest.mark.parametrize("bad", [math.inf, -math.inf, math.nan])
def test_the_stepper_declines_a_control_that_is_not_finite(n, m, bad):
    """None, and the table unchanged: the caller names the bad value."""
    rows = _rows(n, m)
    r = [0.5] * 30
    r[5 + m - 1] = bad
    before = list(r)
    assert linear._stepper(rows, (1.0,) * n, range(5, 5 + m), range(20, 20 + n))(_X[:n], r) \
        is None
    assert [str(v) for v in r] == [str(v) for v in before]  # (nan != nan: compared by name)


@pytest.mark.numeric  # scipy's expm (BLAS) as the oracle
def test_zoh_model_stepper_is_the_exact_discretisation():
    """x' = A x + B u held over h: x1 = Phi x + Gamma u with [Phi, Gamma] the blocks of
    expm([[A, B], [0, 0]] h) (scipy's expm: an independent Pade implementation). A 2 x 1
    system takes the general stepper, the lateral shape (4 x 3) the straight-line one."""
    rng = np.random.default_rng(5)
    for n, m in ((2, 1), (4, 3), (4, 4)):
        A, B = rng.normal(size=(n, n)), rng.normal(size=(n, m))
        model = linear.ZohModel(A.tolist(), B.tolist())
        h = 0.7
        aug = np.zeros((n + m, n + m))
        aug[:n, :n], aug[:n, n:] = A * h, B * h
        E = scipy_expm(aug)
        x, u = rng.normal(size=n), rng.normal(size=m)
        want = E[:n, :n] @ x + E[:n, n:] @ u
        r = [0.0] * (m + n)
        r[:m] = u.tolist()
        got = model.stepper(h, (3.0,) * n, range(0, m), range(m, m + n))(x.tolist(), r)
        # ||E|| of order 1 to 10: two Pade implementations agree to 1e-13 or so
        assert got == pytest.approx(want, rel=1e-12, abs=1e-13)
        assert r[m:] == pytest.approx(3.0 * want, rel=1e-12, abs=1e-13)
        assert got == model.step_list(x.tolist(), u.tolist(), h)  # the same floats


def test_zoh_model_stepper_is_none_where_exp_overflows():
    model = linear.ZohModel([[1.0, 0.0], [0.0, -1.0]], [[1.0], [0.0]])
    assert model.stepper(1000.0, (1.0, 1.0), range(0, 1), range(1, 3)) is None


def test_an_overflowing_step_names_the_growth_rate_and_the_longest_step():
    """A = diag(0.5, -0.25): ||exp(A t)||_1 = exp(0.5 t), so the fastest growth is 0.5 per
    wing beat; a step of 2000 overflows exp(1000), and steps up to log(1e300) / 0.5 = 1381.6
    wing beats stay in range. ||A||_1 = 0.5 < 1."""
    model = linear.ZohModel([[0.5, 0.0], [0.0, -0.25]], [[1.0], [1.0]])
    with pytest.raises(ValueError, match=re.escape(
            "a step of 2000.0 wing beats overflows exp(A h) (fastest growth 0.5000 per wing "
            "beat; exp(1000) is beyond the float range), so only the zero state has a "
            "representable result; take steps of at most 1382 wing beats")):
        model.step_list([1.0, 0.0], [0.0], 2000.0)
    assert model.step_list([0.0, 0.0], [0.0], 2000.0) == [0.0, 0.0]  # zero stays zero


def test_a_step_whose_control_hold_alone_overflows_says_so():
    """A = 0.5, B = 1e300, h = 1000: exp(A h) = e^500 is finite (1.4e217), Gamma = (e^500 - 1)
    B / A is not. The refusal names Gamma and B, not exp(A h); zero stays zero."""
    model = linear.ZohModel([[0.5]], [[1e300]])
    Phi, Gamma = model.transition_rows(1000.0)
    assert math.isfinite(Phi[0][0]) and math.isinf(Gamma[0][0])
    with pytest.raises(ValueError, match=re.escape(
            "a step of 1000.0 wing beats overflows the hold of the controls (Gamma = the "
            "integral of exp(A s) over the step, times B; exp(A h) is finite, B h too large "
            "for the float range)")):
        model.step_list([1.0], [0.0], 1000.0)
    assert model.step_list([0.0], [0.0], 1000.0) == [0.0]


@pytest.mark.parametrize("n, m", _SHAPES)
def test_the_stepper_declines_outputs_whose_sum_overflows(n, m):
    """The documented screen: None also where the outputs are finite but their plain sum
    overflows (the caller then checks each value). Any two outputs 1e308, the others 0: their
    sum is 2e308 = inf (a difference of the two would be 0)."""
    rows = tuple(tuple(1.0 if j == i else 0.0 for j in range(n + m)) for i in range(n))
    for i in range(n):
        for j in range(i + 1, n):
            x = tuple(1e308 if k in (i, j) else 0.0 for k in range(n))
            r = [0.0] * 30
            stepper = linear._stepper(rows, (1.0,) * n, range(5, 5 + m), range(20, 20 + n))
            assert stepper(x, r) is None, (i, j)
            assert r == [0.0] * 30


@pytest.mark.parametrize("n, m", [(2, 1), (3, 2)])
def test_the_general_stepper_screens_the_controls_and_outputs_together(n, m):
    """The general stepper's plain sum holds the controls and the outputs: a control of 1e308
    (weighted 0 in every row) and an output of 1e308 sum to inf, so None (the caller checks each
    value); a difference of the two sums would be 0."""
    rows = tuple(tuple(1.0 if j == i else 0.0 for j in range(n + m)) for i in range(n))
    r = [0.0] * 30
    r[5] = 1e308
    before = list(r)
    x = (1e308,) + (0.0,) * (n - 1)
    assert linear._stepper(rows, (1.0,) * n, range(5, 5 + m), range(20, 20 + n))(x, r) is None
    assert r == before


@pytest.mark.numeric  # discretize_zoh is scipy's expm (BLAS)
def test_discretize_zoh_is_the_double_integrators_closed_form():
    """x'' = u: A = [[0, 1], [0, 0]], B = [[0], [1]]; over h, Phi = [[1, h], [0, 1]] and
    Gamma = [[h^2 / 2], [h]] (integrate u twice). Exact in floats for h = 0.75."""
    A, B = np.array([[0.0, 1.0], [0.0, 0.0]]), np.array([[0.0], [1.0]])
    Phi, Gamma = linear.discretize_zoh(A, B, 0.75)
    np.testing.assert_allclose(Phi, [[1.0, 0.75], [0.0, 1.0]], rtol=0, atol=1e-15)
    np.testing.assert_allclose(Gamma, [[0.75 ** 2 / 2], [0.75]], rtol=0, atol=1e-15)
    Phi, Gamma = linear.zoh_rows(A.tolist(), B.tolist(), 0.75)  # the FMUs' plain-Python path
    np.testing.assert_allclose(Phi, [[1.0, 0.75], [0.0, 1.0]], rtol=0, atol=1e-15)
    np.testing.assert_allclose(Gamma, [[0.75 ** 2 / 2], [0.75]], rtol=0, atol=1e-15)



def test_the_growth_rate_of_a_non_normal_A_follows_the_documented_rule():
    """A = [[0.5, 100], [0, 0.5]]: ||exp(A t)||_1 = exp(0.5 t) (1 + 100 t) (closed form), so
    log ||exp(A t)||_1 / t = 0.5 + log(1 + 100 t) / t, which tends to the eigenvalue 0.5 as t
    grows. The documented rule (ZohModel._growth_rate): t0 = 700 / ||A||_1 = 700 / 100.5,
    doubled while exp(A t) stays finite; the rate at the longest such t below the step, here
    t0 2^7 = 891.5 (0.5128; at t0 itself it would be 1.44)."""
    model = linear.ZohModel([[0.5, 100.0], [0.0, 0.5]], [[1.0], [1.0]])
    with pytest.raises(ValueError) as e:
        model.step_list([1.0, 0.0], [0.0], 2000.0)
    growth = float(re.search(r"fastest growth ([0-9.]+) per wing beat", str(e.value))[1])

    def log_norm(t):  # log ||exp(A t)||_1
        return 0.5 * t + math.log1p(100.0 * t)

    t = 700.0 / 100.5
    while log_norm(2.0 * t) < math.log(1.7976931348623157e308) and 2.0 * t < 2000.0:
        t *= 2.0
    assert t == pytest.approx(700.0 / 100.5 * 2 ** 7, rel=1e-15)
    assert growth == pytest.approx(log_norm(t) / t, abs=5e-5)  # (printed to 4 decimals)


def test_zoh_rows_of_a_scalar_system_is_its_closed_form():
    """x' = a x + b u held over h: Phi = exp(a h), Gamma = b (exp(a h) - 1) / a. a = -0.5,
    b = 3, h = 2: a few ulps apart (expm's Pade approximant; the closed form's two roundings)."""
    Phi, Gamma = linear.zoh_rows([[-0.5]], [[3.0]], 2.0)
    assert Phi[0][0] == pytest.approx(math.exp(-1.0), rel=1e-14)
    assert Gamma[0][0] == pytest.approx(3.0 * math.expm1(-1.0) / -0.5, rel=1e-14)
