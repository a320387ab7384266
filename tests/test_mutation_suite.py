"""Independent oracles for ``dronefly check``'s suite (harness/compliance/suite.py): the reports
(terminal, JSON, JUnit), which FMUs are in scope, and how a checking process that crashed,
hung or failed itself is reported. Written for mutation testing (docs/mutation.md), in-process:
the child process is stood in for by a function that writes the rows a real one would, and the
checks are the Reference-FMUs' own in-process run. Oracles: the JSON Schema shipped with the
package (jsonschema), the JUnit layout read back with ElementTree and counted by hand, the
checks an uninterrupted in-process run reports, and reports written out by hand."""

from __future__ import annotations

import json
import os
import threading
import time
import xml.etree.ElementTree as ET
import zipfile
from dataclasses import asdict
from pathlib import Path
from types import SimpleNamespace

import jsonschema
import pytest

from dronefly.harness.compliance import suite
from dronefly.harness.compliance.checker import run_checks
from dronefly.harness.compliance.child import ChildRun
from dronefly.harness.compliance.rules import CheckOptions, CheckResult, FMUReport, rule_of
from shared_files import need_shared

REF = Path(__file__).resolve().parents[1].parent / "shared" / "reference-fmus"


def _reports() -> list[FMUReport]:
    """Three FMUs: one passing (a warning, a skipped check, a rule), one failing (with what
    its binary printed), one out of scope."""
    good = FMUReport(Path("good.fmu"), profile="standard", duration_s=1.5, output="hello", checks=[
        CheckResult("validate", True, "no problems", "FMI 2.0 2.2.8: ModelStructure",
                    duration_s=0.25),
        CheckResult("state", True, "not applicable: no state", "FMI 2.0 2.1.8", skipped=True),
        CheckResult("reset", True, "identical", "dronefly profile: reset", warning="slow",
                    duration_s=0.5)])
    bad = FMUReport(Path("bad.fmu"), profile="dronefly", output="line 1\nline 2", checks=[
        CheckResult("validate", True, "no problems", "FMI 3.0: the schema"),
        CheckResult("bad-input", False, "x" * 1200, "FMI cross-check rules: y"),
        CheckResult("binary", False, "missing fmi3DoStep", "something without a reference")])
    out = FMUReport(Path("se.fmu"), skipped="not checked: Scheduled Execution only")
    return [good, bad, out]


def test_the_terminal_report_lists_each_check_with_its_tag_and_reference():
    text = suite.format_reports(_reports())
    want = [
        "good.fmu: PASS (profile standard)",
        "  [  ok] validate       no problems [FMI 2.0 2.2.8]",
        "  [skip] state          not applicable: no state [FMI 2.0 2.1.8]",
        "  [warn] reset          identical [dronefly profile]",
        "         warning: slow",
        "bad.fmu: FAIL (profile dronefly)",
        "  [  ok] validate       no problems [FMI 3.0]",
        f"  [FAIL] bad-input      {'x' * 1200} [FMI cross-check]",
        "         rule: FMI cross-check rules: y",
        "  [FAIL] binary         missing fmi3DoStep",
        "         rule: something without a reference",
        "  printed by the FMU's binaries while checked:",
        "    line 1",
        "    line 2",
        "se.fmu: SKIP (not checked: Scheduled Execution only)",
        "1 of 2 FMUs passed, 1 not checked",
    ]
    assert text.splitlines() == want
    verbose = suite.format_reports(_reports()[:1], verbose=True).splitlines()
    assert verbose[2] == "         rule: FMI 2.0 2.2.8: ModelStructure"
    assert verbose[-3:] == ["  printed by the FMU's binaries while checked:", "    hello",
                            "1 of 1 FMUs passed"]
    assert suite.format_reports([]) == "0 of 0 FMUs passed"


def test_the_json_report_follows_the_shipped_schema_and_says_each_status():
    doc = suite.reports_json(_reports())
    schema = json.loads(suite.JSON_SCHEMA_FILE.read_text())
    jsonschema.validate(doc, schema)
    assert doc["schema"] == suite.JSON_SCHEMA == schema["properties"]["schema"]["const"]
    good, bad, out = doc["fmus"]
    assert [f["status"] for f in doc["fmus"]] == ["passed", "failed", "skipped"]
    assert [f["passed"] for f in doc["fmus"]] == [True, False, True]
    assert [f["skipped"] for f in doc["fmus"]] == [None, None,
                                                   "not checked: Scheduled Execution only"]
    assert [f["profile"] for f in doc["fmus"]] == ["standard", "dronefly", None]
    assert good["fmu"] == "good.fmu" and good["duration_s"] == 1.5 and good["output"] == "hello"
    assert [c["status"] for c in good["checks"]] == ["passed", "skipped", "passed"]
    assert [c["warning"] for c in good["checks"]] == [None, None, "slow"]
    assert good["checks"][0] == {"name": "validate", "status": "passed", "passed": True,
                                 "skipped": False, "rule": "FMI 2.0 2.2.8: ModelStructure",
                                 "detail": "no problems", "warning": None, "duration_s": 0.25}
    assert [c["status"] for c in bad["checks"]] == ["passed", "failed", "failed"]
    assert out["checks"] == []


def test_the_junit_report_counts_tests_failures_and_skips_per_fmu():
    root = ET.fromstring(suite.reports_junit(_reports()))
    assert root.tag == "testsuites" and root.get("name") == "dronefly check"
    good, bad, out = root.findall("testsuite")
    # by hand: good 3 cases, 0 failures, 1 skipped; bad 3, 2, 0; out: one skipped case
    assert [(s.get("name"), s.get("tests"), s.get("failures"), s.get("skipped"))
            for s in (good, bad, out)] == [("good.fmu", "3", "0", "1"),
                                           ("bad.fmu", "3", "2", "0"),
                                           ("se.fmu", "1", "0", "1")]
    assert float(good.get("time")) == 1.5
    cases = good.findall("testcase")
    assert [c.get("name") for c in cases] == ["validate", "state", "reset"]
    assert {c.get("classname") for c in cases} == {"good"}
    assert [float(c.get("time")) for c in cases] == [0.25, 0.0, 0.5]
    assert cases[1].find("skipped").get("message") == "not applicable: no state"
    assert cases[0].find("failure") is None and cases[0].find("skipped") is None
    assert cases[2].find("system-out").text == "warning: slow"
    failure = bad.findall("testcase")[1].find("failure")
    assert failure.get("message") == "x" * 1000  # the first 1000 characters
    assert failure.text == "\n".join(["x" * 1200, "FMI cross-check rules: y", "line 1\nline 2"])
    assert bad.findall("testcase")[0].find("failure") is None
    (case,) = out.findall("testcase")
    assert case.get("name") == "fmu"
    assert case.find("skipped").get("message") == "not checked: Scheduled Execution only"


@pytest.mark.parametrize("rule, ref", [
    ("FMI 2.0 4.2.4: fmi2DoStep", "FMI 2.0 4.2.4"), ("FMI 3.0 2.4.7.5 names", "FMI 3.0 2.4.7.5"),
    ("FMI 3.0: any", "FMI 3.0"), ("dronefly profile: x", "dronefly profile"),
    ("FMI cross-check rules", "FMI cross-check"), ("FMI 4.0 1.1", ""), ("", "")])
def test_a_rules_reference_is_its_section(rule, ref):
    assert suite._ref(rule) == ref


# --- which FMUs are in scope ---------------------------------------------------------------
def _archive(tmp_path: Path, name: str, head: str | None, interfaces: str) -> Path:
    path = tmp_path / name
    with zipfile.ZipFile(path, "w") as z:
        if head is not None:
            z.writestr("modelDescription.xml", f'<?xml version="1.0"?>\n<{head}>\n{interfaces}\n'
                                               "<ModelVariables/></fmiModelDescription>\n")
    return path


_SE = '<ScheduledExecution modelIdentifier="m"/>'
_CS = '<CoSimulation modelIdentifier="m"/>'
_ME = '<ModelExchange modelIdentifier="m"/>'
_HEAD3 = 'fmiModelDescription fmiVersion = "3.0" modelName="m" instantiationToken="x"'


def test_scheduled_execution_only_is_out_of_scope_and_the_rest_is_checked(tmp_path):
    se = _archive(tmp_path, "se.fmu", _HEAD3, _SE)
    assert suite.not_checked(se).startswith("not checked: Scheduled Execution only")
    assert suite.interfaces_of(se) == ()
    assert suite._fmi_version(se) == "3.0"
    for name, interfaces, want in [("cs.fmu", _SE + _CS, ("cs",)), ("me.fmu", _ME + _SE, ("me",)),
                                   ("both.fmu", _CS + _ME, ("cs", "me"))]:
        path = _archive(tmp_path, name, _HEAD3, interfaces)
        assert suite.not_checked(path) is None, name
        assert suite.interfaces_of(path) == want, name
    # not an FMI model description, no description, no archive: the load check says why
    other = _archive(tmp_path, "other.fmu", "something", _SE)
    empty = _archive(tmp_path, "empty.fmu", None, "")
    text = tmp_path / "text.fmu"
    text.write_text("not a zip")
    for path in (other, empty, text, tmp_path / "missing.fmu"):
        assert suite.not_checked(path) is None, path
    assert suite.interfaces_of(empty) == ("cs", "me") == suite.interfaces_of(text)
    assert suite._fmi_version(other) is None and suite._fmi_version(text) is None


# --- a checking process that crashed, hung or failed itself --------------------------------
@pytest.fixture(scope="module")
def dahlquist_checks():
    """The Reference-FMUs' Dahlquist (FMI 2.0) and the names of the checks an uninterrupted
    in-process run of the standard profile reports on it, in order."""
    source = REF / "fmi2" / "Dahlquist.fmu"
    need_shared(source, "the Reference-FMUs")
    report = run_checks(source, options=CheckOptions(skip=("reference",)))
    assert report.passed and report.profile == "standard"
    return source, report


def _child(monkeypatch, rows: list, returncode, stdout="", stderr="", cut=""):
    """Stand in for the checking process: write ``rows`` (and a cut line) where the real one
    would, end with ``returncode``; the arguments it got are kept."""
    got = {}

    def run_function(module, function, args, timeout_s, tmp=None):
        got.update(module=module, function=function, args=args, timeout_s=timeout_s, tmp=tmp)
        Path(args[1]).write_text("".join(json.dumps(r) + "\n" for r in rows) + cut)
        return ChildRun(returncode, stdout, stderr)

    monkeypatch.setattr(suite, "run_function", run_function)
    return got


def test_a_clean_child_run_is_its_rows(monkeypatch, dahlquist_checks):
    source, report = dahlquist_checks
    rows = [{"profile": "standard"}]
    for c in report.checks:
        rows += [{"begin": c.name}, {"call": "fmi2DoStep(0.0, 0.1)"}, {"log": "fine"}, asdict(c)]
    got = _child(monkeypatch, rows, 0, stdout=" out \n", stderr="err ")
    options = CheckOptions(skip=("reference",))
    checked = suite._check_isolated(source, options, 7.0)
    assert checked.checks == report.checks and checked.profile == "standard"
    assert checked.output == "out \nerr"
    assert got["module"] == "dronefly.harness.compliance.suite"
    assert got["function"] == "checking_process" and got["timeout_s"] == 7.0
    assert got["args"][0] == str(source) and json.loads(got["args"][2]) == json.loads(
        json.dumps(asdict(options)))
    assert not Path(got["tmp"]).exists()  # the child's folder is removed with its rows


@pytest.mark.parametrize("returncode, died", [(-11, "killed by SIGSEGV"), (3, "exit code 3"),
                                              (None, "hung for more than 7 s")])
def test_a_crash_is_a_failed_check_in_the_call_it_was_in_and_the_rest_not_run(
        monkeypatch, dahlquist_checks, returncode, died):
    """The check that was running fails, naming the FMI call it was in and the last three
    messages the FMU logged; the checks after it are one failed ``not run`` row, in the order
    an uninterrupted run reports them."""
    source, report = dahlquist_checks
    names = [c.name for c in report.checks]
    k = names.index("call-sequence")
    rows = [{"profile": "standard"}]
    rows += [asdict(c) for c in report.checks[:k]]
    rows += [{"begin": "call-sequence"}, {"log": "one"}, {"log": "two"}, {"call": "fmi2DoStep(0)"},
             {"log": "three"}, {"log": "four"}]
    _child(monkeypatch, rows, returncode, cut='{"name": "call-seq')
    checked = suite._check_isolated(source, CheckOptions(skip=("reference",)), 7.0)
    assert checked.checks[:k] == report.checks[:k]
    crash, not_run = checked.checks[k:]
    assert crash == CheckResult(
        "call-sequence", False, f"the checking process died ({died}) in fmi2DoStep(0); the "
        "FMU logged before: two | three | four", rule_of("call-sequence", 2, "standard"))
    assert not_run == CheckResult(
        "not run", False, f"{', '.join(names[k + 1:])} (the checking process died in "
        "call-sequence)")
    assert not checked.passed


def test_a_crash_between_checks_and_one_after_the_last(monkeypatch, dahlquist_checks):
    source, report = dahlquist_checks
    names = [c.name for c in report.checks]
    rows = [{"profile": "standard"}, asdict(report.checks[0])]
    _child(monkeypatch, rows, -6)
    checked = suite._check_isolated(source, CheckOptions(skip=("reference",)), 7.0)
    assert checked.checks[1] == CheckResult(
        "process exit", False, "the checking process died (killed by SIGABRT)", "")
    assert checked.checks[2].detail == (f"{', '.join(names[1:])} (the checking process died "
                                        "between checks)")
    # everything done, then the exit crashes: no "not run" row, nor for a check not selected
    _child(monkeypatch, [{"profile": "standard"}] + [asdict(c) for c in report.checks], 1)
    checked = suite._check_isolated(source, CheckOptions(skip=("reference",)), 7.0)
    assert [c.name for c in checked.checks] == names + ["process exit"]
    _child(monkeypatch, [{"profile": "standard"}] + [asdict(c) for c in report.checks[:-1]], 1)
    checked = suite._check_isolated(source, CheckOptions(skip=("reference", names[-1])), 7.0)
    assert [c.name for c in checked.checks] == names[:-1] + ["process exit"]


def test_an_internal_error_is_the_checkers_not_the_fmus(monkeypatch, dahlquist_checks):
    """An exception of dronefly check itself is said as such, in the check it was in, and is
    no crash of the FMU (no ``not run`` row, whatever the exit code)."""
    source, report = dahlquist_checks
    rows = [{"profile": "standard"}, {"begin": "validate"}, {"internal": "KeyError: 'x' | here"}]
    _child(monkeypatch, rows, 1)
    checked = suite._check_isolated(source, CheckOptions(), 7.0)
    assert checked.checks == [CheckResult("validate", False, "internal error of dronefly "
                                          "check: KeyError: 'x' | here")]
    _child(monkeypatch, [{"internal": "boom"}], 0)
    assert suite._check_isolated(source, CheckOptions(), 7.0).checks[0].name == "internal"


def test_the_checking_process_writes_a_row_per_event_and_says_its_own_errors(tmp_path,
                                                                            monkeypatch):
    rows = tmp_path / "rows.jsonl"
    umask = os.umask(0o022)
    os.umask(umask)
    seen = {}

    def fake_run_checks(path, progress, options):
        seen.update(path=path, options=options)
        progress({"begin": "validate"})
        progress(asdict(CheckResult("validate", True, "ok")))
        raise KeyError("boom")

    monkeypatch.setattr(suite, "run_checks", fake_run_checks)
    opts = json.dumps(asdict(CheckOptions(only=("validate", "fuzz"), step=0.5)))
    suite.checking_process("m.fmu", str(rows), opts)
    lines = [json.loads(x) for x in rows.read_text().splitlines()]
    assert seen == {"path": Path("m.fmu"),
                    "options": CheckOptions(only=("validate", "fuzz"), step=0.5)}
    assert lines[:2] == [{"begin": "validate"}, asdict(CheckResult("validate", True, "ok"))]
    # the exception and the line that raised it (the traceback's last line of code)
    assert len(lines) == 3 and lines[2]["internal"] == (
        "KeyError: 'boom' | raise KeyError(\"boom\")")
    assert os.stat(rows).st_mode & 0o777 == 0o600 & ~umask  # the rows are the user's own


# --- check_fmu: the fuzz added to the dronefly profile's FMI 2.0 FMUs ------------------------
class _Fuzz:
    passed = False

    def summary(self):
        return "2 problems\nin group values"


@pytest.fixture
def stubbed(monkeypatch):
    """check_fmu with the checks and the fuzz stood in for: the calls are kept."""
    calls = []

    def checked(profile, first="validate"):
        def isolated(path, options, timeout_s):
            calls.append(("checks", path, options, timeout_s))
            return FMUReport(path, [CheckResult(first, True)], profile=profile)
        monkeypatch.setattr(suite, "_check_isolated", isolated)

    def fuzz_fmu(path, **kw):
        calls.append(("fuzz", path, kw))
        return _Fuzz()

    monkeypatch.setattr(suite, "fuzz_fmu", fuzz_fmu)
    return calls, checked


def test_the_fuzz_runs_on_the_dronefly_profiles_fmi2_fmus(tmp_path, stubbed):
    calls, checked = stubbed
    fmu2 = _archive(tmp_path, "m2.fmu", 'fmiModelDescription fmiVersion="2.0"', _CS)
    checked("dronefly")
    report = suite.check_fmu(fmu2, timeout_s=9.0)
    assert calls[0] == ("checks", fmu2, CheckOptions(), 9.0)
    assert calls[1] == ("fuzz", fmu2, {"random_calls": 100, "instances": 5})
    fuzz = report.checks[-1]
    assert (fuzz.name, fuzz.passed, fuzz.detail) == ("fuzz", False, "2 problems;in group values")
    assert fuzz.rule.startswith("dronefly profile: the fuzz") and not report.passed
    assert report.duration_s >= 0.0
    # asked not to, or a load that failed: no fuzz
    calls.clear()
    assert [c.name for c in suite.check_fmu(fmu2, fuzz=False).checks] == ["validate"]
    assert [c.name for c in suite.check_fmu(fmu2, options=CheckOptions(skip=("fuzz",))).checks] \
        == ["validate"]
    checked("dronefly", first="load")
    assert [c.name for c in suite.check_fmu(fmu2).checks] == ["load"]
    assert [c[0] for c in calls] == ["checks"] * 3


def test_the_fuzz_is_said_not_to_apply_where_it_cannot_run(tmp_path, stubbed):
    calls, checked = stubbed
    fmu3 = _archive(tmp_path, "m3.fmu", _HEAD3, _CS)
    fmu2 = _archive(tmp_path, "m2.fmu", 'fmiModelDescription fmiVersion="2.0"', _CS)
    checked("dronefly")
    fuzz = suite.check_fmu(fmu3).checks[-1]
    assert fuzz.name == "fuzz" and fuzz.skipped and fuzz.passed
    assert fuzz.detail.startswith("not applicable: the fuzz calls the FMI 2.0 API")
    checked("standard")
    assert [c.name for c in suite.check_fmu(fmu2).checks] == ["validate"]  # not asked for
    fuzz = suite.check_fmu(fmu2, options=CheckOptions(only=("fuzz",))).checks[-1]
    assert fuzz.skipped and fuzz.detail == (
        "not applicable: fuzz is the dronefly profile's check (--profile dronefly runs it); "
        "this FMU is checked under the standard profile")
    assert [c.name for c in suite.check_fmu(fmu2, fuzz=False,
                                            options=CheckOptions(only=("fuzz",))).checks] \
        == ["validate"]
    assert all(c[0] == "checks" for c in calls)
    se = _archive(tmp_path, "se.fmu", _HEAD3, _SE)
    report = suite.check_fmu(se)
    assert report.skipped.startswith("not checked") and report.checks == []


def test_check_fmus_keeps_the_order_of_the_paths_and_stops_at_ctrl_c(monkeypatch):
    """With two jobs the FMUs finish out of order (the first is the slowest) and come back in
    the order given; Ctrl-C returns the finished ones, in that order, and none after."""
    started = []
    lock = threading.Lock()

    def check_fmu(path, **kw):
        with lock:
            started.append(path)
        time.sleep({"a": 0.1, "c": 0.02}.get(path, 0.0))
        if path == "stop":
            raise KeyboardInterrupt
        return FMUReport(Path(path), skipped=kw.get("why", ""))

    monkeypatch.setattr(suite, "check_fmu", check_fmu)
    for jobs in (1, 2, 3):
        got = suite.check_fmus(["a", "b", "c"], jobs=jobs, why="w")
        assert [r.path for r in got] == [Path("a"), Path("b"), Path("c")], jobs
        assert {r.skipped for r in got} == {"w"}
    started.clear()
    with pytest.raises(suite.CheckInterrupted) as e:
        suite.check_fmus(["a", "stop", "b"], jobs=1)
    assert [r.path for r in e.value.reports] == [Path("a")] and started == ["a", "stop"]


# --- what the survivors of the first mutation run showed untested ----------------------------
def test_a_skipped_fmu_between_others_does_not_end_the_report():
    good, bad, out = _reports()
    lines = suite.format_reports([out, good]).splitlines()
    assert lines[0] == "se.fmu: SKIP (not checked: Scheduled Execution only)"
    assert lines[1] == "good.fmu: PASS (profile standard)"
    assert lines[-1] == "1 of 1 FMUs passed, 1 not checked"


def test_durations_are_seconds_to_the_microsecond(monkeypatch, tmp_path, stubbed):
    """check_fmu's and the fuzz's durations: the time between the clock's two readings, in
    seconds rounded to 6 decimals (the clock stood in for: 10.0, then 10.1234567891...)."""
    calls, checked = stubbed
    fmu2 = _archive(tmp_path, "m2.fmu", 'fmiModelDescription fmiVersion="2.0"', _CS)
    checked("dronefly")
    ticks = iter([10.0, 20.0, 20.0 + 0.2345678912, 10.0 + 1.1234567891])
    monkeypatch.setattr(suite, "time", SimpleNamespace(perf_counter=lambda: next(ticks)))
    report = suite.check_fmu(fmu2)
    assert report.checks[-1].duration_s == 0.234568
    assert report.duration_s == 1.123457


def test_check_fmus_runs_jobs_at_once(monkeypatch):
    """With ``jobs`` = 2 two FMUs are checked at the same time: the first waits until the
    second has started (in one thread at a time it would wait for ever: 5 s, then fail)."""
    second_started = threading.Event()

    def check_fmu(path, **kw):
        if path == "first":
            assert second_started.wait(5.0), "the FMUs were checked one after the other"
        else:
            second_started.set()
        return FMUReport(Path(path))

    monkeypatch.setattr(suite, "check_fmu", check_fmu)
    for paths in (["first", "second"], ["first", "second", "third"]):
        second_started.clear()
        assert [r.path.name for r in suite.check_fmus(paths, jobs=2)] == paths
    # one FMU, or one job: no pool (the same reports)
    assert [r.path for r in suite.check_fmus(["x"], jobs=2)] == [Path("x")]


@pytest.mark.parametrize("stop", [KeyboardInterrupt, RuntimeError])
def test_a_parallel_run_that_stops_waits_for_the_running_and_starts_no_other(monkeypatch, stop):
    """Ctrl-C (or an error, which check_fmu never raises for an FMU) in one of two jobs: the
    running checks finish before check_fmus returns, the FMUs not started never are."""
    started, finished = [], []
    lock = threading.Lock()

    def check_fmu(path, **kw):
        with lock:
            started.append(path)
        if path == "stop":
            time.sleep(0.05)
            raise stop("stopped")
        time.sleep(0.4)
        finished.append(path)
        return FMUReport(Path(path))

    monkeypatch.setattr(suite, "check_fmu", check_fmu)
    expected = suite.CheckInterrupted if stop is KeyboardInterrupt else RuntimeError
    with pytest.raises(expected) as e:
        suite.check_fmus(["slow", "stop", "x", "y"], jobs=2)
    # the job "stop" freed takes "x" at once; "y" is still queued when the stop is seen
    assert sorted(started) == ["slow", "stop", "x"] and sorted(finished) == ["slow", "x"]
    if stop is KeyboardInterrupt:
        assert e.value.reports == []  # "slow" and "x" ended after the interruption was seen


def test_a_load_that_failed_gets_no_fuzz_even_if_the_process_then_crashed(tmp_path, stubbed,
                                                                        monkeypatch):
    calls, checked = stubbed
    fmu2 = _archive(tmp_path, "m2.fmu", 'fmiModelDescription fmiVersion="2.0"', _CS)

    def isolated(path, options, timeout_s):
        return FMUReport(path, [CheckResult("load", False, "not a zip"),
                                CheckResult("process exit", False, "died")], profile="dronefly")

    monkeypatch.setattr(suite, "_check_isolated", isolated)
    assert [c.name for c in suite.check_fmu(fmu2).checks] == ["load", "process exit"]
    assert calls == []


def test_the_fuzz_not_applicable_row_passes(tmp_path, stubbed):
    calls, checked = stubbed
    fmu2 = _archive(tmp_path, "m2.fmu", 'fmiModelDescription fmiVersion="2.0"', _CS)
    checked("standard")
    report = suite.check_fmu(fmu2, options=CheckOptions(only=("fuzz",)))
    assert report.checks[-1].passed and report.passed


def test_the_default_timeout_is_the_documented_600_s():
    """check_fmu's docstring and ``dronefly check --timeout``'s help: 600 s."""
    import inspect

    assert inspect.signature(suite.check_fmu).parameters["timeout_s"].default == 600.0
    assert "(default 600 s, as" in inspect.getdoc(suite.check_fmu)


@pytest.fixture(scope="module")
def dahlquist3_checks():
    source = REF / "fmi3" / "Dahlquist.fmu"
    need_shared(source, "the Reference-FMUs")
    report = run_checks(source, options=CheckOptions(skip=("reference",)))
    assert report.passed and report.profile == "standard"
    return source, report


def test_a_crash_of_an_fmi3_fmu_cites_fmi3_and_its_checks(monkeypatch, dahlquist3_checks):
    """FMI 3.0: the crashed check's rule is FMI 3.0's, and the checks left out include those
    of FMI 3.0 only (state-machine), as an uninterrupted run lists them."""
    source, report = dahlquist3_checks
    names = [c.name for c in report.checks]
    assert "state-machine" in names
    rows = [{"profile": "standard"}, {"begin": "validate"}]
    _child(monkeypatch, rows, -11)
    checked = suite._check_isolated(source, CheckOptions(skip=("reference",)), 7.0)
    crash, not_run = checked.checks
    assert crash.rule == rule_of("validate", 3, "standard") != rule_of("validate", 2, "standard")
    assert not_run.detail == f"{', '.join(names[1:])} (the checking process died in validate)"


def test_a_crash_before_the_profile_is_known_lists_the_standard_profiles_checks(
        monkeypatch, dahlquist_checks):
    source, report = dahlquist_checks
    names = [c.name for c in report.checks]
    _child(monkeypatch, [], -9)
    checked = suite._check_isolated(source, CheckOptions(skip=("reference",)), 7.0)
    assert checked.checks[0].name == "process exit"
    assert checked.checks[1].detail == (f"{', '.join(names)} (the checking process died "
                                        "between checks)")


def test_the_checking_process_as_a_program(tmp_path):
    """``python -m dronefly.harness.compliance.suite FMU ROWS [OPTIONS]`` (the fresh
    interpreter the checks fall back to): the rows of its checks; the options are optional."""
    import subprocess
    import sys

    bad = tmp_path / "bad.fmu"
    bad.write_text("not a zip")
    for extra in ([json.dumps(asdict(CheckOptions(profile="standard")))], []):
        rows = tmp_path / "rows.jsonl"
        proc = subprocess.run([sys.executable, "-m", "dronefly.harness.compliance.suite",
                               str(bad), str(rows), *extra], capture_output=True, text=True,
                              timeout=60)
        assert proc.returncode == 0, proc.stderr
        (row,) = [json.loads(x) for x in rows.read_text().splitlines()]
        assert row["name"] == "load" and not row["passed"]
        rows.unlink()
    # the options given are the options used: validate alone on a Reference-FMU
    source = REF / "fmi2" / "Dahlquist.fmu"
    need_shared(source, "the Reference-FMUs")
    rows = tmp_path / "rows.jsonl"
    only = json.dumps(asdict(CheckOptions(only=("validate",))))
    proc = subprocess.run([sys.executable, "-m", "dronefly.harness.compliance.suite",
                           str(source), str(rows), only], capture_output=True, text=True,
                          timeout=60)
    assert proc.returncode == 0, proc.stderr
    got = [json.loads(x) for x in rows.read_text().splitlines()]
    assert [r.get("name") for r in got if "name" in r] == ["validate"]
    assert got[-1]["passed"] and {"profile": "standard"} in got


def test_the_options_are_keywords_and_one_fmu_at_a_time_by_default(monkeypatch):
    """check_fmu's and check_fmus' options are keyword-only (FMPy's flat keyword API), and
    check_fmus checks one FMU at a time unless given ``jobs``: the first FMU is done before
    the second starts."""
    import inspect

    for fn, first in ((suite.check_fmu, "fuzz"), (suite.check_fmus, "jobs")):
        assert inspect.signature(fn).parameters[first].kind is inspect.Parameter.KEYWORD_ONLY
    with pytest.raises(TypeError):
        suite.check_fmus(["a"], 2)
    order = []

    def check_fmu(path, **kw):
        order.append(("start", path))
        time.sleep(0.05)
        order.append(("end", path))
        return FMUReport(Path(path))

    monkeypatch.setattr(suite, "check_fmu", check_fmu)
    suite.check_fmus(["a", "b"])
    assert order == [("start", "a"), ("end", "a"), ("start", "b"), ("end", "b")]
