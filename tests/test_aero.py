"""The quasi-steady blade-element model (dronefly.harness.aero): exact symmetries, closed forms, trim,
and the convergence of its central-difference derivatives."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest

from dronefly.harness.aero import QuasiSteadyModel, Terms, Trim, WingGeometry
from dronefly.harness.aero.beside_paper import (LATERAL_PARAMETERS, closed_loop, derivatives, eigenvalues,
                                                parity_report, matrices_with_derivatives)
from dronefly.models import lateral_dynamics
from dronefly.models.quasisteady import COEFFICIENT_SETS, CONTROLS, FORCES, STATES
from dronefly.cli.app import main
from dronefly.core.errors import DroneflyError

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


def test_cycle_average_equals_the_mean_of_the_instantaneous_forces(model):
    """Two evaluations of the same model: the cycle average through the state-independent
    maps and by parts (``forces_vector``) and the instantaneous forces element by element
    (``forces_over_cycle``). Translation and rotation are the same sums rearranged; the added
    mass differs by the central differences' O(1/n_time^2)."""
    x = (0.1, 0.15, -0.1, 0.1, 0.05, -0.12)
    u = {"delta_Phi_a": 0.2, "delta_alpha_2a": 0.1, "delta_phibar": 0.1}
    W = model.geometry.weight
    for form in ("impulse", "sane2001"):
        m = QuasiSteadyModel(terms=Terms(added_mass=False, added_mass_form=form), n_time=400)
        a = m.forces_vector(x, u, trim=model.trim())
        # the same sums in another order: round-off (1e-12 W)
        np.testing.assert_allclose(a, m.forces_over_cycle(x, u, trim=model.trim()).mean(axis=1),
                                   rtol=0, atol=1e-12 * W)
        errs = []
        for nt in (400, 800):
            am = _added_mass_only(form, n_time=nt)
            errs.append(np.max(np.abs(am.forces_vector(x, u, trim=model.trim())
                                      - am.forces_over_cycle(x, u, trim=model.trim()).mean(axis=1))))
        # the difference is the central differences' error: second order (ratio 4 on halving)
        assert 3.5 < errs[0] / errs[1] < 4.5, errs


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
        N = m.forces_vector({"delta_r": w}, trim=Trim(alpha, alpha, 0.0, 0.0))[FORCES.index("N")]
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
        # the default grid (8 elements, 100 samples) against 32 and 800: the accuracy it was
        # chosen for, 0.1 % of the input's largest derivative (the finer grid's own error,
        # O(dt^2), is 64 times smaller)
        assert np.max(np.abs(d[name] - df[name])) < 1e-3 * scale, name
    # Richardson extrapolation from steps 0.02 and 0.01 agrees with the 1e-3 step
    d1 = derivatives(model, 0.01, ("delta_Phi_a", "delta_alpha_2a"))
    d2 = derivatives(model, 0.02, ("delta_Phi_a", "delta_alpha_2a"))
    for name in d1:
        rich = (4 * d1[name] - d2[name]) / 3
        np.testing.assert_allclose(rich, d[name], rtol=0, atol=1e-6 * np.max(np.abs(d[name])))


def test_paper_derivatives_give_the_papers_eigenvalues():
    from dronefly.harness.paper.printed import table2_eigenvalues
    from dronefly.models.lateral_dynamics import default_parameters
    from dronefly.models.longitudinal_dynamics import default_parameters as lon

    values = {**default_parameters().__dict__, **lon().__dict__}
    ev = eigenvalues(values)
    # Table 2 is printed to 3 decimals
    np.testing.assert_allclose(ev["lateral"], table2_eigenvalues(), atol=1e-3)
    assert ev["longitudinal"][0].real == pytest.approx(0.0481, abs=1e-4)


def test_matched_gains_against_python_control(model):
    """The matched design of ``closed_loop`` (Ackermann's formula, harness.paper.analysis)
    against python-control's ``acker`` (u = -K x there): the same gains to 1e-9 relative
    (both solve the same 4 x 4 controllability system, condition ~1e4 here)."""
    import control

    d = derivatives(model)
    values = {p: float(d[i][FORCES.index(F)]) for p, F, i in LATERAL_PARAMETERS}
    (A1q, B1q), _ = matrices_with_derivatives(values)
    c = closed_loop(values)
    theirs = -np.asarray(control.acker(A1q, B1q[:, [0]], c["targets"])).ravel()
    np.testing.assert_allclose(c["matched_gains"], theirs, rtol=1e-9)


def test_report_json_has_the_schema(model):
    r = parity_report(model).to_json()
    assert r["coefficients"] == "dickinson1999"
    assert {"quasi_steady", "paper"} <= set(r["derivatives"]["Lp_plus"])
    parts = r["derivatives"]["Lp_plus"]["terms"]
    assert sum(parts.values()) == pytest.approx(r["derivatives"]["Lp_plus"]["quasi_steady"],
                                                abs=1e-9)
    assert len(r["derivatives"]) == 9 + 9 + 9 + 12
    assert set(r["eigenvalues"]) == {"lateral", "longitudinal"}
    # the oracles of the eigenvalues it reports: the paper's column is Eq. (19)'s modal
    # diagonal (0.0786, -0.0890 +/- 0.0568i, -0.5097: printed to 1e-4, from derivatives
    # printed to their own digits, so within one unit of the last digit); the quasi-steady
    # column is eig(A) of Eq. (9) with the derivatives this same report gives
    lateral = r["eigenvalues"]["lateral"]
    def order(zs):
        return sorted((complex(z) for z in zs), key=lambda z: (z.real, z.imag))

    paper = order(complex(*z) for z in lateral["paper"])
    printed = order([0.0786, complex(-0.0890, 0.0568), complex(-0.0890, -0.0568), -0.5097])
    diff = np.array(paper) - np.array(printed)
    assert max(np.abs(diff.real).max(), np.abs(diff.imag).max()) <= 1e-4, diff
    qs = {k: v["quasi_steady"] for k, v in r["derivatives"].items()}
    params = lateral_dynamics.default_parameters()
    params = replace(params, **{k: qs[k] for k in lateral_dynamics.LateralParameters.names() if k in qs})
    A, _ = lateral_dynamics.system_matrices(params)
    want = order(np.linalg.eigvals(A))
    got = order(complex(*z) for z in lateral["quasi_steady"])
    assert np.max(np.abs(np.array(got) - np.array(want))) < 1e-12


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


# -- docs/aerodynamics.md and README.md quote what the code renders ---------------------------

from pathlib import Path  # noqa: E402

from docnumbers import NumericText  # noqa: E402
from docnumbers import assert_same_numbers as same  # noqa: E402
from docnumbers import doc_block  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "aerodynamics.md"


def _block(text: str, name: str) -> str:
    return doc_block(text, f"aero:{name}", DOC.name)


@pytest.fixture(scope="module")
def reports(model):
    sane = QuasiSteadyModel(terms=Terms(added_mass_form="sane2001"))
    return parity_report(model), parity_report(sane)


def test_aerodynamics_doc_blocks_are_what_the_code_renders(model, reports):
    from dronefly.harness.aero.beside_paper import readme_paragraph, linearity_summary, trim_table

    text = DOC.read_text(encoding="utf-8")
    default, sane = reports

    def assert_same_numbers(expected: str, actual: str, hint: str) -> None:
        # columns realign when a sign appears: compare with whitespace runs as one space
        same(" ".join(expected.split()), " ".join(actual.split()), hint)

    assert_same_numbers(_block(text, "table"), default.table(), "aero:table")
    assert_same_numbers(_block(text, "sane2001"), sane.table(), "aero:sane2001")
    assert_same_numbers(_block(text, "trim"), trim_table(), "aero:trim")
    assert_same_numbers(_block(text, "linearity"), linearity_summary(model), "aero:linearity")
    ans = readme_paragraph(default, model)
    assert_same_numbers(_block(text, "answer"), ans, "aero:answer")
    readme = NumericText((ROOT / "README.md").read_text(encoding="utf-8"))
    for line in ans.splitlines():
        assert line in readme, f"README does not quote: {line[:60]}"


def test_aerodynamics_doc_prose_numbers(model, reports):
    """The numbers the prose quotes beside the generated blocks, recomputed."""
    from dronefly.harness.aero.beside_paper import linearity_scan, pair_scan, LATERAL_PAIRS

    text = NumericText(DOC.read_text(encoding="utf-8"))
    default, sane_report = reports
    sane = QuasiSteadyModel(terms=Terms(added_mass_form="sane2001"))
    g = model.geometry
    wang = QuasiSteadyModel("wang2004")
    rows = {r.parameter: r for r in default.rows}
    wrows = {r.parameter: r for r in derivative_rows(wang)}
    srows = {r.parameter: r for r in sane_report.rows}

    def slope(name, a, fn):
        h = 1e-6
        f = getattr(COEFFICIENT_SETS[name], fn)
        return float((f(np.array(a + h)) - f(np.array(a - h))) / (2 * h))

    ad = 0.5 * (model.trim().alpha_d + model.trim().alpha_u)
    aw = 0.5 * (wang.trim().alpha_d + wang.trim().alpha_u)
    cd = lambda n, a: float(COEFFICIENT_SETS[n].drag(np.array(a)))  # noqa: E731
    lin = linearity_scan(model, ("delta_Phi_a", "delta_alpha_1a", "delta_alpha_2a"), tuple("YLN"))
    lon = linearity_scan(model, ("delta_Phi", "delta_alpha_1", "delta_phibar", "delta_alpha_2"),
                         tuple("XZM"))
    pairs = [pair_scan(model, p, points=17) for p in LATERAL_PAIRS]
    quotes = [
        f"r1 = {g.r1_hat:.3f} R, p = {g.p:.2f}, q = {g.q:.2f}",
        f"has CD({math.degrees(ad):.1f} deg) = {cd('dickinson1999', ad):.2f}, Wang's "
        f"CD({math.degrees(aw):.1f} deg) = {cd('wang2004', aw):.2f}, and `wang2004` gives "
        f"{wrows['Nr_plus'].ratio:.2f} of the CFD value",
        f"**Lp, Zw, Mq** ({rows['Lp_plus'].ratio:.2f}, {rows['Zw_plus'].ratio:.2f}, "
        f"{rows['Mq_plus'].ratio:.2f}, translational)",
        f"the slope dCL/dalpha at trim, {slope('dickinson1999', ad, 'lift'):.1f} per rad for "
        f"Dickinson's fit at {math.degrees(ad):.1f} deg",
        f"(slope {slope('wang2004', aw, 'lift'):.1f} per rad at {math.degrees(aw):.1f} deg: "
        f"{wrows['Lp_plus'].ratio:.2f}, {wrows['Zw_plus'].ratio:.2f}, {wrows['Mq_plus'].ratio:.2f})",
        f"**Yv, Xu** ({rows['Yv_plus'].ratio:.2f}, {rows['Xu_plus'].ratio:.2f}, translational)",
        f"closer with `wang2004` ({wrows['Yv_plus'].ratio:.2f}, {wrows['Xu_plus'].ratio:.2f})",
        f"**Lv, Mu** ({rows['Lv_plus'].ratio:.1f}, {rows['Mu_plus'].ratio:.1f}; rotational)",
        f"Phi/2 = {math.degrees(g.Phi_rad) / 2:.1f} deg ahead of",
        f"**Yp, Np, Lr, Xq** ({rows['Yp_plus'].ratio:.2f}, {rows['Np_plus'].ratio:.2f}, "
        f"{rows['Lr_plus'].ratio:.2f}, {rows['Xq_plus'].ratio:.2f}; mostly rotational)",
        f"Yp is {rows['Yp_plus'].ratio:.0f} times the CFD's and Lr, {rows['Lr_plus'].paper:.3f} in "
        f"the CFD, is {rows['Lr_plus'].ratio:.0f} times",
        f"**L_Phi_a, Z_Phi** ({rows['L_Phi_a_plus'].ratio:.2f}, {rows['Z_Phi_plus'].ratio:.2f}, "
        "translational)",
        f"L_Phi_a is {srows['L_Phi_a_plus'].ratio:.2f} and Z_Phi {srows['Z_Phi_plus'].ratio:.2f} of",
        f"**L_alpha_1a, Z_alpha_1** ({rows['L_alpha_1a_plus'].ratio:.2f}, "
        f"{rows['Z_alpha_1_plus'].ratio:.2f}, translational)",
        f"**N_alpha_2a, X_alpha_2** ({rows['N_alpha_2a_plus'].ratio:.2f}, "
        f"{rows['X_alpha_2_plus'].ratio:.2f}, translational)",
        f"({slope('dickinson1999', ad, 'drag'):.1f} per rad for Dickinson's fit, "
        f"{slope('wang2004', aw, 'drag'):.1f} for Wang's: `wang2004` gives "
        f"{wrows['N_alpha_2a_plus'].ratio:.2f} and {wrows['X_alpha_2_plus'].ratio:.2f})",
        f"**M_phibar** ({rows['M_phibar_plus'].ratio:.2f}, opposite, translational)",
        f"The magnitude agrees ({-rows['M_phibar_plus'].ratio:.2f})",
        f"The lateral divergence is faster ({default.eigenvalues['lateral']['quasi_steady'][0].real:+.4f} "
        f"against {default.eigenvalues['lateral']['paper'][0].real:+.4f} per wing beat): the "
        f"quasi-steady Lv is {rows['Lv_plus'].ratio:.1f} times",
        f"leave the loop unstable ({default.controller['qs_A_qs_B'][0].real:+.4f} per wing beat)",
        f"quasi-steady B, {default.controller['paper_A_qs_B'][0].real:+.4f}: the gains assume the "
        f"CFD's L_Phi_a, and the model's is {rows['L_Phi_a_plus'].ratio:.2f} of it",
        f"and the model's is {rows['L_Phi_a_plus'].ratio:.2f} of it, so the loop is neutral again; "
        f"with the `sane2001` form, whose L_Phi_a is {srows['L_Phi_a_plus'].ratio:.2f} of the "
        f"CFD's, it is not ({sane_report.controller['paper_A_qs_B'][0].real:+.4f})",
        "k = " + ", ".join(f"{k:.3f}" for k in default.controller["matched_gains"]) + ": a dv+ "
        f"gain {default.controller['matched_gains'][0] / -0.3192:.0f} times the paper's",
        f"an upward force that carries {100 * (1 - translational_share(sane)):.0f} % of the weight "
        "at its trim",
        f"whose spurious lift carries {100 * (1 - translational_share(sane)):.0f} % of the weight",
        f"swings from {math.degrees(model.trim().alpha_d):.1f} deg to "
        f"{math.degrees(model.trim().alpha_d + 0.4):.0f} deg",
        f"(its maximum is at {(90 + 7.2) / 2.13:.1f} deg), and the other's to "
        f"{math.degrees(model.trim().alpha_d - 0.4):.0f} deg",
        f"dalpha_2a ({lin['inputs']['delta_alpha_2a']['N']['max_error_pct']:.1f} % on N at 0.8 rad)",
        f"{lon['inputs']['delta_alpha_1']['Z']['max_error_box_pct']:.0f} % on Z at 0.4 rad, 10 % at "
        f"{lon['inputs']['delta_alpha_1']['Z']['ten_pct_extent']:.2f} rad",
    ]
    missing = [q for q in quotes if q not in text]
    assert not missing, "docs/aerodynamics.md does not quote:\n" + "\n".join(missing)
    # integers the prose quotes, with their bounds
    # the "23 % on Z at 0.4 rad" quoted above, recomputed without linearity_scan: Z at the
    # box edges of delta_alpha_1 against the tangent at hover (a Richardson-extrapolated central
    # difference with steps 0.01 and 0.005, not linearity_scan's 1e-3), over Z's largest range
    # in the box among the four longitudinal controls (41 samples each, not 7). The two
    # computations differ by their derivative steps' O(h^2) and the sampling of the range's
    # ends: measured 2e-6 relative; 1e-4 leaves room
    inputs = ("delta_Phi", "delta_alpha_1", "delta_phibar", "delta_alpha_2")

    def z_of(name, value):
        return model.forces_vector(np.zeros(6), {name: value})[2]

    def slope(h):
        return (z_of("delta_alpha_1", h) - z_of("delta_alpha_1", -h)) / (2 * h)

    tangent = (4 * slope(0.005) - slope(0.01)) / 3
    z_range = max(np.ptp([z_of(n, v) for v in np.linspace(-0.4, 0.4, 41)]) for n in inputs)
    z0 = z_of("delta_alpha_1", 0.0)
    edge_pct = 100 * max(abs(z_of("delta_alpha_1", v) - z0 - tangent * v) for v in (-0.4, 0.4)) \
        / z_range
    assert lon["inputs"]["delta_alpha_1"]["Z"]["max_error_box_pct"] == pytest.approx(edge_pct,
                                                                                      rel=1e-4)
    # the 31 % quoted above is the sane2001 added mass's spurious lift: the rotational force
    # averages to zero over the cycle, so the translational force carries the rest (the share
    # itself is checked against a finer cycle and the instantaneous forces' mean in
    # test_sane2001_added_mass_has_a_spurious_mean_lift_of_31_percent_of_the_weight)
    spurious = -_added_mass_only("sane2001").forces_vector(trim=sane.trim())[2] / sane.geometry.weight
    assert 1 - translational_share(sane) == pytest.approx(spurious, rel=1e-9)
    assert max(p[o]["max_error_box_pct"] for p in pairs for o in "YLN") < 1.2
    assert max(p[o]["max_error_pct"] for p in pairs for o in "YLN") < 9.0
    assert all(p[o]["ten_pct_radius"] is None for p in pairs for o in "YLN")
    assert lin["inputs"]["delta_Phi_a"]["L"]["max_error_pct"] < 1.0
    far = pair_scan(model, ("delta_v", "delta_r"), extent=4.0, points=17)
    # the grid is half a box apart: the radii are grid values, compared exactly
    assert (far["Y"]["ten_pct_radius"], far["N"]["ten_pct_radius"]) == (2.5, 3.0)


def derivative_rows(m):
    from dronefly.harness.aero.beside_paper import derivative_table

    return derivative_table(m)


def translational_share(m):
    single = m.with_options(terms=Terms(rotational=False, added_mass=False))
    return -single.forces_vector(trim=m.trim())[2] / m.geometry.weight


def test_quasi_steady_lateral_matrix_has_the_signs_of_eq9(reports):
    """Axes and signs as the paper's: Eq. (10) with the model's derivatives has +g+ in its first
    row and the sign of Eq. (12) in every aerodynamic entry the paper prints as nonzero."""
    from dronefly.models.lateral_interface import INERTIAS_SECT21
    from dronefly.models.lateral_dynamics import A1_EQ12

    values = {r.parameter: r.quasi_steady for r in reports[0].rows}
    (A1, B1), _ = matrices_with_derivatives(values)
    assert A1[0, 3] == INERTIAS_SECT21["g_plus"] > 0 and INERTIAS_SECT21["Ixz_plus"] < 0
    paper = np.asarray(A1_EQ12)
    printed = np.abs(paper[:3, :3]) > 0.0
    assert np.array_equal(np.sign(A1[:3, :3])[printed], np.sign(paper[:3, :3])[printed])


def test_a_model_without_lift_has_no_trim(capsys):
    # neither the rotational force nor the impulse added mass has a mean lift at hover: the
    # mean force does not depend on the angles
    for extra in (["--no-added-mass"], []):
        assert main(["aero", "--no-translational", *extra]) == 2
        assert "no trim: the force and pitch moment do not depend" in capsys.readouterr().err
    # the sane2001 form's spurious mean force depends on them, but balances nowhere in range
    assert main(["aero", "--no-translational", "--added-mass-form", "sane2001"]) == 2
    assert "no trim with angles of attack" in capsys.readouterr().err


# -- the added mass: the rate of change of a periodic impulse averages to zero ---------------

def _added_mass_only(form: str, n_time: int = 200) -> QuasiSteadyModel:
    return QuasiSteadyModel(terms=Terms(translational=False, rotational=False,
                                        added_mass_form=form), n_time=n_time)


def test_the_default_added_mass_is_the_impulse_rate():
    assert Terms().added_mass_form == "impulse"
    assert QuasiSteadyModel().terms.added_mass_form == "impulse"


@pytest.mark.parametrize("state,control", [
    ((0.0,) * 6, {}),
    ((0.1, 0.15, -0.1, 0.0, 0.0, 0.0), {}),
    ((0.0,) * 6, {"delta_Phi_a": 0.4, "delta_alpha_1a": -0.3, "delta_alpha_2a": 0.2,
                  "delta_Phi": 0.1, "delta_phibar": 0.2, "delta_alpha_2": -0.3}),
])
def test_impulse_added_mass_force_averages_to_zero_over_the_cycle(model, state, control):
    """Without body rates the wing motion in body axes is periodic, so the fluid impulse
    I = m_a V_n n is periodic and its rate of change averages to zero over the cycle: an exact
    identity. The instantaneous forces (``forces_over_cycle``, element by element, the rate of
    change as periodic central differences) keep it exactly on the sampled cycle (the sum of
    the differences telescopes), so only round-off remains; the cycle average
    (``forces_vector``, by parts) holds it by construction."""
    m = _added_mass_only("impulse")
    f = m.forces_over_cycle(state, control, trim=model.trim()).mean(axis=1)
    assert np.all(np.abs(m.forces_vector(state, control, trim=model.trim())[:3])
                  < 1e-12 * model.geometry.weight)
    # the same term's size: the sane2001 form's average at the same motion (its nonzero mean)
    scale = np.max(np.abs(_added_mass_only("sane2001").forces_vector(state, control,
                                                                     trim=model.trim())[:3]))
    assert scale > 0.1 * model.geometry.weight
    # round-off of sums over 100 samples x 16 elements of terms of order the weight: 1e-12 W
    assert np.all(np.abs(f[:3]) < 1e-12 * model.geometry.weight), f[:3]


def test_sane2001_added_mass_has_a_spurious_mean_lift_of_31_percent_of_the_weight():
    """Sane & Dickinson 2001's -m_a dV_n/dt n drops m_a V_n dn/dt, so its cycle average is
    m_a mean(V_n dn/dt), not zero: at its own trim an upward force of 31 % of the weight
    (docs/aerodynamics.md quotes it), a property of the continuous cycle, not of the grid."""
    full = QuasiSteadyModel(terms=Terms(added_mass_form="sane2001"))
    tr = full.trim()
    W = full.geometry.weight
    share = -_added_mass_only("sane2001").forces_vector(trim=tr)[2] / W
    fine = -_added_mass_only("sane2001", n_time=2000).forces_vector(trim=tr)[2] / W
    # the cycle's quadrature (by parts) against 20 times the samples: within 0.1 %
    assert share == pytest.approx(fine, rel=1e-3)
    # and the instantaneous forces' mean (central differences, O(dt^2)) converges to it
    direct = -_added_mass_only("sane2001", n_time=2000).forces_over_cycle(trim=tr)[2].mean() / W
    assert direct == pytest.approx(fine, rel=1e-4)
    # the share docs/aerodynamics.md quotes as 31 %, to the unit of its last digit
    doc = (Path(__file__).resolve().parents[1] / "docs" / "aerodynamics.md").read_text()
    assert "spurious lift carries 31 % of the weight" in " ".join(doc.split())
    assert round(100 * share) == 31
    # and the impulse form's share at its trim is zero (the identity above)
    imp = QuasiSteadyModel()
    assert abs(_added_mass_only("impulse").forces_vector(trim=imp.trim())[2]) < 1e-12 * W
