"""The system master: any number of FMUs from Python or SSP, ordered by ModelStructure.

Oracles: the pair master of harness.cosim (bit for bit), the SSP and the Python description
of one system (same trajectory to 1e-12), an algebraic loop refused with its cycle named.
"""

from __future__ import annotations

import math
import textwrap
import zipfile
from pathlib import Path

import numpy as np
import pytest

from dronefly.harness.cosim.master import Loop
from dronefly.harness.system.description import Connection, System, SystemSpecError
from dronefly.harness.system.master import SystemMaster
from dronefly.controller.law import PAPER_GAINS_EQ27
from dronefly.lateral import CONTROL_NAMES, STATE_NAMES, scale_vector

pytestmark = pytest.mark.integration

H = 0.1 / 164.0  # s: 0.1 wing beat
GAIN = textwrap.dedent('''
    from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real


    class Gain(Fmi2Slave):
        """y = k u, direct feedthrough (pythonfmu declares no dependencies: all)."""

        def __init__(self, **kwargs):
            super().__init__(**kwargs)
            self.u, self.k = 0.0, 1.0
            self.register_variable(Real("u", causality=Fmi2Causality.input,
                                        variability=Fmi2Variability.continuous))
            self.register_variable(Real("k", causality=Fmi2Causality.parameter,
                                        variability=Fmi2Variability.tunable))
            self.register_variable(Real("y", causality=Fmi2Causality.output,
                                        variability=Fmi2Variability.continuous,
                                        getter=lambda: self.k * self.u))

        def do_step(self, t, h):
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


@pytest.mark.parametrize("master", ["gauss-seidel", "jacobi"])
def test_pair_equals_the_pair_master_bit_for_bit(built_fmus, plant, controller, master):
    paths = {"plant": built_fmus["DroneFlyLateral"], "controller": built_fmus["StateFeedback"]}
    system = System.by_name(paths, parameters={"plant": _x0(plant)})
    with SystemMaster(system, master) as sm:
        names = [f"plant.{s}" for s in STATE_NAMES] + [f"controller.{c}" for c in CONTROL_NAMES]
        got = sm.run(H, 200, record=names)
    ref = Loop(plant, controller).run(H, 200, master=master, plant_start=_x0(plant))
    assert got.complete and ref.complete
    assert np.array_equal(got.signals, ref.signals)


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


def _write_ssp(system: System, path: Path) -> Path:
    """A hand-written SSP (SSD + one SSV per instance) of a system: a foreign writer."""
    comps, ssvs = [], {}
    for inst, fmu in system.fmus.items():
        comps.append(f'<ssd:Component name="{inst}" source="resources/{fmu.name}" '
                     f'type="application/x-fmu-sharedlibrary"><ssd:ParameterBindings>'
                     f'<ssd:ParameterBinding source="resources/{inst}.ssv"/>'
                     f'</ssd:ParameterBindings></ssd:Component>')
        params = "".join(f'<ssv:Parameter name="{k}"><ssv:Real value="{v!r}"/></ssv:Parameter>'
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


def test_algebraic_loop_is_refused_with_its_cycle_and_runs_under_jacobi(gain):
    system = System({"g1": gain, "g2": gain},
                    [Connection("g1", "y", "g2", "u"), Connection("g2", "y", "g1", "u")],
                    {"g1": {"k": 0.5}, "g2": {"k": 0.5}})
    with pytest.raises(SystemSpecError, match=r"algebraic loop .*g1\.y -> g2\.u -> g2\.y -> g1\.u"):
        SystemMaster(system)
    with SystemMaster(system, "jacobi") as sm:
        run = sm.run(0.1, 5)
    assert run.complete and np.all(run.signals == 0.0)


@pytest.mark.parametrize("cons,fragment", [
    ([Connection("plant", "delta_v", "controller", "delta_p")], r"units differ \(m/s -> rad/s\)"),
    ([Connection("plant", "delta_q", "controller", "delta_p")], "has no variable 'delta_q'"),
    ([Connection("controller", "delta_v", "plant", "delta_Phi_a")], "is a input, not an output"),
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
    system = _three(built_fmus, gain).with_values({"gain.k": math.inf})
    with SystemMaster(system) as sm:
        run = sm.run(H, 50, record=["plant.delta_gamma"])
    assert not run.complete and run.failure.fmu == "plant" and run.failure.call == "fmi2DoStep"
    assert len(run.time) >= 1
