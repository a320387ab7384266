"""``dronefly sweep``: cases, backends (in-process, process pool, Dask), resume, failures, CLI."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.linalg import expm

from dronefly.harness.sweep.run import COLUMNS, SweepSettings, read_rows, run_sweep
from dronefly.harness.sweep.cases import (STATE_BOUNDS_SECT36, Case, SweepInputError, SweepSpec,
    gain_matrix)
from dronefly.models.lateral_dynamics import default_parameters, system_matrices

pytestmark = pytest.mark.integration

SMALL = SweepSpec(slices=(("dgamma", "dp"),), grid_points=3, amplitudes=2,
                  directions=("+dp", "-mode1"), gains=("paper", "open"), steps_wb=(1.0, 3.0),
                  stop_wb=30.0)


@pytest.fixture(scope="module")
def fmus(built_fmus: dict[str, Path]) -> dict[str, Path]:
    return {"plant": built_fmus["DroneFlyLateral"], "controller": built_fmus["StateFeedback"]}


@pytest.fixture(scope="module")
def reference(fmus: dict[str, Path], tmp_path_factory: pytest.TempPathFactory):
    """The small sweep, uninterrupted, in this process."""
    return run_sweep(SMALL, tmp_path_factory.mktemp("ref"), workers=1, progress_bar=False, **fmus)


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file()}


def test_cases_are_deterministic_and_cover_the_box() -> None:
    a, b = SMALL.cases(), SMALL.cases()
    assert [c.key for c in a] == [c.key for c in b]
    assert [c.case for c in a] == list(range(len(a)))
    # 2 gain sets x 2 steps x (3x3 grid + 2 directions x 2 amplitudes)
    assert len(a) == 2 * 2 * (9 + 4)
    box = np.array(STATE_BOUNDS_SECT36)
    grid = np.array([c.x0 for c in a if c.family == "grid"])
    assert np.allclose(np.abs(grid).max(axis=0), [0, box[1], 0, box[3]])
    ones = [c for c in a if c.family == "direction" and c.amplitude == 1.0]
    assert all(math.isclose(np.max(np.abs(c.x0) / box), 1.0) for c in ones)
    lhs = SweepSpec(disturbances=("lhs",), lhs_points=50, seed=3).initial_states()
    u = np.array([x for *_, x in lhs]) / box
    assert np.all(np.abs(u) <= 1.0)
    for j in range(4):  # a Latin hypercube: one sample per stratum in every dimension
        assert sorted(np.floor((u[:, j] + 1.0) / 2.0 * 50).astype(int)) == list(range(50))
    K = gain_matrix("stabilising")
    A, B = system_matrices(default_parameters())
    assert np.max(np.linalg.eigvals(A + B @ K).real) < -0.05


def test_rows_verdicts_and_summary(reference) -> None:
    rows = reference.rows
    assert [int(r["case"]) for r in rows] == list(range(len(SMALL.cases())))
    assert list(rows[0]) == COLUMNS
    assert read_rows(reference.csv) == rows
    box = np.array(STATE_BOUNDS_SECT36)
    for r in rows:
        start = np.max(np.abs([float(r[f"x0_{a}"]) for a in ("dv", "dp", "dr", "dgamma")]) / box)
        assert float(r["peak"]) >= start - 1e-12
        within = r["verdict"] == "within"
        assert within == (float(r["peak"]) <= 1.0 + 1e-9)
        assert within == (r["t_exit_wb"] == "")
    opened = [r for r in rows if r["gains"] == "open" and r["x0_dp"] != "0.0"]
    assert opened and all(r["verdict"].startswith("left ") for r in opened)
    assert any(r["verdict"] == "within" for r in rows if r["gains"] == "paper")
    s = json.loads(reference.json.read_text())
    for key in ("cases", "within_bounds", "fraction_within_bounds", "elapsed_s", "workers",
                "largest_amplitude_within_bounds"):
        assert key in s
    assert s["cases"] == len(rows) and s["errors"] == 0
    assert s["within_bounds"] == sum(r["verdict"] == "within" for r in rows)
    assert {(a["gains"], a["direction"]) for a in s["largest_amplitude_within_bounds"]} == \
        {(g, d) for g in SMALL.gains for d in SMALL.directions}
    assert [m.name for m in reference.maps] == ["map_dgamma_dp.png"]
    assert not list(reference.csv.parent.glob("*.part"))


def test_process_pool_gives_the_same_rows(fmus, reference, tmp_path: Path) -> None:
    r = run_sweep(SMALL, tmp_path, workers=2, plot=False, progress_bar=False, chunk_steps=100,
                  **fmus)
    assert r.summary["backend"] == "processes" and r.summary["workers"] == 2
    assert r.csv.read_text() == reference.csv.read_text()


def test_dask_local_cluster_gives_the_same_rows(fmus, reference, tmp_path: Path) -> None:
    import distributed  # the test extra installs it: a broken install fails
    with distributed.LocalCluster(n_workers=2, processes=True, threads_per_worker=1,
                                  dashboard_address=":0") as cluster:  # a free port
        r = run_sweep(SMALL, tmp_path, scheduler=cluster.scheduler_address, plot=False,
                      progress_bar=False, chunk_steps=100, **fmus)
    assert r.summary["backend"] == "dask" and r.summary["workers"] == 2
    assert r.rows == reference.rows
    assert r.csv.read_text() == reference.csv.read_text()


def test_interrupted_sweep_resumes_to_the_same_csv(fmus, reference, tmp_path: Path) -> None:
    chunks = []

    def stop_after_two(done: int, total: int) -> None:
        chunks.append(done)
        if len(chunks) == 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_sweep(SMALL, tmp_path, workers=1, plot=False, progress_bar=False, chunk_steps=60,
                  on_chunk=stop_after_two, flush_s=1e9, **fmus)
    partial = read_rows(tmp_path / "sweep.csv")  # flushed on the way out, complete rows only
    ref = {r["case"]: r for r in reference.rows}
    assert 0 < len(partial) < len(reference.rows)
    assert all(ref[r["case"]] == r for r in partial)
    assert not (tmp_path / "sweep.json").exists() and not list(tmp_path.glob("*.part"))
    r = run_sweep(SMALL, tmp_path, workers=2, progress_bar=False, chunk_steps=60, **fmus)
    assert r.summary["resumed_cases"] > 0
    assert r.summary["computed_cases"] + r.summary["resumed_cases"] == len({c.key for c in
                                                                           SMALL.cases()})
    assert r.csv.read_text() == reference.csv.read_text()
    again = run_sweep(SMALL, tmp_path, workers=1, plot=False, progress_bar=False, **fmus)
    assert again.summary["computed_cases"] == 0  # nothing redone
    assert again.csv.read_text() == reference.csv.read_text()


def test_settings_object_and_keywords_give_the_same_rows(fmus, reference, tmp_path: Path) -> None:
    """``run_sweep(spec, out, settings, **options)``: the options replace the settings' fields;
    an option that is not a field is a TypeError, before anything is written."""
    settings = SweepSettings(workers=2, plot=True, progress_bar=False, **fmus)
    r = run_sweep(SMALL, tmp_path / "a", settings, workers=1, plot=False)
    assert r.rows == reference.rows and r.summary["workers"] == 1 and r.maps == []
    with pytest.raises(SweepInputError, match="--compare needs --system"):
        run_sweep(SMALL, tmp_path / "b", settings, compare="other.ssp")
    with pytest.raises(TypeError, match="worker"):
        run_sweep(SMALL, tmp_path / "c", worker=1)
    assert not (tmp_path / "b").exists() and not (tmp_path / "c").exists()


def test_failed_case_is_recorded_and_the_sweep_goes_on(fmus, tmp_path: Path) -> None:
    K = gain_matrix("paper")
    huge = K.copy()
    huge[0, 3] = 1e308  # u = K x+ overflows: the controller refuses the step
    cases = [Case(0, "custom", "", math.nan, (0.0, 0.0, 0.0, 10.0), "huge",
                  tuple(map(tuple, huge)), 1.0, 1.0, 10.0),
             Case(1, "custom", "", math.nan, (0.0, 0.0, 0.0, 0.1), "paper",
                  tuple(map(tuple, K)), 1.0, 1.0, 10.0)]
    r = run_sweep(None, tmp_path, cases=cases, workers=1, plot=False, progress_bar=False, **fmus)
    assert r.rows[0]["verdict"] == "error" and "StateFeedback" in r.rows[0]["error"]
    assert r.rows[1]["verdict"] == "within" and r.rows[1]["error"] == ""
    assert r.summary["errors"] == 1


def test_output_folder_of_another_sweep_is_refused(fmus, reference, tmp_path: Path) -> None:
    (tmp_path / "sweep.csv").write_bytes(reference.csv.read_bytes())
    other = SweepSpec(disturbances=("directions",), directions=("+dv",), amplitudes=1,
                      steps_wb=(1.0,), stop_wb=10.0)
    before = _snapshot(tmp_path)
    with pytest.raises(SweepInputError, match="not in this sweep"):
        run_sweep(other, tmp_path, workers=1, plot=False, progress_bar=False, **fmus)
    assert _snapshot(tmp_path) == before
    r = run_sweep(other, tmp_path, workers=1, plot=False, progress_bar=False, fresh=True, **fmus)
    assert len(read_rows(r.csv)) == 2


def test_cli_sweep(fmus, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from dronefly.cli.app import main

    out = tmp_path / "sw"
    code = main(["sweep", "--plant", str(fmus["plant"]), "--controller", str(fmus["controller"]),
                 "--out", str(out), "--slices", "dgamma:dv", "--grid", "3", "--directions",
                 "+dgamma", "--amplitudes", "2", "--gains", "paper", "--steps", "1",
                 "--stop", "20", "--workers", "1", "--no-progress"])
    text = capsys.readouterr().out
    assert code == 0, text
    assert "within bounds:" in text and "map: " in text
    assert {p.name for p in out.iterdir()} == {"sweep.csv", "sweep.json", "map_dgamma_dv.png"}
    # the oracle: the sampled-data loop of Eq. (9)'s A, B and Eq. (27) in closed form (the
    # plant's zero-order-hold map from scipy's expm, the control held over each 1-wing-beat
    # step from the state at its start): each case's peak over the bounds and its final state
    # (round-off of 20 products of matrices of order 1: 1e-12)
    A, B = system_matrices(default_parameters())
    M = expm(np.block([[A, B], [np.zeros((3, 7))]]))
    phi, gamma, K = M[:4, :4], M[:4, 4:], gain_matrix("paper")
    box = np.array(STATE_BOUNDS_SECT36)
    rows = read_rows(out / "sweep.csv")
    assert len(rows) == 3 * 3 + 2
    for r in rows:
        x = np.array([float(r[f"x0_{a}"]) for a in ("dv", "dp", "dr", "dgamma")])
        peak = np.max(np.abs(x) / box)
        for _ in range(20):
            x = phi @ x + gamma @ (K @ x)
            peak = max(peak, np.max(np.abs(x) / box))
        assert float(r["peak"]) == pytest.approx(peak, rel=1e-12, abs=1e-15), r["case"]
        assert (r["verdict"] == "within") == (peak <= 1.0)
        final = [float(r[f"final_{a}"]) for a in ("dv", "dp", "dr", "dgamma")]
        np.testing.assert_allclose(final, x, rtol=1e-10, atol=1e-15)


@pytest.mark.parametrize("args, named", [
    (["--steps", ""], "steps"),
    (["--steps", "0.1,nan"], "nan"),
    (["--scales", "inf"], "inf"),
    (["--stop", "-5"], "stop"),
    (["--gains", "paper,bogus"], "bogus"),
    (["--grid", "1"], "grid"),
    (["--slices", "dgamma:dgamma"], "dgamma:dgamma"),
    (["--directions", "+roll"], "+roll"),
    (["--workers", "zero"], "workers"),
    (["--scheduler", "tcp://127.0.0.1:1", "--connect-timeout", "0.5"], "tcp://127.0.0.1:1"),
    (["--grid", "100000"], "exceed the limit of 200000"),
    (["--disturbances", "lhs", "--lhs", "100000000"], "exceed the limit of 200000"),
    (["--set", "plant.nope=1"], "plant has no variable 'nope'"),
    (["--set", "controller.limit_enabled=maybe"], "'maybe': a Boolean takes true, false, 1 or 0"),
    (["--set", "plant.Lv_plus=abc"], "plant.Lv_plus = 'abc' is not a number"),
    (["--gains", "paper,missing.json"], "gains file 'missing.json'"),
])
def test_cli_bad_input(fmus, tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str],
                       named: str) -> None:
    from dronefly.cli.app import main

    out = tmp_path / "out"
    out.mkdir()
    (out / "keep.txt").write_text("untouched\n")
    before = _snapshot(tmp_path)
    code = main(["sweep", "--plant", str(fmus["plant"]), "--controller", str(fmus["controller"]),
                 "--out", str(out), "--no-progress", *args])
    err = capsys.readouterr().err
    assert code == 2
    assert len(err.strip().splitlines()) == 1 and err.startswith("dronefly sweep: error:")
    assert named in err
    assert _snapshot(tmp_path) == before


def test_summary_accounts_for_every_case(fmus, tmp_path):
    """cases = run + resumed + identical to another case (the default grid and directions
    overlap where a direction point is also a grid point)."""
    spec = SweepSpec(disturbances=("grid", "directions"), slices=(("dgamma", "dv"),),
                     grid_points=3, directions=("+dgamma", "-dgamma"), amplitudes=1,
                     gains=("open",), steps_wb=(1.0,), stop_wb=2.0)
    r = run_sweep(spec, tmp_path, workers=1, plot=False, progress_bar=False, **fmus)
    s = r.summary
    assert s["duplicate_cases"] > 0
    assert s["cases"] == s["computed_cases"] + s["resumed_cases"] + s["duplicate_cases"]
    from dronefly.harness.sweep.results import format_summary

    assert f"{s['duplicate_cases']} identical to another case" in format_summary(s)
