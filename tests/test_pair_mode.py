"""``cosim``/``sweep`` with ``--plant/--controller``: any pair connected by name is identified
from its own states, and a pair that cannot be is refused up front."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.linalg import expm

from dronefly.cli.app import main
from dronefly.harness.cosim.pair import PairError, pair_layout
from dronefly.harness.paper.longitudinal import design
from dronefly.harness.stability.run import cosimulate
from dronefly.models.longitudinal_dynamics import default_parameters, system_matrices


def _zoh_rates(A: np.ndarray, B: np.ndarray, K: np.ndarray, step_wb: float) -> np.ndarray:
    """log(eig(Phi + Gamma K)) / step: the sampled-data loop by scipy's expm (an oracle
    independent of the harness's discretisation)."""
    n, m = B.shape
    M = np.zeros((n + m, n + m))
    M[:n, :n], M[:n, n:] = A, B
    E = expm(M * step_wb)
    mu = np.linalg.eigvals(E[:n, :n] + E[:n, n:] @ K)
    return np.log(mu.astype(complex)) / step_wb


def test_longitudinal_pair_gives_the_verdict_of_design_b(built_fmus):
    """The project's longitudinal pair runs by name: its states come from the plant, the
    gains are the controller's own (design (b), Sect. 3.5), and the verdict matches
    eig(A + B K) of that design computed from the model, not from the FMUs."""
    r = cosimulate(built_fmus["DroneFlyLongitudinal"], built_fmus["StateFeedbackLongitudinal"],
                   stop_wingbeats=60.0, out_dir=None, plot=False)
    assert r.run.complete and r.check_failures == []
    A, B = system_matrices(default_parameters())
    d = design("mirror", ["delta_phibar"], A, B)
    assert_allclose(r.gains, d.K, rtol=0, atol=1e-12)  # the controller's K is design (b)
    # the FMU's A, B are the model's to rounding (4x4, condition ~1e2): 1e-9 is ample
    assert_allclose(np.sort_complex(r.continuous_eigenvalues), np.sort_complex(d.eigenvalues),
                    atol=1e-9)
    exact = _zoh_rates(A, B, d.K, 0.1)
    # the fit from 20-step runs reproduces the exact transition to ~1e-10 (well conditioned)
    assert r.identification.dominant_growth_rate == pytest.approx(float(np.max(exact.real)),
                                                                  abs=1e-7)
    assert r.verdict == "stable" and max(d.eigenvalues.real) < 0


def test_cli_cosim_longitudinal_pair(built_fmus, tmp_path):
    argv = ["cosim", "--plant", str(built_fmus["DroneFlyLongitudinal"]), "--controller",
            str(built_fmus["StateFeedbackLongitudinal"]), "--stop", "30", "--no-plot",
            "--out", str(tmp_path)]
    assert main(argv) == 0


@pytest.mark.parametrize("extra, words", [
    (["--gains", "paper"], "3x4 matrix"),
    (["--x0=0,0,0.1"], "has 3 values"),
])
def test_cli_cosim_longitudinal_refuses_lateral_shapes(built_fmus, tmp_path, capsys, extra,
                                                       words):
    out = tmp_path / "out"
    argv = ["cosim", "--plant", str(built_fmus["DroneFlyLongitudinal"]), "--controller",
            str(built_fmus["StateFeedbackLongitudinal"]), "--stop", "30", "--no-plot",
            "--out", str(out), *extra]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert words in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


def test_cli_sweep_refuses_a_non_lateral_pair_up_front(built_fmus, tmp_path, capsys):
    out = tmp_path / "sweep"
    argv = ["sweep", "--plant", str(built_fmus["DroneFlyLongitudinal"]), "--controller",
            str(built_fmus["StateFeedbackLongitudinal"]), "--no-plot", "--no-progress",
            "--workers", "1", "--out", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "lateral states" in err and "delta_theta" in err
    assert not out.exists()  # refused before any case ran or any file was written


def _var(name, causality, type_="Real", unit="rad"):
    return SimpleNamespace(name=name, causality=causality, type=type_, unit=unit,
                           declaredType=None)


def _fmu(variables, path="x.fmu"):
    md = SimpleNamespace(modelVariables=variables)
    return SimpleNamespace(
        path=path, model_description=md, variables={v.name: v for v in variables},
        names=lambda c: [v.name for v in variables if v.causality == c])


def _plant(start=True, unit="rad"):
    vs = [_var("u", "input"), _var("x", "output", unit=unit), _var("y", "output", unit="rad/s")]
    if start:
        vs += [_var("x_start", "parameter"), _var("y_start", "parameter")]
    return _fmu(vs)


def _controller(gains=True, inputs=("x", "y")):
    vs = [*(_var(i, "input") for i in inputs), _var("u", "output")]
    if gains:
        vs += [_var("K[1,1]", "parameter"), _var("K[1,2]", "parameter")]
    return _fmu(vs)


def test_pair_layout_reads_any_pair():
    layout = pair_layout(_plant(), _controller())
    assert layout.states == ("x", "y") and layout.controls == ("u",)
    assert layout.scales == ("1", "n") and layout.shape == (1, 2)


@pytest.mark.parametrize("plant, controller, words", [
    (_plant(start=False), _controller(), "x_start"),
    (_plant(), _controller(gains=False), "no gain 'K[1,1]'"),
    (_plant(), _controller(inputs=("y", "x")), "not the plant's states in its order"),
    (_plant(unit="m"), _controller(), "is in 'm'"),
])
def test_pair_layout_refuses_with_the_reason(plant, controller, words):
    with pytest.raises(PairError, match="cannot identify the loop") as e:
        pair_layout(plant, controller)
    assert words in str(e.value)
