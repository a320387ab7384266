"""The StateFeedback slave class called directly (no FMU, no fmpy)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from dronefly.models import feedback as L
from dronefly.controller.slave import StateFeedback

from controller_common import CONTROLS, H, STATES, dimensional, expected_controls


def _messages(s: StateFeedback) -> list[str]:
    return [m.msg for m in s.log_queue]


@pytest.fixture
def slave() -> StateFeedback:
    s = StateFeedback(instance_name="unit")
    s.setup_experiment(0.0)
    s.enter_initialization_mode()
    s.exit_initialization_mode()
    return s


def _set(s: StateFeedback, values: dict[str, float]) -> None:
    s.set_real([s._vr[n] for n in values], list(values.values()))


def _get(s: StateFeedback, names: list[str]) -> list[float]:
    return s.get_real([s._vr[n] for n in names])


def test_slave_outputs_follow_inputs_without_step(slave):
    x = dimensional([0.01, -0.02, 0.03, 0.4])
    _set(slave, dict(zip(STATES, x)))
    assert_allclose(_get(slave, CONTROLS), expected_controls(np.array(L.default_gains()), x)[0],
                    rtol=1e-12)
    _set(slave, {"K[2,4]": 0.5})  # a tunable parameter takes effect at once
    assert _get(slave, ["delta_alpha_1a"]) == [pytest.approx(0.5 * 0.4, rel=1e-15)]
    assert slave.do_step(0.0, H)


def test_slave_bad_input_keeps_outputs_and_refuses_step(slave):
    _set(slave, {"delta_gamma": 0.5})
    before = _get(slave, CONTROLS)
    _set(slave, {"delta_p": math.nan})
    assert _get(slave, CONTROLS) == before
    assert "delta_p = nan is not finite" in _messages(slave)[-1]
    assert slave.do_step(0.0, H) is False
    assert "delta_p = nan" in _messages(slave)[-1]
    _set(slave, {"delta_p": 0.0})
    assert slave.do_step(0.0, H) is True
    assert _get(slave, CONTROLS) == before


def test_slave_has_no_module_level_state():
    a, b = StateFeedback(instance_name="a"), StateFeedback(instance_name="b")
    _set(a, {"K[1,4]": 1.0, "delta_gamma": 0.1})
    _set(b, {"delta_gamma": 0.1})
    assert _get(a, ["delta_Phi_a"]) == [0.1]
    assert _get(b, ["delta_Phi_a"]) == [pytest.approx(-0.00643, rel=1e-14)]
