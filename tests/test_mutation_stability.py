"""Independent oracles for the neutral-stability verdict (harness/cosim/identification.py), written
against the mutants that survived the other tests (docs/mutation.md): the identification
against scipy's exponential of the augmented matrix, the bounds at their edges."""

from __future__ import annotations

import dataclasses
import math
import re

import numpy as np
import pytest
import scipy.linalg

from dronefly.core.errors import CrossCheckError
from dronefly.harness.cosim import identification
from dronefly.models import feedback, lateral_dynamics

from test_mutation_models import N_HZ, U_M_PER_S


# --- harness/cosim/identification.py: identification against the exact sampled loop (scipy) -----

def _paper_loop():
    A, B = lateral_dynamics.system_matrices(lateral_dynamics.default_parameters())
    K = np.array(feedback.default_gains())
    return A, B, K


def _exact_transition(A, B, K, h, jacobi):
    """[[Phi, Gamma], [0, I]] = expm([[A, B], [0, 0]] h) (scipy), closed with u_k = K x_k
    (Gauss-Seidel) or u_k = K x_(k-1) (Jacobi)."""
    n, m = B.shape
    E = scipy.linalg.expm(np.block([[A, B], [np.zeros((m, n + m))]]) * h)
    Phi, Gamma = E[:n, :n], E[:n, n:]
    if not jacobi:
        return Phi + Gamma @ K
    return np.block([[Phi, Gamma @ K], [np.eye(n), np.zeros((n, n))]])


@pytest.mark.parametrize("jacobi", [False, True])
def test_sampled_closed_loop_is_the_exponential_of_the_augmented_matrix(jacobi):
    A, B, K = _paper_loop()
    F = identification.sampled_closed_loop(A, B, K, 0.7, jacobi)
    # both exponentials of a matrix of norm < 1: agree to rounding
    np.testing.assert_allclose(F, _exact_transition(A, B, K, 0.7, jacobi), rtol=1e-12,
                               atol=1e-14)


def _runs(F, steps, n_states=4, delay=False):
    """Trajectories x_(k+1) = F x_k from the unit states (Jacobi: z = (x_k, x_(k-1)), first
    row x_(-1) = 0)."""
    runs = []
    for e in np.eye(n_states):
        z = np.concatenate([e, np.zeros(n_states)]) if delay else e
        xs = [np.zeros(n_states), e] if delay else [e]
        for _ in range(steps):
            z = F @ z
            xs.append(z[:n_states])
        runs.append(np.array(xs))
    return runs


@pytest.mark.parametrize("jacobi", [False, True])
def test_identify_recovers_the_exact_loop_and_its_rates(jacobi):
    A, B, K = _paper_loop()
    h = 0.5
    F = _exact_transition(A, B, K, h, jacobi)
    ident = identification.identify(_runs(F, 40, delay=jacobi), h, jacobi)
    np.testing.assert_allclose(ident.transition, F, atol=1e-10)
    assert ident.fit_residual < 1e-12
    # Gauss-Seidel: the rates log(eig F) / h; Eq. (27) makes the loop neutral (a zero rate)
    mu = np.linalg.eigvals(F)
    mu = mu[np.abs(mu) > 1e-7]
    want = np.log(mu.astype(complex)) / h
    assert sorted(ident.eigenvalues, key=lambda z: (z.real, z.imag)) == pytest.approx(
        sorted(want, key=lambda z: (z.real, z.imag)), abs=1e-8)
    assert ident.dominant_growth_rate == pytest.approx(max(want.real), abs=1e-8)
    assert ident.verdict == "neutral"
    assert len(ident.eigenvalues) == (4 if not jacobi else len(mu))
    checked = identification.verdict_of(_runs(F, 40, delay=jacobi), h, delay=jacobi, where="t")
    assert checked.verdict == "neutral" and checked.step_wb == h


def test_identify_weighs_each_pair_by_its_start_norm():
    # one run grows by 1e6 per step, another decays: unweighted, the large pairs would
    # swamp the fit; with the weights both rates come out exactly
    F = np.diag([1e6, 1e-3, 0.5, 2.0])
    runs = [np.array([e, F @ e, F @ F @ e]) for e in np.eye(4)]
    ident = identification.identify(runs, 1.0, False)
    np.testing.assert_allclose(ident.transition, F, rtol=1e-12, atol=1e-12)
    assert sorted(ident.eigenvalues.real) == pytest.approx(
        sorted(np.log([1e6, 1e-3, 0.5, 2.0])), rel=1e-12)
    assert ident.verdict == "unstable"


def test_rates_from_transition_drop_the_delay_modes_only():
    h = 0.25
    rates = np.array([-0.5, -0.1, 0.2, -3.0])
    F = np.diag(np.concatenate([np.exp(rates * h), [0.0, 1e-8, 2e-7]]))
    got = identification.rates_from_transition(F, h)
    # |mu| <= 1e-7 is a pure delay; 2e-7 is a (fast) physical mode: log(2e-7) / h
    want = np.concatenate([rates, [np.log(2e-7) / h]])
    assert sorted(got.real) == pytest.approx(sorted(want), rel=1e-12)
    assert np.all(got.imag == 0.0)
    # a rotation exp(i w h): a pair +/- i w
    w = 0.3
    R = np.array([[np.cos(w * h), -np.sin(w * h)], [np.sin(w * h), np.cos(w * h)]])
    got = identification.rates_from_transition(R, h)
    assert sorted(got.imag) == pytest.approx([-w, w], rel=1e-12)
    assert np.max(np.abs(got.real)) < 1e-14


@pytest.mark.parametrize("dominant, verdict", [
    (1e-3, "neutral"), (-1e-3, "neutral"), (0.0, "neutral"),
    (1e-3 * (1 + 1e-12), "unstable"), (-1e-3 * (1 + 1e-12), "stable"),
    (0.0786, "unstable"), (-0.5, "stable"),
])
def test_classify_by_the_dominant_rate_and_its_tolerance(dominant, verdict):
    assert identification.TOL_PER_WINGBEAT == 1e-3
    assert identification.classify(np.array([dominant - 1.0, dominant, dominant - 0.1j])) == verdict


def test_checked_refuses_a_fit_that_is_not_the_loop():
    ident = identification.Identification(np.eye(4), np.zeros(4, complex), 0.0, "neutral", 1e-9)
    assert identification.checked(ident, "there") is ident  # at the bound: accepted
    for resid in (1.0000001e-9, math.nan):
        bad = dataclasses.replace(ident, fit_residual=resid)
        with pytest.raises(CrossCheckError, match=re.escape(
                "there: the identification's fit residual")) as err:
            identification.checked(bad, "there")
        assert "> 1e-09: the runs are not the linear 4-state loop identified, so its " \
            "verdict 'neutral' is not theirs" in str(err.value)


def test_cross_check_failures_one_sentence_per_failed_check():
    ok = dict(ident_rate=0.0, exact_rate=1e-6, resid=1e-9, err=1e-8, ident_verdict="neutral",
              exact_verdict="neutral", exact="eig(A + B K)")
    assert identification.cross_check_failures(**ok) == []  # every bound is inclusive
    # the rates are compared by their difference (equal rates far from 0 pass)
    assert identification.cross_check_failures(**dict(ok, ident_rate=0.5, exact_rate=0.5)) == []
    assert identification.cross_check_failures(**dict(ok, ident_rate=0.5, exact_rate=0.25)) == [
        "the identified dominant rate +0.5 per wing beat deviates from +0.25 of eig(A + B K) by "
        "2.5e-01 > 1e-06"]
    bad = dict(ident_rate=0.0, exact_rate=2e-6, resid=2e-9, err=2e-8, ident_verdict="stable",
               exact_verdict="neutral", exact="eig(A + B K)")
    assert identification.cross_check_failures(**bad) == [
        "the identification's fit residual 2.0e-09 > 1e-09: the runs are not the linear loop "
        "identified",
        "the identified dominant rate +0 per wing beat deviates from +2e-06 of eig(A + B K) by "
        "2.0e-06 > 1e-06",
        "the identified verdict 'stable' is not 'neutral' of eig(A + B K)",
        "the co-simulated states deviate from the exact sampled-data solution by 2.0e-08 of "
        "their peak > 1e-08",
    ]
    nan = dict(ok, ident_rate=math.nan, resid=math.nan, err=math.nan)
    assert len(identification.cross_check_failures(**nan)) == 3


def test_relative_deviation_is_relative_to_each_states_peak():
    ref = np.array([[1.0, -100.0], [0.5, 50.0], [0.0, 0.0]])
    xs = ref + np.array([[0.01, 0.0], [0.0, 3.0], [0.0, 0.0]])
    assert identification.relative_deviation(xs, ref) == pytest.approx(0.03, rel=1e-14)
    assert identification.relative_deviation(ref + [[0.02, 0.0], [0, 0], [0, 0]], ref) == \
        pytest.approx(0.02, rel=1e-14)
    assert math.isnan(identification.relative_deviation(np.zeros((0, 2)), np.zeros((0, 2))))
    # a state that stays 0 in both: no deviation (not 0 / 0)
    assert identification.relative_deviation(ref * [1.0, 0.0], ref * [1.0, 0.0]) == 0.0
    # a state that stays 0 in the reference: any deviation of it is huge, not a division by 0
    assert identification.relative_deviation(np.array([[0.0, 1e-290]]), np.array([[1.0, 0.0]])) > 1e9


def test_unit_start_values_are_the_unit_states_made_dimensional():
    scale = np.array([U_M_PER_S, N_HZ, N_HZ, 1.0])
    got = identification.unit_start_values(scale, prefix="plant.")
    assert got == [
        {"plant.delta_v_start": U_M_PER_S, "plant.delta_p_start": 0.0,
         "plant.delta_r_start": 0.0, "plant.delta_gamma_start": 0.0},
        {"plant.delta_v_start": 0.0, "plant.delta_p_start": N_HZ,
         "plant.delta_r_start": 0.0, "plant.delta_gamma_start": 0.0},
        {"plant.delta_v_start": 0.0, "plant.delta_p_start": 0.0,
         "plant.delta_r_start": N_HZ, "plant.delta_gamma_start": 0.0},
        {"plant.delta_v_start": 0.0, "plant.delta_p_start": 0.0,
         "plant.delta_r_start": 0.0, "plant.delta_gamma_start": 1.0},
    ]


def test_fit_residual_of_inconsistent_pairs_is_the_closed_form():
    # one state, two runs x0 = 0.5 -> 0.5 a and x0 = 0.25 -> 0.25 b: the pairs scaled to unit
    # |z_k|, (1, a) and (1, b), fit F = (a + b) / 2 with residual |a - b| / 2 (least squares
    # of two equal-weight points)
    a, b = 0.9, 0.7
    ident = identification.identify([np.array([[0.5], [0.5 * a]]), np.array([[0.25], [0.25 * b]])],
                               0.5, False)
    assert ident.transition[0, 0] == pytest.approx((a + b) / 2, rel=1e-14)
    assert ident.fit_residual == pytest.approx(abs(a - b) / 2, rel=1e-12)
    assert ident.eigenvalues[0] == pytest.approx(math.log((a + b) / 2) / 0.5, rel=1e-13)
    with pytest.raises(dataclasses.FrozenInstanceError):
        ident.verdict = "neutral"  # type: ignore[misc]


def test_a_mode_at_the_delay_bound_is_dropped():
    got = identification.rates_from_transition(np.diag([0.5, 1e-7]), 1.0)
    assert list(got) == [pytest.approx(math.log(0.5), rel=1e-14)]


def test_verdict_is_immutable():
    F = np.diag([0.9, 0.8])
    runs = [np.array([e, F @ e]) for e in np.eye(2)]
    v = identification.verdict_of(runs, 1.0, delay=False, where="t")
    assert v.verdict == "stable" and v.runs is runs
    with pytest.raises(dataclasses.FrozenInstanceError):
        v.step_wb = 2.0  # type: ignore[misc]


def test_a_run_from_the_zero_state_adds_nothing_to_the_fit():
    # pairs (0, 0) carry no information: weight times zero, not 0 / 0
    F = np.diag([0.9, 0.8])
    runs = [np.array([e, F @ e, F @ F @ e]) for e in np.eye(2)] + [np.zeros((3, 2))]
    ident = identification.identify(runs, 1.0, False)
    np.testing.assert_allclose(ident.transition, F, rtol=1e-14, atol=1e-15)
    assert ident.fit_residual < 1e-15


def test_verdict_of_takes_the_ordering_and_the_runner_by_keyword():
    F = np.diag([0.9, 0.8])
    runs = [np.array([e, F @ e]) for e in np.eye(2)]
    with pytest.raises(TypeError):
        identification.verdict_of(runs, 1.0, False, "t")  # type: ignore[misc]
