"""The fuzz of ``dronefly check`` (harness/compliance/fuzz.py, fuzzcases.py, fuzzkit.py,
fuzzrandom.py) on small inputs in-process. Written for mutation testing (docs/mutation.md): a
mutant costs a second, so nothing here starts a child process or builds an FMU.

The groups run against a fake FMU in Python (:class:`_Slave`, FMPy's ``FMU2Slave`` as the fuzz
calls it): a compliant FMI 2.0 co-simulation slave of the dronefly profile (the FMI 2.0 4.2.4
call-sequence table; forbidden calls answered fmi2Error with a message naming the call; a bad
value refused at the step with fmi2Discard and a message naming the variable; a refused call
changes nothing) unless a seeded defect changes one answer. The oracle of a verdict is the
defect seeded: a compliant slave gets no problem, a defect exactly the problem the fuzz
documents for it. The Reference-FMUs (known-good FMUs) run the groups in-process too. The
parent's side (fuzz.py) runs against a stub child that answers as fuzzcases' documented
command line and row protocol say, with crashes, aborts at exit and hangs seeded.
"""

from __future__ import annotations

import json
import math
import os
import random
import signal
import zlib
from pathlib import Path
from types import SimpleNamespace

import pytest

from fmpy.fmi1 import FMICallException

from dronefly.harness.compliance import fuzz, fuzzcases, fuzzkit, fuzzrandom
from dronefly.harness.compliance.child import ChildRun
from dronefly.harness.cosim.fmu import LogMessage
from shared_files import need_shared

REF = Path(__file__).resolve().parents[1].parent / "shared" / "reference-fmus"

# FMI 2.0 (2.1.3): fmi2OK, fmi2Warning, fmi2Discard, fmi2Error, fmi2Fatal, fmi2Pending
_OK, _WARNING, _DISCARD, _ERROR, _FATAL = 0, 1, 2, 3, 4

# --- a fake FMU: an FMI 2.0 co-simulation slave in Python -------------------------------------

#: FMI 2.0 4.2.4 (the co-simulation state machine), for the calls the fuzz makes: the states
#: in which each call is allowed (the fuzz's four: instantiated, initialization, stepping,
#: terminated). Get/set of variables, FMU states and reset are allowed in more states.
_ALLOWED = {
    "setupExperiment": {"instantiated"},
    "enterInitializationMode": {"instantiated"},
    "exitInitializationMode": {"initialization"},
    "doStep": {"stepping"},
    "terminate": {"stepping"},
    "reset": {"instantiated", "initialization", "stepping", "terminated"},
    "getReal": {"initialization", "stepping", "terminated"},
    "setReal": {"instantiated", "initialization", "stepping"},
    "getBoolean": {"initialization", "stepping", "terminated"},
    "setBoolean": {"instantiated", "initialization", "stepping"},
    "getInteger": {"initialization", "stepping", "terminated"},
    "setInteger": {"instantiated", "initialization", "stepping"},
    "getString": {"initialization", "stepping", "terminated"},
    "setString": {"instantiated", "initialization", "stepping"},
}

_START = {1: 1.0, 2: 2.0, 3: 0.5, 4: 0.0, 5: 0.0}


def _var(name, vr, causality, variability="continuous", type_="Real"):
    return SimpleNamespace(name=name, valueReference=vr, causality=causality,
                           variability=variability, type=type_)


#: u input, k fixed parameter, g tunable parameter, y output, x local, b Boolean input,
#: c a constant "parameter" (not settable: no target of the values group)
_VARIABLES = [_var("u", 1, "input"), _var("k", 2, "parameter", "fixed"),
              _var("g", 3, "parameter", "tunable"), _var("y", 4, "output"),
              _var("x", 5, "local"), _var("b", 6, "input", "discrete", "Boolean"),
              _var("c", 7, "parameter", "constant")]


class _State:
    def __init__(self, values, t, state):
        self.values, self.t, self.state, self.freed = dict(values), t, state, False

    def __repr__(self):
        return f"_State({self.values}, {self.t}, {self.state})"


class _Slave:
    """A compliant FMI 2.0 CS slave of the dronefly profile; ``defects`` (a set) change it:

    ``quiet``: no log message ever; ``anon``: messages name neither the call nor the variable;
    ``printed``: the messages go to standard output (PRINTED), not the logger; ``stdout``:
    they are written to fd 1, as a binary prints them; ``fatal``:
    every refusal is fmi2Fatal; ``drift``: a refused step still moves the output; ``obeys``:
    a forbidden call is refused but makes its transition; ``terminated_steps``: doStep is
    accepted after terminate; ``corrupt_ok``: any blob deserializes, to a state with another
    output; ``stuck``: no step after a refused state; ``global``: the output depends on a
    count shared by all instances (a static variable); ``overflow_anon``: a NaN or infinity is
    refused with a message on overflow, not naming the variable; ``no_states``:
    fmi2GetFMUstate is refused; ``odd_blob``: a serialized state of chosen bytes.
    ``calls`` collects (function, arguments, state, status) of each call."""

    shared = [0]  # the "static variable" of the ``global`` defect

    def __init__(self, inst, defects):
        self.inst, self.defects = inst, defects
        self.calls = inst.fmu.calls
        self.state, self.t, self.stuck = "instantiated", 0.0, False
        self.values = {**_START, 6: False}

    # the machinery
    def _log(self, status, text):
        if "quiet" in self.defects:
            return
        if "anon" in self.defects:
            text = "bad call"
        if "stdout" in self.defects:  # as a binary prints: fd 1
            os.write(1, text.encode() + b"\n")
        elif "printed" in self.defects:
            f = fuzzkit.PRINTED.file
            f.seek(0, 2)
            f.write(text.encode() + b"\n")
            f.flush()
        elif self.inst.logging:
            self.inst.messages.append(LogMessage(self.inst.name, status, "logStatusError", text))

    def _refuse(self, fname, status, text):
        status = _FATAL if "fatal" in self.defects else status
        self._log(status, text)
        self.calls[-1] = (*self.calls[-1][:3], status)
        raise FMICallException(f"fmi2{fname[0].upper()}{fname[1:]}", status)

    def _enter(self, fname, *args):
        self.calls.append((fname, args, self.state, _OK))
        self.inst.fmu.callers.append(self.inst.name)
        if self.state not in _ALLOWED.get(fname, {self.state}):
            if "obeys" in self.defects:
                self._transition(fname)
            self._refuse(fname, _ERROR, f"fmi2{fname[0].upper()}{fname[1:]} is not allowed in "
                                        f"state {self.state}")

    def _transition(self, fname):
        self.state = {"setupExperiment": self.state, "enterInitializationMode": "initialization",
                      "exitInitializationMode": "stepping", "terminate": "terminated",
                      "doStep": self.state}.get(fname, self.state)

    def _vrs(self, fname, vrs, known):
        for vr in vrs:
            if vr not in known:
                self._refuse(fname, _ERROR, f"unknown value reference {vr}")

    # FMPy's FMU2Slave
    def setupExperiment(self, tolerance=None, startTime=0.0):
        self._enter("setupExperiment", tolerance, startTime)
        self.t = startTime

    def enterInitializationMode(self):
        self._enter("enterInitializationMode")
        self.state = "initialization"

    def exitInitializationMode(self):
        self._enter("exitInitializationMode")
        self.state = "stepping"

    def terminate(self):
        self._enter("terminate")
        self.state = "terminated"

    def reset(self):
        self._enter("reset")
        self.state, self.t, self.values = "instantiated", 0.0, {**_START, 6: False}

    def doStep(self, currentCommunicationPoint, communicationStepSize,
               noSetFMUStatePriorToCurrentPoint=True):
        t, h = currentCommunicationPoint, communicationStepSize
        if "terminated_steps" in self.defects and self.state == "terminated":
            self.calls.append(("doStep", (t, h), self.state, _OK))
            self.inst.fmu.callers.append(self.inst.name)
            return None
        self._enter("doStep", t, h)
        try:
            return self._step(t, h)
        except FMICallException:
            if "drift" in self.defects:
                self.values[4] += 1.0
            raise

    def _step(self, t, h):
        if self.stuck:
            self._refuse("doStep", _ERROR, "doStep: stuck since a refused state")
        for name, vr in (("u", 1), ("k", 2), ("g", 3)):
            if not math.isfinite(self.values[vr]):
                if "overflow_anon" in self.defects:
                    self._refuse("doStep", _DISCARD, "overflow")
                self._refuse("doStep", _DISCARD, f"{name} = {self.values[vr]!r} refused")
        if not (math.isfinite(h) and h > 0.0):
            self._refuse("doStep", _DISCARD, f"communicationStepSize = {h!r} refused")
        if t != self.t:
            self._refuse("doStep", _DISCARD, f"currentCommunicationPoint = {t!r} is not "
                                             f"the current time {self.t!r}")
        y = self.values[4] + h * (self.values[2] * self.values[1] + self.values[3])
        if "global" in self.defects:
            _Slave.shared[0] += 1
            y += _Slave.shared[0]
        if not math.isfinite(y):
            self._refuse("doStep", _DISCARD, "the step overflows y")
        self.values[4], self.t = y, t + h
        return None  # FMPy's FMU2Slave.doStep returns nothing

    def getReal(self, vr):
        self._enter("getReal", list(vr))
        self._vrs("getReal", vr, (1, 2, 3, 4, 5))
        return [self.values[r] for r in vr]

    def setReal(self, vr, value):
        self._enter("setReal", list(vr), list(value))
        self._vrs("setReal", vr, (1, 2, 3))
        if 2 in vr and self.state not in ("instantiated", "initialization"):
            self._refuse("setReal", _ERROR, "k is a fixed parameter: not settable in "
                                            f"state {self.state}")
        self.values.update(zip(vr, value))

    def getBoolean(self, vr):
        self._enter("getBoolean", list(vr))
        return [self.values[6] for _ in vr]

    def setBoolean(self, vr, value):
        self._enter("setBoolean", list(vr), list(value))
        self.values[6] = bool(value[0])

    def getString(self, vr):
        self._enter("getString", list(vr))
        self._vrs("getString", vr, ())

    def setString(self, vr, value):
        self._enter("setString", list(vr), list(value))
        self._vrs("setString", vr, ())

    def setInteger(self, vr, value):
        self._enter("setInteger", list(vr), list(value))
        self._vrs("setInteger", vr, ())

    def getFMUstate(self):
        self._enter("getFMUstate")
        if "no_states" in self.defects:
            self._refuse("getFMUstate", _ERROR, "getFMUstate: this FMU has no states")
        return _State(self.values, self.t, self.state)

    def setFMUstate(self, state):
        self._enter("setFMUstate", state)
        if not isinstance(state, _State) or state.freed:
            self._refuse("setFMUstate", _ERROR, "setFMUstate: not a live FMU state")
        self.values, self.t, self.state = dict(state.values), state.t, state.state

    def freeFMUstate(self, state):
        self._enter("freeFMUstate", state)
        if state is not None:
            state.freed = True

    def serializeFMUstate(self, state):
        self._enter("serializeFMUstate", state)
        if "odd_blob" in self.defects:  # bytes 5, -6, -5, -4: 0, 0, 0x55, 0 (the states test)
            return b"\x01\x02\x03\x04\x05\x00" + b"\x07" * 10 + b"\x00\x55\x00\x01\x02\x03"
        text = json.dumps([{str(k): v for k, v in state.values.items()}, state.t, state.state])
        return text.encode() + zlib.crc32(text.encode()).to_bytes(4, "big")

    def deSerializeFMUstate(self, blob):
        self._enter("deSerializeFMUstate", bytes(blob))
        body, crc = blob[:-4], blob[-4:]
        if "corrupt_ok" in self.defects:
            return _State({**self.values, 4: 123.0}, self.t, self.state)
        if len(blob) < 5 or zlib.crc32(body).to_bytes(4, "big") != crc:
            if "stuck" in self.defects:
                self.stuck = True
            self._refuse("deSerializeFMUstate", _ERROR, "deSerializeFMUstate: corrupt state")
        values, t, state = json.loads(body)
        return _State({int(k): v for k, v in values.items()}, t, state)


class _Instance:
    """The harness's Instance as the fuzz reads it: ``slave``, ``messages``, ``logging``."""

    def __init__(self, fmu, name, logging):
        self.fmu, self.name, self.logging = fmu, name, logging
        self.messages: list[LogMessage] = []
        self.slave = _Slave(self, fmu.defects)
        fmu.live.append(self)

    def free(self):
        if self in self.fmu.live:
            self.fmu.live.remove(self)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.free()


class _FMU:
    """The harness's FMU as the fuzz reads it: a model description and ``instantiate``."""

    def __init__(self, defects=(), tool="dronefly-fmu 1.0", variables=None, states=True,
                 experiment=(2.0, 0.5)):
        self.defects, self.path = set(defects), Path("fake.fmu")
        self.calls: list[tuple] = []
        self.callers: list[str] = []  # the instance of each call
        self.live: list[_Instance] = []
        self.names: list[tuple[str, bool]] = []
        stop, step = experiment
        self.model_description = SimpleNamespace(
            modelVariables=_VARIABLES if variables is None else variables,
            defaultExperiment=SimpleNamespace(stopTime=stop, stepSize=step),
            coSimulation=SimpleNamespace(canSerializeFMUstate=states), generationTool=tool)

    def instantiate(self, name, logging=True):
        self.names.append((name, logging))
        return _Instance(self, name, logging)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.on_close()

    def on_close(self):
        """Called when the harness closes the FMU (a test may replace it)."""


def _run(cases):
    """{label: result} of a group's cases, run in order."""
    out = {}
    for label, run in cases:
        out[label] = run()
    return out


def _problems(cases):
    return {label: r["problems"] for label, r in _run(cases).items() if r["problems"]}


#: the logging setting as the module defines it, before any test sets it
_LOGGING_AS_IMPORTED = list(fuzzkit.LOGGING)


@pytest.fixture(autouse=True)
def _logging_on():
    """Every test starts as run_groups leaves a logging-on child, and leaves it so."""
    fuzzkit.LOGGING[0] = True
    _Slave.shared[0] = 0
    yield
    fuzzkit.LOGGING[0] = True


# --- fuzzkit.py: statuses, the recorded call, the helpers --------------------------------------

def test_the_status_constants_are_the_fmi_statuses():
    """FMI 2.0 2.1.3: fmi2OK 0, fmi2Warning 1, fmi2Discard 2, fmi2Error 3, fmi2Fatal 4."""
    assert (fuzzkit.OK, fuzzkit.WARNING, fuzzkit.DISCARD, fuzzkit.ERROR, fuzzkit.FATAL) == (
        _OK, _WARNING, _DISCARD, _ERROR, _FATAL)
    assert fuzzkit.STATES == ("instantiated", "initialization", "stepping", "terminated")


def test_bad_values_are_nan_both_infinities_and_huge_finite_values_of_both_signs():
    """What a fuzz sets: NaN, +-inf, and finite values whose double overflows (each sign)."""
    bad = fuzzkit.BAD_VALUES
    assert len(bad) == 5
    assert sum(math.isnan(v) for v in bad) == 1
    assert math.inf in bad and -math.inf in bad
    huge = [v for v in bad if math.isfinite(v)]
    assert len(huge) == 2 and sorted(math.copysign(1.0, v) for v in huge) == [-1.0, 1.0]
    assert all(math.isinf(2.0 * v) for v in huge)


def test_status_of_is_ok_for_a_return_and_the_raised_status_otherwise():
    """The status of a call: 0 if it returns, the status of FMICallException else; other
    exceptions are not statuses."""
    assert fuzzkit.status_of(lambda: 7) == _OK
    for s in (_WARNING, _DISCARD, _ERROR, _FATAL):
        def refuse(s=s):
            raise FMICallException("fmi2DoStep", s)
        assert fuzzkit.status_of(refuse) == s
    with pytest.raises(ZeroDivisionError):
        fuzzkit.status_of(lambda: 1 / 0)


def test_experiment_reads_the_default_experiment_or_takes_a_hundredth_of_the_stop_time():
    """defaultExperiment (FMI 2.0 2.2.5): stopTime, stepSize; without: stop 1 s, step stop/100."""
    fmu = _FMU(experiment=(3.0, 0.25))
    assert fuzzkit.experiment(fmu) == (3.0, 0.25)
    fmu.model_description.defaultExperiment.stepSize = None
    assert fuzzkit.experiment(fmu) == (3.0, 0.03)
    fmu.model_description.defaultExperiment.stopTime = None
    assert fuzzkit.experiment(fmu) == (1.0, 0.01)
    fmu.model_description.defaultExperiment.stepSize = "0.5"
    assert fuzzkit.experiment(fmu) == (1.0, 0.5)
    fmu.model_description.defaultExperiment = None
    assert fuzzkit.experiment(fmu) == (1.0, 0.01)


def test_reals_are_the_real_variables_of_the_causalities_asked():
    """The fake's table: u input, k g c parameters, y output (b is Boolean, x local)."""
    fmu = _FMU()
    assert [v.name for v in fuzzkit.reals(fmu, "input")] == ["u"]  # not the Boolean b
    assert [v.name for v in fuzzkit.reals(fmu, "parameter", "output")] == ["k", "g", "y", "c"]
    assert fuzzkit.reals(fmu) == []


@pytest.mark.parametrize("state, calls", [
    ("instantiated", []),
    ("initialization", ["setupExperiment", "enterInitializationMode"]),
    ("stepping", ["setupExperiment", "enterInitializationMode", "exitInitializationMode"]),
    ("terminated", ["setupExperiment", "enterInitializationMode", "exitInitializationMode",
                    "terminate"])])
def test_to_state_reaches_each_state_with_legal_calls(state, calls):
    """FMI 2.0 4.2.4: the legal path from instantiated to each state; all accepted, at time 0."""
    fmu = _FMU()
    with fuzzkit.instantiate(fmu, "x") as inst:
        c = fuzzkit.Case("c", inst, True)
        fuzzkit.to_state(c, state)
        assert inst.slave.state == state
    assert [f for f, *_ in fmu.calls] == calls
    assert c.statuses == [_OK] * len(calls) and c.problems == []
    assert all(s == _OK for *_, s in fmu.calls)
    if calls:
        assert fmu.calls[0][1] == (None, 0.0)


def test_instances_are_made_with_logging_on_unless_run_groups_turns_it_off():
    """An in-process user of the groups (not run_groups) gets the FMU's logging on: the
    refusals' messages are then asked for."""
    assert _LOGGING_AS_IMPORTED == [True]


def test_instantiate_uses_the_logging_setting():
    """Instances are made with logging as LOGGING says (on unless run_groups turns it off)."""
    fmu = _FMU()
    fuzzkit.instantiate(fmu, "on")
    fuzzkit.LOGGING[0] = False
    fuzzkit.instantiate(fmu, "off")
    assert fmu.names == [("on", True), ("off", False)]


def test_a_call_records_its_status_and_returns_its_result():
    """The fake's answers: getReal's values, an unknown reference refused fmi2Error, a negative
    step fmi2Discard; the case records each status, the result lists them once, sorted."""
    fmu = _FMU()
    with fuzzkit.instantiate(fmu, "x") as inst:
        c = fuzzkit.Case("a case", inst, True)
        fuzzkit.to_state(c, "stepping")
        assert c.call("getReal", [4, 1]) == [0.0, 1.0]
        assert c.call("getReal", [99]) is None  # refused: no result
        c.call("doStep", 0.0, -1.0)
        assert c.statuses == [_OK] * 4 + [_ERROR, _DISCARD]
        assert c.problems == []
        assert c.result() == {"case": "a case", "statuses": [_OK, _DISCARD, _ERROR],
                              "problems": []}


@pytest.mark.parametrize("defects, logging, problem", [
    ((), True, None),
    (("quiet",), True, "getReal returned status 3 without a log message"),
    (("quiet",), False, None),  # logging off: a refusal need not be logged
    (("printed",), True, None),  # printed on standard output: a message too
    (("printed", "quiet"), True, "getReal returned status 3 without a log message"),
    (("fatal",), True, "getReal returned fmi2Fatal"),
    (("fatal",), False, "getReal returned fmi2Fatal"),
    (("fatal", "quiet"), False, "getReal returned fmi2Fatal")])
def test_a_refusal_needs_a_message_and_fatal_is_a_problem(monkeypatch, defects, logging,
                                                          problem):
    """A refusal with logging on must come with a message (the logger's or printed text);
    fmi2Fatal is a problem whatever was logged (FMI 2.0 2.1.3: the instance is unusable)."""
    fuzzkit.LOGGING[0] = logging
    fmu = _FMU(defects)
    with fuzzkit.instantiate(fmu, "x") as inst:
        c = fuzzkit.Case("c", inst, False)
        c.call("getReal", [99])  # unknown, and in instantiated
    assert c.problems == ([] if problem is None else [problem])
    assert c.statuses == [_FATAL if "fatal" in defects else _ERROR]


def test_only_what_the_call_itself_logged_or_printed_is_its_message():
    """Messages and printed text from before a call are not that call's message."""
    fmu = _FMU(("quiet",))
    with fuzzkit.instantiate(fmu, "x") as inst:
        c = fuzzkit.Case("c", inst, False)
        inst.messages.append(LogMessage("x", _ERROR, "", "an earlier message"))
        f = fuzzkit.PRINTED.file
        f.seek(0, 2)
        f.write(b"earlier printed text\n")
        f.flush()
        c.call("terminate")
    assert c.problems == ["terminate returned status 3 without a log message"]


def test_printed_gives_the_new_bytes_once():
    """PRINTED.new(): what was written to the file since the last call, never twice."""
    p = fuzzkit.Printed()
    assert p.new() == b""
    p.file.seek(0, 2)  # written at the end, as fd 1 writes
    p.file.write(b"abc")
    p.file.flush()
    assert p.new() == b"abc"
    assert p.new() == b""
    p.file.seek(0, 2)
    p.file.write(b"de")
    p.file.flush()
    assert p.new() == b"de"
    p.file.close()


@pytest.mark.parametrize("ours, logging, messages, problem", [
    (True, True, [(_ERROR, "u is bad")], False),
    (True, True, [(_DISCARD, "the value of u")], False),
    (True, True, [(_FATAL, "u!")], False),
    (True, True, [(_WARNING, "u is bad")], True),  # a warning is no refusal's message
    (True, True, [(_OK, "u is bad")], True),
    (True, True, [(_ERROR, "v is bad")], True),
    (True, True, [(_ERROR, "an overflow")], False),  # the second fragment
    (True, True, [], True),
    (False, True, [], False),  # other tools' FMUs are held to the statuses only
    (True, False, [], False)])  # logging off: nothing to name
def test_logged_wants_an_error_or_discard_message_naming_a_fragment(monkeypatch, ours, logging,
                                                                    messages, problem):
    """Seeded logs: a message of status Discard or above since ``since`` naming a fragment
    satisfies it; a Warning, an OK, another name or no message is the documented problem."""
    fuzzkit.LOGGING[0] = logging
    fmu = _FMU()
    with fuzzkit.instantiate(fmu, "x") as inst:
        c = fuzzkit.Case("c", inst, ours)
        inst.messages.append(LogMessage("x", _ERROR, "", "u before since"))
        for status, text in messages:
            inst.messages.append(LogMessage("x", status, "", text))
        c.logged(1, "u", "overflow")
    if problem:
        got = [t for s, t in messages if s >= _DISCARD][-2:]
        assert c.problems == [f"no error message naming u or overflow (got {got})"]
    else:
        assert c.problems == []


def test_logged_quotes_the_last_two_refusal_messages():
    """Four Error messages logged: the problem quotes the last two."""
    fmu = _FMU()
    with fuzzkit.instantiate(fmu, "x") as inst:
        c = fuzzkit.Case("c", inst, True)
        for k in range(4):
            inst.messages.append(LogMessage("x", _ERROR, "", f"m{k}"))
        c.logged(0, "zzz")
    assert c.problems == ["no error message naming zzz (got ['m2', 'm3'])"]


# --- fuzzrandom.py: the random call sequence and the interleaved instances ------------------

def _names(calls):
    return [f for f, *_ in calls]


def _random(fmu, seed=1, n=300, ours=True):
    cases = fuzzrandom.group_random(fmu, ours, seed, n)
    assert [label for label, _ in cases] == [f"{n} random calls (seed {seed})"]
    return cases[0][1]()


def test_random_calls_are_reproducible_by_seed():
    """The same seed makes the same calls with the same arguments; another seed others."""
    a, b, c = _FMU(), _FMU(), _FMU()
    _random(a, seed=3, n=80)
    _random(b, seed=3, n=80)
    _random(c, seed=4, n=80)
    assert repr(a.calls) == repr(b.calls)
    assert repr(a.calls) != repr(c.calls)


@pytest.mark.parametrize("n", [0, 1, 57])
def test_random_calls_draw_n_calls(monkeypatch, n):
    """N draws of a call from the 14 kinds, nothing more; one instance, freed at the end."""
    draws = []

    class Counting(random.Random):
        def randrange(self, *args):
            draws.append(args)
            return super().randrange(*args)

    monkeypatch.setattr(fuzzrandom, "random", SimpleNamespace(Random=Counting))
    fmu = _FMU()
    r = _random(fmu, n=n)
    assert draws == [(14,)] * n
    assert fmu.names == [("fuzz", True)] and fmu.live == []
    assert (fmu.calls == []) == (n == 0)
    assert r["case"] == f"{n} random calls (seed 1)"


def test_random_calls_reach_every_call_and_the_bad_arguments():
    """300 calls reach each kind of call, the illegal step sizes, times and values of the fuzz
    (zero, negative, infinite, huge, NaN), an undeclared value reference, and refusals of
    both kinds, with no problem for a compliant slave."""
    fmu = _FMU()
    r = _random(fmu)
    assert r["problems"] == []
    assert r["statuses"] == [_OK, _DISCARD, _ERROR]
    assert set(_names(fmu.calls)) == {
        "setupExperiment", "enterInitializationMode", "exitInitializationMode", "doStep",
        "terminate", "reset", "getReal", "setReal", "getBoolean", "setBoolean", "getFMUstate",
        "setFMUstate", "serializeFMUstate", "deSerializeFMUstate", "freeFMUstate"}
    args = {f: [a for g, a, *_ in fmu.calls if g == f] for f in _names(fmu.calls)}
    h = 0.5  # the fake's stepSize
    sizes = {a[1] for a in args["doStep"]}
    assert {h, 0.5 * h, 0.0, -h, math.inf, 1e300} <= sizes
    assert math.inf in {a[0] for a in args["doStep"]}
    assert {0.0, -1.0} <= {a[1] for a in args["setupExperiment"]}
    assert all(a[0] is None for a in args["setupExperiment"])
    read = [vr for a in args["getReal"] for vr in a[0]]
    assert 2**31 - 1 in read and set(read) >= {1, 2, 3, 4, 5}
    assert all(len(a[0]) == 4 for a in args["getReal"])  # three declared, one more
    assert all(len(a[0]) == 2 and len(set(a[0])) == 2 for a in args["setReal"])
    values = [v for a in args["setReal"] for v in a[1]]
    assert any(math.isnan(v) for v in values)
    assert {0.0, 1.0, -1.0, math.inf, 1e300} <= set(values)
    assert any(0.0 < v < 1.0 for v in values) and any(-1.0 < v < 0.0 for v in values)
    assert {a[0] == [6] for a in args["getBoolean"]} == {True}
    assert {True, False} <= {a[1][0] for a in args["setBoolean"]}


def _scripted(kinds, choices=()):
    """A Random whose call kinds are ``kinds`` (then 6, terminate) and whose choices are the
    indices ``choices``, then the first of each list (the nominal time, step size, value)."""
    class Scripted(random.Random):
        script, picks = list(kinds), list(choices)

        def randrange(self, *args):
            return self.script.pop(0) if self.script else 6

        def choice(self, seq):
            return seq[self.picks.pop(0) if self.picks else 0]

    return SimpleNamespace(Random=Scripted)


def test_random_calls_step_on_from_where_the_fmu_is(monkeypatch):
    """The fuzz keeps the time of its instance: a step drawn at its own time after accepted
    ones lands on the FMU's time (FMPy's doStep returns nothing for FMI 2.0: the status, not
    the result, tells a step was accepted); after fmi2Reset the time is 0 again."""
    monkeypatch.setattr(fuzzrandom, "random", _scripted([0, 1, 2, 3, 4, 5, 7, 0, 1, 2, 3, 4]))
    fmu = _FMU()
    r = _random(fmu, n=12)
    steps = [(a, s) for f, a, state, s in fmu.calls if f == "doStep"]
    assert steps == [((0.0, 0.5), _OK), ((0.5, 0.5), _OK), ((1.0, 0.5), _OK),
                     ((0.0, 0.5), _OK), ((0.5, 0.5), _OK)]
    assert r["statuses"] == [_OK] and r["problems"] == []


def test_random_calls_step_one_step_ahead_of_their_time(monkeypatch):
    """One of the communication points drawn is one step ahead of the fuzz's time (a gap):
    refused by a compliant FMU at that time."""
    monkeypatch.setattr(fuzzrandom, "random", _scripted([0, 1, 2, 3], [0, 0, 2]))
    fmu = _FMU()
    _random(fmu, n=4)
    assert [(a, s) for f, a, _, s in fmu.calls if f == "doStep"] == [((0.5, 0.5), _DISCARD)]


def test_random_calls_keep_their_time_after_a_refused_step(monkeypatch):
    """A refused step (a negative size) does not move the fuzz's time: the next step at its
    own time is accepted."""
    monkeypatch.setattr(fuzzrandom, "random", _scripted([0, 1, 2, 3, 3], [0, 4, 0]))
    fmu = _FMU()
    _random(fmu, n=5)
    steps = [(a, s) for f, a, state, s in fmu.calls if f == "doStep"]
    assert steps == [((0.0, -0.5), _DISCARD), ((0.0, 0.5), _OK)]


def test_each_kind_of_random_call_makes_its_calls(monkeypatch):
    """The 14 kinds of draw, once each in order: setupExperiment, enter and exit
    initialization, three of doStep, terminate, reset, getReal, setReal, get and set
    Boolean, getFMUstate, setFMUstate of a state got, and a state serialized, deserialized,
    set and freed; at the end the states got are freed."""
    monkeypatch.setattr(fuzzrandom, "random", _scripted(range(14)))
    fmu = _FMU()
    _random(fmu, n=14)
    assert _names(fmu.calls) == [
        "setupExperiment", "enterInitializationMode", "exitInitializationMode", "doStep",
        "doStep", "doStep", "terminate", "reset", "getReal", "setReal", "getBoolean",
        "setBoolean", "getFMUstate", "setFMUstate", "serializeFMUstate", "deSerializeFMUstate",
        "setFMUstate", "freeFMUstate", "freeFMUstate"]


def test_random_calls_set_deserialized_states_and_free_every_state():
    """Each FMU state the fuzz gets is freed at the end; a deserialized one right after it
    is set; a state that could not be had is never used."""
    fmu = _FMU()
    _random(fmu)
    got = []
    for k, (f, a, state, s) in enumerate(fmu.calls):
        if f == "setFMUstate":
            assert isinstance(a[0], _State) and s == _OK
        if f == "deSerializeFMUstate" and s == _OK:
            assert _names(fmu.calls[k + 1:k + 3]) == ["setFMUstate", "freeFMUstate"]
            assert fmu.calls[k + 1][1][0] is fmu.calls[k + 2][1][0]
        if f == "serializeFMUstate":
            got.append(a[0])
    frees = [a[0] for f, a, *_ in fmu.calls if f == "freeFMUstate"]
    assert got and all(any(st is g for g in frees) for st in got)
    assert all(st.freed for st in frees)


def test_random_calls_without_booleans_or_states_skip_those_calls():
    """A table without Booleans: no Boolean call; a slave refusing fmi2GetFMUstate: no state
    is set or serialized (nothing to use), and its refusals are logged: no problem."""
    fmu = _FMU(variables=[v for v in _VARIABLES if v.type == "Real"])
    _random(fmu)
    assert not {"getBoolean", "setBoolean"} & set(_names(fmu.calls))
    fmu = _FMU(("no_states",))
    r = _random(fmu)
    assert not {"setFMUstate", "serializeFMUstate"} & set(_names(fmu.calls))
    assert r["problems"] == []


def test_random_calls_report_a_silent_refusal_and_fatal():
    """Seeded defects: every refusal silent, or every refusal fmi2Fatal: the documented
    problems, one per refused call."""
    r = _random(_FMU(("quiet",)), n=60)
    assert r["problems"] and all("without a log message" in p for p in r["problems"])
    r = _random(_FMU(("fatal",)), n=60)
    assert r["problems"] and all(p.endswith("returned fmi2Fatal") for p in r["problems"])
    assert r["statuses"][-1] == _FATAL


def _churn(fmu, n=5, seed=2):
    cases = fuzzrandom.group_churn(fmu, True, seed, n)
    assert [label for label, _ in cases] == [f"{n} interleaved instances"]
    return cases[0][1]()


def test_churn_of_independent_instances_passes_and_frees_them(monkeypatch):
    """n instances live together, each run gives the single run's outputs; all freed, and a
    second load of the library (a new FMU of the same file) gives them too."""
    fmu, loads = _FMU(), []

    def load(path):
        loads.append(_FMU())
        assert path == fmu.path
        return loads[-1]

    monkeypatch.setattr(fuzzrandom, "FMU", load)
    r = _churn(fmu)
    assert r == {"case": "5 interleaved instances", "statuses": [], "problems": []}
    assert [name for name, _ in fmu.names] == ["ref", "i0", "i1", "i2", "i3", "i4"]
    assert fmu.live == [] and loads[0].live == [] and len(loads) == 1
    assert [name for name, _ in loads[0].names] == ["second load"]
    # every instance stepped three times from 0 (after the reference run, before any free)
    steps = [(a, s) for f, a, st, s in fmu.calls if f == "doStep"]
    assert len(steps) == 18 and all(s == _OK for _, s in steps)
    assert [a for a, _ in steps[:3]] == [(0.0, 0.5), (0.5, 0.5), (1.0, 0.5)]
    runs = [fmu.calls[k][1] for k, c in enumerate(fmu.calls) if c[0] == "getReal"]
    assert runs == [([4],)] * 6  # the outputs read after each run


def test_churn_finds_instances_that_share_state_and_a_second_load_that_differs(monkeypatch):
    """A static variable shared by the instances (each run moves the next one's outputs):
    every instance differs from the single run, named; a second load with another result."""
    monkeypatch.setattr(fuzzrandom, "FMU", lambda path: _FMU())
    r = _churn(_FMU(("global",)), n=4)
    names = sorted(p.split()[1] for p in r["problems"][:-1])
    assert names == ["i0", "i1", "i2", "i3"], r["problems"]
    assert all(p.endswith(", the single run [9.75]") for p in r["problems"][:-1])
    assert r["problems"][-1] == "a second load of the library gave [3.75]"
    _Slave.shared[0] = 0
    monkeypatch.setattr(fuzzrandom, "FMU", lambda path: _FMU(("global",)))
    r = _churn(_FMU(), n=3)
    assert r["problems"] == ["a second load of the library gave [9.75]"]


def test_churn_finds_an_instance_whose_outputs_cannot_be_read(monkeypatch):
    """A run whose outputs are refused gives None: a problem, unlike the single run."""
    monkeypatch.setattr(fuzzrandom, "FMU", lambda path: _FMU())
    fmu = _FMU()
    made = []
    real = fmu.instantiate

    def instantiate(name, logging=True):
        inst = real(name, logging)
        made.append(inst)
        if name == "i1":
            inst.slave.getReal = lambda vr: (_ for _ in ()).throw(FMICallException("g", 3))
        return inst

    fmu.instantiate = instantiate
    r = _churn(fmu, n=3)
    assert r["problems"] == ["instance i1 gave None, the single run [3.75]"]


def test_churn_runs_the_instances_interleaved(monkeypatch):
    """The n instances are made first, then run in a shuffled order and freed in another,
    as the seed draws them (not in the order made)."""
    monkeypatch.setattr(fuzzrandom, "FMU", lambda path: _FMU())
    orders = set()
    for seed in range(4):
        fmu = _FMU()
        _churn(fmu, n=6, seed=seed)
        steps = [who for who, (f, *_) in zip(fmu.callers, fmu.calls) if f == "doStep"]
        steppers = steps[3::3]  # each instance steps three times in a row; the reference first
        assert steps == [who for who in ["ref", *steppers] for _ in range(3)]
        orders.add(tuple(steppers))
        assert sorted(steppers) == [f"i{k}" for k in range(6)]
    assert len(orders) > 1 and tuple(f"i{k}" for k in range(6)) not in orders


# --- fuzzcases.py: the groups of cases ------------------------------------------------------

_BAD = ["nan", "inf", "-inf", "1e+308", "-1e+308"]


def test_values_sets_each_bad_value_on_each_settable_real():
    """The targets: Real inputs and parameters that can be set (not a constant, an output, a
    local, a Boolean); each gets every bad value, its case named ``name = value``."""
    cases = fuzzcases.group_values(_FMU(), True, 0, 0)
    assert [label for label, _ in cases] == [f"{v} = {b}" for v in "ukg" for b in _BAD]


def test_values_of_a_compliant_slave_pass_and_reach_the_refusals():
    """Each bad value reaches the step: NaN and the infinities are refused (fmi2Discard), the
    huge values of the input overflow the output and are refused too; no problem."""
    fmu = _FMU()
    results = _run(fuzzcases.group_values(fmu, True, 0, 0))
    assert all(r["problems"] == [] for r in results.values()), results
    for v in "ukg":
        for b in _BAD[:3]:
            assert _DISCARD in results[f"{v} = {b}"]["statuses"]
    assert _DISCARD in results["u = 1e+308"]["statuses"]  # 2e308: the step overflows
    assert results["g = 1e+308"]["statuses"] == [_OK]  # accepted: legal, not overflowing
    assert fmu.live == []


def test_values_set_a_fixed_parameter_in_initialization_and_the_others_while_stepping():
    """FMI 2.0 4.2.4: a fixed parameter is set before exitInitializationMode; the others after
    a step, then the next step is made (and, for a fixed one, refused while stepping)."""
    fmu = _FMU()
    _run(fuzzcases.group_values(fmu, True, 0, 0)[5:6])  # k = nan
    sets = [(a, state, s) for f, a, state, s in fmu.calls if f == "setReal"]
    assert sets[0][1:] == ("initialization", _OK) and sets[0][0][0] == [2]
    assert sets[1][1:] == ("stepping", _ERROR)
    fmu = _FMU()
    _run(fuzzcases.group_values(fmu, True, 0, 0)[0:1])  # u = nan
    assert [(f, state) for f, a, state, s in fmu.calls][3:] == [
        ("doStep", "stepping"), ("getReal", "stepping"), ("setReal", "stepping"),
        ("doStep", "stepping"), ("getReal", "stepping")]
    assert [a for f, a, *_ in fmu.calls if f == "doStep"] == [(0.0, 0.5), (0.5, 0.5)]
    assert [a for f, a, *_ in fmu.calls if f == "getReal"] == [([4],), ([4],)]


@pytest.mark.parametrize("defects, ours, want", [
    (("anon",), True, {**{f"{v} = {b}": f"no error message naming {v}" for v in "ukg"
                          for b in _BAD[:3]},
                       "u = 1e+308": "no error message naming u or overflow",
                       "u = -1e+308": "no error message naming u or overflow"}),
    # (k's refusal while stepping names it)
    (("overflow_anon",), True, {f"{v} = {b}": f"no error message naming {v} (got ['overflow'"
                                for v in "ug" for b in _BAD[:3]}),
    (("drift",), True, {f"{v} = {b}": "outputs changed by a refused step"
                        for v in "ukg" for b in _BAD[:3] + (_BAD[3:] if v == "u" else [])}),
    (("anon", "drift"), False, {}),
    (("overflow_anon", "drift"), False, {})])
def test_values_find_a_refusal_that_does_not_name_the_value_or_moves_the_outputs(defects, ours,
                                                                                want):
    """For the project's FMUs: a refused value must be named (or, for a huge finite value,
    the overflow it causes) and must change no output; other tools' FMUs: statuses only."""
    got = _problems(fuzzcases.group_values(_FMU(defects), ours, 0, 0))
    if "drift" in defects and ours:
        got = {k: [p for p in v if p.startswith("outputs")] for k, v in got.items()}
        got = {k: v for k, v in got.items() if v}
    assert sorted(got) == sorted(want)
    for label, start in want.items():
        assert any(p.startswith(start) for p in got[label]), (label, got[label])


def test_values_of_a_silent_or_fatal_slave():
    """Seeded defects on another tool's FMU (statuses only): a silent refusal of the step and
    fmi2Fatal are problems; an accepted huge value is none."""
    got = _problems(fuzzcases.group_values(_FMU(("quiet",)), False, 0, 0))
    assert got["u = nan"] == ["doStep returned status 2 without a log message"]
    got = _problems(fuzzcases.group_values(_FMU(("fatal",)), False, 0, 0))
    assert got["u = nan"] == ["doStep returned fmi2Fatal"]
    assert "g = 1e+308" not in got


_CALLS = ["SetupExperiment", "EnterInitializationMode", "ExitInitializationMode", "DoStep",
          "Terminate", "Reset", "GetReal", "SetReal", "GetFMUstate"]


def _forbidden():
    """FMI 2.0 4.2.4: the (call, state) pairs of the fuzz's calls that the table forbids."""
    return {(f"fmi2{c}", s) for c in _CALLS for s in fuzzkit.STATES
            if s not in _ALLOWED.get(c[0].lower() + c[1:], set(fuzzkit.STATES))}


def test_sequence_makes_every_call_in_every_state():
    """Nine calls in four states, in order; the forbidden pairs are FMI 2.0 4.2.4's (the
    table ``_ALLOWED`` written from the standard)."""
    cases = fuzzcases.group_sequence(_FMU(), True, 0, 0)
    assert [label for label, _ in cases] == [f"fmi2{c} in {s}" for s in fuzzkit.STATES
                                             for c in _CALLS]
    assert fuzzcases.ILLEGAL == _forbidden()


def test_sequence_of_a_compliant_slave_passes_with_the_forbidden_calls_refused():
    """Each forbidden call refused fmi2Error, the allowed ones accepted; no problem."""
    fmu = _FMU()
    results = _run(fuzzcases.group_sequence(fmu, True, 0, 0))
    assert all(r["problems"] == [] for r in results.values()), results
    for label, r in results.items():
        call, _, state = label.partition(" in ")
        forbidden = (call, state) in _forbidden()
        assert (_ERROR in r["statuses"]) == forbidden, label
        if not forbidden:  # an allowed call, with the arguments of a legal run, is accepted
            assert r["statuses"] == [_OK], label
    assert fmu.live == []


@pytest.mark.parametrize("defects, ours, want", [
    (("anon",), True, {f"{c} in {s}": f"no error message naming {c} or {c[4:]} (got ['bad call'"
                       for c, s in _forbidden()}),
    (("obeys",), True, {
        "fmi2ExitInitializationMode in instantiated": "a forbidden call changed the state: "
                                                      "enterInitializationMode is no longer",
        "fmi2Terminate in instantiated": "a forbidden call changed the state: "
                                         "enterInitializationMode is no longer allowed",
        "fmi2Terminate in initialization": "a forbidden call changed the state: "
                                           "exitInitializationMode is no longer allowed",
        "fmi2EnterInitializationMode in stepping": "a forbidden call changed the state: "
                                                   "terminate is no longer allowed",
        "fmi2ExitInitializationMode in terminated": "a forbidden call left the terminated "
                                                    "state"}),
    (("terminated_steps",), True, {f"{c} in terminated": "a forbidden call left the "
                                   "terminated state" for c, s in _forbidden()
                                   if s == "terminated"}),
    (("anon", "obeys", "terminated_steps"), False, {})])
def test_sequence_finds_an_unnamed_refusal_and_a_forbidden_call_that_changed_the_state(
        defects, ours, want):
    """For the project's FMUs: a forbidden call's message names it, and the instance stays in
    its state (its next legal call works; a terminated one still refuses doStep)."""
    got = _problems(fuzzcases.group_sequence(_FMU(defects), ours, 0, 0))
    assert sorted(got) == sorted(want)
    for label, start in want.items():
        assert [p for p in got[label] if p.startswith(start)], (label, got[label])
        # a doStep accepted after terminate is also a forbidden call not logged
        assert len(got[label]) == 1 + (label == "fmi2DoStep in terminated" and
                                       "terminated_steps" in defects), got[label]


def test_sequence_asks_no_message_of_a_set_of_no_inputs():
    """fmi2SetReal of no variable (an FMU without inputs) in terminated sets nothing: no
    message is asked; with inputs it is."""
    no_inputs = [v for v in _VARIABLES if v.causality != "input"]
    got = _problems(fuzzcases.group_sequence(_FMU(("anon",), variables=no_inputs), True, 0, 0))
    assert "fmi2SetReal in terminated" not in got and "fmi2GetReal in instantiated" in got
    got = _problems(fuzzcases.group_sequence(_FMU(("anon",)), True, 0, 0))
    assert "fmi2SetReal in terminated" in got


def test_sequence_of_a_silent_slave_names_the_call():
    """Seeded defect: silent refusals; the problem names the refused call and its status."""
    got = _problems(fuzzcases.group_sequence(_FMU(("quiet",)), False, 0, 0))
    assert got["fmi2DoStep in instantiated"] == ["doStep returned status 3 without a log message"]
    assert got["fmi2SetupExperiment in stepping"] == [
        "setupExperiment returned status 3 without a log message"]


def _good_blob():
    fmu = _FMU()
    with fuzzkit.instantiate(fmu, "x") as inst:
        fuzzkit.to_state(fuzzkit.Case("x", inst, True), "stepping")
        return bytes(inst.slave.serializeFMUstate(inst.slave.getFMUstate()))


def test_states_try_corrupt_foreign_and_freed_states_and_a_compliant_slave_passes():
    """The blobs are what their names say, against a good serialized state of another
    instance; each is refused, the instance goes on; a freed state is refused too."""
    fmu = _FMU()
    results = _run(fuzzcases.group_states(fmu, True, 5, 0))
    good = _good_blob()
    n = len(good)
    assert list(results) == [
        "deserialize empty", "deserialize truncated", "deserialize one byte",
        "deserialize random", "deserialize not UTF-8", "deserialize flipped byte",
        "deserialize extended", "setFMUstate of a freed state"]
    assert all(r["problems"] == [] and _ERROR in r["statuses"] for r in results.values())
    blobs = [a[0] for f, a, st, s in fmu.calls if f == "deSerializeFMUstate"]
    assert len(blobs) == 7 and all(isinstance(b, bytes) for b in blobs)
    empty, truncated, one, rand, utf, flipped, extended = blobs
    assert empty == b"" and one == good[:1] and extended == good + b"xx"
    assert 1 < len(truncated) < n and good.startswith(truncated)
    assert len(rand) == 200 and rand != good[:200]
    with pytest.raises(UnicodeDecodeError):
        utf.decode()
    assert len(flipped) == n and sum(a != b for a, b in zip(flipped, good)) == 1
    assert fmu.live == []
    other = _FMU()
    _run(fuzzcases.group_states(other, True, 6, 0))
    assert [a[0] for f, a, *_ in other.calls if f == "deSerializeFMUstate"][3] != rand


def test_states_flip_one_byte_of_any_good_blob():
    """Whatever the good blob holds, the flipped one differs from it in exactly one byte
    (a blob whose bytes 5, -6, -5 and -4 are 0, 0, 0x55 and 0: a byte flipped with 0x55 and
    put in the place of another could give the good blob back)."""
    fmu = _FMU(("odd_blob",))
    _run(fuzzcases.group_states(fmu, True, 5, 0))
    good = _FMU(("odd_blob",)).instantiate("x", True).slave.serializeFMUstate(None)
    flipped = [a[0] for f, a, *_ in fmu.calls if f == "deSerializeFMUstate"][5]
    assert len(flipped) == len(good) and sum(a != b for a, b in zip(flipped, good)) == 1


def test_states_record_the_blobs_sizes_in_the_case():
    """A case's name in the results gives the blob's size in bytes."""
    fmu = _FMU()
    names = [fuzzcases.group_states(fmu, True, 5, 0)[k][1]()["case"] for k in (0, 2, 6)]
    assert names == ["deserialize empty (0 bytes)", "deserialize one byte (1 bytes)",
                     f"deserialize extended ({len(_good_blob()) + 2} bytes)"]


@pytest.mark.parametrize("defects, ours, problem", [
    (("corrupt_ok",), True, "a refused state changed the outputs"),
    (("stuck",), True, "the instance did not continue after a refused state"),
    (("corrupt_ok",), False, None), (("stuck",), False, None)])
def test_states_find_a_corrupt_state_accepted_or_an_instance_stuck_after_one(defects, ours,
                                                                             problem):
    """Seeded defects: any blob deserializes (to another output), or the instance refuses to
    step after a refused state: the documented problem in every blob's case, for the
    project's FMUs only."""
    got = _problems(fuzzcases.group_states(_FMU(defects), ours, 5, 0))
    if problem is None:
        assert got == {}
    else:
        assert {k: v for k, v in got.items() if k != "setFMUstate of a freed state"} == {
            f"deserialize {k}": [problem] for k in (
                "empty", "truncated", "one byte", "random", "not UTF-8", "flipped byte",
                "extended")}


def test_states_of_an_fmu_without_them_is_no_case():
    """canSerializeFMUstate false (FMI 2.0 4.3.1): no state to corrupt, no case."""
    assert fuzzcases.group_states(_FMU(states=False), True, 0, 0) == []


def test_states_a_freed_state_set_again_is_refused():
    """The freed state's case: get, free, step, set the freed one (refused), step again."""
    fmu = _FMU()
    r = fuzzcases.group_states(fmu, True, 5, 0)[-1][1]()
    assert r["problems"] == [] and r["statuses"] == [_OK, _ERROR]
    calls = [(f, s) for f, a, st, s in fmu.calls][-5:]
    assert calls == [("getFMUstate", _OK), ("freeFMUstate", _OK), ("doStep", _OK),
                     ("setFMUstate", _ERROR), ("doStep", _OK)]
    r = fuzzcases.group_states(_FMU(("fatal",)), True, 5, 0)[-1][1]()
    assert r["problems"] == ["setFMUstate returned fmi2Fatal"]


def test_format_puts_printf_directives_where_the_logger_sees_them():
    """An instance named with printf directives, undeclared references and a string of
    directives: each refusal logged, the instance still steps; no problem."""
    fmu = _FMU()
    cases = fuzzcases.group_format(fmu, True, 0, 0)
    assert [label for label, _ in cases] == ["printf directives"]
    r = cases[0][1]()
    assert r == {"case": "instance name '%s%s%s%s%n', bad reads", "statuses": [_OK, _ERROR],
                 "problems": []}
    assert fmu.names == [("%s%s%s%s%n", True)]
    made = [(f, a) for f, a, *_ in fmu.calls][3:]
    assert made == [("getReal", ([2**31 - 1],)), ("getString", ([0],)),
                    ("setString", ([0], ["%s%s%s%s%n%x%p"])), ("setInteger", ([2**31 - 1], [7])),
                    ("doStep", (0.0, 0.5))]
    r = fuzzcases.group_format(_FMU(("quiet",)), True, 0, 0)[0][1]()
    assert r["problems"] == [f"{f} returned status 3 without a log message"
                             for f in ("getReal", "getString", "setString", "setInteger")]


def _rows(tmp_path, monkeypatch, fmu, *args, **kw):
    """The rows run_groups writes to its standard output (fd 1), parsed."""
    monkeypatch.setattr(fuzzcases, "FMU", lambda path: fmu)
    monkeypatch.setattr(fuzzrandom, "FMU", lambda path: _FMU())
    out = tmp_path / "rows"
    fd = os.open(out, os.O_WRONLY | os.O_CREAT | os.O_TRUNC)
    saved = os.dup(1)
    os.dup2(fd, 1)
    try:
        fuzzcases.run_groups("fake.fmu", *args, **kw)
    finally:
        os.dup2(saved, 1)
        os.close(saved)
        os.close(fd)
    return [json.loads(line) for line in out.read_text().splitlines()]


def test_run_groups_writes_a_begin_and_a_result_row_per_case(tmp_path, monkeypatch):
    """The child's protocol: ``{"begin": label, "group": g}`` then the result with its group,
    for each case of the groups in order; the random group takes random_calls, the others
    instances; LOGGING as asked; an FMU of dronefly-fmu is held to naming its refusals."""
    fmu = _FMU(("anon",))
    rows = _rows(tmp_path, monkeypatch, fmu, ["format", "random", "churn"], 3, 7, 2,
                 logging=False)
    assert rows[0::2] == [{"begin": "printf directives", "group": "format"},
                          {"begin": "7 random calls (seed 3)", "group": "random"},
                          {"begin": "2 interleaved instances", "group": "churn"}]
    assert [(r["case"], r["group"]) for r in rows[1::2]] == [
        ("instance name '%s%s%s%s%n', bad reads", "format"), ("7 random calls (seed 3)",
                                                               "random"),
        ("2 interleaved instances", "churn")]
    assert {logging for _, logging in fmu.names} == {False}
    assert fuzzkit.LOGGING == [False]
    rows = _rows(tmp_path, monkeypatch, _FMU(("anon",)), ["sequence"], 0, 1, 1, 30)
    assert [r["begin"] for r in rows[0::2]] == ["fmi2DoStep in terminated",
                                                "fmi2Terminate in terminated",
                                                "fmi2Reset in terminated",
                                                "fmi2GetReal in terminated",
                                                "fmi2SetReal in terminated",
                                                "fmi2GetFMUstate in terminated"]
    assert fuzzkit.LOGGING == [True]
    assert rows[1]["problems"] == ["no error message naming fmi2DoStep or DoStep "
                                   "(got ['bad call'])"]
    fmu = _FMU(("anon",), tool="FMPy 0.3")
    rows = _rows(tmp_path, monkeypatch, fmu, ["sequence"], 0, 1, 1, 30)
    assert all(r["problems"] == [] for r in rows[1::2])


def test_run_groups_writes_each_row_before_the_next_case_runs(tmp_path, monkeypatch):
    """A crash kills the child in a case: its begin row, and every row before it, must already
    be out of the process then (the parent names the case from them)."""
    fmu = _FMU()
    seen = []
    real = fmu.instantiate

    def instantiate(name, logging=True):
        seen.append((tmp_path / "rows").read_text().splitlines())
        return real(name, logging)

    fmu.instantiate = instantiate
    fmu.on_close = lambda: seen.append((tmp_path / "rows").read_text().splitlines())
    rows = _rows(tmp_path, monkeypatch, fmu, ["values"], 0, 1, 1, 13)
    assert len(rows) == 4
    assert [json.loads(line) for line in seen[0]] == [{"begin": "g = 1e+308", "group": "values"}]
    assert [json.loads(line) for line in seen[1]] == rows[:3]
    # the last result is out before the FMU is closed (a library that aborts when it is
    # unloaded, at exit, must not take the last case's result with it)
    assert [json.loads(line) for line in seen[2]] == rows


def test_the_module_run_as_a_program_reads_its_documented_command_line(tmp_path, monkeypatch):
    """``python -m ...fuzzcases FMU GROUP[,GROUP...] SEED RANDOM_CALLS INSTANCES START
    LOGGING`` (the module's docstring), its source run in-process as ``__main__`` on the fake
    FMU."""
    import sys

    from dronefly.harness.compliance import child
    from dronefly.harness.cosim import fmu as fmu_module

    made = []

    def load(path):
        made.append((path, _FMU()))
        return made[-1][1]

    monkeypatch.setattr(fmu_module, "FMU", load)
    monkeypatch.setattr(fuzzrandom, "FMU", lambda path: _FMU())
    monkeypatch.setattr(child, "die_with_parent", lambda: made.append("die_with_parent"))
    out = tmp_path / "rows"
    code = compile(Path(fuzzcases.__file__).read_text(), fuzzcases.__file__, "exec")
    for logging in ("0", "1"):
        monkeypatch.setattr(sys, "argv", ["fuzzcases", "x.fmu", "format,random,churn", "3", "7",
                                          "2", "1", logging])
        fd = os.open(out, os.O_WRONLY | os.O_CREAT | os.O_TRUNC)
        saved = os.dup(1)
        os.dup2(fd, 1)
        try:
            exec(code, {"__name__": "__main__", "__package__": "dronefly.harness.compliance",
                        "__file__": fuzzcases.__file__})
        finally:
            os.dup2(saved, 1)
            os.close(saved)
            os.close(fd)
        rows = [json.loads(line) for line in out.read_text().splitlines()]
        assert [r["begin"] for r in rows[0::2]] == ["7 random calls (seed 3)",
                                                    "2 interleaved instances"]
        assert made[-2] == "die_with_parent" and made[-1][0] == "x.fmu"
        assert {lg for _, lg in made[-1][1].names} == {logging == "1"}


def test_run_groups_counts_what_the_fmu_prints_as_its_message(tmp_path, monkeypatch):
    """A binary that reports on its standard output, not the logger: fd 1 is caught, its
    text is the refusal's message and not a row."""
    rows = _rows(tmp_path, monkeypatch, _FMU(("stdout",)), ["format"], 0, 1, 1)
    assert len(rows) == 2 and rows[1]["problems"] == [] and rows[1]["statuses"] == [_OK, _ERROR]
    rows = _rows(tmp_path, monkeypatch, _FMU(("quiet",)), ["format"], 0, 1, 1)
    assert len(rows[1]["problems"]) == 4


@pytest.mark.parametrize("name", ["Feedthrough", "Dahlquist"])
def test_the_reference_fmus_pass_every_group_in_process(name):
    """Known-good FMUs (the Modelica Reference-FMUs, not ours: held to the statuses): no
    problem in any group, refusals reached."""
    from dronefly.harness.cosim.fmu import FMU

    path = REF / "fmi2" / f"{name}.fmu"
    need_shared(path, "the Reference-FMUs")
    statuses = set()
    with FMU(path) as fmu:
        for group, make in fuzzcases.GROUPS.items():
            for label, r in _run(make(fmu, False, 1, 40 if group == "random" else 3)).items():
                assert r["problems"] == [], (group, label, r)
                statuses.update(r["statuses"])
    assert {_OK, _ERROR} <= statuses and _FATAL not in statuses


# --- fuzz.py: the parent's side: the child's rows, crashes, hangs, the report ----------------

@pytest.mark.parametrize("code, text", [
    (0, "exit code 0"), (3, "exit code 3"), (1, "exit code 1"),
    (-signal.SIGSEGV, "killed by SIGSEGV"), (-signal.SIGABRT, "killed by SIGABRT"),
    (-signal.SIGKILL, "killed by SIGKILL"), (-signal.SIGHUP, "killed by SIGHUP"),
    (-200, "killed by signal 200")])
def test_describe_exit_names_the_signal_or_the_exit_code(code, text):
    """subprocess: a negative return code is the signal that killed the process (POSIX)."""
    assert fuzz.describe_exit(code) == text


def _case(problems=(), crash=None, statuses=(0,), group="g", name="c"):
    return fuzz.FuzzCase(group, name, list(statuses), list(problems), crash)


def test_a_case_passes_without_problems_and_crash():
    """A case passes when it has neither a problem nor a crash; by default it has neither."""
    assert _case().passed
    assert not _case(problems=["x"]).passed
    assert not _case(crash="killed by SIGSEGV").passed
    assert fuzz.FuzzCase("g", "c").statuses == [] and fuzz.FuzzCase("g", "c").crash is None


def test_the_report_counts_crashes_fatal_cases_and_statuses():
    """Each case counts once per status it saw; the counts in the order of the statuses."""
    cases = [_case(statuses=[3, 0]), _case(statuses=[4]), _case(statuses=[0, 2, 4]),
             _case(crash="killed by SIGABRT", statuses=[]), _case(statuses=[1])]
    report = fuzz.FuzzReport(Path("f.fmu"), cases)
    assert report.crashes == [cases[3]]
    assert report.fatal == 2
    assert not report.passed
    counts = report.status_counts()
    assert list(counts.items()) == [("OK", 2), ("Warning", 1), ("Discard", 1), ("Error", 1),
                                    ("Fatal", 2)]
    assert fuzz.FuzzReport(Path("f.fmu"), [_case(), _case(statuses=[3])]).passed
    assert fuzz.FuzzReport(Path("f.fmu"), []).passed


def test_the_summary_lists_five_failed_cases_then_says_how_many_more():
    """Counted by hand from the cases given: totals, statuses, the first five failures, the
    rest counted."""
    cases = [_case()] + [_case(problems=[f"p{k}", "q"], name=f"c{k}") for k in range(6)] + [
        _case(crash="hung for more than 1 s", name="h", group="random")]
    text = fuzz.FuzzReport(Path("f.fmu"), cases).summary()
    assert text == ("8 cases, 1 crashes, 0 with fmi2Fatal; statuses seen: {'OK': 8}\n"
                    "  g: c0: p0; q\n  g: c1: p1; q\n  g: c2: p2; q\n  g: c3: p3; q\n"
                    "  g: c4: p4; q\n  ... and 2 more")
    cases = [_case(crash="killed by SIGSEGV", name="h", group="random"), _case(statuses=[4])]
    assert fuzz.FuzzReport(Path("f.fmu"), cases).summary() == (
        "2 cases, 1 crashes, 1 with fmi2Fatal; statuses seen: {'OK': 1, 'Fatal': 1}\n"
        "  random: h: killed by SIGSEGV")
    cases = [_case(problems=["p"], name=f"c{k}") for k in range(5)]
    assert fuzz.FuzzReport(Path("f.fmu"), cases).summary().endswith("  g: c4: p")
    cases = [_case(problems=["p"], name=f"c{k}") for k in range(6)]
    assert fuzz.FuzzReport(Path("f.fmu"), cases).summary().endswith("  g: c4: p\n  ... and 1 more")


class _Child:
    """A stub of run_child answering as fuzzcases does (its documented command line: FMU
    GROUPS SEED RANDOM_CALLS INSTANCES START LOGGING; a begin row before and a result row
    after each case), for the cases ``script`` lists as (group, label, ending): ``None`` a
    result, ``"crash"`` death by SIGSEGV in the case, ``"hang"`` no end before the timeout.
    ``at_exit``: the return code after the last case (an abort at exit); ``load``: the
    return code of a process that dies before any case."""

    def __init__(self, script, at_exit=0, load=None):
        self.script, self.at_exit, self.load = script, at_exit, load
        self.runs: list[dict] = []

    def __call__(self, cmd, timeout_s):
        exe, flag, module, path, groups, seed, calls, inst, start, logging = cmd
        assert (exe, flag, module) == (fuzz.sys.executable, "-m",
                                       "dronefly.harness.compliance.fuzzcases")
        self.runs.append(dict(path=path, groups=groups, seed=int(seed), calls=int(calls),
                              instances=int(inst), start=int(start), logging=logging,
                              timeout=timeout_s))
        # at most one process per case and logging setting, and one more per setting
        assert len(self.runs) <= 2 * (len(self.script) + 1), "a process too many"
        if self.load is not None:
            return ChildRun(self.load, "", "")
        out = ["not a row: what an FMU printed"]
        for group, label, ending in self.script[int(start):]:
            out.append(json.dumps({"begin": label, "group": group}))
            if ending == "crash":
                return ChildRun(-signal.SIGSEGV, "\n".join(out), "")
            if ending == "hang":
                return ChildRun(None, "\n".join(out), "")
            out.append(json.dumps({"case": label + " (run)", "statuses": [0, int(logging) + 2],
                                   "problems": [], "group": group}))
        return ChildRun(self.at_exit, "\n".join(out) + "\n", "")


_SCRIPT = [("values", "a", None), ("values", "b", None), ("sequence", "c", None),
           ("sequence", "d", None), ("random", "e", None)]


def _fuzz(monkeypatch, child, **kw):
    monkeypatch.setattr(fuzz, "run_child", child)
    return fuzz.fuzz_fmu("some.fmu", **kw)


def test_fuzz_runs_each_logging_setting_with_the_arguments_given(monkeypatch):
    """One child per logging setting, from the first case; the arguments as given, the FMU's
    path absolute; the cases of logging off so labelled; all passed."""
    child = _Child(_SCRIPT)
    report = _fuzz(monkeypatch, child, groups=("values", "sequence"), seed=4, random_calls=9,
                   instances=3, timeout_s=2.5)
    assert report.path == Path("some.fmu").resolve() and report.passed
    assert child.runs == [dict(path=str(Path("some.fmu").resolve()), groups="values,sequence",
                               seed=4, calls=9, instances=3, start=0, logging=logging,
                               timeout=2.5) for logging in ("1", "0")]
    assert [(c.group, c.case, c.statuses) for c in report.cases] == [
        (g, f"{label} (run)", [0, 3]) for g, label, _ in _SCRIPT] + [
        (g, f"{label} (run) (logging off)", [0, 2]) for g, label, _ in _SCRIPT]
    child = _Child(_SCRIPT)
    report = _fuzz(monkeypatch, child)
    assert [r["groups"] for r in child.runs] == [",".join(fuzz.GROUP_NAMES)] * 2
    assert [(r["seed"], r["calls"], r["instances"], r["timeout"]) for r in child.runs] == [
        (0, 300, 50, 120.0)] * 2


def test_fuzz_takes_its_settings_by_keyword_only(monkeypatch):
    """``fuzz_fmu(path, *, groups=..., ...)``: a setting passed by position is refused (a
    caller cannot mix up seed, random_calls and instances)."""
    child = _Child(_SCRIPT)
    monkeypatch.setattr(fuzz, "run_child", child)
    with pytest.raises(TypeError):
        fuzz.fuzz_fmu("some.fmu", ("values",))
    assert child.runs == []


def test_fuzz_goes_on_after_each_crash_with_the_next_case(monkeypatch):
    """A case that kills the process is a crash of that case; a new process starts at the case
    after it; the crash is said as the signal."""
    script = [*_SCRIPT[:1], ("values", "b", "crash"), *_SCRIPT[2:3], ("sequence", "d", "crash"),
              *_SCRIPT[4:]]
    child = _Child(script)
    report = _fuzz(monkeypatch, child, logging=(False,))
    assert [r["start"] for r in child.runs] == [0, 2, 4]
    assert [(c.group, c.case, c.crash) for c in report.cases] == [
        ("values", "a (run) (logging off)", None),
        ("values", "b (logging off)", "killed by SIGSEGV"),
        ("sequence", "c (run) (logging off)", None),
        ("sequence", "d (logging off)", "killed by SIGSEGV"),
        ("random", "e (run) (logging off)", None)]
    assert [c.case for c in report.crashes] == ["b (logging off)", "d (logging off)"]
    assert not report.passed


def test_fuzz_counts_a_hang_and_goes_on(monkeypatch):
    """The stub child hangs in the third case: that case is a hang of the timeout given, a
    new process starts at the fourth."""
    script = [*_SCRIPT[:2], ("sequence", "c", "hang"), *_SCRIPT[3:]]
    child = _Child(script)
    report = _fuzz(monkeypatch, child, logging=(True,), timeout_s=7.0)
    assert [r["start"] for r in child.runs] == [0, 3]
    assert [(c.case, c.crash) for c in report.cases][2] == ("c", "hung for more than 7 s")
    assert len(report.cases) == 5


def test_fuzz_counts_an_abort_at_exit_once_after_the_last_case(monkeypatch):
    """A process that dies after its last case (at exit): a crash of "process exit" in the last
    case's group; no new process for it."""
    child = _Child(_SCRIPT, at_exit=-signal.SIGABRT)
    report = _fuzz(monkeypatch, child, logging=(True, False))
    assert [r["start"] for r in child.runs] == [0, 0]
    assert [(c.group, c.case, c.crash) for c in report.crashes] == [
        ("random", "process exit", "killed by SIGABRT"),
        ("random", "process exit (logging off)", "killed by SIGABRT")]
    assert len(report.cases) == 12
    child = _Child(_SCRIPT[:2] + [("sequence", "c", "crash")], at_exit=-signal.SIGABRT)
    report = _fuzz(monkeypatch, child, logging=(True,))
    assert [r["start"] for r in child.runs] == [0, 3]
    assert [c.case for c in report.crashes] == ["c", "process exit"]


def test_fuzz_counts_an_fmu_that_kills_the_process_before_any_case(monkeypatch):
    """Nothing but a death: the FMU did not load; one crash per logging setting, in the first
    group, and no retry."""
    child = _Child(_SCRIPT, load=1)
    report = _fuzz(monkeypatch, child, groups=("sequence", "random"))
    assert len(child.runs) == 2
    assert [(c.group, c.case, c.crash) for c in report.cases] == [
        ("sequence", "loading the FMU", "exit code 1"),
        ("sequence", "loading the FMU (logging off)", "exit code 1")]
    child = _Child(_SCRIPT, load=-signal.SIGSEGV)
    report = _fuzz(monkeypatch, child, groups=(), logging=(True,))
    assert [(c.group, c.case, c.crash) for c in report.cases] == [
        ("", "loading the FMU", "killed by SIGSEGV")]


def test_fuzz_a_process_that_dies_in_its_first_case_after_a_restart(monkeypatch):
    """A crash in the first case a restarted process runs is that case's, not a load's."""
    script = [("values", "a", "crash"), ("values", "b", "crash"), *_SCRIPT[2:]]
    child = _Child(script)
    report = _fuzz(monkeypatch, child, logging=(True,))
    assert [r["start"] for r in child.runs] == [0, 1, 2]
    assert [(c.case, c.crash) for c in report.cases[:2]] == [
        ("a", "killed by SIGSEGV"), ("b", "killed by SIGSEGV")]
