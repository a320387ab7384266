"""`dronefly check`: passes on the project's FMUs, fails with a clear report on broken ones."""

from __future__ import annotations

import zipfile
from pathlib import Path

import pytest

from dronefly.harness.builder.build import FMUS
from dronefly.cli.app import main
from dronefly.harness.compliance.checker import CheckOptions
from dronefly.harness.compliance.suite import check_fmu, format_reports
from dronefly.models.lateral_interface import N_HZ
from fmu_helpers import build_crashing_fmu, build_hanging_fmu

pytestmark = pytest.mark.integration


def _status(report) -> dict[str, bool]:
    return {c.name: c.passed for c in report.checks}


@pytest.mark.parametrize("model", list(FMUS))
def test_project_fmus_pass(built_fmus, model):
    """Every FMU of the project. The fuzz itself is tested in test_reliability.py (on every
    FMU); here once, on the controller."""
    report = check_fmu(built_fmus[model], fuzz=model == "StateFeedback")
    assert report.passed, report.checks
    assert ("fuzz" in {c.name for c in report.checks}) == (model == "StateFeedback")


def _rewrite_md(src: Path, dst: Path, old: bytes, new: bytes) -> Path:
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w") as zout:
        for item in zin.infolist():
            data = zin.read(item.filename)
            if item.filename == "modelDescription.xml":
                assert old in data
                data = data.replace(old, new)
            zout.writestr(item, data)
    return dst


def test_broken_model_description_fails_validate(built_fmus, tmp_path, capsys):
    src = built_fmus["DroneFlyLateral"]
    with zipfile.ZipFile(src) as z:
        md = z.read("modelDescription.xml")
    start = md.index(b"<InitialUnknowns>")
    end = md.index(b"</InitialUnknowns>") + len(b"</InitialUnknowns>")
    broken = _rewrite_md(src, tmp_path / "NoInitialUnknowns.fmu", md[start:end], b"")
    report = check_fmu(broken, fuzz=False)
    status = _status(report)
    assert not report.passed and status["validate"] is False and status["reset"] is True
    assert main(["check", "--no-fuzz", str(broken)]) == 1
    out = capsys.readouterr().out
    assert "FAIL" in out and "validate" in out and "0 of 1 FMUs passed" in out


def test_state_that_is_not_captured_fails(tmp_path, monkeypatch):
    """A plant whose FMU state forgets the integrator state: continuation differs."""
    import dronefly.harness.builder.build as build

    original = build._source_path

    def patched(rel):
        path = original(rel)
        if rel == "fmu_src/linear_slave.py":
            text = path.read_text()
            bad = text.replace('return {"x": list(self._x)}', 'return {"x": [0.0] * 4}')
            assert bad != text
            path = tmp_path / "linear_slave.py"
            path.write_text(bad)
        return path

    monkeypatch.setattr(build, "_source_path", patched)
    fmu = build.build_fmu("DroneFlyLateral", tmp_path / "bad")
    status = _status(check_fmu(fmu, fuzz=False))
    assert {name for name, ok in status.items() if not ok} == {"state"}, status


def test_do_nothing_fmu_fails_validate_and_our_profile(tmp_path):
    """A plain pythonfmu FMU: no InitialUnknowns (FMI 2.0 2.2.8: a real defect of pythonfmu's
    modelDescription.xml); NaN inputs are not refused, which only the dronefly profile asks."""
    from pythonfmu import FmuBuilder

    from dronefly.harness.compliance.checker import CheckOptions

    src = Path(__file__).resolve().parents[1] / "benchmarks" / "null_fmus" / "NullPlant.py"
    fmu = Path(FmuBuilder.build_FMU(src, dest=tmp_path))
    report = check_fmu(fmu, fuzz=False)
    status = _status(report)
    assert report.profile == "standard"
    assert status["validate"] is False and status["bad-input"] is True
    ours = check_fmu(fmu, fuzz=False, options=CheckOptions(profile="dronefly",
                                                           only=("bad-input",)))
    assert _status(ours) == {"bad-input": False}
    assert ours.checks[0].detail.startswith("delta_Phi_a = nan: fmi2DoStep returned fmi2OK")


def test_missing_and_corrupt_files(tmp_path, capsys):
    assert main(["check", str(tmp_path / "nope.fmu")]) == 2
    bad = tmp_path / "corrupt.fmu"
    bad.write_bytes(b"PK\x03\x04 garbage")
    report = check_fmu(bad, fuzz=False)
    assert not report.passed and report.checks[0].name == "load"


def test_container_fmu_passes_and_its_binary_output_is_captured(built_fmus, capfd):
    """The container's binary is fmpy's: statuses and recovery are checked, its messages not.
    FMPy's container prints container::logError(...) lines itself (fd 1); the check keeps them
    in the report and shows them only with --verbose (or when a check fails): the terminal
    text of ``dronefly check`` with and without --verbose from one check run (suite time)."""
    # 30 wing beats, not the default experiment's 300: each check runs the loop several times
    # (suite time), and every check and its messages are the same over any stop time
    options = CheckOptions(stop_time=30 / N_HZ)
    report = check_fmu(built_fmus["DroneFlyClosedLoop"], fuzz=False, options=options)
    assert "container::" not in "".join(capfd.readouterr())  # captured, not passed through
    assert report.passed, report.checks
    detail = {c.name: c.detail for c in report.checks}
    assert report.profile == "standard"  # its binary is fmpy's: judged by the standard
    assert "not applicable" in detail["state"] and "Reset recovered" in detail["bad-input"]
    assert "container::logError" in report.output
    quiet = format_reports([report])
    assert "container::" not in quiet and "1 of 1 FMUs passed" in quiet
    assert "container::logError" in format_reports([report], verbose=True)


def test_a_crashing_fmu_is_a_failed_check_not_a_crash(tmp_path):
    """An FMU that segfaults its host in doStep: dronefly check reports it and goes on."""
    report = check_fmu(build_crashing_fmu(tmp_path), fuzz=False)
    died = [c for c in report.checks if "the checking process died (killed by SIGSEGV)" in c.detail]
    assert died and died[0].name == "call-sequence" and not report.passed


def test_the_fmus_own_log_message_is_shown(tmp_path, monkeypatch, capsys):
    """An FMU whose do_step raises: pythonfmu answers fmi2Fatal and logs the exception; the
    failed check's detail in --json carries that message, whether the later use after free
    crashes the checking process (the crash line: the call and what the FMU logged before)
    or not (the failure line: what the FMU logged)."""
    import json

    import dronefly.harness.builder.build as build

    original = build._source_path

    def patched(rel):
        path = original(rel)
        if rel == "fmi/base.py":
            text = path.read_text()
            old = "        return do_step_status(self, current_time, step_size) == 0"
            assert old in text
            path = tmp_path / "base.py"
            path.write_text(text.replace(old, "        raise RuntimeError('broken doStep')"))
        return path

    monkeypatch.setattr(build, "_source_path", patched)
    fmu = build.build_fmu("DroneFlyLateral", tmp_path / "bad")
    assert main(["check", "--no-fuzz", "--check", "call-sequence", "--json", str(fmu)]) == 1
    doc = json.loads(capsys.readouterr().out)
    check = doc["fmus"][0]["checks"][0]
    assert check["name"] == "call-sequence" and check["status"] == "failed"
    assert "fmi2DoStep" in check["detail"]
    # pythonfmu hands its logger the exception's text from memory it frees in the same call
    # (it goes on using its objects after a Fatal): in a rare run, seen once under a full
    # suite's load, both the category and the message arrive empty. The checker shows that
    # entry as it came; what it must never do is drop the FMU's log.
    assert "the FMU logged" in check["detail"], check  # "logged before" where it crashed
    assert "broken doStep" in check["detail"] or check["detail"].endswith("log: )"), check


def test_a_hanging_fmu_is_reported_with_the_call(tmp_path, capsys):
    """A step that never returns: after --timeout the check is failed, naming the call, its
    arguments (the time) and the rest not run; exit 1."""
    fmu = build_hanging_fmu(tmp_path)
    assert main(["check", "--no-fuzz", "--timeout", "3", "--skip", "validate", str(fmu)]) == 1
    out = capsys.readouterr().out
    assert ("[FAIL] call-sequence  the checking process died (hung for more than 3 s) in "
            "fmi2DoStep(currentCommunicationPoint=0.05") in out
    assert "[FAIL] not run        start-values, dependencies" in out
