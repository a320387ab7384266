"""`dronefly check` on the user's path: options refused before the work, a selection that does
not apply, Ctrl-C within one FMU's check, and no temporary folder left at any end."""

from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path

import pytest

from dronefly.cli.app import main
from dronefly.harness.compliance import suite
from dronefly.harness.compliance.checker import CheckOptions
from fmu_helpers import build_crashing_fmu, build_hanging_fmu
from sigint_at import install_at_check

ROOT = Path(__file__).resolve().parents[1]
REF = ROOT.parent / "shared" / "reference-fmus"
pytestmark = pytest.mark.skipif(not REF.is_dir(), reason=f"the Reference-FMUs are not beside "
                                                         f"the checkout ({REF})")
DAHLQUIST2 = str(REF / "fmi2" / "Dahlquist.fmu")
DAHLQUIST3 = str(REF / "fmi3" / "Dahlquist.fmu")


@pytest.fixture
def no_work(monkeypatch):
    """check_fmus that fails the test if called: the refusal came before the work."""

    def called(*args, **kwargs):
        raise AssertionError("the checks ran before the option was refused")

    monkeypatch.setattr("dronefly.cli.commands.check.check_fmus", called)


@pytest.mark.parametrize("argv, message", [
    (["--check", "reset", "--skip", "reset"], "--check reset with --skip reset: selects no check"),
    (["--no-fuzz", "--check", "fuzz"], "--check fuzz cannot take effect with --no-fuzz"),
    (["--stop-time", "0.001", "--step", "0.01"],
     "--stop-time 0.001 --step 0.01: the step is longer than the run"),
    (["--step", "100"], "step 100.0 s is longer than the run from 0.0 s to 10.0 s"),
    (["--junit", "nodir/x.xml"], "--junit 'nodir/x.xml': the folder 'nodir' does not exist"),
])
def test_bad_options_are_refused_before_any_check(no_work, capsys, tmp_path, monkeypatch,
                                                  argv, message):
    monkeypatch.chdir(tmp_path)
    assert main(["check", *argv, DAHLQUIST2]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1, err
    assert not (tmp_path / "nodir").exists()


@pytest.mark.parametrize("fmu, argv, detail", [
    (DAHLQUIST2, ["--check", "state-machine"],
     "not applicable: state-machine is an FMI 3.0 check; this FMU is FMI 2.0"),
    (DAHLQUIST2, ["--check", "fuzz"],
     "not applicable: fuzz is the dronefly profile's check (--profile dronefly runs it); this "
     "FMU is checked under the standard profile"),
    (DAHLQUIST3, ["--check", "discard"],
     "not applicable: discard is the dronefly profile's check (--profile dronefly runs it); this "
     "FMU is checked under the standard profile"),
    (DAHLQUIST3, ["--check", "state-refusal"],
     "not applicable: state-refusal is the dronefly profile's check (--profile dronefly runs "
     "it); this FMU is checked under the standard profile"),
])
def test_a_selected_check_that_does_not_apply_is_skipped_with_its_reason(capsys, fmu, argv,
                                                                          detail):
    """FMI 2.0 and 3.0 alike: a check selected by name that does not apply to the FMU is
    `[skip]` with the reason, the FMU passes (exit 0), never `FAIL` with no check."""
    assert main(["check", *argv, fmu]) == 0
    out = capsys.readouterr().out
    name = argv[1]
    assert f"  [skip] {name:<14} {detail}" in out, out
    assert out.splitlines()[-1] == "1 of 1 FMUs passed"


@pytest.fixture(scope="module")
def hanging(tmp_path_factory) -> Path:
    return build_hanging_fmu(tmp_path_factory.mktemp("hanging"))


@pytest.fixture
def private_tmp(tmp_path, monkeypatch) -> Path:
    """TMPDIR (this process's and its children's) in a fresh folder, to see what is left."""
    folder = tmp_path / "tmp"
    folder.mkdir()
    monkeypatch.setenv("TMPDIR", str(folder))
    monkeypatch.setattr(tempfile, "tempdir", str(folder))
    return folder


def test_ctrl_c_stops_within_one_fmus_check(hanging, private_tmp, tmp_path, capsys,
                                            monkeypatch, sigint_as_in_a_terminal):
    """SIGINT at a known point (tests/sigint_at.py: the 3rd time check asks whether Ctrl-C
    came: while the first of several FMUs, one whose step never returns, is being checked):
    exit 130 within one poll of that FMU's checking process, not after its 600 s timeout nor
    after the other FMUs; no JUnit file; no temporary folder left."""
    install_at_check(monkeypatch, 3)
    junit = tmp_path / "check.xml"
    t0 = time.monotonic()
    code = main(["check", "--no-fuzz", "--skip", "validate", "--junit", str(junit),
                 str(hanging), DAHLQUIST2, DAHLQUIST3])
    elapsed = time.monotonic() - t0
    assert code == 130
    err = capsys.readouterr().err
    assert "0 of 3 FMUs checked when interrupted" in err and "not written" in err
    assert err.strip().splitlines()[-1] == "dronefly check: interrupted"
    assert elapsed < 60, elapsed  # the hanging step would hold it 600 s
    assert not junit.exists() and not list(tmp_path.glob("*.part"))
    assert list(private_tmp.iterdir()) == []


def test_ctrl_c_keeps_the_finished_fmus(private_tmp, tmp_path, capsys, monkeypatch,
                                        sigint_as_in_a_terminal):
    """With -j 1 and Ctrl-C while the second FMU is checked (its first poll), the first
    FMU's report is shown, exit 130, no JUnit."""
    reads = {"n": 0}
    real = suite.check_fmu

    def second_interrupted(path, **kwargs):
        reads["n"] += 1
        if reads["n"] == 2:
            os.kill(os.getpid(), __import__("signal").SIGINT)
        return real(path, **kwargs)

    monkeypatch.setattr(suite, "check_fmu", second_interrupted)
    junit = tmp_path / "check.xml"
    assert main(["check", "--no-fuzz", "--junit", str(junit), DAHLQUIST2, DAHLQUIST3]) == 130
    cap = capsys.readouterr()
    assert f"{DAHLQUIST2}: PASS" in cap.out and DAHLQUIST3 not in cap.out
    assert "1 of 2 FMUs checked when interrupted" in cap.err
    assert not junit.exists()
    assert list(private_tmp.iterdir()) == []


@pytest.mark.parametrize("case", ["passed", "failed", "crashed", "timed out"])
def test_no_temporary_folder_survives(hanging, private_tmp, tmp_path, case):
    """The checking process's temporary files (the extracted FMU, pythonfmu's) are removed
    whatever the end: success, a failed check, a crash of the FMU, the timeout."""
    if case == "crashed":
        fmu = build_crashing_fmu(tmp_path)
    elif case == "timed out":
        fmu = hanging
    else:
        fmu = Path(DAHLQUIST2)
    options = CheckOptions(stop_time=1.0, step=2.0) if case == "failed" else CheckOptions()
    report = suite.check_fmu(fmu, fuzz=case != "timed out", options=options,
                             timeout_s=3.0 if case == "timed out" else 120.0)
    assert report.passed == (case == "passed"), report.checks
    assert list(private_tmp.iterdir()) == [], case


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="/proc and pgrep: Linux")
def test_sigterm_stops_the_checking_process_and_removes_its_folder(hanging, tmp_path):
    """SIGTERM to `dronefly check` (a CI job's timeout) while an FMU's step hangs: exit 143,
    neither the checking process nor the fork server it came from outlives it, and no
    temporary folder is left."""
    import signal
    import subprocess

    folder = tmp_path / "tmp"
    folder.mkdir()
    env = {**os.environ, "TMPDIR": str(folder)}
    proc = subprocess.Popen([sys.executable, "-m", "dronefly", "check", "--no-fuzz", "--skip",
                             "validate", str(hanging)], env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    rows = None
    while time.monotonic() < deadline:  # until the checking process is in the hanging step
        rows = next(folder.glob("dronefly_check_*/checks.jsonl"), None)
        if rows is not None and "fmi2DoStep(currentCommunicationPoint=0.05" in rows.read_text():
            break
        time.sleep(0.1)
    else:
        proc.kill()
        pytest.fail(f"the check did not reach the hanging step: {proc.communicate()}")
    def children_of(pid: int | str) -> list[str]:
        return subprocess.run(["pgrep", "-P", str(pid)], capture_output=True,
                              text=True).stdout.split()

    # the checking process: forked by the fork server, the child of dronefly check
    servers = children_of(proc.pid)
    children = servers + [c for s in servers for c in children_of(s)]
    assert len(children) >= 2, children
    proc.send_signal(signal.SIGTERM)
    assert proc.wait(timeout=60) == 143
    for _ in range(50):  # the child is killed with its parent
        if not any(Path(f"/proc/{pid}").exists() for pid in children):
            break
        time.sleep(0.1)
    assert not any(Path(f"/proc/{pid}").exists() for pid in children), children
    assert list(folder.iterdir()) == []
