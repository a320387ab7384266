"""The quasi-steady blade-element model (dronefly.aero): exact symmetries, closed forms, trim,
and the convergence of its central-difference derivatives."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest

from dronefly.aero import QuasiSteadyModel, Terms, Trim, WingGeometry
from dronefly.aero.compare import ackermann, derivatives, eigenvalues, parity_report
from dronefly.aero.quasisteady import COEFFICIENT_SETS, CONTROLS, FORCES, STATES
from dronefly.cli import main
from dronefly.errors import DroneflyError

pytestmark = pytest.mark.numeric

LATERAL_OUT = [FORCES.index(f) for f in "YLN"]
LONGITUDINAL_OUT = [FORCES.index(f) for f in "XZM"]


@pytest.fixture(scope="module")
def model() -> QuasiSteadyModel:
    m = QuasiSteadyModel()
    m.trim()
    return m


@pytest.mark.parametrize("coefficients", sorted(COEFFICIENT_SETS))
def test_trim_balances_the_weight_and_the_lateral_forces_vanish(coefficients):
    m = QuasiSteadyModel(coefficients)
    tr = m.trim()
    W = m.geometry.weight
    f = m.forces_vector()
    # the acceptance bound: X, Z + W, M below 1e-6 of the weight
    assert abs(f[0]) < 1e-6 * W and abs(f[2] + W) < 1e-6 * W and abs(f[4]) < 1e-6 * W
    assert tr.residual < 1e-6
    # mirror symmetry of the two wings: Y, L, N cancel to round-off (sums of ~1e2 terms of
    # order 1: 1e-12 W is a thousand ulps)
    assert np.all(np.abs(f[LATERAL_OUT]) < 1e-12 * W)
    assert 0.0 < tr.alpha_d < math.pi / 2 and 0.0 < tr.alpha_u < math.pi / 2


@pytest.mark.parametrize("name", ["delta_v", "delta_p", "delta_r", "delta_Phi_a",
                                  "delta_alpha_1a", "delta_alpha_2a"])
def test_lateral_forces_are_odd_and_longitudinal_even_in_a_lateral_input(model, name):
    def at(value):
        if name in STATES:
            x = np.zeros(6)
            x[STATES.index(name)] = value
            return model.forces_vector(x)
        return model.forces_vector(np.zeros(6), {name: value})

    plus, minus = at(0.2), at(-0.2)
    scale = model.geometry.weight
    # a lateral disturbance mirrors to its negative: Y, L, N change sign, X, Z, M do not,
    # exactly up to the round-off of the mirrored sums
    np.testing.assert_allclose(plus[LATERAL_OUT], -minus[LATERAL_OUT], rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(plus[LONGITUDINAL_OUT], minus[LONGITUDINAL_OUT], rtol=0,
                               atol=1e-12 * scale)
    assert np.max(np.abs(plus[LATERAL_OUT])) > 1e-3  # and it does act on the lateral forces


def _constant_aoa(coefficients: str, n_time: int = 200, **geometry) -> QuasiSteadyModel:
    """Translation only, the wing flipping instantly at the reversals (no rotation phase)."""
    g = replace(WingGeometry.from_flight_data(), rotation_fraction=0.0, **geometry)
    return QuasiSteadyModel(coefficients, Terms(rotational=False, added_mass=False),
                            n_time=n_time, geometry=g)


@pytest.mark.parametrize("coefficients", sorted(COEFFICIENT_SETS))
def test_mean_lift_at_constant_angle_of_attack_is_the_second_moment_closed_form(coefficients):
    """A wing at constant alpha, a harmonic stroke, no body motion: the velocity at r is
    r dphi/dt, so mean lift = CL(alpha) * 0.5 rho S r2^2 mean(dphi/dt^2); over
    0.5 rho U^2 S_t with U = 2 Phi n r2 this is CL(alpha) pi^2/8 for both wings."""
    alpha = math.radians(35.0)
    m = _constant_aoa(coefficients)
    f = m.forces_vector(trim=Trim(alpha, alpha, 0.0, 0.0))
    cl = float(COEFFICIENT_SETS[coefficients].lift(np.array(alpha)))
    # Gauss-Jacobi integrates r^2 c(r) exactly, the midpoint rule sin^2 exactly: round-off only
    assert f[2] == pytest.approx(-cl * math.pi**2 / 8, rel=1e-12)
    assert abs(f[0]) < 1e-12 and abs(f[1]) < 1e-12


def test_flapping_counter_torque_against_its_closed_form():
    """Roots on the yaw axis, constant alpha: a yaw rate w adds -/+ k w r along each wing's
    stroke, so N = -2 CD k^2 I3/S_t g(w), g(w) = mean (a + w)|a + w| over a = A sin, A = pi Phi,
    g(w) = (4/pi) [(3w/4) sqrt(A^2 - w^2) + (A^2/4 + w^2/2) asin(w/A)], linear to O(w^3/A^2)
    (the counter-torque of Hedrick, Cheng & Deng 2009)."""
    alpha = math.radians(35.0)
    m = _constant_aoa("dickinson1999", n_time=4000, hinge=(0.0, 0.0, 0.0))
    g = m.geometry
    A = math.pi * g.Phi_rad
    # third moment of area of the beta planform: S R^3 E[r^3] of Beta(p, q)
    p, q = g.p, g.q
    I3 = g.S_wing * g.R**3 * p * (p + 1) * (p + 2) / ((p + q) * (p + q + 1) * (p + q + 2))
    cd = float(COEFFICIENT_SETS["dickinson1999"].drag(np.array(alpha)))
    for w in (0.05, 0.1, 0.3):
        gw = 4 / math.pi * (0.75 * w * math.sqrt(A * A - w * w)
                            + (A * A / 4 + w * w / 2) * math.asin(w / A))
        expected = -2 * cd * g.k**2 * I3 / (2 * g.S_wing) * gw
        N = m.forces({"delta_r": w}, trim=Trim(alpha, alpha, 0.0, 0.0))["N"]
        # the midpoint rule on |a + w| (a kink at each zero crossing): error O(dt^2) = 6e-8,
        # relative; 1e-6 leaves room
        assert N == pytest.approx(expected, rel=1e-6)
        # and the linear counter-torque -(8/pi) CD k^2 A I3/S_t w holds to (w/A)^2
        linear = -(8 / math.pi) * cd * g.k**2 * A * I3 / (2 * g.S_wing) * w
        assert N == pytest.approx(linear, rel=(w / A) ** 2)


@pytest.mark.parametrize("name,force", [("delta_v", "L"), ("delta_Phi_a", "L"),
                                        ("delta_alpha_2a", "N"), ("delta_alpha_1", "Z")])
def test_central_differences_converge_at_second_order(model, name, force):
    i = FORCES.index(force)
    hs = (0.04, 0.02, 0.01, 0.005)
    d = [derivatives(model, h, (name,))[name][i] for h in hs]
    ratios = [(d[j] - d[j + 1]) / (d[j + 1] - d[j + 2]) for j in range(2)]
    # error ~ c2 h^2 (+ c3 |h|^3 from the folding of alpha where the velocity passes the
    # chord line at the reversals): successive differences shrink by 4 (up to 5.5 observed)
    assert all(3.5 < r < 6.0 for r in ratios), ratios


def test_derivatives_against_a_finer_grid_and_richardson(model):
    fine = QuasiSteadyModel(n_span=32, n_time=800)
    fine.trim()
    names = ("delta_v", "delta_p", "delta_r", "delta_u", "delta_w", "delta_q", *CONTROLS)
    d = derivatives(model, 1e-3, names)
    df = derivatives(fine, 1e-3, names)
    for name in names:
        scale = np.max(np.abs(df[name]))
        # the 200-sample cycle and 20 elements against 800 and 32: the midpoint rule's
        # O(dt^2) = 2.5e-5 and the round-off of the steps; 1 % of the largest derivative
        assert np.max(np.abs(d[name] - df[name])) < 1e-2 * scale, name
    # Richardson extrapolation from steps 0.02 and 0.01 agrees with the 1e-3 step
    d1 = derivatives(model, 0.01, ("delta_Phi_a", "delta_alpha_2a"))
    d2 = derivatives(model, 0.02, ("delta_Phi_a", "delta_alpha_2a"))
    for name in d1:
        rich = (4 * d1[name] - d2[name]) / 3
        np.testing.assert_allclose(rich, d[name], rtol=0, atol=1e-6 * np.max(np.abs(d[name])))


def test_paper_derivatives_give_the_papers_eigenvalues():
    from dronefly.harness.paper.values import table2_eigenvalues
    from dronefly.plant.model import default_parameters
    from dronefly.plant_longitudinal.model import default_parameters as lon

    values = {**default_parameters().__dict__, **lon().__dict__}
    ev = eigenvalues(values)
    # Table 2 is printed to 3 decimals
    np.testing.assert_allclose(ev["lateral"], table2_eigenvalues(), atol=1e-3)
    assert ev["longitudinal"][0].real == pytest.approx(0.0481, abs=1e-4)


def test_ackermann_against_the_harness_design():
    from dronefly.harness.paper.analysis import ackermann_gains
    from dronefly.plant.model import default_parameters, system_matrices

    A, B = system_matrices(default_parameters())
    targets = [0.0, -0.089 + 0.057j, -0.089 - 0.057j, -0.51]
    np.testing.assert_allclose(ackermann(A, B[:, 0], targets),
                               np.ravel(ackermann_gains(A, B, targets, 0)), rtol=1e-9)


def test_report_json_has_the_schema(model):
    r = parity_report(model).to_json()
    assert r["coefficients"] == "dickinson1999"
    assert set(r["derivatives"]["Lp_plus"]) == {"quasi_steady", "paper"}
    assert len(r["derivatives"]) == 9 + 9 + 9 + 12
    assert set(r["eigenvalues"]) == {"lateral", "longitudinal"}
    assert len(r["eigenvalues"]["lateral"]["quasi_steady"]) == 4


def test_cli_forces_json_and_bad_input(capsys):
    assert main(["aero", "forces", "--state", "delta_v=0.1", "--control", "delta_Phi_a=0.2",
                 "--no-rotational", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert set(out) == set(FORCES)
    assert main(["aero", "forces", "--state", "delta_x=0.1"]) == 2
    assert "delta_x" in capsys.readouterr().err
    assert main(["aero", "--coefficients", "nope"]) == 2
    assert "nope" in capsys.readouterr().err
    with pytest.raises(DroneflyError):
        QuasiSteadyModel(n_time=7)
