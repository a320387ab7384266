"""What a user sets from the command line reaches the co-simulation; exit codes say what failed.

Oracles: the eigenvalues of A1 + B1 K computed from dronefly.plant.model with the same
parameters (not from the FMU), and python's own behaviour for --version.
"""

from __future__ import annotations

import json
import sys

import numpy as np
import pytest
from numpy.testing import assert_allclose

from dronefly import __version__, commands
from dronefly.cli import main
from dronefly.errors import DroneflyError
from dronefly.harness.cosim.params import parse_gains
from dronefly.harness.cosim.run import cosimulate
from dronefly.lateral import sort_eigenvalues
from dronefly.plant import model

pytestmark = pytest.mark.integration


@pytest.fixture(scope="module")
def fmus(built_fmus):
    return built_fmus["DroneFlyLateral"], built_fmus["StateFeedback"]


def _expected(K: np.ndarray, **params: float) -> np.ndarray:
    A, B = model.system_matrices(model.default_parameters().with_values(**params))
    return np.array(sort_eigenvalues(np.linalg.eigvals(A + B @ K)))


def test_set_changes_the_plant_as_the_model_predicts(fmus, tmp_path, capsys):
    argv = ["cosim", "--plant", str(fmus[0]), "--controller", str(fmus[1]), "--stop", "40",
            "--gains", "open", "--set", "plant.Lv_plus=0.5", "--set", "Nr_plus=-6",
            "--json", "--no-plot", "--out", str(tmp_path)]
    assert main(argv) == 0
    out = json.loads(capsys.readouterr().out)
    got = np.array([complex(*z) for z in out["eigenvalues_per_wingbeat"]])
    want = _expected(np.zeros((3, 4)), Lv_plus=0.5, Nr_plus=-6.0)
    assert_allclose(got, want, atol=1e-6)
    assert not np.allclose(want, _expected(np.zeros((3, 4))), atol=1e-3)  # it did change


def test_full_gain_matrix_on_all_three_controls(fmus, tmp_path):
    """An LQR-like full-state design on every control: the co-simulated loop has the
    eigenvalues of A1 + B1 K (computed here with scipy, not by the FMUs)."""
    from scipy.signal import place_poles

    A, B = model.system_matrices(model.default_parameters())
    K = -place_poles(A, B, [-0.2, -0.25, -0.3, -0.35]).gain_matrix
    path = tmp_path / "K.json"
    path.write_text(json.dumps({"K": K.tolist()}))
    r = cosimulate(*fmus, gains=str(path), stop_wingbeats=40, out_dir=None, plot=False)
    # the loop as co-simulated: u_k = K x_k held over each 0.1 wing beat (sampled data), by
    # the eigendecomposition of A1 (independent of the FMU's matrix exponential)
    h = 0.1
    lam, V = np.linalg.eig(A)
    Vi = np.linalg.inv(V)
    Phi = (V * np.exp(lam * h)) @ Vi
    Gamma = (V * ((np.exp(lam * h) - 1) / lam)) @ Vi @ B
    sampled = np.log(np.linalg.eigvals(Phi + Gamma @ K).astype(complex)) / h
    assert_allclose(np.sort(r.identification.eigenvalues.real), np.sort(sampled.real), atol=1e-6)
    assert_allclose(np.sort(r.continuous_eigenvalues.real), [-0.35, -0.3, -0.25, -0.2], atol=1e-9)
    assert r.identification.verdict == "stable"
    inline = ";".join(",".join(repr(float(v)) for v in row) for row in K)
    assert np.array_equal(parse_gains(inline), K)
    csv_path = tmp_path / "K.csv"
    csv_path.write_text("k1,k2,k3,k4\n" + "\n".join(",".join(repr(float(v)) for v in row) for row in K))
    assert np.array_equal(parse_gains(str(csv_path)), K)


def test_set_and_gains_reach_the_sweep(fmus, tmp_path):
    from dronefly.harness.sweep.cases import SweepSpec
    from dronefly.harness.sweep.run import run_sweep

    spec = SweepSpec(disturbances=("directions",), directions=("+dgamma",), amplitudes=1,
                     gains=("open",), steps_wb=(1.0,), stop_wb=5.0)
    a = run_sweep(spec, tmp_path / "a", plant=fmus[0], controller=fmus[1], workers=1,
                  plot=False, progress_bar=False)
    b = run_sweep(spec, tmp_path / "b", plant=fmus[0], controller=fmus[1], workers=1,
                  plot=False, progress_bar=False, set_values={"plant.g_plus": 0.0})
    ra, rb = a.rows[0], b.rows[0]
    assert float(ra["final_dv"]) != float(rb["final_dv"])  # gravity off: no sideslip from roll
    assert abs(float(rb["final_dv"])) < 1e-12


def test_version(capsys):
    assert main(["--version"]) == 0
    assert capsys.readouterr().out.strip() == f"dronefly {__version__}"


def test_a_bug_is_not_reported_as_bad_input(monkeypatch, capsys):
    def broken(args):
        raise RuntimeError("boom")

    monkeypatch.setattr(commands, "demo", broken)
    assert main(["demo"]) == 1
    err = capsys.readouterr().err
    assert "internal error (a bug" in err and "RuntimeError: boom" in err and "Traceback" not in err
    assert main(["--debug", "demo"]) == 1
    assert "Traceback" in capsys.readouterr().err


def test_bad_input_is_one_line_exit_2(monkeypatch, capsys):
    def bad(args):
        raise DroneflyError("x = 'y' is not a number\nsecond line")

    monkeypatch.setattr(commands, "demo", bad)
    assert main(["demo"]) == 2
    err = capsys.readouterr().err
    assert err == "dronefly demo: error: x = 'y' is not a number\n"


@pytest.mark.parametrize("argv,module,extra", [
    (["cosim"], "matplotlib", "plot"),
    (["demo"], "matplotlib", "plot"),
    (["sweep", "--no-plot"], "tqdm", "sweep"),
])
def test_missing_extra_gives_a_hint_and_writes_nothing(monkeypatch, capsys, tmp_path, argv,
                                                       module, extra):
    monkeypatch.setitem(sys.modules, module, None)  # import fails as if not installed
    out = tmp_path / "out"
    assert main([*argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and f"dronefly-fmu[{extra}]" in err and module in err
    assert not out.exists()
