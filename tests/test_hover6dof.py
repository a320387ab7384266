"""DroneFlyHover6DOF, the nonlinear six-degree-of-freedom plant: is its physics right?

Oracles, none of them our own output:

- the Newton-Euler equations of fmu_src/hover6dof/README.md written again here, independently of
  models/rigid_body.py (numpy, scipy's ``Rotation`` for the attitude matrix, the inertia
  tensor inverted by numpy), integrated by ``scipy.integrate.solve_ivp`` (DOP853, rtol 1e-12);
- the linear models (A, B of Eq. 12 and Sect. 3.5, from the linear plants' modules) stepped
  with an exact zero-order hold (``scipy.linalg.expm``);
- closed-form solutions: free fall at a constant attitude, rotation at a constant rate.

Time is in wing beats and the state is non-dimensional (velocity / U, rate / n, length /
(U / n)) as in the model; through the FMU the values are SI.
"""

from __future__ import annotations

import math
from dataclasses import replace
from functools import lru_cache

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.linalg import expm
from scipy.spatial.transform import Rotation

from dronefly.models.feedback import LONGITUDINAL_GAINS_DESIGN_B, PAPER_GAINS_EQ27
from dronefly.models.lateral_interface import N_HZ, U_M_PER_S
from dronefly.models import lateral_dynamics
from dronefly.models.rigid_body import Hover6DOF, initial_state, outputs
from dronefly.models import longitudinal_dynamics

LP, NP = lateral_dynamics.default_parameters(), longitudinal_dynamics.default_parameters()
A1, B1 = lateral_dynamics.system_matrices(LP)
A2, B2 = longitudinal_dynamics.system_matrices(NP)
#: the eight linear states: lateral (Eq. 12) then longitudinal (Sect. 3.5)
EIGHT = ("delta_v", "delta_p", "delta_r", "delta_gamma", "delta_u", "delta_w", "delta_q",
         "delta_theta")

pytestmark = pytest.mark.numeric  # also run under a second BLAS kernel (.ci/run)
#: held controls of the accuracy tests, rad: lateral (3) and longitudinal (4)
C_LAT, C_LON = np.array([0.02, -0.01, 0.005]), np.array([0.01, -0.02, 0.03, 0.005])
_INERTIA_AND_GRAVITY = ("m_plus", "Ix_plus", "Iy_plus", "Iz_plus", "Ixz_plus", "g_plus")


# -- the independent equations -----------------------------------------------------------
def _quat(phi: float, theta: float, psi: float) -> np.ndarray:
    """(e0, e1, e2, e3), body to earth, of yaw psi, pitch theta, roll phi (scipy)."""
    x, y, z, w = Rotation.from_euler("ZYX", [psi, theta, phi]).as_quat()
    return np.array([w, x, y, z])


def _R(e) -> np.ndarray:
    """Body-to-earth rotation matrix of a quaternion (scipy)."""
    return Rotation.from_quat([e[1], e[2], e[3], e[0]]).as_matrix()


def newton_euler(lp=LP, np_=NP):
    """f(t, x, c_lat, c_lon): dV = a - w x V + g (R^T e_z - e_z), dw = J^-1 (M - w x J w),
    de = e (x) (0, w) / 2, dP = R V; a, J^-1 M from the linear models' A, B (not their
    gravity column)."""
    a1, b1 = lateral_dynamics.system_matrices(lp)
    a2, b2 = longitudinal_dynamics.system_matrices(np_)
    J = np.array([[lp.Ix_plus, 0.0, -lp.Ixz_plus], [0.0, np_.Iy_plus, 0.0],
                  [-lp.Ixz_plus, 0.0, lp.Iz_plus]])
    Jinv, g, ez = np.linalg.inv(J), lp.g_plus, np.array([0.0, 0.0, 1.0])

    def f(_t, x, cl, cn):
        V, w, e = x[0:3], x[3:6], x[6:10]
        R = _R(e)
        al = a1[:3, :3] @ x[[1, 3, 5]] + b1[:3] @ cl  # (v, p, r) rows
        an = a2[:3, :3] @ x[[0, 2, 4]] + b2[:3] @ cn  # (u, w, q) rows
        dV = np.array([an[0], al[0], an[1]]) - np.cross(w, V) + g * (R.T @ ez - ez)
        dw = np.array([al[1], an[2], al[2]]) - Jinv @ np.cross(w, J @ w)
        e0, e1, e2, e3 = e
        p, q, r = w
        de = 0.5 * np.array([-e1 * p - e2 * q - e3 * r, e0 * p + e2 * r - e3 * q,
                             e0 * q - e1 * r + e3 * p, e0 * r + e1 * q - e2 * p])
        return np.concatenate([dV, dw, de, R @ V])

    return f


def _eight(x) -> np.ndarray:
    """The linear models' state (v, p, r, gamma, u, w, q, theta) of a 13-value state."""
    R = _R(x[6:10])
    return np.array([x[1], x[3], x[5], math.asin(R[2, 1]), x[0], x[2], x[4],
                     -math.asin(R[2, 0])])


def _start(z) -> list[float]:
    """13-value state of a linear state z (attitude gamma, theta: roll phi with sin phi =
    sin gamma / cos theta, no heading), at the origin."""
    v, p, r, gamma, u, w, q, theta = z
    phi = math.asin(math.sin(gamma) / math.cos(theta))
    return [u, v, w, p, q, r, *_quat(phi, theta, 0.0), 0.0, 0.0, 0.0]


def _zero_aero():
    """Parameters with every aerodynamic derivative zero (inertias and g+ kept)."""
    return (replace(LP, **{k: 0.0 for k in lateral_dynamics.LateralParameters.names()
                           if k not in _INERTIA_AND_GRAVITY}),
            replace(NP, **{k: 0.0 for k in longitudinal_dynamics.LongitudinalParameters.names()
                           if k not in _INERTIA_AND_GRAVITY}))


# -- 1. the equations and the integration ------------------------------------------------
def test_rhs_equals_an_independent_newton_euler():
    """The model's right-hand side against the equations written here, at random states
    (any attitude, rates of the order of 1 rad per wing beat) and controls, for the paper's parameters
    and for changed ones (every inertia, g+ and derivative used where it belongs)."""
    rng = np.random.default_rng(13)
    changed = (replace(LP, Ixz_plus=0.7 * LP.Ixz_plus, Ix_plus=1.3 * LP.Ix_plus, g_plus=0.02,
                       Yr_plus=0.4, Nv_plus=-0.3),
               replace(NP, Iy_plus=0.8 * NP.Iy_plus, g_plus=0.02, Xq_plus=0.2, Mw_plus=0.5))
    for lp, np_ in ((LP, NP), changed):
        model, f = Hover6DOF(lp, np_), newton_euler(lp, np_)
        for _ in range(20):
            x = rng.normal(size=13)
            x[6:10] /= np.linalg.norm(x[6:10])
            cl, cn = rng.normal(scale=0.1, size=3), rng.normal(scale=0.1, size=4)
            want = f(0.0, x, cl, cn)
            got = np.array(model.derivative(list(x), list(cl), list(cn)))
            np.testing.assert_allclose(got, want, rtol=0, atol=1e-13 * np.abs(want).max())


def test_jacobian_at_hover_is_the_two_linear_models():
    """Linearised about hover (complex-step derivatives: exact to rounding) the model is the
    lateral model of Eq. (12) and the longitudinal one of Sect. 3.5, with no coupling between
    them; gamma = 2 e1 and theta = 2 e2 to first order."""
    model = Hover6DOF(LP, NP)
    hover = [0.0] * 6 + [1.0, 0.0, 0.0, 0.0] + [0.0] * 3
    # the 8 linear states as directions in the 13-value state (gamma = 2 e1, theta = 2 e2),
    # and the rows that read their derivatives from the 13 derivatives
    index = {"delta_v": 1, "delta_p": 3, "delta_r": 5, "delta_gamma": 7, "delta_u": 0,
             "delta_w": 2, "delta_q": 4, "delta_theta": 8}
    scale = {"delta_gamma": 0.5, "delta_theta": 0.5}
    cols = [scale.get(n, 1.0) * np.eye(13)[index[n]] for n in EIGHT]
    rows = np.array([np.eye(13)[index[n]] / scale.get(n, 1.0) for n in EIGHT])
    h = 1e-30
    J = np.empty((8, 8))
    for j, d in enumerate(cols):
        dx = np.imag(model.derivative(list(np.array(hover) + 1j * h * d), [0.0] * 3,
                                      [0.0] * 4)) / h
        J[:, j] = rows @ dx
    want = np.zeros((8, 8))
    want[:4, :4], want[4:, 4:] = A1, A2
    np.testing.assert_allclose(J, want, rtol=0, atol=1e-15)
    Bl, Bn = np.empty((8, 3)), np.empty((8, 4))
    for B, n, lateral in ((Bl, 3, True), (Bn, 4, False)):
        for j in range(n):
            c = np.zeros(n, complex)
            c[j] = 1j * h
            dx = np.imag(model.derivative(hover, list(c) if lateral else [0.0] * 3,
                                          [0.0] * 4 if lateral else list(c))) / h
            B[:, j] = rows @ dx
    np.testing.assert_allclose(Bl, np.vstack([B1, np.zeros((4, 3))]), rtol=0, atol=1e-15)
    np.testing.assert_allclose(Bn, np.vstack([np.zeros((4, 4)), B2]), rtol=0, atol=1e-15)


ACCURACY_STATES = {
    # the Sect. 3.6 box's corner in the lateral states, a longitudinal disturbance: slow
    # rotation, the sub-steps at their largest (the fast roll mode, -0.51 per wing beat, sets
    # the error)
    "box corner": [0.05, 0.15, -0.05, 0.15, 0.05, 0.15, *_quat(0.22, 0.1, 0.0), 0.0, 0.0, 0.0],
    # twice the Sect. 3.6 box in the lateral rates, a tilted and turned attitude, moving
    "twice the box": [0.03, 0.3, -0.02, 0.3, 0.1, -0.3, *_quat(0.3, -0.2, 0.5), 0.1, -0.2,
                      0.05],
    # 1 rad per wing beat: the sub-steps shrink to keep the turn per sub-step small
    "fast turn": [0.0, 0.1, 0.0, 1.0, 0.3, -0.5, *_quat(1.3, 1.2, 0.5), 0.0, 0.0, 0.0],
}
HORIZON_WB = 15.0


@lru_cache(maxsize=None)
def _dop853(state: str):
    sol = solve_ivp(newton_euler(), (0.0, HORIZON_WB), ACCURACY_STATES[state], method="DOP853",
                    rtol=1e-12, atol=1e-14, args=(C_LAT, C_LON), dense_output=True)
    assert sol.success
    return sol.sol


@pytest.mark.parametrize("state", list(ACCURACY_STATES))
@pytest.mark.parametrize("step_wb", [0.01, 0.1, 1.0, 3.0])
def test_step_against_solve_ivp(state, step_wb):
    """``Hover6DOF.step`` with the controls held, against DOP853 (rtol 1e-12) on the equations
    written here: every one of the 13 values within 1e-9 of its peak over 15 wing beats, at
    each communication step (the sub-steps, at most 0.2 wing beat, set the accuracy: about
    1e-11 at 0.01 and 0.1, at most 2.4e-10 at 1 and 3)."""
    model = Hover6DOF(LP, NP)
    n = round(HORIZON_WB / step_wb)
    x = ACCURACY_STATES[state]
    got = [x]
    for _ in range(n):
        x = model.step(x, list(C_LAT), list(C_LON), step_wb)
        got.append(x)
    want = _dop853(state)(np.arange(n + 1) * step_wb).T
    peak = np.abs(want).max(axis=0)
    err = (np.abs(np.array(got) - want) / peak).max()
    assert err <= 1e-9, f"{err:.2e} relative at steps of {step_wb} wing beats"
    assert np.ptp(want[:, 6:10], axis=0).max() > 0.5, "the attitude really moved"


# -- 2. the linear theory as the small-disturbance limit --------------------------------
def _zoh(A, B, h):
    n, m = B.shape
    M = np.zeros((n + m, n + m))
    M[:n, :n], M[:n, n:] = A, B
    E = expm(M * h)
    return E[:n, :n], E[:n, n:]


def _gains(closed: bool):
    Kl, Kn = np.zeros((3, 4)), np.zeros((4, 4))
    if closed:
        Kl[0], Kn[2] = PAPER_GAINS_EQ27, LONGITUDINAL_GAINS_DESIGN_B
    return Kl, Kn


def _nonlinear_and_linear(z0, closed: bool, stop_wb: float = 30.0, step_wb: float = 1.0):
    """Both loops from the same initial state, the controls u = K x held over each step
    (computed from each loop's own state): (nonlinear, linear) linear states per step."""
    model = Hover6DOF(LP, NP)
    Kl, Kn = _gains(closed)
    (P1, G1), (P2, G2) = _zoh(A1, B1, step_wb), _zoh(A2, B2, step_wb)
    x, z = _start(z0), np.array(z0, float)
    nl, li = [_eight(x)], [z]
    for _ in range(round(stop_wb / step_wb)):
        y = _eight(x)
        x = model.step(x, list(Kl @ y[:4]), list(Kn @ y[4:]), step_wb)
        z = np.concatenate([(P1 + G1 @ Kl) @ z[:4], (P2 + G2 @ Kn) @ z[4:]])
        nl.append(_eight(x))
        li.append(z)
    return np.array(nl), np.array(li)


def _direction(name: str) -> np.ndarray:
    """A unit initial state: one of the eight states, or an unstable open-loop mode."""
    if name in EIGHT:
        return np.eye(8)[EIGHT.index(name)]
    A, axis = (A1, 0) if name.startswith("lateral") else (A2, 4)
    w, V = np.linalg.eig(A)
    v = V[:, int(np.argmax(w.real))]
    v = v / v[int(np.argmax(np.abs(v)))]  # phase: the largest component real
    part = v.imag if name.endswith("(imaginary part)") else v.real
    out = np.zeros(8)
    out[axis:axis + 4] = part / np.linalg.norm(part)
    return out


DIRECTIONS = [*EIGHT, "lateral unstable mode", "longitudinal unstable mode (real part)",
              "longitudinal unstable mode (imaginary part)"]
EPS = (1e-3, 5e-4)


@pytest.mark.parametrize("closed", [False, True], ids=["open loop", "closed loop"])
@pytest.mark.parametrize("direction", DIRECTIONS)
def test_difference_to_the_linear_model_is_second_order(direction, closed):
    """From eps x0, over 30 wing beats (steps of 1 wing beat; closed loop: Eq. 27 on the
    lateral axis, longitudinal design b), the peak of |nonlinear - linear| over the run and
    the eight states is divided by 4 +/- 10 % when eps halves (1e-3 -> 5e-4).

    By axis: the longitudinal part of the difference is of second order (w q, u q, the lift
    lost g (1 - cos)). The lateral part is of third order for a lateral disturbance (factor
    8): the mirror symmetry y -> -y maps a lateral disturbance to its negative and the
    longitudinal motion to itself, so the lateral error is odd in eps; and it is zero for a
    longitudinal disturbance (symmetry, below)."""
    x0 = _direction(direction)
    lateral = bool(np.any(x0[:4]))
    peaks = []
    for eps in EPS:
        nl, li = _nonlinear_and_linear(eps * x0, closed)
        d = np.abs(nl - li).max(axis=0)
        peaks.append((d.max(), d[:4].max(), d[4:].max()))
    (all1, lat1, lon1), (all2, lat2, lon2) = peaks
    assert all1 / all2 == pytest.approx(4.0, rel=0.1)
    assert lon1 / lon2 == pytest.approx(4.0, rel=0.1)
    if lateral:
        assert lat1 / lat2 == pytest.approx(8.0, rel=0.1)
        assert lat1 < 0.1 * lon1  # the second-order part dominates the whole difference
    else:
        assert lat1 == lat2 == 0.0


# -- 3. symmetry -------------------------------------------------------------------------
@pytest.mark.parametrize("closed", [False, True], ids=["open loop", "closed loop"])
def test_longitudinal_disturbance_moves_nothing_laterally(closed):
    """A large longitudinal disturbance (at the lateral box's size, all four states; open loop
    it pitches past 90 degrees): no lateral motion at all, to 1e-12: sideslip, roll and yaw
    rates, gamma, the quaternion's e1 and e3 (any rotation out of the plane of symmetry),
    sideways position."""
    model = Hover6DOF(LP, NP)
    Kl, Kn = _gains(closed)
    x = _start([0.0, 0.0, 0.0, 0.0, 0.15, -0.15, 0.15, 0.22])
    for _ in range(30):
        y = _eight(x)
        x = model.step(x, list(Kl @ y[:4]), list(Kn @ y[4:]), 1.0)
        lateral = [x[1], x[3], x[5], _eight(x)[3], x[7], x[9], x[11]]
        assert np.abs(lateral).max() <= 1e-12, lateral
    assert np.abs(_eight(x)[4:]).max() > 0.1, "the longitudinal motion is large"


@pytest.mark.parametrize("direction", ["delta_p", "delta_gamma", "lateral unstable mode"])
def test_lateral_disturbance_moves_longitudinally_at_second_order(direction):
    """A lateral disturbance eps x0 (open loop, 30 wing beats): the longitudinal motion of the
    nonlinear model (u, w, q, theta and the forward and downward positions) is divided by 4
    +/- 10 % when eps halves; the linear models have none."""
    peaks = []
    for eps in EPS:
        model, x = Hover6DOF(LP, NP), _start(eps * _direction(direction))
        peak = np.zeros(6)
        for _ in range(30):
            x = model.step(x, [0.0] * 3, [0.0] * 4, 1.0)
            peak = np.maximum(peak, np.abs([*_eight(x)[4:], x[10], x[12]]))
        peaks.append(peak)
    assert np.all(peaks[1] > 0)
    np.testing.assert_allclose(peaks[0] / peaks[1], 4.0, rtol=0.1)


# -- 4. an analytic case -----------------------------------------------------------------
def _free_fall(e0, t):
    """Earth-axis (position, velocity) at t of a body at rest at the origin, held at the
    attitude e0 with no aerodynamic force but the equilibrium lift -m g along body z:
    acceleration g (e_z - R e_z), R e_z written out from the Euler angles."""
    phi, theta, psi = e0
    z_body = np.array([math.cos(phi) * math.sin(theta) * math.cos(psi)
                       + math.sin(phi) * math.sin(psi),
                       math.cos(phi) * math.sin(theta) * math.sin(psi)
                       - math.sin(phi) * math.cos(psi),
                       math.cos(phi) * math.cos(theta)])
    a = LP.g_plus * (np.array([0.0, 0.0, 1.0]) - z_body)
    return a * t * t / 2, a * t


@pytest.mark.parametrize("attitude", [(0.1, 0.0, 0.0), (0.22, 0.0, 0.0), (1.0, 0.0, 0.0),
                                      (2.5, 0.0, 0.0), (0.4, -0.3, 1.2)],
                         ids=["roll 0.1", "roll 0.22 (box edge)", "roll 1.0", "roll 2.5",
                              "roll, pitch and heading"])
def test_constant_attitude_without_aerodynamics(attitude):
    """All aerodynamic derivatives zero, controls zero, a constant roll phi0 (and once a
    general attitude): in earth axes y = g+ sin(phi0) t^2 / 2 and z = g+ (1 - cos(phi0))
    t^2 / 2 (g+ = g t_w / U, time in wing beats), no rotation; to 1e-9 over 30 wing beats."""
    model = Hover6DOF(*_zero_aero())
    x = [0.0] * 6 + list(_quat(*attitude)) + [0.0] * 3
    e0 = list(x[6:10])
    for k in range(1, 31):
        x = model.step(x, [0.0] * 3, [0.0] * 4, 1.0)
        P, v = _free_fall(attitude, float(k))
        scale = np.abs(_free_fall(attitude, 30.0)[0]).max()
        np.testing.assert_allclose(x[10:13], P, rtol=0, atol=1e-9 * scale)
        np.testing.assert_allclose(_R(e0) @ np.array(x[0:3]), v, rtol=0,
                                   atol=1e-9 * np.abs(_free_fall(attitude, 30.0)[1]).max())
        assert x[3:6] == [0.0, 0.0, 0.0] and x[6:10] == pytest.approx(e0, abs=1e-15)
    if attitude[1:] == (0.0, 0.0):
        g, phi = LP.g_plus, attitude[0]
        assert x[11] == pytest.approx(g * math.sin(phi) * 450.0, rel=1e-9)
        assert x[12] == pytest.approx(g * (1 - math.cos(phi)) * 450.0, rel=1e-9)


# -- 5. large attitudes ------------------------------------------------------------------
@pytest.mark.parametrize("axis", ["pitch", "roll"])
def test_loop_through_every_attitude(axis):
    """A constant rate of 0.3 (pitch) or 0.5 (roll) rad per wing beat, no aerodynamics: a
    loop through 90 degrees and on past 360 (30 wing beats, steps of 1). The quaternion is
    the exact rotation (cos(w t / 2), sin(w t / 2) about the axis) to 1e-9, of norm 1 to
    1e-12; velocity and position are the closed-form free fall of a rotating lift, e.g. for
    the pitch loop vx = -g (1 - cos w t) / w, z = g t^2 / 2 - g (1 - cos w t) / w^2.
    Roll about x is a steady rotation only without the product of inertia (Ixz+ = 0 here);
    a pitch rotation is steady with it."""
    lp, np_ = _zero_aero()
    if axis == "roll":
        lp = replace(lp, Ixz_plus=0.0)
    model = Hover6DOF(lp, np_)
    w, i = (0.3, 4) if axis == "pitch" else (0.5, 3)
    x = [0.0] * 13
    x[6], x[i] = 1.0, w
    g = LP.g_plus
    for k in range(1, 31):
        x = model.step(x, [0.0] * 3, [0.0] * 4, 1.0)
        t = float(k)
        e = np.zeros(4)
        e[0], e[2 if axis == "pitch" else 1] = math.cos(w * t / 2), math.sin(w * t / 2)
        c, s = 1 - math.cos(w * t), w * t - math.sin(w * t)
        # earth velocity and position: pitch moves along -x, roll along +y
        sign, j = (-1.0, 0) if axis == "pitch" else (1.0, 1)
        v_e, p_e = np.zeros(3), np.zeros(3)
        v_e[j], v_e[2] = sign * g * c / w, g * s / w
        p_e[j], p_e[2] = sign * g * s / w ** 2, g * t * t / 2 - g * c / w ** 2
        assert all(math.isfinite(a) for a in x)
        assert abs(math.sqrt(sum(a * a for a in x[6:10])) - 1.0) <= 1e-12
        np.testing.assert_allclose(x[6:10], e, rtol=0, atol=1e-9)
        np.testing.assert_allclose(_R(x[6:10]) @ np.array(x[0:3]), v_e, rtol=0,
                                   atol=1e-9 * g * 30)
        np.testing.assert_allclose(x[10:13], p_e, rtol=0, atol=1e-9 * g * 450)
        assert all(math.isfinite(a) for a in outputs(x, U_M_PER_S, N_HZ))
    assert w * 30 > 2 * math.pi, "past a full loop"


def test_paper_model_at_90_degrees_pitch_spinning():
    """The paper's model (derivatives, Ixz) started at exactly 90 degrees of pitch (gimbal
    lock of the Euler angles) with a roll rate of 0.5 rad per wing beat and large controls:
    no exception, nothing non-finite, the quaternion of norm 1 to 1e-12, over 30 wing beats
    in steps of 0.1. The norm alone says little (the model normalises the quaternion after
    every step); the attitude itself, and the other 12 values, are checked against DOP853 on
    the equations written here: within 1e-9 of each value's peak, through the gimbal lock."""
    starts = {f"{s}_start": 0.0 for s in EIGHT}
    starts.update(psi_start=0.4, x_earth_start=0.0, y_earth_start=0.0, z_earth_start=0.0,
                  delta_theta_start=math.pi / 2, delta_p_start=0.5 * N_HZ)
    x = initial_state(starts, U_M_PER_S, N_HZ)
    out = outputs(x, U_M_PER_S, N_HZ)
    assert out[EIGHT.index("delta_theta")] == pytest.approx(math.pi / 2, abs=1e-15)
    model = Hover6DOF(LP, NP)
    c_lat, c_lon = [0.2, -0.1, 0.1], [0.1, 0.0, -0.2, 0.1]
    ref = solve_ivp(newton_euler(), (0.0, 30.0), x, method="DOP853", rtol=1e-12, atol=1e-14,
                    args=(np.array(c_lat), np.array(c_lon)), t_eval=np.linspace(0.0, 30.0, 301))
    got = [x]
    for _ in range(300):
        x = model.step(x, c_lat, c_lon, 0.1)
        assert abs(math.sqrt(sum(a * a for a in x[6:10])) - 1.0) <= 1e-12
        assert all(math.isfinite(a) for a in [*x, *outputs(x, U_M_PER_S, N_HZ)])
        got.append(x)
    want = ref.y.T
    err = np.abs(np.array(got) - want) / np.abs(want).max(axis=0)
    assert err.max() <= 1e-9, f"{err.max():.2e} relative ({err.max(axis=0).round(12)})"
    assert np.ptp(want[:, 6:10], axis=0).max() > 0.5, "the attitude really moved"


# -- 6. through FMI (fmpy) ---------------------------------------------------------------
H_WB = 1.0 / N_HZ  # one wing beat, s
G_SI = LP.g_plus * U_M_PER_S * N_HZ  # g+ = g t_w / U


@pytest.fixture(scope="module")
def hover6dof(built_fmus):
    from dronefly.harness.cosim.fmu import FMU

    with FMU(built_fmus["DroneFlyHover6DOF"]) as fmu:
        yield fmu


def _get(inst, names) -> np.ndarray:
    return np.array(inst.slave.getReal(inst.vrs(list(names))))


def _unit(u) -> tuple:
    base = u.baseUnit
    return (None if base is None else tuple(getattr(base, k) for k in (
        "kg", "m", "s", "A", "K", "mol", "cd", "rad", "factor", "offset")),
            tuple((d.name, d.factor, d.offset) for d in u.displayUnits))


@pytest.mark.integration
def test_drop_in_for_the_linear_plants(built_fmus):
    """Every input, output and parameter of DroneFlyLateral and DroneFlyLongitudinal exists in
    DroneFlyHover6DOF with the same causality, variability, unit (and its definition),
    display unit, initial and start value; no output depends directly on an input."""
    from fmpy import read_model_description

    six = read_model_description(str(built_fmus["DroneFlyHover6DOF"]))
    mine = {v.name: v for v in six.modelVariables}
    my_units = {u.name: u for u in six.unitDefinitions}
    shared = set()
    for plant in ("DroneFlyLateral", "DroneFlyLongitudinal"):
        md = read_model_description(str(built_fmus[plant]))
        units = {u.name: u for u in md.unitDefinitions}
        for v in md.modelVariables:
            if v.causality == "calculatedParameter":  # A[i,j], B[i,j]: linear models only
                continue
            w = mine.get(v.name)
            assert w is not None, f"{plant}.{v.name} missing"
            assert (w.causality, w.variability, w.type, w.unit, w.displayUnit, w.initial) == \
                (v.causality, v.variability, v.type, v.unit, v.displayUnit, v.initial), v.name
            assert _unit(my_units[w.unit]) == _unit(units[v.unit]), v.unit
            if v.causality != "output":
                assert float(w.start) == float(v.start), v.name
            shared.add(v.name)
    assert set(EIGHT) <= shared and len(shared) >= 8 + 7 + 40
    assert all(u.dependencies == [] for u in six.outputs), "no direct feedthrough"


def _oracle_outputs(x) -> dict[str, float]:
    """The FMU's outputs (SI) of a 13-value state, computed here (scipy's Euler angles)."""
    R = _R(x[6:10])
    psi, theta, phi = Rotation.from_quat([*x[7:10], x[6]]).as_euler("ZYX")
    z = _eight(x)
    si = (U_M_PER_S, N_HZ, N_HZ, 1.0, U_M_PER_S, U_M_PER_S, N_HZ, 1.0)
    out = dict(zip(EIGHT, z * np.array(si)))
    out.update(phi=phi, theta=theta, psi=psi)
    out.update(zip(("x_earth", "y_earth", "z_earth"), np.array(x[10:13]) * U_M_PER_S / N_HZ))
    out.update(zip(("vx_earth", "vy_earth", "vz_earth"), R @ np.array(x[0:3]) * U_M_PER_S))
    return out


@pytest.mark.integration
@pytest.mark.parametrize("step_wb", [0.01, 1.0, 3.0])
def test_fmu_outputs_against_solve_ivp(hover6dof, step_wb):
    """Through fmpy, SI starts (a tilted, turned, moving body), the controls held, 15 wing
    beats in communication steps of 0.01, 1 and 3 wing beats: every output against DOP853 on
    the equations written here, the outputs (Euler angles, earth-axis position and velocity)
    computed here too; within 1e-9 of each output's peak at every communication point."""
    from fmu_helpers import start

    gamma, theta, psi = 0.3, -0.2, 0.5
    starts = {"delta_v_start": 0.1, "delta_p_start": 20.0, "delta_r_start": -15.0,
              "delta_gamma_start": gamma, "delta_u_start": -0.05, "delta_w_start": 0.08,
              "delta_q_start": 10.0, "delta_theta_start": theta, "psi_start": psi,
              "x_earth_start": 0.01, "y_earth_start": -0.02, "z_earth_start": 0.003}
    controls = dict(zip(("delta_Phi_a", "delta_alpha_1a", "delta_alpha_2a", "delta_Phi",
                         "delta_alpha_1", "delta_phibar", "delta_alpha_2"), (*C_LAT, *C_LON)))
    names = list(_oracle_outputs(_start(np.zeros(8))))
    phi = math.asin(math.sin(gamma) / math.cos(theta))
    s, k = starts, N_HZ / U_M_PER_S
    x0 = [s["delta_u_start"] / U_M_PER_S, s["delta_v_start"] / U_M_PER_S,
          s["delta_w_start"] / U_M_PER_S, s["delta_p_start"] / N_HZ, s["delta_q_start"] / N_HZ,
          s["delta_r_start"] / N_HZ, *_quat(phi, theta, psi), s["x_earth_start"] * k,
          s["y_earth_start"] * k, s["z_earth_start"] * k]
    steps = round(15.0 / step_wb)
    ref = solve_ivp(newton_euler(), (0.0, 15.0), x0, method="DOP853", rtol=1e-12, atol=1e-14,
                    args=(C_LAT, C_LON), t_eval=np.linspace(0.0, 15.0, steps + 1))
    want = np.array([[_oracle_outputs(x)[n] for n in names] for x in ref.y.T])
    h = step_wb * H_WB
    with hover6dof.instantiate() as inst:
        start(inst, {**starts, **controls})
        got = [_get(inst, names)]
        for i in range(steps):
            inst.slave.doStep(currentCommunicationPoint=i * h, communicationStepSize=h)
            got.append(_get(inst, names))
        assert not [m for m in inst.messages if m.status > 0]
    peak = np.abs(want).max(axis=0)
    err = np.abs(np.array(got) - want) / peak
    assert err.max() <= 1e-9, dict(zip(names, err.max(axis=0)))
    assert np.abs(want[:, :3]).max() > 0.1  # it moved


@pytest.mark.integration
def test_fmu_constant_roll_without_aerodynamics(hover6dof):
    """Through fmpy in SI: every aerodynamic derivative set to zero as a parameter, controls
    zero, delta_gamma_start = phi0 = 0.5 rad: y_earth = g sin(phi0) t^2 / 2, z_earth =
    g (1 - cos(phi0)) t^2 / 2, vy_earth, vz_earth their derivatives, with g = g+ U n; the
    attitude and rates do not change; to 1e-9 over 30 wing beats."""
    from fmu_helpers import start

    zero = {k: 0.0 for k in (*lateral_dynamics.LateralParameters.names(), *longitudinal_dynamics.LongitudinalParameters.names())
            if k not in _INERTIA_AND_GRAVITY}
    assert len(zero) == 18 + 21
    phi0, T = 0.5, 30 * H_WB
    names = ("y_earth", "z_earth", "vy_earth", "vz_earth", "x_earth", "vx_earth")
    with hover6dof.instantiate() as inst:
        start(inst, {**zero, "delta_gamma_start": phi0})
        for i in range(30):
            inst.slave.doStep(currentCommunicationPoint=i * H_WB, communicationStepSize=H_WB)
            t = (i + 1) * H_WB
            a = G_SI * np.array([math.sin(phi0), 1 - math.cos(phi0)])
            want = [*(a * t * t / 2), *(a * t), 0.0, 0.0]
            scale = [*(a * T * T / 2), *(a * T), 1.0, 1.0]
            np.testing.assert_allclose(_get(inst, names) / scale, np.divide(want, scale),
                                       rtol=0, atol=1e-9)
            att = _get(inst, ("phi", "delta_gamma", "theta", "psi", "delta_p", "delta_q",
                              "delta_r"))
            np.testing.assert_allclose(att, [phi0, phi0, 0, 0, 0, 0, 0], rtol=0, atol=1e-15)


@pytest.mark.integration
def test_fmu_at_90_degrees_pitch(hover6dof):
    """Through fmpy: delta_theta_start = 90 degrees (gimbal lock of the Euler outputs) and a
    roll rate of 0.5 rad per wing beat, large controls: 300 steps of 0.1 wing beat, every
    output finite at every step, nothing logged."""
    from fmu_helpers import start

    with hover6dof.instantiate() as inst:
        start(inst, {"delta_theta_start": math.pi / 2, "delta_p_start": 0.5 * N_HZ,
                     "delta_Phi_a": 0.2, "delta_phibar": -0.2})
        assert _get(inst, ["theta"])[0] == pytest.approx(math.pi / 2, abs=1e-15)
        h = 0.1 * H_WB
        for i in range(300):
            inst.slave.doStep(currentCommunicationPoint=i * h, communicationStepSize=h)
            assert np.isfinite(inst.slave.getReal(inst.vrs(hover6dof.names("output")))).all()
        assert not [m for m in inst.messages if m.status > 0]


def _run(inst, t0: int, n: int, h: float) -> np.ndarray:
    """n steps from step t0 with inputs that change every step; the outputs after each."""
    rows = []
    for k in range(t0, t0 + n):
        inst.slave.setReal(inst.vrs(["delta_Phi_a", "delta_phibar"]),
                           [0.05 * math.sin(0.7 * k), 0.03 * math.cos(0.4 * k)])
        inst.slave.doStep(currentCommunicationPoint=k * h, communicationStepSize=h)
        rows.append(inst.slave.getReal(inst.vrs(inst.fmu.names("output"))))
    return np.array(rows)


TUMBLING = {"delta_gamma_start": 1.0, "delta_theta_start": 0.3, "psi_start": 2.0,
            "delta_p_start": 0.4 * N_HZ, "delta_r_start": -0.3 * N_HZ, "delta_v_start": 0.5}


@pytest.mark.integration
def test_fmu_state_round_trip_while_tumbling(hover6dof):
    """The FMU state taken mid-run from a tumbling body (1 rad of roll, heading 2 rad, fast
    rates): the continuation after fmi2SetFMUstate, and after fmi2DeSerializeFMUstate into
    another instance started elsewhere, equals the first continuation bit for bit (all 13
    values of the state, the time and the clock restored; dronefly check covers the default
    experiment)."""
    from fmu_helpers import start

    h = 0.5 * H_WB
    with hover6dof.instantiate() as a, hover6dof.instantiate() as b:
        start(a, TUMBLING)
        _run(a, 0, 20, h)
        state = a.slave.getFMUstate()
        blob = a.slave.serializeFMUstate(state)
        first = _run(a, 20, 20, h)
        a.slave.setFMUstate(state)
        again = _run(a, 20, 20, h)
        start(b, {"psi_start": -1.0, "delta_q_start": 30.0})
        _run(b, 0, 3, h)
        restored = b.slave.deSerializeFMUstate(blob)
        b.slave.setFMUstate(restored)
        other = _run(b, 20, 20, h)
        for s, inst in ((state, a), (restored, b)):
            inst.slave.freeFMUstate(s)
    assert np.ptp(first, axis=0).max() > 1.0
    assert np.array_equal(first, again) and np.array_equal(first, other)


@pytest.mark.integration
@pytest.mark.parametrize("name, value, fragment", [
    ("delta_Phi_a", math.nan, "delta_Phi_a = nan"),
    ("delta_phibar", math.nan, "delta_phibar = nan"),
    ("delta_alpha_2a", 1e300, "state overflow"),
])
def test_fmu_bad_input_is_discarded_and_the_instance_stays_usable(hover6dof, name, value,
                                                                 fragment):
    """A NaN input, or one so large that the state overflows: doStep returns fmi2Discard with
    a message naming it, the outputs stay as they were, and after the input is set back the
    run continues exactly as a twin instance that never saw the bad value."""
    from fmpy.fmi1 import FMICallException

    from fmu_helpers import start

    h = 0.5 * H_WB
    with hover6dof.instantiate() as bad, hover6dof.instantiate() as twin:
        for inst in (bad, twin):
            start(inst, TUMBLING)
            _run(inst, 0, 5, h)
        vr = bad.vrs([name])
        good = bad.slave.getReal(vr)
        before = _get(bad, hover6dof.names("output"))
        bad.slave.setReal(vr, [value])
        with pytest.raises(FMICallException) as e:
            bad.slave.doStep(currentCommunicationPoint=5 * h, communicationStepSize=h)
        assert e.value.status == 2, "fmi2Discard"
        assert fragment in bad.messages[-1].message, bad.messages[-1].message
        assert np.array_equal(_get(bad, hover6dof.names("output")), before)
        bad.slave.setReal(vr, good)
        assert np.array_equal(_run(bad, 5, 5, h), _run(twin, 5, 5, h))


@pytest.mark.integration
@pytest.mark.parametrize("starts, fragment", [
    ({"delta_gamma_start": math.nan}, "delta_gamma_start = nan"),
    ({"psi_start": math.inf}, "psi_start = inf"),
    ({"delta_gamma_start": 1.0, "delta_theta_start": 1.2}, "no attitude has both"),
], ids=["gamma nan", "heading inf", "|sin gamma| > cos theta"])
def test_fmu_infeasible_attitude_start_is_refused(hover6dof, starts, fragment):
    """A start attitude that is not finite, or that no attitude has (a wing lower than the
    pitch allows): fmi2ExitInitializationMode logs an error naming it, every doStep is
    discarded naming it; after fmi2Reset a feasible start (gamma 0.5 at theta 1.0, near the
    limit) runs, its outputs reproducing the starts."""
    from fmpy.fmi1 import FMICallException

    from fmu_helpers import start

    with hover6dof.instantiate() as inst:
        start(inst, starts)
        assert any(m.status == 3 and fragment in m.message for m in inst.messages), \
            inst.messages
        for _ in range(2):
            with pytest.raises(FMICallException) as e:
                inst.slave.doStep(currentCommunicationPoint=0.0, communicationStepSize=H_WB)
            assert e.value.status == 2 and fragment in inst.messages[-1].message
        inst.slave.reset()
        start(inst, {"delta_gamma_start": 0.5, "delta_theta_start": 1.0})
        inst.slave.doStep(currentCommunicationPoint=0.0, communicationStepSize=H_WB)
        inst.slave.reset()
        start(inst, {"delta_gamma_start": 0.5, "delta_theta_start": 1.0})
        np.testing.assert_allclose(_get(inst, ["delta_gamma", "delta_theta", "psi"]),
                                   [0.5, 1.0, 0.0], rtol=0, atol=1e-15)
