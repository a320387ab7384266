"""Independent oracles for models/flapping/model.py (the equations of the wing-beat-resolved
model), written for mutation testing (docs/mutation.md), on small inputs (20 steps a beat, at
most one beat).

Oracles: the quasi-steady model's own kinematics (``kinematics.stroke``, ``pitch`` and
``sampled_motion``'s wing frame and element positions) and loads (``forces_at``,
``forces_vector``); the rules of :mod:`dronefly.models.flapping` written again here (the
stroke as half cosines between reversals, the pitch rotations centred on them, when new
controls take effect); central differences of positions and angles for their rates; the
rigid-body equations written again with numpy and scipy's ``Rotation``; the classical
Runge-Kutta method written again on the model's public derivative; the left-right mirror
symmetry of the insect; the documented bounds of the grids kept.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from dronefly.models.flapping import (STATE_SIZE, WING_CM_OVER_R, FlappingError, FlappingModel,
                                      wing_beat_controls)
from dronefly.models.lateral_interface import FLIGHT_DATA, reference_scales
from dronefly.models.quasisteady import CONTROLS, kinematics

N = 20
ZERO = (0.0,) * 7
C7 = (0.05, 0.03, -0.02, 0.04, 0.02, -0.03, 0.01)
#: the controls of the next beat: every one changes (the lateral ones change sign)
C7B = (-0.04, 0.02, 0.03, -0.03, 0.05, 0.02, -0.02)
#: a disturbed body state: every velocity, rate and angle nonzero, position off the origin
X13 = np.array([0.02, -0.015, 0.01, 0.25, -0.2, 0.3,
                *Rotation.from_euler("ZYX", [0.5, -0.2, 0.3]).as_quat()[[3, 0, 1, 2]],
                0.1, -0.2, 0.3])
#: phases off the grid and off every kink of the kinematics (reversals at 0 and 0.5, the
#: rotations' ends at 0.15, 0.35, 0.65, 0.85), by at least 0.01: in rotations and held parts
TAUS = (0.03, 0.11, 0.22, 0.41, 0.48, 0.52, 0.6, 0.77, 0.9, 0.97)


@pytest.fixture(scope="module")
def fm() -> FlappingModel:
    return FlappingModel(steps_per_beat=N)


def _kin(fm, c):
    """The per-wing Phi, phibar, alpha_d, alpha_u of controls ``c`` (the quasi-steady model)."""
    return fm.qs.wing_kinematics(dict(zip(CONTROLS, c)), fm.trim)


def _reference_angles(fm, tau, cp, cn, down):
    """(phi, psi) of both wings at phase ``tau`` of a beat with controls ``cn`` after ``cp``,
    by the rules of :mod:`dronefly.models.flapping` (``down``: on the downstroke's branch).

    The stroke: half a cosine from the rear reversal the last beat reached to the new front
    reversal (downstroke), then from there to the new rear reversal (upstroke). The pitch:
    rotations of length D centred on the reversals (profile s - sin(2 pi s) / (2 pi)), held
    between them; the one about the beat's start ends at the old alpha_d, the one about the
    front reversal goes from it to the new pi - alpha_u, the one about the end to the new
    alpha_d."""
    old, new = _kin(fm, cp), _kin(fm, cn)
    D = fm.qs.geometry.rotation_fraction
    out = np.zeros((2, 2))
    for w in range(2):
        rear_old = old["phibar"][w] - 0.5 * old["Phi"][w]
        front = new["phibar"][w] + 0.5 * new["Phi"][w]
        rear = new["phibar"][w] - 0.5 * new["Phi"][w]
        if down:
            phi = rear_old + (front - rear_old) * 0.5 * (1.0 - math.cos(2.0 * math.pi * tau))
        else:
            phi = front - (front - rear) * 0.5 * (1.0 - math.cos(2.0 * math.pi * (tau - 0.5)))
        up_old, down_old = math.pi - old["alpha_u"][w], old["alpha_d"][w]
        up_new, down_new = math.pi - new["alpha_u"][w], new["alpha_d"][w]

        def rotation(frm, to, centre):
            s = (tau - centre) / D + 0.5
            return frm + (to - frm) * (s - math.sin(2.0 * math.pi * s) / (2.0 * math.pi))

        if tau < 0.5 * D:
            psi = rotation(up_old, down_old, 0.0)
        elif tau <= 0.5 - 0.5 * D:
            psi = down_old
        elif tau < 0.5 + 0.5 * D:
            psi = rotation(down_old, up_new, 0.5)
        elif tau <= 1.0 - 0.5 * D:
            psi = up_new
        else:
            psi = rotation(up_new, down_new, 1.0)
        out[:, w] = phi, psi
    return out


def _reference_inertia(fm, tau, x, cp, cn):
    """The wings' inertial reaction by its definition (:mod:`dronefly.models.flapping`): each
    wing a point mass m_w at WING_CM_OVER_R R on its span axis, the body feeling
    -m_w (a_rel + 2 omega x v_rel) there and its moment about the centre of mass.

    The point's position is the quasi-steady model's (``sampled_motion``: hinge and span axis,
    one element at r = 0.35 R) for the stroke of the phase's half (a half cosine is the
    harmonic stroke of phibar = the reversals' mean, Phi = their distance); its velocity and
    acceleration in the phase are five-point central differences (h = 1e-3: error h^4 times
    the stroke's fifth derivative, about 1e-9 of the positions). Non-dimensional: positions
    in chords, forces over 0.5 rho U^2 S_t, so the force is m_w+ k (P'' + 2 omega+ x P'),
    k = c / (U t_w)."""
    g = fm.qs.geometry
    old, new = _kin(fm, cp), _kin(fm, cn)
    rear_old = old["phibar"] - 0.5 * old["Phi"]
    front, rear = new["phibar"] + 0.5 * new["Phi"], new["phibar"] - 0.5 * new["Phi"]
    start, end = (rear_old, front) if tau <= 0.5 else (rear, front)
    Phi, phibar = end - start, 0.5 * (start + end)
    h = 1e-3
    t = tau + h * np.arange(-2, 3)
    mo = kinematics.sampled_motion(g, np.array([WING_CM_OVER_R * g.R]), t, Phi, phibar,
                                   new["alpha_d"], new["alpha_u"])
    P = np.stack([mo["Px"][..., 0], mo["Py"][..., 0],
                  np.broadcast_to(mo["Pz"][..., 0], mo["Px"][..., 0].shape)], axis=-1)  # (2, 5, 3)
    v = (P[:, 0] - 8.0 * P[:, 1] + 8.0 * P[:, 3] - P[:, 4]) / (12.0 * h)
    a = (-P[:, 0] + 16.0 * P[:, 1] - 30.0 * P[:, 2] + 16.0 * P[:, 3] - P[:, 4]) / (12.0 * h * h)
    omega = np.asarray(x[3:6])
    m_w = FLIGHT_DATA["m_wing"] / (FLIGHT_DATA["m_body"] + 2.0 * FLIGHT_DATA["m_wing"]) * fm.m
    F = -m_w * g.k * (a + 2.0 * np.cross(omega, v))  # (2, 3)
    return np.concatenate([F.sum(axis=0), np.cross(P[:, 2], F).sum(axis=0)])


def _reference_rhs(fm, x, F):
    """dx/dtau of the rigid body under the loads F (the equations of
    :mod:`dronefly.models.flapping`, numpy and scipy's Rotation), times the model's period:
    m+ dV/dt = F + m+ g+ R^T e_z - m+ omega x V, J+ domega/dt = M - omega x J+ omega,
    de/dt = e * (0, omega) / 2, dP/dt = R V."""
    s = reference_scales()
    J = np.array([[s["Ix_plus"], 0.0, -s["Ixz_plus"]], [0.0, s["Iy_plus"], 0.0],
                  [-s["Ixz_plus"], 0.0, s["Iz_plus"]]])
    V, w, e = x[:3], x[3:6], x[6:10]
    R = Rotation.from_quat([e[1], e[2], e[3], e[0]]).as_matrix()  # body -> earth
    dV = F[:3] / s["m_plus"] + s["g_plus"] * R.T @ [0.0, 0.0, 1.0] - np.cross(w, V)
    dw = np.linalg.solve(J, F[3:] - np.cross(w, J @ w))
    de = 0.5 * np.array([-e[1:] @ w, *(e[0] * w + np.cross(e[1:], w))])
    return fm.period * np.concatenate([dV, dw, de, R @ V])


def _reference_advance(fm, x, t0, t1, cp, cn):
    """The classical Runge-Kutta method written again on the model's public derivative, on the
    grid of ``steps_per_beat`` steps a beat, a partial step at either end off it, the
    quaternion normalised at the end. Each stage is evaluated 1e-13 inside its step so that at
    the front reversal (where the stroke's acceleration jumps when the controls change) it
    takes its own step's half-stroke; the loads' rate in the phase is below 1e3 (measured 220),
    so that moves a stage by 1e-10 of the loads at most, 1e-14 of the state after the step's
    h / 6."""
    n = fm.steps_per_beat
    cuts = [t0, *(j / n for j in range(n + 1) if t0 < j / n < t1), t1]
    y = np.array(x, dtype=float)
    eps = 1e-13

    def f(t, yy):
        return fm.derivative(t, yy, cp, cn)

    for a, b in zip(cuts[:-1], cuts[1:]):
        h = b - a
        k1 = f(a + eps, y)
        k2 = f(a + 0.5 * h, y + 0.5 * h * k1)
        k3 = f(a + 0.5 * h, y + 0.5 * h * k2)
        k4 = f(b - eps, y + h * k3)
        y = y + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    y[6:10] /= np.linalg.norm(y[6:10])
    return y


def _mirror(x):
    """The insect mirrored left to right (y -> -y): v, p, r, the roll and yaw parts of the
    quaternion (e1, e3) and the position's y change sign."""
    out = np.array(x, dtype=float)
    out[[1, 3, 5, 7, 9, 11]] *= -1.0
    return out


def _mirror_controls(c):
    """The lateral controls (the first three, split between the wings with opposite signs)
    change sign: the wings swap."""
    return (-c[0], -c[1], -c[2], *c[3:])


# -- the controls and the settings -------------------------------------------------------------
def test_controls_by_name_or_in_order_and_the_refused_ones():
    """None is the trim (seven zeros); a mapping gives each named control, 0 for the others, in
    CONTROLS order; a sequence is taken in order as floats. A name that is not a control, a
    sequence of another length, and a value that is not finite (in either form) are refused
    naming what is wrong."""
    assert wing_beat_controls(None) == ZERO
    got = wing_beat_controls({"delta_Phi": 0.25, "delta_alpha_2a": -0.5})
    assert got == (0.0, 0.0, -0.5, 0.25, 0.0, 0.0, 0.0)
    assert wing_beat_controls(np.arange(7) * 0.5) == (0.0, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0)
    assert all(type(v) is float for v in wing_beat_controls(np.arange(7)))
    with pytest.raises(FlappingError, match=r"controls \['delta_x'\]: expected delta_Phi_a, "):
        wing_beat_controls({"delta_x": 1.0, "delta_Phi": 0.0})
    for n in (6, 8):
        with pytest.raises(FlappingError, match=f"^{n} controls: expected 7"):
            wing_beat_controls((0.0,) * n)
    for bad in (math.nan, math.inf, -math.inf):
        with pytest.raises(FlappingError, match=f"control delta_phibar = {bad!r} is not finite"):
            wing_beat_controls({"delta_phibar": bad})
        with pytest.raises(FlappingError, match=f"control delta_Phi_a = {bad!r} is not finite"):
            wing_beat_controls((bad,) + (0.0,) * 6)


def test_settings_refused_and_accepted_at_their_bounds(fm):
    """A frequency factor below 1 or not finite is refused, 1 accepted (period 1), 2.5 gives
    the period 0.4 wing beat; steps per beat must be a positive integer multiple of 20 (0,
    -20, 30, 20.0 refused; 20 and 60 accepted); the pitch rotation must last a fraction in
    (0, 0.5) of the beat (0 and 0.5 refused)."""
    for bad in (0.999, math.nan, math.inf, -2.0):
        with pytest.raises(FlappingError, match="must be >= 1"):
            FlappingModel(fm.qs, N, frequency_factor=bad)
    assert FlappingModel(fm.qs, N, frequency_factor=1.0).period == 1.0
    assert FlappingModel(fm.qs, N, frequency_factor=2.5).period == 0.4
    for bad in (0, -20, 30, 21, 20.0):
        with pytest.raises(FlappingError, match="must be a positive multiple of 20"):
            FlappingModel(fm.qs, bad)
    assert FlappingModel(fm.qs, 60).steps_per_beat == 60
    for D in (0.0, 0.5):
        qs = fm.qs.with_options(geometry=replace(fm.qs.geometry, rotation_fraction=D))
        qs._trim = fm.trim  # the trim's kinematics do not matter here
        with pytest.raises(FlappingError, match=f"rotation fraction {D!r} must be in"):
            FlappingModel(qs, N)


def test_mass_properties_from_the_flight_data(fm):
    """The body's m+, g+ and inertia tensor (Ixz+ off the diagonal with a minus sign) are the
    Sect. 2.4 data's (reference_scales); one wing's m_w+ is its share of the insect's mass
    (m_wing / (m_body + 2 m_wing)) of m+; its centre of mass is at 0.35 R. The averaged model
    has no wing inertia whatever it is asked."""
    s = reference_scales()
    assert fm.m == s["m_plus"] and fm.g == s["g_plus"]
    J = np.array([[s["Ix_plus"], 0.0, -s["Ixz_plus"]], [0.0, s["Iy_plus"], 0.0],
                  [-s["Ixz_plus"], 0.0, s["Iz_plus"]]])
    np.testing.assert_array_equal(fm.J, J)
    # an inverse to rounding: entries of J+ are O(10) to O(100), its condition number ~10
    np.testing.assert_allclose(fm.J_inv @ J, np.eye(3), rtol=0, atol=1e-13)
    share = FLIGHT_DATA["m_wing"] / (FLIGHT_DATA["m_body"] + 2.0 * FLIGHT_DATA["m_wing"])
    assert fm.m_wing == pytest.approx(share * s["m_plus"], rel=1e-14)  # a few roundings
    assert fm.r_wing == pytest.approx(0.35 * fm.qs.geometry.R, rel=1e-15)
    assert fm.wing_inertia and not fm.averaged
    twin = FlappingModel(fm.qs, N, wing_inertia=True, averaged=True)
    assert twin.averaged and not twin.wing_inertia
    assert not FlappingModel(fm.qs, N, wing_inertia=False).wing_inertia


# -- the kinematics ----------------------------------------------------------------------------
@pytest.mark.parametrize("c", [ZERO, C7])
def test_held_controls_give_the_quasi_steady_models_kinematics(fm, c):
    """With the controls held the angles are those of the quasi-steady model (its ``stroke``
    and ``pitch`` of the same per-wing angles), at the grid's points and off it; the stroke's
    acceleration is the derivative of its rate pi Phi sin(2 pi t), 2 pi^2 Phi cos(2 pi t).
    Tolerance: a few roundings of angles O(1) and of pitch accelerations O(100)."""
    k = _kin(fm, c)
    D = fm.qs.geometry.rotation_fraction
    taus = np.array([*np.arange(N + 1) / N, *TAUS, 0.5 * D, 0.5 + 0.5 * D, 1.0 - 0.5 * D])
    phi, dphi = kinematics.stroke(taus, k["Phi"], k["phibar"])
    psi, dpsi, ddpsi = kinematics.pitch(taus, D, k["alpha_d"], k["alpha_u"])
    ddphi = 2.0 * np.pi ** 2 * k["Phi"][:, None] * np.cos(2.0 * np.pi * taus)
    want = np.stack([phi, dphi, ddphi, psi, dpsi, ddpsi], axis=0).transpose(2, 0, 1)
    got = np.array([fm.angles(t, c, c) for t in taus])
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-11)


def test_kinematics_across_a_control_change_by_the_documented_rules(fm):
    """The stroke and pitch angles of a beat whose controls change at its start are those of
    the rules written again here (:func:`_reference_angles`), on both half-strokes, at the
    grid's points (the front reversal on the downstroke's branch: the phase's own, up to 0.5
    included) and off it; the wings differ (the lateral controls). Tolerance: roundings of
    angles O(1)."""
    for tau in (*np.arange(N + 1) / N, *TAUS):
        got = fm.angles(tau, C7, C7B)[[0, 3]]
        want = _reference_angles(fm, tau, C7, C7B, down=tau <= 0.5)
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-13, err_msg=str(tau))
    assert abs(got[0, 0] - got[0, 1]) > 1e-3 and abs(got[1, 0] - got[1, 1]) > 1e-3


def test_rates_are_the_derivatives_of_the_angles(fm):
    """dphi, ddphi, dpsi, ddpsi are the phase derivatives of phi and psi: five-point central
    differences (h = 1e-3) of the model's own angles, within a phase of the pitch and a
    half-stroke (the phases of TAUS are 0.01 or more from every kink). The differences' error
    is h^4 times the fifth or sixth derivative, (2 pi / D)^5 to ^6 times the rotation's 2 rad:
    up to 1e-6 of ddpsi's O(100); the bound is 1e-5 of each row's largest value."""
    h = 1e-3
    for tau in TAUS:
        a = np.array([fm.angles(tau + i * h, C7, C7B) for i in range(-2, 3)])
        for row, d1, d2 in ((0, 1, 2), (3, 4, 5)):
            f = a[:, row]
            first = (f[0] - 8.0 * f[1] + 8.0 * f[3] - f[4]) / (12.0 * h)
            second = (-f[0] + 16.0 * f[1] - 30.0 * f[2] + 16.0 * f[3] - f[4]) / (12.0 * h * h)
            for got, want in ((a[2, d1], first), (a[2, d2], second)):
                np.testing.assert_allclose(got, want, rtol=0,
                                           atol=1e-5 * max(1.0, np.abs(want).max()),
                                           err_msg=str((tau, row)))


def test_the_front_reversal_and_the_beats_ends_on_the_grid(fm):
    """At a grid point (within 1e-9 of a step: 5e-11 of a beat here) the angles are the grid
    point's, the same floats on the phase's side: at the front reversal the downstroke's up to
    0.5 and the upstroke's after it (the stroke's acceleration jumps, -2 pi^2 times the
    distance between the reversals of either half); at the beat's start those of phase 0,
    also just below it, at its end those of phase 1, also just above it. 2e-9 of a step off, a phase is its own
    (the stroke's or the pitch's rate, 4 to 16 rad a beat, moves phi or psi by 1e-10 or more:
    not the grid point's float)."""
    old, new = _kin(fm, C7), _kin(fm, C7B)
    front = new["phibar"] + 0.5 * new["Phi"]
    down_b = front - (old["phibar"] - 0.5 * old["Phi"])
    up_b = new["Phi"]
    tol = 1e-9 / N
    at = fm.angles(0.5, C7, C7B)
    np.testing.assert_allclose(at[2], -2.0 * np.pi ** 2 * down_b, rtol=1e-14, atol=0)
    np.testing.assert_array_equal(fm.angles(0.5 - 0.5 * tol, C7, C7B), at)
    after = fm.angles(0.5 + 0.5 * tol, C7, C7B)
    np.testing.assert_allclose(after[2], -2.0 * np.pi ** 2 * up_b, rtol=1e-14, atol=0)
    np.testing.assert_array_equal(fm.angles(0.5 + 0.2 * tol, C7, C7B), after)
    assert np.all(np.abs(at[2] - after[2]) > 0.01)
    start = fm.angles(0.0, C7, C7B)
    np.testing.assert_array_equal(fm.angles(-0.5 * tol, C7, C7B), start)
    np.testing.assert_array_equal(fm.angles(0.5 * tol, C7, C7B), start)
    end = fm.angles(1.0, C7, C7B)
    np.testing.assert_array_equal(fm.angles(1.0 - 0.5 * tol, C7, C7B), end)
    np.testing.assert_array_equal(fm.angles(1.0 + 0.5 * tol, C7, C7B), end)
    np.testing.assert_allclose(start[[0, 3]], _reference_angles(fm, 0.0, C7, C7B, True),
                               rtol=0, atol=1e-14)
    np.testing.assert_allclose(end[[0, 3]], _reference_angles(fm, 1.0, C7, C7B, False),
                               rtol=0, atol=1e-14)
    for t in (0.25, 0.5, 1.0):
        off = fm.angles(t - 2.0 * tol, C7, C7B)
        assert not np.array_equal(off[[0, 3]], fm.angles(t, C7, C7B)[[0, 3]])
        # off the grid by 1e-10 of a beat: within that times the rate of each row (up to
        # 3e3 for ddpsi, (2 pi / D)^3 times the rotation's 2 rad / (2 pi)) of the point
        np.testing.assert_allclose(off, fm.angles(t, C7, C7B), rtol=0, atol=1e-6)


# -- the loads ---------------------------------------------------------------------------------
def test_aerodynamic_loads_are_the_quasi_steady_forces_at_the_angles(fm):
    """The aerodynamic loads at a phase are the quasi-steady model's ``forces_at`` the
    angles of the phase (from the rules written here, their rates from the model) and the
    body's velocities and rates; at the front reversal on the downstroke's branch up to 0.5
    included, also through the derivative (which does not snap to the grid). Tolerance: the
    loads are O(1) (the weight is 1.47), evaluated by the same terms vectorised: 1e-13."""
    v = X13[:6]
    for tau in (0.0, 0.15, *TAUS, 0.5, 0.5 + 0.25e-9 / N, 0.75, 1.0):
        ang = fm.angles(tau, C7, C7B)
        # a phase within 1e-9 of a step of a grid point is that point, on its own side
        point = 0.5 if tau > 0.5 and tau - 0.5 < 1e-9 / N else tau
        ref = _reference_angles(fm, point, C7, C7B, down=tau <= 0.5)
        np.testing.assert_allclose(ang[[0, 3]], ref, rtol=0, atol=1e-13)
        aero, _ = fm.loads(tau, X13, C7, C7B)
        np.testing.assert_allclose(aero, fm.qs.forces_at(ang, v), rtol=0, atol=1e-13,
                                   err_msg=str(tau))
    # the derivative at the front reversal: the downstroke's loads
    aero, wing = fm.loads(0.5, X13, C7, C7B)
    np.testing.assert_allclose(fm.derivative(0.5, X13, C7, C7B),
                               _reference_rhs(fm, X13, aero + wing), rtol=0, atol=1e-13)


def test_wing_inertia_is_the_reaction_of_two_point_masses(fm):
    """The wings' inertial loads are -m_w (a_rel + 2 omega x v_rel) at each wing's centre of
    mass and its moment (:func:`_reference_inertia`: the quasi-steady model's wing frame and
    hinge, central differences), with the controls held and across a change, on both
    half-strokes, with nonzero body rates (the Coriolis part). Tolerance: the differences'
    error, about 1e-9 of loads up to 6 (four weights; measured 2.9e-9): 1e-8."""
    for cp, cn in ((C7, C7), (C7, C7B)):
        for tau in TAUS:
            _, wing = fm.loads(tau, X13, cp, cn)
            want = _reference_inertia(fm, tau, X13, cp, cn)
            np.testing.assert_allclose(wing, want, rtol=0, atol=1e-8, err_msg=str((tau, cn)))
    assert np.abs(wing).max() > 1.0
    # without the wing inertia, and in the averaged model: none
    for other in (FlappingModel(fm.qs, N, wing_inertia=False),
                  FlappingModel(fm.qs, N, averaged=True)):
        for tau in (0.0, 0.3, 0.52):
            assert not np.any(other.loads(tau, X13, C7, C7B)[1])


def test_the_averaged_model_takes_the_cycle_average_of_the_beats_controls(fm):
    """The averaged model's aerodynamic loads at any phase are the quasi-steady model's cycle
    average (``forces_vector``) of the beat's own controls, not the previous beat's. Same
    computation by another path: 1e-14 of loads O(1)."""
    twin = FlappingModel(fm.qs, N, averaged=True)
    v = X13[:6]
    want = fm.qs.forces_vector(v, dict(zip(CONTROLS, C7B)), fm.trim)
    for tau in (0.0, 0.3, 0.5, 0.52, 0.9):
        np.testing.assert_allclose(twin.loads(tau, X13, C7, C7B)[0], want, rtol=0, atol=1e-14)


def test_the_mirrored_insect_feels_the_mirrored_loads(fm):
    """Left-right symmetry: the insect mirrored (y -> -y, the wings swapped by the lateral
    controls' signs) feels the mirrored loads and moves as the mirror image, at every phase,
    aerodynamic and inertial loads alike. Tolerance: the two wings' terms are computed in
    other orders: roundings of O(1) values."""
    flip6 = np.array([1.0, -1.0, 1.0, -1.0, 1.0, -1.0])
    Mx, Mp, Mn = _mirror(X13), _mirror_controls(C7), _mirror_controls(C7B)
    for tau in (0.0, *TAUS, 0.5, 1.0):
        for ours, theirs in zip(fm.loads(tau, X13, C7, C7B), fm.loads(tau, Mx, Mp, Mn)):
            np.testing.assert_allclose(theirs, flip6 * ours, rtol=0, atol=1e-13)
        np.testing.assert_allclose(fm.derivative(tau, Mx, Mp, Mn),
                                   _mirror(fm.derivative(tau, X13, C7, C7B)), rtol=0, atol=1e-13)


def test_derivative_is_the_documented_rigid_body_under_the_loads(fm):
    """dx/dtau is the rigid body's equations (written again, :func:`_reference_rhs`) under
    the model's loads at that phase, times the period: a model forced 1.6 times faster feels
    the same loads at each phase, and its state moves 1/1.6 as far per phase. Default
    controls: the trim (zeros). Tolerance: roundings of O(1) terms."""
    fast = FlappingModel(fm.qs, N, frequency_factor=1.6)
    for tau in (0.0, 0.3, 0.52, 0.9):
        aero, wing = fm.loads(tau, X13, C7, C7B)
        for model in (fm, fast):
            for a, b in zip(model.loads(tau, X13, C7, C7B), (aero, wing)):
                np.testing.assert_array_equal(a, b)
            np.testing.assert_allclose(model.derivative(tau, X13, C7, C7B),
                                       _reference_rhs(model, X13, aero + wing), rtol=0,
                                       atol=1e-13)
    aero, wing = fm.loads(0.3, X13, ZERO, ZERO)
    np.testing.assert_allclose(fm.derivative(0.3, list(X13)), _reference_rhs(fm, X13, aero + wing),
                               rtol=0, atol=1e-13)



def test_a_body_at_rest_under_no_loads_falls_at_g(monkeypatch):
    """Without loads, at rest (no velocity, no rates), the body falls: dV/dtau is g+ along
    the earth's z axis in body axes (scipy's rotation of e_z), times the period, and nothing
    else moves: every torque and rate is exactly 0.0, and so is every change of a rate, of the
    attitude and of the position. Exact zeros, and the gravity's roundings (1e-17 of g+ =
    0.016)."""
    for ff in (1.0, 1.6):
        m = FlappingModel(steps_per_beat=N, frequency_factor=ff)
        monkeypatch.setattr(m, "_loads", lambda *args, **kw: (np.zeros(6), np.zeros(6)))
        x = np.array([0.0] * 6 + list(X13[6:10]) + [0.1, -0.2, 0.3])
        R = Rotation.from_quat(x[[7, 8, 9, 6]]).as_matrix()  # body -> earth
        got = m.derivative(0.3, x)
        np.testing.assert_allclose(got[:3], m.period * m.g * R.T @ [0.0, 0.0, 1.0], rtol=0,
                                   atol=1e-17)
        np.testing.assert_array_equal(got[3:], np.zeros(10))

# -- the integration ---------------------------------------------------------------------------
def test_a_beat_is_classical_runge_kutta_on_the_grid(fm):
    """A beat (and the one-beat map in reduced coordinates) is the classical Runge-Kutta
    method on the grid of 20 steps written again on the public derivative
    (:func:`_reference_advance`), across a control change, for a model forced faster too;
    the quaternion comes back of unit length from one that is not. Tolerance: the same
    arithmetic in another order, 20 steps: 1e-13 of a state O(1)."""
    fast = FlappingModel(fm.qs, N, frequency_factor=1.6)
    x = X13.copy()
    x[6:10] *= 1.1
    for model in (fm, fast):
        got = model.beat(x, C7, C7B)
        np.testing.assert_allclose(got, _reference_advance(model, x, 0.0, 1.0, C7, C7B),
                                   rtol=0, atol=1e-13)
        assert abs(np.linalg.norm(got[6:10]) - 1.0) < 1e-15
    np.testing.assert_array_equal(x[6:10], 1.1 * X13[6:10])  # the input is not changed
    # the default controls are the trim
    np.testing.assert_allclose(fm.beat(X13), _reference_advance(fm, X13, 0.0, 1.0, ZERO, ZERO),
                               rtol=0, atol=1e-13)
    # the one-beat map in reduced coordinates, heading 0 and position 0 (scipy's Euler angles)
    z = np.array([0.02, -0.015, 0.01, 0.25, -0.2, 0.3, 0.3, -0.2])
    quat = Rotation.from_euler("ZYX", [0.0, z[7], z[6]]).as_quat()[[3, 0, 1, 2]]
    start = np.array([*z[:6], *quat, 0.0, 0.0, 0.0])
    end = _reference_advance(fm, start, 0.0, 1.0, C7, C7)
    _, theta, phi = Rotation.from_quat(end[[7, 8, 9, 6]]).as_euler("ZYX")
    np.testing.assert_allclose(fm.z_map(z, C7), [*end[:6], phi, theta], rtol=0, atol=1e-13)


def test_partial_steps_at_either_end_of_a_stretch(fm):
    """From and to phases off the grid: a partial step to the first grid point, whole steps,
    a partial step from the last one (the reference's cuts), across the front reversal; a
    stretch within one step is one partial step; phases on the grid or within round-off of it
    take no extra step. Tolerance as for a beat."""
    for t0, t1 in ((0.1234, 0.6789), (0.45, 0.55), (0.51, 0.54), (0.2, 0.35), (0.0, 0.05),
                   (0.95, 1.0), (0.5, 0.5 + 1e-3)):
        np.testing.assert_allclose(fm.advance(X13, t0, t1, C7, C7B),
                                   _reference_advance(fm, X13, t0, t1, C7, C7B),
                                   rtol=0, atol=1e-13, err_msg=str((t0, t1)))
    # a stretch from a phase a rounding error off the grid is the stretch from the grid point
    np.testing.assert_allclose(fm.advance(X13, 0.15 + 1e-16, 0.4, C7, C7B),
                               _reference_advance(fm, X13, 0.15, 0.4, C7, C7B), rtol=0, atol=1e-13)
    np.testing.assert_allclose(fm.advance(X13, 0.1, 0.4 - 1e-16, C7, C7B),
                               _reference_advance(fm, X13, 0.1, 0.4, C7, C7B), rtol=0, atol=1e-13)


def test_an_empty_stretch_returns_a_normalised_copy(fm):
    """A stretch of length 0 returns the state with its quaternion of unit length, a new
    array: the given state (through the checked entry and the one that takes an array) is not
    changed."""
    x = X13.copy()
    x[6:10] *= 2.0
    for t in (0.0, 0.3, 1.0):
        got = fm.advance(x, t, t, C7, C7B)
        np.testing.assert_allclose(got, [*X13[:6], *(X13[6:10] / np.linalg.norm(X13[6:10])),
                                         *X13[10:]], rtol=0, atol=1e-15)
        np.testing.assert_array_equal(x[6:10], 2.0 * X13[6:10])
        got = fm._advance(x, t, t, C7, C7B)
        assert got is not x
        np.testing.assert_array_equal(x[6:10], 2.0 * X13[6:10])


def test_advance_refuses_bad_phases_states_and_a_state_that_is_not_finite(fm):
    """Phases outside 0 <= tau0 <= tau1 <= 1, a state of another size, and a state that is not
    finite after the stretch are refused, the last naming its velocities and rates."""
    for t0, t1 in ((0.5, 0.4), (-0.1, 0.5), (0.5, 1.1)):
        with pytest.raises(FlappingError, match="must satisfy 0 <= tau0 <= tau1 <= 1"):
            fm.advance(X13, t0, t1)
    fm.advance(X13, 0.0, 0.0)
    fm.advance(X13, 1.0, 1.0)
    for n in (12, 14):
        with pytest.raises(FlappingError, match=f"state of {n} values: expected {STATE_SIZE}"):
            fm.advance(np.zeros(n), 0.0, 0.5)
    bad = X13.copy()
    bad[1] = math.nan
    with pytest.raises(FlappingError, match=r"not finite after phases 0.2 -> 0.7 \(from u, v, "
                                            r"w, p, q, r = \[0.02, nan, 0.01, 0.25, -0.2, 0.3\]\)"):
        fm.advance(bad, 0.2, 0.7)
    with pytest.raises(FlappingError, match="not finite after phases 0.3 -> 0.3"):
        fm.advance(bad, 0.3, 0.3)


# -- the reduced coordinates -------------------------------------------------------------------
def test_reduced_coordinates_are_the_state_with_scipys_euler_angles():
    """state_from_z: the velocities and rates, the quaternion of (phi, theta, psi) (scipy's
    ZYX, up to the sign of a quaternion), position 0; z_from_state its inverse (scipy's Euler
    angles). Roundings of O(1) values."""
    z = np.array([0.02, -0.015, 0.01, 0.25, -0.2, 0.3, 0.3, -0.2])
    x = FlappingModel.state_from_z(z, 0.5)
    assert x.shape == (13,)
    np.testing.assert_array_equal(x[:6], z[:6])
    np.testing.assert_array_equal(x[10:], 0.0)
    q = Rotation.from_euler("ZYX", [0.5, -0.2, 0.3]).as_quat()[[3, 0, 1, 2]]
    np.testing.assert_allclose(x[6:10] * np.sign(x[6] * q[0]), q, rtol=0, atol=1e-15)
    np.testing.assert_allclose(FlappingModel.z_from_state(X13), [*X13[:6], 0.3, -0.2],
                               rtol=0, atol=1e-14)
    np.testing.assert_allclose(FlappingModel.z_from_state(x), z, rtol=0, atol=1e-14)
    np.testing.assert_array_equal(FlappingModel.state_from_z(z)[6:10],
                                  FlappingModel.state_from_z(z, 0.0)[6:10])


# -- the grids kept ----------------------------------------------------------------------------
def test_sixteen_grids_are_kept_the_least_recently_used_dropped(fm, monkeypatch):
    """One model keeps the grids of stages of 16 pairs of controls (the documented bound),
    dropping the least recently used: 16 pairs stepped in turn make 16 grids; a 17th drops the
    oldest not used since, and the pair used again is kept. Counted as the calls that make
    the stages of a whole grid (each beat that makes one calls it once)."""
    m = FlappingModel(fm.qs, N)
    made = []
    original = m._stages
    monkeypatch.setattr(m, "_stages", lambda times, *a: made.append(len(times)) or
                        original(times, *a))
    pairs = [((0.001 * k,) + (0.0,) * 6,) * 2 for k in range(17)]
    x = X13

    def fly(k):
        m.beat(x, *pairs[k])

    for k in range(16):
        fly(k)
    for k in range(16):
        fly(k)
    assert len(made) == 16
    fly(0)  # the oldest used again: the most recent
    fly(16)  # a 17th: drops pair 1, the least recently used
    assert len(made) == 17
    fly(0)
    assert len(made) == 17
    fly(1)
    assert len(made) == 18
