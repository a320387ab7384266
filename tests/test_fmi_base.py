"""Unit tests of the slave base (dronefly.fmi) through the two slave classes, called directly.

What pythonfmu 0.7.0 cannot return as a status (fmi2Error from anything but doStep) must be
logged at once, change nothing and refuse the next doStep; states must be guarded; every
message must be safe for a printf-style logger.
"""

from __future__ import annotations

import math
import sys

import pytest

from dronefly.controller.slave import StateFeedback
from dronefly.fmi.state import MAGIC, StateHandle
from dronefly.fmu_src.lateral.slave import DroneFlyLateral

H = 1e-3  # s


def _new(cls=DroneFlyLateral, name: str = "unit", resources: str | None = None):
    return cls(instance_name=name, resources=resources)


def _stepping(cls=DroneFlyLateral):
    s = _new(cls)
    s.setup_experiment(0.0)
    s.enter_initialization_mode()
    s.exit_initialization_mode()
    return s


def _messages(s) -> list[tuple[int, str]]:
    out = [(int(m.status), m.msg) for m in s.log_queue]
    s.log_queue.clear()
    return out


def _vr(s, name: str) -> int:
    return s._vr[name]


# --- the FMI 2.0 co-simulation call-sequence table (section 4.2.4) ---------------------------
ILLEGAL = [
    ("instantiated", "exit_initialization_mode", (), "fmi2ExitInitializationMode"),
    ("instantiated", "terminate", (), "fmi2Terminate"),
    ("initialization", "setup_experiment", (0.0,), "fmi2SetupExperiment"),
    ("initialization", "enter_initialization_mode", (), "fmi2EnterInitializationMode"),
    ("initialization", "terminate", (), "fmi2Terminate"),
    ("stepping", "setup_experiment", (0.0,), "fmi2SetupExperiment"),
    ("stepping", "enter_initialization_mode", (), "fmi2EnterInitializationMode"),
    ("stepping", "exit_initialization_mode", (), "fmi2ExitInitializationMode"),
    ("terminated", "enter_initialization_mode", (), "fmi2EnterInitializationMode"),
    ("terminated", "exit_initialization_mode", (), "fmi2ExitInitializationMode"),
    ("terminated", "terminate", (), "fmi2Terminate"),
    ("terminated", "setup_experiment", (0.0,), "fmi2SetupExperiment"),
]


def _in_state(state: str, cls=DroneFlyLateral):
    s = _new(cls)
    if state != "instantiated":
        s.setup_experiment(0.0)
        s.enter_initialization_mode()
    if state in ("stepping", "terminated"):
        s.exit_initialization_mode()
    if state == "terminated":
        s.terminate()
    _messages(s)
    return s


@pytest.mark.parametrize("cls", [DroneFlyLateral, StateFeedback])
@pytest.mark.parametrize("state,call,args,fmi_name", ILLEGAL)
def test_illegal_call_is_logged_as_error_and_changes_nothing(cls, state, call, args, fmi_name):
    s = _in_state(state, cls)
    getattr(s, call)(*args)
    msgs = _messages(s)
    assert any(status == 3 and fmi_name in text and repr(state) in text for status, text in msgs), msgs
    assert s._mode == state
    if state == "stepping":  # the error is reported once more by the next doStep, then it works
        assert s.do_step(0.0, H) is False
        assert s.do_step(0.0, H) is True


@pytest.mark.parametrize("state", ["instantiated", "initialization", "terminated"])
def test_do_step_outside_stepping_is_refused(state):
    s = _in_state(state)
    assert s.do_step(0.0, H) is False
    assert any("fmi2DoStep" in text for _, text in _messages(s))


def test_get_in_instantiated_is_logged():
    s = _new()
    s.get_real([_vr(s, "delta_v")])
    assert any(status == 3 and "fmi2GetReal" in text for status, text in _messages(s))


# --- communication points --------------------------------------------------------------------
@pytest.mark.parametrize("t,h,fragment", [
    (math.inf, H, "currentCommunicationPoint = inf"),
    (math.nan, H, "currentCommunicationPoint = nan"),
    (0.0, math.inf, "communicationStepSize = inf"),
    (0.0, 1e308 * 10, "communicationStepSize = inf"),
    (1e308, 1e308, "with a finite end"),
])
def test_non_finite_times_are_refused_and_the_clock_stays_finite(t, h, fragment):
    s = _stepping()
    assert s.do_step(t, h) is False
    assert any(fragment in text for _, text in _messages(s))
    assert s._time == 0.0
    assert s.do_step(0.0, H) is True


def test_a_huge_step_does_not_widen_the_continuity_tolerance():
    s = _stepping(StateFeedback)
    assert s.do_step(0.0, 0.001) is True
    assert s.do_step(0.001, 1e300) is False or s._time == 0.001 + 1e300
    s = _stepping(StateFeedback)
    assert s.do_step(0.0, 0.001) is True
    assert s.do_step(5.001, 0.001) is False  # 5 s later than the clock: refused
    assert any("does not continue" in text for _, text in _messages(s))


def test_setup_experiment_refuses_non_finite_times():
    s = _new()
    s.setup_experiment(math.inf)
    assert any("startTime = inf" in text for _, text in _messages(s))
    assert s._time == 0.0


# --- values ------------------------------------------------------------------------------------
def test_out_of_range_value_references_are_logged():
    s = _stepping()
    out = s.get_real([-1, 10**6])  # the wrapper passes 2**32 - 1 as -1
    assert all(math.isnan(v) for v in out)
    texts = [text for status, text in _messages(s) if status == 3]
    assert any("valueReference 4294967295" in t for t in texts), texts
    assert any("valueReference 1000000" in t for t in texts), texts


def test_repeated_reads_and_sets_keep_every_check():
    """The second fmi2GetReal/fmi2SetReal of the same value references (a slice of the value
    table) answers and refuses exactly as the first: in the wrong state, for values that may not
    be set, for a different number of values."""
    s = _new()
    states = [_vr(s, n) for n in ("delta_v", "delta_p", "delta_r", "delta_gamma")]
    controls = [_vr(s, n) for n in ("delta_Phi_a", "delta_alpha_1a", "delta_alpha_2a")]
    for _ in range(2):  # instantiated: logged every time, however often read
        s.get_real(list(states))
        assert any(status == 3 and "fmi2GetReal" in text for status, text in _messages(s))
    s.setup_experiment(0.0)
    s.enter_initialization_mode()
    s.exit_initialization_mode()
    for k in range(3):
        s.set_real(list(controls), [0.01 * k, 0.0, -0.02])
        assert s.get_real(list(controls)) == [0.01 * k, 0.0, -0.02]
        assert s.get_real(list(states)) == [s._real[i] for i in states]
    assert _messages(s) == []
    s.set_real(list(controls), [1.0, 2.0])  # fewer values than references: no slice
    assert len(s._real) == len(s.VARIABLES)
    s.set_real(list(states), [0.0] * 4)  # outputs: rejected each time
    s.set_real(list(states), [0.0] * 4)
    assert sum("rejected" in text for _, text in _messages(s)) == 8
    assert s.do_step(0.0, H) is False
    s.terminate()
    _messages(s)
    s.set_real(list(controls), [0.0, 0.0, 0.0])  # settable in stepping, not in terminated
    assert any(status == 3 and "'terminated'" in text for status, text in _messages(s))
    s.set_real(list(controls), [0.0, 0.0, 0.0])
    assert any(status == 3 and "'terminated'" in text for status, text in _messages(s))


@pytest.mark.parametrize("call,args,fragment", [
    ("get_string", ([0],), "fmi2GetString"), ("get_integer", ([0],), "fmi2GetInteger"),
    ("set_string", ([0], ["x"]), "fmi2SetString"), ("set_integer", ([0], [1]), "fmi2SetInteger"),
    ("get_boolean", ([0],), "fmi2GetBoolean"),
])
def test_kinds_the_fmu_does_not_have_are_errors(call, args, fragment):
    s = _stepping()
    getattr(s, call)(*args)
    assert any(status == 3 and fragment in text for status, text in _messages(s))


# --- log messages ------------------------------------------------------------------------------
def test_messages_are_safe_for_a_printf_logger():
    s = _new(name="%s%n\udcff")
    s.setup_experiment(0.0)
    s.enter_initialization_mode()
    s.exit_initialization_mode()
    s.set_string([0], ["%s%s%s%s%n"])
    for _, text in _messages(s):
        text.encode("utf-8")  # valid UTF-8
        bare = text.replace("%%", "")
        assert "%" not in bare, text  # every % escaped


def test_resources_folder_leaves_sys_path(tmp_path):
    res = str(tmp_path)
    sys.path.insert(0, res)
    sys.path.insert(0, res)
    try:
        _new(resources=res)
        assert res not in sys.path
    finally:
        while res in sys.path:
            sys.path.remove(res)


# --- FMU states ----------------------------------------------------------------------------------
def test_state_of_another_fmu_is_refused_and_nothing_changes():
    plant, ctrl = _stepping(DroneFlyLateral), _stepping(StateFeedback)
    before = ctrl._get_fmu_state().payload
    ctrl._set_fmu_state(plant._get_fmu_state())
    assert any("fmi2SetFMUstate refused" in text and "DroneFlyLateral" in text
               for _, text in _messages(ctrl))
    assert ctrl._get_fmu_state().payload == before


def test_state_of_another_instance_of_the_same_fmu_is_accepted():
    a, b = _stepping(), _stepping()
    a.set_real([_vr(a, "delta_Phi_a")], [0.1])
    assert a.do_step(0.0, H) is True
    b._set_fmu_state(a._get_fmu_state())
    assert b.get_real([_vr(b, "delta_v")]) == a.get_real([_vr(a, "delta_v")])


def _blob(s) -> bytes:
    return type(s)._fmu_state_to_bytes(s._get_fmu_state())


@pytest.mark.parametrize("mutate,fragment", [
    (lambda b: b"", "0 bytes"),
    (lambda b: b[:40], "truncated"),
    (lambda b: b[: len(b) // 2], "payload bytes"),
    (lambda b: b"\xff\xfe" * 50, "header"),
    (lambda b: b[:-3] + bytes([b[-3] ^ 1]) + b[-2:], "checksum"),
    (lambda b: b.replace(b'"format": 1', b'"format": 2'), "format 2"),
    (lambda b: b.replace(b"DroneFlyLateral@", b"DroneFlyLateral2@"), "saved by FMU"),
])
def test_corrupt_serialized_states_are_refused_without_touching_the_instance(mutate, fragment):
    s = _stepping()
    s.set_real([_vr(s, "delta_Phi_a")], [0.2])
    assert s.do_step(0.0, H) is True
    blob = _blob(s)
    assert blob.startswith(MAGIC)
    before = s._get_fmu_state().payload
    handle = DroneFlyLateral._fmu_state_from_bytes(mutate(blob))  # must not raise
    assert isinstance(handle, StateHandle) and handle.rejected
    s._set_fmu_state(handle)
    assert any(fragment in text for _, text in _messages(s)), fragment
    assert s._get_fmu_state().payload == before
    assert s.do_step(H, H) is True


def test_serialized_state_round_trip_continues_bit_for_bit():
    a = _stepping()
    a.set_real([_vr(a, "delta_Phi_a")], [0.2])
    a.do_step(0.0, H)
    blob = _blob(a)
    b = _stepping()
    b._set_fmu_state(DroneFlyLateral._fmu_state_from_bytes(blob))
    a.do_step(H, H)
    b.do_step(H, H)
    assert a.get_real(list(range(7))) == b.get_real(list(range(7)))


def test_freed_state_is_refused():
    s = _stepping()
    handle = s._get_fmu_state()
    handle.__del__()  # what the host's fmi2FreeFMUstate leads to (the last reference dropped)
    s._set_fmu_state(handle)
    assert any("freed" in text for _, text in _messages(s))


def test_ctrl_c_inside_a_step_is_a_refusal_not_fatal(monkeypatch):
    """SIGINT delivered while the FMU's Python code runs must not escape into the wrapper
    (where it would be fmi2Fatal and crash the host later)."""
    s = _stepping()

    def interrupted(t, h):
        raise KeyboardInterrupt

    monkeypatch.setattr(s, "_advance", interrupted)
    assert s.do_step(0.0, H) is False
    assert any("interrupted (SIGINT)" in text for _, text in _messages(s))
    assert s._time == 0.0
    monkeypatch.undo()
    assert s.do_step(0.0, H) is True
