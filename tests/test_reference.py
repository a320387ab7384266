"""Reference results (FMI cross-check rules): <Model>_in.csv, _ref.opt, _ref.csv per FMU folder."""

from __future__ import annotations

import shutil

import numpy as np
import pytest
from fmpy.util import read_csv
from scipy.integrate import solve_ivp
from scipy.linalg import expm

from dronefly.harness.compliance.reference import (REFERENCES, check_reference, reference_outputs,
                                                 reference_paths)
from dronefly.harness.paper.analysis import lateral_system, longitudinal_system
from dronefly.models.feedback import default_gains
from dronefly.models.lateral_interface import CONTROL_NAMES as LATERAL_CONTROLS
from dronefly.models.lateral_interface import LATERAL, N_HZ, U_M_PER_S
from dronefly.models.longitudinal_interface import CONTROL_NAMES as LONGITUDINAL_CONTROLS
from dronefly.models.longitudinal_interface import LONGITUDINAL
from test_hover6dof import _oracle_outputs, newton_euler

pytestmark = pytest.mark.integration


@pytest.mark.parametrize("model", sorted(REFERENCES))
def test_reference_reproduces(built_fmus, model):
    """fmpy's cross-check band: no outliers; and, both FMUs being exact, equal to 1e-9 relative."""
    check = check_reference(model, built_fmus[model])
    assert check.cross_check_outliers == 0.0
    assert check.max_rel_error <= 1e-9, check


@pytest.mark.parametrize("model", sorted(REFERENCES))
def test_reference_files_follow_cross_check_rules(model, request):
    from fmpy.util import read_csv, read_ref_opt_file

    inp, opt, ref = reference_paths(model)
    opts = read_ref_opt_file(str(opt))
    data = read_csv(str(ref))
    assert data["time"][0] == opts["StartTime"]
    assert data["time"][-1] == pytest.approx(opts["StopTime"], rel=1e-12)
    assert np.allclose(np.diff(data["time"]), opts["StepSize"], rtol=1e-9)
    # the outputs of REFERENCES, or (where it names none) those of the built FMU's model
    # description, in its order
    fmu = (request.getfixturevalue("built_fmus")[model] if REFERENCES[model].outputs is None
           else None)
    assert list(data.dtype.names[1:]) == reference_outputs(model, fmu)
    assert max(np.ptp(data[n]) for n in data.dtype.names[1:]) > 0, \
        "the reference exercises the model"
    if REFERENCES[model].inputs(data["time"]):
        assert read_csv(str(inp)).shape == data.shape
    else:
        assert not inp.exists(), "no _in.csv for a model without inputs"


def test_a_wrong_reference_is_detected(built_fmus, tmp_path):
    """The comparison can fail: a reference whose delta_gamma is 1.5 times the true value from
    row 100 on (far outside fmpy's cross-check band) is reported."""
    model = "DroneFlyLateral"
    for p in reference_paths(model):
        shutil.copy(p, tmp_path / p.name)
    ref = tmp_path / f"{model}_ref.csv"
    lines = ref.read_text().splitlines()
    head, rows = lines[0], [r.split(",") for r in lines[1:]]
    for r in rows[100:]:
        r[4] = repr(float(r[4]) * 1.5)
    ref.write_text("\n".join([head, *(",".join(r) for r in rows)]) + "\n")
    check = check_reference(model, built_fmus[model], folder=tmp_path)
    assert check.cross_check_outliers > 0 and not check.passed


def _columns(data) -> np.ndarray:
    return np.column_stack([data[n] for n in data.dtype.names[1:]])


# The stored references are written by the FMUs themselves (write_reference): each is checked
# here against a computation that does not use the FMU or its stepper.
@pytest.mark.parametrize("model, system, axes", [
    ("DroneFlyLateral", lateral_system, LATERAL),
    ("DroneFlyLongitudinal", longitudinal_system, LONGITUDINAL),
])
def test_linear_plant_references_are_the_papers_equations_integrated(model, system, axes):
    """The plant's _ref.csv is dx+/dt+ = A x+ + B u of the paper (Eq. (9); Sect. 3.5 as
    printed) from rest, each input of _in.csv held over its communication step, integrated by
    scipy's DOP853 (rtol 1e-12) step by step and scaled to SI (x = x+ * (U or n or 1)): the
    FMU's exact zero-order hold and an adaptive Runge-Kutta method agree to their round-off
    and DOP853's tolerance, 1e-12 of each state's range (measured 2e-14)."""
    inp, _, ref = reference_paths(model)
    u, y = read_csv(str(inp)), read_csv(str(ref))
    assert inp.exists() and np.array_equal(u["time"], y["time"])
    A, B = system()
    controls, want = _columns(u), _columns(y)
    scale = np.array(axes.scale_vector(U_M_PER_S, N_HZ))
    t_wb = y["time"] * N_HZ
    x, got = np.zeros(4), [np.zeros(4)]
    for k in range(len(t_wb) - 1):
        uk = controls[k]
        sol = solve_ivp(lambda t, z: A @ z + B @ uk, (t_wb[k], t_wb[k + 1]), x,
                        method="DOP853", rtol=1e-12, atol=1e-14)
        x = sol.y[:, -1]
        got.append(x * scale)
    err = np.max(np.abs(np.array(got) - want), axis=0) / np.max(np.abs(want), axis=0)
    assert np.all(err < 1e-12), err


def test_controller_reference_is_eq27_applied_to_its_inputs():
    """StateFeedback's _ref.csv: after each step the controls are K x+ of the inputs set
    before it (x+ = x / scale, K of Eq. (27), no saturation): one product, round-off 1e-15."""
    inp, _, ref = reference_paths("StateFeedback")
    u, y = read_csv(str(inp)), read_csv(str(ref))
    x_plus = _columns(u) / np.array(LATERAL.scale_vector(U_M_PER_S, N_HZ))
    want = x_plus @ np.array(default_gains()).T
    got = _columns(y)
    assert y.dtype.names[-1] == "saturated" and not got[:, -1].any()
    np.testing.assert_allclose(got[1:, :3], want[:-1], rtol=0,
                               atol=1e-15 * np.max(np.abs(want)))


def test_closed_loop_container_reference_is_the_sampled_data_loop():
    """DroneFlyClosedLoop's _ref.csv (the container FMU from its default 0.1 rad roll): the
    sampled-data loop of Eq. (9) and Eq. (27) in closed form, x+_{k+1} = (Phi + Gamma K) x+_k
    with Phi, Gamma from scipy's expm of the augmented matrix over the 0.1-wing-beat step, and
    the controls K x+_k: 1000 steps of a contracting map, round-off 1e-14 of the ranges
    (measured 4e-15)."""
    _, _, ref = reference_paths("DroneFlyClosedLoop")
    y = read_csv(str(ref))
    got = _columns(y)
    A, B = lateral_system()
    K = np.array(default_gains())
    scale = np.array(LATERAL.scale_vector(U_M_PER_S, N_HZ))
    h_wb = (y["time"][1] - y["time"][0]) * N_HZ
    M = expm(np.block([[A, B], [np.zeros((3, 7))]]) * h_wb)
    x = np.array([0.0, 0.0, 0.0, 0.1])  # delta_gamma_start = 0.1 rad, the container's default
    want = []
    for _ in range(len(got)):
        want.append([*(x * scale), *(K @ x)])
        x = M[:4, :4] @ x + M[:4, 4:] @ (K @ x)
    want = np.array(want)
    err = np.max(np.abs(got - want), axis=0) / np.maximum(np.max(np.abs(want), axis=0), 1e-300)
    assert np.all(err < 1e-13), err


def test_hover6dof_reference_is_newton_euler_integrated():
    """DroneFlyHover6DOF's _ref.csv (both plants' doublets and pulses from rest, 60 wing beats)
    against the Newton-Euler equations written in tests/test_hover6dof.py, integrated by
    DOP853 (rtol 1e-12) step by step with each input of _in.csv held over its step, the
    outputs (Euler angles, earth axes) computed there too: within 1e-9 of each output's peak,
    the bound of test_hover6dof.py::test_fmu_outputs_against_solve_ivp (the FMU's sub-steps)."""
    inp, _, ref = reference_paths("DroneFlyHover6DOF")
    u, y = read_csv(str(inp)), read_csv(str(ref))
    names = list(y.dtype.names[1:])
    f = newton_euler()
    lat_in, lon_in = LATERAL_CONTROLS, LONGITUDINAL_CONTROLS
    t_wb = y["time"] * N_HZ
    x = np.array([0.0] * 6 + [1.0, 0.0, 0.0, 0.0] + [0.0] * 3)  # at rest, level, the origin
    controls = np.column_stack([u[n] for n in (*lat_in, *lon_in)])
    # one integration per stretch of held controls (they change a few times), through its
    # communication points
    change = [0, *(k for k in range(1, len(t_wb) - 1) if (controls[k] != controls[k - 1]).any()),
              len(t_wb) - 1]
    states = [x]
    for a, b in zip(change[:-1], change[1:]):
        c = controls[a]
        sol = solve_ivp(f, (t_wb[a], t_wb[b]), states[-1], method="DOP853", rtol=1e-12,
                        atol=1e-14, t_eval=t_wb[a + 1:b + 1], args=(c[:3], c[3:]))
        states.extend(sol.y.T)
    want = np.array([[_oracle_outputs(z)[n] for n in names] for z in states])
    got = _columns(y)
    err = np.abs(got - want) / np.maximum(np.abs(want).max(axis=0), 1e-300)
    assert err.max() <= 1e-9, dict(zip(names, err.max(axis=0)))
