"""The system master: any number of FMUs from Python or SSP, ordered by ModelStructure.

Oracles: the pair master of harness.cosim (bit for bit), the SSP and the Python description
of one system (same trajectory to 1e-12), an algebraic loop refused with its cycle named.
"""

from __future__ import annotations

import contextlib
import json
import math
import re
import textwrap
import zipfile
from pathlib import Path

import numpy as np
import pytest
from pair_master import PairMaster

from dronefly.cli.app import main
from dronefly.harness.cosim.master import Loop
from dronefly.harness.cosim.system import Connection, System, SystemSpecError
from dronefly.harness.cosim.system_master import SystemMaster
from dronefly.models.feedback import PAPER_GAINS_EQ27
from dronefly.models.lateral_interface import CONTROL_NAMES, STATE_NAMES, scale_vector

pytestmark = pytest.mark.integration

H = 0.1 / 164.0  # s: 0.1 wing beat
GAIN = textwrap.dedent('''
    from pythonfmu import (Boolean, Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real,
                           String)


    class Gain(Fmi2Slave):
        """y = (-1 if negate else 1) m k u, direct feedthrough (pythonfmu declares no
        dependencies: all); steps counts the steps done; a step from t >= fail_at_s fails."""

        def __init__(self, **kwargs):
            super().__init__(**kwargs)
            self.u, self.k, self.m, self.negate, self.label = 0.0, 1.0, 1, False, "gain"
            self.fail_at_s, self.steps = 1e300, 0
            self.register_variable(Real("u", causality=Fmi2Causality.input,
                                        variability=Fmi2Variability.continuous))
            for name in ("k", "fail_at_s"):
                self.register_variable(Real(name, causality=Fmi2Causality.parameter,
                                            variability=Fmi2Variability.tunable))
            self.register_variable(Integer("m", causality=Fmi2Causality.parameter,
                                           variability=Fmi2Variability.tunable))
            self.register_variable(Boolean("negate", causality=Fmi2Causality.parameter,
                                           variability=Fmi2Variability.tunable))
            self.register_variable(String("label", causality=Fmi2Causality.parameter,
                                          variability=Fmi2Variability.tunable))
            self.register_variable(Real("y", causality=Fmi2Causality.output,
                                        variability=Fmi2Variability.continuous,
                                        getter=lambda: (-1 if self.negate else 1) * self.m
                                        * self.k * self.u))
            self.register_variable(Integer("steps", causality=Fmi2Causality.output,
                                           variability=Fmi2Variability.discrete))

        def do_step(self, t, h):
            if t >= self.fail_at_s:
                return False
            self.steps += 1
            return True
''')


@pytest.fixture(scope="module")
def gain(tmp_path_factory) -> Path:
    from pythonfmu import FmuBuilder

    d = tmp_path_factory.mktemp("gain")
    (d / "Gain.py").write_text(GAIN)
    return Path(FmuBuilder.build_FMU(d / "Gain.py", dest=d))


def _x0(plant_fmu) -> dict[str, float]:
    scale = scale_vector()
    return {f"{s}_start": float(v) for s, v in zip(STATE_NAMES, np.array([0, 0, 0, 0.1]) * scale)}


class _GainsFirst:
    """The controller FMU, its instances given ``gains`` before initialization (the dedicated
    pair master sets no controller parameter; the FMU reads them when it computes)."""

    def __init__(self, fmu, gains: dict[str, float]) -> None:
        self.fmu, self.gains = fmu, gains

    def names(self, causality: str) -> list[str]:
        return self.fmu.names(causality)

    @contextlib.contextmanager
    def instantiate(self):
        with self.fmu.instantiate() as c:
            c.slave.setReal(c.vrs(list(self.gains)), list(self.gains.values()))
            yield c


def _gain_sets() -> dict[str, np.ndarray]:
    from dronefly.harness.paper.gains import gain_matrix

    rng = np.random.default_rng(12)  # two random sets: every row and column in play
    return {"paper": gain_matrix("paper"), "random 1": rng.normal(0.0, 0.3, (3, 4)),
            "open": gain_matrix("open"), "random 2": rng.normal(0.0, 0.1, (3, 4))}


@pytest.mark.parametrize("master", ["gauss-seidel", "jacobi"])
def test_pair_through_the_system_master_equals_the_former_pair_master(built_fmus, plant,
                                                                      controller, master):
    """Oracle: the pair master kept in benchmarks/ (and its Jacobi ordering, kept above),
    bit for bit, for the pair through SystemMaster (derived order, fresh instances) and
    through Loop (the pair's order, reused instances, Jacobi's u_source0)."""
    from dronefly.models.feedback import gain_name

    former = PairMaster
    system = System.by_name({"plant": built_fmus["DroneFlyLateral"],
                             "controller": built_fmus["StateFeedback"]})
    names = [f"plant.{s}" for s in STATE_NAMES] + [f"controller.{c}" for c in CONTROL_NAMES]
    scale = scale_vector()
    loop = Loop(plant, controller)
    with SystemMaster(system, master) as sm, plant.instantiate() as p, \
            controller.instantiate() as c:
        for (tag, K), step_wb, x0 in zip(_gain_sets().items(), (0.1, 1.0, 3.0, 0.1),
                                         ([0, 0, 0, 0.1], [0.1, -0.2, 0.05, 0.0],
                                          [0, 0.3, 0, -0.1], [0.2, 0, 0.1, 0.1])):
            gains = {gain_name(i, j): float(K[i, j]) for i in range(3) for j in range(4)}
            start = {f"{s}_start": float(v) for s, v in zip(STATE_NAMES, np.array(x0) * scale)}
            h, n = step_wb / 164.0, 60
            ref = former(plant, _GainsFirst(controller, gains), master).run(
                h, n, plant_start=start)
            got = sm.run(h, n, record=names, values={"plant": start, "controller": gains})
            via_loop = loop.run(h, n, master=master, plant_start=start,
                                controller_params=gains, instances=(p, c))
            assert got.complete and via_loop.complete
            assert np.array_equal(got.signals, ref.signals), (tag, step_wb)
            assert np.array_equal(via_loop.signals, ref.signals), (tag, step_wb)
            assert np.any(ref.signals[1:] != ref.signals[0]), "it moved"
        if master == "jacobi":  # the identification runs' start: another previous state
            u0 = [0.0, 0.1 * scale[1], 0.0, 0.0]
            ref = former(plant, _GainsFirst(controller, gains), master).run(
                h, n, plant_start=start, u_source0=u0)
            via_loop = loop.run(h, n, master=master, plant_start=start,
                                controller_params=gains, u_source0=u0, instances=(p, c))
            assert np.array_equal(via_loop.signals, ref.signals)
            assert not np.array_equal(via_loop.signals[:2], got.signals[:2])


def _three(built_fmus, gain) -> System:
    """Plant -> controller -> foreign gain block (k = 1) -> plant's delta_Phi_a."""
    cons = [Connection("plant", s, "controller", s) for s in STATE_NAMES]
    cons += [Connection("controller", "delta_Phi_a", "gain", "u"),
             Connection("gain", "y", "plant", "delta_Phi_a"),
             Connection("controller", "delta_alpha_1a", "plant", "delta_alpha_1a")]
    return System({"plant": built_fmus["DroneFlyLateral"],
                   "controller": built_fmus["StateFeedback"], "gain": gain}, cons,
                  {"plant": _x0(None), "gain": {"k": 1.0}})


def test_three_fmus_with_a_foreign_one_in_the_loop(built_fmus, gain, plant, controller):
    """A gain of 1 inserted in the loop changes nothing: the pair's trajectory."""
    with SystemMaster(_three(built_fmus, gain)) as sm:
        assert sm.order.free == ("plant",) and sm.order.chained == ("controller", "gain")
        run = sm.run(H, 200, record=[f"plant.{s}" for s in STATE_NAMES])
    ref = Loop(plant, controller).run(H, 200, plant_start=_x0(plant))
    assert run.complete
    np.testing.assert_array_equal(run.signals, ref.signals[:, :4])


def _write_ssp(system: System, path: Path, prefixed: bool = False) -> Path:
    """A hand-written SSP (SSD + one SSV per instance) of a system: a foreign writer.
    ``prefixed``: each SSV names its parameters ``<instance>.NAME`` and the binding declares
    the prefix ``<instance>.`` (SSP 1.0 ParameterBinding prefix, removed by the reader)."""
    comps, ssvs = [], {}
    for inst, fmu in system.fmus.items():
        prefix = f"{inst}." if prefixed else ""
        attr = f' prefix="{prefix}"' if prefixed else ""
        comps.append(f'<ssd:Component name="{inst}" source="resources/{fmu.name}" '
                     f'type="application/x-fmu-sharedlibrary"><ssd:ParameterBindings>'
                     f'<ssd:ParameterBinding source="resources/{inst}.ssv"{attr}/>'
                     f'</ssd:ParameterBindings></ssd:Component>')
        params = "".join(f'<ssv:Parameter name="{prefix}{k}"><ssv:Real value="{v!r}"/>'
                         '</ssv:Parameter>'
                         for k, v in system.parameters.get(inst, {}).items())
        ssvs[inst] = ('<?xml version="1.0" encoding="UTF-8"?><ssv:ParameterSet version="1.0" '
                      f'name="{inst}" xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues">'
                      f'<ssv:Parameters>{params}</ssv:Parameters></ssv:ParameterSet>')
    cons = "".join(f'<ssd:Connection startElement="{c.source}" startConnector="{c.output}" '
                   f'endElement="{c.target}" endConnector="{c.input}"/>' for c in system.connections)
    ssd = ('<?xml version="1.0" encoding="UTF-8"?><ssd:SystemStructureDescription version="1.0" '
           'name="three" xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription">'
           f'<ssd:System name="three"><ssd:Elements>{"".join(comps)}</ssd:Elements>'
           f'<ssd:Connections>{cons}</ssd:Connections></ssd:System></ssd:SystemStructureDescription>')
    with zipfile.ZipFile(path, "w") as z:
        z.writestr("SystemStructure.ssd", ssd)
        for inst, fmu in system.fmus.items():
            z.write(fmu, f"resources/{fmu.name}")
            z.writestr(f"resources/{inst}.ssv", ssvs[inst])
    return path


def test_ssp_and_python_give_the_same_trajectory(built_fmus, gain, tmp_path):
    system = _three(built_fmus, gain)
    from_ssp = System.from_ssp(_write_ssp(system, tmp_path / "three.ssp"))
    assert set(from_ssp.fmus) == {"plant", "controller", "gain"}
    names = [f"plant.{s}" for s in STATE_NAMES]
    with SystemMaster(system) as a, SystemMaster(from_ssp) as b:
        ra, rb = a.run(H, 300, record=names), b.run(H, 300, record=names)
    assert ra.complete and rb.complete
    np.testing.assert_allclose(rb.signals, ra.signals, rtol=1e-12, atol=0)
    assert np.max(np.abs(ra.signals)) > 0.05  # it moved


def test_a_binding_prefix_is_removed_from_the_parameter_names(built_fmus, gain, tmp_path):
    """SSP 1.0: a ParameterBinding's prefix is removed from the names of its parameter values;
    the system read back binds each value to the FMU variable it names."""
    system = _three(built_fmus, gain)
    assert any(system.parameters.values())
    from_ssp = System.from_ssp(_write_ssp(system, tmp_path / "three.ssp", prefixed=True))
    assert {k: v for k, v in from_ssp.parameters.items() if v} == \
        {k: v for k, v in system.parameters.items() if v}


def test_algebraic_loop_is_refused_with_its_cycle_and_runs_under_jacobi(gain):
    """g1.u = 2 given (the input keeps it at initialization: its source g2 comes later in
    the loop), then every FMU answers from the previous point's inputs."""
    from dronefly.harness.stability.system_verdicts import cosimulate_system

    k1, k2, u0 = 0.5, -0.8, 2.0
    system = System({"g1": gain, "g2": gain},
                    [Connection("g1", "y", "g2", "u"), Connection("g2", "y", "g1", "u")],
                    {"g1": {"k": k1}, "g2": {"k": k2}})
    with pytest.raises(SystemSpecError, match=r"algebraic loop .*g1\.y -> g2\.u -> g2\.y -> g1\.u"):
        SystemMaster(system)
    r = cosimulate_system(system, master="jacobi", step_wingbeats=0.1, stop_wingbeats=0.8,
                          set_values={"g1.u": "2"}, record=["g1.y", "g2.y", "g1.u"],
                          verdicts=False, out_dir=None)
    # expected: initialization in the declared order (g1 from its given input, g2 from g1),
    # then y1[k+1] = k1 y2[k], y2[k+1] = k2 y1[k]; g1's input at k is y2[k] (from k = 0 on)
    y1, y2, expected = k1 * u0, k2 * k1 * u0, []
    for _ in range(9):
        expected.append((y1, y2, y2))
        y1, y2 = k1 * y2, k2 * y1
    assert r.run.complete and len(r.run.time) == 9 and not r.axes
    np.testing.assert_allclose(r.run.signals, expected, rtol=1e-15, atol=0)
    assert r.run.signals[0, 0] == 1.0 and r.run.signals[1, 0] == pytest.approx(-0.4)


@pytest.mark.parametrize("cons,fragment", [
    ([Connection("plant", "delta_v", "controller", "delta_p")], r"units differ \(m/s -> rad/s\)"),
    ([Connection("plant", "delta_q", "controller", "delta_p")], "has no variable 'delta_q'"),
    ([Connection("controller", "delta_v", "plant", "delta_Phi_a")], "is an input, not an output"),
])
def test_bad_connections_are_refused(built_fmus, cons, fragment):
    system = System({"plant": built_fmus["DroneFlyLateral"],
                     "controller": built_fmus["StateFeedback"]}, cons)
    with pytest.raises(SystemSpecError, match=fragment):
        SystemMaster(system)


def test_two_sources_for_one_input_are_refused(built_fmus):
    with pytest.raises(SystemSpecError, match="has two sources"):
        System({"a": built_fmus["DroneFlyLateral"], "b": built_fmus["DroneFlyLateral"],
                "c": built_fmus["StateFeedback"]},
               [Connection("a", "delta_v", "c", "delta_v"), Connection("b", "delta_v", "c", "delta_v")])


def test_unconnected_inputs_keep_their_start_value_or_a_given_one(built_fmus):
    """The controller alone: its inputs are unconnected; u = K x from the values given."""
    system = System({"controller": built_fmus["StateFeedback"]},
                    parameters={"controller": {"delta_gamma": 0.1}})
    with SystemMaster(system) as sm:
        run = sm.run(H, 2, record=["controller.delta_Phi_a"])
    assert run.signals[0, 0] == pytest.approx(PAPER_GAINS_EQ27[3] * 0.1, rel=1e-12)


def test_failed_call_stops_the_run_naming_instance_call_and_time(built_fmus, gain):
    """The foreign gain block refuses its step from t = 20 h on: the run stops there, names
    the gain, fmi2DoStep and the time, and keeps the 21 points recorded before."""
    names = ["plant.delta_gamma", "controller.delta_Phi_a"]
    with SystemMaster(_three(built_fmus, gain)) as sm:
        full = sm.run(H, 50, record=names)
        run = sm.run(H, 50, record=names, values={"gain": {"fail_at_s": 20 * H}})
        early = sm.run(H, 50, record=names, values={"gain": {"fail_at_s": 0.0}})
    assert full.complete and not run.complete
    assert (run.failure.fmu, run.failure.call, run.failure.time) == ("gain", "fmi2DoStep", 20 * H)
    assert run.failure.status == 2 and f"gain: fmi2DoStep at t = {20 * H!r} s" in str(run.failure)
    assert len(run.time) == 21 and np.array_equal(run.signals, full.signals[:21])
    assert (early.failure.fmu, early.failure.time, len(early.time)) == ("gain", 0.0, 1)


def test_cli_marks_a_failed_run_incomplete_and_keeps_its_csv(built_fmus, gain, tmp_path, capsys):
    from dronefly.harness.cosim.ssp import write_system_ssp

    ssp = write_system_ssp(_three(built_fmus, gain), tmp_path / "three.ssp")
    out = tmp_path / "o"
    code = main(["cosim", "--system", str(ssp), "--stop", "5", "--no-plot", "--json", "--out",
                 str(out), "--set", f"gain.fail_at_s={20 * H!r}"])
    captured = capsys.readouterr()
    assert code == 1
    where = f"gain: fmi2DoStep at t = {20 * H!r} s"
    assert captured.err.count("\n") == 1 and "run incomplete" in captured.err and where in captured.err
    printed = json.loads(captured.out)
    (written,) = out.glob("*.json")
    assert json.loads(written.read_text()) == printed
    assert printed["complete"] is False and printed["failure"].startswith(where)
    assert printed["axes"] == []  # no verdict from a broken run
    rows = Path(printed["csv"]).read_text().splitlines()
    assert len(rows) == 1 + 21 and rows[0].split(",")[0] == "time"
    assert float(rows[-1].split(",")[0]) == pytest.approx(20 * H, rel=1e-15)


# ------------------------------------------------------------------ values of declared types
def test_values_take_the_declared_types_of_a_foreign_fmu(gain):
    """Text (as from --set), numbers and booleans, converted to Integer, Boolean, String
    and Real; u unconnected: y = -(m k u)."""
    system = System({"g": gain}, parameters={"g": {"m": "3", "negate": "1", "label": "x"}})
    with SystemMaster(system.with_values({"g.k": "0.5", "g.u": 2})) as sm:
        a = sm.run(0.1, 2, record=["g.y", "g.m", "g.negate"])
        b = sm.run(0.1, 2, record=["g.y"], values={"g": {"m": 4.0, "negate": False,
                                                         "label": "y"}})
    assert a.signals.tolist() == [[-3.0, 3.0, 1.0]] * 3
    assert b.signals[:, 0].tolist() == [4.0] * 3


@pytest.mark.parametrize("name, value, fragment", [
    ("m", 1.5, "g.m = 1.5: an Integer takes a whole number"),
    ("m", "abc", "g.m = 'abc': an Integer takes a whole number"),
    ("m", True, "g.m = True: an Integer"),
    ("m", 2 ** 31, "g.m = 2147483648 is outside the Integer range"),
    ("negate", 2, "g.negate = 2: a Boolean takes true, false, 1 or 0"),
    ("negate", "yes", "g.negate = 'yes': a Boolean"),
    ("k", True, "g.k = True: a Real takes a number"),
    ("k", "true", "g.k = 'true' is not a number"),
    ("k", math.nan, "g.k = nan is not finite"),
    ("u", "inf", "g.u = 'inf' is not finite"),
    ("label", 3, "g.label = 3: a String takes text"),
    ("y", 1.0, "g.y: no parameter or input of that name"),
    pytest.param("m", "9" * 400, "g.m = '" + "9" * 29 + "... (402 characters) is outside",
                 id="m-400-digits"),
    pytest.param("m", 10 ** 400, "g.m = 1" + "0" * 29 + "... (401 characters) is outside",
                 id="m-10**400"),
    pytest.param("k", -10 ** 400, "g.k = -1" + "0" * 28 + "... (402 characters) is beyond "
                 "the range of a Real", id="k--10**400"),
])
def test_values_of_the_wrong_type_are_refused_naming_them(gain, name, value, fragment):
    with pytest.raises(SystemSpecError, match=re.escape(fragment)):
        SystemMaster(System({"g": gain}, parameters={"g": {name: value}}))
    with SystemMaster(System({"g": gain})) as sm, \
            pytest.raises(SystemSpecError, match=re.escape(fragment)):
        sm.run(0.1, 2, values={"g": {name: value}})
    from dronefly.harness.stability.system_verdicts import cosimulate_system

    with pytest.raises(SystemSpecError, match=re.escape(fragment)):
        cosimulate_system(System({"g": gain}), set_values={f"g.{name}": value}, out_dir=None)


@pytest.mark.parametrize("setting, fragment", [
    ("controller.limit_enabled=2", "'2': a Boolean takes true, false, 1 or 0"),
    ("controller.K[1,1]=true", "controller.K[1,1] = 'true' is not a number (a Real)"),
    ("controller.u_max=abc", "controller.u_max = 'abc' is not a number (a Real)"),
])
def test_pair_values_of_the_wrong_type_exit_2(built_fmus, tmp_path, capsys, setting, fragment):
    """The --plant/--controller path refuses them the same way (one line, exit 2, nothing
    written), and so does its Python API."""
    from dronefly.core.errors import DroneflyError
    from dronefly.harness.stability.run import cosimulate

    out = tmp_path / "o"
    code = main(["cosim", "--plant", str(built_fmus["DroneFlyLateral"]), "--controller",
                 str(built_fmus["StateFeedback"]), "--no-plot", "--out", str(out),
                 "--set", setting])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and fragment in err and not out.exists()
    with pytest.raises(DroneflyError, match=re.escape(fragment)):
        cosimulate(built_fmus["DroneFlyLateral"], built_fmus["StateFeedback"], out_dir=None,
                   set_values=dict([setting.split("=", 1)]))  # text, as --set gives it


def test_a_huge_value_exits_2_naming_it(built_fmus, gain, tmp_path, capsys):
    """--set of 400 digits on an Integer: one line naming instance.NAME, exit 2 (it raised
    OverflowError, an internal error)."""
    from dronefly.harness.cosim.ssp import write_system_ssp

    ssp = write_system_ssp(_three(built_fmus, gain), tmp_path / "three.ssp")
    out = tmp_path / "o"
    code = main(["cosim", "--system", str(ssp), "--stop", "1", "--no-plot", "--out", str(out),
                 "--set", "gain.m=" + "9" * 400])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and not out.exists()
    assert "gain.m = '99999" in err and "(402 characters) is outside the Integer range" in err
    assert len(err) < 200


# ------------------------------------------------------------------ recording any variable
def test_record_any_variable_of_any_instance(built_fmus, gain):
    """Inputs (as set for the step from each point), parameters, calculated parameters,
    Integer and Boolean outputs, array elements; the Real outputs unchanged by them."""
    from dronefly.models import lateral_dynamics

    states = [f"plant.{s}" for s in STATE_NAMES]
    extra = ["plant.delta_Phi_a", "gain.u", "gain.k", "gain.m", "gain.negate", "gain.steps",
             "plant.A[2,1]", "controller.K[1,4]", "controller.saturated"]
    with SystemMaster(_three(built_fmus, gain)) as sm:
        plain = sm.run(H, 40, record=states + ["controller.delta_Phi_a"])
        run = sm.run(H, 40, record=[*states, *extra, "controller.delta_Phi_a"])
    assert run.complete and run.names[len(states):-1] == extra
    assert np.array_equal(run.signals[:, :4], plain.signals[:, :4])
    col = dict(zip(run.names, run.signals.T))
    u = plain.signals[:, 4]
    assert np.array_equal(col["controller.delta_Phi_a"], u)
    assert np.array_equal(col["plant.delta_Phi_a"], u) and np.array_equal(col["gain.u"], u)
    assert np.all(col["gain.k"] == 1.0) and np.all(col["gain.m"] == 1.0)
    assert np.all(col["gain.negate"] == 0.0) and np.all(col["controller.saturated"] == 0.0)
    assert col["gain.steps"].tolist() == list(range(41))
    A, _ = lateral_dynamics.system_matrices(lateral_dynamics.default_parameters())
    assert np.all(col["plant.A[2,1]"] == np.asarray(A)[1, 0]) and np.asarray(A)[1, 0] != 0
    assert np.all(col["controller.K[1,4]"] == PAPER_GAINS_EQ27[3])


def test_default_recording_reads_nothing_more(built_fmus, gain):
    """Recording the Real outputs adds no call to a step (the plan's record ops are empty);
    the default also records the Integer and Boolean outputs, each read with its own call."""
    from dronefly.harness.cosim.plan import build_nodes, record_ops

    with SystemMaster(_three(built_fmus, gain)) as sm:
        kind = {n: sm.fmus[n.split(".")[0]].variables[n.split(".", 1)[1]].type for n in sm.names}
        reals = [n for n in sm.names if kind[n] == "Real"]
        nodes, every_out, where = build_nodes(sm.fmus, sm.system.connections, reals)
        assert record_ops(nodes, every_out) == []
        assert len(every_out) == len({*reals, "controller.delta_alpha_1a"})
        others = [n for n in sm.names if kind[n] != "Real"]
        assert all(kind[n] in ("Integer", "Boolean") for n in others)


@pytest.mark.parametrize("name, fragment", [
    ("g.label", "a String variable"), ("g.nosuch", "g has no variable 'nosuch'"),
    ("nosuch.y", "no instance 'nosuch'"),
])
def test_record_refuses_what_cannot_be_recorded(gain, name, fragment):
    with SystemMaster(System({"g": gain})) as sm, \
            pytest.raises(SystemSpecError, match=re.escape(f"cannot record {name!r}: {fragment}")):
        sm.run(0.1, 2, record=[name])


def test_the_pair_records_more_variables_after_its_own(plant, controller):
    """Loop.run(record=...): the pair's columns unchanged, then the variables asked for."""
    extra = ["plant.delta_Phi_a", "controller.K[1,4]", "controller.saturated", "plant.A[2,1]"]
    loop = Loop(plant, controller)
    ref = loop.run(H, 30, plant_start=_x0(plant))
    run = loop.run(H, 30, plant_start=_x0(plant), record=extra)
    assert run.names == [*ref.names, *extra]
    assert np.array_equal(run.signals[:, :len(ref.names)], ref.signals)
    assert np.array_equal(run.column("plant.delta_Phi_a"), ref.column("delta_Phi_a"))
    assert np.all(run.column("controller.K[1,4]") == PAPER_GAINS_EQ27[3])
    assert np.all(run.column("controller.saturated") == 0.0)


def test_ssp_round_trip_keeps_integer_boolean_and_string_values(gain, tmp_path):
    """Our SSP writer and reader: each SSV value keeps its type, and the system runs."""
    from dronefly.harness.cosim.ssp import write_system_ssp

    values = {"k": 0.25, "m": 3, "negate": True, "label": "g1", "u": 2.0}
    back = System.from_ssp(write_system_ssp(System({"g": gain}, parameters={"g": values}),
                                            tmp_path / "g.ssp"))
    assert back.parameters == {"g": values}
    assert [type(v) for v in back.parameters["g"].values()] == [float, int, bool, str, float]
    with SystemMaster(back) as sm:
        assert sm.run(0.1, 1, record=["g.y"]).signals[:, 0].tolist() == [-1.5, -1.5]


class _CountingSlave:
    """An fmpy slave that counts the FMI set calls made through it (everything else passes)."""

    def __init__(self, slave) -> None:
        self._s, self.sets = slave, 0

    def __getattr__(self, name: str):
        f = getattr(self._s, name)
        if not name.startswith("fmi2Set"):
            return f

        def counted(*args):
            self.sets += 1
            return f(*args)
        return counted


@pytest.mark.parametrize("master", ["gauss-seidel", "jacobi"])
def test_recording_is_a_pure_observer(built_fmus, plant, controller, master):
    """Recorded variables are read with the point's outputs: with the limit binding on some
    rows only, ``saturated`` is 1 exactly in the rows where a recorded control is at u_max
    (under Jacobi the controller answers from the previous inputs for both); the plant's
    recorded inputs are the controller's outputs; the default columns are the same bit for
    bit, and recording sets nothing (no set at the last point)."""
    u_max = 0.1503718
    x0 = np.array([0, 0.5, 0, 0.1]) * scale_vector()
    values = {"plant": {f"{s}_start": float(v) for s, v in zip(STATE_NAMES, x0)},
              "controller": {"limit_enabled": True, "u_max": u_max}}
    extra = ["controller.saturated", *(f"plant.{u}" for u in CONTROL_NAMES)]
    system = System.by_name({"plant": built_fmus["DroneFlyLateral"],
                             "controller": built_fmus["StateFeedback"]})
    with SystemMaster(system, master) as sm, plant.instantiate() as p, \
            controller.instantiate() as c:
        p.slave, c.slave = _CountingSlave(p.slave), _CountingSlave(c.slave)
        runs = []
        for record in (None, [*sm.names, *extra]):
            p.slave.sets = c.slave.sets = 0
            runs.append(sm.run(1 / 164.0, 40, record=record, values=values,
                               instances={"plant": p, "controller": c}))
            runs[-1].sets = (p.slave.sets, c.slave.sets)
    plain, rec = runs
    assert plain.complete and rec.complete and rec.sets == plain.sets
    assert np.array_equal(rec.signals[:, :len(sm.names)], plain.signals)
    col = dict(zip(rec.names, rec.signals.T))
    u = np.array([col[f"controller.{n}"] for n in CONTROL_NAMES]).T
    sat = col["controller.saturated"]
    assert 0 < sat.sum() < len(sat) - 5, "the limit binds on some rows, not on others"
    assert np.array_equal(sat == 1.0, np.any(np.abs(u) >= u_max, axis=1))
    for n in CONTROL_NAMES:
        assert np.array_equal(col[f"plant.{n}"], col[f"controller.{n}"])


def test_ssv_enumeration_items_are_resolved_by_name(gain, tmp_path):
    """An SSV Enumeration given by an item name (SSP allows names or numbers) is kept as
    that name and resolved against the variable's type definition; an unknown name is refused
    naming it and the items (int('left') raised 'not a valid Enumeration')."""
    from types import SimpleNamespace as NS

    from dronefly.harness.cosim.typed_values import typed_value

    ssv = ('<?xml version="1.0" encoding="UTF-8"?><ssv:ParameterSet version="1.0" name="g" '
           'xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues">'
           '<ssv:Parameters><ssv:Parameter name="mode"><ssv:Enumeration value="left"/>'
           '</ssv:Parameter><ssv:Parameter name="gear"><ssv:Enumeration value="-2"/>'
           '</ssv:Parameter></ssv:Parameters></ssv:ParameterSet>')
    ssd = ('<?xml version="1.0" encoding="UTF-8"?><ssd:SystemStructureDescription version="1.0" '
           'name="e" xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription">'
           '<ssd:System name="e"><ssd:Elements><ssd:Component name="g" source="resources/g.fmu" '
           'type="application/x-fmu-sharedlibrary"><ssd:ParameterBindings><ssd:ParameterBinding '
           'source="resources/g.ssv"/></ssd:ParameterBindings></ssd:Component></ssd:Elements>'
           '</ssd:System></ssd:SystemStructureDescription>')
    with zipfile.ZipFile(tmp_path / "e.ssp", "w") as z:
        z.writestr("SystemStructure.ssd", ssd)
        z.write(gain, "resources/g.fmu")
        z.writestr("resources/g.ssv", ssv)
    assert System.from_ssp(tmp_path / "e.ssp").parameters == {"g": {"mode": "left", "gear": -2}}
    v = NS(type="Enumeration", declaredType=NS(items=[NS(name="left", value="1"),
                                                      NS(name="right", value="2")]))
    assert typed_value("g.mode", v, "left") == 1 and typed_value("g.mode", v, "2") == 2
    with pytest.raises(SystemSpecError, match=re.escape(
            "g.mode = 'up' is not an item of the variable's Enumeration (items: left = 1, "
            "right = 2)")):
        typed_value("g.mode", v, "up")


def test_a_large_fmi2_value_reference_is_read_as_fmi2():
    """FMI 2.0 value references may be >= 2**30 (the harness's virtual references of FMI 3.0
    array elements start there): the record reads such a Real local with fmi2GetReal, as the
    FMU's FMI version says (the plan took it for an FMI 3.0 array element and called
    getReal)."""
    from ctypes import c_double
    from types import SimpleNamespace as NS

    from dronefly.harness.cosim.plan import build_nodes, record_ops

    variables = [NS(name="loc", type="Real", causality="local", valueReference=2 ** 30 + 5)]
    fmu = NS(model_description=NS(modelVariables=variables), fmi_version=2, elements={},
             variables={v.name: v for v in variables}, vr=lambda n: 2 ** 30 + 5)
    reads = []

    def get_real(component, vr, n, values):
        reads.append(list(vr))
        values[0] = 4.5

    nodes, every_out, where = build_nodes({"x": fmu}, [], ["x.loc"])
    nodes["x"].inst = NS(slave=NS(component=None, fmi2GetReal=get_real,
                                  getReal=lambda vr: pytest.fail("getReal called")))
    (op,) = record_ops(nodes, every_out)
    op[2](*op[3])
    assert op[1] == "fmi2GetReal" and reads == [[2 ** 30 + 5]]
    assert (c_double * len(every_out)).from_buffer(every_out)[where[0]] == 4.5


def test_sweep_compare_refuses_a_set_value_the_two_systems_read_differently(built_fmus, gain,
                                                                            tmp_path):
    """--system A --compare B --set g.m=3: an Integer 3 in A, a Real 3.0 in B; one value per
    case serves both systems, so it must mean the same in both (B's typed value silently
    replaced A's)."""
    from pythonfmu import FmuBuilder

    from dronefly.harness.sweep.cases import SweepInputError
    from dronefly.harness.sweep.run import run_sweep
    from dronefly.harness.cosim.ssp import write_system_ssp

    d = tmp_path / "real_m"
    d.mkdir()
    (d / "RealM.py").write_text(GAIN.replace('Integer("m"', 'Real("m"').replace(
        "class Gain(", "class RealM("))  # another model identifier: no clash of libraries
    real_m = Path(FmuBuilder.build_FMU(d / "RealM.py", dest=d))
    pair = {"plant": built_fmus["DroneFlyLateral"], "controller": built_fmus["StateFeedback"]}
    a, b = (write_system_ssp(System.by_name({**pair, "g": g}), tmp_path / f"{tag}.ssp")
            for tag, g in (("a", gain), ("b", real_m)))
    out = tmp_path / "o"
    with pytest.raises(SweepInputError, match=re.escape(
            f"--set g.m='3' is 3 in {a} but 3.0 in {b}")):
        run_sweep(None, out, workers=1, progress_bar=False, plot=False, system=a, compare=b,
                  set_values={"g.m": "3"}, cases=[])  # refused before "the sweep has no cases"
    assert not out.exists()
