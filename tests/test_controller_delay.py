"""Sensing delay, sampling and integral action of the controller FMUs.

The oracle of the timing is exact: times in wing beats as Fractions. The delayed output at a
communication point t must be, bit for bit, what the undelayed controller output for the input
of the latest sample instant t_k with t_k + sensing_delay <= t (the equilibrium, u = 0, before
the first). Unit tests drive the slave classes directly; a few run the built FMUs through fmpy.
"""

from __future__ import annotations

import math
from fractions import Fraction as F

import numpy as np
import pytest

from dronefly.controller import delay as D
from dronefly.controller import timing as T
from dronefly.models import feedback as L
from dronefly.controller.slave import (StateFeedback, StateFeedbackDelayed,
    StateFeedbackLongitudinalDelayed)
from dronefly.models.lateral_interface import CONTROL_NAMES, N_HZ, STATE_NAMES
from fmu_helpers import model_description

WB = 1.0 / N_HZ  # one wing beat [s]
KI_NAMES = [L.integral_gain_name(i, j) for i in range(3) for j in range(4)]


# -- helpers -----------------------------------------------------------------------------------
def _slave(cls=StateFeedback, **params: float):
    s = cls(instance_name="unit")
    s.setup_experiment(0.0)
    s.enter_initialization_mode()
    _set(s, params)
    s.exit_initialization_mode()
    return s


def _set(s, values: dict[str, float]) -> None:
    if values:
        s.set_real([s._vr[n] for n in values], [float(v) for v in values.values()])


def _controls(s) -> list[float]:
    return s.get_real([s._vr[n] for n in CONTROL_NAMES])


def _messages(s) -> list[str]:
    return [m.msg for m in s.log_queue]


def _inputs(n: int, seed: int = 5) -> np.ndarray:
    """n random dimensional states of a disturbed hover."""
    return np.random.default_rng(seed).normal(0.0, 1.0, (n, 4)) * [0.1, 5.0, 3.0, 0.1]


def _expected(steps: list[F], delay: F, period: F) -> list[int | None]:
    """For each communication point m, the index of the point whose input is sensed there:
    the step holding the latest sample instant t_k < t_m with t_k + delay <= t_m; m itself
    (the live input) at delay 0 on a sample instant; None (the equilibrium) before any."""
    points = [F(0)]
    for h in steps:
        points.append(points[-1] + h)
    out: list[int | None] = []
    for m, t in enumerate(points):
        if delay == 0 and (period == 0 or t % period == 0):
            out.append(m)
            continue
        latest = t - delay  # the latest instant in effect: <= t - delay, and before t
        if period == 0:
            due = [i for i in range(m) if points[i] <= latest]
            out.append(due[-1] if due else None)
            continue
        if latest < 0:
            out.append(None)
            continue
        s = (latest // period) * period  # < t: delay > 0, or t is no sample instant
        out.append(max(i for i in range(m) if points[i] <= s))
    return out


def _run(cls, steps: list[F], delay: F, period: F, xs: np.ndarray) -> tuple[list, list]:
    """Outputs at every communication point (after the input there was set) of a controller
    with the given timing, and of the undelayed one for the same inputs."""
    s = _slave(cls, sensing_delay=float(delay * F(1, 164)) if delay else 0.0,
               sample_period=float(period * F(1, 164)))
    ref = _slave(StateFeedback)
    got, want = [], []
    t = 0.0
    for m, h in enumerate([*steps, None]):
        for inst in (s, ref):
            _set(inst, dict(zip(STATE_NAMES, xs[m])))
        got.append(_controls(s))
        want.append(_controls(ref))
        if h is not None:
            hs = float(h) * WB
            assert s.do_step(t, hs) and ref.do_step(t, hs), _messages(s)[-1:]
            t += hs
    return got, want


# -- the delayed output equals the input sampled sensing_delay earlier, exactly --------------
CASES = [(F(h), F(d), F(p)) for h in ("0.1", "0.5", "1") for d in (1, 2, 3) for p in (0, 1)]
CASES += [(F("0.1"), F("0.25"), F(0)), (F("0.5"), F("1.3"), F(0)), (F("0.5"), F(1), F("0.7")),
          (F(1), F("0.4"), F("0.3")), (F("0.1"), F(0), F("0.7"))]


@pytest.mark.parametrize("h,delay,period", CASES, ids=lambda v: str(v))
def test_delayed_output_is_the_input_sampled_the_delay_earlier_exactly(h, delay, period):
    """Steps of 0.1, 0.5, 1 wing beat; delays of 1, 2, 3 wing beats and delays that are not a
    multiple of the step; sample period 0 and 1 wing beat, and 0.7 and 0.3 (not multiples)."""
    n = int(12 / h)
    steps = [h] * n
    xs = _inputs(n + 1)
    cls = StateFeedbackDelayed if delay > 0 else StateFeedback
    for c in {cls, StateFeedback}:
        got, want = _run(c, steps, delay, period, xs)
        for m, i in enumerate(_expected(steps, delay, period)):
            assert got[m] == (want[i] if i is not None else [0.0, 0.0, 0.0]), (c, m, i)


def test_variable_steps_are_honoured_too():
    """Steps of 0.05 to 1.35 wing beats in random order; delay 2 wb, period 0.7 wb: effect
    times fall inside steps and on communication points (the 1e-9 tolerance)."""
    rng = np.random.default_rng(11)
    steps = [F(int(k), 20) for k in rng.integers(1, 28, 60)]
    xs = _inputs(len(steps) + 1, seed=3)
    for delay, period in ((F(2), F(7, 10)), (F(3, 2), F(0)), (F(1, 20), F(1, 20))):
        got, want = _run(StateFeedbackDelayed, steps, delay, period, xs)
        for m, i in enumerate(_expected(steps, delay, period)):
            assert got[m] == (want[i] if i is not None else [0.0, 0.0, 0.0]), (delay, m, i)


@pytest.mark.parametrize("h_wb", [1.0, 0.1])
def test_a_long_run_on_the_grid_stays_on_it(h_wb):
    """12000 steps, the time added up step by step as masters do (it drifts by more than
    1e-9 of a step after about 2000): delay and period 1 wing beat stay on the grid, so every
    output is the control of the input set one wing beat earlier and nothing is logged.
    (With the tolerance 1e-9 h alone a sample would fall into the step before its own: the
    output would be wrong from step 6855 on steps of 1 wing beat and 10029 on 0.1.)"""
    h = h_wb * WB
    cross = next(m for m in range(1, 10**4) if T.tolerance(0.0, m * h, h) > 2 * T.TOLERANCE * h)
    assert 2000 < cross < 2200  # docs: the drift passes 1e-9 of a step after about 2000 steps
    s = _slave(StateFeedbackDelayed, sensing_delay=WB, sample_period=WB)
    law = L.FeedbackLaw(L.default_gains())
    per = round(1 / h_wb)
    xs = _inputs(12000 // per + 2, seed=13)
    t = 0.0
    for m in range(12000):
        _set(s, dict(zip(STATE_NAMES, xs[m // per])))
        assert s.do_step(t, h)
        t += h
        if (m + 1) % per == 0:  # a whole wing beat: the sample of the previous one in effect
            k = (m + 1) // per - 1
            assert _controls(s) == list(law.evaluate(list(xs[k]))[0]), m
    assert _messages(s) == []
    # the step's tolerance (inlined in Sensor.advance) is timing.tolerance at its start
    assert T.TOLERANCE * h + s._sensor.drift == pytest.approx(T.tolerance(0.0, t - h, h),
                                                              rel=1e-9)


@pytest.mark.parametrize("h_wb", [1.0, 0.5, 0.1])
def test_summed_steps_stay_within_the_drift_cap_for_a_million_steps(h_wb):
    """The drift cap's premise (timing.DRIFT_CAP, 5e-5 of a step): a master that adds up its
    steps, for the 1e6 steps the project's masters allow, stays within it: at most 2.4e-5 of
    a step from the exact sum m h (Fractions) on steps of 1 and 0.5 wing beat, 9e-7 on 0.1."""
    from dronefly.harness.cosim.records import MAX_STEPS

    h = h_wb * WB
    exact, t, worst = F(h), 0.0, F(0)
    for k in range(1, MAX_STEPS // 1000 + 1):
        for _ in range(1000):
            t += h
        worst = max(worst, abs(F(t) - k * 1000 * exact))
    assert worst / exact <= 2.4e-5 < T.DRIFT_CAP == 5e-5  # controller/README.md
    assert 4.6e5 < math.sqrt(T.DRIFT_CAP / T.DRIFT) < 4.8e5  # the cap reached after 4.7e5 steps
    assert 6.6e5 < math.sqrt(1e-4 / T.DRIFT) < 6.8e5  # uncapped: 1e-4 h after 6.7e5 steps
    assert float(worst) < T.tolerance(0.0, t, h) - T.TOLERANCE * h  # still on the grid


@pytest.mark.parametrize("m", [1, 10**6])
def test_an_effect_just_off_the_grid_stays_off_it_after_a_million_steps(m):
    """An effect 1e-4 step after a communication point is inside the next step, the same at
    step 1 and step 1e6 (t = k h computed directly, as fmpy's master does): in effect from the
    point after, the latency unchanged mid-run. (Without the drift cap the drift term would reach
    2.2e-4 of a step by 1e6 steps and snap the effect onto the point before.)"""
    h, d = WB, WB * (1.0 + 1e-4)
    timing, x, scale = T.Timing(sensing_delay=d), (0.1, 5.0, 3.0, 0.1), (1.0,) * 4
    s = D.Sensor(4, 0.0)
    t = (m - 1) * h
    s.advance(t, h, x, scale, N_HZ, timing, False)  # samples x at t: effect at t + h + 1e-4 h
    assert s.held == (0.0,) * 4 and len(s.line) == 1 and s.off_grid is None  # not yet at t + h
    s.advance(t + h, h, x, scale, N_HZ, timing, False)
    assert s.held == x and s.off_grid == ("an effect instant", t + d, t + h, h)
    assert T.tolerance(0.0, m * h, h) <= (T.TOLERANCE + T.DRIFT_CAP) * h < 1e-4 * h


def test_undo_restores_every_field_and_the_line():
    """After steps that append to the line, put samples into effect and switch integral action
    on, undo gives back the sensor as it was before each step: every field, the line's
    entries (popped ones back at its front, appended ones gone) and the deque itself."""
    timing, scale = T.Timing(sensing_delay=2 * WB, sample_period=0.5 * WB), (1.0, 2.0, 3.0, 4.0)
    s = D.Sensor(4, 0.0)
    line = s.line
    for k in range(8):
        x = (0.1 * k, 0.2, -0.3 * k, 0.4)
        before = (repr(s), list(s.line))
        token = s.advance(k * WB, WB, x, scale, N_HZ, timing, k >= 3)
        assert repr(s) != before[0]
        s.undo(token)
        assert (repr(s), list(s.line)) == before and s.line is line
        s.advance(k * WB, WB, x, scale, N_HZ, timing, k >= 3)
    assert s.integrating and any(s.z0) and s.current is not None and s.line


def test_the_off_grid_warning_cannot_fail_the_committed_step(monkeypatch):
    """The warning is formed after the step's state moved on. Steps of 1e306 s with samples
    every 0.7e306 s: an instant inside the first step, and a latency grid that leaves float
    range (its instant index would be math.ceil(inf): OverflowError after the sensor has
    advanced). The step is OK, its result kept, and the warning logged; if the
    warning still cannot be formed, a plain one is logged and the step is OK as well."""
    h = 1e306
    for broken in (False, True):
        if broken:
            def fail(*args, **kwargs):
                raise OverflowError("int too large to convert to float")

            monkeypatch.setattr(T.Timing, "off_grid_warning", fail)
        s = _slave(StateFeedback, sample_period=0.7e306)
        _set(s, dict(zip(STATE_NAMES, [0.1, 5.0, 3.0, 0.1])))
        assert s.do_step(0.0, h), _messages(s)
        assert s._time == h and s._sensor.last_k == 1 and s._sensor.off_grid is False
        assert _controls(s) == list(L.FeedbackLaw(L.default_gains()).evaluate(
            [0.1, 5.0, 3.0, 0.1])[0])
        [msg] = s.log_queue
        assert msg.status == 1 and "sample_period = 7e+305 s" in msg.msg, msg.msg
        assert ("latency the importer sees could not be computed" in msg.msg) == broken
        if not broken:
            assert "(FMI 2.0 co-simulation)" in msg.msg and "0 to 1 steps" in msg.msg
        assert s.do_step(h, h) and len(s.log_queue) == 1  # warned once


def test_zero_delay_and_period_is_the_old_law_bit_for_bit():
    """Defaults (no delay, no sampling, KI = 0): u = K x+ of the current input at once."""
    s = _slave()
    law = L.FeedbackLaw(L.default_gains())
    t = 0.0
    for x in _inputs(50, seed=8):
        _set(s, dict(zip(STATE_NAMES, x)))
        assert _controls(s) == list(law.evaluate(list(x))[0])
        assert s.do_step(t, 0.1 * WB)
        assert _controls(s) == list(law.evaluate(list(x))[0])
        t += 0.1 * WB


# -- integral action -----------------------------------------------------------------------
@pytest.mark.parametrize("delay_wb", [0, 1])
def test_integral_of_a_constant_input_is_KI_x_t_plus_exactly(delay_wb):
    """K = 0, KI[1,4] = k, delta_gamma = x (x+ = x): delta_Phi_a = k (x (t - t_e) n), t_e the
    instant the sample takes effect (the start, or the communication point t0 + delay)."""
    k, x, h = -0.37, 0.0123, 0.1 * WB
    zero = {L.gain_name(i, j): 0.0 for i in range(3) for j in range(4)}
    s = _slave(StateFeedbackDelayed if delay_wb else StateFeedback, **zero, **{"KI[1,4]": k},
               sensing_delay=delay_wb * WB)
    _set(s, {"delta_gamma": x})
    t, t_e = 0.0, None if delay_wb else 0.0
    for m in range(40):
        assert s.do_step(t, h)
        t = t + h
        if t_e is None and m == 9:  # 10 steps of 0.1 wing beat: the sample of t0 takes effect
            t_e = t
        u = _controls(s)[0]
        assert u == (k * (x * ((t - t_e) * N_HZ)) if t_e is not None else 0.0), m


@pytest.mark.parametrize("h,delay,period", [(F(1, 2), F(13, 10), F(7, 10)),
                                            (F(1), F(2, 5), F(3, 10)),
                                            (F(1, 2), F(1), F(3, 10))], ids=str)
def test_integral_follows_the_held_sensed_state_exactly(h, delay, period):
    """Mid-step effects (period 0.7, delay 1.3 wing beats, steps of 0.5; and periods of 0.3,
    shorter than the step, so several instants fall in one step and take effect one by one):
    the control is computed when a sample takes effect and held, so z is the exact integral of
    the held sensed signal (Fractions) up to the instant the sample in effect took effect, to
    rounding: every instant of a step counts, not only the first (at delay 0.4, period 0.3,
    step 1 the control at t = 1 is KI z(1.0), not KI z(0.4))."""
    n = 40
    xs = _inputs(n + 1, seed=2)
    ki = np.random.default_rng(4).normal(0.0, 1.0, (3, 4))
    s = _slave(StateFeedback, **dict(zip(KI_NAMES, ki.ravel())),
               **{g: 0.0 for g in [L.gain_name(i, j) for i in range(3) for j in range(4)]},
               sensing_delay=float(delay) * WB, sample_period=float(period) * WB)
    scale = np.array(L.FeedbackLaw(L.default_gains()).scale)
    t = 0.0
    # effects: sample k*period (input of its step) in effect from k*period + delay
    effects = [(k * period + delay, xs[int(k * period / h)] / scale)
               for k in range(int(n * h / period) + 1)]
    for m in range(n):
        _set(s, dict(zip(STATE_NAMES, xs[m])))
        assert s.do_step(t, float(h) * WB)
        t += float(h) * WB
        end = (m + 1) * h
        z = np.zeros(4)
        last = max((a for a, _ in effects if a <= end), default=None)  # in effect at end
        for (a, xp), (b, _) in zip(effects, effects[1:]):
            if last is not None and a < last:
                z += xp * float(min(b, last) - a)  # t+ in wing beats
        np.testing.assert_allclose(_controls(s), ki @ z, rtol=1e-12, atol=1e-15)


def test_integral_action_switched_on_later_starts_from_zero():
    """z integrates while any KI is non-zero: gains set at t1 integrate from t1 on."""
    s = _slave(StateFeedback, **{g: 0.0 for g in [L.gain_name(i, j) for i in range(3)
                                                   for j in range(4)]})
    _set(s, {"delta_gamma": 0.5})
    h = 0.5 * WB
    for m in range(4):
        assert s.do_step(m * h, h)
    assert _controls(s) == [0.0, 0.0, 0.0]
    _set(s, {"KI[2,4]": 2.0})
    t = 4 * h
    for m in range(4):
        assert s.do_step(t, h)
        t += h
    assert _controls(s)[1] == pytest.approx(2.0 * 0.5 * 2.0, rel=1e-14)  # 4 steps of 0.5 wb


# -- refusals --------------------------------------------------------------------------------
@pytest.mark.parametrize("name,value,cls,fragment", [
    ("sensing_delay", -WB, StateFeedback, "must be finite and >= 0"),
    ("sensing_delay", math.nan, StateFeedback, "must be finite and >= 0"),
    ("sensing_delay", math.inf, StateFeedbackDelayed, "must be finite and >= 0"),
    ("sample_period", -1e-3, StateFeedback, "must be finite and >= 0"),
    ("sample_period", math.nan, StateFeedbackDelayed, "must be finite and >= 0"),
    ("sensing_delay", 0.0, StateFeedbackDelayed, "must be > 0 in this FMU"),
    ("KI[2,3]", math.nan, StateFeedback, "is not finite"),
])
def test_bad_timing_is_refused_with_discard_and_the_instance_stays_usable(name, value, cls,
                                                                          fragment):
    s = _slave(cls)
    _set(s, {"delta_p": 1.0})
    assert s.do_step(0.0, 0.1 * WB)
    before = _controls(s)
    _set(s, {name: value})
    assert s.do_step(0.1 * WB, 0.1 * WB) is False
    assert f"{name} = {value!r}" in _messages(s)[-1] and fragment in _messages(s)[-1]
    assert _controls(s) == before
    _set(s, {name: 0.0 if name.startswith("KI") or name == "sample_period" else WB})
    assert s.do_step(0.1 * WB, 0.1 * WB)


def test_a_delay_line_past_the_memory_bound_is_refused(monkeypatch):
    """By the estimate (delay / max(step, period) > MAX_SAMPLES) and by the line itself (a
    delay raised while running keeps the samples taken); the message names sensing_delay,
    sample_period and the step; the refused step changes nothing."""
    s = _slave(StateFeedbackDelayed)  # one wing beat of delay
    h = WB / (D.MAX_SAMPLES + 1)
    assert s.do_step(0.0, h) is False
    msg = _messages(s)[-1]
    assert f"sensing_delay = {WB!r} s" in msg and "sample_period = 0.0 s" in msg
    assert f"communication step of {h!r} s" in msg and "memory bound" in msg
    _set(s, {"sample_period": 0.1 * WB})  # one sample per 0.1 wing beat: 10 in the line
    assert s.do_step(0.0, h)
    monkeypatch.setattr(D, "MAX_SAMPLES", 8)  # the line
    monkeypatch.setattr(T, "MAX_SAMPLES", 8)  # the estimate and its message
    s = _slave(StateFeedbackDelayed)
    t, x = 0.0, _inputs(40)
    for m in range(16):  # steps of 0.125 wing beat: 8 samples within the delay at most
        _set(s, dict(zip(STATE_NAMES, x[m])))
        assert s.do_step(t, 0.125 * WB), _messages(s)[-1:]
        t += 0.125 * WB
    assert len(s._sensor.line) == 7  # taken within the last wing beat, not in effect yet
    _set(s, {"sensing_delay": 2 * WB})  # 2 wb / 0.25 wb = 8 by the estimate, but the line
    _set(s, dict(zip(STATE_NAMES, x[16])))  # still holds the samples of the smaller steps
    assert s.do_step(t, 0.25 * WB) and len(s._sensor.line) == 8
    _set(s, dict(zip(STATE_NAMES, x[17])))
    before = s._sensor.to_dict()
    assert s.do_step(t + 0.25 * WB, 0.25 * WB) is False
    assert "more than 8 samples (memory bound)" in _messages(s)[-1]
    assert s._sensor.to_dict() == before


def test_a_refused_step_changes_nothing_in_the_sensor():
    """K x+ overflowing when a huge delayed sample takes effect: the step is refused, and the
    delay line, the sample in effect and the integral are as before it."""
    s = _slave(StateFeedbackDelayed, **{"K[1,1]": 1e308, "KI[2,2]": 0.5},
               sensing_delay=0.2 * WB)
    t = 0.0
    for m, v in enumerate((0.1, 0.2, 1e300, 0.3)):  # 1e300 sampled at 0.2, in effect at 0.4
        _set(s, {"delta_v": v, "delta_p": 1.0})
        before = s._sensor.to_dict()
        ok = s.do_step(t, 0.1 * WB)
        t += 0.1 * WB
        assert ok is (m < 3), m
    assert "delta_Phi_a = inf is not finite (K x+ + KI z overflows)" in _messages(s)[-1]
    assert s._sensor.to_dict() == before and before["line"][0][1][0] == 1e300
    assert any(before["z0"])


# -- the FMU state -----------------------------------------------------------------------------
@pytest.mark.parametrize("h_wb", [0.2, 0.7])
def test_state_round_trip_holds_the_delay_line_and_the_integral(h_wb):
    """Period 0.3 wb on steps of 0.2 (one instant per step at most) and of 0.7 (two or three:
    entries with their last instant, and the sample in effect, are part of the state)."""
    s = _slave(StateFeedbackDelayed, **{"KI[1,2]": 0.3}, sensing_delay=2.5 * WB,
               sample_period=0.3 * WB)
    xs, h = _inputs(60, seed=9), h_wb * WB

    def run(a: int, b: int) -> list:
        out = []
        for m in range(a, b):
            _set(s, dict(zip(STATE_NAMES, xs[m])))
            assert s.do_step(m * h, h)
            out.append(_controls(s))
        return out

    run(0, 20)
    assert len(s._sensor.line) > 1 and any(s._sensor.z0)
    assert (len(s._sensor.current) == 4) is (h_wb > 0.3)  # several instants in the step
    state = s._get_fmu_state()
    blob = type(s)._fmu_state_to_bytes(state)
    first = run(20, 60)
    s._set_fmu_state(state)
    assert run(20, 60) == first
    s._set_fmu_state(type(s)._fmu_state_from_bytes(blob))
    assert run(20, 60) == first


# -- through fmpy, on the built FMUs ----------------------------------------------------------
@pytest.fixture(scope="module")
def fmus(built_fmus):
    from dronefly.harness.cosim.fmu import FMU

    opened = {n: FMU(built_fmus[n]) for n in ("StateFeedback", "StateFeedbackDelayed")}
    yield opened
    for f in opened.values():
        f.close()


def _start(inst, values: dict[str, float]) -> None:
    s = inst.slave
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    if values:
        s.setReal(inst.vrs(list(values)), list(values.values()))
    s.exitInitializationMode()


def _fmpy_run(inst, h: float, xs: np.ndarray, m0: int = 0) -> list:
    """Set each input, step from (m0 + m) h, read the controls."""
    s, out = inst.slave, []
    for m, x in enumerate(xs, start=m0):
        s.setReal(inst.vrs(STATE_NAMES), list(x))
        s.doStep(m * h, h)
        out.append(list(s.getReal(inst.vrs(CONTROL_NAMES))))
    return out


def _built_run(fmus, name: str, h: F, delay: F, period: F) -> list:
    """Run the built FMU ``name`` with the timing on steps of ``h`` wing beats and check each
    output against the oracle; its log messages."""
    n = int(8 / h)
    xs = _inputs(n, seed=6)
    steps = [h] * n
    with fmus[name].instantiate("d") as a, fmus["StateFeedback"].instantiate("r") as r:
        _start(a, {"sensing_delay": float(delay) * WB, "sample_period": float(period) * WB})
        _start(r, {})
        got = _fmpy_run(a, float(h) * WB, xs)
        # the undelayed FMU's output for each input, read before its step
        want = []
        for m, x in enumerate(xs):
            r.slave.setReal(r.vrs(STATE_NAMES), list(x))
            want.append(list(r.slave.getReal(r.vrs(CONTROL_NAMES))))
            r.slave.doStep(m * float(h) * WB, float(h) * WB)
        messages = list(a.messages)
    for m, i in enumerate(_expected(steps, delay, period)[1:], start=1):  # after step m-1
        assert got[m - 1] == (want[i] if i is not None else [0.0, 0.0, 0.0]), (m, i)
    return messages


@pytest.mark.integration
@pytest.mark.parametrize("name,h,delay,period", [
    ("StateFeedbackDelayed", F("0.1"), F(3), F(0)),
    ("StateFeedbackDelayed", F("0.5"), F(2), F(1)),
    ("StateFeedback", F(1), F(1), F(0)),
    ("StateFeedbackDelayed", F("0.1"), F("0.5"), F("0.3")),
])
def test_built_fmus_output_the_input_sampled_the_delay_earlier(fmus, name, h, delay, period):
    """On the grid (delay and period whole numbers of steps): exact, and nothing logged."""
    assert _built_run(fmus, name, h, delay, period) == []


@pytest.mark.integration
@pytest.mark.parametrize("h,delay,period,what,seen", [
    (F(1), F("0.4"), F("0.3"), "a sample instant", "1 step(s)"),
    (F("0.5"), F("1.3"), F(0), "an effect instant", "3 step(s)"),
    (F("0.5"), F(1), F("0.7"), "a sample instant", "2 to 3 steps"),
    (F("0.1"), F("0.25"), F(0), "an effect instant", "3 step(s)"),
])
def test_built_fmu_warns_once_off_the_grid_and_computes_as_stated(fmus, h, delay, period,
                                                                    what, seen):
    """A sample or effect instant inside a communication step: the values are the oracle's
    (held input sampled, control visible from the next communication point), and one warning
    (fmi2Warning, logStatusWarning) names both values, the step and the latency the importer
    sees: delay 0.4 wb sampled every 0.3 wb on steps of 1 wb is seen as 1 step; 1.3 wb on
    steps of 0.5 as 3 steps (1.5 wb); delay 1, period 0.7 on steps of 0.5 as 2 or 3 steps;
    0.25 wb on steps of 0.1 as 3 steps."""
    messages = _built_run(fmus, "StateFeedbackDelayed", h, delay, period)
    assert len(messages) == 1, messages
    msg = messages[0]
    assert (msg.status, msg.category) == (1, "logStatusWarning")
    hs = float(h) * WB
    for part in (f"sensing_delay = {float(delay) * WB!r} s",
                 f"sample_period = {float(period) * WB!r} s",
                 f"communication step of {hs!r} s: {what} (t = ",
                 "samples the input held since the start of the step",
                 "visible from the next communication point on",
                 f"input set at a communication point {seen} ("):
        assert part in msg.message, (part, msg.message)


@pytest.mark.integration
def test_built_fmu_refuses_bad_timing_with_discard_and_recovers(fmus):
    from fmpy.fmi1 import FMICallException

    fmu = fmus["StateFeedbackDelayed"]
    with fmu.instantiate("bad") as inst:
        _start(inst, {})
        s, h = inst.slave, 0.1 * WB
        s.doStep(0.0, h)
        for name, value in (("sensing_delay", -WB), ("sensing_delay", math.nan),
                            ("sensing_delay", 0.0), ("sample_period", math.inf)):
            s.setReal([fmu.vr(name)], [value])
            with pytest.raises(FMICallException) as e:
                s.doStep(h, h)
            assert e.value.status == 2  # fmi2Discard
            assert f"{name} = {value!r}" in inst.messages[-1].message
            s.setReal([fmu.vr(name)], [WB if name == "sensing_delay" else 0.0])
        with pytest.raises(FMICallException):  # a line of more than 100000 samples
            s.doStep(h, WB / 200_000)
        assert "sensing_delay" in inst.messages[-1].message
        assert "sample_period" in inst.messages[-1].message
        s.doStep(h, h)  # usable


@pytest.mark.integration
def test_built_fmu_state_round_trip_and_reset(fmus):
    """get/set and serialize/deserialize with samples in the line and z != 0; fmi2Reset
    empties both: a run after reset equals a fresh instance's."""
    fmu = fmus["StateFeedbackDelayed"]
    xs, h = _inputs(40, seed=12), 0.3 * WB
    params = {"sensing_delay": 2.2 * WB, "sample_period": 0.5 * WB, "KI[1,4]": 0.2}
    with fmu.instantiate("st") as inst:
        _start(inst, params)
        s = inst.slave
        first = _fmpy_run(inst, h, xs[:40])
        s.reset()
        _start(inst, params)
        assert list(s.getReal(inst.vrs(CONTROL_NAMES))) == [0.0, 0.0, 0.0]
        assert _fmpy_run(inst, h, xs[:40]) == first
        s.reset()
        _start(inst, params)
        _fmpy_run(inst, h, xs[:15])
        state = s.getFMUstate()
        blob = s.serializeFMUstate(state)
        cont = _fmpy_run(inst, h, xs[15:], m0=15)
        assert cont == first[15:]
        s.setFMUstate(state)
        assert _fmpy_run(inst, h, xs[15:], m0=15) == cont
        restored = s.deSerializeFMUstate(blob)
        s.setFMUstate(restored)
        assert _fmpy_run(inst, h, xs[15:], m0=15) == cont
        s.freeFMUstate(restored)
        s.freeFMUstate(state)
    assert b'"line":[[' in bytes(blob) and b'"integrating":true' in bytes(blob)


@pytest.mark.integration
def test_model_structure_of_both_variants(built_fmus):
    """Feedthrough FMUs: the outputs depend on the four inputs (conservative, exact at delay
    0). Delayed variants: on no input, at initialization on nothing; delay one wing beat."""
    for name, delayed in (("StateFeedback", False), ("StateFeedbackDelayed", True),
                          ("StateFeedbackLongitudinalDelayed", True)):
        root = model_description(built_fmus[name])
        svs = root.find("ModelVariables").findall("ScalarVariable")
        idx = {sv.get("name"): i + 1 for i, sv in enumerate(svs)}
        by_name = {sv.get("name"): sv for sv in svs}
        inputs = [n for n in idx if by_name[n].get("causality") == "input"]
        outputs = [n for n in idx if by_name[n].get("causality") == "output"]
        deps = {int(u.get("index")): u.get("dependencies")
                for u in root.find("ModelStructure/Outputs")}
        init = {int(u.get("index")): u.get("dependencies")
                for u in root.find("ModelStructure/InitialUnknowns")}
        assert sorted(deps) == sorted(init) == sorted(idx[n] for n in outputs)
        if delayed:
            assert set(deps.values()) == set(init.values()) == {""}
        else:
            assert set(deps.values()) == {" ".join(str(idx[n]) for n in inputs)}
            assert all(str(idx["sensing_delay"]) in d.split() for d in init.values())
        for v in ("sensing_delay", "sample_period"):
            real = by_name[v].find("Real")
            assert (real.get("unit"), real.get("displayUnit"), by_name[v].get("variability")) \
                == ("s", "ms", "tunable")
        start = float(by_name["sensing_delay"].find("Real").get("start"))
        assert start == (WB if delayed else 0.0)
        unit_s = [u for u in root.find("UnitDefinitions") if u.get("name") == "s"][0]
        assert [(d.get("name"), float(d.get("factor"))) for d in unit_s.findall("DisplayUnit")] \
            == [("ms", 1000.0)]
    assert StateFeedbackLongitudinalDelayed.DIRECT_FEEDTHROUGH is False
