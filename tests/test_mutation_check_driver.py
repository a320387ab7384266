"""Independent oracles for the driver of ``dronefly check`` (harness/compliance/driver.py),
written for mutation testing (docs/mutation.md): the run the checks make (FMI 2.0 4.2.2: whole
steps within the experiment), the variables read and written with the get/set call of their
type, the inputs' excitation, a step and the end of a run (FMI 2.0 4.2.3: fmi2Discard with
fmi2Terminated after some progress), the log a failure quotes. A fake FMU and slave record
every call; the expected values are written out from the FMI 2.0 text and the documented
formulas."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from fmpy.fmi1 import FMICallException

from dronefly.harness.compliance import driver
from dronefly.harness.compliance.driver import Context, Var
from dronefly.harness.compliance.rules import CheckFailed, CheckOptions
from dronefly.harness.cosim.fmu import FMUError


class Slave:
    """Records the FMI calls; ``refuse`` maps a call's name to the status it fails with."""

    def __init__(self, refuse=None, values=None):
        self.calls, self.refuse = [], refuse or {}
        self.values = values or {}

    def _call(self, name, *args):
        self.calls.append((name, *args))
        if name in self.refuse:
            raise FMICallException(f"fmi2{name[0].upper()}{name[1:]}", self.refuse[name])

    def getReal(self, vrs):
        self._call("getReal", list(vrs))
        return [self.values.get(vr, 0.5 + vr) for vr in vrs]

    def getInteger(self, vrs):
        self._call("getInteger", list(vrs))
        return [int(self.values.get(vr, vr)) for vr in vrs]

    def getBoolean(self, vrs):
        self._call("getBoolean", list(vrs))
        return [bool(self.values.get(vr, vr % 2)) for vr in vrs]

    def setReal(self, vrs, xs):
        self._call("setReal", list(vrs), list(xs))

    def setInteger(self, vrs, xs):
        self._call("setInteger", list(vrs), list(xs))

    def setBoolean(self, vrs, xs):
        self._call("setBoolean", list(vrs), list(xs))

    def doStep(self, currentCommunicationPoint, communicationStepSize):
        self._call("doStep", currentCommunicationPoint, communicationStepSize)
        return self.step_result

    step_result = (False, False, False, 0.0)

    def getBooleanStatus(self, kind):
        self.calls.append(("getBooleanStatus", kind))
        return self.terminated

    def getRealStatus(self, kind):
        self.calls.append(("getRealStatus", kind))
        return self.last_time

    terminated, last_time = False, 0.0

    def setupExperiment(self, **kw):
        self.calls.append(("setupExperiment", kw))

    def enterInitializationMode(self):
        self.calls.append(("enterInitializationMode",))

    def exitInitializationMode(self):
        self.calls.append(("exitInitializationMode",))

    def terminate(self):
        self.calls.append(("terminate",))


def _v(name, vr, kind="Real", **attrs):
    return Var(name, kind, vr, SimpleNamespace(**{"min": None, "max": None, **attrs}))


def _variable(name, vr, causality, type_="Real", start=None, variability="continuous", **kw):
    return SimpleNamespace(name=name, valueReference=vr, causality=causality, type=type_,
                           start=start, variability=variability, min=kw.get("min"),
                           max=kw.get("max"))


def _fmu(variables=(), cs=True, me=True, de=(0.0, 2.0, 0.5), fmi=2, tool="X"):
    experiment = None if de is None else SimpleNamespace(startTime=de[0], stopTime=de[1],
                                                         stepSize=de[2])
    md = SimpleNamespace(coSimulation=object() if cs else None,
                         modelExchange=object() if me else None, defaultExperiment=experiment,
                         modelVariables=list(variables), generationTool=tool)
    fmu = SimpleNamespace(model_description=md, fmi_version=fmi, made=[])

    def instantiate(name, interface):
        inst = SimpleNamespace(slave=Slave(), messages=[], interface=interface, name=name)
        fmu.made.append(inst)
        return inst

    fmu.instantiate = instantiate
    return fmu


# --- the run: experiment ----------------------------------------------------------------------
@pytest.mark.parametrize("de, options, want", [
    ((0.0, 2.0, 0.5), CheckOptions(), (0.0, 2.0, 0.5, 4)),
    ((1.0, 3.0, None), CheckOptions(), (1.0, 3.0, 0.02, 100)),  # a hundredth of the run
    ((1.0, None, None), CheckOptions(), (1.0, 2.0, 0.01, 100)),  # no stop: start + 1 s
    (None, CheckOptions(), (0.0, 1.0, 0.01, 100)),
    ((2.0, 3.0, 0.5), CheckOptions(stop_time=4.2, step=0.4), (2.0, 4.2, 0.4, 5)),  # 2.0 s / 0.4
    # 0.3 / 0.1 is 2.9999999999999996 in floats: 3 whole steps, within the 1e-12 tolerance
    ((0.0, 0.3, 0.1), CheckOptions(), (0.0, 0.3, 0.1, 3)),
    ((0.0, 1.0, 1.0), CheckOptions(), (0.0, 1.0, 1.0, 1)),  # one step exactly
])
def test_the_run_is_whole_steps_within_the_experiment(de, options, want):
    start, stop, step, n = driver.experiment(_fmu(de=de).model_description, options)
    assert (start, stop, n) == (want[0], want[1], want[3])
    assert step == pytest.approx(want[2], rel=1e-15)


@pytest.mark.parametrize("de, options, message", [
    ((1.0, 1.0, 0.1), CheckOptions(), "stop time 1.0 s is not after the start time 1.0 s"),
    ((1.0, 0.5, 0.1), CheckOptions(), "stop time 0.5 s is not after the start time 1.0 s"),
    ((0.0, 1.0, 0.1), CheckOptions(step=1.5),
     "step 1.5 s is longer than the run from 0.0 s to 1.0 s"),
])
def test_a_run_with_no_step_is_refused_naming_the_values(de, options, message):
    with pytest.raises(FMUError) as e:
        driver.experiment(_fmu(de=de).model_description, options)
    assert str(e.value) == message


# --- the context ------------------------------------------------------------------------------
def test_the_context_reads_interfaces_inputs_and_outputs():
    vs = [_variable("u", 1, "input", start=2.5), _variable("w", 2, "input"),
          _variable("k", 3, "input", "Integer", start=4), _variable("s", 4, "input", "String"),
          _variable("y", 5, "output"), _variable("n", 6, "output", "Enumeration"),
          _variable("p", 7, "parameter", start=1.0)]
    for cs, me, want in [(True, True, ("cs", "me")), (True, False, ("cs",)),
                         (False, True, ("me",))]:
        ctx = Context(_fmu(vs, cs, me), CheckOptions(), None)
        assert ctx.interfaces == want
    assert [(v.name, v.kind, v.vr) for v in ctx.inputs] == [("u", "Real", 1), ("w", "Real", 2),
                                                            ("k", "Integer", 3)]
    assert [(v.name, v.kind) for v in ctx.outputs] == [("y", "Real"), ("n", "Integer")]
    # the Real inputs move about their start, 0 where they have none
    assert ctx.input_base == [2.5, 0.0] and ctx.input_start == {1: 2.5, 2: 0.0}
    assert (ctx.start, ctx.stop, ctx.step, ctx.n) == (0.0, 2.0, 0.5, 4)
    assert ctx.profile == "standard" and not ctx.ours and ctx.fmi == "fmi2"
    assert Context(_fmu(vs, tool="dronefly-fmu 2.1"), CheckOptions(), None).ours
    assert Context(_fmu(vs, tool="dronefly-fmu"), CheckOptions(profile="standard"),
                   None).profile == "standard"


def test_an_instance_is_announced_and_its_log_passed_on_only_to_a_listener():
    rows = []
    ctx = Context(_fmu(), CheckOptions(), rows.append)
    ctx.interface = "me"
    inst = ctx.instantiate("first")
    ctx.interface = "cs"
    ctx.instantiate("second")
    assert rows == [{"call": "fmi2Instantiate(instanceName='first') through Model Exchange"},
                    {"call": "fmi2Instantiate(instanceName='second')"}]
    assert ctx.instances == ctx.fmu.made
    inst.messages.append(SimpleNamespace(status=3, category="logError", message="x" * 600))
    assert rows[-1] == {"log": ("[3] logError: " + "x" * 600)[:500]}
    assert len(rows[-1]["log"]) == 500
    quiet = Context(_fmu(), CheckOptions(), None)
    inst = quiet.instantiate("q")
    assert type(inst.messages) is list  # noqa: E721 (no tee without a listener)


def _msg(status, category, message):
    return SimpleNamespace(status=status, category=category, message=message)


def test_the_log_tail_is_the_last_messages_above_ok():
    """The last three messages with a status above OK (or one that is no status: a message
    the FMU corrupted); all messages if none is above OK; the category, or ``log``."""
    ctx = Context(_fmu(), CheckOptions(), None)
    a, b = SimpleNamespace(messages=[]), SimpleNamespace(messages=[])
    ctx.instances = [a, b]
    a.messages += [_msg(0, "logAll", "fine"), _msg(2, "logDiscard", " d1 "), _msg(1, "", "w1")]
    b.messages += [_msg(3, "logError", "e1"), _msg(0, "logAll", "ok2"), _msg(4, "logFatal", "f")]
    assert ctx.log_tail() == "log: w1; logError: e1; logFatal: f"
    assert ctx.log_tail(k=2) == "logError: e1; logFatal: f"
    b.messages[:] = [_msg(None, "odd", "corrupt")]
    assert ctx.log_tail() == "logDiscard: d1; log: w1; odd: corrupt"
    a.messages[:] = [_msg(0, "logAll", "one"), _msg(0, "logAll", "two")]
    b.messages[:] = []
    assert ctx.log_tail() == "logAll: one; logAll: two"


# --- variables: named, read, written, bounded ----------------------------------------------------
def test_variables_are_named_with_their_value_references_four_at_most():
    vs = [_v(c, k) for k, c in enumerate("abcdef", start=1)]
    assert driver.named(vs[:1]) == "a (value reference 1)"
    assert driver.named(vs[:4]) == ("a (value reference 1), b (value reference 2), "
                                    "c (value reference 3), d (value reference 4)")
    assert driver.named(vs[:5]) == driver.named(vs[:4]) + " and 1 more"
    assert driver.named(vs) == driver.named(vs[:4]) + " and 2 more"


def test_reals_are_read_in_one_call_and_other_types_with_their_own():
    reals = [_v("x", 5), _v("y", 3)]
    slave = Slave(values={5: 1.25, 3: -2.0})
    assert driver.read_now(SimpleNamespace(slave=slave), reals) == [1.25, -2.0]
    assert slave.calls == [("getReal", [5, 3])]
    mixed = [_v("b", 7, "Boolean"), _v("x", 5), _v("n", 2, "Integer"), _v("y", 3),
             _v("m", 4, "Integer")]
    slave = Slave(values={5: 1.25, 3: -2.0, 2: 9, 4: -3, 7: 1})
    got = driver.read_now(SimpleNamespace(slave=slave), mixed)
    assert got == [1.0, 1.25, 9.0, -2.0, -3.0] and all(type(x) is float for x in got)
    assert slave.calls == [("getReal", [5, 3]), ("getInteger", [2, 4]), ("getBoolean", [7])]
    ints = [_v("n", 2, "Integer"), _v("m", 4, "Integer")]
    slave = Slave(values={2: 9, 4: -3})
    assert driver.read_now(SimpleNamespace(slave=slave), ints) == [9.0, -3.0]
    assert slave.calls == [("getInteger", [2, 4])]


def test_a_refused_get_fails_naming_the_variables_of_the_call():
    mixed = [_v("x", 5), _v("n", 2, "Integer"), _v("m", 4, "Integer")]
    with pytest.raises(CheckFailed) as e:
        driver.read_now(SimpleNamespace(slave=Slave(refuse={"getInteger": 3})), mixed)
    assert str(e.value) == ("fmi2GetInteger failed with status 3 (error) reading "
                            "n (value reference 2), m (value reference 4)")
    with pytest.raises(CheckFailed) as e:
        driver.read_now(SimpleNamespace(slave=Slave(refuse={"getReal": 2})), mixed[:1])
    assert str(e.value) == ("fmi2GetReal failed with status 2 (discard) reading "
                            "x (value reference 5)")


def test_a_value_is_written_with_the_set_call_of_its_type():
    slave = Slave()
    inst = SimpleNamespace(slave=slave)
    driver.write(inst, _v("x", 1), 2)
    driver.write(inst, _v("n", 2, "Integer"), 3.0)
    driver.write(inst, _v("b", 3, "Boolean"), 1)
    assert slave.calls == [("setReal", [1], [2.0]), ("setInteger", [2], [3]),
                           ("setBoolean", [3], [True])]
    assert [type(c[2][0]) for c in slave.calls] == [float, int, bool]
    with pytest.raises(CheckFailed) as e:
        driver.write(SimpleNamespace(slave=Slave(refuse={"setReal": 3})), _v("x", 1), 2.5)
    assert str(e.value) == "fmi2SetReal failed with status 3 (error) setting x (value reference 1) = 2.5"


@pytest.mark.parametrize("lo, hi, x, want", [(None, None, 5.0, 5.0), (0.0, None, -1.0, 0.0),
                                             (None, 2.0, 3.0, 2.0), (-1.0, 1.0, 0.5, 0.5),
                                             ("1", "4", 9.0, 4.0), ("1", "4", -9.0, 1.0)])
def test_a_value_is_bounded_by_the_variables_min_and_max(lo, hi, x, want):
    assert driver.bounded(_v("u", 1, min=lo, max=hi), x) == want


def test_the_real_inputs_are_moved_about_their_start_within_their_bounds():
    """Step k: input j at start + 0.01 sin(0.3 k + j), clipped to [min, max]; through Model
    Exchange only the continuous ones; no call without Real inputs."""
    vs = [_variable("u", 1, "input", start=2.5), _variable("w", 2, "input", max=-0.001),
          _variable("d", 3, "input", start=1.0, variability="discrete")]
    ctx = Context(_fmu(vs), CheckOptions(), None)
    slave = Slave()
    driver.excite(ctx, SimpleNamespace(slave=slave), 7)
    (name, vrs, xs), = slave.calls
    assert (name, vrs) == ("setReal", [1, 2, 3])
    want = [2.5 + 0.01 * math.sin(2.1), min(0.01 * math.sin(3.1), -0.001),
            1.0 + 0.01 * math.sin(4.1)]
    assert xs == pytest.approx(want, rel=1e-15, abs=0)
    assert xs[1] == -0.001  # 0.01 sin(3.1) = 4.2e-4 is above the max
    ctx.interface = "me"
    slave = Slave()
    driver.excite(ctx, SimpleNamespace(slave=slave), 0)
    assert slave.calls == [("setReal", [1, 2], [2.5 + 0.01 * math.sin(0.0),
                                                min(0.01 * math.sin(1.0), -0.001)])]
    none = Context(_fmu([_variable("y", 5, "output")]), CheckOptions(), None)
    slave = Slave()
    driver.excite(none, SimpleNamespace(slave=slave), 3)
    assert slave.calls == []


# --- a step, a run --------------------------------------------------------------------------------
def _stepping(fmi=2, interface="cs", rows=None):
    ctx = Context(_fmu(fmi=fmi), CheckOptions(), rows.append if rows is not None else None)
    return ctx, SimpleNamespace(slave=Slave(), interface=interface)


def test_a_step_is_announced_with_its_interface():
    rows = []
    ctx, inst = _stepping(rows=rows)
    assert driver.do_step(ctx, inst, 0.5, 0.25) is False
    inst.interface = "me"
    driver.do_step(ctx, inst, 1.0, 0.5)
    assert rows == [
        {"call": "fmi2DoStep(currentCommunicationPoint=0.5, communicationStepSize=0.25)"},
        {"call": "Model Exchange step (CVODE, events)(currentCommunicationPoint=1.0, "
                 "communicationStepSize=0.5)"}]
    assert inst.slave.calls == [("doStep", 0.5, 0.25), ("doStep", 1.0, 0.5)]


@pytest.mark.parametrize("fmi, interface", [(3, "cs"), (2, "me"), (3, "me")])
@pytest.mark.parametrize("result, ended", [((False, False, False, 1.0), False),
                                           ((False, True, False, 1.0), True),
                                           ((False, False, True, 0.7), True)])
def test_an_fmi3_or_model_exchange_step_ends_the_run_on_terminate_or_early_return(
        fmi, interface, result, ended):
    ctx, inst = _stepping(fmi, interface)
    inst.slave.step_result = result
    assert driver.do_step(ctx, inst, 0.5, 0.5) is ended


@pytest.mark.parametrize("terminated, last, ends", [(True, 0.75, True), (True, 0.5, False),
                                                    (False, 0.75, False)])
def test_an_fmi2_discard_ends_the_run_only_terminated_after_progress(terminated, last, ends):
    """FMI 2.0 4.2.3: fmi2Discard with fmi2Terminated and a last successful time after the
    step's start: the FMU ended the run; without progress (or not terminated) the step was
    refused, and the error goes on."""
    ctx, inst = _stepping()
    inst.slave.refuse = {"doStep": 2}
    inst.slave.terminated, inst.slave.last_time = terminated, last
    if ends:
        assert driver.do_step(ctx, inst, 0.5, 0.5) is True
    else:
        with pytest.raises(FMICallException):
            driver.do_step(ctx, inst, 0.5, 0.5)
    inst.slave.refuse = {"doStep": 3}  # an error is never the end of a run
    with pytest.raises(FMICallException):
        driver.do_step(ctx, inst, 0.5, 0.5)


def test_a_run_records_the_outputs_after_each_step_and_where_the_fmu_ended_it():
    vs = [_variable("u", 1, "input", start=1.0), _variable("y", 5, "output")]
    ctx = Context(_fmu(vs, fmi=3), CheckOptions(), None)
    inst = SimpleNamespace(slave=Slave(values={5: 2.0}), interface="cs")
    run = driver.whole_run(ctx, inst)
    assert run.ended_at is None and run.rows.shape == (5, 1)  # the start and 4 steps
    steps = [c for c in inst.slave.calls if c[0] == "doStep"]
    assert steps == [("doStep", k * 0.5, 0.5) for k in range(4)]
    assert inst.slave.calls[0][0] == "setupExperiment"
    assert inst.slave.calls[0][1] == {"startTime": 0.0, "stopTime": 2.0}
    assert inst.slave.calls[-1] == ("terminate",)
    inst = SimpleNamespace(slave=Slave(), interface="cs")
    inst.slave.step_result = (False, True, False, 1.0)  # terminate asked at the first step
    run = driver.run_steps(ctx, inst, range(2, 4))
    assert run.ended_at == 1.5 and run.rows.shape == (2, 1)


def test_same_is_equal_shapes_and_values_nan_included():
    a = np.array([[1.0, math.nan], [2.0, 3.0]])
    assert driver.same(a, a.copy())
    assert not driver.same(a, a[:1]) and not driver.same(a, a + 1e-16 * 0 + np.eye(2) * 1e-9)


def test_a_step_status_is_the_status_of_the_call():
    rows = []
    ctx, inst = _stepping(rows=rows)
    assert driver.step_status(ctx, inst, 0.0, 0.1) == 0
    inst.slave.refuse = {"doStep": 3}
    assert driver.step_status(ctx, inst, 0.1, 0.1) == 3
    assert rows[-1] == {"call": "fmi2DoStep(currentCommunicationPoint=0.1, "
                                "communicationStepSize=0.1)"}


def test_a_variable_is_a_value():
    import dataclasses

    with pytest.raises(dataclasses.FrozenInstanceError):
        _v("u", 1).vr = 2
