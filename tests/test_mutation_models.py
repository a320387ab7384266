"""Independent oracles for the plant and law modules (models/), written against the mutants
that survived the other tests (docs/mutation.md): the paper's definitions and printed values,
closed forms, numpy."""

from __future__ import annotations

import dataclasses
import math
import re
import subprocess
import sys

import numpy as np
import pytest

from dronefly.core.errors import DroneflyError
from dronefly.models import feedback, lateral_interface, lateral_dynamics, longitudinal_dynamics
from dronefly.models.axes import Axis
from dronefly.models.linear import ModelParameterError

from controller_common import ROOT
from shared_files import need_shared

PAPER = ROOT.parent / "shared" / "paper" / "zhang-sun-lateral-stabilization-control.md"

# Sect. 2.4: U = 2 Phi n r2, with Phi = 107.1 deg, n = 164 Hz, r2 = 0.55 R, R = 11.2 mm
N_HZ = 164.0
U_M_PER_S = 2.0 * math.radians(107.1) * N_HZ * 0.55 * 11.2e-3



def test_lateral_axis_scales_are_the_papers_definitions():
    # Sect. 2.1: dv+ = dv / U, dp+ = dp t_w, dr+ = dr t_w with t_w = 1/n; dgamma is an angle.
    x = (0.3, 5.0, -7.0, 0.02)
    t_w = 1.0 / N_HZ
    expected = (x[0] / U_M_PER_S, x[1] * t_w, x[2] * t_w, x[3])
    got = lateral_interface.LATERAL.to_nondimensional(x, U_M_PER_S, N_HZ)
    # a division and a multiplication each: a few ulps apart at most
    assert got == pytest.approx(expected, rel=1e-14, abs=0.0)
    back = lateral_interface.LATERAL.to_dimensional(expected, U_M_PER_S, N_HZ)
    assert back == pytest.approx(x, rel=1e-14, abs=0.0)
    assert lateral_interface.LATERAL.scale_vector(U_M_PER_S, N_HZ) == (U_M_PER_S, N_HZ, N_HZ, 1.0)


def test_lateral_axis_names_each_nondimensional_component():
    assert lateral_interface.NONDIMENSIONAL == ("x+1 = delta_v/U", "x+2 = delta_p/n", "x+3 = delta_r/n",
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


def test_longitudinal_parameters_are_immutable():
    p = longitudinal_dynamics.default_parameters()
    with pytest.raises(dataclasses.FrozenInstanceError):
        p.m_plus = 1.0  # type: ignore[misc]


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


def test_longitudinal_design_b_mirrors_the_unstable_pair():
    """Design (b): delta_phibar = k x+ moves the unstable oscillatory pair of Sect. 3.5's A to
    its mirror image and keeps the two real modes (numpy's eigenvalues of the printed A)."""
    A = np.array(longitudinal_dynamics.A_SECT35)
    b = np.array(longitudinal_dynamics.B_SECT35)[:, 2]  # the delta_phibar column
    k = np.array(feedback.LONGITUDINAL_GAINS_DESIGN_B)
    open_loop = np.linalg.eigvals(A)
    want = np.where(open_loop.real > 0, -open_loop.conj(), open_loop)
    got = np.linalg.eigvals(A + np.outer(b, k))
    key = lambda z: (round(z.real, 9), z.imag)  # noqa: E731
    # eigenvalues of a 4x4 of norm 0.1 whose gains carry 17 digits: 1e-12 of margin to spare
    assert sorted(got, key=key) == pytest.approx(sorted(want, key=key), abs=1e-12)
    assert sorted(np.round(want.real, 4)) == [-0.1194, -0.0481, -0.0481, -0.0122]  # the paper's
    assert feedback.default_longitudinal_gains() == ((0.0,) * 4, (0.0,) * 4, tuple(k), (0.0,) * 4)


@pytest.mark.parametrize("integral, what", [(False, "K x+"), (True, "K x+ + KI z")])
def test_law_overflow_names_the_sum_that_overflowed(integral, what):
    K = ((1e300, 0.0, 0.0, 0.0), (0.0,) * 4, (0.0,) * 4)
    KI = ((1.0, 0.0, 0.0, 0.0), (0.0,) * 4, (0.0,) * 4) if integral else None
    law = feedback.FeedbackLaw(K, KI=KI)
    with pytest.raises(feedback.LawParameterError, match=re.escape(
            f"delta_Phi_a = inf is not finite ({what} overflows)")):
        law.evaluate([1e300, 0.0, 0.0, 0.0], [0.0] * 4)


@pytest.mark.parametrize("gains", list(_GAINS))
@pytest.mark.parametrize("pair", [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)])
def test_the_table_declines_exactly_where_the_proportional_law_does(gains, pair):
    # two finite states whose sum overflows: evaluate_proportional declines (None), so the
    # table must too (False, nothing written), whatever the pair
    law = feedback.FeedbackLaw(_GAINS[gains])
    x = [0.0] * 4
    for i in pair:
        x[i] = 1e308
    assert law.evaluate_proportional(x) is None
    r = x + [1.0, 2.0, 3.0, "untouched"]
    assert law.on_table((0, 1, 2, 3), range(4, 7), 7)(r) is False
    assert r[4:] == [1.0, 2.0, 3.0, "untouched"]


def test_law_on_an_axis_of_three_states():
    # u = K x+ on three states (x+ = (x1/U, x2, x3/n)); a row of zeros gives 0.0
    units = (("m/s", None), ("rad", "deg"), ("1/s", None))
    axis = Axis("three", ("a", "b", "c"), ("u", "w"), units, ("rad", "deg"), ("a", "b", "c"),
                ("u", "w"), ("U", "1", "n"))
    law = feedback.FeedbackLaw(((2.0, -3.0, 0.5), (0.0, 0.0, 0.0)), axis=axis, U=4.0, n=10.0)
    law.validate()
    want = 2.0 * 8.0 / 4.0 - 3.0 * 0.5 + 0.5 * 20.0 / 10.0
    assert law.evaluate([8.0, 0.5, 20.0]) == ((want, 0.0), False)
    assert law.evaluate_proportional([8.0, 0.5, 20.0]) == ([want, 0.0], False)


def test_proportional_law_exactly_at_the_limit_is_not_limited():
    K = ((1.0, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0, -1.0), (0.0, 0.0, 0.0, 0.0))
    law = feedback.FeedbackLaw(K, u_max=0.25, limit_enabled=True)
    # x+ = (0.25, 0, 0, -0.25): both controls exactly at +/-u_max
    assert law.evaluate_proportional([0.25 * U_M_PER_S, 0.0, 0.0, -0.25]) == (
        [pytest.approx(0.25, rel=1e-15), 0.25, 0.0], False)
    assert law.evaluate_proportional([0.0, 0.0, 0.0, 0.25]) == ([0.0, -0.25, 0.0], False)


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_every_path_exactly_at_the_limit_is_not_limited(sign):
    # one row of gains (the table's straight-line branch): u = x0 / U exactly at +/-u_max
    law = feedback.FeedbackLaw(((1.0, 0.0, 0.0, 0.0), (0.0,) * 4, (0.0,) * 4), U=4.0,
                               u_max=0.25, limit_enabled=True)
    x = [sign * 1.0, 0.0, 0.0, 0.0]  # x+ = 0.25 exactly (a power of two)
    assert law.evaluate(x) == ((sign * 0.25, 0.0, 0.0), False)
    assert law.evaluate_proportional(x) == ([sign * 0.25, 0.0, 0.0], False)
    r = x + [None, None, None, None]
    assert law.on_table((0, 1, 2, 3), range(4, 7), 7)(r) is True
    assert r[4:] == [sign * 0.25, 0.0, 0.0, False]
