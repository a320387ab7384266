"""Independent oracles for ``dronefly check``'s runner (harness/compliance/checker.py): which
checks are listed for an FMU, and how one finding is reported once, under the rule broken,
with the checks that depend on it ``not run``. Written for mutation testing
(docs/mutation.md), in-process on the Reference-FMUs (Dahlquist: both interfaces; a copy
declaring Co-Simulation only), with the checks' functions stood in for by ones that pass, fail,
do not apply, raise an FMI error or return Fatal as told. Oracles: the FMI standard's rule that
nothing may be called after Fatal (FMI 2.0 2.1.3, FMI 3.0 2.2.3), the dependencies written out
by hand, the table of the docs (docs/compliance.md: the checks per FMI version and profile)."""

from __future__ import annotations

import dataclasses
import zipfile
from dataclasses import asdict, replace
from types import SimpleNamespace
from pathlib import Path

import pytest

from dronefly.harness.compliance import checker
from dronefly.harness.compliance.checker import CHECKS, Check, run_checks
from dronefly.harness.compliance.driver import Context
from dronefly.harness.compliance.rules import (CheckFailed, CheckOptions, CheckResult,
                                               CheckSkipped, rule_of)
from shared_files import need_shared

REF = Path(__file__).resolve().parents[1].parent / "shared" / "reference-fmus"


def _ref(fmi: int, name: str = "Dahlquist") -> Path:
    source = REF / f"fmi{fmi}" / f"{name}.fmu"
    need_shared(source, "the Reference-FMUs")
    return source


def _copy(tmp_path: Path, fmi: int, name: str, drop_element: str | None = None,
          drop_files: str | None = None, edit: tuple[str, str] | None = None) -> Path:
    """A copy of Dahlquist without the interface element ``drop_element`` of its
    modelDescription.xml, without the files under ``drop_files``, or with ``edit`` (old, new)
    made to the XML."""
    source, path = _ref(fmi), tmp_path / name
    with zipfile.ZipFile(source) as zin, zipfile.ZipFile(path, "w") as zout:
        for item in zin.infolist():
            if drop_files and item.filename.startswith(drop_files):
                continue
            data = zin.read(item)
            if item.filename == "modelDescription.xml":
                text = data.decode()
                if drop_element:
                    start = text.index(f"<{drop_element}")
                    tag_end = text.index(">", start) + 1
                    end = tag_end if text[tag_end - 2] == "/" else \
                        text.index(f"</{drop_element}>") + len(f"</{drop_element}>")
                    text = text[:start] + text[end:]
                if edit:
                    assert edit[0] in text
                    text = text.replace(edit[0], edit[1], 1)
                data = text.encode()
            zout.writestr(item, data)
    return path


def _cs_only(tmp_path: Path, fmi: int) -> Path:
    """Dahlquist declaring its Co-Simulation interface only."""
    return _copy(tmp_path, fmi, f"cs{fmi}.fmu", drop_element="ModelExchange")


class FMIError(Exception):
    """An FMI call that failed, as fmpy raises it (``status`` 3: Error, 4: Fatal)."""

    def __init__(self, message: str, status: int) -> None:
        super().__init__(message)
        self.status = status


def _table(monkeypatch, outcomes: dict[str, object], log: list | None = None):
    """CHECKS with each function replaced: ``outcomes[name]`` is raised if an exception,
    else returned (a detail); a check not named passes with "ok". Each call is logged with
    the interface the runner set and opens an instance (freed by the runner unless Fatal)."""
    calls = [] if log is None else log

    def fn_of(name):
        def fn(ctx):
            calls.append((name, ctx.interface))
            inst = ctx.instantiate(name)  # the runner frees it (or not, after a Fatal)
            freed = []
            inst.free = lambda: freed.append(name)
            calls.append(("instance", name, freed))
            ctx.warnings.append(f"{name} noted")
            out = outcomes.get(name, "ok")
            if isinstance(out, BaseException):
                raise out
            return out
        return fn

    monkeypatch.setattr(checker, "CHECKS", tuple(replace(c, fn=fn_of(c.name)) for c in CHECKS))
    monkeypatch.setattr(Context, "instantiate", lambda self, name: _Inst(self, name))
    return calls


class _Inst:
    def __init__(self, ctx, name):
        ctx.instances.append(self)
        self.messages = []


def _by_name(report):
    return {c.name: c for c in report.checks}


def test_a_failure_is_reported_once_and_the_checks_that_need_it_are_not_run(monkeypatch):
    """call-sequence fails: reset, two-instances, state and reference (they need its run) are
    not run, saying so; the others run. The failure keeps its rule and the FMU's last log."""
    calls = _table(monkeypatch, {"call-sequence": CheckFailed("the run stopped at t = 3 s")})
    monkeypatch.setattr(Context, "log_tail", lambda self, k=3: "warning: slow | error: bad")
    report = run_checks(_ref(2), options=CheckOptions(profile="standard"))
    got = _by_name(report)
    failed = got["call-sequence"]
    assert not failed.passed and failed.rule == rule_of("call-sequence", 2, "standard")
    assert failed.detail == ("the run stopped at t = 3 s (the FMU logged: warning: slow | "
                             "error: bad)")
    assert failed.warning == "call-sequence noted"
    needs_run = ["reset", "two-instances", "state", "reference"]
    for name in needs_run:
        c = got[name]
        assert c.skipped and c.passed and c.detail == (
            "not run: it depends on call-sequence, which failed (the finding is reported "
            "there)"), name
        assert c.rule == rule_of(name, 2, "standard") and c.warning == ""
    ran = [c[0] for c in calls if c[0] != "instance"]
    assert not set(needs_run) & set(ran)
    # the Model Exchange family runs on (its own call sequence)
    assert {"model-exchange", "me:call-sequence", "me:reset", "bad-input"} <= set(ran)
    assert [c for c in report.checks if not c.passed] == [failed]
    assert not report.passed and report.profile == "standard"


def test_the_model_exchange_family_depends_on_its_own_findings(monkeypatch):
    calls = _table(monkeypatch, {"model-exchange": CheckFailed("no"),
                                 "me:call-sequence": "ok"})
    got = _by_name(run_checks(_ref(3), options=CheckOptions(profile="standard")))
    for name in ("me:call-sequence", "me:start-values", "me:dependencies", "me:reset",
                 "me:two-instances", "me:state"):
        assert got[name].detail.startswith("not run: it depends on model-exchange, "), name
    assert got["reset"].detail == "ok"
    _table(monkeypatch, {"me:call-sequence": CheckFailed("no")})
    got = _by_name(run_checks(_ref(3), options=CheckOptions(profile="standard")))
    assert got["me:start-values"].detail == "ok" and got["me:dependencies"].detail == "ok"
    for name in ("me:reset", "me:two-instances", "me:state"):
        assert got[name].detail.startswith("not run: it depends on me:call-sequence, "), name
    # each check drives the interface it is of
    interfaces = {c[0]: c[1] for c in calls if c[0] != "instance"}
    assert interfaces["model-exchange"] == "me" and interfaces["validate"] == "cs"
    assert interfaces["binary"] == "cs" and interfaces["reset"] == "cs"


@pytest.mark.parametrize("fmi", [2, 3])
def test_after_fatal_nothing_is_called(monkeypatch, fmi):
    """A Fatal status (4) in one check: no instance is freed after it, and every later check
    is not run, citing the rule (FMI 2.0 2.1.3 / FMI 3.0 2.2.3)."""
    calls = _table(monkeypatch, {"start-values": FMIError("fmi2GetReal failed.", 4)})
    monkeypatch.setattr(Context, "log_tail", lambda self, k=3: "")
    report = run_checks(_ref(fmi), options=CheckOptions(profile="standard"))
    names = [c.name for c in report.checks]
    k = names.index("start-values")
    fatal = report.checks[k]
    assert (fatal.passed, fatal.detail) == (False, "FMIError: fmi2GetReal failed")
    rule = "FMI 2.0 2.1.3" if fmi == 2 else "FMI 3.0 2.2.3"
    for c in report.checks[k + 1:]:
        assert c.skipped and c.detail == (
            f"not run: the FMU returned fmi{fmi}Fatal in start-values, after which no function "
            f"of any of its instances may be called ({rule})"), c.name
    ran = [c[0] for c in calls if c[0] != "instance"]
    assert ran[-1] == "start-values"
    freed = {c[1]: c[2] for c in calls if c[0] == "instance"}
    assert freed["start-values"] == [] and freed["call-sequence"] == ["call-sequence"]


def test_an_fmi_error_is_a_finding_and_a_skip_says_why(monkeypatch):
    """An FMI call that fails with Error (3) fails its check only (its message, the final
    period dropped); a check that does not apply is passed and skipped."""
    _table(monkeypatch, {"dependencies": FMIError("fmi2SetReal failed...", 3),
                         "state": CheckSkipped("canGetAndSetFMUstate is false")})
    monkeypatch.setattr(Context, "log_tail", lambda self, k=3: "")
    got = _by_name(run_checks(_ref(2), options=CheckOptions(profile="standard")))
    assert got["dependencies"].detail == "FMIError: fmi2SetReal failed"
    assert not got["dependencies"].passed
    assert got["state"].skipped and got["state"].passed
    assert got["state"].detail == "not applicable: canGetAndSetFMUstate is false"
    assert got["reset"].detail == "ok" and got["bad-input"].detail == "ok"  # no Fatal


def test_the_log_is_added_to_a_failure_of_a_check_that_runs_the_fmu_only(monkeypatch):
    _table(monkeypatch, {"validate": CheckFailed("1 problem"), "reset": CheckFailed("differs")})
    monkeypatch.setattr(Context, "log_tail", lambda self, k=3: "error: x")
    got = _by_name(run_checks(_ref(2), options=CheckOptions(profile="standard")))
    assert got["validate"].detail == "1 problem"  # a static check: the FMU ran nothing
    assert got["reset"].detail == "differs (the FMU logged: error: x)"

    def unreadable(self, k=3):
        raise UnicodeDecodeError("utf-8", b"\xff", 0, 1, "bad")

    monkeypatch.setattr(Context, "log_tail", unreadable)
    got = _by_name(run_checks(_ref(2), options=CheckOptions(profile="standard")))
    assert got["reset"].detail == ("differs (the FMU logged: (its log cannot be read: "
                                   "UnicodeDecodeError))")


def test_a_binary_that_cannot_run_or_be_used_leaves_the_running_checks_out(monkeypatch):
    """No binary for this platform (``cannot_run``): the static checks run, the others are not
    run with the reason; a binary a host cannot use (``unusable``, the binary check's finding)
    does the same for the checks after it."""
    calls = _table(monkeypatch, {})
    monkeypatch.setattr(checker.static, "cannot_run", lambda ctx: "no binary for linux64")
    got = _by_name(run_checks(_ref(2), options=CheckOptions(profile="standard")))
    assert got["validate"].detail == "ok" and got["archive"].detail == "ok"
    for name in ("binary", "call-sequence", "reset", "model-exchange", "logger-format"):
        assert got[name].detail == "not run: no binary for linux64", name
    assert [c[0] for c in calls if c[0] != "instance"] == ["validate", "archive"]

    def unusable(ctx):
        ctx.unusable = "fmi2DoStep is not exported"
        raise CheckFailed("a function is missing")

    monkeypatch.setattr(checker.static, "cannot_run", lambda ctx: None)
    monkeypatch.setattr(checker, "CHECKS", tuple(
        replace(c, fn=unusable) if c.name == "binary" else c for c in checker.CHECKS))
    monkeypatch.setattr(Context, "log_tail", lambda self, k=3: "")
    got = _by_name(run_checks(_ref(2), options=CheckOptions(profile="standard")))
    assert got["binary"].detail == "a function is missing"
    assert got["call-sequence"].detail == "not run: fmi2DoStep is not exported"
    assert got["archive"].detail == "ok"


def test_the_checks_listed_per_version_profile_and_interface(monkeypatch, tmp_path):
    """By docs/compliance.md: FMI 3.0 adds state-machine, the dronefly profile adds discard
    and state-refusal on FMI 3.0; an FMU without Model Exchange is said to have none
    (model-exchange) and its me: checks are not listed; a check selected by name that does
    not apply says why."""
    _table(monkeypatch, {})
    base = ["validate", "archive", "binary", "call-sequence", "start-values", "dependencies",
            "reset", "two-instances", "state"]
    me = ["model-exchange", "me:call-sequence", "me:start-values", "me:dependencies",
          "me:reset", "me:two-instances", "me:state"]
    names = lambda r: [c.name for c in r.checks]  # noqa: E731
    std = CheckOptions(profile="standard")
    ours = CheckOptions(profile="dronefly")
    assert names(run_checks(_ref(2), options=std)) == base + me + [
        "bad-input", "reference", "logger-format"]
    assert names(run_checks(_ref(3), options=std)) == base + me + [
        "bad-input", "reference", "state-machine", "logger-format"]
    assert names(run_checks(_ref(3), options=ours)) == base + me + [
        "bad-input", "reference", "state-machine", "discard", "state-refusal", "logger-format"]
    assert names(run_checks(_ref(2), options=ours)) == base + me + [
        "bad-input", "reference", "logger-format"]
    cs = run_checks(_cs_only(tmp_path, 2), options=std)
    assert names(cs) == base + ["model-exchange", "bad-input", "reference", "logger-format"]
    assert _by_name(cs)["model-exchange"].detail == (
        "not applicable: no Model Exchange interface")
    assert _by_name(cs)["model-exchange"].skipped and _by_name(cs)["model-exchange"].passed
    # selected by name where it does not apply: said why, nothing run
    picked = CheckOptions(profile="standard", only=("state-machine", "discard", "me:state"))
    got = _by_name(run_checks(_cs_only(tmp_path, 2), options=picked))
    assert got["state-machine"].detail == (
        "not applicable: state-machine is an FMI 3.0 check; this FMU is FMI 2.0")
    assert got["discard"].detail == (
        "not applicable: discard is an FMI 3.0 check; this FMU is FMI 2.0")
    assert got["me:state"].detail == "not applicable: no Model Exchange interface"
    got = _by_name(run_checks(_ref(3), options=CheckOptions(profile="standard",
                                                            only=("discard",))))
    assert list(got) == ["discard"] and got["discard"].detail == (
        "not applicable: discard is the dronefly profile's check (--profile dronefly runs "
        "it); this FMU is checked under the standard profile")
    assert all(c.skipped for c in got.values())
    # skip and only
    got = run_checks(_ref(2), options=CheckOptions(profile="standard", skip=("validate",),
                                                   only=("validate", "archive")))
    assert names(got) == ["archive"]


def test_progress_reports_the_profile_each_begin_and_each_result(monkeypatch):
    _table(monkeypatch, {})
    rows = []
    report = run_checks(_ref(2), rows.append, CheckOptions(profile="standard",
                                                           only=("validate", "reset")))
    assert rows == [{"profile": "standard"}, {"begin": "validate"}, asdict(report.checks[0]),
                    {"begin": "reset"}, asdict(report.checks[1])]
    assert report.checks[1].warning == "reset noted" and report.duration_s > 0.0


def test_an_fmu_that_does_not_load_or_has_no_step(tmp_path):
    bad = tmp_path / "bad.fmu"
    bad.write_text("not a zip")
    report = run_checks(bad)
    (load,) = report.checks
    assert (load.name, load.passed, load.rule) == ("load", False, "FMI 2.0 / 3.0 FMU archive")
    report = run_checks(_ref(2), options=CheckOptions(stop_time=0.05, step=0.1))
    (exp,) = report.checks
    assert (exp.name, exp.passed) == ("experiment", False)
    assert exp.detail == "step 0.1 s is longer than the run from 0.0 s to 0.05 s"
    assert exp.rule.startswith("FMI 2.0 4.2.2 / FMI 3.0 4.2")


def test_ctrl_c_between_checks_stops_the_run(monkeypatch):
    _table(monkeypatch, {})
    asked = iter([False, False, True])
    monkeypatch.setattr(checker, "pending", lambda: next(asked))
    with pytest.raises(KeyboardInterrupt):
        run_checks(_ref(2), options=CheckOptions(profile="standard"))


@pytest.mark.parametrize("fmi", [2, 3])
def test_an_fmu_with_model_exchange_only_is_checked_and_told_it_has_no_co_simulation(
        monkeypatch, tmp_path, fmi):
    """The checker loads an FMU that has no Co-Simulation interface: its Model Exchange
    checks run, and call-sequence says the Co-Simulation checks do not apply."""
    _table(monkeypatch, {})
    me = _copy(tmp_path, fmi, f"me{fmi}.fmu", drop_element="CoSimulation")
    got = _by_name(run_checks(me, options=CheckOptions(profile="standard")))
    assert got["call-sequence"].detail == "not applicable: no Co-Simulation interface"
    assert got["call-sequence"].skipped and got["call-sequence"].passed
    assert "reset" not in got and got["me:reset"].detail == "ok"


def test_an_invalid_description_or_no_binary_is_a_finding_not_a_failed_load(tmp_path):
    """The FMU is loaded unvalidated and without a binary for this platform: the validate
    check reports the description's problem (the other checks run), and with no binary the
    checks that call the FMU are not run, saying why (the real checks, Dahlquist FMI 2.0)."""
    # Outputs listing the derivative, not the output (FMI 2.0 2.2.8: FMPy's validation finds it)
    edit = ('<Outputs>\n      <Unknown index="2"', '<Outputs>\n      <Unknown index="3"')
    invalid = _copy(tmp_path, 2, "invalid.fmu", edit=edit)
    got = _by_name(run_checks(invalid, options=CheckOptions(profile="standard",
                                                            skip=("reference",))))
    assert not got["validate"].passed and "ModelStructure/Outputs" in got["validate"].detail
    assert got["call-sequence"].passed and got["model-exchange"].passed
    source = _copy(tmp_path, 2, "sources.fmu", drop_files="binaries/")
    got = _by_name(run_checks(source, options=CheckOptions(profile="standard",
                                                           skip=("reference",))))
    assert "load" not in got and got["validate"].passed and got["archive"].passed
    assert got["call-sequence"].detail.startswith("not run: ")
    assert got["call-sequence"].skipped


def test_an_instance_that_cannot_be_freed_does_not_stop_the_run(monkeypatch):
    calls = _table(monkeypatch, {})

    class Stubborn(_Inst):
        def free(self):
            raise RuntimeError("cannot free")

    monkeypatch.setattr(Context, "instantiate", lambda self, name: Stubborn(self, name))
    report = run_checks(_ref(2), options=CheckOptions(profile="standard",
                                                      only=("call-sequence", "reset")))
    assert [(c.name, c.detail) for c in report.checks] == [("call-sequence", "ok"),
                                                           ("reset", "ok")]
    assert report.passed and calls


def test_durations_are_the_clocks_seconds_to_the_microsecond(monkeypatch):
    """Each check's duration: the clock's reading after it less the one before, rounded to 6
    decimals; the report's: the whole run's (the clock stood in for: it advances
    0.1234567891 s a reading)."""
    _table(monkeypatch, {})
    readings = []

    def perf_counter():
        readings.append(100.0 + 0.1234567891 * len(readings))
        return readings[-1]

    monkeypatch.setattr(checker, "time", SimpleNamespace(perf_counter=perf_counter))
    report = run_checks(_ref(2), options=CheckOptions(profile="standard",
                                                      only=("validate", "reset")))
    assert [c.duration_s for c in report.checks] == [0.123457, 0.123457]
    assert report.duration_s == pytest.approx(readings[-1] - readings[0], abs=1e-12)
    assert len(readings) == 6  # the run's two readings and each check's two


def test_the_table_of_checks_cannot_be_changed_by_accident():
    with pytest.raises(dataclasses.FrozenInstanceError):
        CHECKS[0].needs = ("binary",)
