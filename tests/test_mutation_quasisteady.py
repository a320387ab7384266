"""Independent oracles for models/quasisteady/ on small inputs, written for mutation testing
(docs/mutation.md): the geometry against the Sect. 2.4 data and Ellington's planform
definitions (scipy's ``quad`` for the moments of the beta planform), the Gauss-Jacobi rule
against ``scipy.special.roots_jacobi``, the wing motion against its closed forms, central
differences and the paper's definitions of the controls (Sect. 2.1)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.special import beta as beta_fn, roots_jacobi

from dronefly.core.errors import DroneflyError
from dronefly.models.lateral_interface import FLIGHT_DATA
from dronefly.models.quasisteady import COEFFICIENT_SETS, Terms, Trim, WingGeometry, gauss_jacobi
from dronefly.models.quasisteady import kinematics as kin
from dronefly.models.quasisteady.cycle import sampled_forces as sampled_cycle_forces
from dronefly.models.quasisteady.elements import blade_elements
from dronefly.models.quasisteady.wing import BODY_DATA

GEOM = WingGeometry.from_flight_data()


# -- wing.py ---------------------------------------------------------------------------------
def _planform_moment(p, q, j):
    """The j-th moment of r^(p-1) (1-r)^(q-1) on [0, 1] (scipy's quad)."""
    return quad(lambda r: r ** (j + p - 1.0) * (1.0 - r) ** (q - 1.0), 0.0, 1.0,
                epsabs=0.0, epsrel=1e-13, limit=200)[0]


def test_geometry_from_the_flight_data():
    """Sect. 2.4 and Ellington (1984): r2 = 0.929 r1^0.732; the beta planform's first moment
    over its area is r1 and its radius of gyration r2 (scipy's quad, rel 1e-13: 1e-10);
    lengths in c, U = 2 Phi n r2, k = c / (U t_w); the roots 0.33 l_b apart, l1 = 0.13 l_b
    from the centre of mass at chi0 - chi = 10 deg below and ahead of it; W+ = m g over
    0.5 rho U^2 S_t (closed forms: a few roundings, 1e-14)."""
    d, g = FLIGHT_DATA, GEOM
    assert 0.929 * g.r1_hat ** 0.732 == pytest.approx(d["r2_over_R"], rel=1e-14)
    area = _planform_moment(g.p, g.q, 0)
    assert _planform_moment(g.p, g.q, 1) / area == pytest.approx(g.r1_hat, rel=1e-10)
    assert math.sqrt(_planform_moment(g.p, g.q, 2) / area) == pytest.approx(g.r2_hat, rel=1e-10)
    c = d["c"]
    Phi = math.radians(d["Phi_deg"])
    U = 2.0 * Phi * d["n"] * d["r2_over_R"] * d["R"]
    lb, l1 = BODY_DATA["l_b"], 0.13 * BODY_DATA["l_b"]
    tilt = math.radians(10.0)
    want = dict(R=d["R"] / c, r2_hat=0.55, S_wing=d["S_wing"] / c ** 2, Phi_rad=Phi,
                k=c * d["n"] / U, x0_hat=0.25, rotation_fraction=0.3,
                weight=(d["m_body"] + 2 * d["m_wing"]) * d["g"]
                / (0.5 * d["rho"] * U ** 2 * 2 * d["S_wing"]))
    for name, value in want.items():
        assert getattr(g, name) == pytest.approx(value, rel=1e-14), name
    assert g.hinge == pytest.approx((l1 * math.sin(tilt) / c, 0.165 * lb / c,
                                     -l1 * math.cos(tilt) / c), rel=1e-14)


@pytest.mark.parametrize("alpha_deg", [0.0, 20.0, 45.0, 70.0, 90.0])
def test_coefficient_sets_are_their_sources_formulas(alpha_deg):
    """Dickinson et al. 1999 in degrees: 0.225 + 1.58 sin(2.13 a - 7.20), 1.92 - 1.55
    cos(2.04 a - 9.82); Wang et al. 2004: 1.2 sin 2a, 1.4 - cos 2a (rounding only)."""
    a = math.radians(alpha_deg)
    d, w = COEFFICIENT_SETS["dickinson1999"], COEFFICIENT_SETS["wang2004"]
    s = math.radians
    assert d.lift(a) == pytest.approx(0.225 + 1.58 * math.sin(s(2.13 * alpha_deg - 7.20)), abs=1e-14)
    assert d.drag(a) == pytest.approx(1.92 - 1.55 * math.cos(s(2.04 * alpha_deg - 9.82)), abs=1e-14)
    assert w.lift(a) == pytest.approx(1.2 * math.sin(2 * a), abs=1e-14)
    assert w.drag(a) == pytest.approx(1.4 - math.cos(2 * a), abs=1e-14)


def test_terms_default_to_every_term_and_the_impulse_form():
    assert Terms() == Terms(True, True, True, "impulse")


# -- elements.py -------------------------------------------------------------------------------
@pytest.mark.parametrize("n, a, b", [(1, 0.3, 0.7), (2, 0.0, 0.0), (5, 0.5, -0.5), (8, 1.7, 0.4),
                                     (8, -0.4, 2.2), (12, 0.0, 0.0)])
def test_gauss_jacobi_against_scipy(n, a, b):
    """Nodes and weights against scipy's roots_jacobi (1e-13: eigenvalues of a symmetric
    matrix of O(1) entries), and the rule integrates x^(2n-1) against (1-x)^a (1+x)^b exactly
    (the closed form 2^(a+b+1) B(a+1, b+1) times the beta moments, via quad)."""
    x, w = gauss_jacobi(n, a, b)
    xs, ws = roots_jacobi(n, a, b)
    np.testing.assert_allclose(x, xs, rtol=0, atol=1e-13)
    np.testing.assert_allclose(w, ws, rtol=1e-12, atol=0)
    for j in (0, 2 * n - 1):
        want = quad(lambda t: t ** j, -1.0, 1.0, weight="alg", wvar=(b, a), epsabs=1e-14,
                    epsrel=1e-13)[0]
        assert float(np.sum(w * x ** j)) == pytest.approx(want, rel=1e-11, abs=1e-13)


def _chord(g, r):
    """Ellington's beta planform scaled to the wing area: c(r) = S / (R B(p, q)) rh^(p-1)
    (1 - rh)^(q-1), rh = r / R (scipy's beta function)."""
    rh = r / g.R
    return g.S_wing / (g.R * beta_fn(g.p, g.q)) * rh ** (g.p - 1.0) * (1.0 - rh) ** (g.q - 1.0)


def test_blade_elements_integrate_the_planform():
    """The span quadrature against the planform: sum cw = S_wing, sum cw r / S = r1 R,
    sum cw r^2 / S = (r2 R)^2 (a polynomial of degree 2 under the weight: exact to rounding,
    1e-13); each chord is c(r_i) (scipy's beta function); the roots are the hinge and its
    mirror in y."""
    g = GEOM
    e = blade_elements(g, Terms(), 8)
    S = g.S_wing
    assert float(np.sum(e.cw)) == pytest.approx(S, rel=1e-13)
    assert float(np.sum(e.cw * e.r)) / S == pytest.approx(g.r1_hat * g.R, rel=1e-13)
    assert float(np.sum(e.cw * e.r ** 2)) / S == pytest.approx((g.r2_hat * g.R) ** 2, rel=1e-13)
    np.testing.assert_allclose(e.chord, _chord(g, e.r), rtol=1e-13)
    np.testing.assert_array_equal(e.roots, [[g.hinge[0], -g.hinge[1], g.hinge[2]], g.hinge])
    assert np.all(np.diff(e.r) > 0) and e.r[0] > 0 and e.r[-1] < g.R


def test_added_mass_span_sums_against_quad():
    """The added mass m_a = rho (pi/4) c^2 dr, non-dimensional (forces over 0.5 rho U^2 S_t,
    lengths in c: (pi/2) k c^2 dr), and the mid-chord's lever arm k (1/2 - x0/c) c: the sums
    of m_a r^j (j = 0, 1, 2) and m_a mid r^j (j = 0, 1) against quad's integrals. The
    integrand c^2 is not a polynomial times the weight: with 40 elements the rule is within
    8e-7 of the integral (1.4e-4, 1.1e-5, 7.5e-7, 5.7e-8 at 10, 20, 40, 80 elements: it
    converges as n^-3.8), 1e-5 here.
    Without the term, every sum is 0."""
    g = GEOM
    sums = blade_elements(g, Terms(), 40).added_mass_sums
    k, mid = g.k, g.k * (0.5 - g.x0_hat)
    want = [quad(lambda r: 0.5 * math.pi * k * _chord(g, r) ** 2 * r ** j, 0.0, g.R,
                 epsrel=1e-12, limit=200)[0] for j in range(3)]
    want += [quad(lambda r: 0.5 * math.pi * k * mid * _chord(g, r) ** 3 * r ** j, 0.0, g.R,
                  epsrel=1e-12, limit=200)[0] for j in range(2)]
    np.testing.assert_allclose(sums, want, rtol=1e-5)
    assert blade_elements(g, Terms(added_mass=False), 8).added_mass_sums == (0.0,) * 5


# -- kinematics.py -----------------------------------------------------------------------------
def test_cross_is_numpys_cross_broadcast():
    rng = np.random.default_rng(1)
    a, b = rng.normal(size=(2, 4, 3)), rng.normal(size=(4, 3))
    np.testing.assert_allclose(kin.cross(a, b), np.cross(a, b), rtol=0, atol=1e-15)


def test_named_values_and_refusals():
    """Unnamed controls are 0, named ones floats; an unknown name or a value that is not
    finite is refused by name."""
    out = kin.controls_by_name({"delta_Phi": 1, "delta_alpha_2a": -0.5})
    assert out == {**{n: 0.0 for n in kin.CONTROLS}, "delta_Phi": 1.0, "delta_alpha_2a": -0.5}
    assert kin.controls_by_name(None) == {n: 0.0 for n in kin.CONTROLS}
    with pytest.raises(DroneflyError, match="control 'delta_x': expected one of delta_Phi_a"):
        kin.controls_by_name({"delta_x": 0.1})
    for bad in (math.nan, math.inf, -math.inf):
        with pytest.raises(DroneflyError, match="control delta_Phi = .* is not finite"):
            kin.controls_by_name({"delta_Phi": bad})


def _central(f, t, h=1e-6):
    """Central difference of f at t: error h^2 f''' / 6, about 1e-11 for these O(10^2)
    third derivatives, and rounding 1e-16 / h = 1e-10 times the values."""
    return (f(t + h) - f(t - h)) / (2 * h)


def test_rotation_profile_closed_form_and_derivatives():
    """tau - sin(2 pi tau) / (2 pi) inside the rotation (tau = (t - start) mod 1 over the
    duration), 0 derivatives and f = 1 outside; the derivatives in t against central
    differences (1e-8: see _central), across the wrap of t through 1."""
    start, dur = 0.85, 0.3
    t = np.array([0.86, 0.9, 0.99, 0.01, 0.1, 0.14, 0.2, 0.5, 0.84])
    f, df, ddf = kin.rotation_profile(t, start, dur)
    tau = np.mod(t - start, 1.0) / dur
    inside = tau < 1.0
    want = np.where(inside, tau - np.sin(2 * np.pi * tau) / (2 * np.pi), 1.0)
    np.testing.assert_allclose(f, want, rtol=0, atol=1e-15)
    assert list(inside) == [True] * 6 + [False] * 3
    np.testing.assert_allclose(df, _central(lambda s: kin.rotation_profile(s, start, dur)[0], t),
                               rtol=0, atol=1e-8)
    np.testing.assert_allclose(ddf, _central(lambda s: kin.rotation_profile(s, start, dur)[1], t),
                               rtol=0, atol=1e-6)


def test_stroke_closed_form_and_rate():
    """phi = phibar - (Phi / 2) cos(2 pi t) per wing, its rate against central differences."""
    t = np.linspace(0.03, 0.97, 9)
    Phi, phibar = np.array([1.8, 1.9]), np.array([0.1, -0.05])
    phi, dphi = kin.stroke(t, Phi, phibar)
    np.testing.assert_allclose(phi, phibar[:, None] - 0.5 * Phi[:, None] * np.cos(2 * np.pi * t),
                               rtol=0, atol=1e-15)
    np.testing.assert_allclose(dphi, _central(lambda s: kin.stroke(s, Phi, phibar)[0], t),
                               rtol=0, atol=1e-8)


def test_pitch_history():
    """psi = alpha_d in mid-downstroke ([0.15, 0.35]), pi - alpha_u in mid-upstroke ([0.65,
    0.85]), continuous through the rotations centred on t = 0.5 and 1, with the rotation
    profile (psi halfway at the reversal); the rate and acceleration against central
    differences; an instantaneous flip (no rotation) at t = 0.5 and 1."""
    ad, au = np.array([0.6, 0.5]), np.array([0.7, 0.4])
    t = np.array([0.02, 0.1, 0.15, 0.16, 0.25, 0.34, 0.4, 0.5, 0.6, 0.66, 0.75, 0.84, 0.9,
                  0.98])
    psi, dpsi, ddpsi = kin.pitch(t, 0.3, ad, au)
    up = np.pi - au
    # t = 0.15, the end of the rotation before the downstroke, included
    mid_down, mid_up = (t >= 0.15) & (t < 0.35), (t > 0.65) & (t < 0.85)
    np.testing.assert_array_equal(psi[:, mid_down], np.repeat(ad[:, None], mid_down.sum(), 1))
    np.testing.assert_array_equal(psi[:, mid_up], np.repeat(up[:, None], mid_up.sum(), 1))
    assert np.all(dpsi[:, mid_down | mid_up] == 0.0)
    np.testing.assert_allclose(psi[:, t == 0.5][:, 0], (ad + up) / 2, rtol=0, atol=1e-15)
    # in the rotation after the downstroke: psi = ad + (up - ad) (tau - sin(2 pi tau)/(2 pi))
    tau = (0.4 - 0.35) / 0.3
    np.testing.assert_allclose(psi[:, t == 0.4][:, 0],
                               ad + (up - ad) * (tau - math.sin(2 * math.pi * tau) / (2 * math.pi)),
                               rtol=0, atol=1e-15)
    tau = (0.98 - 0.85) / 0.3
    np.testing.assert_allclose(psi[:, t == 0.98][:, 0],
                               up - (up - ad) * (tau - math.sin(2 * math.pi * tau) / (2 * math.pi)),
                               rtol=0, atol=1e-15)
    # the derivatives away from the rotations' ends (t = 0.15: the third derivative jumps
    # there, and a central difference of dpsi is off by h times that jump, 1e-3)
    ts = t[t != 0.15]
    smooth = t != 0.15
    np.testing.assert_allclose(dpsi[:, smooth], _central(lambda s: kin.pitch(s, 0.3, ad, au)[0],
                                                         ts), rtol=0, atol=1e-8)
    np.testing.assert_allclose(ddpsi[:, smooth], _central(lambda s: kin.pitch(s, 0.3, ad, au)[1],
                                                          ts), rtol=0, atol=1e-6)
    psi0, dpsi0, ddpsi0 = kin.pitch(t, 0.0, ad, au)
    np.testing.assert_array_equal(psi0, np.where(t < 0.5, ad[:, None], up[:, None]))
    assert not np.any(dpsi0) and not np.any(ddpsi0)


def test_wing_kinematics_split_the_controls_as_the_paper_defines():
    """Sect. 2.1: dPhi_a raises Phi of the left wing by dPhi_a/2 and lowers the right's;
    dalpha_1a raises alpha_d and alpha_u of the left wing by half of it, lowers the right's;
    dalpha_2a raises alpha_d and lowers alpha_u of the left wing by half, the opposite on the
    right; the longitudinal ones act alike on both wings (dalpha_2: alpha_d up, alpha_u down
    by half)."""
    trim = Trim(alpha_d=0.6, alpha_u=0.5, phibar=0.05, residual=0.0)
    u = dict(delta_Phi_a=0.1, delta_alpha_1a=0.02, delta_alpha_2a=0.04, delta_Phi=0.3,
             delta_alpha_1=0.01, delta_phibar=0.07, delta_alpha_2=0.2)
    k = kin.wing_kinematics(GEOM, trim, u)
    P = GEOM.Phi_rad + 0.3
    np.testing.assert_allclose(k["Phi"], [P + 0.05, P - 0.05], rtol=0, atol=1e-15)
    np.testing.assert_allclose(k["phibar"], [0.12, 0.12], rtol=0, atol=1e-15)
    ad, au = 0.6 + 0.01 + 0.1, 0.5 + 0.01 - 0.1
    np.testing.assert_allclose(k["alpha_d"], [ad + 0.01 + 0.02, ad - 0.01 - 0.02], rtol=0,
                               atol=1e-15)
    np.testing.assert_allclose(k["alpha_u"], [au + 0.01 - 0.02, au - 0.01 + 0.02], rtol=0,
                               atol=1e-15)


def test_sampled_motion_is_the_flapping_of_each_element():
    """Each element sits at the root (the left one mirrored in y) plus r e_r, e_r the span
    direction at the stroke angle (forward positive on both wings), e_t perpendicular in the
    stroke plane; its flapping velocity k d(position)/dt (central differences) is vflap e_t;
    e_r and e_t are unit vectors."""
    r = np.array([0.5, 1.5, 3.0])
    t = np.array([0.1, 0.3, 0.6, 0.9])
    Phi, phibar = np.array([1.8, 1.9]), np.array([0.1, -0.05])
    ad, au = np.array([0.6, 0.5]), np.array([0.7, 0.4])
    m = kin.sampled_motion(GEOM, r, t, Phi, phibar, ad, au)
    phi, _ = kin.stroke(t, Phi, phibar)
    side = np.array([-1.0, 1.0])[:, None, None]
    np.testing.assert_allclose(m["Px"], GEOM.hinge[0] + np.sin(phi)[..., None] * r, atol=1e-15)
    np.testing.assert_allclose(m["Py"], side * (GEOM.hinge[1] + np.cos(phi)[..., None] * r),
                               atol=1e-15)
    np.testing.assert_allclose(np.broadcast_to(m["Pz"], m["Px"].shape), GEOM.hinge[2], atol=0)
    np.testing.assert_allclose(m["erx"] ** 2 + m["ery"] ** 2, 1.0, atol=1e-15)
    np.testing.assert_allclose(m["erx"] * m["etx"] + m["ery"] * m["ety"], 0.0, atol=1e-15)

    def pos(s):
        mm = kin.sampled_motion(GEOM, r, s, Phi, phibar, ad, au)
        return np.stack([mm["Px"], mm["Py"]])

    vel = GEOM.k * _central(pos, t)
    np.testing.assert_allclose(vel[0], m["vflap"] * m["etx"], rtol=0, atol=1e-8)
    np.testing.assert_allclose(vel[1], m["vflap"] * m["ety"], rtol=0, atol=1e-8)
    psi, dpsi, _ = kin.pitch(t, GEOM.rotation_fraction, ad, au)
    np.testing.assert_allclose(m["cpsi"][..., 0], np.cos(psi), atol=1e-15)
    np.testing.assert_allclose(m["spsi"][..., 0], np.sin(psi), atol=1e-15)
    np.testing.assert_array_equal(m["dpsi"][..., 0], dpsi)
    np.testing.assert_array_equal(m["side"][:, 0, 0], [-1.0, 1.0])


def test_a_wing_standing_still_at_the_reversal_feels_no_translational_or_rotational_load():
    """At the stroke reversal t+ = 0 (dphi = pi Phi sin 0 = 0 exactly) of a body at rest no
    element moves through the air: V = 0, so the translational lift and drag (proportional to
    |V|^2) and the rotational force (proportional to a_p x V) vanish there, exactly (a sum of
    products with a zero factor), whatever the pitch rate. Elsewhere in the cycle the loads
    are finite, and at the same reversal with the body moving they are finite and continuous
    in time: the forces at t+ = +-1e-7 bracket them to first order (their rate is O(1) per
    wing beat in the scaled units, so 1e-7 of it, times a margin of 10 for the second-order
    term and the moment arms of up to ~3 chords)."""
    g = GEOM
    terms = Terms(added_mass=False)
    e = blade_elements(g, terms, 8)
    coeffs = COEFFICIENT_SETS["dickinson1999"]
    Phi, phibar = np.array([1.8, 1.9]), np.array([0.1, -0.05])
    ad, au = np.array([0.6, 0.5]), np.array([0.7, 0.4])

    def loads(t, state):
        m = kin.sampled_motion(g, e.r, np.asarray(t, dtype=float), Phi, phibar, ad, au)
        return sampled_cycle_forces(m, np.asarray(state, dtype=float), g, terms, coeffs, e, len(t))

    t = [0.0, 0.25, 0.5, 0.75]
    m = kin.sampled_motion(g, e.r, np.asarray(t), Phi, phibar, ad, au)
    assert np.all(m["vflap"][:, 0, :] == 0.0) and np.all(m["dpsi"][:, 0, 0] != 0.0)
    at_rest = loads(t, np.zeros(6))
    assert np.all(np.isfinite(at_rest))
    np.testing.assert_array_equal(at_rest[:, 0], np.zeros(6))
    assert np.all(np.abs(at_rest[:, 1]) > 0.0)  # mid-stroke: lift, drag and their moments
    moving = np.array([0.3, -0.2, 0.1, 0.05, -0.04, 0.03])
    mid = loads([0.0], moving)[:, 0]
    before, after = loads([-1e-7], moving)[:, 0], loads([1e-7], moving)[:, 0]
    assert np.all(np.isfinite(mid)) and np.abs(mid).max() > 0.0
    np.testing.assert_allclose(mid, 0.5 * (before + after), rtol=0, atol=1e-6)


# -- trim.py -------------------------------------------------------------------------------------
Z_STAR = np.array([0.6, 0.5, 0.1])  # the root of the synthetic forces below: alpha_d, alpha_u, phibar
W = 2.5


class Forces:
    """Cycle-averaged forces with a known trim at Z_STAR: X, Z + W, M are a well-conditioned
    linear map of (z - Z_STAR) plus ``c`` times its squares (Newton converges quadratically);
    Y, L, N are constants. Counts its calls."""

    def __init__(self, c=0.3):
        self.c, self.calls = c, 0
        self.A = np.array([[1.0, 0.2, -0.3], [0.1, -1.5, 0.2], [0.3, 0.1, 0.8]])

    def __call__(self, ad, au, pb):
        self.calls += 1
        d = np.array([ad, au, pb]) - Z_STAR
        x, z, m = self.A @ d + self.c * d * d
        return np.array([x, 0.01, z - W, 0.02, m, 0.03])


def test_solve_trim_finds_the_root_of_the_forces():
    """Newton from (30 deg, 30 deg, 0) finds the known root (the map's Jacobian has condition
    number about 3: a residual below 1e-12 of W puts the angles within 1e-11), reports its
    residual over W and the forces there by name, and converges quadratically: at most 6
    Newton steps of 7 evaluations each (a central-difference Jacobian)."""
    from dronefly.models.quasisteady.trim import solve_trim
    f = Forces()
    tr = solve_trim(f, W, "test")
    assert (tr.alpha_d, tr.alpha_u, tr.phibar) == pytest.approx(tuple(Z_STAR), abs=1e-11)
    assert 0.0 <= tr.residual < 1e-12
    assert tr.forces == pytest.approx(dict(X=0.0, Y=0.01, Z=-W, L=0.02, M=0.0, N=0.03),
                                      abs=1e-11)
    assert f.calls <= 1 + 6 * 7 + 1
    j = tr.to_json()
    assert j["alpha_d_deg"] == pytest.approx(0.6 * 180 / math.pi, rel=1e-11)
    assert j["alpha_u_deg"] == pytest.approx(0.5 * 180 / math.pi, rel=1e-11)
    assert j["phibar_deg"] == pytest.approx(0.1 * 180 / math.pi, rel=1e-10)
    assert j["residual_over_weight"] == tr.residual and j["Y_plus"] == tr.forces["Y"]


def test_solve_trim_of_an_affine_map_takes_one_step():
    """For forces affine in the angles the central-difference Jacobian is exact but for
    rounding, 1e-16 / h = 1e-10 of it (h = 1e-6): the first Newton step leaves about 1e-10
    of the residual (O(1)), above tol = 1e-12, the second one rounding: 2 steps of 7
    evaluations, the first one and one more for the forces at trim."""
    from dronefly.models.quasisteady.trim import solve_trim
    f = Forces(c=0.0)
    tr = solve_trim(f, W, "test")
    assert f.calls == 1 + 2 * 7 + 1
    assert (tr.alpha_d, tr.alpha_u, tr.phibar) == pytest.approx(tuple(Z_STAR), abs=1e-11)


def test_solve_trim_refusals():
    """Forces that do not depend on the angles (a singular Jacobian); a root outside
    0 < alpha < 90 deg; too few Newton steps: each refused by its message, naming the model."""
    from dronefly.models.quasisteady.trim import solve_trim
    with pytest.raises(DroneflyError, match=r"do not depend on the angles of attack \(flat\)"):
        solve_trim(lambda a, b, c: np.array([0.1, 0.0, -1.0, 0.0, 0.2, 0.0]), W, "flat")
    for bad in ([-0.2, 0.5, 0.1], [0.6, 1.7, 0.1], [0.6, 0.5, 1.65], [0.6, 0.5, -1.65]):
        Z = np.array(bad)

        def shifted(ad, au, pb, Z=Z):
            d = np.array([ad, au, pb]) - Z
            return np.array([d[0], 0.0, d[1] - W, 0.0, d[2], 0.0])

        with pytest.raises(DroneflyError, match=r"no trim with angles .*\(out\)"):
            solve_trim(shifted, W, "out")
    with pytest.raises(DroneflyError, match=r"trim did not converge: residual .* \(slow\)"):
        solve_trim(Forces(c=3.0), W, "slow", max_iter=2)
    with pytest.raises(DroneflyError, match="no trim|did not converge"):
        solve_trim(lambda a, b, c: np.full(6, np.nan), W, "nan")

    # forces that are nan beyond alpha_d = 1 rad: the first step (towards the root at 1.2
    # rad) lands there; Newton stops at that finite angle and says its residual is nan
    def beyond(ad, au, pb):
        d = np.array([ad, au, pb]) - np.array([1.2, 0.5, 0.1])
        out = np.array([d[0], 0.0, d[1] - W, 0.0, d[2], 0.0])
        return out * np.nan if ad > 1.0 else out

    with pytest.raises(DroneflyError, match=r"did not converge: residual nan of the weight"):
        solve_trim(beyond, W, "nan beyond")


# -- model.py ------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def qs_model():
    from dronefly.models.quasisteady import QuasiSteadyModel
    return QuasiSteadyModel(n_span=4, n_time=20)


@pytest.mark.parametrize("kwargs, fragment", [
    (dict(coefficients="robofly"), "coefficients 'robofly': expected one of dickinson1999"),
    (dict(n_time=19), "n_time = 19 must be an even number >= 20"),
    (dict(n_time=21), "n_time = 21 must be an even"),
    (dict(n_time=18), "n_time = 18 must be an even"),
    (dict(n_span=1), "n_span = 1 must be >= 2"),
    (dict(terms=Terms(added_mass_form="x")), "added_mass_form 'x': expected sane2001 or impulse"),
])
def test_model_refuses_bad_options(kwargs, fragment):
    from dronefly.models.quasisteady import QuasiSteadyModel
    with pytest.raises(DroneflyError, match=fragment):
        QuasiSteadyModel(**kwargs)


def test_model_accepts_the_smallest_grid_and_both_added_mass_forms():
    """n_time = 20 and n_span = 2 are allowed (the bounds are inclusive), sane2001 too; a
    coefficient set may be given as the object; the options are kept."""
    from dronefly.models.quasisteady import QuasiSteadyModel
    m = QuasiSteadyModel(COEFFICIENT_SETS["wang2004"], Terms(added_mass_form="sane2001"),
                         n_span=2, n_time=20)
    assert (m.coefficients.name, m.terms.added_mass_form, m.n_span, m.n_time) == \
        ("wang2004", "sane2001", 2, 20)
    assert len(m.elements.r) == 2
    assert m.geometry == GEOM


@pytest.mark.parametrize("state", [[0.0] * 5, [0.0] * 7, [0.0] * 5 + [math.nan],
                                   [math.inf] + [0.0] * 5])
def test_model_refuses_a_state_that_is_not_six_finite_numbers(qs_model, state):
    with pytest.raises(DroneflyError, match="expected 6 finite numbers"):
        qs_model.forces_vector(state)
    with pytest.raises(DroneflyError, match="expected 6 finite numbers"):
        qs_model.forces_over_cycle(state)


def test_model_refusals_of_controls_and_angles(qs_model):
    with pytest.raises(DroneflyError, match="expected 7 values"):
        qs_model.state_function((0.0,) * 6)
    with pytest.raises(DroneflyError, match=r"expected \(6, 2\) and \(6,\)"):
        qs_model.forces_at(np.zeros((6, 3)))
    with pytest.raises(DroneflyError, match=r"expected \(6, 2\) and \(6,\)"):
        qs_model.forces_at(np.zeros((6, 2)), (0.0,) * 5)


def test_model_paths_agree_and_the_caches_follow_the_kinematics(qs_model):
    """A state by name is the state by position; the state function of the controls gives
    forces_vector at those controls; after other controls, forces at the first ones are again
    those of a fresh model (the caches of the wing motion follow the kinematics); the
    cycle average of the element-by-element samples (forces_over_cycle, without the added
    mass, whose sampled derivatives differ at O(1/n_time^2)) is the cycle average to
    rounding (1e-12 of the weight); the trim is computed once."""
    from dronefly.models.quasisteady import QuasiSteadyModel
    x = [0.01, -0.02, 0.015, 0.03, -0.01, 0.02]
    u1, u2 = dict(delta_Phi_a=0.05, delta_alpha_1=0.02), dict(delta_phibar=-0.04)
    by_name = dict(zip(("delta_u", "delta_v", "delta_w", "delta_p", "delta_q", "delta_r"), x))
    f1 = qs_model.forces_vector(x, u1)
    np.testing.assert_array_equal(qs_model.forces_vector(by_name, u1), f1)
    f2 = qs_model.forces_vector(x, u2)
    fresh = QuasiSteadyModel(n_span=4, n_time=20)
    np.testing.assert_allclose(fresh.forces_vector(x, u2), f2, rtol=1e-13, atol=1e-15)
    np.testing.assert_allclose(qs_model.forces_vector(x, u1), fresh.forces_vector(x, u1),
                               rtol=1e-13, atol=1e-15)
    c = [u1.get(n, 0.0) for n in kin.CONTROLS]
    np.testing.assert_allclose(qs_model.state_function(c)(np.array(x)), f1, rtol=1e-13,
                               atol=1e-15)
    assert qs_model.trim() is qs_model.trim()
    plain = qs_model.with_options(terms=Terms(added_mass=False))
    assert (plain.n_span, plain.n_time, plain.terms.added_mass) == (4, 20, False)
    tr = qs_model.trim()
    for u in (u1, u2):
        samples = plain.forces_over_cycle(x, u, trim=tr)
        assert samples.shape == (6, 20)
        np.testing.assert_allclose(samples.mean(axis=1), plain.forces_vector(x, u, trim=tr),
                                   rtol=0, atol=1e-12 * GEOM.weight)
    again = plain.forces_over_cycle(x, u1, trim=tr)
    np.testing.assert_allclose(again.mean(axis=1), plain.forces_vector(x, u1, trim=tr),
                               rtol=0, atol=1e-12 * GEOM.weight)


def test_model_kinematics_use_the_trim_given(qs_model):
    """wing_kinematics with an explicit trim: its angles (not the model's trim) plus the
    controls."""
    tr = Trim(alpha_d=0.7, alpha_u=0.6, phibar=0.02, residual=0.0)
    k = qs_model.wing_kinematics({"delta_alpha_1": 0.01}, trim=tr)
    np.testing.assert_allclose(k["alpha_d"], [0.71, 0.71], rtol=0, atol=1e-15)
    np.testing.assert_allclose(k["phibar"], [0.02, 0.02], rtol=0, atol=1e-15)


# -- the Sect. 2.4 data, the dataclasses, the trim's start, floor and messages -----------------
def test_body_data_are_the_papers_section_2_4():
    """Sect. 2.4: l_b = 14.11 mm, roots 0.33 l_b apart, l1 = 0.13 l_b, chi0 = 52 deg,
    chi = 42 deg, Delta t_r 30 % of the cycle, Re = 781.6 (printed values)."""
    assert BODY_DATA == {"l_b": 14.11e-3, "root_spacing_over_lb": 0.33, "l1_over_lb": 0.13,
                         "chi0_deg": 52.0, "chi_deg": 42.0, "rotation_fraction": 0.30,
                         "Re": 781.6}


def test_geometry_defaults_are_the_papers_rotation_and_no_weight():
    """A geometry given without them has the pitch axis at c/4, the rotation of 30 % of the
    cycle (Sect. 2.4) and no weight (W+ = 0: what it does not know)."""
    g = WingGeometry(R=3.8, r2_hat=0.55, r1_hat=0.49, p=1.2, q=1.3, S_wing=3.75, Phi_rad=1.87,
                     k=0.2, hinge=(0.1, 0.8, -0.6))
    assert (g.x0_hat, g.rotation_fraction, g.weight) == (0.25, 0.3, 0.0)


@pytest.mark.parametrize("make, field", [
    (lambda: COEFFICIENT_SETS["wang2004"], "name"), (Terms, "rotational"),
    (lambda: GEOM, "R"), (lambda: Trim(0.6, 0.5, 0.0, 0.0), "alpha_d")])
def test_options_and_results_are_frozen(make, field):
    """The coefficient sets, terms, geometry and trim are values (the models key their caches
    and reuse on them): a field cannot be reassigned."""
    import dataclasses
    with pytest.raises(dataclasses.FrozenInstanceError):
        setattr(make(), field, None)


def test_solve_trim_starts_from_30_30_0():
    """The documented start of Newton's method: alpha_d = alpha_u = 30 deg, phibar = 0."""
    from dronefly.models.quasisteady.trim import solve_trim
    seen = []

    def f(ad, au, pb):
        seen.append((ad, au, pb))
        return Forces(c=0.0)(ad, au, pb)

    solve_trim(f, W, "test")
    assert seen[0] == (math.radians(30.0), math.radians(30.0), 0.0)


def test_solve_trim_accepts_a_rounding_floor_after_its_newton_steps():
    """X with a jump of 2 a W where alpha_d crosses its root (+a W above, -a W below): the
    forces have no root (A^-1[0, 0] = 0.90 > 0 puts the root of either side on the other),
    so the residual stays of the order of a (as rounding would keep it): with a = 2e-11
    Newton takes all its 30 steps (default max_iter; 7 evaluations each, one first and one
    for the forces at trim) and the result is accepted, its residual between tol = 1e-12 and
    the floor of 1e-9 of W; with a = 1e-8 it is not."""
    from dronefly.models.quasisteady.trim import solve_trim

    def noisy(amplitude):
        f = Forces(c=0.0)

        def mean(ad, au, pb):
            out = f(ad, au, pb)
            out[0] += math.copysign(amplitude * W, ad - 0.6)
            return out
        return f, mean

    f, mean = noisy(2e-11)
    tr = solve_trim(mean, W, "noisy")
    assert f.calls == 1 + 30 * 7 + 1
    assert 1e-12 <= tr.residual < 1e-9
    # the residual reported is that of the forces at trim, max |X, Z + W, M| over W: the
    # same forces at the same angles (an ulp for the division)
    F = tr.forces
    assert tr.residual == pytest.approx(max(abs(F["X"]), abs(F["Z"] + W), abs(F["M"])) / W,
                                        rel=1e-15)
    assert tr.alpha_d == pytest.approx(0.6, abs=1e-9)
    _, mean = noisy(1e-8)
    with pytest.raises(DroneflyError, match="trim did not converge"):
        solve_trim(mean, W, "noisy")


@pytest.mark.parametrize("root", [[0.6, 1.7, 0.1], [0.6, -0.2, 0.1], [1.7, 0.5, 0.1],
                                  [1.2, 0.5, -0.3], [0.6, 1.2, 0.1], [0.6, 0.5, 1.2],
                                  [0.6, 0.5, -1.2]])
def test_solve_trim_names_where_newton_ended_outside_the_angles(root):
    """A root with an angle of attack outside (0, 90) deg is refused, the message giving
    the angles Newton ended at (the root: 4 significant digits, read back as numbers); roots
    with an angle of 69 deg (alpha_d, alpha_u, +-phibar: within) are accepted."""
    from dronefly.models.quasisteady.trim import solve_trim
    Z = np.array(root)

    def shifted(ad, au, pb):
        d = np.array([ad, au, pb]) - Z
        return np.array([d[0], 0.0, d[1] - W, 0.0, d[2], 0.0])

    if all(0.0 < a < math.pi / 2 for a in root[:2]):
        tr = solve_trim(shifted, W, "in")
        assert (tr.alpha_d, tr.alpha_u, tr.phibar) == pytest.approx(root, abs=1e-11)
        return
    with pytest.raises(DroneflyError, match="no trim with angles") as info:
        solve_trim(shifted, W, "out")
    import re
    got = [float(v) for v in re.findall(r"= (-?[0-9.]+) deg", str(info.value))]
    assert got == pytest.approx(np.degrees(root), rel=6e-4)  # 4 significant digits


def test_forces_at_a_sample_are_the_element_by_element_forces(qs_model):
    """forces_at, at the angles of this model's kinematics at a sample t = (j + 1/2) / n_time
    (phi, its rate and its acceleration 2 pi^2 Phi cos 2 pi t in closed form, psi from
    ``pitch``), is the element-by-element sample of forces_over_cycle (without the added
    mass, whose sampled derivatives are central differences): two evaluations of the same
    terms, to rounding (1e-12 of the weight). Its default state is hover (zeros), and the
    state function's default controls are none (those of forces_vector without controls)."""
    plain = qs_model.with_options(terms=Terms(added_mass=False))
    tr = qs_model.trim()
    x = np.array([0.01, -0.02, 0.015, 0.03, -0.01, 0.02])
    u = dict(delta_Phi_a=0.05, delta_alpha_2=0.02)
    k = plain.wing_kinematics(u, trim=tr)
    samples = plain.forces_over_cycle(x, u, trim=tr)
    zero = plain.forces_over_cycle(np.zeros(6), u, trim=tr)
    for j in (3, 14):
        t = np.array([(j + 0.5) / 20])
        phi, dphi = kin.stroke(t, k["Phi"], k["phibar"])
        ddphi = 2 * np.pi ** 2 * k["Phi"][:, None] * np.cos(2 * np.pi * t)
        psi, dpsi, ddpsi = kin.pitch(t, GEOM.rotation_fraction, k["alpha_d"], k["alpha_u"])
        angles = np.concatenate([phi, dphi, ddphi, psi, dpsi, ddpsi], axis=1).T  # (6, 2)
        np.testing.assert_allclose(plain.forces_at(angles, x), samples[:, j], rtol=0,
                                   atol=1e-12 * GEOM.weight)
        np.testing.assert_allclose(plain.forces_at(angles), zero[:, j], rtol=0,
                                   atol=1e-12 * GEOM.weight)
    np.testing.assert_array_equal(qs_model.state_function()(x), qs_model.state_function(
        (0.0,) * 7)(x))
    np.testing.assert_allclose(qs_model.state_function()(x), qs_model.forces_vector(x),
                               rtol=1e-13, atol=1e-15)


def test_instants_refuse_angles_of_another_shape_and_the_other_added_mass_form(qs_model):
    """The blade-element instants (models/quasisteady/instantaneous.py) take angles of shape
    (6, 2) or (T, 6, 2) only, and the impulse form of the added mass only where the added mass
    is on (the cycle-averaged path has Sane's form too): a (T, 6, 3) stack and Sane's form are
    refused by name, and without added mass Sane's form is no matter."""
    import dataclasses

    from dronefly.models.quasisteady.instantaneous import instants

    m = qs_model
    args = (m.geometry, m.terms, m.coefficients, m.elements)
    with pytest.raises(DroneflyError, match=r"angles of shape \(1, 6, 3\)"):
        instants(np.zeros((1, 6, 3)), *args)
    sane = dataclasses.replace(m.terms, added_mass=True, added_mass_form="sane2001")
    with pytest.raises(DroneflyError, match="impulse form of the added mass only"):
        instants(np.zeros((6, 2)), m.geometry, sane, m.coefficients, m.elements)
    off = dataclasses.replace(m.terms, added_mass=False, added_mass_form="sane2001")
    assert len(instants(np.zeros((2, 6, 2)), m.geometry, off, m.coefficients, m.elements)) == 2
