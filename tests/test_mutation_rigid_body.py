"""Independent oracles for models/rigid_body.py on small inputs, written against the mutants
that survived tests/test_hover6dof.py (docs/mutation.md).

Oracles: scipy's ``Rotation`` for every attitude conversion; the Newton-Euler equations
written again here with numpy (as in tests/test_hover6dof.py) for the right-hand side with
each subset of the restored terms and with cycle-averaged aerodynamics given as functions of
the state; ``solve_ivp`` (DOP853, rtol 1e-12) for a step; the documented sub-step bounds
(the fewest sub-steps of at most ``MAX_SUBSTEP_*`` wing beats and ``MAX_TURN_*`` rad) for the
sub-step count; exact float facts (2 * sqrt(0.5)**2 rounds above 1) for the clamps.
"""

from __future__ import annotations

import math
import re
from dataclasses import replace

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.spatial.transform import Rotation

from dronefly.models import lateral_dynamics, longitudinal_dynamics, rigid_body
from dronefly.models.rigid_body import (Hover6DOF, Hover6DOFError, euler_from_quaternion,
                                        gamma_from_quaternion, initial_state, outputs,
                                        quaternion_from_euler)

LP, NP = lateral_dynamics.default_parameters(), longitudinal_dynamics.default_parameters()
#: changed inertias and gravity: every one enters where it belongs (Ixz 1.3 times the paper's)
LP2 = replace(LP, Ix_plus=1.3 * LP.Ix_plus, Iz_plus=0.9 * LP.Iz_plus, Ixz_plus=1.3 * LP.Ixz_plus,
              g_plus=0.03)
NP2 = replace(NP, Iy_plus=0.8 * NP.Iy_plus, g_plus=0.03)
#: 2 sqrt(0.5)^2 = 1.0000000000000002 in floats: a sine just above 1 (the clamps' case)
R_HALF = math.sqrt(0.5)


def _quat(phi, theta, psi):
    """(e0, e1, e2, e3) body -> earth of yaw psi, pitch theta, roll phi (scipy)."""
    x, y, z, w = Rotation.from_euler("ZYX", [psi, theta, phi]).as_quat()
    return np.array([w, x, y, z])


def _R(e):
    """Body -> earth rotation matrix of a quaternion (scipy)."""
    return Rotation.from_quat([e[1], e[2], e[3], e[0]]).as_matrix()


def _J(lp, np_):
    return np.array([[lp.Ix_plus, 0.0, -lp.Ixz_plus], [0.0, np_.Iy_plus, 0.0],
                     [-lp.Ixz_plus, 0.0, lp.Iz_plus]])


def _newton_euler(lp, np_, terms=rigid_body.TERMS, aero=None):
    """dx/dt+ (13 values): dV = a - [transport] w x V + g [gravity: R^T e_z - e_z, else
    (-theta, gamma, 0)], dw = J^-1 M - [gyroscopic] J^-1 (w x J w), de = e (x) (0, w) / 2,
    dP = R V. a, J^-1 M: the linear models' rows, or (F(x) - F(0)) / m and J^-1 (M(x) - M(0))
    of ``aero(c)(state)`` (forces X, Y, Z, moments L, M, N)."""
    a1, b1 = lateral_dynamics.system_matrices(lp)
    a2, b2 = longitudinal_dynamics.system_matrices(np_)
    J = _J(lp, np_)
    Jinv, g, ez = np.linalg.inv(J), lp.g_plus, np.array([0.0, 0.0, 1.0])

    def f(_t, x, cl, cn):
        x = np.asarray(x, float)
        V, w, e = x[0:3], x[3:6], x[6:10]
        R = _R(e / np.linalg.norm(e))
        if aero is None:
            al = a1[:3, :3] @ x[[1, 3, 5]] + b1[:3] @ cl
            an = a2[:3, :3] @ x[[0, 2, 4]] + b2[:3] @ cn
            dV, dw = np.array([an[0], al[0], an[1]]), np.array([al[1], an[2], al[2]])
        else:
            fc = aero.state_function(np.concatenate([cl, cn]))
            F = np.asarray(fc(x[:6]), float) - np.asarray(
                aero.state_function(np.zeros(7))(np.zeros(6)), float)
            dV, dw = F[:3] / lp.m_plus, Jinv @ F[3:]
        if "gravity" in terms:
            dV = dV + g * (R.T @ ez - ez)
        else:
            dV = dV + g * np.array([-math.asin(-R[2, 0]), math.asin(R[2, 1]), 0.0])
        if "transport" in terms:
            dV = dV - np.cross(w, V)
        if "gyroscopic" in terms:
            dw = dw - Jinv @ np.cross(w, J @ w)
        e0, e1, e2, e3 = e
        p, q, r = w
        de = 0.5 * np.array([-e1 * p - e2 * q - e3 * r, e0 * p + e2 * r - e3 * q,
                             e0 * q - e1 * r + e3 * p, e0 * r + e1 * q - e2 * p])
        return np.concatenate([dV, dw, de, R @ V])

    return f


class LinearAero:
    """Cycle-averaged forces linear in the state and the controls: F = F0 + D s + E c, as a
    numpy array (``tolist``) or, with ``as_tuple``, a tuple of floats."""

    def __init__(self, seed=3, as_tuple=False, scale=0.05):
        rng = np.random.default_rng(seed)
        self.F0 = rng.normal(size=6)
        self.D, self.E = rng.normal(scale=scale, size=(6, 6)), rng.normal(scale=scale, size=(6, 7))
        self.as_tuple = as_tuple
        self.calls = 0

    def state_function(self, controls):
        c = np.asarray(controls, float)

        def f(s):
            self.calls += 1
            F = self.F0 + self.D @ np.asarray(s, float) + self.E @ c
            return tuple(F.tolist()) if self.as_tuple else F

        return f


def _random_states(rng, k, scale=1.0):
    for _ in range(k):
        x = rng.normal(scale=scale, size=13)
        x[6:10] /= np.linalg.norm(x[6:10])
        yield x


# -- attitude conversions ------------------------------------------------------------------
def test_quaternion_and_euler_angles_against_scipy():
    """quaternion_from_euler, euler_from_quaternion and gamma_from_quaternion against scipy's
    ZYX Euler angles and rotation matrix (sin gamma = R[2, 1], the body y-axis' downward
    component), at random attitudes with |theta| < pi/2: a few roundings each, 1e-14."""
    rng = np.random.default_rng(7)
    for _ in range(20):
        phi, psi = rng.uniform(-math.pi, math.pi, 2)
        theta = rng.uniform(-1.5, 1.5)
        e = quaternion_from_euler(phi, theta, psi)
        np.testing.assert_allclose(e, _quat(phi, theta, psi), rtol=0, atol=1e-15)
        assert euler_from_quaternion(e) == pytest.approx((phi, theta, psi), abs=1e-14)
        assert gamma_from_quaternion(e) == pytest.approx(math.asin(_R(e)[2, 1]), abs=1e-14)


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_attitude_sines_just_beyond_one_are_clamped(sign):
    """At pitch +-90 deg (roll +-90 deg for gamma) written with sqrt(0.5), the sine computed
    from the quaternion is 2 * 0.5000000000000001 = 1.0000000000000002: the angle is +-pi/2
    (scipy: the same attitude), not a math domain error."""
    e = (R_HALF, 0.0, sign * R_HALF, 0.0)
    assert euler_from_quaternion(e)[1] == sign * math.pi / 2
    e = (R_HALF, sign * R_HALF, 0.0, 0.0)
    assert gamma_from_quaternion(e) == sign * math.pi / 2


# -- the right-hand side -------------------------------------------------------------------
TERM_SETS = [frozenset(), frozenset({"gravity"}), frozenset({"transport"}),
             frozenset({"gyroscopic"}), rigid_body.TERMS]


@pytest.mark.parametrize("terms", TERM_SETS, ids=lambda t: "+".join(sorted(t)) or "none")
def test_rhs_with_each_choice_of_terms(terms):
    """The right-hand side without some of the restored terms (gravity then linear, g+ (-theta,
    gamma, 0)) against the Newton-Euler equations written here, with changed inertias (Ixz
    doubled) and g+: O(1) values from a few dozen roundings, 1e-13 of the largest."""
    rng = np.random.default_rng(11)
    model, f = Hover6DOF(LP2, NP2, terms=terms), _newton_euler(LP2, NP2, terms)
    for x in _random_states(rng, 6):
        cl, cn = rng.normal(scale=0.1, size=3), rng.normal(scale=0.1, size=4)
        want = f(0.0, x, cl, cn)
        got = np.array(model.derivative(list(x), list(cl), list(cn)))
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-13 * np.abs(want).max())


@pytest.mark.parametrize("as_tuple", [False, True], ids=["array", "tuple"])
def test_rhs_with_cycle_averaged_aerodynamics(as_tuple):
    """With aerodynamics as functions of the state (linear here, with a non-zero force at
    hover F0), the right-hand side is Newton-Euler with (F(x) - F0) / m and J^-1 (M(x) - M0):
    against the equations written here (numpy's inverse of J), 1e-13 of the largest; the
    forces may come as an array or a tuple."""
    rng = np.random.default_rng(5)
    aero = LinearAero(as_tuple=as_tuple, scale=0.5)
    model, f = Hover6DOF(LP2, NP2, aerodynamics=aero), _newton_euler(LP2, NP2, aero=aero)
    for x in _random_states(rng, 6):
        cl, cn = rng.normal(scale=0.1, size=3), rng.normal(scale=0.1, size=4)
        want = f(0.0, x, cl, cn)
        got = np.array(model.derivative(list(x), list(cl), list(cn)))
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-13 * np.abs(want).max())
    # at hover, level, with no control: the trimmed force balances the weight (equilibrium)
    level = [0.0] * 6 + [1.0, 0.0, 0.0, 0.0] + [0.0] * 3
    assert model.derivative(level, [0.0] * 3, [0.0] * 4) == [0.0] * 13


def _dop853(f, x, cl, cn, h):
    sol = solve_ivp(f, (0.0, h), x, method="DOP853", rtol=1e-12, atol=1e-14, args=(cl, cn))
    assert sol.success
    return sol.y[:, -1]


@pytest.mark.parametrize("quasi_steady", [False, True], ids=["linear", "quasi-steady"])
def test_step_against_solve_ivp(quasi_steady):
    """One step of 2.3 wing beats from a state that turns at about 0.3 rad per wing beat, the
    controls held, against DOP853 (rtol 1e-12; at 1e-13 it moves by 1e-14) on the equations
    written here. The order-6 truncation error of the 12 sub-steps of 0.19 wing beat is
    1.4e-9 of the largest value here (5 sub-steps of 0.46 with the quasi-steady bound:
    2.5e-8), and sub-steps of 0.01 wing beat agree with DOP853 to 2e-14: the tolerance is
    that error with a margin of 7 (a sub-step k times longer multiplies it by k^6); the
    quaternion stays a unit one (normalised each step: a few ulps)."""
    aero = LinearAero(scale=0.05) if quasi_steady else None
    model, f = Hover6DOF(LP2, NP2, aerodynamics=aero), _newton_euler(LP2, NP2, aero=aero)
    x = np.array([0.3, -0.2, 0.1, 0.2, -0.15, 0.12, *_quat(0.4, -0.3, 1.0), 0.5, -0.5, 0.2])
    cl, cn = np.array([0.05, -0.02, 0.01]), np.array([0.02, -0.03, 0.04, 0.01])
    got = np.array(model.step(list(x), list(cl), list(cn), 2.3))
    want = _dop853(f, x, cl, cn, 2.3)
    assert np.abs(got - want).max() <= (2e-7 if quasi_steady else 1e-8) * np.abs(want).max()
    assert math.fsum(v * v for v in got[6:10]) == pytest.approx(1.0, abs=4e-16)


# -- the sub-steps --------------------------------------------------------------------------
def _spy(model):
    """Record (n, h) of each call of the model's sub-step function, which returns y itself."""
    seen = []

    def substeps(y, n, h, *args):
        seen.append((n, h))
        return list(y)

    object.__setattr__(model, "_substeps", substeps)
    return seen


def _at_rate(rate):
    """A level state turning at ``rate`` rad per wing beat about an axis (p, q, r) = (3, 4,
    12) / 13: |omega| = rate exactly for rate a multiple of 13."""
    return [0.0, 0.0, 0.0, 3 * rate / 13, 4 * rate / 13, 12 * rate / 13, 1.0, 0.0, 0.0, 0.0,
            0.0, 0.0, 0.0]


@pytest.mark.parametrize("quasi_steady, rate, h, n", [
    (False, 0.0, 1.0, 5),      # 0.2 wing beat: exactly 5 sub-steps
    (False, 0.0, 1.01, 6),
    (False, 0.0, 0.05, 1),
    (False, 0.0, 1e-12, 1),    # a step far below the 1e-9 slack still takes one sub-step
    (False, 1.3, 1.0, 26),     # 0.05 rad per sub-step: 0.05 / 1.3 wing beat
    (True, 0.0, 1.0, 2),       # 0.5 wing beat
    (True, 0.0, 1.01, 3),
    (True, 0.0, 0.1, 1),
    (True, 0.26, 1.0, 3),      # 0.1 rad: 0.1 / 0.26 = 0.385 wing beat
    (True, 0.13, 1.0, 2),      # 0.1 / 0.13 = 0.77 wing beat: the 0.5 bound rules
])
def test_substeps_are_the_fewest_within_the_documented_bounds(quasi_steady, rate, h, n):
    """The number of sub-steps of a step is the fewest whose length is at most
    MAX_SUBSTEP_WB (0.2; quasi-steady MAX_SUBSTEP_QS_WB, 0.5) wing beats and whose turn at
    the state's rate is at most MAX_TURN_PER_SUBSTEP_RAD (0.05; quasi-steady 0.1) rad:
    ceil of h over the bound, worked out by hand for each case (an exact multiple takes no
    extra sub-step)."""
    model = Hover6DOF(LP, NP, aerodynamics=LinearAero() if quasi_steady else None)
    seen = _spy(model)
    model.step(_at_rate(rate), [0.0] * 3, [0.0] * 4, h)
    assert seen == [(n, pytest.approx(h / n, rel=1e-15))]


def test_quasi_steady_step_evaluates_the_forces_once_per_stage():
    """Butcher's method has 7 stages: a step of 1 wing beat in 2 sub-steps of 0.5 evaluates
    the cycle-averaged forces 14 times (and once for the trim at construction)."""
    aero = LinearAero()
    model = Hover6DOF(LP, NP, aerodynamics=aero)
    assert aero.calls == 1
    model.step(_at_rate(0.0), [0.0] * 3, [0.0] * 4, 1.0)
    assert aero.calls == 1 + 14


def test_the_number_of_substeps_is_bounded_at_ten_million():
    """At 0.5 rad per wing beat a sub-step is 0.1 wing beat: a step of 1e6 wing beats takes
    10 000 000 sub-steps, the most allowed; 1e6 + 0.1 wing beats one more, refused."""
    model = Hover6DOF(LP, NP)
    seen = _spy(model)
    x = [0.0, 0.0, 0.0, 0.5, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
    model.step(x, [0.0] * 3, [0.0] * 4, 1e6)
    assert [n for n, _ in seen] == [10_000_000]
    with pytest.raises(Hover6DOFError, match="needs 10000001 sub-steps"):
        model.step(x, [0.0] * 3, [0.0] * 4, 1e6 + 0.1)


# -- refusals and limits ------------------------------------------------------------------
def _six_values_named(message, x):
    """The message names u, v, w, p, q, r of the start state: the six values, read back as
    floats (Python's repr reads back exactly, nan included)."""
    listed = re.search(r"u, v, w, p, q, r = \[([^]]*)\]", message)[1].split(",")
    np.testing.assert_array_equal([float(v) for v in listed], x[:6])


@pytest.mark.parametrize("h", [0.0, -1.0, math.nan, math.inf])
def test_step_refuses_a_step_that_is_not_finite_and_positive(h):
    with pytest.raises(Hover6DOFError, match="must be finite and > 0"):
        Hover6DOF(LP, NP).step(_at_rate(0.0), [0.0] * 3, [0.0] * 4, h)


def test_step_refuses_a_state_that_is_not_finite_or_has_no_attitude():
    """A nan velocity gives a nan state; a zero quaternion stays zero (no rates): both have
    no attitude to normalise, refused by name."""
    model = Hover6DOF(LP, NP)
    x = _at_rate(0.0)
    x[0] = math.nan
    with pytest.raises(Hover6DOFError, match="not finite") as info:
        model.step(x, [0.0] * 3, [0.0] * 4, 0.1)
    _six_values_named(str(info.value), x)
    x = _at_rate(0.0)
    x[6] = 0.0
    with pytest.raises(Hover6DOFError, match="not finite"):
        model.step(x, [0.0] * 3, [0.0] * 4, 0.1)


def test_a_far_position_is_a_finite_state():
    """Each position coordinate 1e308 (their sum beyond the float range), at rest at hover:
    nothing moves, the state comes back unchanged (the finiteness screen on the sum falls
    back to each value)."""
    x = _at_rate(0.0)
    x[10:13] = [1e308, 1e308, 1e308]
    assert Hover6DOF(LP, NP).step(x, [0.0] * 3, [0.0] * 4, 0.5) == x


@pytest.mark.parametrize("error", [OverflowError, ValueError, FloatingPointError])
def test_aerodynamics_that_fail_in_a_step_are_named(error):
    class Failing(LinearAero):
        def state_function(self, controls):
            f = super().state_function(controls)

            def g(s):
                if any(s):
                    raise error("boom")
                return f(s)
            return g

    model = Hover6DOF(LP, NP, aerodynamics=Failing())
    x = _at_rate(0.13)
    with pytest.raises(Hover6DOFError, match="aerodynamics failed.*: boom") as info:
        model.step(x, [0.0] * 3, [0.0] * 4, 0.5)
    _six_values_named(str(info.value), x)


@pytest.mark.parametrize("forces", [[0.0] * 5, [0.0] * 7, [0.0] * 5 + [math.nan],
                                    [math.inf] + [0.0] * 5])
def test_aerodynamics_with_a_bad_trim_are_refused(forces):
    class Bad:
        def state_function(self, controls):
            return lambda s: list(forces)

    with pytest.raises(Hover6DOFError, match="expected 6 finite"):
        Hover6DOF(LP, NP, aerodynamics=Bad())


@pytest.mark.parametrize("name", ["m_plus", "g_plus"])
def test_parameters_that_disagree_are_refused(name):
    with pytest.raises(Hover6DOFError, match=f"{name} = .* must agree"):
        Hover6DOF(LP, replace(NP, **{name: 1.5 * getattr(NP, name)}))


def test_the_model_is_frozen():
    """A model's parameters and compiled equations are fixed at construction (a frozen
    dataclass: assigning a field raises)."""
    import dataclasses
    model = Hover6DOF(LP, NP)
    with pytest.raises(dataclasses.FrozenInstanceError):
        model.terms = frozenset()


def test_unknown_terms_are_refused():
    with pytest.raises(Hover6DOFError, match="terms \\['drag'\\]"):
        Hover6DOF(LP, NP, terms=frozenset({"gravity", "drag"}))


@pytest.mark.parametrize("row", [1, 2])
def test_a_moment_that_depends_on_the_attitude_is_refused(row):
    """The moment rows (p, r) of A have a structural zero in the attitude column; a non-zero
    one is not aerodynamic (the force row v holds gravity there and is accepted)."""
    A = [[0.1, 0.2, 0.3, 0.4] for _ in range(4)]
    for i in (1, 2):
        A[i][3] = 0.5 if i == row else 0.0
    with pytest.raises(Hover6DOFError, match=f"A\\[{row + 1},4\\] = 0.5"):
        rigid_body._aero_rows(A, [[0.0] * 3] * 4, (0, 1, 2), 3)


# -- the FMU's start values and outputs ------------------------------------------------------
U, N = 2.3, 160.0
STARTS = dict(delta_u_start=0.1, delta_v_start=-0.2, delta_w_start=0.3, delta_p_start=5.0,
              delta_q_start=-6.0, delta_r_start=7.0, x_earth_start=0.01, y_earth_start=-0.02,
              z_earth_start=0.03, psi_start=0.7)


@pytest.mark.parametrize("gamma, theta", [(0.3, -0.5), (-0.2, 1.1), (0.0, 0.4),
                                          (math.pi / 2, 0.0), (-math.pi / 2, 0.0),
                                          (1.035611379977463, 0.5351849468174336),
                                          (-1.035611379977463, 0.5351849468174336)])
def test_initial_state_has_the_start_attitude_and_scales(gamma, theta):
    """The start state: V / U, omega / n, P n / U (Sect. 2.1's scales) and an attitude whose
    scipy Euler angles are (phi, theta, psi_start) with sin gamma = R[2, 1] = the start's
    gamma. The last case: sin gamma / cos theta = 1.0000000000000002 by rounding (roll 90
    deg), within the 1e-15 the check allows; the case after it mirrored (-1.0000000000000002);
    gamma = +-pi/2 at theta = 0: sin gamma = +-1 exactly, roll +-90 deg. The state has
    STATE_SIZE values."""
    starts = dict(STARTS, delta_gamma_start=gamma, delta_theta_start=theta)
    x = initial_state(starts, U, N)
    assert len(x) == rigid_body.STATE_SIZE == 13
    assert x[:6] == pytest.approx([0.1 / U, -0.2 / U, 0.3 / U, 5.0 / N, -6.0 / N, 7.0 / N],
                                  rel=1e-15)
    assert x[10:] == pytest.approx([0.01 * N / U, -0.02 * N / U, 0.03 * N / U], rel=1e-15)
    R = _R(x[6:10])
    # asin near 1 turns an ulp of its argument into sqrt(2 ulp) = 2e-8 rad
    assert math.asin(max(-1.0, min(1.0, R[2, 1]))) == pytest.approx(gamma, abs=1e-7)
    psi, th, phi = Rotation.from_matrix(R).as_euler("ZYX")
    assert (th, psi) == pytest.approx((theta, 0.7), abs=1e-14)
    assert math.sin(phi) * math.cos(theta) == pytest.approx(math.sin(gamma), abs=1e-15)


@pytest.mark.parametrize("gamma, theta", [(0.5, 1.4), (-0.5, 1.4), (0.1, -1.5)])
def test_initial_state_refuses_an_attitude_that_does_not_exist(gamma, theta):
    """|sin gamma| > cos theta: no roll gives that gamma at that pitch."""
    with pytest.raises(Hover6DOFError, match="no attitude has both"):
        initial_state(dict(STARTS, delta_gamma_start=gamma, delta_theta_start=theta), U, N)


def test_outputs_against_scipy():
    """The outputs (OUTPUT_NAMES' order) of a random state: the eight disturbances in SI,
    the Euler angles (scipy), the position times U / n and the earth velocity R V U (scipy's
    matrix): a few roundings, 1e-14 of each value's size."""
    rng = np.random.default_rng(2)
    x = next(_random_states(rng, 1))
    x[7] *= 0.3  # keep |theta| away from 90 deg, where yaw and roll are not unique
    x[6:10] /= np.linalg.norm(x[6:10])
    R = _R(x[6:10])
    psi, theta, phi = Rotation.from_matrix(R).as_euler("ZYX")
    u, v, w, p, q, r = x[:6]
    want = [v * U, p * N, r * N, math.asin(R[2, 1]), u * U, w * U, q * N, theta, phi, theta,
            psi, *(x[10:13] * U / N), *(R @ x[:3] * U)]
    np.testing.assert_allclose(outputs(list(x), U, N), want, rtol=1e-13, atol=1e-14)
