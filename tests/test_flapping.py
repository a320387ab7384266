"""The wing-beat-resolved model (models/flapping/): its forces, its rigid body, its
integration, when its controls take effect, and its periodic orbit.

Oracles: the quasi-steady model's own sampled forces (``forces_over_cycle``) and cycle average
(``forces_vector``); the 6-DOF plant's rigid body (``Hover6DOF.derivative``) fed the same
loads; ``scipy.integrate.solve_ivp`` at rtol 1e-10. Coarse grids and few wing beats (the
whole file runs in a few seconds).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from dronefly.models import lateral_dynamics
from dronefly.models import longitudinal_dynamics
from dronefly.models.flapping import (WING_CM_OVER_R, FlappingError, FlappingModel, Flight,
                                      periodic_orbit, wing_beat_controls)
from dronefly.models.lateral_interface import FLIGHT_DATA, INERTIAS_SECT21
from dronefly.models.quasisteady import CONTROLS, QuasiSteadyModel, Terms
from dronefly.models.rigid_body import Hover6DOF

#: the orbit and the monodromy (numpy's LAPACK): run again under a second BLAS kernel
pytestmark = pytest.mark.numeric

X6 = np.array([0.03, -0.02, 0.01, 0.02, -0.03, 0.04])
C7 = (0.05, 0.03, -0.02, 0.04, 0.02, -0.03, 0.01)


@pytest.fixture(scope="module")
def model() -> FlappingModel:
    return FlappingModel(steps_per_beat=20)


def _sampled_gap(n: int, js: np.ndarray) -> np.ndarray:
    """|forces_at - forces_over_cycle| at samples js of a grid of n (controls C7, state X6)."""
    qs = QuasiSteadyModel(n_time=n)
    control = dict(zip(CONTROLS, C7))
    F = qs.forces_over_cycle(X6, control)
    kin = qs.wing_kinematics(control)
    fm = FlappingModel(qs)
    out = []
    for j in js:
        tau = (j + 0.5) / n
        ang = fm.angles(tau, C7, C7)
        # the model's harmonic stroke and its pitch profile, at the sample
        assert np.allclose(ang[0], kin["phibar"] - 0.5 * kin["Phi"] * math.cos(2 * math.pi * tau),
                           rtol=0, atol=1e-14)
        out.append(np.max(np.abs(qs.forces_at(ang, X6) - F[:, j])))
    return np.array(out)


def test_instantaneous_forces_are_the_sampled_forces_of_the_quasi_steady_model():
    # forces_over_cycle differentiates the added mass's impulse by periodic central
    # differences (error O(1/n^2)); forces_at differentiates it analytically: the gap falls
    # nine times when the grid is three times finer, and the rest agrees to round-off
    js = np.array([0, 100, 333, 600, 999])
    coarse, fine = _sampled_gap(1000, js), _sampled_gap(3000, 3 * js + 1)
    assert np.all(fine < coarse / 7.0)
    assert np.max(fine) < 1e-4


def test_instantaneous_forces_are_an_element_by_element_evaluation_to_round_off(model):
    # forces_at (its instants, each called with the state) against forces_over_cycle, which sums every
    # element's force and moment in Cartesian components: without the added mass the same to
    # round-off (measured 5e-15 of the weight); the added mass, analytic in forces_at, against
    # the Richardson extrapolation of forces_over_cycle's central differences (error
    # O(1/n^4)) on 600 and 1800 samples (measured 1e-7 of the weight, at the reversals)
    n, W, trim = 200, model.qs.geometry.weight, model.trim
    control = dict(zip(CONTROLS, C7))
    js = np.arange(n)
    angles = np.array([model.angles((j + 0.5) / n, C7, C7) for j in js])
    for terms, tol in ((Terms(added_mass=False), 1e-13), (Terms(translational=False,
                                                                rotational=False), 1e-6)):
        qs = model.qs.with_options(terms=terms)
        mine = np.array([instant(X6) for instant in qs.instants(angles)])
        F3, F9 = (qs.with_options(n_time=m * n).forces_over_cycle(X6, control, trim)
                  for m in (3, 9))
        ref = (9.0 * F9[:, 9 * js + 4] - F3[:, 3 * js + 1]) / 8.0
        assert np.max(np.abs(mine - ref.T)) < tol * W, terms
        # one instant at a time (forces_at, which checks its arguments) as all together
        for j in (0, 57, 100, 199):
            assert np.max(np.abs(qs.forces_at(angles[j], X6) - mine[j])) < 1e-14 * W


def test_the_kept_stages_are_the_equations_on_the_fly(model):
    # the grid's stages made once per pair of controls give the derivative and the loads of
    # the equations evaluated at that instant (round-off: the same terms, vectorised)
    cp, cn = (0.0,) * 7, C7
    beat = model._beat(cp, cn)
    y = model.state_from_z(np.array([0.03, -0.02, 0.01, 0.02, -0.03, 0.04, 0.1, -0.05]))
    N = model.steps_per_beat
    table = model._grid((cp, cn), beat, cn)
    for j in (0, 3, N // 2 - 1, N // 2, N - 1):
        mid = j / N + 0.5 * ((j + 1) / N - j / N)
        for stage, tau in zip(table[j], (j / N, mid, (j + 1) / N)):
            assert np.max(np.abs(model._at(stage, y) - model._rhs(tau, y, beat, cn, mid))) \
                < 1e-13
    # at (or within round-off of) a grid point the loads and angles are its stage's, those of
    # the grid point on the phase's own half-stroke (at the front reversal the stroke's
    # acceleration jumps when the controls change)
    for tau in (0.0, 0.5, 0.5 + 1e-15, 0.55, 0.525, 1.0 - 1e-15, 1.0):
        point = round(tau * N) / N if abs(tau * N - round(tau * N)) < 1e-9 else tau  # 0.525: off
        ours = np.concatenate(model.loads(tau, y, cp, cn))
        theirs = np.concatenate(model._loads(point, y[:6], beat, cn, tau))
        assert np.max(np.abs(ours - theirs)) < 1e-13, tau
        assert np.max(np.abs(model.angles(tau, cp, cn) - model._angles(point, beat, tau))) \
            < 1e-13, tau


def test_cycle_average_of_the_instantaneous_forces_is_the_averaged_model(model):
    # the mean of 400 midpoint samples against the 400-sample cycle average, whose added mass
    # is integrated by parts (exact): they differ by the midpoint rule's O(1/n^2) on the
    # analytic added mass, 3e-5 of the weight here
    taus = (np.arange(400) + 0.5) / 400
    mean = np.mean([model.loads(t, X6, C7, C7)[0] for t in taus], axis=0)
    avg = QuasiSteadyModel(n_time=400).forces_vector(X6, dict(zip(CONTROLS, C7)), model.trim)
    assert np.max(np.abs(mean - avg)) < 1e-4 * model.qs.geometry.weight


def test_wing_inertia_averages_to_zero_and_peaks_at_four_weights(model):
    taus = (np.arange(400) + 0.5) / 400
    c0 = (0.0,) * 7
    inertial = np.array([model.loads(t, np.zeros(6), c0, c0)[1] for t in taus])
    W = model.qs.geometry.weight
    assert np.max(np.abs(inertial.mean(axis=0))) < 1e-12 * W
    # fore-aft force of both wings (they add) and the pitch moment; the others cancel. The
    # oracle, in SI from the Sect. 2.4 flight data: each wing's centre of mass at 0.35 R on
    # phi(t) = phibar - Phi/2 cos(2 pi n t), its fore-aft position r sin(phi), differentiated
    # twice by central differences (h = 1e-4 of a beat: O(h^2) = 4e-7), the force of both
    # wings over the weight (m_body + 2 m_wing) g: 4.23
    d = FLIGHT_DATA
    r, phi_amp, n = WING_CM_OVER_R * d["R"], math.radians(d["Phi_deg"]), d["n"]

    def fore_aft_m(t_s):
        return r * np.sin(model.trim.phibar - 0.5 * phi_amp * np.cos(2 * np.pi * n * t_s))

    t, h = taus / n, 1e-4 / n
    accel = (fore_aft_m(t + h) - 2 * fore_aft_m(t) + fore_aft_m(t - h)) / h ** 2
    peak = np.max(np.abs(2 * d["m_wing"] * accel)) / ((d["m_body"] + 2 * d["m_wing"]) * d["g"])
    assert np.max(np.abs(inertial[:, 0])) / W == pytest.approx(peak, rel=1e-5)
    assert round(peak, 1) == 4.2  # "up to 4.2 times the weight" (dronefly.models.flapping's docstring)
    assert np.max(np.abs(inertial[:, [1, 2, 3, 5]])) < 1e-12
    assert np.max(np.abs(inertial[:, 4])) > W


def test_rigid_body_is_the_6dof_plants_when_given_its_loads(monkeypatch):
    # the 6-DOF plant's rigid body (paper's inertias) with its linear aerodynamics: feed the
    # same accelerations to the flapping model's equations as loads; the derivatives agree
    LP, NP = lateral_dynamics.default_parameters(), longitudinal_dynamics.default_parameters()
    plant = Hover6DOF(LP, NP)
    fm = FlappingModel(steps_per_beat=20)
    m, g = INERTIAS_SECT21["m_plus"], INERTIAS_SECT21["g_plus"]
    J = np.array([[LP.Ix_plus, 0, -LP.Ixz_plus], [0, NP.Iy_plus, 0], [-LP.Ixz_plus, 0, LP.Iz_plus]])
    fm.m, fm.g, fm.J, fm.J_inv = m, g, J, np.linalg.inv(J)
    x = np.array([0.05, -0.04, 0.03, 0.2, -0.1, 0.15, *plant_quaternion(), 0.0, 0.0, 0.0])
    c_lat, c_lon = (0.1, -0.05, 0.02), (0.03, -0.02, 0.04, 0.01)
    # the plant's aerodynamic accelerations: its derivative at the level attitude without the
    # transport and gyroscopic terms (there the gravity terms vanish)
    plain = Hover6DOF(LP, NP, terms=frozenset({"gravity"}))
    a = np.array(plain.derivative([*x[:6], 1.0, 0.0, 0.0, 0.0, 0, 0, 0], c_lat, c_lon)[:6])
    # the plant's weight is balanced by the mean force: F/m+ = a - g+ e_z
    loads = np.concatenate([m * (a[:3] - np.array([0.0, 0.0, g])), J @ a[3:]])
    monkeypatch.setattr(fm, "_loads", lambda *args, **kw: (loads, np.zeros(6)))
    mine = fm.derivative(0.3, x)
    theirs = np.array(plant.derivative(x, c_lat, c_lon))
    assert np.max(np.abs(mine - theirs)) < 1e-13


def plant_quaternion() -> tuple[float, ...]:
    from dronefly.models.rigid_body import quaternion_from_euler
    return quaternion_from_euler(0.3, -0.2, 0.5)


def _reference_beat(fm: FlappingModel, x0, cp, cn, end: float = 1.0,
                    start: float = 0.0, rtol: float = 1e-10) -> np.ndarray:
    """solve_ivp (DOP853, ``rtol``, atol 1e-3 of it) piecewise between the kinks of the forces
    in time (the reversals, the rotations' ends), each piece on its own half-stroke's branch."""
    beat = fm._beat(wing_beat_controls(cp), wing_beat_controls(cn))
    cn = wing_beat_controls(cn)
    cuts = [c for c in (0.0, 0.15, 0.35, 0.5, 0.65, 0.85, 1.0) if start <= c <= end]
    y = np.array(x0, dtype=float)
    for a, b in zip(cuts[:-1], cuts[1:]):
        sol = solve_ivp(lambda t, yy: fm._rhs(t, yy, beat, cn, 0.5 * (a + b)), (a, b), y,
                        method="DOP853", rtol=rtol, atol=1e-3 * rtol)
        y = sol.y[:, -1]
    return y


def test_fixed_step_against_solve_ivp():
    # half a wing beat from the hover state with the trimmed kinematics. The forces have kinks
    # at the reversals and the rotations' ends, all on the grid: the classical Runge-Kutta
    # method keeps its order 4 (the error falls ~16 times from 20 to 40 steps per beat)
    fm20, fm40 = FlappingModel(steps_per_beat=20), FlappingModel(steps_per_beat=40)
    x0 = fm20.state_from_z(np.zeros(8))
    ref = _reference_beat(fm20, x0, None, None, end=0.5)
    e20 = np.max(np.abs(fm20.advance(x0, 0.0, 0.5) - ref))
    e40 = np.max(np.abs(fm40.advance(x0, 0.0, 0.5) - ref))
    # the default grid: 3e-6 in the pitch rate q+ (whose swing in the beat is 0.03) at mid-beat,
    # 8e-7 at the beat's end, where the half-strokes' errors partly cancel
    assert e40 < 5e-6
    assert e20 / e40 > 12.0


def test_fixed_step_against_solve_ivp_across_a_control_change():
    # a beat whose controls change at its start: the stroke's acceleration jumps at the front
    # reversal (on the grid); where the flow meets an element at 0 or 90 deg off the grid the
    # lift coefficient's nonzero ends make a small jump the grid does not see: 1e-6 over the
    # beat. Here the stretch around the front reversal, where both happen
    fm = FlappingModel(steps_per_beat=40)
    x0 = fm.state_from_z(np.zeros(8))
    cn = (0.1, 0.05, -0.05, 0.05, 0.02, 0.03, -0.02)
    ref = _reference_beat(fm, x0, None, cn, start=0.35, end=0.65)
    assert np.max(np.abs(fm.advance(x0, 0.35, 0.65, None, cn) - ref)) < 2e-6


def test_fixed_step_against_solve_ivp_from_a_disturbance_with_new_controls():
    """As a closed loop flies: from a disturbed state (velocities 0.005 to 0.02 of U, rates
    0.01 to 0.03), a beat whose seven controls are new (within 0.05 rad, about the largest the
    paper's gains command in docs/averaging.md's runs), against solve_ivp. Off the grid an
    element's normal velocity crosses zero, where the Dickinson lift coefficient's nonzero
    value at zero incidence (0.027) turns the normal force over: a jump the fixed grid does not
    locate, a local error of first order in the step. Measured 7.5e-6 (40 steps per beat;
    2.0e-6 with 80), and 1.3e-5 after two such beats: the bound 2e-5 is 0.1 % of the
    disturbance, against the 8e-7 of a beat from hover (above)."""
    fm = FlappingModel(steps_per_beat=40)
    rng = np.random.default_rng(3)
    cp, cn = (tuple(rng.uniform(-0.05, 0.05, 7)) for _ in range(2))
    x0 = np.array([0.01, -0.02, 0.005, 0.03, -0.01, 0.02, 1.0, 0, 0, 0, 0, 0, 0])
    flight = Flight(fm, x0, cp)  # the insect flapped with cp before
    flight.set_controls(cn)  # taken at the first beat's start
    ours = flight.advance_to(1.0)
    # the jumps off the grid cost solve_ivp's error control many rejected steps: rtol 1e-8
    # (4.5 times fewer evaluations than 1e-10) differs from the 1e-10 solution by 1.9e-8,
    # a thousandth of the bound
    ref = _reference_beat(fm, x0, cp, cn, rtol=1e-8)
    ref[6:10] /= np.linalg.norm(ref[6:10])
    assert np.max(np.abs(ours - ref)) < 2e-5


def test_kinematics_continuous_when_the_controls_change(model):
    cp, cn, cq = (0.0,) * 7, C7, (-0.02, 0.04, 0.03, -0.03, 0.01, 0.02, -0.04)
    eps = 1e-9
    # across the start of a beat: the end of beat (cp -> cn) and the start of beat (cn -> cq)
    end, start = model.angles(1.0 - eps, cp, cn), model.angles(eps, cn, cq)
    assert np.max(np.abs(end[[0, 1, 3, 4]] - start[[0, 1, 3, 4]])) < 1e-6  # angles and rates
    for tau in (0.15, 0.35, 0.5, 0.65, 0.85):
        a, b = model.angles(tau - eps, cp, cn), model.angles(tau + eps, cp, cn)
        assert np.max(np.abs(a[[0, 1, 3, 4]] - b[[0, 1, 3, 4]])) < 1e-6


def _fly(fm: FlappingModel, steps_per_beat: int, schedule: list, beats: int = 2) -> np.ndarray:
    """A host stepping ``steps_per_beat`` times per beat, setting schedule[k] at beat k's start."""
    flight = Flight(fm, fm.state_from_z(np.zeros(8)))
    h = 1.0 / steps_per_beat
    x = None
    for k in range(beats):
        flight.set_controls(schedule[k])
        for j in range(steps_per_beat):
            x = flight.advance_to(k + (j + 1) * h)
    return x


def test_host_step_does_not_change_the_physics(model):
    schedule = [C7, (0.0,) * 7]
    once = _fly(model, 1, schedule)
    assert np.array_equal(_fly(model, 40, schedule), once)  # on the grid: the same steps
    # off the grid: partial steps that the flight does not keep
    assert np.array_equal(_fly(model, 7, schedule), once)


def test_a_control_set_within_a_beat_waits_for_the_next(model):
    flight = Flight(model, model.state_from_z(np.zeros(8)))
    flight.advance_to(0.3)
    flight.set_controls(C7)  # mid-beat: beat 0 keeps the trim
    x1 = flight.advance_to(1.0)
    ref = Flight(model, model.state_from_z(np.zeros(8)))
    assert np.array_equal(ref.advance_to(1.0), x1)
    ref.set_controls(C7)
    assert np.array_equal(ref.advance_to(1.5), flight.advance_to(1.5))


def test_snapshot_restores_the_future(model):
    flight = Flight(model, model.state_from_z(np.zeros(8)), C7)
    flight.advance_to(0.4)
    snap = flight.snapshot()
    a = flight.advance_to(1.3)
    flight.restore(snap)
    assert np.array_equal(flight.advance_to(1.3), a)


def test_bad_values_are_refused(model):
    with pytest.raises(FlappingError, match="multiple of 20"):
        FlappingModel(steps_per_beat=30)
    with pytest.raises(FlappingError, match="not finite"):
        wing_beat_controls((math.nan,) + (0.0,) * 6)
    with pytest.raises(FlappingError, match="expected 7"):
        wing_beat_controls((0.0,) * 3)
    flight = Flight(model, model.state_from_z(np.zeros(8)))
    flight.advance_to(0.5)
    with pytest.raises(FlappingError, match="before"):
        flight.advance_to(0.2)


def test_hover_is_a_periodic_orbit(model):
    orbit = periodic_orbit(model)
    assert orbit.residuals[-1] < 1e-12
    x0 = model.state_from_z(orbit.z0)
    x1 = Flight(model, x0).advance_to(1.0)
    # back to the start after one beat, but for the position (the orbit drifts slowly)
    assert np.max(np.abs(x1[:10] - x0[:10])) < 1e-11
    # symmetric: no lateral motion on the orbit
    assert np.max(np.abs(orbit.z0[[1, 3, 5, 6]])) < 1e-14


def test_the_averaged_twin_is_the_quasi_steady_linear_model():
    # the flapping model with its forces replaced by their cycle average, linearised about
    # hover (its one-beat map's logarithm), is the linear model of the quasi-steady
    # derivatives with the same mass, inertias and gravity (Sect. 2.4 data): the eigenvalues
    # agree to the derivatives' central differences (step 1e-3 across the forces' kinks in
    # the state; measured 6e-8 lateral, 1.4e-5 longitudinal, relative)
    from dataclasses import replace

    from dronefly.harness.aero.beside_paper import LATERAL_PARAMETERS, LONGITUDINAL_PARAMETERS
    from dronefly.harness.aero.beside_paper import derivative_table
    from dronefly.harness.flapping import averaged_exponents
    from dronefly.models.lateral_interface import reference_scales, sort_eigenvalues

    fm = FlappingModel(steps_per_beat=20)
    qs = {r.parameter: r.quasi_steady for r in derivative_table(fm.qs)}
    s = reference_scales()
    lp = replace(lateral_dynamics.default_parameters(), **{p: qs[p] for p, _, _ in LATERAL_PARAMETERS},
                 **{k: s[k] for k in ("m_plus", "Ix_plus", "Iz_plus", "Ixz_plus", "g_plus")})
    np_ = replace(longitudinal_dynamics.default_parameters(), **{p: qs[p] for p, _, _ in LONGITUDINAL_PARAMETERS},
                  **{k: s[k] for k in ("m_plus", "Iy_plus", "g_plus")})
    avg = averaged_exponents(fm)
    for axis, params, module in (("lateral", lp, lateral_dynamics), ("longitudinal", np_, longitudinal_dynamics)):
        A, _ = module.system_matrices(params)
        ev = sort_eigenvalues(np.linalg.eigvals(np.array(A)))
        gap = max(abs(a - b) / abs(b) for a, b in zip(avg[axis], ev))
        assert gap < 1e-4, (axis, avg[axis], ev)


def test_with_averaged_forces_it_is_the_quasi_steady_6dof_plant():
    """The flapping model with its forces replaced by their cycle average (and so no wing
    inertia, zero on average) flies as DroneFlyHover6DOF's model with the quasi-steady
    aerodynamics and the same body (Sect. 2.4 mass and inertias): over 10 wing beats
    from a lateral disturbance the states agree to 1e-5 of the disturbance. The bound is the
    6-DOF plant's sub-steps (half a wing beat at most; measured 4.2e-6 of the disturbance
    against finer ones), not the flapping model's 40 RK4 steps per beat; measured 3.3e-6."""
    from dataclasses import replace

    from dronefly.models.lateral_interface import reference_scales

    fm = FlappingModel(averaged=True)
    s = reference_scales()
    lp = replace(lateral_dynamics.default_parameters(),
                 **{k: s[k] for k in ("m_plus", "Ix_plus", "Iz_plus", "Ixz_plus", "g_plus")})
    np_ = replace(longitudinal_dynamics.default_parameters(), **{k: s[k] for k in ("m_plus", "Iy_plus", "g_plus")})
    six = Hover6DOF(lp, np_, aerodynamics=fm.qs)
    x = [0.0, 0.02, 0.0, 0.03, 0.0, 0.01, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
    a, b = np.array(x), list(x)
    for _ in range(10):
        a = fm.beat(a)
        b = six.step(b, [0.0] * 3, [0.0] * 4, 1.0)
        assert np.max(np.abs(a - np.array(b))) <= 1e-5 * 0.03, (a, b)
    assert np.max(np.abs(a[:6])) > 0.03  # the disturbance grew (the lateral instability)


def test_eight_flights_at_their_own_held_controls_share_the_model_without_remaking_grids(
        monkeypatch):
    """One model serves every FMU instance of a process: eight flights, each at its own held
    controls, stepped in turn for three beats, make each one's grid of stages once (eight
    grids; with the four kept before, 24: each made again every beat), and fly as each would
    alone, to the bit."""
    m = FlappingModel(steps_per_beat=20)
    made = []
    original = m._stages
    monkeypatch.setattr(m, "_stages", lambda *a: made.append(1) or original(*a))
    x0 = [0.0] * 6 + [1.0] + [0.0] * 6
    flights = [Flight(m, x0, (0.01 * k,) + (0.0,) * 6) for k in range(8)]
    for beat in range(1, 4):
        for f in flights:
            f.advance_to(float(beat))
    assert len(made) == 8
    alone = Flight(FlappingModel(steps_per_beat=20), x0, (0.07,) + (0.0,) * 6)
    assert np.array_equal(alone.advance_to(3.0), flights[7].y)
