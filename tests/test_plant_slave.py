"""Fast unit tests of the DroneFlyLateral slave class, called directly (no FMU, no fmpy)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from dronefly.fmi import UNITS
from dronefly.models import lateral_dynamics
from dronefly.models import lateral_interface
from dronefly.fmu_src.lateral.slave import DroneFlyLateral


@pytest.fixture
def slave() -> DroneFlyLateral:
    s = DroneFlyLateral(instance_name="unit")
    s.setup_experiment(0.0)
    s.enter_initialization_mode()
    return s


def _get(s: DroneFlyLateral, *names: str) -> list[float]:
    return s.get_real([s._vr[n] for n in names])


def _set(s: DroneFlyLateral, **values: float) -> None:
    s.set_real([s._vr[n] for n in values], list(values.values()))


def test_every_variable_is_described_with_a_declared_unit():
    for v in DroneFlyLateral.VARIABLES:
        assert v.description and v.unit in UNITS, v.name
        if v.display_unit is not None:
            assert v.display_unit in UNITS[v.unit][1], v.name


def test_declared_matrix_dependencies_match_perturbation(slave):
    """InitialUnknowns of A[i,j], B[i,j]: the knowns that change them are exactly those declared."""
    slave.exit_initialization_mode()
    matrix = [v for v in DroneFlyLateral.VARIABLES if v.causality == "calculatedParameter"]
    base = dict(zip([v.name for v in matrix], _get(slave, *[v.name for v in matrix])))
    found: dict[str, set[str]] = {v.name: set() for v in matrix}
    for name in lateral_dynamics.LateralParameters.names():
        s = DroneFlyLateral(instance_name="perturbed")
        s.setup_experiment(0.0)
        s.enter_initialization_mode()
        _set(s, **{name: _get(s, name)[0] * 1.1 + 0.01})
        s.exit_initialization_mode()
        for v in matrix:
            if _get(s, v.name)[0] != base[v.name]:
                found[v.name].add(name)
    for v in matrix:
        declared = set(v.initial_dependencies)
        assert found[v.name] <= declared, v.name  # nothing undeclared
        if base[v.name] != 0.0:  # a zero entry (Yr+ = 0) hides its structural factor m+
            assert found[v.name] == declared, v.name


def test_initial_outputs_are_the_start_values(slave):
    _set(slave, delta_v_start=0.1, delta_p_start=-2.0, delta_r_start=1.0, delta_gamma_start=0.2)
    slave.exit_initialization_mode()
    assert _get(slave, *lateral_interface.STATE_NAMES) == [0.1, -2.0, 1.0, 0.2]


def test_step_is_exact_and_independent_of_step_size(slave):
    _set(slave, delta_gamma_start=0.1, delta_Phi_a=0.01)
    slave.exit_initialization_mode()
    h = 1.0 / lateral_interface.N_HZ
    t = 0.0
    for _ in range(10):
        assert slave.do_step(t, h / 10)
        t += h / 10
    fine = np.array(_get(slave, *lateral_interface.STATE_NAMES))
    other = DroneFlyLateral(instance_name="coarse")
    other.setup_experiment(0.0)
    other.enter_initialization_mode()
    _set(other, delta_gamma_start=0.1, delta_Phi_a=0.01)
    other.exit_initialization_mode()
    assert other.do_step(0.0, h)
    assert_allclose(fine, _get(other, *lateral_interface.STATE_NAMES), rtol=1e-12)


def test_refused_step_changes_nothing_and_never_raises(slave):
    slave.exit_initialization_mode()
    _set(slave, delta_Phi_a=math.nan)
    before = slave._get_fmu_state().payload
    assert slave.do_step(0.0, 0.001) is False
    after = slave._get_fmu_state().payload
    assert after["time"] == before["time"] and after["extra"] == before["extra"]
    assert "delta_Phi_a = nan" in slave.log_queue[-1].msg
    assert int(slave.log_queue[-1].status) == 2  # fmi2Discard


def test_unknown_value_reference_is_reported_not_raised(slave):
    slave.set_real([10_000], [1.0])
    slave.exit_initialization_mode()
    assert slave.do_step(0.0, 0.001) is False
    assert "valueReference 10000" in slave.log_queue[-1].msg
    assert slave.do_step(0.0, 0.001) is True


def test_state_serialization_round_trip(slave):
    _set(slave, delta_gamma_start=0.1)
    slave.exit_initialization_mode()
    slave.do_step(0.0, 0.001)
    blob = DroneFlyLateral._fmu_state_to_bytes(slave._get_fmu_state())
    slave.do_step(0.001, 0.001)
    ref = _get(slave, *lateral_interface.STATE_NAMES)
    slave._set_fmu_state(DroneFlyLateral._fmu_state_from_bytes(blob))
    slave.do_step(0.001, 0.001)
    assert _get(slave, *lateral_interface.STATE_NAMES) == ref


def test_initial_unknowns_readable_in_initialization_mode(slave):
    """FMI 2.0: outputs and calculated parameters follow the start values before exit."""
    _set(slave, delta_gamma_start=0.2, m_plus=2 * lateral_interface.INERTIAS_SECT21["m_plus"])
    assert _get(slave, "delta_gamma", "A[1,1]") == [0.2, lateral_dynamics.A1_EQ12[0][0] / 2]


def test_no_step_past_stop_time():
    s = DroneFlyLateral(instance_name="stop")
    s.setup_experiment(0.0, 0.002)
    s.enter_initialization_mode()
    s.exit_initialization_mode()
    assert s.do_step(0.0, 0.002) is True
    assert s.do_step(0.002, 0.5) is False
    assert "past stopTime = 0.002" in s.log_queue[-1].msg


@pytest.mark.parametrize("call, fragment", [
    (lambda s: s.get_real([10_000]), "fmi2GetReal of valueReference 10000"),
    (lambda s: s.get_integer([0]), "fmi2GetInteger of delta_Phi_a (a Real variable)"),
    (lambda s: s.get_boolean([0]), "fmi2GetBoolean of delta_Phi_a (a Real variable)"),
])
def test_misused_getters_are_logged(slave, call, fragment):
    call(slave)
    assert fragment in slave.log_queue[-1].msg
    assert int(slave.log_queue[-1].status) == 3  # fmi2Error


def test_long_step_is_exact_or_refused_with_the_reason(slave):
    """exp(A1 h) overflows beyond about 9000 wing beats: the zero state stays exactly zero,
    any other state is refused with the reason and the largest step that works."""
    slave.exit_initialization_mode()
    assert slave.do_step(0.0, 100.0) is True
    assert _get(slave, *lateral_interface.STATE_NAMES) == [0.0, 0.0, 0.0, 0.0]
    _set(slave, delta_Phi_a=0.01)
    assert slave.do_step(100.0, 100.0) is False
    text = " ".join(m.msg for m in slave.log_queue)
    assert "overflows exp(A1 h)" in text and "take steps of at most" in text
    assert _get(slave, *lateral_interface.STATE_NAMES) == [0.0, 0.0, 0.0, 0.0]  # refused: nothing changed
    assert slave.do_step(100.0, 1.0) is True  # a shorter step works
