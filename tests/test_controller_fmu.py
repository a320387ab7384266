"""The built StateFeedback FMU through fmpy: interface, feedthrough, saturation, closed loop,
bad input, state; and with the plant FMU."""

from __future__ import annotations

import math
from typing import Any
from xml.etree import ElementTree as ET

import numpy as np
import pytest
from numpy.testing import assert_allclose

from dronefly.models import feedback as L
from dronefly.models import lateral_dynamics
from dronefly.models import lateral_interface

from controller_common import (B1_COL1_EQ24, CONTROLS, EIG_EQ27, GAINS, H, STATES, dimensional,
                               expected_controls, random_gains)
from fmu_helpers import model_description, set_values, start


def _outputs(inst: Any) -> tuple[list[float], bool]:
    u = inst.slave.getReal(inst.vrs(CONTROLS))
    (sat,) = inst.slave.getBoolean([inst.fmu.vr("saturated")])
    return u, bool(sat)


def _discarded(inst: Any, t: float, h: float) -> str:
    from fmpy.fmi1 import FMICallException

    with pytest.raises(FMICallException) as e:
        inst.slave.doStep(currentCommunicationPoint=t, communicationStepSize=h)
    assert e.value.status == 2, "fmi2Discard"
    return inst.messages[-1].message


@pytest.mark.integration
def test_fmpy_validate_reports_no_problems(built_fmus):
    from fmpy.validation import validate_fmu

    assert validate_fmu(str(built_fmus["StateFeedback"])) == []


@pytest.mark.integration
def test_reproducible_build_and_own_package(tmp_path, built_fmus):
    from dronefly.harness.builder.build import build_fmu, fmu_sources

    again = build_fmu("StateFeedback", tmp_path)
    assert again.read_bytes() == built_fmus["StateFeedback"].read_bytes()
    pkg_c, files_c = fmu_sources("StateFeedback")
    pkg_p, _ = fmu_sources("DroneFlyLateral")
    assert pkg_c != pkg_p and pkg_c.startswith("dronefly_statefeedback_")
    assert files_c["resources/slavemodule.txt"].decode() == f"{pkg_c}_slave"
    shipped = {k for k in files_c if k.startswith(f"resources/{pkg_c}/") and k.endswith(".py")
               and not k.endswith("__init__.py")}
    assert shipped == {f"resources/{pkg_c}/{r}" for r in
                       ("core/errors.py", "fmi/base.py", "fmi/calls.py", "fmi/host.py",
                        "fmi/state.py", "fmi/access.py", "fmi/vars.py", "models/axes.py",
                        "models/lateral_interface.py", "models/longitudinal_interface.py",
                        "models/feedback.py", "controller/delay.py", "controller/timing.py",
                        "controller/variables.py",
                        "controller/slave.py")}


@pytest.mark.integration
def test_model_description_interface(built_fmus):
    root = model_description(built_fmus["StateFeedback"])
    units = {u.get("name"): u for u in root.find("UnitDefinitions")}
    svs = root.find("ModelVariables").findall("ScalarVariable")
    idx = {sv.get("name"): i + 1 for i, sv in enumerate(svs)}
    by_name = {sv.get("name"): sv for sv in svs}
    for sv in svs:
        assert sv.get("description"), sv.get("name")
        real = sv.find("Real")
        if real is not None:
            assert real.get("unit") in units, sv.get("name")
    assert [n for n in idx if n.startswith("K[")] == GAINS
    assert {n: by_name[n].find("Real").get("unit") for n in ("n", "U", "u_max")} == {
        "n": "Hz", "U": "m/s", "u_max": "rad"}
    sat, lim = by_name["saturated"], by_name["limit_enabled"]
    assert (sat.get("causality"), sat.get("variability"), sat.get("initial")) == (
        "output", "discrete", "calculated")
    assert sat.find("Boolean") is not None and sat.find("Boolean").get("start") is None
    assert (lim.get("causality"), lim.get("variability"), lim.find("Boolean").get("start")) == (
        "parameter", "tunable", "false")
    assert float(by_name["u_max"].find("Real").get("start")) == 0.4
    for name in GAINS + ["n", "U", "u_max"]:
        assert by_name[name].get("variability") == "tunable"
    inputs = " ".join(str(idx[n]) for n in STATES)
    outs = root.find("ModelStructure/Outputs")
    assert [(int(u.get("index")), u.get("dependencies")) for u in outs] == [
        (idx[n], inputs) for n in CONTROLS + ["saturated"]]
    init = {int(u.get("index")): set(map(int, u.get("dependencies").split()))
            for u in root.find("ModelStructure/InitialUnknowns")}
    common = {idx[n] for n in STATES + ["n", "U", "limit_enabled", "u_max", "sensing_delay"]}
    for i, name in enumerate(CONTROLS):
        assert init[idx[name]] == common | {idx[L.gain_name(i, j)] for j in range(4)}
    assert init[idx["saturated"]] == common | {idx[g] for g in GAINS}
    assert "nan" not in ET.tostring(root, encoding="unicode").lower()


@pytest.mark.integration
def test_plant_and_controller_connect_by_name_and_the_plant_breaks_the_loop(built_fmus):
    """Controller inputs = plant outputs and vice versa (names, units); only the controller
    has direct feedthrough, so plant -> controller -> plant is not an algebraic loop."""
    def interface(path, causality):
        root = model_description(path)
        svs = root.find("ModelVariables").findall("ScalarVariable")
        deps = {int(u.get("index")): u.get("dependencies")
                for u in root.find("ModelStructure/Outputs")}
        return {sv.get("name"): (sv.find("Real").get("unit"), deps.get(i + 1))
                for i, sv in enumerate(svs)
                if sv.get("causality") == causality and sv.find("Real") is not None}

    plant_out = interface(built_fmus["DroneFlyLateral"], "output")
    ctrl_in = interface(built_fmus["StateFeedback"], "input")
    assert {n: u for n, (u, _) in plant_out.items()} == {n: u for n, (u, _) in ctrl_in.items()}
    assert all(d == "" for _, d in plant_out.values()), "plant outputs: no feedthrough"
    ctrl_out = interface(built_fmus["StateFeedback"], "output")
    plant_in = interface(built_fmus["DroneFlyLateral"], "input")
    assert {n: u for n, (u, _) in ctrl_out.items()} == {n: u for n, (u, _) in plant_in.items()}
    assert all(d for _, d in ctrl_out.values()), "controller outputs: direct feedthrough"


@pytest.mark.integration
@pytest.mark.parametrize("gains", ["eq27", "random"])
@pytest.mark.parametrize("mode", ["initialization", "stepping"])
def test_outputs_follow_inputs_without_do_step(controller, gains, mode):
    K = np.array(L.default_gains()) if gains == "eq27" else random_gains()
    rng = np.random.default_rng(11)
    with controller.instantiate() as inst:
        s = inst.slave
        s.setupExperiment(startTime=0.0)
        s.enterInitializationMode()
        if gains == "random":
            s.setReal(inst.vrs(GAINS), K.ravel().tolist())
        if mode == "stepping":
            s.exitInitializationMode()
        for xp in rng.normal(0.0, 0.2, (5, 4)):
            x = dimensional(xp)
            s.setReal(inst.vrs(STATES), x)
            u, sat = _outputs(inst)
            assert_allclose(u, K @ xp, rtol=1e-12, atol=1e-300, err_msg="u = K x+")
            assert sat is False
        assert not [m for m in inst.messages if m.status > 0]


@pytest.mark.integration
def test_saturation_through_fmpy(controller):
    K = random_gains(5)
    u_max = 0.3
    with controller.instantiate() as inst:
        start(inst, {"limit_enabled": True, "u_max": u_max})
        inst.slave.setReal(inst.vrs(GAINS), K.ravel().tolist())
        seen = set()
        for k, xp in enumerate(np.random.default_rng(2).normal(0.0, 0.15, (40, 4))):
            x = dimensional(xp)
            inst.slave.setReal(inst.vrs(STATES), x)
            u, sat = _outputs(inst)
            ref, ref_sat = expected_controls(K, x, u_max=u_max)
            assert_allclose(u, ref, rtol=1e-12, atol=1e-300)
            assert max(abs(v) for v in u) <= u_max
            assert sat is ref_sat
            seen.add(sat)
            inst.slave.doStep(currentCommunicationPoint=k * H, communicationStepSize=H)
        assert seen == {True, False}, "both regimes exercised"
        inst.slave.setBoolean([inst.fmu.vr("limit_enabled")], [False])  # tunable: off again
        u, sat = _outputs(inst)
        assert_allclose(u, expected_controls(K, x)[0], rtol=1e-12)
        assert sat is False


@pytest.mark.integration
def test_closed_loop_eigenvalues_from_the_two_fmus(plant, controller):
    """A1 + B1 K, all read through fmpy, has the eigenvalues of Sect. 3.4."""
    import scipy.linalg as sl

    with plant.instantiate() as p, controller.instantiate() as c:
        start(p)
        start(c)
        A = np.array(p.slave.getReal(p.vrs([f"A[{i},{j}]" for i in range(1, 5)
                                             for j in range(1, 5)]))).reshape(4, 4)
        B = np.array(p.slave.getReal(p.vrs([f"B[{i},{j}]" for i in range(1, 5)
                                             for j in range(1, 4)]))).reshape(4, 3)
        K = np.array(c.slave.getReal(c.vrs(GAINS))).reshape(3, 4)
    ev, left, right = sl.eig(A + B @ K, left=True, right=True)
    order = np.lexsort((-ev.imag, -ev.real))
    ev = ev[order]
    assert_allclose(ev, EIG_EQ27, rtol=0, atol=5e-4, err_msg="printed to 3 decimals")
    # The zero eigenvalue: first-order bound of the rounding of Eq. (27) (half a unit of the
    # 4th decimal in each k) plus the difference between the plant's B1 column (from Table 1
    # and the printed inertias) and Eq. (24) as printed, which the paper used to solve for k.
    i = order[0]
    w, v = left[:, i].conj(), right[:, i]
    s = w @ v
    k = K[0]
    bound = (np.abs((w @ B[:, 0]) * v / s).sum() * 0.5e-4
             + np.abs(w * (k @ v) / s) @ np.abs(B[:, 0] - np.array(B1_COL1_EQ24)))
    residual = abs(ev[0])
    print(f"closed-loop eigenvalues per wing beat: {ev}; |lambda1| = {residual:.3e} "
          f"(first-order rounding bound {bound:.3e})")
    assert residual <= bound
    assert residual < 1e-4


BAD_CASES = [
    # (values set after a first valid step, fragment expected in the logged messages)
    ({"delta_v": math.nan}, "delta_v = nan"),
    ({"delta_p": math.inf}, "delta_p = inf"),
    ({"delta_r": -math.inf}, "delta_r = -inf"),
    ({"delta_gamma": math.nan}, "delta_gamma = nan"),
    ({"K[1,1]": math.nan}, "K[1,1] = nan"),
    ({"K[3,4]": math.inf}, "K[3,4] = inf"),
    ({"n": 0.0}, "n = 0.0"),
    ({"n": -164.0}, "n = -164.0"),
    ({"n": math.nan}, "n = nan"),
    ({"U": 0.0}, "U = 0.0"),
    ({"U": -3.0}, "U = -3.0"),
    ({"U": math.inf}, "U = inf"),
    ({"u_max": 0.0}, "u_max = 0.0"),
    ({"u_max": -0.1}, "u_max = -0.1"),
    ({"u_max": math.nan, "limit_enabled": True}, "u_max = nan"),
]


@pytest.mark.integration
@pytest.mark.parametrize("bad, fragment", BAD_CASES, ids=[c[1] for c in BAD_CASES])
def test_bad_values_are_refused_and_the_instance_recovers(controller, bad, fragment):
    x = dimensional([0.02, -0.03, 0.01, 0.3])
    with controller.instantiate() as inst:
        start(inst, dict(zip(STATES, x)))
        inst.slave.doStep(currentCommunicationPoint=0.0, communicationStepSize=H)
        before = _outputs(inst)
        good = {n: (inst.slave.getBoolean([controller.vr(n)])[0] == 1 if n == "limit_enabled"
                    else inst.slave.getReal([controller.vr(n)])[0]) for n in bad}
        set_values(inst, bad)
        assert _outputs(inst) == before, "outputs keep their last valid values"
        errors = [m for m in inst.messages if m.status == 3]
        assert errors and fragment in errors[-1].message, inst.messages
        assert "last valid values" in errors[-1].message
        msg = _discarded(inst, H, H)
        assert fragment in msg and "step refused" in msg, msg
        set_values(inst, good)
        inst.slave.doStep(currentCommunicationPoint=H, communicationStepSize=H)  # usable again
        u, sat = _outputs(inst)
        assert_allclose(u, expected_controls(np.array(L.default_gains()), x)[0], rtol=1e-12)


@pytest.mark.integration
def test_bad_value_in_initialization_mode(controller):
    with controller.instantiate() as inst:
        start(inst, {"U": -1.0})
        assert "U = -1.0" in inst.messages[-1].message and inst.messages[-1].status == 3
        assert "U = -1.0" in _discarded(inst, 0.0, H)
        set_values(inst, {"U": lateral_interface.U_M_PER_S, "delta_v": 0.1})
        inst.slave.doStep(currentCommunicationPoint=0.0, communicationStepSize=H)
        assert_allclose(_outputs(inst)[0][0], L.PAPER_GAINS_EQ27[0] * 0.1 / lateral_interface.U_M_PER_S, rtol=1e-12)


@pytest.mark.integration
@pytest.mark.parametrize("setter, name, value, fragment", [
    ("setReal", "limit_enabled", 1.0, "limit_enabled = 1.0 rejected: is a Boolean variable"),
    ("setBoolean", "u_max", True, "u_max = True rejected: is a Real variable"),
    ("setReal", "delta_Phi_a", 0.1, "delta_Phi_a = 0.1 rejected: not settable"),
])
def test_wrong_type_or_causality_is_rejected(controller, setter, name, value, fragment):
    with controller.instantiate() as inst:
        start(inst)
        getattr(inst.slave, setter)([controller.vr(name)], [value])
        assert fragment in inst.messages[-1].message, inst.messages
        assert fragment in _discarded(inst, 0.0, H)
        inst.slave.doStep(currentCommunicationPoint=0.0, communicationStepSize=H)  # reported once
        assert inst.slave.getReal([controller.vr("u_max")]) == [0.4]


@pytest.mark.integration
@pytest.mark.parametrize("t, h, fragment", [
    (0.0, 0.0, "communicationStepSize = 0.0"),
    (0.0, -H, "communicationStepSize = -"),
    (0.0, math.inf, "communicationStepSize = inf"),
    (0.5, H, "currentCommunicationPoint = 0.5"),
])
def test_bad_step_arguments_refused(controller, t, h, fragment):
    with controller.instantiate() as inst:
        start(inst)
        assert fragment in _discarded(inst, t, h)
        inst.slave.doStep(currentCommunicationPoint=0.0, communicationStepSize=H)
        assert "does not continue" in _discarded(inst, 0.0, H)  # time now continues from H
        inst.slave.doStep(currentCommunicationPoint=H, communicationStepSize=H)


@pytest.mark.integration
def test_state_get_set_serialize_and_reset(controller):
    with controller.instantiate() as inst:
        s = inst.slave
        start(inst, {"limit_enabled": True, "u_max": 0.01})
        s.setReal(inst.vrs(STATES), dimensional([0.1, 0.0, 0.0, 0.2]))
        s.doStep(currentCommunicationPoint=0.0, communicationStepSize=H)
        saved = _outputs(inst)
        assert saved[1] is True
        state = s.getFMUstate()
        blob = s.serializeFMUstate(state)
        s.setReal(inst.vrs(STATES + ["K[1,1]"]), [0.0, 0.0, 0.0, 0.0, 5.0])
        s.setBoolean([controller.vr("limit_enabled")], [False])
        s.doStep(currentCommunicationPoint=H, communicationStepSize=H)
        assert _outputs(inst) == ([0.0, 0.0, 0.0], False)
        s.setFMUstate(state)
        assert _outputs(inst) == saved
        s.doStep(currentCommunicationPoint=H, communicationStepSize=H)  # time restored to H
        restored = s.deSerializeFMUstate(blob)
        s.setReal([controller.vr("delta_v")], [0.0])
        s.setFMUstate(restored)
        assert _outputs(inst) == saved
        s.freeFMUstate(restored)
        s.freeFMUstate(state)
        s.reset()
        assert s.getReal([controller.vr("K[1,1]")]) == [L.PAPER_GAINS_EQ27[0]]
        start(inst)
        assert _outputs(inst) == ([0.0, 0.0, 0.0], False)


@pytest.mark.integration
def test_closed_loop_cosimulation_with_the_plant(plant, controller):
    """Both FMUs in one process, connected by name: plant outputs at t_k -> controller ->
    plant inputs held over [t_k, t_k + h]. Equals x[k+1] = (Phi + Gamma K) x[k] exactly."""
    steps, h = 50, 1.0 / lateral_interface.N_HZ  # one wing beat per communication step
    x0 = [0.0, 0.0, 0.0, 0.1]
    with plant.instantiate("p") as p, controller.instantiate("c") as c:
        start(p, {f"{n}_start": v for n, v in zip(STATES, x0)})
        start(c)
        xs = []
        for k in range(steps):
            y = p.slave.getReal(p.vrs(STATES))
            xs.append(lateral_interface.to_nondimensional(np.array(y), lateral_interface.U_M_PER_S, lateral_interface.N_HZ))
            c.slave.setReal(c.vrs(STATES), y)
            u = c.slave.getReal(c.vrs(CONTROLS))
            p.slave.setReal(p.vrs(CONTROLS), u)
            p.slave.doStep(currentCommunicationPoint=k * h, communicationStepSize=h)
            c.slave.doStep(currentCommunicationPoint=k * h, communicationStepSize=h)
    A, B = lateral_dynamics.system_matrices(lateral_dynamics.default_parameters())
    # the exact one-wing-beat transition by the eigendecomposition of A1 (independent of the
    # FMU's matrix exponential): Phi = V e^(Lambda) V^-1, Gamma = V (e^Lambda - 1)/Lambda V^-1 B
    lam, V = np.linalg.eig(A)
    Vi = np.linalg.inv(V)
    Phi = np.real((V * np.exp(lam)) @ Vi)
    Gamma = np.real((V * ((np.exp(lam) - 1.0) / lam)) @ Vi @ B)
    F = Phi + Gamma @ np.array(L.default_gains())
    ref = [np.array(x0)]
    for _ in range(steps - 1):
        ref.append(F @ ref[-1])
    assert_allclose(np.array(xs), np.array(ref), rtol=0, atol=1e-13)
    assert abs(xs[-1][3]) < 0.1 * 1.01, "neutrally stable: no divergence"
