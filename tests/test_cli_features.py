"""What a user sets from the command line reaches the co-simulation; exit codes say what failed.

Oracles: the eigenvalues of A1 + B1 K computed from dronefly.models.lateral_dynamics with the same
parameters (not from the FMU), and python's own behaviour for --version.
"""

from __future__ import annotations

import csv
import json
import sys
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

from dronefly import __version__
from dronefly.cli.commands import demo as demo_command
from dronefly.cli.app import main
from dronefly.core.errors import DroneflyError
from dronefly.harness.paper.gains import parse_gains
from dronefly.harness.stability.run import cosimulate
from dronefly.models.lateral_interface import CONTROL_NAMES, N_HZ, STATE_NAMES, U_M_PER_S, sort_eigenvalues
from dronefly.models import lateral_dynamics

pytestmark = pytest.mark.integration


@pytest.fixture(scope="module")
def fmus(built_fmus):
    return built_fmus["DroneFlyLateral"], built_fmus["StateFeedback"]


def _expected(K: np.ndarray, **params: float) -> np.ndarray:
    A, B = lateral_dynamics.system_matrices(lateral_dynamics.default_parameters().with_values(**params))
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

    A, B = lateral_dynamics.system_matrices(lateral_dynamics.default_parameters())
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


def _read_csv(path: Path) -> tuple[list[str], np.ndarray]:
    rows = list(csv.reader(path.read_text(encoding="utf-8").splitlines()))
    return rows[0], np.array(rows[1:], dtype=float)


#: gains on dp+ and dr+ from dp+ = 0.1, dgamma = 0.1: |delta_Phi_a| falls from 0.03 to about
#: 0.0105 rad in 10 wing beats, so that a limit of 0.015 rad clips it for a while, not throughout
K_TEST = np.array([[0.0, -0.3, 0.0, 0.0], [0.0, 0.0, 0.2, 0.0], [0.0, 0.0, 0.0, 0.0]])
U_MAX = 0.015
LIMIT = ["--gains", ";".join(",".join(map(str, row)) for row in K_TEST), "--x0", "0,0.1,0,0.1",
         "--set", "controller.limit_enabled=1", "--set", f"controller.u_max={U_MAX}"]
RECORD = ["plant.delta_Phi_a", "controller.saturated", "controller.K[1,2]", "plant.n"]


def test_set_boolean_as_1_limits_and_record_adds_variables_of_both_fmus(fmus, tmp_path, capsys):
    """--set controller.limit_enabled=1 (a Boolean given as 1) clips every control to u_max;
    --record adds an input, a Boolean output and parameters of both FMUs to the CSV. Oracle:
    u = clip(K x+, -u_max, u_max), saturated = any |K x+| > u_max, with the K given and
    x+ = x / (U, n, n, 1) from the flight data, computed here from the recorded states. A
    clipped loop is not the linear loop the verdict identifies: the run's cross-check fails
    (exit 1), and the outputs are kept."""
    argv = ["cosim", "--plant", str(fmus[0]), "--controller", str(fmus[1]), "--stop", "10",
            *LIMIT, "--record", ",".join(RECORD), "--json", "--no-plot", "--out", str(tmp_path)]
    assert main(argv) == 1
    captured = capsys.readouterr()
    assert "cross-check failed" in captured.err
    out = json.loads(captured.out)
    assert out["check_failures"]
    header, data = _read_csv(Path(out["csv"]))
    assert header == ["time", *STATE_NAMES, *CONTROL_NAMES, *RECORD]
    assert out["recorded"] == header[1:]
    col = dict(zip(header, data.T))
    xplus = np.column_stack([col[s] for s in STATE_NAMES]) / [U_M_PER_S, N_HZ, N_HZ, 1.0]
    free = xplus @ K_TEST.T
    u = np.column_stack([col[c] for c in CONTROL_NAMES])
    assert_allclose(u, np.clip(free, -U_MAX, U_MAX), rtol=1e-12, atol=1e-15)
    saturated = np.any(np.abs(free) > U_MAX, axis=1)
    assert 0 < saturated.sum() < len(saturated)  # limited for a while, not throughout
    assert np.array_equal(col["controller.saturated"], saturated.astype(float))
    assert np.array_equal(col["plant.delta_Phi_a"], col["delta_Phi_a"])  # the input as set
    assert np.all(col["controller.K[1,2]"] == K_TEST[0, 1]) and np.all(col["plant.n"] == N_HZ)


def test_python_values_are_typed_as_on_the_command_line(fmus):
    """cosimulate(set_values=): 1, True and "1" are the same Boolean (same run bit for bit),
    and the limit holds; what a Boolean cannot take is refused, one line naming it."""
    runs = [cosimulate(*fmus, gains=K_TEST, x0=(0, 0.1, 0, 0.1), stop_wingbeats=5,
                       out_dir=None,
                       set_values={"controller.limit_enabled": v, "controller.u_max": U_MAX})
            for v in (1, True, "1")]
    for r in runs[1:]:
        assert np.array_equal(r.run.signals, runs[0].run.signals)
    u = runs[0].run.column("delta_Phi_a")
    assert np.max(np.abs(u)) == U_MAX
    for bad in ("maybe", 2, 0.5):
        with pytest.raises(DroneflyError) as e:
            cosimulate(*fmus, stop_wingbeats=5, out_dir=None,
                       set_values={"controller.limit_enabled": bad})
        assert str(e.value) == (f"controller.limit_enabled = {bad!r}: a Boolean takes true, "
                                "false, 1 or 0")


@pytest.mark.parametrize("args, line", [
    (["--set", "controller.limit_enabled=maybe"],
     "controller.limit_enabled = 'maybe': a Boolean takes true, false, 1 or 0"),
    (["--set", "controller.u_max=abc"], "controller.u_max = 'abc' is not a number (a Real)"),
    (["--record", "plant.nope"], "cannot record 'plant.nope': plant has no variable 'nope'"),
    (["--record", "controller.K"], "cannot record 'controller.K': controller has no variable 'K'"),
])
def test_pair_bad_set_or_record_is_one_line_exit_2(fmus, tmp_path, capsys, args, line):
    out = tmp_path / "o"
    argv = ["cosim", "--plant", str(fmus[0]), "--controller", str(fmus[1]), "--stop", "5",
            "--no-plot", "--out", str(out), *args]
    assert main(argv) == 2
    assert capsys.readouterr().err == f"dronefly cosim: error: {line}\n"
    assert not out.exists(), "nothing written"


def test_version(capsys):
    assert main(["--version"]) == 0
    assert capsys.readouterr().out.strip() == f"dronefly {__version__}"


def test_a_bug_is_not_reported_as_bad_input(monkeypatch, capsys):
    def broken(args):
        raise RuntimeError("boom")

    monkeypatch.setattr(demo_command, "run", broken)
    assert main(["demo"]) == 1
    err = capsys.readouterr().err
    assert "internal error (a bug" in err and "RuntimeError: boom" in err and "Traceback" not in err
    assert main(["--debug", "demo"]) == 1
    assert "Traceback" in capsys.readouterr().err


def test_bad_input_is_one_line_exit_2(monkeypatch, capsys):
    def bad(args):
        raise DroneflyError("x = 'y' is not a number\nsecond line")

    monkeypatch.setattr(demo_command, "run", bad)
    assert main(["demo"]) == 2
    err = capsys.readouterr().err
    assert err == "dronefly demo: error: x = 'y' is not a number\n"


def test_an_option_that_needs_a_missing_extra_is_refused_and_writes_nothing(monkeypatch, capsys,
                                                                             tmp_path):
    """--scheduler asks for Dask: without it, one line naming the extra, exit 2. (A feature that
    is on by default is skipped instead: tests/test_core_install.py.)"""
    monkeypatch.setitem(sys.modules, "distributed", None)  # import fails as if not installed
    out = tmp_path / "out"
    assert main(["sweep", "--scheduler", "tcp://127.0.0.1:1", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "dronefly-fmu[sweep]" in err and "distributed" in err
    assert not out.exists()
