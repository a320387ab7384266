"""The runner of ``dronefly check`` (harness/compliance/checker.py) on small inputs in-process,
for mutation testing (docs/mutation.md): the check list CHECKS with each check's function
replaced by a stub that passes, fails, does not apply, raises or returns fmi2Fatal as the test
says, on the Reference-FMUs' Dahlquist (FMI 2.0 and 3.0, Co-Simulation and Model Exchange).

Oracles: the module's documented contract (a failure is reported once, under the rule the FMU
broke; the checks that depend on it are ``not run`` and say which; nothing is called after
fmiXFatal, FMI 2.0 2.1.3 / FMI 3.0 2.2.3; static checks run without a binary for this
platform) and the checks' families as the module's docstring lists them.
"""

from __future__ import annotations

import dataclasses
import zipfile
from pathlib import Path

import pytest

from fmpy import read_model_description
from fmpy.fmi1 import FMICallException

from dronefly.harness.compliance import checker
from dronefly.harness.compliance.rules import CheckFailed, CheckOptions, CheckSkipped, rule_of
from dronefly.harness.cosim.fmu import LogMessage
from shared_files import edited_copy, need_shared

REF = Path(__file__).resolve().parents[1].parent / "shared" / "reference-fmus"

#: the checks in the order the module's docstring gives their families
_STATIC = ["validate", "archive", "binary"]
_CS = ["call-sequence", "start-values", "dependencies", "reset", "two-instances", "state"]
_ME = ["model-exchange", "me:call-sequence", "me:start-values", "me:dependencies", "me:reset",
       "me:two-instances", "me:state"]
_ALL = [*_STATIC, *_CS, *_ME, "bad-input", "reference", "state-machine", "discard",
        "state-refusal", "logger-format"]


def _dahlquist(fmi: int) -> Path:
    path = REF / f"fmi{fmi}" / "Dahlquist.fmu"
    need_shared(path, "the Reference-FMUs")
    return path


class _Inst:
    """An instance as the runner frees it (``free``) and reads its log (``messages``)."""

    def __init__(self, messages=(), fails=False):
        self.messages, self.fails, self.freed = list(messages), fails, 0

    def free(self):
        self.freed += 1
        if self.fails:
            raise RuntimeError("cannot free")


def _run(monkeypatch, path, acts=None, **options):
    """run_checks with every check's function a stub: ``acts`` maps a check's name to what it
    does (a callable of the context, or "fail", "skip", "error", "fatal"; default: pass).
    Returns (report, [(check, interface) of the stubs called], progress events)."""
    acts = acts or {}
    called, events = [], []

    def stub(name):
        def fn(ctx):
            called.append((name, ctx.interface))
            act = acts.get(name, "pass")
            if callable(act):
                return act(ctx)
            if act == "fail":
                raise CheckFailed(f"{name} broken")
            if act == "skip":
                raise CheckSkipped(f"{name} does not apply")
            if act == "error":
                raise ValueError("a bad call.")
            if act == "fatal":
                raise FMICallException(f"{ctx.fmi}DoStep", 4)
            return f"{name} ok"
        return fn

    monkeypatch.setattr(checker, "CHECKS", tuple(dataclasses.replace(c, fn=stub(c.name))
                                                 for c in checker.CHECKS))
    report = checker.run_checks(path, events.append, CheckOptions(**options))
    return report, called, events


def _by_name(report):
    return {c.name: c for c in report.checks}


@pytest.mark.parametrize("fmi, profile, left_out", [
    (2, None, ["state-machine", "discard", "state-refusal"]),
    (2, "dronefly", ["state-machine", "discard", "state-refusal"]),
    (3, None, ["discard", "state-refusal"]),
    (3, "dronefly", [])])
def test_every_check_listed_runs_once_in_order_on_its_interface(monkeypatch, fmi, profile,
                                                                left_out):
    """An FMU with both interfaces: the checks of its FMI version and profile run in the
    table's order, each under its rule; the me: checks through Model Exchange, the others
    through Co-Simulation (static ones too, which call nothing)."""
    report, called, events = _run(monkeypatch, _dahlquist(fmi), profile=profile)
    want = [n for n in _ALL if n not in left_out]
    assert [c.name for c in report.checks] == want
    assert called == [(n, "me" if n in _ME else "cs") for n in want]
    prof = profile or "standard"
    assert report.profile == prof and report.passed
    for c in report.checks:
        assert (c.passed, c.skipped, c.detail, c.warning) == (True, False, f"{c.name} ok", "")
        assert c.rule == rule_of(c.name, fmi, prof) and 0.0 <= c.duration_s < 10.0
    assert events[0] == {"profile": prof}
    assert events[1::2] == [{"begin": n} for n in want]
    assert [e["name"] for e in events[2::2]] == want
    assert 0.0 < report.duration_s < 60.0  # stubs: far below a minute


def test_run_checks_without_progress_or_options(monkeypatch):
    """Both are optional: the default options (every check listed for the FMU) and no
    events."""
    monkeypatch.setattr(checker, "CHECKS", tuple(dataclasses.replace(c, fn=lambda ctx: "ok")
                                                 for c in checker.CHECKS))
    report = checker.run_checks(_dahlquist(2))
    assert len(report.checks) == len(_ALL) - 3 and report.passed


def test_the_table_lists_each_rule_with_what_it_needs():
    """The families of the docstring; static checks run without a binary; Model Exchange's
    checks drive that interface and wait for model-exchange (its runs for me:call-sequence);
    reset, two-instances, state, reference, discard and state-refusal wait for call-sequence."""
    by = {c.name: c for c in checker.CHECKS}
    assert list(by) == _ALL and list(checker.CHECK_NAMES) == _ALL
    assert [n for n, c in by.items() if not c.runs] == ["validate", "archive"]
    assert {n: c.interface for n, c in by.items() if c.interface != "cs"} == {
        "validate": "any", "archive": "any", "binary": "any", **{n: "me" for n in _ME}}
    assert [n for n, c in by.items() if c.announces] == ["call-sequence", "model-exchange"]
    assert {n: c.needs for n, c in by.items() if c.needs} == {
        **{n: ("call-sequence",) for n in ("reset", "two-instances", "state", "reference",
                                            "discard", "state-refusal")},
        **{n: ("model-exchange",) for n in _ME[1:4]},
        **{n: ("model-exchange", "me:call-sequence") for n in _ME[4:]}}
    assert {n: c.versions for n, c in by.items() if c.versions != (2, 3)} == {
        "state-machine": (3,), "discard": (3,), "state-refusal": (3,)}
    assert {n: c.profiles for n, c in by.items() if c.profiles != ("standard", "dronefly")} == {
        "discard": ("dronefly",), "state-refusal": ("dronefly",)}
    assert sorted(checker.PROFILES) == ["dronefly", "standard"]


@pytest.mark.parametrize("failed, not_run", [
    ("call-sequence", ["reset", "two-instances", "state", "reference", "discard",
                       "state-refusal"]),
    ("model-exchange", _ME[1:]),
    ("me:call-sequence", ["me:reset", "me:two-instances", "me:state"]),
    ("reset", [])])
def test_a_failure_is_reported_once_and_what_depends_on_it_is_not_run(monkeypatch, failed,
                                                                      not_run):
    """One stub fails: it alone fails, under its rule; the checks that need it (the table's
    ``needs``, as the docstring says) are not run, naming it; the others run."""
    report, called, _ = _run(monkeypatch, _dahlquist(3), {failed: "fail"}, profile="dronefly")
    by = _by_name(report)
    assert [n for n, c in by.items() if not c.passed] == [failed]
    assert by[failed].detail == f"{failed} broken" and not by[failed].skipped
    assert not report.passed
    for n in not_run:
        deps = [d for d in checker.CHECKS[_ALL.index(n)].needs if d == failed]
        assert by[n].skipped and by[n].passed, n
        assert by[n].detail == (f"not run: it depends on {', '.join(deps)}, which failed (the "
                                "finding is reported there)")
        assert by[n].rule == rule_of(n, 3, "dronefly")
    assert [n for n, _ in called] == [n for n in _ALL if n not in not_run]


def test_a_check_that_fails_on_both_its_dependencies_names_them():
    """me:reset waits for model-exchange and me:call-sequence: with both failed it names both
    (model-exchange failing leaves me:call-sequence not run, so the pair is seen through the
    context the runner keeps)."""
    ctx = type("Ctx", (), {"fatal": None, "cannot_run": None, "unusable": None,
                           "failed": {"model-exchange", "me:call-sequence"}})()
    check = checker.CHECKS[_ALL.index("me:reset")]
    assert checker._not_run(ctx, check) == (
        "it depends on model-exchange, me:call-sequence, which failed (the finding is "
        "reported there)")
    ctx.failed = {"reset"}
    assert checker._not_run(ctx, check) is None


@pytest.mark.parametrize("fmi", [2, 3])
def test_after_fatal_nothing_runs_and_no_instance_is_freed(monkeypatch, fmi):
    """fmiXFatal: the check fails with the call's error; every later check is not run,
    naming the check and the rule; the instances of that check are not freed (no call
    after Fatal), those of an earlier check are."""
    earlier, fatal_inst = _Inst(), _Inst()

    def make(inst, act):
        def fn(ctx):
            ctx.instances.append(inst)
            if act == "fatal":
                raise FMICallException(f"{ctx.fmi}DoStep", 4)
            return "ok"
        return fn

    report, called, _ = _run(monkeypatch, _dahlquist(fmi), {
        "start-values": make(earlier, "pass"), "dependencies": make(fatal_inst, "fatal")})
    by = _by_name(report)
    assert by["dependencies"].detail == (
        f"FMICallException: fmi{fmi}DoStep failed with status 4 (fatal)")
    assert not by["dependencies"].passed
    rule = "FMI 2.0 2.1.3" if fmi == 2 else "FMI 3.0 2.2.3"
    later = _ALL[_ALL.index("dependencies") + 1:]
    assert [n for n, _ in called] == _ALL[:_ALL.index("dependencies") + 1]
    for n in later:
        if n in by:
            assert by[n].skipped and by[n].detail == (
                f"not run: the FMU returned fmi{fmi}Fatal in dependencies, after which no "
                f"function of any of its instances may be called ({rule})")
    assert earlier.freed == 1 and fatal_inst.freed == 0


def test_an_exception_fails_the_check_and_a_status_below_fatal_stops_nothing(monkeypatch):
    """An exception other than a check's verdict is a failure named by its type (its trailing
    dot dropped); fmi2Error (3) is no Fatal: later checks run."""
    def error(ctx):
        raise FMICallException("fmi2DoStep", 3)

    report, called, _ = _run(monkeypatch, _dahlquist(2), {"reset": "error", "state": error})
    by = _by_name(report)
    assert by["reset"].detail == "ValueError: a bad call" and not by["reset"].passed
    assert by["state"].detail == "FMICallException: fmi2DoStep failed with status 3 (error)"
    assert by["bad-input"].detail == "bad-input ok"
    assert len(called) == len(report.checks) and not report.passed


def test_a_check_that_does_not_apply_is_skipped_not_failed(monkeypatch):
    """CheckSkipped: passed and skipped, its reason given; nothing depends on a skip."""
    report, _, _ = _run(monkeypatch, _dahlquist(2), {"call-sequence": "skip"})
    c = _by_name(report)["call-sequence"]
    assert (c.passed, c.skipped, c.detail) == (True, True, "not applicable: call-sequence does "
                                                           "not apply")
    assert _by_name(report)["reset"].detail == "reset ok"  # a skip is no failure
    assert report.passed


def test_a_failure_quotes_the_fmus_log_if_the_check_called_it(monkeypatch):
    """The last three messages above OK of the check's instances follow a failure of a check
    that runs the FMU; a static check's failure quotes nothing; each check has its own
    warnings and instances; an instance that cannot be freed stops nothing."""
    def logged(name):
        def fn(ctx):
            ctx.instances.append(_Inst([LogMessage("i", 0, "info", "fine"),
                                        LogMessage("i", 3, "logStatusError", "bad u")],
                                       fails=True))
            ctx.warnings.append(f"{name} warns")
            raise CheckFailed(f"{name} broken")
        return fn

    def clean(ctx):
        assert ctx.instances == [] and ctx.warnings == []
        return "clean"

    report, _, _ = _run(monkeypatch, _dahlquist(2), {"validate": logged("validate"),
                                                      "start-values": logged("start-values"),
                                                      "dependencies": clean})
    by = _by_name(report)
    assert by["validate"].detail == "validate broken"
    assert by["validate"].warning == "validate warns"
    assert by["start-values"].detail == ("start-values broken (the FMU logged: "
                                         "logStatusError: bad u)")
    assert by["dependencies"].detail == "clean" and by["dependencies"].warning == ""


def test_a_log_that_cannot_be_read_is_said_so(monkeypatch):
    """After a Fatal the FMU may have corrupted what it delivered: a log that cannot be read
    is named as such, the failure stays reported."""
    class Broken(_Inst):
        @property
        def messages(self):
            raise RuntimeError("freed")

        @messages.setter
        def messages(self, value):
            pass

    def fail(ctx):
        ctx.instances.append(Broken())
        raise CheckFailed("reset broken")

    report, _, _ = _run(monkeypatch, _dahlquist(2), {"reset": fail})
    assert _by_name(report)["reset"].detail == (
        "reset broken (the FMU logged: (its log cannot be read: RuntimeError))")


def test_the_binary_check_finding_an_unusable_binary_leaves_the_running_checks_not_run(
        monkeypatch):
    """The binary check marks the binary unusable: every later check that runs the FMU is not
    run, with that reason."""
    def unusable(ctx):
        ctx.unusable = "the binary lacks fmi2DoStep"
        raise CheckFailed("not exported: fmi2DoStep")

    report, called, _ = _run(monkeypatch, _dahlquist(2), {"binary": unusable})
    by = _by_name(report)
    assert [n for n, _ in called] == ["validate", "archive", "binary"]
    assert all(by[n].detail == "not run: the binary lacks fmi2DoStep" and by[n].skipped
               for n in list(by)[3:])


def _without(tmp_path: Path, fmi: int, drop: str = "", xml_drop: str = "",
             xml_put: str = "") -> Path:
    """Dahlquist with the archive members starting with ``drop`` left out and ``xml_drop``
    replaced by ``xml_put`` in its model description."""
    return edited_copy(_dahlquist(fmi), tmp_path / f"Dahlquist{fmi}.fmu",
                       [(xml_drop, xml_put)] if xml_drop else [], drop, every=True)


def test_an_fmu_that_fails_validation_is_checked_not_refused(monkeypatch, tmp_path):
    """A model description FMPy's validation refuses (an attribute the schema does not
    allow, FMI 2.0 2.2) is the validate check's finding: every check runs, the FMU is not
    refused at load."""
    text = ' description="the only state"'
    path = _without(tmp_path, 2, xml_drop=text, xml_put=text + ' bogus="1"')
    with pytest.raises(Exception, match="bogus"):  # the finding FMPy's validation makes
        read_model_description(str(path), validate=True)
    report, called, _ = _run(monkeypatch, path)
    assert [c.name for c in report.checks] == [n for n in _ALL if n not in (
        "state-machine", "discard", "state-refusal")]
    assert report.passed


def test_the_checks_are_values():
    """The table cannot be changed by a run (a check's fields are frozen)."""
    with pytest.raises(dataclasses.FrozenInstanceError):
        checker.CHECKS[0].needs = ("binary",)  # type: ignore[misc]


def test_an_fmu_without_a_binary_here_gets_the_static_checks_only(monkeypatch, tmp_path):
    """Dahlquist without binaries/ (sources only): validate and archive run, the others are not
    run saying why (static.cannot_run's message)."""
    report, called, _ = _run(monkeypatch, _without(tmp_path, 2, "binaries/"))
    by = _by_name(report)
    assert [n for n, _ in called] == ["validate", "archive"]
    assert by["binary"].detail == ("not run: cannot run on linux64: no binary for it, only "
                                   "sources (dronefly check does not compile them)")
    assert all(by[n].skipped for n in list(by)[2:])


def test_an_interface_the_fmu_lacks_is_said_by_its_announcing_check_only(monkeypatch,
                                                                         tmp_path):
    """Without Model Exchange: model-exchange says it does not apply, the me: checks are not
    listed; without Co-Simulation: call-sequence says it, its followers are not listed."""
    md = zipfile.ZipFile(_dahlquist(2)).read("modelDescription.xml").decode()
    me = md[md.index("<ModelExchange"):md.index("</ModelExchange>") + len("</ModelExchange>")] \
        if "</ModelExchange>" in md else md[md.index("<ModelExchange"):md.index("/>", md.index(
            "<ModelExchange")) + 2]
    report, called, _ = _run(monkeypatch, _without(tmp_path, 2, xml_drop=me))
    by = _by_name(report)
    assert by["model-exchange"].detail == "not applicable: no Model Exchange interface"
    assert by["model-exchange"].skipped and by["model-exchange"].passed
    assert by["model-exchange"].rule == rule_of("model-exchange", 2, "standard")
    assert not set(_ME[1:]) & set(by) and "model-exchange" not in dict(called)
    cs = md[md.index("<CoSimulation"):md.index("</CoSimulation>") + len("</CoSimulation>")] \
        if "</CoSimulation>" in md else md[md.index("<CoSimulation"):md.index("/>", md.index(
            "<CoSimulation")) + 2]
    (tmp_path / "cs").mkdir()
    report, called, _ = _run(monkeypatch, _without(tmp_path / "cs", 2, xml_drop=cs))
    by = _by_name(report)
    assert by["call-sequence"].detail == "not applicable: no Co-Simulation interface"
    assert [n for n in _CS if n in by] == ["call-sequence"]
    assert {n for n, i in called} >= set(_ME) and all(i == "me" or n in ("validate", "archive",
                                                      "binary") for n, i in called)


@pytest.mark.parametrize("fmi, name, why", [
    (2, "state-machine", "state-machine is an FMI 3.0 check; this FMU is FMI 2.0"),
    (3, "discard", "discard is the dronefly profile's check (--profile dronefly runs it); this "
                   "FMU is checked under the standard profile")])
def test_a_check_selected_by_name_that_is_not_listed_says_why(monkeypatch, fmi, name, why):
    """Selected by name on an FMU it is not for (FMI version, profile): said not applicable,
    with the reason, after the checks that run."""
    report, called, _ = _run(monkeypatch, _dahlquist(fmi), only=(name, "reset"))
    assert [(c.name, c.detail, c.skipped) for c in report.checks] == [
        ("reset", "reset ok", False), (name, f"not applicable: {why}", True)]
    assert called == [("reset", "cs")]


def test_only_and_skip_select_the_checks(monkeypatch):
    """CheckOptions.only and skip (rules.py): exactly the checks selected run."""
    report, called, _ = _run(monkeypatch, _dahlquist(2), skip=tuple(_ALL[1:]))
    assert [c.name for c in report.checks] == ["validate"]
    report, called, _ = _run(monkeypatch, _dahlquist(2), only=("reset", "me:state"))
    assert called == [("reset", "cs"), ("me:state", "me")]


def test_listed_is_the_version_the_profile_and_an_interface():
    """listed(): the FMI version and profile the table gives, and an interface the FMU has
    (or an announcing check)."""
    by = {c.name: c for c in checker.CHECKS}
    assert checker.listed(by["me:state"], 2, "standard", ("cs", "me"))
    assert not checker.listed(by["me:state"], 2, "standard", ("cs",))
    assert checker.listed(by["model-exchange"], 2, "standard", ("cs",))  # announces
    assert checker.listed(by["validate"], 3, "standard", ())
    assert not checker.listed(by["state-machine"], 2, "dronefly")
    assert checker.listed(by["discard"], 3, "dronefly") and not checker.listed(
        by["discard"], 3, "standard")


def test_a_file_that_is_no_fmu_and_an_experiment_without_a_step(monkeypatch, tmp_path):
    """A file that is not an FMU: one failed ``load``; a stop time before the start: one failed
    ``experiment``; no check runs."""
    bad = tmp_path / "x.fmu"
    bad.write_bytes(b"not a zip")
    report, called, _ = _run(monkeypatch, bad)
    assert [(c.name, c.passed, c.rule) for c in report.checks] == [
        ("load", False, "FMI 2.0 / 3.0 FMU archive")]
    assert "not an FMU" in report.checks[0].detail and called == []
    report, called, _ = _run(monkeypatch, _dahlquist(2), stop_time=-1.0)
    assert [(c.name, c.passed) for c in report.checks] == [("experiment", False)]
    assert report.checks[0].rule == ("FMI 2.0 4.2.2 / FMI 3.0 4.2: steps within the "
                                     "experiment") and called == []


def test_ctrl_c_between_two_checks_stops_the_run(monkeypatch):
    """Ctrl-C pending after two checks: KeyboardInterrupt before the third."""
    seen = []
    monkeypatch.setattr(checker, "pending", lambda: len(seen) >= 2)

    def count(ctx):
        seen.append(1)
        return "ok"

    with pytest.raises(KeyboardInterrupt):
        _run(monkeypatch, _dahlquist(2), {n: count for n in _ALL})
    assert len(seen) == 2


def test_durations_are_the_clocks_seconds_to_the_microsecond(monkeypatch):
    """Each check's duration: the clock's reading after it less the one before, rounded to 6
    decimals; the report's: the whole run's, unrounded (the module's clock stood in for: it
    advances 0.1234567891 s a reading)."""
    from types import SimpleNamespace

    readings = []

    def perf_counter():
        readings.append(100.0 + 0.1234567891 * len(readings))
        return readings[-1]

    monkeypatch.setattr(checker, "time", SimpleNamespace(perf_counter=perf_counter))
    report, _, _ = _run(monkeypatch, _dahlquist(2), profile="standard",
                        only=("validate", "reset"))
    assert [c.duration_s for c in report.checks] == [0.123457, 0.123457]
    assert len(readings) == 6  # the run's two readings and each check's two
    assert report.duration_s == pytest.approx(readings[-1] - readings[0], abs=1e-12)
