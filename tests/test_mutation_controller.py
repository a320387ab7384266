"""Independent oracles for the controller's timing and variable table (controller/), written
against the mutants that survived the other tests (docs/mutation.md)."""

from __future__ import annotations

import dataclasses
import math
import re
from fractions import Fraction as F

import pytest

from dronefly.controller import delay as delay_mod
from dronefly.controller import slave as slave_mod
from dronefly.controller import timing, variables
from dronefly.fmu_src.lateral.slave import DroneFlyLateral
from dronefly.fmu_src.longitudinal.slave import DroneFlyLongitudinal
from dronefly.models import feedback, lateral_interface

from test_mutation_models import N_HZ, U_M_PER_S


# --- controller/timing.py: the latency an importer sees, by counting grid steps by hand -----

def test_tolerance_is_the_documented_bound():
    h = 0.1
    assert timing.tolerance(0.0, 5.0, 0.0) == 0.0 and timing.tolerance(0.0, 5.0, -h) == 0.0
    assert timing.tolerance(0.0, 0.0, h) == timing.TOLERANCE * h  # no drift at t0
    assert timing.tolerance(5.0, 5.0, h) == timing.TOLERANCE * h  # (also from t0 != 0)
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


def test_seen_latency_on_a_fine_grid():
    # the snapping tolerance is 1e-9 of a step, whatever the step: 2.5 steps of 1 us show at
    # the 3rd point, a sample every 4 steps with 1.5 steps of delay at the 2nd
    h = 1e-6
    assert timing.Timing(2.5 * h, 0.0).seen_latency(h) == pytest.approx((3 * h, 3 * h),
                                                                         rel=1e-9)
    assert timing.Timing(1.5 * h, 4 * h).seen_latency(h) == pytest.approx((2 * h, 2 * h),
                                                                          rel=1e-9)


def test_seen_latency_beyond_the_float_range_is_infinite():
    assert timing.Timing(0.0, 0.0).seen_latency(1e308, steps=5) == (0.0, 0.0)
    # (d + t) / h overflows: no instant index
    assert timing.Timing(1.7e308, 0.0).seen_latency(0.5, steps=3) == (math.inf, math.inf)
    # a delay of 8 steps of 1e307: the index times h overflows from the 10th point on
    lo, hi = timing.Timing(8e307, 0.0).seen_latency(1e307)
    assert lo == pytest.approx(8e307, rel=1e-15) and hi == math.inf
    # a grid that leaves the float range after one step: one point seen
    assert timing.Timing(0.0, 0.0).seen_latency(1.5e308, steps=5) == (0.0, 0.0)
    h = 1.5e308  # half a step of delay: seen one step later, at the one point in range
    assert timing.Timing(0.5 * h, 0.0).seen_latency(h, steps=5) == (h, h)
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


@pytest.mark.parametrize("h, delay, period, seen", [
    # samples at 0.25 k: from point 0.0 the control (0.1 s later) shows at 0.1, from 0.2 (the
    # sample at 0.25) at 0.4: one to two steps
    (0.1, 0.1, 0.25, "1 to 2 steps (0.1 to 0.2 s) later"),
    # the same on a 1 us grid: the tolerance scales with the step
    (1e-6, 1e-6, 2.5e-6, "1 to 2 steps (1e-06 to 2e-06 s) later"),
])
def test_off_grid_warning_states_a_range_of_latencies(h, delay, period, seen):
    text = timing.Timing(delay, period).off_grid_warning("x", 0.0, 0.0, h)
    assert f"communication point {seen}, instead of sensing_delay" in text


def test_timing_defaults_to_no_delay_and_no_sampling():
    t = timing.Timing()
    assert (t.sensing_delay, t.sample_period, t.delay_required) == (0.0, 0.0, False)
    assert t.immediate
    with pytest.raises(dataclasses.FrozenInstanceError):  # a value, shared by the FMU's steps
        t.sensing_delay = 1.0  # type: ignore[misc]


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


# --- controller/variables.py: the interface the paper's law needs, variable by variable ------

@pytest.mark.parametrize("delayed", [False, True])
def test_controller_variables_carry_the_laws_defaults_and_structure(delayed):
    K = ((0.5, -1.0, 2.0, 0.25), (0.0, 0.0, 0.0, 0.0), (1.5, 0.0, 0.0, -3.0))
    sources = ("row one", "row two", "row three")
    got = {v.name: v for v in variables.controller_variables(lateral_interface.LATERAL, K, sources,
                                                             delayed)}
    states = lateral_interface.STATE_NAMES
    for s in states:
        assert (got[s].causality, got[s].start) == ("input", 0.0)
    for i, c in enumerate(lateral_interface.CONTROL_NAMES):
        v = got[c]
        assert v.causality == "output" and v.initial == "calculated"
        assert f": row {i + 1} of u = K x+_s + KI z" in v.description  # 1-based, as K[i,j]
        # no feedthrough in the delayed variant; at initialization the row's own gains only
        row = tuple(f"K[{i + 1},{j + 1}]" for j in range(4))
        assert v.dependencies == (() if delayed else states)
        assert v.initial_dependencies == (() if delayed else (
            *states, *row, "n", "U", "limit_enabled", "u_max", "sensing_delay"))
    every_gain = tuple(f"K[{i},{j}]" for i in (1, 2, 3) for j in (1, 2, 3, 4))
    assert variables.all_gains(lateral_interface.LATERAL) == every_gain
    assert variables.all_integral_gains(lateral_interface.LATERAL) == tuple("KI" + g[1:] for g in every_gain)
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


# --- controller/delay.py: the Sensor against the module's definition, in exact arithmetic -----
# The oracle is test_controller_delay._expected: the input sensed at each communication point is
# that of the step holding the latest sample instant t_k = t_start + k * period with
# t_k + delay <= t (the live input at delay 0 on a sample instant), by Fractions. Here in
# seconds, with periods longer than a second and t_start != 0 (the FMU tests run in wing beats
# from 0), and binary-exact times so that the floats are the fractions.

def _sensor_run(steps, delay, period, t0):
    s = delay_mod.Sensor(1, float(t0))
    tm = timing.Timing(float(delay), float(period))
    t, got = F(t0), []
    for m, h in enumerate([*steps, None]):
        x = (float(m + 1),)  # the input set at point m
        got.append(s.sensed(float(t), x, tm, True)[0])
        if h is not None:
            s.advance(float(t), float(h), x, (1.0,), 1.0, tm, False)
            t += h
    return got


@pytest.mark.parametrize("t0", ["0", "0.25", "10"])
@pytest.mark.parametrize("h, delay, period", [
    ("1", "0", "2"), ("1", "3", "2"), ("0.5", "1.5", "2.5"), ("1", "0.25", "0.75"),
    ("0.25", "0", "0.75"), ("2", "1", "3"), ("1", "0", "0"), ("0.5", "1.25", "0"),
])
def test_sensor_senses_the_input_of_the_latest_instant_due(t0, h, delay, period):
    from test_controller_delay import _expected  # (numpy and the slaves: only here)

    steps = [F(h)] * int(12 / F(h))
    got = _sensor_run(steps, F(delay), F(period), F(t0))
    want = [0.0 if i is None else float(i + 1) for i in _expected(steps, F(delay), F(period))]
    assert got == want


def test_sensor_records_the_first_sample_instant_strictly_inside_a_step():
    """Several instants in one step [0, 1) s, period 0.5 s: the one at 0 is on the point, the
    first strictly inside is 0.5 (the FMU's off-grid warning names it)."""
    s = delay_mod.Sensor(1)
    s.advance(0.0, 1.0, (1.0,), (1.0,), 1.0, timing.Timing(0.0, 0.5), False)
    assert s.off_grid == ("a sample instant", 0.5, 0.0, 1.0)


def test_sensor_without_delay_or_sampling_holds_no_line_entry():
    """``current`` is None for a sample without delay (the attribute's definition), and the
    sample is in effect at once."""
    s = delay_mod.Sensor(1)
    s.advance(0.0, 1.0, (2.0,), (1.0,), 1.0, timing.Timing(0.0, 0.0), False)
    assert s.current is None and s.held == (2.0,) and s.t_effect == 0.0 and not s.line


def test_sensor_before_the_first_step_has_no_tolerance_and_after_it_the_drift_counts():
    """The tolerance is 1e-9 of the last communication step plus the drift term (0 before the
    first step): a delay of 5e-10 s is a delay before it, within the tolerance after a 1 s step,
    and 1.5e-9 s is within it only with a drift term of 1e-9 s."""
    x_live = (7.0,)
    s = delay_mod.Sensor(1)
    assert (s.h, s.drift) == (0.0, 0.0)
    assert s.sensed(0.0, x_live, timing.Timing(5e-10, 0.0), True) == (0.0,)
    s.h = 1.0
    assert s.sensed(0.0, x_live, timing.Timing(5e-10, 0.0), True) == x_live
    assert s.sensed(0.0, x_live, timing.Timing(1.5e-9, 0.0), True) == (0.0,)
    s.drift = 1e-9
    assert s.sensed(0.0, x_live, timing.Timing(1.5e-9, 0.0), True) == x_live


def test_integral_takes_the_new_scale_from_the_step_it_changes():
    """z = integral of x / scale * n dt: x = 2 held from 0 s, scale 1 over [0, 1) s and 4 from
    1 s on (n = 1 Hz): z(1) = 2, z(2) = 2 + 2 / 4 = 2.5 (exact)."""
    s = delay_mod.Sensor(1)
    tm = timing.Timing(0.0, 0.0)
    s.advance(0.0, 1.0, (2.0,), (1.0,), 1.0, tm, True)
    assert s.integral(1.0) == (2.0,)
    s.advance(1.0, 1.0, (2.0,), (4.0,), 1.0, tm, True)
    assert s.integral(2.0) == (2.5,)


def test_integral_overflow_names_the_component():
    """x+1 = 1e300 at n = 1e10 Hz for 1 s: z1 overflows; the error names z1 and x+1."""
    s = delay_mod.Sensor(1)
    tm = timing.Timing(0.0, 0.0)
    s.advance(0.0, 1.0, (1e300,), (1.0,), 1e10, tm, True)
    with pytest.raises(timing.SensingError, match=r"integral state z1 = inf \(of x\+1\)"):
        s.advance(1.0, 1.0, (2e300,), (1.0,), 1e10, tm, True)


def test_a_line_of_several_instants_a_step_stops_at_its_bound(monkeypatch):
    """Four sample instants a step (period 0.25 s, steps of 1 s) and a delay of 10 s: one line
    entry a step; with the bound at 2 entries the third step is refused and the line keeps 2."""
    monkeypatch.setattr(delay_mod, "MAX_SAMPLES", 2)
    s = delay_mod.Sensor(1)
    tm = timing.Timing(10.0, 0.25)
    for k in range(2):
        s.advance(float(k), 1.0, (1.0,), (1.0,), 1.0, tm, False)
    assert len(s.line) == 2
    assert [e[2] for e in s.line] == [0.75, 1.75]  # the last instant of each step
    with pytest.raises(timing.SensingError):
        s.advance(2.0, 1.0, (1.0,), (1.0,), 1.0, tm, False)
    assert len(s.line) == 2
    # a saved state holds at most the bound
    state = s.to_dict()
    assert len(delay_mod.Sensor.from_dict(state, 1).line) == 2
    state["line"].append(state["line"][-1])
    with pytest.raises(ValueError, match="more than 2"):
        delay_mod.Sensor.from_dict(state, 1)


@pytest.mark.parametrize("t0, t, h", [(0.0, 0.5, 0.5), (-1.0, -0.5, 0.5), (0.0, 3.0, 0.25),
                                      (-2.0, 1.0, 0.5)])
def test_the_step_tolerance_is_timings(t0, t, h):
    """The drift term kept after a step is that of timing.tolerance (inlined in advance)."""
    s = delay_mod.Sensor(1, t0)
    s.advance(t, h, (1.0,), (1.0,), 1.0, timing.Timing(0.0, 0.0), False)
    assert s.h == h
    assert timing.TOLERANCE * h + s.drift == timing.tolerance(t0, t, h)
    assert s.drift > 0.0


def test_instant_indices_beyond_the_float_range_sample_at_the_point():
    """(t - t_start) / period beyond the float range: the sample is taken at the point, no
    OverflowError (an FMU never crashes)."""
    s = delay_mod.Sensor(1)
    s.advance(1e306, 1.0, (3.0,), (1.0,), 1.0, timing.Timing(0.0, 1e-3), False)
    assert s.held == (3.0,)
    s.h, s.drift = 1e-300, 0.0
    assert s.is_instant(1e10, 1e-300)


def test_a_delay_above_the_tolerance_of_a_short_step_takes_effect_inside_it():
    """Steps of 1 ms: the tolerance is 1e-9 of the step (1e-12 s), so a delay of 1e-7 s is a
    delay: the sample at 0 takes effect at 1e-7 s, strictly inside the step (recorded for the
    off-grid warning), and is in effect at its end."""
    s = delay_mod.Sensor(1)
    s.advance(0.0, 1e-3, (1.0,), (1.0,), 1.0, timing.Timing(1e-7, 0.0), False)
    assert s.off_grid == ("an effect instant", 1e-7, 0.0, 1e-3)
    assert s.held == (1.0,) and s.t_effect == 1e-7


def test_a_new_sample_period_starts_its_own_grid():
    """Period 0.5 s over [0, 2) s (last instant 1.5 s), then 2 s: the instant 2 s = 1 * 2 s of
    the new grid lies in [2, 3) and is taken (delay 0: in effect at once)."""
    s = delay_mod.Sensor(1)
    for k, period in enumerate((0.5, 0.5, 2.0)):
        s.advance(float(k), 1.0, (float(k + 1),), (1.0,), 1.0, timing.Timing(0.0, period), False)
    assert s.held == (3.0,) and s.t_effect == 2.0


def test_a_grid_the_step_cannot_resolve_and_then_can_again():
    """Period 0.5 s: a step of 1e10 s makes the period finer than the step's tolerance (every
    point is an instant); the next 1 s step is on the grid again."""
    s = delay_mod.Sensor(1)
    tm = timing.Timing(0.0, 0.5)
    s.advance(0.0, 1.0, (1.0,), (1.0,), 1.0, tm, False)
    s.advance(1.0, 1e10, (2.0,), (1.0,), 1.0, tm, False)
    assert s.held == (2.0,)
    s.advance(1e10 + 1.0, 1.0, (3.0,), (1.0,), 1.0, tm, False)
    assert s.held == (3.0,)


def test_the_sensor_state_round_trips():
    """to_dict / from_dict: every field back, with and without a grid index."""
    s = delay_mod.Sensor(1, 0.25)
    assert delay_mod.Sensor.from_dict(s.to_dict(), 1).to_dict() == s.to_dict()
    tm = timing.Timing(1.5, 0.5)
    for k in range(3):
        s.advance(0.25 + k, 1.0, (float(k),), (1.0,), 1.0, tm, True)
    assert s.last_k is not None and s.line
    assert delay_mod.Sensor.from_dict(s.to_dict(), 1).to_dict() == s.to_dict()
    assert delay_mod.Sensor(1).t0 == 0.0  # the default start time


def test_integral_action_switched_off_freezes_z():
    """x = 2 integrated over [0, 1) s (z = 2), integral action off from 1 s: z stays 2."""
    s = delay_mod.Sensor(1)
    tm = timing.Timing(0.0, 0.0)
    assert not s.integrating and s.integral(3.0) == (0.0,)
    s.advance(0.0, 1.0, (2.0,), (1.0,), 1.0, tm, True)
    s.advance(1.0, 1.0, (2.0,), (1.0,), 1.0, tm, False)
    assert s.integral(1.0) == s.integral(5.0) == (2.0,)


# --- controller/delay.py: the integral term of a step of several instants, and the grid index
# carried from one step to the next when the step size changes. Oracles: the module's
# definition (each sample instant taken once, by the step that holds it; u uses z at the
# instant the latest sample due took effect) worked by hand, z the closed form
# z(t) = z(t_b) + x+ (t - t_b) n of a held sample (n = 1 Hz, scale 1: x+ = x).

def test_integral_in_effect_stops_at_the_last_instant_of_a_step_entry():
    """From t_start = 10 s, period 0.25 s, delay 0.5 s: the step [10, 11) holds the instants
    10, 10.25, 10.5, 10.75 (one entry, x = 2), in effect from 10.5, 10.75, 11, 11.25 s. Then
    the period becomes 2 s: the next instant is 10 + 2 = 12 s, not in [11, 12), so at t = 12 s
    the latest sample due is still 10.75 s, in effect from 11.25 s (not 12 s). z is 0 up to
    10.5 s (the equilibrium held), then x = 2: z(11.25) = 2 * 0.75 = 1.5 (exact)."""
    s = delay_mod.Sensor(1, 10.0)
    s.advance(10.0, 1.0, (2.0,), (1.0,), 1.0, timing.Timing(0.5, 0.25), True)
    late = timing.Timing(0.5, 2.0)
    s.advance(11.0, 1.0, (3.0,), (1.0,), 1.0, late, True)
    assert s.integral_in_effect(12.0, late, True) == (1.5,)
    assert s.integral(12.0) == (3.0,)  # (what the control would use if 12 s were the instant)


def test_integral_in_effect_snaps_to_the_tolerance_of_a_long_step():
    """Steps of 1024 s: times within 1e-9 of the step (1.024e-6 s) count as equal. Period
    256 s, delay 256 s - 1e-7 s: the instants 0, 256, 512, 768 s of the first step take effect
    1e-7 s before 256, 512, 768 and 1024 s; at the point t = 1024 s the last of them counts as
    in effect at t. z runs from the first effect t_b = 256 - 1e-7 s with x = 1:
    z(1024) = 1024 - t_b = 768 + 1e-7 (z(1024 - 1e-7) = 768 would be the effect instant
    taken as distinct from t)."""
    d = 256.0 - 1e-7
    tm = timing.Timing(d, 256.0)
    s = delay_mod.Sensor(1)
    s.advance(0.0, 1024.0, (1.0,), (1.0,), 1.0, tm, True)
    (z,) = s.integral_in_effect(1024.0, tm, True)
    assert z == pytest.approx(1024.0 - d, abs=1e-10)  # (ulp of 768: 1.1e-13)
    assert abs(z - 768.0) > 9e-8


def test_an_instant_taken_near_the_end_of_a_step_is_not_taken_again_by_a_longer_step():
    """Period 1 s from 0. [0, 1): instant 0 (x = 1). [1, 2.000001): instants 1 and 2 (x = 2; 2 s
    lies 1e-6 s before the step's end, beyond its tolerance of 1e-9 s). [2.000001, 10002.000001)
    with a tolerance of 1e-5 s: instant 2 is already taken; the next is 3 s, x = 4 in effect
    from 3 s (delay 0). z = 1 * 1 + 2 * (3 - 1) + 4 * (10002.000001 - 3)."""
    s = delay_mod.Sensor(1)
    tm = timing.Timing(0.0, 1.0)
    s.advance(0.0, 1.0, (1.0,), (1.0,), 1.0, tm, True)
    s.advance(1.0, 1.000001, (2.0,), (1.0,), 1.0, tm, True)
    t = 1.0 + 1.000001
    s.advance(t, 1e4, (4.0,), (1.0,), 1.0, tm, True)
    assert s.current[0] == 3.0 and s.t_effect == 3.0
    end = t + 1e4
    assert s.integral(end)[0] == pytest.approx(1.0 + 2.0 * 2.0 + 4.0 * (end - 3.0), rel=1e-14)


def test_an_instant_a_long_step_left_to_the_next_is_taken_by_a_shorter_step():
    """Period p = 5000 s - 5e-7 s from 0. [0, 1e4 s) with a tolerance of 1e-5 s holds the
    instants 0 and p; 2p = 1e4 s - 1e-6 s lies within that tolerance of its end, so it belongs
    to the next step [1e4, 1e4 + 1e-3) s (whose own tolerance is far smaller): taken there with
    the input set at 1e4 s (x = 2), in effect at once (delay 0)."""
    p = 5000.0 - 5e-7
    s = delay_mod.Sensor(1)
    tm = timing.Timing(0.0, p)
    s.advance(0.0, 1e4, (1.0,), (1.0,), 1.0, tm, False)
    assert s.current == (0.0, (1.0,), p, p) and s.held == (1.0,)
    s.advance(1e4, 1e-3, (2.0,), (1.0,), 1.0, tm, False)
    assert s.held == (2.0,) and s.current[0] == 2 * p


# Late in a run the tolerance is 1e-9 of the step plus the drift term, capped at 5e-5 of the
# step (timing.DRIFT_CAP): at t = 1e6 s on steps of 1 s from 0 the drift 2^-52 t^2 / h = 2.2e-4 s
# is capped, so times within 5e-5 s count as equal (test_tolerance_is_the_documented_bound).
_LATE = 1e6


def test_late_in_a_run_a_sample_instant_is_sensed_live_and_integrated_up_to_it():
    """Period 1 s, no delay: the instant 1e6 - 1 s takes x = 1 (held from then, z from 0);
    at the instant 1e6 s the live input is sensed and z(1e6) = 1 * 1 s (Sensor.sensed,
    integral_in_effect: the sample at t in effect at once)."""
    s = delay_mod.Sensor(1)
    tm = timing.Timing(0.0, 1.0)
    s.advance(_LATE - 1.0, 1.0, (1.0,), (1.0,), 1.0, tm, True)
    assert s.drift == timing.DRIFT_CAP * 1.0
    assert s.sensed(_LATE, (5.0,), tm, True) == (5.0,)
    assert s.integral_in_effect(_LATE, tm, True) == (1.0,)


def test_late_in_a_run_the_latest_instant_of_a_step_entry_is_found():
    """Period 0.25 s, delay 0.5 s: the step [1e6 - 1, 1e6) takes 4 instants (x = 2), in effect
    from 1e6 - 0.5 s on; at t = 1e6 s the instant 1e6 - 0.5 s takes effect (the third), so
    z = 2 * (1e6 - (1e6 - 0.5)) = 1 (exact), not z at the second (1e6 - 0.25 s: 0.5)."""
    s = delay_mod.Sensor(1)
    tm = timing.Timing(0.5, 0.25)
    s.advance(_LATE - 1.0, 1.0, (2.0,), (1.0,), 1.0, tm, True)
    assert s.integral_in_effect(_LATE, tm, True) == (1.0,)


def test_late_in_a_run_an_instant_left_to_a_shorter_step_is_taken():
    """Period p = 0.5 s - 5e-12 s: the instant 2e6 p = 1e6 s - 1e-5 s lies within the tolerance
    (5e-5 s) of the end of the step [1e6 - 1, 1e6), so that step leaves it to the next, a step
    of 1e-3 s (tolerance 5e-8 s): taken there with the input set at 1e6 s (x = 3, delay 0)."""
    p = 0.5 - 5e-12
    s = delay_mod.Sensor(1)
    tm = timing.Timing(0.0, p)
    s.advance(_LATE - 2.0, 1.0, (1.0,), (1.0,), 1.0, tm, False)
    s.advance(_LATE - 1.0, 1.0, (2.0,), (1.0,), 1.0, tm, False)
    assert s.held == (2.0,) and s.last_k == 2 * 10**6 - 1
    s.advance(_LATE, 1e-3, (3.0,), (1.0,), 1.0, tm, False)
    assert s.held == (3.0,) and s.current[0] == 2e6 * p


def test_instants_on_the_communication_points_are_not_off_the_grid():
    """Period 2 s on steps of 1 s, delay 0 or 1 s: every instant and every effect lands on a
    communication point, so nothing is recorded for the off-grid warning."""
    for d in (0.0, 1.0):
        s = delay_mod.Sensor(1)
        tm = timing.Timing(d, 2.0)
        for k in range(6):
            s.advance(float(k), 1.0, (float(k + 1),), (1.0,), 1.0, tm, False)
        assert s.off_grid is None
        assert s.held == (5.0,)  # the instant 4 s, in effect at 4 s + d <= 6 s


# --- controller/slave.py: the slave classes called in-process (no FMU, no fmpy). Oracles: the
# plants' own classes, the FMI call sequence and the module's documented behaviour.

def _slave(cls, **params):
    s = cls(instance_name="unit")
    s.setup_experiment(0.0)
    s.enter_initialization_mode()
    if params:
        s.set_real([s._vr[n] for n in params], [float(v) for v in params.values()])
    s.exit_initialization_mode()
    return s


def _set(s, values):
    s.set_real([s._vr[n] for n in values], [float(v) for v in values.values()])


@pytest.mark.parametrize("controller, plant, wing_beats", [
    (slave_mod.StateFeedback, DroneFlyLateral, 30),
    (slave_mod.StateFeedbackDelayed, DroneFlyLateral, 30),
    (slave_mod.StateFeedbackLongitudinal, DroneFlyLongitudinal, 60),
    (slave_mod.StateFeedbackLongitudinalDelayed, DroneFlyLongitudinal, 60),
])
def test_a_controllers_default_experiment_is_its_plants(controller, plant, wing_beats):
    """The closed loop runs controller and plant on one grid: the controller's default
    experiment is its plant's, from 0 over 30 (lateral: the open loop diverges) or 60
    (longitudinal: it oscillates) wing beats of 1 / 164 s, in steps of 0.1 wing beat."""
    assert controller.DEFAULT_EXPERIMENT == plant.DEFAULT_EXPERIMENT
    start, stop, step = controller.DEFAULT_EXPERIMENT
    assert start == 0.0
    assert stop * N_HZ == pytest.approx(wing_beats, rel=1e-15)
    assert step * N_HZ == pytest.approx(0.1, rel=1e-15)


@pytest.mark.parametrize("cls", [slave_mod.StateFeedbackDelayed,
                                 slave_mod.StateFeedbackLongitudinalDelayed])
@pytest.mark.parametrize("bad", [math.nan, math.inf])
def test_a_non_finite_input_refuses_the_step_even_when_its_control_comes_later(cls, bad):
    """With a sensing delay the step's own output is the control of an earlier sample, so
    only the input check stops a non-finite value entering the delay line: the step is refused
    naming the input, changes nothing, and the run continues with finite outputs."""
    s = _slave(cls)
    name = s.AXIS.state_names[1]
    h = 0.25 / N_HZ
    assert s.do_step(0.0, h)
    _set(s, {name: bad})
    assert s.do_step(h, h) is False
    assert f"{name} = {bad!r} is not finite" in s.log_queue[-1].msg
    _set(s, {name: 0.5})
    for k in range(1, 12):  # past the delay of one wing beat
        assert s.do_step(k * h, h)
    u = s.get_real([s._vr[c] for c in s.AXIS.control_names])
    assert all(math.isfinite(v) for v in u) and any(u)


def test_the_off_grid_warning_is_once_per_instance_across_a_state_restore():
    """The warning belongs to the instance: a state saved in initialization mode and restored
    after the warning, then initialized and run off the grid again, logs no second one."""
    s = slave_mod.StateFeedbackDelayed(instance_name="unit")
    s.setup_experiment(0.0)
    s.enter_initialization_mode()
    saved = s._get_fmu_state()  # (pythonfmu's fmi2GetFMUstate)
    s.exit_initialization_mode()
    wb = 1.0 / N_HZ
    _set(s, {"sensing_delay": 1.3 * wb})  # effects 0.3 wing beat into a step of one
    assert s.do_step(0.0, wb) and s.do_step(wb, wb)
    assert [m.status for m in s.log_queue] == [1]  # (fmi2Warning)
    s._set_fmu_state(saved)
    _set(s, {"sensing_delay": 1.3 * wb})
    s.exit_initialization_mode()
    for k in range(3):
        assert s.do_step(k * wb, wb)
    assert len(s.log_queue) == 1, [m.msg for m in s.log_queue]


def test_a_state_restored_before_any_warning_still_warns_once():
    """A state saved before any instant fell inside a step and restored at once: the instance has
    not warned yet, so the first off-grid step logs the warning (once)."""
    s = _slave(slave_mod.StateFeedbackDelayed)
    s._set_fmu_state(s._get_fmu_state())
    wb = 1.0 / N_HZ
    _set(s, {"sensing_delay": 1.3 * wb})
    for k in range(3):
        assert s.do_step(k * wb, wb)
    assert [m.status for m in s.log_queue] == [1]


@pytest.mark.parametrize("cls", [slave_mod.StateFeedback, slave_mod.StateFeedbackLongitudinal])
def test_a_non_finite_input_set_just_before_a_step_refuses_it(cls):
    """No output read between the set and the step: the step itself computes u from the new
    input, refuses it naming the input, and changes nothing."""
    s = _slave(cls)
    names = s.AXIS.state_names
    _set(s, {names[0]: 0.25})
    controls = [s._vr[c] for c in s.AXIS.control_names]
    before = s.get_real(controls)
    _set(s, {names[2]: math.nan})
    assert s.do_step(0.0, 0.1 / N_HZ) is False
    assert f"{names[2]} = nan is not finite" in s.log_queue[-1].msg
    _set(s, {names[2]: 0.0})
    assert s.do_step(0.0, 0.1 / N_HZ) and s.get_real(controls) == before


@pytest.fixture
def computations(monkeypatch):
    """The control computations of the controller slaves, counted: each output computation
    (``_outputs_at``) and each run of the value-table law (``FeedbackLaw.on_table``)."""
    calls: list[str] = []
    outputs_at = slave_mod._Feedback._outputs_at
    on_table = feedback.FeedbackLaw.on_table

    def counted_outputs_at(self, *args):
        calls.append("outputs_at")
        return outputs_at(self, *args)

    def counted_on_table(self, *args):
        table = on_table(self, *args)

        def run(r):
            calls.append("on_table")
            return table(r)

        return run

    monkeypatch.setattr(slave_mod._Feedback, "_outputs_at", counted_outputs_at)
    monkeypatch.setattr(feedback.FeedbackLaw, "on_table", counted_on_table)
    return calls


def test_outputs_are_computed_once_per_change(computations):
    """The module's contract: the outputs are recomputed when an output is read after a value
    was set, and at the end of a step; not again for a second read, nor for a step of the law
    without delay, sampling or integral whose outputs (of the inputs, valid at t) hold at t + h."""
    s = _slave(slave_mod.StateFeedback)
    h, reads = 0.1 / N_HZ, [s._vr[c] for c in s.AXIS.control_names]
    computations.clear()
    _set(s, {"delta_p": 0.1})
    s.get_real(reads)
    s.get_real(reads)
    assert len(computations) == 1  # the read after the set
    assert s.do_step(0.0, h)
    s.get_real(reads)
    assert len(computations) == 1  # the outputs of the same inputs hold
    _set(s, {"K[1,1]": 0.5})  # a parameter: the law is rebuilt at the next read
    s.get_real(reads)
    assert len(computations) == 2
    assert s.do_step(h, h)
    assert len(computations) == 2
    _set(s, {"delta_p": 0.2})
    assert s.do_step(2 * h, h)  # the step computes the outputs of the new input ...
    assert len(computations) == 3
    assert s.do_step(3 * h, h)  # ... which hold over the next step
    s.get_real(reads)
    assert len(computations) == 3
    _set(s, {"KI[1,1]": 0.5})  # integral action: every step computes
    assert s.do_step(4 * h, h) and len(computations) == 4
    _set(s, {"KI[1,1]": 0.0})  # off again: the step that freezes z computes, ...
    assert s.do_step(5 * h, h) and len(computations) == 5
    assert s.do_step(6 * h, h) and len(computations) == 5  # ... the next holds the outputs


def test_a_delayed_controller_computes_its_outputs_once_a_step(computations):
    """With a sensing delay the outputs change with the steps only: one computation a step,
    none for reading them."""
    s = _slave(slave_mod.StateFeedbackDelayed)
    h, reads = 0.1 / N_HZ, [s._vr[c] for c in s.AXIS.control_names]
    computations.clear()
    for k in range(3):
        assert s.do_step(k * h, h)
        s.get_real(reads)
        s.get_real(reads)
    assert computations == ["outputs_at"] * 3


def test_an_input_set_between_steps_of_an_integral_law_reads_k_x_plus_ki_z():
    """u = K x+_s + KI z (Eq. 22 with integral action), also for a read right after a set, no
    step between. K = 0 but K[1,4] = 1, KI[1,4] = 0.5; delta_gamma (x+4 = x4, an angle) = 0.1
    over 10 steps of 0.1 wing beat: z4 = 0.1 * 1 wing beat = 0.1. Then delta_gamma = 0.2 is in
    effect at once (no delay): u1 = 1 * 0.2 + 0.5 * 0.1 = 0.25."""
    zero = {f"K[{i + 1},{j + 1}]": 0.0 for i in range(3) for j in range(4)}
    s = _slave(slave_mod.StateFeedback, **{**zero, "K[1,4]": 1.0, "KI[1,4]": 0.5})
    h = 0.1 / N_HZ
    _set(s, {"delta_gamma": 0.1})
    for k in range(10):
        assert s.do_step(k * h, h)
    _set(s, {"delta_gamma": 0.2})
    (u1,) = s.get_real([s._vr["delta_Phi_a"]])
    assert u1 == pytest.approx(0.25, rel=1e-14)  # (z: ten sums of 0.01)


def test_a_logger_that_fails_on_the_off_grid_warning_does_not_fail_the_step(monkeypatch):
    """The warning is logged after the step is committed: if logging it raises, the step is
    still OK (nothing is left to log with)."""
    s = _slave(slave_mod.StateFeedbackDelayed)
    wb = 1.0 / N_HZ
    _set(s, {"sensing_delay": 1.3 * wb})

    def broken(msg, status):
        raise RuntimeError("the logger is gone")

    monkeypatch.setattr(s, "_report", broken)
    assert s.do_step(0.0, wb) and s.do_step(wb, wb)  # the second step warns
    assert s._sensor.off_grid is False and s._time == 2 * wb


def test_samples_pending_when_the_delay_is_set_to_zero_never_take_effect():
    """The output at t is the control of the latest sample with t_k + sensing_delay <= t.
    Delay 2 wing beats while x = 1 (samples pending), then 0 for 4 steps of a wing beat with
    x = 2, then 2 again: at the next points the latest such sample is one of x = 2 (taken at
    most 4 wing beats ago), never a pending one of x = 1."""
    zero = {f"K[{i + 1},{j + 1}]": 0.0 for i in range(3) for j in range(4)}
    wb = 1.0 / N_HZ
    s = _slave(slave_mod.StateFeedback, **{**zero, "K[1,4]": 1.0}, sensing_delay=2 * wb)
    read = [s._vr["delta_Phi_a"]]
    t = 0.0
    _set(s, {"delta_gamma": 1.0})
    for _ in range(2):
        assert s.do_step(t, wb)
        t += wb
    _set(s, {"sensing_delay": 0.0, "delta_gamma": 2.0})
    assert s.get_real(read) == [2.0]
    for _ in range(4):
        assert s.do_step(t, wb)
        t += wb
        assert s.get_real(read) == [2.0]
    _set(s, {"sensing_delay": 2 * wb})
    for _ in range(3):
        assert s.do_step(t, wb)
        t += wb
        assert s.get_real(read) == [2.0]


def test_a_controller_class_keeps_at_most_laws_parameter_sets():
    """slave.LAWS bounds the validated laws a class keeps for its instances (oldest first)."""
    s = _slave(slave_mod.StateFeedbackLongitudinal)
    for k in range(slave_mod.LAWS + 5):
        _set(s, {"K[1,1]": 0.01 * (k + 1)})
        s.get_real([s._vr[s.AXIS.control_names[0]]])
    laws = slave_mod.StateFeedbackLongitudinal._LAWS
    assert len(laws) == slave_mod.LAWS
    assert s._law_key in laws


@pytest.mark.parametrize("read_between", [False, True])
def test_integral_action_off_freezes_z_and_on_again_resumes_it(read_between):
    """z integrates while integral action is on (any KI non-zero): KI[1,4] = 1 and
    delta_gamma = 0.1 for 10 steps of 0.1 wing beat (z4 = 0.1 * 1 = 0.1), KI = 0 for 10 steps
    (z frozen; the outputs read or not between set and step), KI[1,4] = 1 again: u1 = KI z4
    = 0.1 at once (K = 0), and 0.1 + 0.1 * 1 after 10 more steps."""
    zero = {f"K[{i + 1},{j + 1}]": 0.0 for i in range(3) for j in range(4)}
    s = _slave(slave_mod.StateFeedback, **zero, **{"KI[1,4]": 1.0})
    h, read = 0.1 / N_HZ, [s._vr["delta_Phi_a"]]
    _set(s, {"delta_gamma": 0.1})
    for k in range(10):
        assert s.do_step(k * h, h)
    _set(s, {"KI[1,4]": 0.0})
    if read_between:
        assert s.get_real(read) == [0.0]
    for k in range(10, 20):
        assert s.do_step(k * h, h)
    _set(s, {"KI[1,4]": 1.0})
    assert s.get_real(read)[0] == pytest.approx(0.1, rel=1e-14)  # (ten sums of 0.01)
    for k in range(20, 30):
        assert s.do_step(k * h, h)
    assert s.get_real(read)[0] == pytest.approx(0.2, rel=1e-14)


@pytest.mark.parametrize("missing", ["_law", "_timing"])
def test_a_step_makes_a_law_or_timing_it_lacks(missing):
    """The base class makes the law and the timing before any step; if one were missing, the
    step makes it from the parameters: the same outputs as an intact instance's."""
    a, b = _slave(slave_mod.StateFeedbackDelayed), _slave(slave_mod.StateFeedbackDelayed)
    wb = 1.0 / N_HZ
    for s in (a, b):
        _set(s, {"delta_gamma": 0.1, "delta_v": 0.2})
        assert s.do_step(0.0, wb)
    setattr(b, missing, None)
    reads = [a._vr[c] for c in a.AXIS.control_names]
    for k in range(1, 4):
        assert a.do_step(k * wb, wb) and b.do_step(k * wb, wb)
        assert b.get_real(reads) == a.get_real(reads) and any(a.get_real(reads))
