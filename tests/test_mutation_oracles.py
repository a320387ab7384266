"""Independent oracles for the physics modules, written to kill the mutants that survived the
other tests (docs/mutation.md): the paper's definitions and printed values, closed forms."""

from __future__ import annotations

import dataclasses
import math
import re
import subprocess
import sys

import numpy as np
import pytest
import scipy.linalg

from dronefly.controller import timing, variables
from dronefly.core.errors import CrossCheckError, DroneflyError
from dronefly.harness.cosim import stability
from dronefly.models import feedback, lateral, lateral_dynamics, longitudinal_dynamics
from dronefly.models.linear import ModelParameterError

from controller_common import ROOT
from shared_files import need_shared

PAPER = ROOT.parent / "shared" / "paper" / "zhang-sun-lateral-stabilization-control.md"
from dronefly.models.axes import Axis

# Sect. 2.4: U = 2 Phi n r2, with Phi = 107.1 deg, n = 164 Hz, r2 = 0.55 R, R = 11.2 mm
N_HZ = 164.0
U_M_PER_S = 2.0 * math.radians(107.1) * N_HZ * 0.55 * 11.2e-3


def test_lateral_axis_scales_are_the_papers_definitions():
    # Sect. 2.1: dv+ = dv / U, dp+ = dp t_w, dr+ = dr t_w with t_w = 1/n; dgamma is an angle.
    x = (0.3, 5.0, -7.0, 0.02)
    t_w = 1.0 / N_HZ
    expected = (x[0] / U_M_PER_S, x[1] * t_w, x[2] * t_w, x[3])
    got = lateral.LATERAL.to_nondimensional(x, U_M_PER_S, N_HZ)
    # a division and a multiplication each: a few ulps apart at most
    assert got == pytest.approx(expected, rel=1e-14, abs=0.0)
    back = lateral.LATERAL.to_dimensional(expected, U_M_PER_S, N_HZ)
    assert back == pytest.approx(x, rel=1e-14, abs=0.0)
    assert lateral.LATERAL.scale_vector(U_M_PER_S, N_HZ) == (U_M_PER_S, N_HZ, N_HZ, 1.0)


def test_lateral_axis_names_each_nondimensional_component():
    assert lateral.NONDIMENSIONAL == ("x+1 = delta_v/U", "x+2 = delta_p/n", "x+3 = delta_r/n",
                                      "x+4 = delta_gamma")


@pytest.mark.parametrize("field", ["state_units", "state_descriptions", "scales",
                                   "control_descriptions"])
def test_axis_refuses_tables_of_the_wrong_length(field):
    kwargs = dict(name="t", state_names=("a", "b"), control_names=("u",),
                  state_units=(("m/s", None), ("rad", "deg")), control_unit=("rad", "deg"),
                  state_descriptions=("a", "b"), control_descriptions=("u",),
                  scales=("U", "1"))
    Axis(**kwargs)  # the consistent axis is accepted
    kwargs[field] = kwargs[field][:1] if field != "control_descriptions" else ("u", "v")
    with pytest.raises(DroneflyError, match="axis 't'"):
        Axis(**kwargs)


# --- models/feedback.py: u = clip(K x+ + KI z), x+ by Sect. 2.1, against numpy -------------

def _law_oracle(K, x, *, KI=None, z=None, u_max=None):
    """u = K x+ (+ KI z), clipped to [-u_max, u_max]; x+ = (dv/U, dp/n, dr/n, dgamma)."""
    xp = np.array([x[0] / U_M_PER_S, x[1] / N_HZ, x[2] / N_HZ, x[3]])
    u = np.asarray(K, float) @ xp
    if KI is not None:
        u = u + np.asarray(KI, float) @ np.asarray(z, float)
    if u_max is None:
        return u, False
    return np.clip(u, -u_max, u_max), bool(np.any(np.abs(u) > u_max))


_GAINS = {
    "eq27": feedback.default_gains(),  # one row of non-zero gains: the straight-line path
    "three_rows": tuple(map(tuple, np.random.default_rng(5).uniform(-2, 2, (3, 4)).tolist())),
}


@pytest.mark.parametrize("limited", [False, True])
@pytest.mark.parametrize("gains", list(_GAINS))
def test_every_evaluation_path_of_the_law_is_K_x_plus_clipped(gains, limited):
    K = _GAINS[gains]
    # a limit that some samples exceed and some do not
    limit = {"eq27": 0.05, "three_rows": 0.5}[gains] if limited else None
    law = feedback.FeedbackLaw(K, u_max=limit or 0.4, limit_enabled=limit is not None)
    law.validate()
    proportional = law.evaluate_proportional
    states, controls, saturated = (0, 2, 4, 6), range(7, 10), 10
    table = law.on_table(states, controls, saturated)
    rng = np.random.default_rng(11)
    seen = set()
    for xp in rng.normal(0.0, 0.3, (60, 4)):
        x = [xp[0] * U_M_PER_S, xp[1] * N_HZ, xp[2] * N_HZ, xp[3]]
        want, want_sat = _law_oracle(K, x, u_max=limit)
        seen.add(want_sat)
        # sums of four products of O(1) terms: a few ulps
        u, sat = law.evaluate(x)
        assert u == pytest.approx(tuple(want), rel=1e-12, abs=1e-15) and sat is want_sat
        u, sat = proportional(x)
        assert u == pytest.approx(list(want), rel=1e-12, abs=1e-15) and sat is want_sat
        r = [None] * 11
        for i, v in zip(states, x):
            r[i] = v
        assert table(r) is True
        assert r[7:10] == pytest.approx(list(want), rel=1e-12, abs=1e-15)
        assert r[saturated] is want_sat
    assert seen == ({False} if limit is None else {False, True})


@pytest.mark.parametrize("gains", list(_GAINS))
def test_the_fast_paths_decline_a_non_finite_state(gains):
    law = feedback.FeedbackLaw(_GAINS[gains])
    table = law.on_table((0, 1, 2, 3), range(4, 7), 7)
    for bad in (math.inf, -math.inf, math.nan):
        x = [0.1, bad, 0.0, 0.0]
        assert law.evaluate_proportional(x) is None
        r = x + [1.0, 2.0, 3.0, "untouched"]
        assert table(r) is False and r[4:] == [1.0, 2.0, 3.0, "untouched"]


@pytest.mark.parametrize("gains", list(_GAINS))
def test_the_fast_paths_decline_an_overflowing_control(gains):
    K = tuple(tuple(1e300 * k for k in row) for row in _GAINS[gains])
    law = feedback.FeedbackLaw(K)
    x = [1e300, 1e300, 1e300, 1e300]  # finite state; K x+ overflows
    assert law.evaluate_proportional(x) is None
    assert law.on_table((0, 1, 2, 3), range(4, 7), 7)(x + [0.0, 0.0, 0.0, False]) is False
    with pytest.raises(feedback.LawParameterError, match="overflows"):
        law.evaluate(x)


def test_integral_action_adds_KI_z():
    rng = np.random.default_rng(2)
    K = _GAINS["three_rows"]
    KI = tuple(map(tuple, rng.uniform(-1, 1, (3, 4)).tolist()))
    law = feedback.FeedbackLaw(K, KI=KI, u_max=0.3, limit_enabled=True)
    law.validate()
    assert law.has_integral
    assert not feedback.FeedbackLaw(K, KI=((0.0,) * 4,) * 3).has_integral
    for _ in range(20):
        x = list(rng.normal(0.0, 0.3, 4) * (U_M_PER_S, N_HZ, N_HZ, 1.0))
        z = rng.normal(0.0, 0.3, 4)
        want, want_sat = _law_oracle(K, x, KI=KI, z=z, u_max=0.3)
        u, sat = law.evaluate(x, list(z))
        assert u == pytest.approx(tuple(want), rel=1e-12, abs=1e-15) and sat is want_sat
        # without z, the proportional law alone
        u, _ = law.evaluate(x)
        assert u == pytest.approx(tuple(_law_oracle(K, x, u_max=0.3)[0]), rel=1e-12, abs=1e-15)


@pytest.mark.parametrize("changes, fragment", [
    ({"KI": ((0.0, math.nan, 0.0, 0.0),) + ((0.0,) * 4,) * 2}, "KI[1,2] = nan"),
    ({"KI": ((0.0,) * 4,) * 2}, "KI must be 3x4"),
    ({"K": ((0.0,) * 3,) * 3}, "K must be 3x4"),
    ({"n": math.inf}, "n = inf"),
    ({"U": math.nan}, "U = nan"),
])
def test_law_validation_covers_the_integral_gains_and_non_finite_scales(changes, fragment):
    law = feedback.FeedbackLaw(**{"K": feedback.default_gains(), **changes})
    with pytest.raises(feedback.LawParameterError, match=re.escape(fragment)):
        law.validate()
    feedback.FeedbackLaw(feedback.default_gains(), u_max=1e-300).validate()  # tiny is > 0


def test_law_with_two_or_three_states_takes_the_general_dot_product():
    # an axis with two states: u = K x+ still, summed by models.axes.dot
    axis = Axis("two", ("a", "b"), ("u",), (("m/s", None), ("rad", "deg")), ("rad", "deg"),
                ("a", "b"), ("u",), ("U", "1"))
    law = feedback.FeedbackLaw(((2.0, -3.0),), axis=axis, U=4.0)
    law.validate()
    assert law.evaluate([8.0, 0.5]) == ((2.0 * 8.0 / 4.0 - 3.0 * 0.5,), False)
    assert law.evaluate_proportional([8.0, 0.5]) == ([2.0 * 8.0 / 4.0 - 3.0 * 0.5], False)


# --- models/lateral_dynamics.py, longitudinal_dynamics.py: Eqs. (9)-(11), Sect. 3.5 ----------

def _random_lateral(seed: int):
    """Parameters with every derivative drawn at random (inertias keep Ix Iz > Ixz^2)."""
    rng = np.random.default_rng(seed)
    p = lateral_dynamics.default_parameters()
    values = {n: float(rng.uniform(-3.0, 3.0)) for n in p.names()}
    values.update(m_plus=float(rng.uniform(50, 150)), Ix_plus=float(rng.uniform(5, 15)),
                  Iz_plus=float(rng.uniform(5, 15)), Ixz_plus=float(rng.uniform(-4, 4)))
    return p.with_values(**values)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_lateral_rows_solve_eqs_10_11(seed):
    """Eq. (9)-(11): m+ dv+ = Y + m+ g+ dgamma; [Ix -Ixz; -Ixz Iz] [dp+'; dr+'] = [L; N];
    dgamma' = dp+. Solved here by numpy for the derivatives of each column."""
    p = _random_lateral(seed)
    A, B = (np.array(M) for M in lateral_dynamics.system_rows(p))
    inertia = np.array([[p.Ix_plus, -p.Ixz_plus], [-p.Ixz_plus, p.Iz_plus]])
    want_A = np.zeros((4, 4))
    for j, s in enumerate("vpr"):
        Y, L, N = (getattr(p, f"{F}{s}_plus") for F in "YLN")
        want_A[0, j] = Y / p.m_plus
        want_A[1:3, j] = np.linalg.solve(inertia, [L, N])
    want_A[0, 3], want_A[3, 1] = p.g_plus, 1.0
    want_B = np.zeros((4, 3))
    for j, c in enumerate(("Phi_a", "alpha_1a", "alpha_2a")):
        Y, L, N = (getattr(p, f"{F}_{c}_plus") for F in "YLN")
        want_B[0, j] = Y / p.m_plus
        want_B[1:3, j] = np.linalg.solve(inertia, [L, N])
    # a 2x2 solve by Cramer's rule against LAPACK: cond(inertia) < 10 here, so 1e-13 is ample
    np.testing.assert_allclose(A, want_A, rtol=1e-13, atol=1e-15)
    np.testing.assert_allclose(B, want_B, rtol=1e-13, atol=1e-15)
    # derive_stability_derivatives inverts Eq. (10) exactly: back to the same derivatives
    inertias = {k: getattr(p, k) for k in ("m_plus", "Ix_plus", "Iz_plus", "Ixz_plus")}
    back = lateral_dynamics.derive_stability_derivatives(A, inertias)
    for name, value in back.items():
        assert value == pytest.approx(getattr(p, name), rel=1e-12, abs=1e-13)


@pytest.mark.parametrize("changes, fragment", [
    ({"m_plus": 0.0}, "m_plus = 0.0 must be > 0"),
    ({"m_plus": -0.5}, "m_plus = -0.5 must be > 0"),
    ({"Ix_plus": 0.0}, "must be > 0"),
    ({"Iz_plus": 0.0}, "must be > 0"),
    ({"Ix_plus": -0.5}, "must be > 0"),
    ({"Iz_plus": -0.5}, "must be > 0"),
    ({"Ix_plus": 4.0, "Iz_plus": 1.0, "Ixz_plus": 2.0}, "must exceed"),  # det exactly 0
    ({"Ix_plus": 4.0, "Iz_plus": 1.0, "Ixz_plus": -3.0}, "must exceed"),
    ({"Ix_plus": 1e200, "Iz_plus": 1e200}, "is not finite"),  # Ix Iz overflows
    ({"Yv_plus": 1e308, "m_plus": 1e-10}, "A[1,1] = inf is not finite"),
    ({"Y_alpha_2a_plus": -1e308, "m_plus": 1e-10}, "B[1,3] = -inf is not finite"),
])
def test_lateral_parameters_refused_at_their_bounds(changes, fragment):
    p = lateral_dynamics.default_parameters().with_values(**changes)
    with pytest.raises(ModelParameterError, match=re.escape(fragment)):
        lateral_dynamics.system_rows(p)


def test_lateral_parameters_just_inside_the_bounds_are_accepted():
    # 0.5 lies between the bound 0 and the bound that a changed constant (0 -> 1) would give
    p = lateral_dynamics.default_parameters().with_values(m_plus=0.5, Ix_plus=0.5,
                                                          Iz_plus=0.5, Ixz_plus=0.0)
    A, _ = lateral_dynamics.system_rows(p)
    assert A[0][0] == pytest.approx(p.Yv_plus / 0.5, rel=1e-15)
    lateral_dynamics.system_rows(p.with_values(Ix_plus=1.0, Iz_plus=1.0, Ixz_plus=0.999))


@pytest.mark.parametrize("seed", [4, 5])
def test_longitudinal_rows_are_the_derivatives_over_mass_and_inertia(seed):
    """Sect. 3.5: X = m+ A[0, :], Z = m+ A[1, :], M = Iy+ A[2, :]; A[0, 3] = -g+; dtheta' = dq+."""
    rng = np.random.default_rng(seed)
    p0 = longitudinal_dynamics.default_parameters()
    p = p0.with_values(**{n: float(rng.uniform(-3, 3)) for n in p0.names()})
    p = p.with_values(m_plus=float(rng.uniform(50, 150)), Iy_plus=float(rng.uniform(5, 40)))
    A, B = (np.array(M) for M in longitudinal_dynamics.system_rows(p))
    scale = (p.m_plus, p.m_plus, p.Iy_plus)
    for i, F in enumerate("XZM"):
        for j, s in enumerate("uwq"):
            assert A[i, j] == getattr(p, f"{F}{s}_plus") / scale[i]
        for j, c in enumerate(("Phi", "alpha_1", "phibar", "alpha_2")):
            assert B[i, j] == getattr(p, f"{F}_{c}_plus") / scale[i]
    assert A[0, 3] == -p.g_plus and A[1, 3] == 0.0 and A[2, 3] == 0.0
    np.testing.assert_array_equal(A[3], [0.0, 0.0, 1.0, 0.0])
    np.testing.assert_array_equal(B[3], [0.0] * 4)
    back = longitudinal_dynamics.derive_derivatives(A, B, p.m_plus, p.Iy_plus)
    for name, value in back.items():
        assert value == pytest.approx(getattr(p, name), rel=1e-14, abs=1e-15)


def test_longitudinal_default_is_the_printed_matrices():
    # Sect. 3.5 prints A and B; the defaults are derived from them and give them back
    A, B = longitudinal_dynamics.system_rows(longitudinal_dynamics.default_parameters())
    np.testing.assert_allclose(A, longitudinal_dynamics.A_SECT35, rtol=1e-14, atol=1e-18)
    np.testing.assert_allclose(B, longitudinal_dynamics.B_SECT35, rtol=1e-14, atol=1e-18)


@pytest.mark.parametrize("name", ["m_plus", "Iy_plus"])
@pytest.mark.parametrize("value", [0.0, -0.5])
def test_longitudinal_mass_and_inertia_must_be_positive(name, value):
    p = longitudinal_dynamics.default_parameters()
    with pytest.raises(ModelParameterError, match=re.escape(f"{name} = {value!r} must be > 0")):
        longitudinal_dynamics.system_rows(p.with_values(**{name: value}))
    longitudinal_dynamics.system_rows(p.with_values(**{name: 0.5}))


@pytest.mark.parametrize("row, col, controls, want", [
    (3, 0, False, ()), (3, 2, True, ()),
    (0, 3, False, ("g_plus",)), (1, 3, False, ()), (2, 3, False, ()),
    (0, 0, False, ("m_plus", "Xu_plus")), (1, 2, False, ("m_plus", "Zq_plus")),
    (2, 1, False, ("Iy_plus", "Mw_plus")), (2, 3, True, ("Iy_plus", "M_alpha_2_plus")),
    (0, 2, True, ("m_plus", "X_phibar_plus")),
])
def test_longitudinal_parameter_dependencies_follow_the_equations(row, col, controls, want):
    assert longitudinal_dynamics.parameter_dependencies(row, col, controls) == want


def test_table1_control_derivatives_are_the_printed_row():
    """Table 1 of the paper, read from its text: the nine values in the printed order."""
    need_shared(PAPER, "the paper's text")
    text = PAPER.read_text(encoding="utf-8")
    table = text[text.index("Table 1 Non-dimensional control derivatives"):]
    row = [line for line in table.splitlines() if line.startswith("| -0.049")][0]
    printed = [float(cell) for cell in row.strip("| ").split("|")]
    order = [f"{F}_{c}_plus" for c in ("Phi_a", "alpha_1a", "alpha_2a") for F in "YLN"]
    assert [lateral_dynamics.CONTROL_DERIVATIVES_TABLE1[k] for k in order] == printed


def test_lateral_parameters_are_immutable_and_name_the_singular_products():
    p = lateral_dynamics.default_parameters()
    with pytest.raises(dataclasses.FrozenInstanceError):
        p.m_plus = 1.0  # type: ignore[misc]
    bad = p.with_values(Ix_plus=4.0, Iz_plus=2.0, Ixz_plus=-3.0)
    with pytest.raises(ModelParameterError, match=re.escape(
            "Ix_plus*Iz_plus = 8.0 must exceed Ixz_plus^2 = 9.0 (Ixz_plus = -3.0)")):
        bad.validate()


def _printed_matrix(text: str, symbol: str) -> list[list[float]]:
    r"""The matrix printed as ``\boldsymbol{<symbol>}=\left[\begin{array}...\end{array}``."""
    start = text.index(r"\boldsymbol{%s}=\left[\begin{array}{cccc}" % symbol)
    body = text[text.index("}", text.index("array}", start) + 6) + 1:text.index(r"\end{array}",
                                                                                 start)]
    return [[float(c) for c in row.split("&")] for row in body.split(r"\\")]


def test_sect35_matrices_are_the_printed_ones():
    """Sect. 3.5 (from Ref. [17]): A and B as the paper prints them, read from its text."""
    need_shared(PAPER, "the paper's text")
    text = PAPER.read_text(encoding="utf-8")
    assert _printed_matrix(text, "A") == [list(r) for r in longitudinal_dynamics.A_SECT35]
    assert _printed_matrix(text, "B") == [list(r) for r in longitudinal_dynamics.B_SECT35]


# --- controller/timing.py: the latency an importer sees, by counting grid steps by hand -----

def test_tolerance_is_the_documented_bound():
    h = 0.1
    assert timing.tolerance(0.0, 5.0, 0.0) == 0.0 and timing.tolerance(0.0, 5.0, -h) == 0.0
    assert timing.tolerance(0.0, 0.0, h) == timing.TOLERANCE * h  # no drift at t0
    # the drift DRIFT m^2 h of m steps from t0 = 0 equals TOLERANCE h at m = sqrt(1e-9 * 2^52)
    m = math.sqrt(timing.TOLERANCE / timing.DRIFT)
    assert 2100 < m < 2150  # "after about 2100 steps"
    assert timing.tolerance(0.0, m * h, h) == pytest.approx(2 * timing.TOLERANCE * h, rel=1e-9)
    assert timing.tolerance(-m * h, 0.0, h) == timing.TOLERANCE * h  # |t| = 0
    assert timing.tolerance(m * h, 0.0, h) == timing.TOLERANCE * h
    assert timing.tolerance(0.0, -m * h, h) == pytest.approx(2 * timing.TOLERANCE * h, rel=1e-9)
    # capped at DRIFT_CAP h from m = sqrt(5e-5 * 2^52) = 4.7e5 steps on
    assert timing.tolerance(0.0, 1e6 * h, h) == pytest.approx(
        (timing.TOLERANCE + timing.DRIFT_CAP) * h, rel=1e-12)


@pytest.mark.parametrize("delay, period, lo, hi", [
    (0.0, 0.0, 0.0, 0.0),      # in effect at once
    (0.25, 0.0, 3, 3),         # a control due 2.5 steps later shows at the 3rd point
    (0.2, 0.0, 2, 2),          # a whole number of steps: exactly that
    # sampled every 3 steps: only the points whose step holds a sample count, here the
    # points on the samples: seen at once, or half a step of delay later: at the next point
    (0.0, 0.3, 0, 0),
    (0.05, 0.3, 1, 1),
    # samples at 0.25 k: at points 0.0 and 0.5 (at once) and inside the steps from 0.2 and
    # 0.7 (seen at the next point, one step later)
    (0.0, 0.25, 0, 1),
    (0.0, 0.05, 0, 0),         # sampled twice a step: the first sample is at the point
])
def test_seen_latency_counts_grid_steps(delay, period, lo, hi):
    h = 0.1
    got = timing.Timing(delay, period).seen_latency(h)
    # steps of 0.1 are not exact binary: a few ulps of the times involved
    assert got == pytest.approx((lo * h, hi * h), abs=1e-12)


def test_seen_latency_beyond_the_float_range_is_infinite():
    assert timing.Timing(0.0, 0.0).seen_latency(1e308, steps=5) == (0.0, 0.0)
    # (d + t) / h overflows: no instant index
    assert timing.Timing(1.7e308, 0.0).seen_latency(0.5, steps=3) == (math.inf, math.inf)
    # a delay of 8 steps of 1e307: the index times h overflows from the 10th point on
    lo, hi = timing.Timing(8e307, 0.0).seen_latency(1e307)
    assert lo == pytest.approx(8e307, rel=1e-15) and hi == math.inf
    # a grid that leaves the float range after one step: one point seen
    assert timing.Timing(0.0, 0.0).seen_latency(1.5e308, steps=5) == (0.0, 0.0)
    assert timing.Timing(0.0, 0.0).seen_latency(1.0, steps=0) == (math.inf, math.inf)


@pytest.mark.parametrize("delay, period, seen", [
    (0.25, 0.0, "3 step(s) (0.3 s) later"),
    (0.0, 0.25, "0 to 1 steps (0 to 0.1 s) later"),
    (1.7e308, 0.0, "more than 2000 steps later (or beyond float range)"),
])
def test_off_grid_warning_states_the_seen_latency(delay, period, seen):
    h = 0.5 if delay > 1e300 else 0.1
    text = timing.Timing(delay, period).off_grid_warning("a sample instant", 0.25, 0.2, h,
                                                         "FMI 3.0")
    assert f"the importer sees the control of an input set at a communication point {seen}, " \
        "instead of sensing_delay" in text
    assert text.startswith(f"sensing_delay = {delay!r} s and sample_period = {period!r} s on a "
                           f"communication step of {h} s: a sample instant (t = 0.25 s) falls "
                           "inside the step from 0.2 s. Inputs are constant over a "
                           "communication step (FMI 3.0 co-simulation)")


def test_off_grid_warning_with_a_latency_infinite_at_one_end():
    t = timing.Timing(0.0, 0.0)
    assert "0 step(s) (0 s) later" in t.off_grid_warning("x", 0.0, 0.0, 1.0)
    text = timing.Timing(8e307, 0.0).off_grid_warning("x", 0.0, 0.0, 1e307)
    assert "8 steps (8e+307 s) or more later" in text


@pytest.mark.parametrize("kwargs, fragment", [
    ({"sensing_delay": -0.1}, "sensing_delay = -0.1 s must be finite and >= 0"),
    ({"sensing_delay": math.nan}, "sensing_delay = nan s must be finite and >= 0"),
    ({"sample_period": -1e-300}, "sample_period = -1e-300 s must be finite and >= 0"),
    ({"sample_period": math.inf}, "sample_period = inf s must be finite and >= 0"),
    ({"delay_required": True}, "sensing_delay = 0.0 s must be > 0 in this FMU"),
])
def test_timing_validation_names_the_value(kwargs, fragment):
    with pytest.raises(timing.SensingError, match=re.escape(fragment)):
        timing.Timing(**kwargs).validate()


def test_timing_accepts_its_bounds_and_knows_when_it_is_immediate():
    timing.Timing(0.0, 0.0).validate()
    timing.Timing(1e-300, 0.0, delay_required=True).validate()
    assert timing.Timing(0.0, 0.0).immediate is True
    assert timing.Timing(1e-300, 0.0).immediate is False
    assert timing.Timing(0.0, 1e-300).immediate is False


def test_delay_line_bound_is_max_samples_of_the_longer_of_step_and_period():
    h = 0.5
    at_bound = timing.Timing(timing.MAX_SAMPLES * h, 0.0)
    at_bound.check_step(h)  # exactly MAX_SAMPLES entries: accepted
    over = timing.Timing(timing.MAX_SAMPLES * h * (1 + 1e-15), 0.0)
    with pytest.raises(timing.SensingError, match=re.escape(
            f"a delay line of more than {timing.MAX_SAMPLES} samples")):
        over.check_step(h)
    # a sample period longer than the step sets the bound
    timing.Timing(timing.MAX_SAMPLES * 2.0, 2.0).check_step(h)
    with pytest.raises(timing.SensingError, match="communication step of 0.5 s"):
        timing.Timing(timing.MAX_SAMPLES * 2.0 + 1.0, 2.0).check_step(h)
    assert timing.MAX_SAMPLES == 100_000


# --- harness/cosim/stability.py: identification against the exact sampled loop (scipy) -----

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
    F = stability.sampled_closed_loop(A, B, K, 0.7, jacobi)
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
    ident = stability.identify(_runs(F, 40, delay=jacobi), h, jacobi)
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
    checked = stability.verdict_of(_runs(F, 40, delay=jacobi), h, delay=jacobi, where="t")
    assert checked.verdict == "neutral" and checked.step_wb == h


def test_identify_weighs_each_pair_by_its_start_norm():
    # one run grows by 1e6 per step, another decays: unweighted, the large pairs would
    # swamp the fit; with the weights both rates come out exactly
    F = np.diag([1e6, 1e-3, 0.5, 2.0])
    runs = [np.array([e, F @ e, F @ F @ e]) for e in np.eye(4)]
    ident = stability.identify(runs, 1.0, False)
    np.testing.assert_allclose(ident.transition, F, rtol=1e-12, atol=1e-12)
    assert sorted(ident.eigenvalues.real) == pytest.approx(
        sorted(np.log([1e6, 1e-3, 0.5, 2.0])), rel=1e-12)
    assert ident.verdict == "unstable"


def test_rates_from_transition_drop_the_delay_modes_only():
    h = 0.25
    rates = np.array([-0.5, -0.1, 0.2, -3.0])
    F = np.diag(np.concatenate([np.exp(rates * h), [0.0, 1e-8, 2e-7]]))
    got = stability.rates_from_transition(F, h)
    # |mu| <= 1e-7 is a pure delay; 2e-7 is a (fast) physical mode: log(2e-7) / h
    want = np.concatenate([rates, [np.log(2e-7) / h]])
    assert sorted(got.real) == pytest.approx(sorted(want), rel=1e-12)
    assert np.all(got.imag == 0.0)
    # a rotation exp(i w h): a pair +/- i w
    w = 0.3
    R = np.array([[np.cos(w * h), -np.sin(w * h)], [np.sin(w * h), np.cos(w * h)]])
    got = stability.rates_from_transition(R, h)
    assert sorted(got.imag) == pytest.approx([-w, w], rel=1e-12)
    assert np.max(np.abs(got.real)) < 1e-14


@pytest.mark.parametrize("dominant, verdict", [
    (1e-3, "neutral"), (-1e-3, "neutral"), (0.0, "neutral"),
    (1e-3 * (1 + 1e-12), "unstable"), (-1e-3 * (1 + 1e-12), "stable"),
    (0.0786, "unstable"), (-0.5, "stable"),
])
def test_classify_by_the_dominant_rate_and_its_tolerance(dominant, verdict):
    assert stability.TOL_PER_WINGBEAT == 1e-3
    assert stability.classify(np.array([dominant - 1.0, dominant, dominant - 0.1j])) == verdict


def test_checked_refuses_a_fit_that_is_not_the_loop():
    ident = stability.Identification(np.eye(4), np.zeros(4, complex), 0.0, "neutral", 1e-9)
    assert stability.checked(ident, "there") is ident  # at the bound: accepted
    for resid in (1.0000001e-9, math.nan):
        bad = dataclasses.replace(ident, fit_residual=resid)
        with pytest.raises(CrossCheckError, match=re.escape(
                "there: the identification's fit residual")) as err:
            stability.checked(bad, "there")
        assert "> 1e-09: the runs are not the linear 4-state loop identified, so its " \
            "verdict 'neutral' is not theirs" in str(err.value)


def test_cross_check_failures_one_sentence_per_failed_check():
    ok = dict(ident_rate=0.0, exact_rate=1e-6, resid=1e-9, err=1e-8, ident_verdict="neutral",
              exact_verdict="neutral", exact="eig(A + B K)")
    assert stability.cross_check_failures(**ok) == []  # every bound is inclusive
    bad = dict(ident_rate=0.0, exact_rate=2e-6, resid=2e-9, err=2e-8, ident_verdict="stable",
               exact_verdict="neutral", exact="eig(A + B K)")
    assert stability.cross_check_failures(**bad) == [
        "the identification's fit residual 2.0e-09 > 1e-09: the runs are not the linear loop "
        "identified",
        "the identified dominant rate +0 per wing beat deviates from +2e-06 of eig(A + B K) by "
        "2.0e-06 > 1e-06",
        "the identified verdict 'stable' is not 'neutral' of eig(A + B K)",
        "the co-simulated states deviate from the exact sampled-data solution by 2.0e-08 of "
        "their peak > 1e-08",
    ]
    nan = dict(ok, ident_rate=math.nan, resid=math.nan, err=math.nan)
    assert len(stability.cross_check_failures(**nan)) == 3


def test_relative_deviation_is_relative_to_each_states_peak():
    ref = np.array([[1.0, -100.0], [0.5, 50.0], [0.0, 0.0]])
    xs = ref + np.array([[0.01, 0.0], [0.0, 3.0], [0.0, 0.0]])
    assert stability.relative_deviation(xs, ref) == pytest.approx(0.03, rel=1e-14)
    assert stability.relative_deviation(ref + [[0.02, 0.0], [0, 0], [0, 0]], ref) == \
        pytest.approx(0.02, rel=1e-14)
    assert math.isnan(stability.relative_deviation(np.zeros((0, 2)), np.zeros((0, 2))))
    # a state that stays 0 in the reference: any deviation of it is huge, not a division by 0
    assert stability.relative_deviation(np.array([[0.0, 1e-290]]), np.array([[1.0, 0.0]])) > 1e9


def test_unit_start_values_are_the_unit_states_made_dimensional():
    scale = np.array([U_M_PER_S, N_HZ, N_HZ, 1.0])
    got = stability.unit_start_values(scale, prefix="plant.")
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


# --- controller/variables.py: the interface the paper's law needs, variable by variable ------

@pytest.mark.parametrize("delayed", [False, True])
def test_controller_variables_carry_the_laws_defaults_and_structure(delayed):
    K = ((0.5, -1.0, 2.0, 0.25), (0.0, 0.0, 0.0, 0.0), (1.5, 0.0, 0.0, -3.0))
    sources = ("row one", "row two", "row three")
    got = {v.name: v for v in variables.controller_variables(lateral.LATERAL, K, sources,
                                                             delayed)}
    states = lateral.STATE_NAMES
    for s in states:
        assert (got[s].causality, got[s].start) == ("input", 0.0)
    for i, c in enumerate(lateral.CONTROL_NAMES):
        v = got[c]
        assert v.causality == "output" and v.initial == "calculated"
        assert f": row {i + 1} of u = K x+_s + KI z" in v.description  # 1-based, as K[i,j]
        # no feedthrough in the delayed variant; at initialization the row's own gains only
        row = tuple(f"K[{i + 1},{j + 1}]" for j in range(4))
        assert v.dependencies == (() if delayed else states)
        assert v.initial_dependencies == (() if delayed else (
            *states, *row, "n", "U", "limit_enabled", "u_max", "sensing_delay"))
    every_gain = tuple(f"K[{i},{j}]" for i in (1, 2, 3) for j in (1, 2, 3, 4))
    assert variables.all_gains(lateral.LATERAL) == every_gain
    assert variables.all_integral_gains(lateral.LATERAL) == tuple("KI" + g[1:] for g in every_gain)
    assert got["saturated"].type == "Boolean"
    assert got["saturated"].initial_dependencies == (() if delayed else (
        *states, *every_gain, "n", "U", "limit_enabled", "u_max", "sensing_delay"))
    for i, row in enumerate(K):
        for j, k in enumerate(row):
            g = got[f"K[{i + 1},{j + 1}]"]
            assert g.start == k and sources[i] in g.description and f"x+{j + 1}" in g.description
            ki = got[f"KI[{i + 1},{j + 1}]"]
            assert ki.start == 0.0
            # the description names the component it weighs (1-based, as the FMI names)
            assert f"[rad] on z{j + 1}, the integral of x+{j + 1} ({states[j]}) over" in \
                ki.description
    # Sect. 2.4: n = 164 Hz, U = 2 Phi n r2; Sect. 3.1: linear range to 0.4 rad
    assert got["n"].start == N_HZ and got["U"].start == pytest.approx(U_M_PER_S, rel=1e-12)
    assert (got["limit_enabled"].start, got["u_max"].start) == (False, 0.4)
    # the delayed variant defaults to one wing beat of sensing delay; the other to none
    assert got["sensing_delay"].start == (1.0 / N_HZ if delayed else 0.0)
    assert got["sample_period"].start == 0.0
    assert variables.LAW_PARAMETERS == ("n", "U", "limit_enabled", "u_max")
    names = list(got)
    # the integral gains and the timing come after the proportional law's parameters
    assert names.index("u_max") < names.index("KI[1,1]") < names.index("sensing_delay")
    assert names[-2:] == ["sensing_delay", "sample_period"]


# --- the FMUs' modules import without numpy (they ship into hosts that have none) -------------

def test_the_fmu_runtime_modules_import_without_numpy():
    code = ("import sys; sys.modules['numpy'] = None\n"  # import numpy now raises ImportError
            "import dronefly.models.lateral_dynamics, dronefly.models.longitudinal_dynamics, "
            "dronefly.models.feedback, dronefly.models.linear, dronefly.models.linear_algebra, "
            "dronefly.controller.timing, dronefly.controller.delay, dronefly.controller.variables\n"
            "print('imported')")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=60)
    assert out.returncode == 0 and out.stdout == "imported\n", out.stderr
