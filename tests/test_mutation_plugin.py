"""Independent oracles for the pytest plugin of ``dronefly check``
(harness/compliance/pytest_plugin.py), written for mutation testing (docs/mutation.md): the
tests it plans for an FMU against the checks an in-process run reports on it, and the verdict
of each test (passed, failed with detail and rule, skipped with the reason) against reports
written by hand, handed to the plugin by a conftest in a pytest run of its own."""

from __future__ import annotations

import json
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from dronefly.harness.compliance import pytest_plugin
from dronefly.harness.compliance.checker import run_checks
from dronefly.harness.compliance.rules import CheckOptions
from shared_files import edited_copy, need_shared

REF = Path(__file__).resolve().parents[1].parent / "shared" / "reference-fmus"


def _ref(fmi: int, name: str = "Dahlquist") -> Path:
    source = REF / f"fmi{fmi}" / f"{name}.fmu"
    need_shared(source, "the Reference-FMUs")
    return source


@pytest.mark.parametrize("fmi", [2, 3])
@pytest.mark.parametrize("options", [  # the options the plugin passes: a profile, or auto
    CheckOptions(profile="standard"), CheckOptions(profile="dronefly"), CheckOptions()])
def test_the_planned_tests_are_the_checks_a_run_reports(fmi, options):
    """A test per check that ``dronefly check`` reports on the FMU (its in-process run, the
    checks' functions really called), and ``fuzz`` where the dronefly profile adds it (the
    Reference-FMUs' automatic profile is the standard one)."""
    ran = [c.name for c in run_checks(_ref(fmi), options=options).checks]
    fuzz = ["fuzz"] if options.profile == "dronefly" and options.wants("fuzz") else []
    assert pytest_plugin._planned(_ref(fmi), options, fuzz=True) == ran + fuzz
    assert pytest_plugin._planned(_ref(fmi), options, fuzz=False) == ran


def test_the_planned_test_of_an_fmu_out_of_scope_or_unreadable(tmp_path):
    se = tmp_path / "se.fmu"
    with zipfile.ZipFile(se, "w") as z:
        z.writestr("modelDescription.xml", '<fmiModelDescription fmiVersion="3.0">'
                   '<ScheduledExecution modelIdentifier="m"/></fmiModelDescription>')
    bad = tmp_path / "bad.fmu"
    bad.write_text("not a zip")
    assert pytest_plugin._planned(se, CheckOptions(), True) == ["fmu"]
    assert pytest_plugin._planned(bad, CheckOptions(), True) == ["load"]
    # the profile of a Reference-FMU is the standard one: no fuzz unless asked for
    auto = pytest_plugin._planned(_ref(2), CheckOptions(), True)
    assert "fuzz" not in auto and auto == pytest_plugin._planned(
        _ref(2), CheckOptions(profile="standard"), True)


def test_an_fmu_whose_description_fmpy_refuses_is_planned_as_checked(tmp_path):
    """A model description FMPy's validation refuses (an attribute the schema does not allow)
    is the validate check's finding, not a failed load: the same tests are planned as for
    the FMU as it was (the checks run on it in-process say the same)."""
    source = _ref(2)
    path = edited_copy(source, tmp_path / "bogus.fmu",
                       [('modelName="Dahlquist"', 'modelName="Dahlquist" bogus="1"')])
    options = CheckOptions(profile="standard")
    planned = pytest_plugin._planned(path, options, fuzz=True)
    assert planned == pytest_plugin._planned(source, options, fuzz=True)
    assert planned == [c.name for c in run_checks(path, options=options).checks]


_CONFTEST = '''
import json
from pathlib import Path
from dronefly.harness.compliance import pytest_plugin
from dronefly.harness.compliance.rules import CheckResult, FMUReport

def fake_check_fmu(path, fuzz, options):
    with open("calls.jsonl", "a") as f:
        f.write(json.dumps([Path(path).name, fuzz, options.profile]) + "\\n")
    name = Path(path).name
    if name == "skipped.fmu":
        return FMUReport(Path(path), skipped="not checked: out of scope")
    if name == "died.fmu":
        return FMUReport(Path(path), [CheckResult("validate", True, "fine"),
                                      CheckResult("archive", False, "the process died", "R1"),
                                      CheckResult("not run", False, "binary, reset")])
    if name == "empty.fmu":
        return FMUReport(Path(path), [CheckResult("validate", True, "fine")])
    return FMUReport(Path(path), [
        CheckResult("validate", True, "no problems"),
        CheckResult("archive", False, "no sources and no binaries", "FMI 2.0 2.3: the archive"),
        CheckResult("binary", True, "not applicable: no binary here", skipped=True)])

pytest_plugin.check_fmu = fake_check_fmu
pytest_plugin._planned = lambda path, options, fuzz: ["validate", "archive", "binary"]
'''


def _pytest(tmp_path: Path, *args: str) -> subprocess.CompletedProcess:
    (tmp_path / "pytest.ini").write_text("[pytest]\n")
    (tmp_path / "conftest.py").write_text(_CONFTEST)
    return subprocess.run([sys.executable, "-m", "pytest", "-p", "no:randomly", "-p",
                           "no:cacheprovider", "-p", "no:xdist", "-rA", *args], cwd=tmp_path,
                          capture_output=True, text=True, timeout=120)


def test_each_test_says_its_checks_verdict(tmp_path):
    """Per FMU and check: passed, failed with the detail and the rule, skipped with the
    reason; a check the report lacks fails naming what failed instead (or that there is no
    result); an FMU out of scope skips all its tests; each FMU is checked once."""
    for name in ("a.fmu", "skipped.fmu", "died.fmu", "empty.fmu"):
        (tmp_path / name).write_bytes(b"")
    proc = _pytest(tmp_path, "--fmu", "a.fmu", "skipped.fmu", "died.fmu", "--fmu", "empty.fmu")
    out = proc.stdout
    assert proc.returncode == 1, out[-3000:]
    status = {}
    for line in out.splitlines():
        for word in ("PASSED", "FAILED", "SKIPPED"):
            if line.startswith(word + " "):
                status.setdefault(word, []).append(line.split(" ")[1].lstrip(":"))
    assert sorted(status["PASSED"]) == [
        "a.fmu::validate", "died.fmu::validate", "empty.fmu::validate"]
    failed = sorted(status["FAILED"])
    assert failed == ["a.fmu::archive", "died.fmu::archive", "died.fmu::binary",
                      "empty.fmu::archive", "empty.fmu::binary"], out[-3000:]
    # -rA groups skips by reason ("SKIPPED [3] ..."): a.fmu's binary, skipped.fmu's three
    assert sum(int(s.strip("[]")) for s in status["SKIPPED"]) == 4
    assert "no sources and no binaries\nrule: FMI 2.0 2.3: the archive" in out
    assert "binary was not run: archive: the process died; not run: binary, reset" in out
    assert "archive was not run: no result" in out
    # a skip is reported at the FMU (the item's location, line 0 shown as 1), not the plugin
    assert "SKIPPED [1] a.fmu:1: not applicable: no binary here" in out, out[-3000:]
    assert "SKIPPED [3] skipped.fmu:1: not checked: out of scope" in out, out[-3000:]
    calls = [json.loads(x) for x in (tmp_path / "calls.jsonl").read_text().splitlines()]
    assert calls == [["a.fmu", True, None], ["skipped.fmu", True, None],
                     ["died.fmu", True, None], ["empty.fmu", True, None]]


def test_the_options_reach_the_checks_and_a_missing_fmu_is_a_usage_error(tmp_path):
    (tmp_path / "a.fmu").write_bytes(b"")
    proc = _pytest(tmp_path, "--fmu-profile", "dronefly", "--fmu-no-fuzz", "--fmu", "a.fmu")
    assert proc.returncode == 1, proc.stdout[-2000:]
    calls = [json.loads(x) for x in (tmp_path / "calls.jsonl").read_text().splitlines()]
    assert calls == [["a.fmu", False, "dronefly"]]
    proc = _pytest(tmp_path, "--fmu-profile", "standard", "--fmu", "a.fmu", "gone.fmu")
    assert proc.returncode == 4, proc.stdout[-2000:]
    assert "--fmu 'gone.fmu': no such FMU file" in proc.stderr + proc.stdout
    # without --fmu the plugin adds nothing: no test collected
    proc = _pytest(tmp_path)
    assert proc.returncode == 5 and "no tests ran" in proc.stdout
