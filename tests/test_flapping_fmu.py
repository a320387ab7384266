"""DroneFlyFlapping through FMI: the same physics whatever the host's step, bad inputs refused,
and the Floquet analysis through fmi2GetFMUstate/fmi2SetFMUstate equal to the model's own, and to
the eigenvalues of a linear time-invariant FMU."""

from __future__ import annotations

import json
import math

import fmpy
import numpy as np
import pytest

from dronefly.cli.app import main
from dronefly.harness.flapping import fmi_floquet
from dronefly.models import lateral_dynamics
from dronefly.models.flapping import Floquet, FlappingModel, periodic_orbit
from dronefly.models.lateral_interface import N_HZ, sort_eigenvalues

pytestmark = pytest.mark.integration

STATES = ("delta_v", "delta_p", "delta_r", "delta_gamma", "delta_u", "delta_w", "delta_q",
          "delta_theta", "x_earth", "z_earth", "stroke_angle_left", "angle_of_attack_right",
          "Z_aero")


def _inputs(steps_per_beat: int, beats: int) -> np.ndarray:
    """A lateral and a longitudinal control changed at beat starts, on the host's grid."""
    t = np.arange(beats * steps_per_beat + 1) / (steps_per_beat * N_HZ)
    table = np.zeros(len(t), dtype=[("time", float), ("delta_Phi_a", float),
                                    ("delta_phibar", float)])
    table["time"] = t
    wb = t * N_HZ
    table["delta_Phi_a"] = np.where(wb >= 1 - 1e-9, 0.05, 0.0)
    table["delta_phibar"] = np.where(wb >= 2 - 1e-9, -0.03, 0.0)
    return table


def test_one_step_or_forty_per_wing_beat_is_the_same_flight(built_fmus):
    path = str(built_fmus["DroneFlyFlapping"])
    runs = {}
    for k in (1, 40):
        r = fmpy.simulate_fmu(path, stop_time=3 / N_HZ, output_interval=1 / (k * N_HZ),
                              input=_inputs(k, 3), output=list(STATES))
        runs[k] = r[::k]  # the beats' ends
    for name in STATES:
        # the inputs are taken at the beats' starts; the internal grid does not move with the
        # communication step: the same floating-point operations, so the same bits
        assert np.array_equal(runs[1][name], runs[40][name]), name


def _instance(path, folder):
    md = fmpy.read_model_description(path)
    unzip = fmpy.extract(path, str(folder))
    from fmpy.fmi2 import FMU2Slave
    s = FMU2Slave(guid=md.guid, unzipDirectory=unzip,
                  modelIdentifier=md.coSimulation.modelIdentifier, instanceName="bad")
    s.instantiate(loggingOn=False)
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.exitInitializationMode()
    return s, {v.name: v.valueReference for v in md.modelVariables}


@pytest.mark.parametrize("value", [math.nan, math.inf, 1.5])
def test_a_bad_input_is_refused_with_discard_and_the_state_kept(built_fmus, value, tmp_path):
    s, vr = _instance(str(built_fmus["DroneFlyFlapping"]), tmp_path / "fmu")
    h = 0.25 / N_HZ
    s.doStep(currentCommunicationPoint=0.0, communicationStepSize=h)
    before = s.getReal([vr["delta_u"], vr["delta_q"]])
    s.setReal([vr["delta_alpha_1a"]], [value])
    with pytest.raises(Exception, match="discard"):
        s.doStep(currentCommunicationPoint=h, communicationStepSize=h)
    assert s.getReal([vr["delta_u"], vr["delta_q"]]) == before
    s.setReal([vr["delta_alpha_1a"]], [0.0])
    s.doStep(currentCommunicationPoint=h, communicationStepSize=h)  # recovered
    s.terminate()
    s.freeInstance()


def test_floquet_of_a_linear_fmu_is_its_eigenvalues(built_fmus):
    # the linear lateral plant with a period of one wing beat given: the map is exp(A), the
    # central differences of a linear map are exact but for round-off (1e-15 here)
    r = fmi_floquet(built_fmus["DroneFlyLateral"], 1.0 / N_HZ)
    A, _ = lateral_dynamics.system_matrices(lateral_dynamics.default_parameters())
    ev = sort_eigenvalues(np.linalg.eigvals(np.array(A)))
    assert np.max(np.abs(np.array(r.exponents) - np.array(ev))) < 1e-8


def test_floquet_through_fmi_is_the_models(built_fmus):
    r = fmi_floquet(built_fmus["DroneFlyFlapping"])
    model = FlappingModel()
    orbit = periodic_orbit(model)
    fl = Floquet.of(model, orbit)
    # the same equations and grid: the orbit agrees to the Newton tolerance (in the FMU's
    # SI units: velocities times U, rates times n), the exponents to the finite differences'
    # round-off (a step of 1e-6 on a map computed to 1e-15: 1e-9)
    z = orbit.z0
    U, n = model.U, model.n
    expected = [z[1] * U, z[3] * n, z[5] * n, z[6], z[0] * U, z[2] * U, z[4] * n, z[7]]
    assert np.max(np.abs(r.orbit_start - expected) / r_scales(U, n)) < 1e-10
    assert np.max(np.abs(np.array(r.exponents) - np.array(sort_eigenvalues(fl.exponents)))) \
        < 1e-7


def r_scales(U: float, n: float) -> np.ndarray:
    return np.array([U, n, n, 1.0, U, U, n, 1.0])


def test_floquet_command_json(built_fmus, capsys):
    assert main(["floquet", "--plant", str(built_fmus["DroneFlyLateral"]), "--period",
                 repr(1.0 / N_HZ), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    # the linear lateral plant (no averaged model to compare): its exponents as [re, im] are
    # eig(A) of Eq. (9) (as test_floquet_of_a_linear_fmu_is_its_eigenvalues, 1e-8), its orbit
    # the origin, the period the one asked for
    A, _ = lateral_dynamics.system_matrices(lateral_dynamics.default_parameters())
    ev = sort_eigenvalues(np.linalg.eigvals(np.array(A)))
    got = [complex(re, im) for re, im in out["floquet_exponents"]]
    assert np.max(np.abs(np.array(got) - np.array(ev))) < 1e-8
    assert out["period_s"] == 1.0 / N_HZ and out["averaged_eigenvalues"] == []
    assert out["orbit_start"] == dict.fromkeys(("delta_v", "delta_p", "delta_r", "delta_gamma"),
                                               0.0)


@pytest.mark.numeric
def test_with_forces_averaged_the_fmu_flies_as_the_quasi_steady_6dof_fmu(built_fmus):
    """With the flapping forces replaced by their cycle average (forces = 2) the
    FMU is DroneFlyHover6DOF with the quasi-steady aerodynamics (aerodynamics = 2) and the same
    body (the Sect. 2.4 mass and inertias, set as the 6-DOF FMU's parameters). Both through
    fmpy, 10 wing beats from a lateral disturbance, compared at the beats' ends: they agree to
    1e-5 of the disturbance in each state, the bound of the model-level test
    (tests/test_flapping.py): the 6-DOF plant's sub-steps, not round-off, set it (measured
    6.4e-6 of it, in delta_theta)."""
    from dronefly.models.lateral_interface import LATERAL, U_M_PER_S, reference_scales
    from dronefly.models.longitudinal_interface import LONGITUDINAL

    s = reference_scales()
    body = {k: s[k] for k in ("m_plus", "Ix_plus", "Iy_plus", "Iz_plus", "Ixz_plus", "g_plus")}
    lat_scale = dict(zip(LATERAL.state_names, LATERAL.scale_vector(U_M_PER_S, N_HZ)))
    lon_scale = dict(zip(LONGITUDINAL.state_names, LONGITUDINAL.scale_vector(U_M_PER_S, N_HZ)))
    scale = {**lat_scale, **lon_scale}
    x0 = {"delta_v": 0.02, "delta_p": 0.03, "delta_r": 0.01}  # non-dimensional
    starts = {f"{n}_start": v * scale[n] for n, v in x0.items()}
    names = [*LATERAL.state_names, *LONGITUDINAL.state_names]
    run = {}
    for model, extra in (("DroneFlyFlapping", {"forces": 2}),
                         ("DroneFlyHover6DOF", {"aerodynamics": 2, **body})):
        run[model] = fmpy.simulate_fmu(str(built_fmus[model]), stop_time=10 / N_HZ,
                                       output_interval=1 / N_HZ, output=names,
                                       start_values={**starts, **extra})
    a, b = run["DroneFlyFlapping"], run["DroneFlyHover6DOF"]
    assert len(a) == len(b) == 11
    for n in names:
        gap = np.max(np.abs(a[n] - b[n])) / scale[n]
        assert gap <= 1e-5 * 0.03, (n, gap)
    assert np.max(np.abs(a["delta_p"])) / scale["delta_p"] > 0.03  # the disturbance grew
    # and the instantaneous forces (the default) are not that: the test can fail
    c = fmpy.simulate_fmu(str(built_fmus["DroneFlyFlapping"]), stop_time=10 / N_HZ,
                          output_interval=1 / N_HZ, output=names, start_values=starts)
    assert np.max(np.abs(c["delta_v"] - b["delta_v"])) / scale["delta_v"] > 1e-3


@pytest.mark.numeric
def test_started_on_the_periodic_orbit_the_fmu_returns_to_its_start_after_a_wing_beat(
        built_fmus):
    """At trim (the averaged trim's kinematics, controls 0) hover is a periodic
    orbit. The FMU started at the orbit's start (found by the model's Newton shooting, to a
    residual of 1e-12) is back there after one wing beat, through fmpy: to 1e-10 of U (and of
    1/t_w, 1 rad), the Newton tolerance and the round-off of the start parameters' SI
    conversion (the FMU integrates on the same grid as the model). Half a beat in, it is not
    (the body's oscillation within the beat), and from rest (state 0) the beat does not close
    (the orbit is not trivial)."""
    from dronefly.harness.cosim.ssp import flapping_starts
    from dronefly.models.flapping import orbit_start
    from dronefly.models.lateral_interface import U_M_PER_S

    names = ("delta_u", "delta_v", "delta_w", "delta_p", "delta_q", "delta_r", "delta_gamma",
             "delta_theta")
    scale = (U_M_PER_S,) * 3 + (N_HZ,) * 3 + (1.0, 1.0)

    def run(starts):
        r = fmpy.simulate_fmu(str(built_fmus["DroneFlyFlapping"]), stop_time=1 / N_HZ,
                              output_interval=0.5 / N_HZ, output=list(names),
                              start_values=starts)
        return np.array([[row[n] / s for n, s in zip(names, scale)] for row in r])

    orbit = run(flapping_starts(orbit_start()))
    assert np.max(np.abs(orbit[2] - orbit[0])) <= 1e-10, orbit[2] - orbit[0]
    assert np.max(np.abs(orbit[1] - orbit[0])) > 1e-4  # within the beat it moves
    rest = run({})
    assert np.max(np.abs(rest[2] - rest[0])) > 1e-4
