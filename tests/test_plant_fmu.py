"""Integration tests: the real DroneFlyLateral FMU, built into a temporary folder, run by fmpy."""

from __future__ import annotations

import math
import zipfile

import numpy as np
import pytest
from numpy.testing import assert_allclose

from dronefly.harness.paper import printed as pv
from dronefly.models import lateral_dynamics
from dronefly.models import lateral_interface
from dronefly.harness.stability.simulate import exact_open_loop
from dronefly.harness.cosim.fmu import FMU
from fmu_helpers import model_description, start

pytestmark = pytest.mark.integration

STATES = list(lateral_interface.STATE_NAMES)
CONTROLS = list(lateral_interface.CONTROL_NAMES)
DT_WB = 1.0 / lateral_interface.N_HZ  # one wing beat in s


def _outputs(inst):
    return np.array(inst.slave.getReal(inst.vrs(STATES)))


def test_fmpy_validate_reports_no_problems(built_fmus):
    from fmpy.validation import validate_fmu

    assert validate_fmu(str(built_fmus["DroneFlyLateral"])) == []


def test_reproducible_build(tmp_path, built_fmus):
    from dronefly.harness.builder.build import build_fmu

    again = build_fmu("DroneFlyLateral", tmp_path)
    first = built_fmus["DroneFlyLateral"]
    assert model_description(again).get("guid") == model_description(first).get("guid")
    with zipfile.ZipFile(first) as a, zipfile.ZipFile(again) as b:
        assert a.read("modelDescription.xml") == b.read("modelDescription.xml")
    assert again.read_bytes() == first.read_bytes()


def test_model_description_interface(built_fmus):
    root = model_description(built_fmus["DroneFlyLateral"])
    units = {u.get("name"): u for u in root.find("UnitDefinitions")}
    svs = root.find("ModelVariables").findall("ScalarVariable")
    by_name = {sv.get("name"): (i + 1, sv) for i, sv in enumerate(svs)}
    for sv in svs:
        assert sv.get("description"), sv.get("name")
        real = sv.find("Real")
        assert real.get("unit") in units, sv.get("name")
        if real.get("unit") in ("rad", "rad/s"):
            assert real.get("displayUnit") in ("deg", "deg/s"), sv.get("name")
        if sv.get("causality") == "parameter":
            assert sv.get("variability") in ("fixed", "tunable")
    assert_allclose(float(units["rad"].find("DisplayUnit").get("factor")), 180 / math.pi, rtol=1e-15)
    assert units["m/s"].find("BaseUnit").attrib == {"m": "1", "s": "-1"}
    outputs = root.find("ModelStructure/Outputs")
    assert [int(u.get("index")) for u in outputs] == [by_name[n][0] for n in STATES]
    assert all(u.get("dependencies") == "" for u in outputs), "no direct feedthrough"
    initial = [int(u.get("index")) for u in root.find("ModelStructure/InitialUnknowns")]
    expected = sorted(i for i, sv in by_name.values()
                      if sv.get("causality") in ("output", "calculatedParameter"))
    assert initial == expected
    cs = root.find("CoSimulation").attrib
    assert cs["canGetAndSetFMUstate"] == cs["canSerializeFMUstate"] == "true"
    assert cs["needsExecutionTool"] == "true"


@pytest.mark.parametrize("step_wb", [0.01, 0.1, 1.0])
def test_simulate_fmu_matches_exact_solution(built_fmus, step_wb):
    """Non-zero initial state, constant input: ZOH stepping equals the linear ODE's solution."""
    import fmpy

    x0 = {"delta_v_start": 0.05, "delta_p_start": 1.5, "delta_r_start": -0.8,
          "delta_gamma_start": 0.1}
    u = {"delta_Phi_a": 0.02, "delta_alpha_1a": -0.01, "delta_alpha_2a": 0.005}
    stop = 20 * DT_WB
    res = fmpy.simulate_fmu(str(built_fmus["DroneFlyLateral"]), stop_time=stop,
                            output_interval=step_wb * DT_WB, start_values={**x0, **u},
                            output=STATES)
    x = np.column_stack([res[n] for n in STATES])
    ref = exact_open_loop(np.array(list(x0.values())), res["time"], np.array(list(u.values())))
    assert len(res) == round(20 / step_wb) + 1
    peak = np.abs(ref).max(axis=0)  # relative to each signal's magnitude (zero crossings)
    assert_allclose(x / peak, ref / peak, rtol=1e-9, atol=1e-9,
                    err_msg=f"step {step_wb} wing beats vs exact solution")


def test_matrices_read_through_fmpy(plant):
    with plant.instantiate() as inst:
        start(inst)
        A = np.array(inst.slave.getReal(inst.vrs([f"A[{i},{j}]" for i in range(1, 5)
                                                   for j in range(1, 5)]))).reshape(4, 4)
        B = np.array(inst.slave.getReal(inst.vrs([f"B[{i},{j}]" for i in range(1, 5)
                                                   for j in range(1, 4)]))).reshape(4, 3)
    assert_allclose(A, np.array(lateral_dynamics.A1_EQ12), atol=5e-5, rtol=0, err_msg="Eq. (12), 4 decimals")
    ev = np.linalg.eigvals(A)
    ev = ev[np.lexsort((-ev.imag, -ev.real))]
    assert_allclose(ev, pv.table2_eigenvalues(), atol=5e-4,
                    err_msg="Table 2")
    # Eq. (24): within 6e-4 (the rounding of the printed inertias; see test_model)
    assert_allclose(B[:, 0], [float(t) for t in pv.EQ24_B_COLUMN], atol=6e-4, rtol=0)


def _step(inst, t, h):
    inst.slave.doStep(currentCommunicationPoint=t, communicationStepSize=h)


def _discarded(inst, t, h):
    from fmpy.fmi1 import FMICallException

    with pytest.raises(FMICallException) as e:
        _step(inst, t, h)
    assert e.value.status == 2, "fmi2Discard"
    return inst.messages[-1].message


BAD_CASES = [
    # (what is set after initialization, fragment expected in the logged message)
    ({"delta_Phi_a": math.nan}, "delta_Phi_a = nan"),
    ({"delta_alpha_2a": math.inf}, "delta_alpha_2a = inf"),
    ({"Lp_plus": math.nan}, "Lp_plus = nan"),
    ({"m_plus": 0.0}, "m_plus = 0.0"),
    ({"m_plus": -92.7}, "m_plus = -92.7"),
    ({"Ixz_plus": 12.0}, "Ixz_plus = 12.0"),
    ({"n": 0.0}, "n = 0.0"),
    ({"n": -164.0}, "n = -164.0"),
    ({"U": 0.0}, "U = 0.0"),
    ({"U": math.inf}, "U = inf"),
    ({"delta_gamma_start": 0.2}, "delta_gamma_start = 0.2 rejected"),  # fixed after init
]


@pytest.mark.parametrize("bad, fragment", BAD_CASES, ids=[f[1] for f in BAD_CASES])
def test_bad_values_refuse_the_step(plant, bad, fragment):
    h = 0.1 * DT_WB
    with plant.instantiate() as inst:
        start(inst, {"delta_gamma_start": 0.1})
        _step(inst, 0.0, h)
        before = _outputs(inst)
        good = {n: inst.slave.getReal([plant.vr(n)])[0] for n in bad}
        for n, v in bad.items():
            inst.slave.setReal([plant.vr(n)], [v])
        msg = _discarded(inst, h, h)
        assert fragment in msg, msg
        assert_allclose(_outputs(inst), before, rtol=0, atol=0, err_msg="state unchanged")
        for n, v in good.items():
            if n != "delta_gamma_start":
                inst.slave.setReal([plant.vr(n)], [v])
        _step(inst, h, h)  # valid again: the step works and continues from h
        assert not np.allclose(_outputs(inst), before)


@pytest.mark.parametrize("t, h, fragment", [
    (0.0, 0.0, "communicationStepSize = 0.0"),
    (0.0, -0.001, "communicationStepSize = -0.001"),
    (0.0, math.nan, "communicationStepSize = nan"),
    (0.5, 0.001, "currentCommunicationPoint = 0.5"),
])
def test_bad_step_arguments_refused(plant, t, h, fragment):
    with plant.instantiate() as inst:
        start(inst, {"delta_gamma_start": 0.1})
        msg = _discarded(inst, t, h)
        assert fragment in msg, msg
        _step(inst, 0.0, 0.001)
        assert _outputs(inst)[3] != 0.1


def test_reset_restores_fresh_instance(plant):
    h = DT_WB
    with plant.instantiate() as inst:
        start(inst, {"delta_gamma_start": 0.1})
        _step(inst, 0.0, h)
        first = _outputs(inst)
        inst.slave.setReal([plant.vr("m_plus")], [-1.0])
        _discarded(inst, h, h)
        inst.slave.reset()
        assert inst.slave.getReal([plant.vr("m_plus")]) == [92.7]
        start(inst, {"delta_gamma_start": 0.1})
        _step(inst, 0.0, h)
        assert_allclose(_outputs(inst), first, rtol=0, atol=0)


def test_two_instances_are_independent(plant):
    h = DT_WB
    with plant.instantiate("a") as a, plant.instantiate("b") as b:
        start(a, {"delta_gamma_start": 0.1})
        start(b, {"delta_gamma_start": 0.2})
        b.slave.setReal([plant.vr("m_plus")], [-1.0])
        _step(a, 0.0, h)
        _discarded(b, 0.0, h)
        assert_allclose(_outputs(a)[3], exact_open_loop(np.array([0, 0, 0, 0.1]),
                                                        np.array([h]))[0][3], rtol=1e-12)


def test_state_get_set_and_serialize_continue_bit_for_bit(plant):
    h = 0.1 * DT_WB
    with plant.instantiate() as inst:
        s = inst.slave
        start(inst, {"delta_gamma_start": 0.1, "delta_Phi_a": 0.01})
        for k in range(5):
            _step(inst, k * h, h)
        state = s.getFMUstate()
        blob = s.serializeFMUstate(state)
        _step(inst, 5 * h, h)
        _step(inst, 6 * h, h)
        reference = _outputs(inst)
        s.setFMUstate(state)  # rewinds time to 5 h
        _step(inst, 5 * h, h)
        _step(inst, 6 * h, h)
        assert np.array_equal(_outputs(inst), reference)
        restored = s.deSerializeFMUstate(blob)
        s.setFMUstate(restored)
        _step(inst, 5 * h, h)
        _step(inst, 6 * h, h)
        assert np.array_equal(_outputs(inst), reference)
        s.freeFMUstate(restored)
        s.freeFMUstate(state)


def test_fmu_runs_the_code_it_ships(built_fmus, monkeypatch):
    """A host that imported (and changed) the project's model module does not affect the FMU."""
    expected = [lateral_dynamics.A1_EQ12[1][0], lateral_interface.N_HZ]  # the printed A1(2,1) and n, unchanged
    monkeypatch.setattr(lateral_dynamics, "A1_EQ12", tuple(tuple(2 * a for a in row) for row in lateral_dynamics.A1_EQ12))
    monkeypatch.setattr(lateral_interface, "N_HZ", 1.0)
    with FMU(built_fmus["DroneFlyLateral"]) as fmu, fmu.instantiate() as inst:
        start(inst)
        assert inst.slave.getReal([fmu.vr("A[2,1]"), fmu.vr("n")]) == expected


def test_module_names_are_content_addressed(tmp_path, monkeypatch, built_fmus):
    """Two versions of the plant in one process each run their own code."""
    import dronefly.harness.builder.build as build

    pkg, _ = build.fmu_sources("DroneFlyLateral")
    original = build._source_path

    def patched(rel):
        path = original(rel)
        if rel == "models/lateral_dynamics.py":
            text = path.read_text().replace('"L_Phi_a_plus": 2.236', '"L_Phi_a_plus": 4.472')
            path = tmp_path / "model.py"
            path.write_text(text)
        return path

    monkeypatch.setattr(build, "_source_path", patched)
    other = build.build_fmu("DroneFlyLateral", tmp_path / "v2")
    pkg2, _ = build.fmu_sources("DroneFlyLateral")
    assert pkg2 != pkg and model_description(other).get("guid") != model_description(built_fmus["DroneFlyLateral"]).get("guid")
    values = []
    with FMU(built_fmus["DroneFlyLateral"]) as f1, FMU(other) as f2:
        with f1.instantiate() as a, f2.instantiate() as b:
            for inst in (a, b):
                start(inst)
                values.append(inst.slave.getReal([inst.fmu.vr("B[2,1]")])[0])
    expected = [lateral_dynamics.system_matrices(lateral_dynamics.default_parameters().with_values(L_Phi_a_plus=L))[1][1, 0]
                for L in (2.236, 4.472)]
    assert_allclose(values, expected, rtol=1e-15, err_msg="each FMU runs its own model.py")
