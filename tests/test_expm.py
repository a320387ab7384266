"""The FMUs' plain-Python matrix exponential (dronefly.models.linear_algebra.expm) and zero-order hold
(dronefly.models.linear.zoh_rows), against scipy.linalg.expm and analytic exponentials."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.linalg import expm as scipy_expm

from dronefly.models.linear import discretize_zoh, zoh_rows
from dronefly.models.linear_algebra import expm, matmul, solve
from dronefly.models import lateral_dynamics
from dronefly.models import longitudinal_dynamics

U = 2.0 ** -53  # unit round-off of double precision
#: Relative 1-norm error allowed between two backward-stable exponentials of M: each is off by
#: at most cond(exp, M) * u, and for these matrices cond(exp, M) is of the order of ||M||_1
#: (Higham 2005, Sect. 1; measured worst over 600 plant cases: 32 u ||M||_1), so 128 u
#: max(1, ||M||_1) leaves a factor 4 above what was seen.
FACTOR = 128.0


def _rel_error(E, R) -> float:
    E, R = np.asarray(E, float), np.asarray(R, float)
    return float(np.linalg.norm(E - R, 1) / np.linalg.norm(R, 1))


@pytest.mark.parametrize("norm", [1e-6, 1e-2, 0.2, 0.9, 2.0, 5.0, 20.0])
@pytest.mark.parametrize("n", [1, 2, 4, 7, 8])
def test_expm_matches_scipy_at_every_pade_degree(n, norm):
    """Random n x n matrices with 1-norms on both sides of each Pade degree's bound (theta_3 =
    0.015 ... theta_13 = 5.4, and scaled beyond it): relative error at round-off times ||M||.
    At larger 1-norms random matrices are ill-conditioned (and at some hundreds, with
    eigenvalues of +-200, scipy's algorithm is the less accurate of the two): there the closed
    form of the next test is the oracle."""
    rng = np.random.default_rng(1000 * n + int(norm * 100))
    for _ in range(5):
        M = rng.normal(size=(n, n))
        M *= norm / np.linalg.norm(M, 1)
        R = scipy_expm(M)
        err = _rel_error(expm(M.tolist()), R)
        assert err <= FACTOR * U * max(1.0, norm), (n, norm, err)


@pytest.mark.parametrize("norm", [0.5, 20.0, 300.0])
def test_expm_of_2x2_matrices_is_the_closed_form(norm):
    """exp(M) = e^s (cosh d I + sinh d / d (M - s I)), s = tr M / 2, d^2 = s^2 - det M (cos and
    sin for d^2 < 0), for random 2 x 2 matrices up to eigenvalues of +-250; the closed form's
    own error is of the order u d, so the bound is FACTOR u max(1, ||M||_1)."""
    rng = np.random.default_rng(int(norm * 10))
    for _ in range(10):
        M = rng.normal(size=(2, 2))
        M *= norm / np.linalg.norm(M, 1)
        s = (M[0, 0] + M[1, 1]) / 2
        d2 = s * s - (M[0, 0] * M[1, 1] - M[0, 1] * M[1, 0])
        d = math.sqrt(abs(d2))
        c, f = (math.cosh(d), math.sinh(d) / d) if d2 > 0 else (math.cos(d), math.sin(d) / d)
        ref = math.exp(s) * (c * np.eye(2) + f * (M - s * np.eye(2)))
        assert _rel_error(expm(M.tolist()), ref) <= FACTOR * U * max(1.0, norm)


@pytest.mark.parametrize("t", [1e-8, 0.01, 0.5, 3.0, 40.0])
def test_expm_of_a_rotation_and_a_jordan_block_is_analytic(t):
    """exp([[0, -w], [w, 0]] t) = [[cos wt, -sin wt], [sin wt, cos wt]]; exp of the 3 x 3 Jordan
    block J(lambda) t = e^(lambda t) [[1, t, t^2/2], [0, 1, t], [0, 0, 1]]. The rotation's
    condition is ||M||: errors up to FACTOR u max(1, wt)."""
    w = 1.3
    E = expm([[0.0, -w * t], [w * t, 0.0]])
    c, s = math.cos(w * t), math.sin(w * t)
    assert _rel_error(E, [[c, -s], [s, c]]) <= FACTOR * U * max(1.0, w * t)
    lam = -0.2
    J = expm([[lam * t, t, 0.0], [0.0, lam * t, t], [0.0, 0.0, lam * t]])
    e = math.exp(lam * t)
    ref = [[e, e * t, e * t * t / 2], [0.0, e, e * t], [0.0, 0.0, e]]
    assert _rel_error(J, ref) <= FACTOR * U * max(1.0, (abs(lam) + 1.0) * t) * (1.0 + t)


def test_solve_and_matmul_are_exact_on_small_integers():
    """Gaussian elimination with pivoting (a zero leading pivot) and the product, on integers
    whose results are exact in floating point."""
    a = [[0.0, 2.0, 1.0], [1.0, 1.0, 0.0], [2.0, 0.0, 1.0]]
    x = [[1.0, 2.0], [-1.0, 0.0], [3.0, 1.0]]
    b = matmul(a, x)
    assert b == [[1.0, 1.0], [0.0, 2.0], [5.0, 5.0]]
    assert solve(a, b) == x


def test_expm_rejects_what_it_cannot_exponentiate():
    with pytest.raises(ValueError, match="square"):
        expm([[1.0, 2.0]])
    with pytest.raises(ValueError, match="finite"):
        expm([[math.nan]])


def _cases(model, n_cases: int, seed: int):
    """Parameters the FMU accepts (every default scaled by 10^U(-1, 1), rejected sets skipped)
    and steps of 10^U(-4, 3) wing beats (1e-4 wb to 1000 wb: the open loop grows at most by
    e^80 there, inside the float range)."""
    rng = np.random.default_rng(seed)
    p0 = model.default_parameters()
    out = []
    while len(out) < n_cases:
        p = p0.with_values(**{n: getattr(p0, n) * 10 ** rng.uniform(-1, 1) for n in p0.names()})
        try:
            A, B = model.system_rows(p)
        except model.ModelParameterError:
            continue
        out.append((A, B, 10 ** rng.uniform(-4, 3)))
    return out


@pytest.mark.parametrize("model", [lateral_dynamics, longitudinal_dynamics], ids=["lateral", "longitudinal"])
def test_zero_order_hold_matches_scipy_over_the_parameter_range(model):
    """Phi and Gamma of the plants' exact zero-order hold (7 x 7 and 8 x 8 augmented matrices)
    against scipy.linalg.expm of the same augmented matrix, over 150 parameter sets and steps
    the FMU accepts: relative error at most FACTOR u max(1, ||M||_1)."""
    for A, B, h in _cases(model, 150, seed=28 + len(model.default_parameters().names())):
        n, m = len(A), len(B[0])
        M = np.zeros((n + m, n + m))
        M[:n, :n], M[:n, n:] = np.array(A) * h, np.array(B) * h
        R = scipy_expm(M)[:n]
        Phi, Gamma = zoh_rows(A, B, h)
        err = _rel_error(np.hstack([Phi, Gamma]), R)
        assert err <= FACTOR * U * max(1.0, np.linalg.norm(M, 1)), (h, err)


def test_zero_order_hold_is_the_same_under_another_blas_kernel(tmp_path):
    """The plain-Python exponential uses no BLAS: the default plant's Phi and Gamma over 0.1 wing
    beat are the same floats with OPENBLAS_CORETYPE=Prescott (the numpy analysis path may not)."""
    import os
    import subprocess
    import sys

    code = ("from dronefly.models import lateral_dynamics as m; "
            "from dronefly.models.linear import discretize_zoh, zoh_rows; "
            "A, B = m.system_rows(m.default_parameters()); "
            "print(*[x.hex() for M in zoh_rows(A, B, 0.1) for r in M for x in r])")
    runs = [subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                           env={**os.environ, **extra}, timeout=60, check=True).stdout.split()
            for extra in ({}, {"OPENBLAS_CORETYPE": "Prescott"})]
    assert [float.fromhex(x) for x in runs[0]] == [float.fromhex(x) for x in runs[1]]


def test_expm_beyond_the_float_range_is_not_finite_rather_than_an_error():
    """exp(1000 I) overflows: entries inf or nan, no exception (the plant then refuses the step
    or keeps the zero state, tests/test_plant_slave.py)."""
    E = expm([[1000.0, 1.0], [0.0, 1000.0]])
    assert not all(math.isfinite(x) for row in E for x in row)


@pytest.mark.parametrize("b", [1e10, 1e100, 1e300])
def test_a_hold_whose_control_matrix_dwarfs_the_system_matrix_is_exact(b):
    """x' = a x + b u over h = 20 with a = 0.5: Phi = e^(a h) and Gamma = (e^(a h) - 1) b / a
    (closed form), however large b. The exponential of [[a h, b h], [0, 0]] as it stands would
    take its squarings from b h (over 30 more than a h = 10 needs) and their rounding reaches Phi
    (7.5e-8 off at b = 1e10): hold_exponential scales b h down first. Bound: each is a backward-
    stable exponential of a h, relative error cond(exp, a h) u = |a h| u, with FACTOR's margin."""
    a, h = 0.5, 20.0
    Phi, Gamma = zoh_rows([[a]], [[b]], h)
    phi, gamma = math.exp(a * h), math.expm1(a * h) / a * b
    assert abs(Phi[0][0] / phi - 1.0) <= FACTOR * U * a * h
    assert abs(Gamma[0][0] / gamma - 1.0) <= FACTOR * U * a * h


@pytest.mark.parametrize("scale", [1e3, 1e12, 1e100])
@pytest.mark.parametrize("model", [lateral_dynamics, longitudinal_dynamics],
                         ids=["lateral", "longitudinal"])
def test_a_plant_with_control_derivatives_far_above_the_paper_keeps_its_phi(model, scale):
    """The plant's B times ``scale`` over a step of 20 wing beats, through the FMUs' hold
    (zoh_rows) and the analyses' (discretize_zoh). Oracles: Phi is scipy's
    exp(A h); Gamma, linear in B, is ``scale`` times scipy's hold at the paper's B (scipy's
    exponential of the augmented matrix is itself driven by B h: its Phi is 360 u off at 1e12
    and 1e13 u at 1e100). Each within FACTOR u max(1, ||A h||_1) of its own norm, the
    conditioning of exp(A h), plus one rounding of the product by ``scale``."""
    A, B = model.system_rows(model.default_parameters())
    n, m, h = len(A), len(B[0]), 20.0
    M = np.zeros((n + m, n + m))
    M[:n, :n], M[:n, n:] = np.array(A) * h, np.array(B) * h
    Bs = [[x * scale for x in row] for row in B]
    bound = FACTOR * U * max(1.0, np.linalg.norm(M[:n, :n], 1)) + U
    # the FMUs' plain-Python hold, and the analyses' (scipy's expm, B h scaled the same way)
    for Phi, Gamma in (zoh_rows(A, Bs, h), discretize_zoh(np.array(A), np.array(Bs), h)):
        assert _rel_error(Phi, scipy_expm(M[:n, :n])) <= bound
        assert _rel_error(Gamma, scale * scipy_expm(M)[:n, n:]) <= bound


@pytest.mark.parametrize("model", [lateral_dynamics, longitudinal_dynamics],
                         ids=["lateral", "longitudinal"])
def test_a_hold_whose_control_matrix_does_not_dwarf_the_system_matrix_is_expms(model):
    """At the paper's parameters B h never raises the squarings (no scaling): the hold is the
    augmented exponential's blocks bit for bit, over steps of 0.01 to 100 wing beats."""
    A, B = model.system_rows(model.default_parameters())
    n, m = len(A), len(B[0])
    for h in (0.01, 0.1, 1.0, 10.0, 100.0):
        Phi, Gamma = zoh_rows(A, B, h)
        E = expm([[x * h for x in A[i]] + [x * h for x in B[i]] for i in range(n)]
                 + [[0.0] * (n + m) for _ in range(m)])
        assert [list(r) for r in Phi] == [r[:n] for r in E[:n]], h
        assert [list(r) for r in Gamma] == [r[n:] for r in E[:n]], h
