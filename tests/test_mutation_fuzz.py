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


class _Slave:
    """A compliant FMI 2.0 CS slave of the dronefly profile; ``defects`` (a set) change it:

    ``quiet``: no log message ever; ``anon``: messages name neither the call nor the variable;
    ``printed``: the messages go to standard output (PRINTED), not the logger; ``fatal``:
    every refusal is fmi2Fatal; ``drift``: a refused step still moves the output; ``obeys``:
    a forbidden call is refused but makes its transition; ``terminated_steps``: doStep is
    accepted after terminate; ``corrupt_ok``: any blob deserializes, to a state with another
    output; ``stuck``: no step after a refused state; ``global``: the output depends on a
    count shared by all instances (a static variable); ``overflow_anon``: a NaN or infinity is
    refused with a message on overflow, not naming the variable; ``bool_refused``: get/set
    Boolean are refused without a message.
    ``calls`` collects (function, arguments, state, status) of each call."""

    shared = [0]  # the "static variable" of the ``global`` defect

    def __init__(self, inst, defects):
        self.inst, self.defects = inst, defects
        self.calls = inst.fmu.calls
        self.state, self.t = "instantiated", 0.0
        self.values = {**_START, 6: False}

    # the machinery
    def _log(self, status, text):
        if "quiet" in self.defects:
            return
        if "anon" in self.defects:
            text = "refused"
        if "printed" in self.defects:
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
            return None
        self._enter("doStep", t, h)
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
            if "drift" in self.defects:
                self.values[4] += 1.0
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
        if "bool_refused" in self.defects:
            self.defects = self.defects | {"quiet"}
            self._refuse("getBoolean", _ERROR, "")
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
        text = json.dumps([{str(k): v for k, v in state.values.items()}, state.t, state.state])
        return text.encode() + zlib.crc32(text.encode()).to_bytes(4, "big")

    def deSerializeFMUstate(self, blob):
        self._enter("deSerializeFMUstate", bytes(blob))
        body, crc = blob[:-4], blob[-4:]
        if "corrupt_ok" in self.defects:
            return _State({**self.values, 4: 123.0}, self.t, self.state)
        if len(blob) < 5 or zlib.crc32(body).to_bytes(4, "big") != crc:
            if "stuck" in self.defects:
                self.state = "error"
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
        pass


def _run(cases):
    """{label: result} of a group's cases, run in order."""
    out = {}
    for label, run in cases:
        r = run()
        assert r["case"] == label
        out[label] = r
    return out


def _problems(cases):
    return {label: r["problems"] for label, r in _run(cases).items() if r["problems"]}


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


def test_instantiate_uses_the_logging_setting(monkeypatch):
    """Instances are made with logging as LOGGING says (on unless run_groups turns it off)."""
    fmu = _FMU()
    fuzzkit.instantiate(fmu, "on")
    fuzzkit.LOGGING[0] = False
    fuzzkit.instantiate(fmu, "off")
    assert fmu.names == [("on", True), ("off", False)]


def test_a_call_records_its_status_and_returns_its_result():
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
    fmu = _FMU()
    with fuzzkit.instantiate(fmu, "x") as inst:
        c = fuzzkit.Case("c", inst, True)
        for k in range(4):
            inst.messages.append(LogMessage("x", _ERROR, "", f"m{k}"))
        c.logged(0, "zzz")
    assert c.problems == ["no error message naming zzz (got ['m2', 'm3'])"]
