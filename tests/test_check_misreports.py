"""`dronefly check` reports each defect once, under the rule the FMU broke (four
defects once reported twice or under another rule), on FMUs built here: Reference-FMUs (``../shared/reference-fmus``) with an edited
modelDescription.xml or archive layout, or rebuilt with gcc from their shipped sources after an
edit that seeds one defect."""

from __future__ import annotations

import json
import re
import shutil
import sys
import zipfile
from dataclasses import replace
from pathlib import Path

import pytest

from dronefly.cli.app import main
from dronefly.harness.compliance.checker import CheckOptions
from dronefly.harness.compliance.suite import JSON_SCHEMA_FILE, check_fmu, reports_json
from dronefly.harness.cosim.fmu import FMU, FMUError
from fmu_helpers import rebuilt_reference_fmu

ROOT = Path(__file__).resolve().parents[1]
REF = ROOT.parent / "shared" / "reference-fmus"
pytestmark = pytest.mark.skipif(not REF.is_dir(), reason=f"the Reference-FMUs are not beside "
                                                         f"the checkout ({REF})")
needs_gcc = pytest.mark.skipif(sys.platform != "linux" or shutil.which("gcc") is None,
                               reason="rebuilding a Reference-FMU (binaries/linux64) needs gcc "
                                      "on Linux")


def _copy(src: Path, dst: Path, md_edits: tuple[tuple[bytes, bytes], ...] = (),
          rename: dict[str, str | None] | None = None) -> Path:
    """A copy of an FMU with modelDescription.xml edits (each ``old`` once: the first
    occurrence after the preceding edit's) and entries renamed (None: left out)."""
    rename = rename or {}
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w") as zout:
        for item in zin.infolist():
            data = zin.read(item.filename)
            name = item.filename
            for prefix, new in rename.items():
                if name.startswith(prefix):
                    name = None if new is None else new + name[len(prefix):]
                    break
            if name is None:
                continue
            if name == "modelDescription.xml":
                for old, new_text in md_edits:
                    assert old in data, old
                    data = data.replace(old, new_text, 1)
            zout.writestr(name, data)
    return dst


def _failed(report) -> dict:
    return {c.name: c for c in report.checks if not c.passed}


def _by_name(report) -> dict:
    return {c.name: c for c in report.checks}


# -- 1. static defects listed, each with its rule and section -------------------------------------
#: Feedthrough (FMI 2.0): an Enumeration declared continuous (2.2.7) and an output left out of
#: InitialUnknowns (2.2.8)
TWO_STATIC = ((b'valueReference="33" causality="input" variability="discrete"',
               b'valueReference="33" causality="input" variability="continuous"'),
              (b'<InitialUnknowns>\n      <Unknown index="5" dependencies="4" dependenciesKind='
               b'"constant"/>\n      <Unknown index="7" dependencies="6" dependenciesKind='
               b'"constant"/>\n      <Unknown index="9" dependencies="8" dependenciesKind='
               b'"constant"/>\n',
               b'<InitialUnknowns>\n      <Unknown index="5" dependencies="4" dependenciesKind='
               b'"constant"/>\n      <Unknown index="7" dependencies="6" dependenciesKind='
               b'"constant"/>\n'))


def test_every_static_problem_is_listed_with_its_section(tmp_path, capsys):
    """Both defects are listed, each with its section, under ``validate`` (not as an
    unreadable FMU), and the FMU's runtime checks still run and pass."""
    fmu = _copy(REF / "fmi2" / "Feedthrough.fmu", tmp_path / "Feedthrough.fmu", TWO_STATIC)
    report = check_fmu(fmu, fuzz=False, isolate=False)
    failed = _failed(report)
    assert set(failed) == {"validate"}, report.checks
    detail = failed["validate"].detail
    assert detail.startswith("2 problem(s): (1) FMI 2.0 2.2.7: The variable "
                             "\"Enumeration_input\" (line 87) is of type Enumeration and must "
                             "have variability != \"continuous\""), detail
    assert "(2) FMI 2.0 2.2.8: ModelStructure/InitialUnknowns does not contain the expected " \
           "set of variables" in detail
    assert _by_name(report)["call-sequence"].passed
    assert main(["check", "--no-fuzz", str(fmu)]) == 1
    assert "Enumeration_input" in capsys.readouterr().out


def test_an_unreadable_fmu_names_its_problems(tmp_path):
    """harness.cosim.fmu (every command): FMPy's reasons are kept in the one-line error, not
    only its first line ("Failed to validate modelDescription.xml:")."""
    fmu = _copy(REF / "fmi2" / "Feedthrough.fmu", tmp_path / "Feedthrough.fmu", TWO_STATIC)
    with pytest.raises(FMUError) as e:
        FMU(fmu)
    text = str(e.value)
    assert "\n" not in text
    assert text.endswith("is not a readable FMU: modelDescription.xml breaks 1 rule(s): The "
                         "variable \"Enumeration_input\" (line 87) is of type Enumeration and "
                         "must have variability != \"continuous\"."), text


# -- 2. a refused reset is reported once, under bad-input's rule -----------------------------------
@needs_gcc
def test_a_reset_refused_after_error_fails_bad_input_only(tmp_path):
    """Dahlquist rebuilt so that fmi2Reset after an fmi2Error is refused ("Illegal call
    sequence"; FMI 2.0 2.1.3 allows reset there): ``bad-input`` fails citing 2.1.3;
    ``logger-format`` (printf, FMI 2.0 2.1.5), which no longer relies on that reset, passes."""
    edits = {"fmi2Functions.c": [
        ("fmi2Status fmi2Reset(fmi2Component c) {\n    BEGIN_FUNCTION(Reset);\n",
         "static int refusedStep = 0;\n\nfmi2Status fmi2Reset(fmi2Component c) {\n"
         "    BEGIN_FUNCTION(Reset);\n    if (refusedStep) {\n"
         "        logError(S, \"fmi2Reset: Illegal call sequence.\");\n        CALL(Error);\n"
         "    }\n"),
        ("        logError(S, \"Communication step size must be > 0 but was %g.\", "
         "communicationStepSize);\n",
         "        logError(S, \"Communication step size must be > 0 but was %g.\", "
         "communicationStepSize);\n        refusedStep = 1;\n"),
    ]}
    fmu = rebuilt_reference_fmu(REF / "fmi2" / "Dahlquist.fmu", tmp_path / "Dahlquist.fmu", tmp_path / "src",
                   edits)
    report = check_fmu(fmu, fuzz=False)
    failed = _failed(report)
    assert set(failed) == {"bad-input"}, report.checks
    assert failed["bad-input"].detail.startswith(
        "communicationStepSize = 0.0: fmi2DoStep returned fmi2Error, then fmi2Reset, the call "
        "FMI 2.0 2.1.3 allows after it, returned fmi2Error"), failed["bad-input"].detail
    assert "2.1.3" in failed["bad-input"].rule
    assert _by_name(report)["logger-format"].passed


# -- 3. a platform gap is no failure; no implementation at all is -------------------------------
@pytest.mark.parametrize("version, here, other", [("fmi2", "linux64", "win64"),
                                                 ("fmi3", "x86_64-linux", "x86_64-windows")])
def test_a_binary_for_another_platform_only(tmp_path, capsys, version, here, other):
    """Dahlquist with its binary moved to another platform's folder: the static checks run and
    pass, the checks that call the FMU are skipped with the reason, the FMU passes (exit 0)."""
    fmu = _copy(REF / version / "Dahlquist.fmu", tmp_path / "Dahlquist.fmu",
                rename={f"binaries/{here}/Dahlquist.so": f"binaries/{other}/Dahlquist.dll"})
    report = check_fmu(fmu, fuzz=False)
    checks = _by_name(report)
    assert report.passed, report.checks
    assert checks["validate"].status == checks["archive"].status == "passed"
    assert checks["archive"].detail.startswith(f"binaries for {other}; sources")
    reason = f"not run: cannot run on {here}: binaries for {other} only"
    for name in ("call-sequence", "start-values", "reset", "bad-input", "logger-format"):
        assert checks[name].skipped and checks[name].detail == reason, checks[name]
    assert main(["check", str(fmu)]) == 0
    capsys.readouterr()


@pytest.mark.parametrize("version, section", [("fmi2", "FMI 2.0 2.3"), ("fmi3", "FMI 3.0 2.5")])
def test_no_implementation_at_all_fails_archive(tmp_path, version, section):
    """Neither binaries nor sources: ``archive`` fails citing the FMU Distribution section; the
    checks that would call the FMU are not run, with the reason."""
    fmu = _copy(REF / version / "Dahlquist.fmu", tmp_path / "Dahlquist.fmu",
                rename={"binaries/": None, "sources/": None})
    report = check_fmu(fmu, fuzz=False)
    failed = _failed(report)
    assert set(failed) == {"archive"}, report.checks
    assert f"({section}: an FMU is distributed in source code and/or binary form)" in \
        failed["archive"].detail
    assert failed["archive"].rule.startswith(section)
    assert _by_name(report)["call-sequence"].detail.endswith("no implementation (see archive)")


# -- 4. no call the standard forbids: a crash there is not blamed on printf ---------------------
@needs_gcc
def test_an_fmu_that_crashes_on_an_unknown_value_reference_passes(tmp_path):
    """Dahlquist rebuilt to segfault when asked for a value reference it does not have (a call
    FMI 2.0 forbids, as the Toolbox container does): no check makes that call, so every check
    passes and ``logger-format`` is not blamed for the crash."""
    edits = {"fmi2Functions.c": [
        ("    BEGIN_FUNCTION(GetReal)\n",
         "    for (size_t k = 0; k < nvr; k++) if (vr[k] > 1000) *(volatile int *)0 = 0;\n"
         "    BEGIN_FUNCTION(GetReal)\n")]}
    fmu = rebuilt_reference_fmu(REF / "fmi2" / "Dahlquist.fmu", tmp_path / "Dahlquist.fmu", tmp_path / "src",
                   edits)
    report = check_fmu(fmu, fuzz=False)
    assert report.passed, report.checks
    assert "instance '%s%s%s%s%n'" in _by_name(report)["logger-format"].detail


def test_dependent_checks_are_not_run_after_their_dependency_failed(monkeypatch):
    """Attribution: a run that the FMU cannot complete is reported once, under
    ``call-sequence``; reset and state (which would fail on the same finding) are ``not run``
    with the reason. (call-sequence's finding is seeded: Dahlquist completes its run.)"""
    from dronefly.harness.compliance import checker
    from dronefly.harness.compliance.rules import CheckFailed

    only = CheckOptions(only=("call-sequence", "reset", "state"))
    report = check_fmu(REF / "fmi2" / "Dahlquist.fmu", fuzz=False, isolate=False, options=only)
    assert report.passed and not any(c.skipped for c in report.checks)

    def broken(ctx):
        raise CheckFailed("seeded")

    monkeypatch.setattr(checker, "CHECKS", tuple(
        replace(c, fn=broken) if c.name == "call-sequence" else c for c in checker.CHECKS))
    report = check_fmu(REF / "fmi2" / "Dahlquist.fmu", fuzz=False, isolate=False, options=only)
    checks = _by_name(report)
    assert [n for n, c in checks.items() if not c.passed] == ["call-sequence"]
    for name in ("reset", "state"):
        assert checks[name].skipped and checks[name].detail == (
            "not run: it depends on call-sequence, which failed (the finding is reported "
            "there)"), checks[name]


# -- the static rules beyond FMPy's validation: one seeded defect each ----------------------------
_BB_E = b'<Real start="0.7" min="0.5" max="1"/>'
_BB_H = b'<Real start="1" reinit="true" declaredType="Position"/>'
#: (FMU, [(old, new)], the problem validate lists, with its section)
STATIC = {
    "start below min": ("fmi2/BouncingBall.fmu", [(_BB_E, b'<Real start="0.7" min="0.8" max="1"/>')],
                        "FMI 2.0 2.2.7: variable 'e': start 0.7 < min 0.8"),
    "nominal not positive": ("fmi2/BouncingBall.fmu",
                             [(_BB_E, b'<Real start="0.7" min="0.5" max="1" nominal="-1"/>')],
                             "FMI 2.0 2.2.7: variable 'e': nominal -1.0 is not > 0"),
    "unit not defined": ("fmi2/BouncingBall.fmu",
                         [(b'<Real start="0.7" min="0.5"', b'<Real unit="km" start="0.7" min="0.5"')],
                         "FMI 2.0 2.2.2: variable 'e': unit 'km' is not among the "
                         "UnitDefinitions"),
    "display unit not of the unit": (
        "fmi2/BouncingBall.fmu", [(_BB_H, _BB_H.replace(b"/>", b' displayUnit="ft"/>'))],
        "FMI 2.0 2.2.2: variable 'h': displayUnit 'ft' is not a DisplayUnit of unit 'm'"),
    "start of a calculated variable": (
        "fmi2/BouncingBall.fmu", [(b'<Real derivative="2" declaredType="Velocity"/>',
                                   b'<Real derivative="2" declaredType="Velocity" start="0"/>')],
        "FMI 2.0 2.2.7: variable 'der(h)': a start value with initial 'calculated'"),
    "outputs out of order": (
        "fmi2/BouncingBall.fmu", [(b'<Unknown index="2" dependencies=""/>\n      <Unknown '
                                   b'index="4" dependencies=""/>',
                                   b'<Unknown index="4" dependencies=""/>\n      <Unknown '
                                   b'index="2" dependencies=""/>')],
        "FMI 2.0 2.2.8: ModelStructure/Outputs: indices not in ascending order or repeated "
        "(4, 2)"),
    "derivative that is a state": (
        "fmi2/BouncingBall.fmu", [(b'<Derivatives>\n      <Unknown index="3"',
                                   b'<Derivatives>\n      <Unknown index="2"')],
        "FMI 2.0 2.2.8: ModelStructure/Derivatives: 'h' is not the derivative of a state"),
    "fmi3 start above max": (
        "fmi3/BouncingBall.fmu", [(b'start="0.7" min="0.5" max="1"', b'start="0.7" min="0.5" '
                                                                     b'max="0.6"')],
        "FMI 3.0 2.4.7: variable 'e': start 0.7 > max 0.6"),
    "fmi3 dimension of a plain parameter": (
        "fmi3/StateSpace.fmu", [(b'name="m" valueReference="1" description="Number of inputs" '
                                 b'causality="structuralParameter"',
                                 b'name="m" valueReference="1" description="Number of inputs" '
                                 b'causality="parameter"')],
        "FMI 3.0 2.4.7: variable 'B': a dimension given by 'm', not a structural parameter or "
        "constant of an unsigned integer type"),
}


def test_aliases_of_two_variabilities_pass_validate_with_a_note(tmp_path):
    """FMI 2.0 lets aliases differ in "other parts of the variable definition" (the paragraph
    on value references; fmi-standard issue #436: the highest variability governs), as Dymola
    exports them (a tunable local beside a continuous output): validate passes, with a note."""
    fmu = _copy(REF / "fmi2/BouncingBall.fmu", tmp_path / "BouncingBall.fmu",
                ((b"  </ModelVariables>",
                  b'    <ScalarVariable name="h_alias" valueReference="1" causality="local" '
                  b'variability="discrete" initial="calculated">\n      <Real/>\n'
                  b"    </ScalarVariable>\n  </ModelVariables>"),))
    report = check_fmu(fmu, fuzz=False, isolate=False)
    validate = next(c for c in report.checks if c.name == "validate")
    assert validate.passed and not validate.skipped, validate
    assert "aliases 'h', 'h_alias' (value reference 1) differ in variability" in validate.warning


@pytest.mark.parametrize("defect", list(STATIC))
def test_a_static_defect_fails_validate_only_with_its_section(tmp_path, defect):
    src, edits, problem = STATIC[defect]
    fmu = _copy(REF / src, tmp_path / Path(src).name, tuple(edits))
    report = check_fmu(fmu, fuzz=False, isolate=False)
    failed = _failed(report)
    assert set(failed) == {"validate"}, report.checks
    assert problem in failed["validate"].detail, failed["validate"].detail


# -- the binary: exported functions, version strings, what the logger gets ------------------------
BINARY = {
    "a function not exported": (
        {"fmi2Functions.c": [("fmi2Status fmi2CancelStep(fmi2Component c) {",
                              "static fmi2Status notExported(fmi2Component c) {")]},
        "not exported: fmi2CancelStep"),
    "a wrong version string": (
        {"fmi2Functions.c": [("const char* fmi2GetVersion(void) {\n    return fmi2Version;",
                              "const char* fmi2GetVersion(void) {\n    return \"2.1\";")]},
        "fmi2GetVersion() returned '2.1', not '2.0'"),
    "a logger given another instance name": (
        {"cosimulation.c": [("comp->logger(comp->componentEnvironment, comp->instanceName, "
                             "status, category, buf);",
                             "comp->logger(comp->componentEnvironment, \"someone\", status, "
                             "category, buf);")]},
        "the logger got instance name 'someone', not 'dronefly binary check'"),
    "a logger given another environment": (
        {"cosimulation.c": [("comp->logger(comp->componentEnvironment, comp->instanceName, "
                             "status, category, buf);",
                             "comp->logger(NULL, comp->instanceName, status, category, buf);")]},
        "the logger got componentEnvironment None, not the 0x5eed the host passed"),
}
#: the check each defect of BINARY fails
BINARY_CHECK = {"a function not exported": "binary", "a wrong version string": "binary",
                "a logger given another instance name": "logger-format",
                "a logger given another environment": "logger-format"}


@needs_gcc
@pytest.mark.parametrize("defect", list(BINARY))
def test_a_binary_defect_fails_binary_only(tmp_path, defect):
    """Dahlquist rebuilt from its sources with one defect of its binary: ``binary`` (exports,
    version strings) or ``logger-format`` (what the logger is given) fails, naming it, and no
    other check."""
    edits, detail = BINARY[defect]
    fmu = rebuilt_reference_fmu(REF / "fmi2" / "Dahlquist.fmu", tmp_path / "Dahlquist.fmu", tmp_path / "src",
                   edits)
    report = check_fmu(fmu, fuzz=False)
    failed = _failed(report)
    check = BINARY_CHECK[defect]
    assert set(failed) == {check}, report.checks
    assert failed[check].detail.startswith(detail), failed[check].detail


# -- the Outputs dependency lie, caught in Step Mode ------------------------------------------------
OUTPUTS_LIE = {
    "fmi2": (b'<Unknown index="5" dependencies="4" dependenciesKind="constant"/>',
             b'<Unknown index="5" dependencies=""/>'),
    "fmi3": (b'<Output valueReference="8" dependencies="7" dependenciesKind="constant"/>',
             b'<Output valueReference="8" dependencies=""/>'),
}


#: what ``me:dependencies`` says of the lie: found by a get after a set in Continuous-Time Mode
ME_LIE = ("Float64_continuous_output (declared in Outputs with no dependency among the inputs) "
          "changed when only Float64_continuous_input was set, through Model Exchange (set, "
          "then get")


@pytest.mark.parametrize("version", list(OUTPUTS_LIE))
def test_an_outputs_dependency_lie_fails_dependencies_only(tmp_path, version):
    """Feedthrough with Float64_continuous_output declared in <Outputs> without a dependency
    (InitialUnknowns left truthful) while it follows Float64_continuous_input directly: two
    continuations from one saved FMU state, with the input as it was and moved, differ by O(1)
    over a step of 1e-3 and of 1e-4 of the run's: ``dependencies`` fails; through Model
    Exchange, a get after a set in Continuous-Time Mode sees it: ``me:dependencies`` fails;
    no other check, FMI 2.0 and 3.0 alike."""
    fmu = _copy(REF / version / "Feedthrough.fmu", tmp_path / "Feedthrough.fmu",
                (OUTPUTS_LIE[version],))
    report = check_fmu(fmu, fuzz=False, isolate=False)
    failed = _failed(report)
    assert set(failed) == {"dependencies", "me:dependencies"}, report.checks
    assert failed["dependencies"].detail.startswith(
        "Float64_continuous_output (declared in Outputs with no dependency among the inputs) "
        "changed when only Float64_continuous_input was set, in Step Mode"), \
        failed["dependencies"].detail
    assert failed["me:dependencies"].detail.startswith(ME_LIE), failed["me:dependencies"].detail


# -- Model Exchange -----------------------------------------------------------------------------
def _me_only(src: Path, dst: Path, md_edits: tuple[tuple[bytes, bytes], ...] = ()) -> Path:
    """A copy of a Reference-FMU with its <CoSimulation> element left out (Model Exchange
    only) and ``md_edits``."""
    text = zipfile.ZipFile(src).read("modelDescription.xml")
    cs = re.search(rb"<CoSimulation[^>]*/>|<CoSimulation\b.*?</CoSimulation>", text, re.S)
    assert cs is not None
    return _copy(src, dst, ((cs.group(0), b""), *md_edits))


#: the Model Exchange checks, each passed or said not to apply (no inputs, no exact start)
ME_CHECKS = ("model-exchange", "me:call-sequence", "me:start-values", "me:dependencies",
             "me:reset", "me:two-instances", "me:state")


@pytest.mark.parametrize("version", ["fmi2", "fmi3"])
@pytest.mark.parametrize("model", ["Feedthrough", "Stair"])
def test_a_model_exchange_only_fmu_is_checked(tmp_path, model, version):
    """A Reference-FMU without its <CoSimulation> element is checked, not declined (in its
    checking process, as the CLI runs it): the static and binary checks (the Model Exchange
    functions) and every Model Exchange check pass; of the Co-Simulation checks only
    ``call-sequence`` is listed, saying it does not apply. Stair's reset holds through Model
    Exchange (see :func:`test_stairs_reset_defect_is_its_co_simulation_step_only`)."""
    fmu = _me_only(REF / version / f"{model}.fmu", tmp_path / f"{model}.fmu")
    assert "<CoSimulation" not in zipfile.ZipFile(fmu).read("modelDescription.xml").decode()
    report = check_fmu(fmu, fuzz=False)
    assert not report.skipped, report.skipped
    assert report.passed, [c for c in report.checks if not c.passed]
    by = _by_name(report)
    assert [c.name for c in report.checks] == ["validate", "archive", "binary",
                                               "call-sequence", *ME_CHECKS]
    assert by["call-sequence"].detail == "not applicable: no Co-Simulation interface"
    assert by["binary"].passed and not by["binary"].skipped, by["binary"]
    run = ["model-exchange", "me:call-sequence", "me:reset", "me:two-instances", "me:state"]
    if model == "Feedthrough":
        run.append("me:dependencies")
    for name in run:
        assert by[name].status == "passed", by[name]
    # its --json document validates against the shipped schema, the me: names included
    import jsonschema

    doc = reports_json([report])
    jsonschema.validate(doc, json.loads(JSON_SCHEMA_FILE.read_text(encoding="utf-8")))
    assert "me:reset" in [c["name"] for c in doc["fmus"][0]["checks"]]


@pytest.mark.parametrize("version", list(OUTPUTS_LIE))
def test_an_outputs_dependency_lie_in_a_model_exchange_only_fmu(tmp_path, version):
    """The Outputs dependency lie in a Feedthrough with Model Exchange only: a get after a set
    in Continuous-Time Mode sees Float64_continuous_output follow its input; only
    ``me:dependencies`` fails, FMI 2.0 and 3.0 alike."""
    fmu = _me_only(REF / version / "Feedthrough.fmu", tmp_path / "Feedthrough.fmu",
                   (OUTPUTS_LIE[version],))
    report = check_fmu(fmu, fuzz=False, isolate=False)
    failed = _failed(report)
    assert set(failed) == {"me:dependencies"}, report.checks
    assert failed["me:dependencies"].detail.startswith(ME_LIE), failed["me:dependencies"].detail


#: Float64_discrete_output declared in <Outputs> without its dependency on
#: Float64_discrete_input (InitialUnknowns left truthful)
DISCRETE_LIE = {
    "fmi2": (b'<Unknown index="7" dependencies="6" dependenciesKind="constant"/>',
             b'<Unknown index="7" dependencies=""/>'),
    "fmi3": (b'<Output valueReference="10" dependencies="9" dependenciesKind="constant"/>',
             b'<Output valueReference="10" dependencies=""/>'),
}


@pytest.mark.parametrize("version", list(DISCRETE_LIE))
def test_a_discrete_outputs_dependency_lie_in_a_model_exchange_only_fmu(tmp_path, version):
    """The Outputs dependency lie on a discrete input, through Model Exchange only: the input
    can be set in Event Mode only (FMI 2.0 3.2.3, FMI 3.0 3.2.3), and a get after the set there
    sees Float64_discrete_output follow Float64_discrete_input; only ``me:dependencies``
    fails, FMI 2.0 and 3.0 alike."""
    fmu = _me_only(REF / version / "Feedthrough.fmu", tmp_path / "Feedthrough.fmu",
                   (DISCRETE_LIE[version],))
    report = check_fmu(fmu, fuzz=False, isolate=False)
    failed = _failed(report)
    assert set(failed) == {"me:dependencies"}, report.checks
    assert failed["me:dependencies"].detail.startswith(
        "Float64_discrete_output (declared in Outputs with no dependency among the inputs) "
        "changed when only Float64_discrete_input was set, through Model Exchange"), \
        failed["me:dependencies"].detail


@pytest.mark.parametrize("version", ["fmi2", "fmi3"])
def test_stairs_reset_defect_is_its_co_simulation_step_only(version):
    """Stair at its default experiment fails ``reset`` through Co-Simulation and passes
    ``me:reset``. Its sources' reset() (cosimulation.c) leaves terminateSimulation true from
    the first run; only fmi2DoStep / fmi3DoStep read that flag (the run after the reset ends
    at its first step). Through Model Exchange the flag is recomputed by eventUpdate (model.c:
    terminateSimulation = counter >= 10) in the event iteration of initialization before any
    function reports it, and the counter and nextEventTime are reset by setStartValues: the
    run after fmi2Reset / fmi3Reset equals the first, to its end at 9 s. ``me:state`` passes:
    a restored FMU state keeps its next time event."""
    report = check_fmu(REF / version / "Stair.fmu", fuzz=False, isolate=False,
                       options=CheckOptions(only=("call-sequence", "reset", "model-exchange",
                                                  "me:call-sequence", "me:reset", "me:state")))
    by = _by_name(report)
    assert set(_failed(report)) == {"reset"}, report.checks
    assert by["reset"].detail.startswith(f"the run after fmi{version[-1]}Reset differs from "
                                         "the first: the FMU ended it at t = 0.2 s")
    assert by["me:reset"].status == "passed"
    # its time events (nextEventTime) kept with a saved FMU state: restored at t = 5 s, the
    # counter steps at 6, 7, 8 s and the run ends at 9 s as the original did
    assert by["me:state"].status == "passed", by["me:state"]
    assert "the FMU ended the run at t = 9 s" in by["me:call-sequence"].detail


@pytest.mark.parametrize("version", ["fmi2", "fmi3"])
@pytest.mark.parametrize("model", ["BouncingBall", "Dahlquist", "Stair", "VanDerPol"])
def test_reference_fmus_pass_model_exchange(model, version):
    """The Reference-FMUs with both interfaces pass ``model-exchange`` (FMPy's Model Exchange
    simulation with CVODE and its event handling; Stair's terminateSimulation at 9 s ends it)."""
    c = _by_name(check_fmu(REF / version / f"{model}.fmu", fuzz=False, isolate=False,
                           options=CheckOptions(only=("model-exchange",))))["model-exchange"]
    assert c.passed and not c.skipped, c
    assert "event iteration at initialization: 1 iteration(s); FMPy's Model Exchange " \
           "simulation (CVODE) to t = " in c.detail


@needs_gcc
def test_an_event_iteration_that_never_ends_fails_model_exchange(tmp_path):
    """Dahlquist rebuilt so that fmi2NewDiscreteStates always asks for another iteration:
    ``model-exchange`` fails (the event iteration must terminate), no other check (the other
    Model Exchange checks are not run: they depend on it)."""
    edits = {"fmi2Functions.c": [
        ("    eventInfo->newDiscreteStatesNeeded           = S->newDiscreteStatesNeeded;",
         "    eventInfo->newDiscreteStatesNeeded           = fmi2True;")]}
    fmu = rebuilt_reference_fmu(REF / "fmi2" / "Dahlquist.fmu", tmp_path / "Dahlquist.fmu", tmp_path / "src",
                   edits)
    report = check_fmu(fmu, fuzz=False)
    failed = _failed(report)
    assert set(failed) == {"model-exchange"}, report.checks
    assert failed["model-exchange"].detail.startswith(
        "the event iteration of initialization did not terminate in 1000 iterations")
    by = _by_name(report)
    for name in ME_CHECKS[1:]:
        assert by[name].detail.startswith("not run: it depends on model-exchange"), by[name]
