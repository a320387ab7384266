"""SIGINT deferred to the master's next check between steps."""

from __future__ import annotations

import importlib
import json
import os
import signal
from pathlib import Path

import pytest

from dronefly.core.interrupt import deferred_sigint


def test_sigint_sets_a_flag_instead_of_raising(sigint_as_in_a_terminal):
    with deferred_sigint() as stop:
        assert not stop.requested
        os.kill(os.getpid(), signal.SIGINT)
        signal.getsignal(signal.SIGINT)  # bytecodes run: the handler has been called
        assert stop.requested
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_third_sigint_raises(sigint_as_in_a_terminal):
    with pytest.raises(KeyboardInterrupt):
        with deferred_sigint():
            for _ in range(3):
                os.kill(os.getpid(), signal.SIGINT)
                signal.getsignal(signal.SIGINT)


@pytest.mark.integration
@pytest.mark.parametrize("argv", [
    ["cosim", "--stop", "500000", "--no-plot", "--step", "0.5"],
    ["sweep", "--workers", "1", "--no-progress", "--no-plot", "--grid", "5", "--stop", "2000",
     "--disturbances", "grid", "--slices", "dgamma:dv"],
])
def test_ctrl_c_during_an_in_process_run_stops_cleanly(built_fmus, tmp_path, argv):
    """SIGINT in the middle of a run (delivered at a known point, see tests/sigint_at.py):
    exit 130 with one line, no crash; the sweep keeps the cases it finished."""
    import subprocess
    import sys

    out = tmp_path / "out"
    build = tmp_path / "fmus"
    build.mkdir()
    for name in ("DroneFlyLateral", "StateFeedback"):
        (build / f"{name}.fmu").write_bytes(built_fmus[name].read_bytes())
    extra = ["--plant", str(build / "DroneFlyLateral.fmu"), "--controller",
             str(build / "StateFeedback.fmu"), "--out", str(out)]
    for _ in range(2):  # twice: the first and a later run in the same folder
        proc = subprocess.run([sys.executable, str(Path(__file__).with_name("sigint_at.py")),
                               *argv, *extra],
                              capture_output=True, text=True, timeout=300)
        assert proc.returncode == 130, (proc.returncode, proc.stderr[-400:])
        assert proc.stderr.strip().splitlines()[-1].endswith("interrupted"), proc.stderr
    if argv[0] == "sweep":  # the finished cases were written before the exit
        assert len((out / "sweep.csv").read_text().splitlines()) > 1



# --- every command stops within one step or one sweep chunk ----------------------------------
_SWEEP = ["sweep", "--grid", "15", "--slices", "dgamma:dp", "--disturbances", "grid", "--steps",
          "0.1", "--gains", "paper", "--stop", "20", "--no-plot", "--no-progress"]


def _copy_pair(built_fmus, folder: Path) -> list[str]:
    folder.mkdir()
    for name in ("DroneFlyLateral", "StateFeedback"):
        (folder / f"{name}.fmu").write_bytes(built_fmus[name].read_bytes())
    return ["--plant", str(folder / "DroneFlyLateral.fmu"),
            "--controller", str(folder / "StateFeedback.fmu")]


def _dronefly(*argv: str, script: str | None = None):
    import subprocess
    import sys

    head = [str(Path(__file__).with_name(script))] if script else ["-m", "dronefly"]
    return subprocess.run([sys.executable, *head, *argv], capture_output=True, text=True,
                          timeout=300)


@pytest.fixture(scope="module")
def sweep_reference(built_fmus, tmp_path_factory):
    """(--plant/--controller options, sweep.csv bytes) of the small sweep, uninterrupted, in
    one process."""
    folder = tmp_path_factory.mktemp("sweep_reference")
    pair = _copy_pair(built_fmus, folder / "fmus")
    r = _dronefly(*_SWEEP, *pair, "--workers", "1", "--out", str(folder / "out"))
    assert r.returncode == 0, r.stderr[-800:]
    return pair, (folder / "out" / "sweep.csv").read_bytes()


@pytest.fixture(scope="module")
def dask_scheduler():
    import distributed  # the test extra installs the sweep extra (dask): a broken install fails
    with distributed.LocalCluster(n_workers=2, processes=True, threads_per_worker=1,
                                  dashboard_address=":0") as cluster:
        yield cluster.scheduler_address


@pytest.mark.integration
@pytest.mark.parametrize("backend", ["pool", "dask"])
def test_ctrl_c_stops_a_parallel_sweep_within_a_chunk_and_a_rerun_resumes_it(
        sweep_reference, tmp_path, backend, request):
    """SIGINT once the first chunk is collected (tests/sigint_at.py): exit 130 with the
    finished cases in sweep.csv and no sweep.json, at most one more chunk per worker done
    (the pool's workers end their chunks before the next case; Dask's are cancelled), and the
    rerun that resumes writes the same sweep.csv, byte for byte, as an uninterrupted run."""
    from dronefly.harness.sweep.backends import chunk_cases
    from dronefly.harness.sweep.cases import SweepSpec

    pair, reference = sweep_reference
    where = (["--workers", "2"] if backend == "pool"
             else ["--scheduler", request.getfixturevalue("dask_scheduler")])
    out = tmp_path / "out"
    proc = _dronefly(*_SWEEP, *pair, *where, "--out", str(out), script="sigint_at.py")
    assert proc.returncode == 130, (proc.returncode, proc.stderr[-800:])
    assert proc.stderr.strip().splitlines()[-1] == "dronefly sweep: interrupted"
    cases = SweepSpec(disturbances=("grid",), slices=(("dgamma", "dp"),), grid_points=15,
                      gains=("paper",), steps_wb=(0.1,), stop_wb=20.0).cases()
    chunks = chunk_cases(cases, 2, None)
    assert len(chunks) >= 8  # so that "within one chunk" is a bound that can fail
    done = len((out / "sweep.csv").read_text().splitlines()) - 1
    assert len(chunks[0]) <= done <= 3 * max(map(len, chunks)), (done, len(cases))
    assert not (out / "sweep.json").exists() and not list(out.glob("*.part"))
    assert (out / "sweep.csv").read_bytes() != reference
    r = _dronefly(*_SWEEP, *pair, *where, "--out", str(out))
    assert r.returncode == 0, r.stderr[-800:]
    summary = json.loads((out / "sweep.json").read_text())
    assert summary["resumed_cases"] == done and summary["computed_cases"] == len(cases) - done
    assert (out / "sweep.csv").read_bytes() == reference


def _record_ctrl_c(monkeypatch, count) -> list[int]:
    """The value of ``count()`` when tests/sigint_at.py sends SIGINT (appended to the list)."""
    import sigint_at

    sent: list[int] = []
    send = sigint_at._ctrl_c

    def ctrl_c() -> None:
        sent.append(count())
        send()

    monkeypatch.setattr(sigint_at, "_ctrl_c", ctrl_c)
    return sent


@pytest.mark.integration
def test_ctrl_c_stops_simulate_within_a_step_and_writes_no_csv(
        built_fmus, tmp_path, monkeypatch, sigint_as_in_a_terminal, capsys):
    """SIGINT at the 50th check between steps of a 990,000-step run: exit 130 after the step
    it arrived in, and no result CSV (it would claim a run that did not happen)."""
    from dronefly.cli.app import main
    from sigint_at import install_at_check

    simulate = importlib.import_module("dronefly.harness.stability.simulate")
    out = tmp_path / "out"
    out.mkdir()
    (out / "DroneFlyLateral.fmu").write_bytes(built_fmus["DroneFlyLateral"].read_bytes())
    steps = [0]
    simulate_fmu = simulate.fmpy.simulate_fmu

    def counted(*args, step_finished=None, **kwargs):
        def finished(time, recorder):
            steps[0] += 1
            return True if step_finished is None else step_finished(time, recorder)

        return simulate_fmu(*args, step_finished=finished, **kwargs)

    monkeypatch.setattr(simulate.fmpy, "simulate_fmu", counted)
    sent = _record_ctrl_c(monkeypatch, lambda: steps[0])
    install_at_check(monkeypatch, 50)
    assert main(["simulate", "--stop", "99000", "--out", str(out)]) == 130
    assert len(sent) == 1 and steps[0] - sent[0] <= 1, (sent, steps)
    assert sorted(p.name for p in out.iterdir()) == ["DroneFlyLateral.fmu"]
    assert capsys.readouterr().err.strip() == "dronefly simulate: interrupted"


@pytest.mark.integration
def test_ctrl_c_stops_floquet_within_a_step_and_prints_no_result(
        built_fmus, tmp_path, monkeypatch, sigint_as_in_a_terminal, capsys):
    """SIGINT at the 20th check between steps (44 one-period evaluations make the result):
    exit 130 with at most the step it arrived in done after it, nothing printed on stdout."""
    from dronefly.cli.app import main
    from sigint_at import install_at_check

    fmi_floquet = importlib.import_module("dronefly.harness.flapping.fmi_floquet")
    steps = [0]

    class Counting(fmi_floquet.FmiPeriodicMap):
        def __call__(self, x):
            slave = self._inst.slave
            do_step = slave.doStep

            def counted(*a, **k):
                steps[0] += 1
                return do_step(*a, **k)

            slave.doStep = counted
            try:
                return super().__call__(x)
            finally:
                del slave.doStep

    monkeypatch.setattr(fmi_floquet, "FmiPeriodicMap", Counting)
    sent = _record_ctrl_c(monkeypatch, lambda: steps[0])
    install_at_check(monkeypatch, 20)
    plant = tmp_path / "DroneFlyFlapping.fmu"
    plant.write_bytes(built_fmus["DroneFlyFlapping"].read_bytes())
    assert main(["floquet", "--plant", str(plant)]) == 130
    assert len(sent) == 1 and steps[0] - sent[0] <= 1 and steps[0] < 44, (sent, steps)
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err.strip() == "dronefly floquet: interrupted"


@pytest.mark.parametrize("command", ["analyze", "aero"])
def test_ctrl_c_stops_a_command_that_runs_no_fmu_at_once(
        tmp_path, monkeypatch, sigint_as_in_a_terminal, capsys, command):
    """analyze and aero run no FMU: SIGINT raises where it lands (nothing to protect), so the
    command stops there: exit 130, no report printed, no --out file."""
    from dronefly.cli.app import main
    from dronefly.cli.commands import aero, analyze

    def ctrl_c_then(fn):
        def wrapped(*args, **kwargs):
            os.kill(os.getpid(), signal.SIGINT)
            for _ in range(1000):  # the handler runs at the next bytecode
                signal.getsignal(signal.SIGINT)
            return fn(*args, **kwargs)

        return wrapped

    if command == "analyze":
        monkeypatch.setattr(analyze, "analyze", ctrl_c_then(analyze.analyze))
        out = tmp_path / "report.md"
        assert main(["analyze", "--out", str(out)]) == 130
        assert not out.exists() and not list(tmp_path.iterdir())
    else:
        monkeypatch.setattr(aero, "parity_report", ctrl_c_then(aero.parity_report))
        assert main(["aero"]) == 130
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err.strip() == f"dronefly {command}: interrupted"
