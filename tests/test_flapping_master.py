"""The paper's lateral loop on the flapping insect as a system of two FMUs (DroneFlyFlapping and
StateFeedback) through the project's master: the exponents identified from its runs
are the linearised wing-beat map's, its beat starts are the in-model flight's, a step of 0.1
wing beat gives the same beat starts as a step of 1 (under Gauss-Seidel; under Jacobi the step
is a delay), the system is an SSP that ``dronefly cosim --system`` flies, and the FMI 3.0 build
flies the same bits."""

from __future__ import annotations

import numpy as np
import pytest

from dronefly.cli.app import main
from dronefly.harness.cosim.ssp import FLAPPING_FMUS, flapping_system
from dronefly.harness.cosim.identification import RATE_TOL_PER_WINGBEAT, classify
from dronefly.harness.cosim.system import System
from dronefly.harness.cosim.system_master import SystemMaster
from dronefly.harness.flapping import closed_loop_report, master_report, write_flapping_ssp
from dronefly.models.flapping import STEPS_PER_BEAT
from dronefly.models.lateral_interface import N_HZ
from dronefly.models.longitudinal_interface import LONGITUDINAL

#: integration: real FMUs through the master; numeric: the exponents depend on the BLAS kernel
pytestmark = [pytest.mark.integration, pytest.mark.numeric]

BEATS = 20  # the in-model run has 30: its first 21 beat starts are compared


@pytest.fixture(scope="module")
def report():
    # the map of the FMU's own integration (40 Runge-Kutta steps per beat), some 3 s
    return closed_loop_report(steps_per_beat=STEPS_PER_BEAT)


@pytest.fixture(scope="module")
def flown(built_fmus, report):
    return master_report(built_fmus, report, beats=BEATS)


def test_exponents_identified_from_the_runs_are_the_linearised_maps(flown, report):
    for name, loop in flown.loops.items():
        ident = loop.verdict.identification
        # Both sides are the one linear wing-beat map of the sampled loop: the map by central
        # differences of step 1e-6 (round-off 1e-16 / 1e-6 = 1e-10 in its entries), the runs
        # by a linear fit of once-per-beat samples 1e-5 from the orbit (the lateral map is odd
        # in the lateral state, so the fit leaves its cubic part, 2.4e-10 of |z|, measured).
        # Measured 3e-10 (Eq. 27) and 8e-9 (the design, its slow root less well
        # conditioned); the project's tolerance of an identified against an exact rate,
        # RATE_TOL_PER_WINGBEAT = 1e-6, is far below the margins the verdicts rest on (the
        # design's dominant rate +0.0129 against the neutral band of 1e-3)
        assert len(ident.eigenvalues) == len(report.flapping[name]) == 5, name
        assert loop.deviation <= RATE_TOL_PER_WINGBEAT, (name, loop.deviation)
        assert np.max(np.abs(ident.eigenvalues - np.array(report.flapping[name]))) \
            == loop.deviation
        assert loop.verdict.verdict == classify(np.array(report.flapping[name])) == "unstable"
        assert ident.fit_residual <= 1e-9


def test_beat_starts_through_the_master_are_the_in_model_flight(flown, report):
    for name, loop in flown.loops.items():
        ref = np.array(report.runs[name].states[:BEATS + 1])
        # Round-off: the start values pass through SI units (times U, then over U) and the
        # roll through gamma (asin(sin phi cos theta), inverted in the FMU), 1 ulp each, and the
        # controller computes K x+ from the plant's SI outputs; the loop then multiplies an
        # error by at most exp(0.0844 x 30) = 13 (measured 1.1e-16 of each state's peak)
        peak = np.abs(ref).max(axis=0)
        assert np.max(np.abs(loop.states - ref) / peak) < 1e-12, name
        assert np.allclose(loop.controls, report.runs[name].u[:BEATS], rtol=0, atol=1e-14)


def test_a_step_of_a_tenth_wing_beat_gives_the_same_beat_starts(flown):
    # the plant takes its controls at each beat's start and integrates on its own grid:
    # under Gauss-Seidel the control set at a beat's start is K x+ of that start at either
    # step, so the same floating-point operations, the same bits
    for name, loop in flown.loops.items():
        assert loop.fine_deviation == 0.0, name
        assert loop.oscillation["x_pp_um"] > 10 * loop.oscillation["y_pp_um"] > 0, name


def test_under_jacobi_the_step_is_a_delay(built_fmus, report):
    """Jacobi feeds the plant the controller's answer to the previous point: K x+ one step
    before the beat's start, a delay that changes with the step (documented in
    harness.flapping.master_run), so the two steps fly different loops."""
    system = flapping_system(built_fmus, z0=report.orbit.z0)
    gamma = {}
    with SystemMaster(system, "jacobi") as master:
        for k in (1, 10):
            r = master.run(1 / (k * N_HZ), 10 * k, record=["plant.delta_gamma"])
            gamma[k] = r.signals[::k, 0]
    assert gamma[1][0] == gamma[10][0]
    assert abs(gamma[1][-1] - gamma[10][-1]) > 1e-4


def test_the_system_is_an_ssp_that_dronefly_cosim_flies(built_fmus, tmp_path, capsys):
    fmu_dir = built_fmus["DroneFlyFlapping"].parent
    ssp = write_flapping_ssp(fmu_dir, tmp_path / "flapping.ssp", stop_wb=3.0)
    system = System.from_ssp(ssp)
    assert set(system.fmus) == set(FLAPPING_FMUS)
    driven = {c.input for c in system.connections if c.target == "plant"}
    assert driven == {"delta_Phi_a", "delta_alpha_1a", "delta_alpha_2a"}
    # the longitudinal controls are inputs no connection drives: they keep their start values
    assert not driven & set(LONGITUDINAL.control_names)
    assert system.stop_s == pytest.approx(3.0 / N_HZ)
    assert main(["cosim", "--system", str(ssp), "--step", "1", "--no-plot", "--out",
                 str(tmp_path / "out")]) == 0
    out = capsys.readouterr().out
    assert "3 steps to 3 wing beats" in out
    # the flapping plant (wing angles and loads without *_start) is no plant the command's
    # identification knows: it says so (the verdict is master_report's)
    assert "no verdict: nothing to identify: the system has no plant" in out


def test_the_fmi3_build_flies_the_same_bits_the_unconnected_inputs_at_their_starts(
        built_fmus, built_fmus3, report):
    # the same model behind either interface, the same master: the same floating-point
    # operations
    runs = []
    for fmus in (built_fmus, built_fmus3):
        with SystemMaster(flapping_system(fmus, z0=report.orbit.z0)) as master:
            runs.append(master.run(1 / N_HZ, 10, record=[
                "plant.delta_gamma", "plant.delta_p", "lateral_controller.delta_Phi_a",
                *(f"plant.{c}" for c in LONGITUDINAL.control_names)]))
    assert np.array_equal(runs[0].signals, runs[1].signals)
    # the unconnected inputs (recorded as themselves) kept their start values
    assert not np.any(runs[0].signals[:, 3:])
    assert np.any(runs[0].signals[:, 2])
