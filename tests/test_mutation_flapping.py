"""Independent oracles for models/flapping/flight.py (the model in time for a host), written
for mutation testing (docs/mutation.md): the flight's documented bookkeeping (the grid of
``steps_per_beat`` steps, the tolerance of 1e-9 of a step for a time on the grid, the controls
latched at the beats' starts, a snapshot of plain values) checked against the model's own
steps from the same state, which are not the flight's bookkeeping."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from dronefly.models.flapping import FlappingError, FlappingModel, Flight

C7 = (0.05, 0.03, -0.02, 0.04, 0.02, -0.03, 0.01)
ZERO = (0.0,) * 7
N = 20


@pytest.fixture(scope="module")
def fm() -> FlappingModel:
    return FlappingModel(steps_per_beat=N)


def _hover(fm):
    return fm.state_from_z(np.zeros(8))


@pytest.mark.parametrize("x0", [[0.0] * 12, [0.0] * 14, [math.nan] + [0.0] * 12])
def test_flight_refuses_an_initial_state_that_is_not_13_finite_values(fm, x0):
    with pytest.raises(FlappingError, match="expected 13 finite values"):
        Flight(fm, x0)


def test_flight_steps_are_the_models_steps(fm):
    """On the grid the flight's state is the model's steps of 1/N wing beat from the start
    (the controls of the previous and current beat: the initial ones, then from the next
    beat the ones set), bit for bit; an off-grid time is a partial step from the last grid
    point, kept aside."""
    x0 = _hover(fm)
    flight = Flight(fm, x0, C7)
    y = np.array(x0)
    for j in range(N):
        y = fm._advance(y, j / N, (j + 1) / N, C7, C7)
    assert np.array_equal(flight.advance_to(1.0), y)
    flight.set_controls(ZERO)
    partial = fm.advance(y, 0.0, 0.03125, C7, ZERO)  # 1/32 wing beat: exact in floats
    assert np.array_equal(flight.advance_to(1.03125), partial)
    assert flight.grid == N and np.array_equal(flight.y, y)


def test_times_within_the_tolerance_of_a_grid_point_are_on_it(fm):
    """A time within 1e-9 of a step (5e-11 wing beat at N = 20) of a grid point is that
    point: just before 1.0 reaches the grid point 1.0 and returns it; just before the kept
    state is still allowed; 4e-11 after it is the state itself. Farther before it is
    refused, and farther than a step after it is no partial step."""
    tol = 1e-9 / N
    flight = Flight(fm, _hover(fm), C7)
    at_one = flight.advance_to(1.0 - 0.5 * tol)
    assert flight.grid == N
    ref = Flight(fm, _hover(fm), C7)
    assert np.array_equal(ref.advance_to(1.0), at_one)
    assert np.array_equal(flight.advance_to(1.0 - 0.8 * tol), at_one)
    assert np.array_equal(flight.state_at(1.0 + 0.8 * tol), at_one)
    with pytest.raises(FlappingError, match="before the flight's state"):
        flight.advance_to(1.0 - 2.0 * tol)
    with pytest.raises(FlappingError, match="not within one grid step"):
        flight.state_at(1.0 + 1.0 / N + 2.0 * tol)
    with pytest.raises(FlappingError, match="not within one grid step"):
        flight.state_at(1.0 - 2.0 * tol)
    # a partial step of a whole grid step and half the tolerance is allowed: the next grid
    # point's state 2.5e-11 wing beat later (rates of order 1: within 1e-10)
    nxt = flight.state_at(1.0 + 1.0 / N + 0.5 * tol)
    np.testing.assert_allclose(nxt, Flight(fm, _hover(fm), C7).advance_to(1.0 + 1.0 / N),
                               rtol=0, atol=1e-10)


def test_phase_and_the_controls_latched_at_the_beats_starts(fm):
    """The phase in the beat and the controls of the previous and current beat: before the
    first beat is entered the phase is 0 with the initial controls; in beat 0 the time in it;
    at the start of beat 1, not yet entered, the end of beat 0 (1.0); once entered, its phase
    with (the previous beat's, the new) controls."""
    flight = Flight(fm, _hover(fm), ZERO)
    assert flight.phase(0.0) == (0.0, ZERO, ZERO)
    flight.advance_to(0.5)
    assert flight.phase(0.5) == (0.5, ZERO, ZERO)
    flight.set_controls(C7)
    flight.advance_to(1.0)
    assert flight.phase(1.0) == (1.0, ZERO, ZERO)
    flight.advance_to(1.25)
    ph, prev, now = flight.phase(1.25)
    assert ph == pytest.approx(0.25, abs=1e-15) and (prev, now) == (ZERO, C7)
    # a time within the tolerance below the beat's start counts as the beat
    assert flight.phase(1.0 - 0.5e-9 / N)[0] == 0.0
    flight.advance_to(2.5)
    assert flight.phase(2.5)[1:] == (C7, C7)


def test_a_snapshot_is_plain_values_that_restore_the_future(fm):
    """The snapshot survives JSON (plain values, the FMU's state); restored, in a fresh
    flight too, the future is the same, bit for bit, the controls pending included."""
    flight = Flight(fm, _hover(fm), ZERO)
    flight.advance_to(0.4)
    flight.set_controls(C7)
    snap = json.loads(json.dumps(flight.snapshot()))
    a = flight.advance_to(1.3)
    other = Flight(fm, _hover(fm), (0.01,) * 7)
    other.restore(snap)
    assert np.array_equal(other.advance_to(1.3), a)
    assert json.loads(json.dumps(other.snapshot())) == json.loads(json.dumps(flight.snapshot()))
    assert other.N == N


def test_the_previous_beats_controls_are_those_it_flew(fm):
    """Controls set before the first beat starts act in beat 0 (the initial ones are those
    the insect flapped with before it: beat 0's previous); entering beat 1, the previous
    controls are beat 0's, not the initial ones."""
    C7b = (-0.01, 0.02, 0.03, -0.02, 0.01, 0.04, -0.03)
    flight = Flight(fm, _hover(fm), C7)
    flight.set_controls(ZERO)
    flight.advance_to(0.5)
    assert flight.phase(0.5)[1:] == (C7, ZERO)
    flight.set_controls(C7b)
    flight.advance_to(1.5)
    assert flight.phase(1.5)[1:] == (ZERO, C7b)


def test_a_refused_time_names_the_state_time(fm):
    """The message of a time before the kept state gives the state's time, 0.5 wing beat
    (read back as a number)."""
    import re
    flight = Flight(fm, _hover(fm))
    flight.advance_to(0.5)
    with pytest.raises(FlappingError, match="before the flight's state") as info:
        flight.advance_to(0.2)
    assert float(re.search(r"state \(([^)]*)\)", str(info.value))[1]) == 0.5


def test_partial_steps_within_a_beat_and_to_its_end(fm):
    """A partial step from grid point j of a beat runs from j / N: from 1.25 wing beats
    (j = 5) to 1.28125 it is the model's step from phase 0.25 to 0.28125 (exact in floats);
    from the beat's last grid point to its end (within the tolerance beyond it) it is the
    step to phase 1.0, the next grid point's state."""
    flight = Flight(fm, _hover(fm), C7)
    y = flight.advance_to(1.25)
    assert np.array_equal(flight.state_at(1.28125), fm.advance(y, 0.25, 0.28125, C7, C7))
    y = flight.advance_to(1.95)
    end = flight.state_at(2.0 + 0.5e-9 / N)
    assert np.array_equal(end, fm.advance(y, 0.95, 1.0, C7, C7))


# -- orbit.py ----------------------------------------------------------------------------------
class AffineBeat:
    """A stand-in for the wing-beat map, z -> A z + b (8 reduced coordinates), with the
    period of 1.25 wing beats of the insect; records the controls it is given."""

    period = 1.25

    def __init__(self):
        rng = np.random.default_rng(4)
        Q = rng.normal(size=(8, 8))
        # eigenvalues 0.9, 0.5, -0.3, 1.2, 0.7, 0.2 and 0.6 +- 0.4i: distinct, real and a pair
        D = np.diag([0.9, 0.5, -0.3, 1.2, 0.7, 0.2, 0.6, 0.6])
        D[6, 7], D[7, 6] = 0.4, -0.4
        self.A = Q @ D @ np.linalg.inv(Q)
        self.b = rng.normal(scale=0.1, size=8)
        self.controls = []

    def z_map(self, z, control=None):
        self.controls.append(control)
        return self.A @ z + self.b


def test_monodromy_of_an_affine_map_is_its_matrix():
    """Central differences of an affine map are its matrix, to rounding (1e-16 / step =
    1e-10 of the O(1) entries, 1e-8 for step = 1e-8); the controls reach the map."""
    from dronefly.models.flapping import monodromy
    m = AffineBeat()
    np.testing.assert_allclose(monodromy(m, np.zeros(8), C7), m.A, rtol=0, atol=1e-9)
    assert m.controls == [C7] * 16
    np.testing.assert_allclose(monodromy(m, np.ones(8), step=1e-4), m.A, rtol=0, atol=1e-9)


def test_periodic_orbit_of_an_affine_map_and_its_floquet_analysis():
    """The orbit's start is the fixed point (I - A)^-1 b (numpy), reached in one chord step
    with the exact Jacobian given, or a few with the central-difference one; a Jacobian that
    does not converge in max_iter steps is a FlappingError. The Floquet multipliers are A's
    eigenvalues (numpy), the exponents log(mu) / period, largest real part first; the blocks'
    exponents of a block-diagonal matrix are those of each block."""
    from dronefly.models.flapping import Floquet, block_exponents, periodic_orbit, AXES
    m = AffineBeat()
    want = np.linalg.solve(np.eye(8) - m.A, m.b)
    orbit = periodic_orbit(m, jacobian=m.A)
    np.testing.assert_allclose(orbit.z0, want, rtol=0, atol=1e-13)
    assert len(orbit.residuals) == 2 and orbit.samples == 200
    orbit = periodic_orbit(m, C7, tol=1e-13, samples=7)
    np.testing.assert_allclose(orbit.z0, want, rtol=0, atol=1e-12)
    assert orbit.samples == 7 and orbit.control == C7 and orbit.residuals[-1] < 1e-13
    with pytest.raises(FlappingError, match="no periodic orbit"):
        periodic_orbit(m, jacobian=0.5 * m.A, max_iter=2)
    fl = Floquet.of(m, orbit)
    np.testing.assert_allclose(fl.monodromy, m.A, rtol=0, atol=1e-9)
    mu = np.linalg.eigvals(m.A)
    lam = np.log(mu.astype(complex)) / 1.25
    order = np.lexsort((-lam.imag, -lam.real))
    np.testing.assert_allclose(fl.exponents, lam[order], rtol=0, atol=1e-8)
    np.testing.assert_allclose(fl.multipliers, mu[order], rtol=0, atol=1e-8)
    assert np.all(np.diff(fl.exponents.real) <= 1e-12)
    # a block-diagonal monodromy in the axes' coordinates
    rng = np.random.default_rng(8)
    M = np.zeros((8, 8))
    blocks = {}
    for axis, idx in AXES.items():
        B = np.diag([0.9, 0.5, 0.3, 0.2]) + 0.05 * rng.normal(size=(4, 4))
        M[np.ix_(idx, idx)] = B
        blocks[axis] = np.log(np.linalg.eigvals(B).astype(complex)) / 0.8
    got = block_exponents(M, 0.8)
    for axis, lam in blocks.items():
        key = lambda c: (round(c.real, 9), round(c.imag, 9))  # noqa: E731
        np.testing.assert_allclose(sorted(got[axis], key=key), sorted(lam, key=key), atol=1e-12)


def test_orbit_trajectory_and_oscillation_by_their_definitions(fm):
    """The trajectory is the flight from the orbit's start at samples + 1 equally spaced
    phases; the oscillation's excursions are its peak-to-peak position (drift over the beat
    removed, in micrometres of U t_w) and Euler angles (scipy's ZYX), the drift velocity and
    the mean pitch, by their definitions (a few roundings: 1e-9 relative); the drift velocity
    in time, for a model of another period too."""
    from dronefly.models.flapping import periodic_orbit
    orbit = periodic_orbit(fm, samples=20)
    X = orbit.trajectory()
    assert X.shape == (21, 13)
    np.testing.assert_array_equal(X[0], fm.state_from_z(orbit.z0))
    ref = Flight(fm, fm.state_from_z(orbit.z0))
    np.testing.assert_array_equal(X[7], ref.advance_to(7 / 20))
    _oscillation_by_definition(orbit, X)
    # a model forced 1.25 times faster (period 0.8 wing beat), from the hover state: the
    # definitions hold for any start
    from dronefly.models.flapping import PeriodicOrbit
    fast = FlappingModel(fm.qs, N, frequency_factor=1.25)
    other = PeriodicOrbit(fast, np.zeros(8), None, [], 4)
    _oscillation_by_definition(other, other.trajectory())


def _oscillation_by_definition(orbit, X):
    from scipy.spatial.transform import Rotation
    fm = orbit.model
    osc = orbit.oscillation()
    L_um, tau = fm.U / fm.n * 1e6, np.linspace(0.0, 1.0, len(X))
    want = {}
    for i, name in zip((10, 11, 12), "xyz"):
        drift = X[-1, i] - X[0, i]
        pos = X[:, i] - X[0, i] - drift * tau
        want[f"{name}_pp_um"] = np.ptp(pos) * L_um
        want[f"{name}_drift_mm_per_s"] = drift / fm.period * fm.U * 1e3
    eul = Rotation.from_quat(X[:, [7, 8, 9, 6]]).as_euler("ZYX")  # psi, theta, phi
    for j, name in ((2, "phi"), (1, "theta"), (0, "psi")):
        want[f"{name}_pp_deg"] = np.degrees(np.ptp(eul[:, j]))
    want["theta_mean_deg"] = np.degrees(eul[:-1, 1].mean())
    assert set(osc) == set(want)
    for k, v in want.items():
        assert osc[k] == pytest.approx(v, rel=1e-9, abs=1e-12), k


def test_orbit_start_and_the_floquet_monodromy_of_the_model(fm):
    """orbit_start (the averaged twin's monodromy as the Jacobian) finds the same fixed point
    of the beat map as periodic_orbit with the model's own (a unique fixed point: the two
    agree to the shooting tolerance, 1e-12, times the map's conditioning: 1e-10); Floquet.of's
    monodromy is the derivative of the beat map: central differences at 1e-6 and 1e-5 agree
    to their O(h^2) error and rounding (1e-6 of the largest entry); the averaged monodromy
    is that of the averaged twin's beat map, an (8, 8) matrix."""
    from dronefly.models.flapping import Floquet, averaged_monodromy, monodromy, orbit_start
    from dronefly.models.flapping import periodic_orbit
    orbit = periodic_orbit(fm)
    np.testing.assert_allclose(orbit_start(fm), orbit.z0, rtol=0, atol=1e-10)
    fl = Floquet.of(fm, orbit)
    coarse = monodromy(fm, orbit.z0, None, 1e-5)
    np.testing.assert_allclose(fl.monodromy, coarse, rtol=0, atol=1e-6 * np.abs(coarse).max())
    twin = FlappingModel(fm.qs, fm.steps_per_beat, averaged=True)
    np.testing.assert_allclose(averaged_monodromy(fm), monodromy(twin, np.zeros(8)), rtol=0,
                               atol=1e-12)


def test_averaged_exponents_do_not_depend_on_the_forcing_period(fm):
    """The averaged twin's forces are the cycle average whatever the wing beat's frequency, so
    its dynamics, and their eigenvalues per wing beat of the insect, are those of the insect's
    averaged model (built here by its definition: averaged forces, one wing beat, the
    logarithms of its monodromy's eigenvalues) for the model and for one forced 1.25 times
    faster (period 0.8 wing beat): the twin keeps the model's period and its map over one
    period gives the same exponents. Tolerance: the Runge-Kutta error of 20 steps a period,
    (lambda h)^4 / 120 relative with |lambda| up to 0.84 per wing beat, h = 0.05: 3e-8
    (measured 1.6e-8 for the forced model, the fastest lateral mode); the monodromy's central
    differences, 1e-10."""
    from dronefly.models.flapping import averaged_exponents, block_exponents, monodromy
    insect = FlappingModel(fm.qs, N, averaged=True)
    want = block_exponents(monodromy(insect, np.zeros(8)), 1.0)
    for model in (fm, FlappingModel(fm.qs, N, frequency_factor=1.25)):
        got = averaged_exponents(model)
        for axis in ("lateral", "longitudinal"):
            key = lambda c: (round(c.real, 6), round(c.imag, 6))  # noqa: E731
            a, b = sorted(want[axis], key=key), sorted(got[axis], key=key)
            np.testing.assert_allclose(b, a, rtol=1e-7, atol=1e-9, err_msg=axis)
