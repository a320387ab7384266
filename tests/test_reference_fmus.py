"""`dronefly check` on FMUs we did not write: the Modelica Reference-FMUs (v0.0.41, in
``../shared/reference-fmus``). They are correct FMUs (``fmpy validate`` finds no problem): a
check that fails one must cite the rule of the standard it breaks. Each known false positive
of a check on them has an assertion here on the FMU that shows it; seeded defects
are copies of Reference-FMUs with an edited modelDescription.xml or rebuilt from their shipped
sources with one edit, each failing exactly the check that names its rule."""

from __future__ import annotations

import json
import shutil
import sys
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path


import pytest
from shared_files import ON_CI, need_shared
from fmu_helpers import rebuilt_reference_fmu

from dronefly.cli.app import main
from dronefly.harness.compliance.checker import CheckOptions
from dronefly.harness.compliance.suite import JSON_SCHEMA, check_fmu, format_reports

ROOT = Path(__file__).resolve().parents[1]
REF = ROOT.parent / "shared" / "reference-fmus"
FMUS = sorted(str(p.relative_to(REF)) for p in REF.glob("fmi[23]/*.fmu")) if REF.is_dir() else []

#: Roberts' default experiment runs to 1e8 s: 1 s is 100 steps
STOP = {"fmi3/Roberts.fmu": 1.0}


@pytest.fixture(scope="module")
def ref() -> Path:
    need_shared(REF, "the Reference-FMUs")
    return REF


def _check(ref: Path, name: str, **options) -> object:
    options.setdefault("stop_time", STOP.get(name))
    return check_fmu(ref / name, fuzz=True, isolate=False, options=CheckOptions(**options))


def _by_name(report) -> dict:
    return {c.name: c for c in report.checks}


@pytest.mark.parametrize("name", FMUS or ["(none)"])
def test_every_reference_fmu_passes(ref, name):
    """Every Co-Simulation Reference-FMU passes under the default (standard) profile; each
    check names its rule and section; Clocks (Scheduled Execution only) is skipped with a
    one-line reason. Stair's default experiment is checked in
    :func:`test_stair_ends_its_run_and_its_reset_keeps_the_end`."""
    if name == "(none)":
        need_shared(REF / "fmi2", "the Reference-FMUs' builds")
    report = _check(ref, name, stop_time=STOP.get(name, 8.0 if "Stair" in name else None))
    if name.endswith("Clocks.fmu"):  # J
        assert report.skipped.startswith("not checked: Scheduled Execution only")
        assert report.passed and not report.checks
        return
    assert report.profile == "standard"
    assert report.passed, [c for c in report.checks if not c.passed]
    version = "FMI 3.0" if name.startswith("fmi3") else "FMI 2.0"
    for c in report.checks:
        assert c.rule.startswith((version, "FMI cross-check", "dronefly")), c
    status = {c.name: c.status for c in report.checks}
    # the dronefly profile's checks do not run on a foreign FMU (B, E, F)
    assert "discard" not in status and "state-refusal" not in status and "fuzz" not in status
    assert status["validate"] == status["call-sequence"] == status["reset"] == "passed"
    assert status["reference"] == "skipped"


def test_error_is_followed_by_reset_not_by_a_step(ref):
    """A: a step of size 0 is answered fmi2Error; the check then resets (FMI 2.0 2.1.3)."""
    c = _by_name(_check(ref, "fmi2/BouncingBall.fmu"))["bad-input"]
    assert c.passed and "communicationStepSize = 0.0: Error" in c.detail
    assert "fmi2Reset recovered the instance" in c.detail and "2.1.3" in c.rule


def test_nan_is_our_promise_not_the_standards(ref):
    """B: Feedthrough takes a NaN input with OK: fine by the standard; the dronefly profile
    (our FMUs' promise) fails it."""
    assert _by_name(_check(ref, "fmi2/Feedthrough.fmu"))["bad-input"].passed
    ours = _by_name(_check(ref, "fmi2/Feedthrough.fmu", profile="dronefly", only=("bad-input",)))
    assert not ours["bad-input"].passed
    assert ours["bad-input"].detail.startswith("Float64_continuous_input = nan: fmi2DoStep "
                                               "returned fmi2OK")


@pytest.mark.parametrize("version", ["fmi2", "fmi3"])
def test_stair_ends_its_run_and_its_reset_keeps_the_end(ref, version):
    """D, H: Stair asks to stop at t = 9 s (FMI 2.0: fmi2Discard with fmi2Terminated, 4.2.3;
    FMI 3.0: terminateSimulation): the run ends there cleanly and no other check stumbles
    on it. Its fmi2Reset / fmi3Reset does not clear that request (the next run ends after
    one step): a real defect of the FMU, cited to FMI 2.0 2.1.6 / FMI 3.0 fmi3Reset, the only
    check that fails."""
    report = _check(ref, f"{version}/Stair.fmu")
    checks = _by_name(report)
    assert "the FMU ended the run at t = 9 s" in checks["call-sequence"].detail
    failed = {n for n, c in checks.items() if not c.passed}
    assert failed == {"reset"}, report.checks
    assert "ended it at t = 0.2 s, the first at t = 9 s" in checks["reset"].detail
    assert "Reset" in checks["reset"].rule


def test_fmi3_state_machine_wording_and_corrupt_state_are_our_profile(ref):
    """E, F: the standard asks for fmi3Error, which the FMU returns; our log wording and
    the refusal of corrupt state bytes are the dronefly profile's."""
    std = _by_name(_check(ref, "fmi3/Dahlquist.fmu"))
    assert std["state-machine"].passed and "state-refusal" not in std
    ours = _by_name(_check(ref, "fmi3/Dahlquist.fmu", profile="dronefly",
                           only=("state-machine", "state-refusal")))
    assert "not allowed in state 'instantiated'" in ours["state-machine"].detail
    assert not ours["state-refusal"].passed


def test_float32_read_with_its_own_call(ref):
    """G: Feedthrough's Float32 output follows its Float32 input, read with fmi3GetFloat32
    (fmi3GetFloat64 on it is refused). Float32 holds 0.25 exactly."""
    from dronefly.harness.cosim.fmu import FMU

    with FMU(ref / "fmi3" / "Feedthrough.fmu") as fmu, fmu.instantiate("g") as inst:
        s = inst.slave
        s.setupExperiment(startTime=0.0)
        s.enterInitializationMode()
        s.exitInitializationMode()
        s.setReal([fmu.vr("Float32_continuous_input")], [0.25])
        s.doStep(currentCommunicationPoint=0.0, communicationStepSize=0.1)
        assert s.getReal([fmu.vr("Float32_continuous_output")]) == [0.25]


@pytest.mark.parametrize("name", ["StateSpace", "LinearTransform-v0.0.27"])
def test_array_extent_from_a_structural_parameter(ref, name):
    """I: array dimensions given by a structural parameter (m, n): the arrays are read."""
    report = _check(ref, f"fmi3/{name}.fmu", only=("start-values", "dependencies"))
    assert report.passed and "start-values" in _by_name(report)


def test_cli_on_reference_fmus_json_junit_jobs(ref, tmp_path, capsys):
    """K, J and CI: --stop-time, -j 2, --json (schema, skipped distinct from passed,
    durations) and --junit (a test case per check and FMU); exit 0."""
    junit = tmp_path / "check.xml"
    paths = [str(ref / "fmi3" / "Roberts.fmu"), str(ref / "fmi3" / "Clocks.fmu"),
             str(ref / "fmi2" / "Dahlquist.fmu")]
    assert main(["check", "--stop-time", "1", "-j", "2", "--json", "--junit", str(junit),
                 *paths]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["schema"] == JSON_SCHEMA
    fmus = {Path(f["fmu"]).name: f for f in doc["fmus"]}
    assert fmus["Clocks.fmu"]["status"] == "skipped"
    roberts = {c["name"]: c for c in fmus["Roberts.fmu"]["checks"]}
    assert roberts["reference"]["status"] == "skipped" and roberts["reference"]["skipped"]
    assert roberts["call-sequence"]["status"] == "passed"
    assert roberts["call-sequence"]["duration_s"] > 0
    suites = ET.parse(junit).getroot().findall("testsuite")
    assert len(suites) == 3
    for s in suites:
        name = Path(s.get("name")).name
        cases = s.findall("testcase")
        expected = 1 if name == "Clocks.fmu" else len(fmus[name]["checks"])
        assert len(cases) == expected
        assert all(float(c.get("time")) >= 0 for c in cases)
        assert sum(c.find("skipped") is not None for c in cases) == int(s.get("skipped"))


def test_cli_clocks_one_line_and_bad_options(ref, capsys):
    assert main(["check", str(ref / "fmi3" / "Clocks.fmu")]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].endswith("SKIP (not checked: Scheduled Execution only, no Co-Simulation or "
                           "Model Exchange interface (dronefly check tests those two))")
    assert out[-1] == "0 of 0 FMUs passed, 1 not checked"
    assert main(["check", "--check", "nope", str(ref / "fmi3" / "Clocks.fmu")]) == 2
    assert "--check 'nope': no such check" in capsys.readouterr().err


# -- seeded defects: copies with an edited modelDescription.xml --------------------------------
def _edited(src: Path, dst: Path, old: bytes, new: bytes) -> Path:
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w") as zout:
        for item in zin.infolist():
            data = zin.read(item.filename)
            if item.filename == "modelDescription.xml":
                assert data.count(old) >= 1
                data = data.replace(old, new)
            zout.writestr(item, data)
    return dst


#: (FMU, original text, edited text, the check that must fail, the start of its detail)
SEEDED = {
    # a parameter declared -2.0 that holds -9.81
    "start-value-lie": ("fmi2/BouncingBall.fmu",
                        b'<Real start="-9.81" declaredType="Acceleration"/>',
                        b'<Real start="-2.0" declaredType="Acceleration"/>',
                        ("start-values", "me:start-values"),
                        "g: declared start -2.0, holds -9.81"),
    # an output declared without direct feedthrough (Outputs and InitialUnknowns) that
    # follows its input
    "dependency-lie": ("fmi2/Feedthrough.fmu",
                       b'<Unknown index="5" dependencies="4" dependenciesKind="constant"/>',
                       b'<Unknown index="5" dependencies=""/>',
                       ("dependencies", "me:dependencies"),
                       "Float64_continuous_output (declared in InitialUnknowns with no "
                       "dependency among the inputs) changed when only Float64_continuous_input "
                       "was set, in Initialization Mode"),
    # a state the FMU does not declare it can restore: not applicable, not failed
}


@pytest.mark.parametrize("defect", list(SEEDED))
def test_seeded_defect_fails_only_its_check(ref, tmp_path, defect):
    """Each seeded defect of the model description fails its check, through Co-Simulation and
    through Model Exchange (the FMUs have both interfaces), and no other."""
    src, old, new, checks, detail = SEEDED[defect]
    fmu = _edited(ref / src, tmp_path / Path(src).name, old, new)
    report = check_fmu(fmu, fuzz=False, isolate=False)
    failed = {c.name: c for c in report.checks if not c.passed}
    assert set(failed) == set(checks), report.checks
    for check in checks:
        assert failed[check].detail.startswith(detail)
        assert f"[FAIL] {check:<14} {detail}" in format_reports([report])


def _rebuilt(src: Path, dst: Path, work: Path, source: str, old: str, new: str) -> Path:
    """A copy of a Reference-FMU (FMI 2.0, linux64) whose binary is rebuilt with gcc from its
    own ``sources/`` after one edit of ``source`` (the FMI headers are fmpy's)."""
    return rebuilt_reference_fmu(src, dst, work, {source: [(old, new)]})


@pytest.mark.skipif(sys.platform != "linux" or shutil.which("gcc") is None and not ON_CI,
                    reason="rebuilding a Reference-FMU (binaries/linux64) needs gcc on Linux")
def test_a_reset_that_does_nothing_fails_reset_only(ref, tmp_path):
    """Dahlquist whose fmi2Reset keeps the state (its start values are not set again): the run
    after the reset continues from the first run's end. Only ``reset`` fails (FMI 2.0 2.1.6),
    and ``me:reset`` (the reset is shared by both interfaces); ``bad-input``, which resets
    after each refused call, still recovers the instance."""
    reset = ("    comp->status = OK;\n    setStartValues(comp);\n    comp->isDirtyValues = true;\n",
             "    comp->status = OK;\n")
    fmu = _rebuilt(ref / "fmi2/Dahlquist.fmu", tmp_path / "Dahlquist.fmu", tmp_path / "src",
                   "cosimulation.c", *reset)
    report = check_fmu(fmu, fuzz=False, isolate=False)
    failed = {c.name: c for c in report.checks if not c.passed}
    assert set(failed) == {"reset", "me:reset"}, report.checks
    assert failed["reset"].detail == "the run after fmi2Reset differs from the first"
    assert failed["me:reset"].detail == "the run after fmi2Reset differs from the first"
    # that a rebuild alone breaks nothing: the mended Stair below passes every check


@pytest.mark.skipif(sys.platform != "linux" or shutil.which("gcc") is None and not ON_CI,
                    reason="rebuilding a Reference-FMU (binaries/linux64) needs gcc on Linux")
def test_stair_with_its_reset_mended_passes_every_check(ref, tmp_path):
    """Stair's one failed check is its reset (above): its sources set terminateSimulation to
    false when instantiated (cosimulation.c) and never in reset(). Rebuilt with that one line
    in reset(), Stair passes every check at its default experiment, reset included."""
    fmu = _rebuilt(ref / "fmi2/Stair.fmu", tmp_path / "Stair.fmu", tmp_path / "src",
                   "cosimulation.c", "    comp->nSteps = 0;\n",
                   "    comp->nSteps = 0;\n    comp->terminateSimulation = false;\n")
    report = check_fmu(fmu, fuzz=False, isolate=False)
    assert report.passed, report.checks
    assert "the FMU ended the run at t = 9 s" in _by_name(report)["call-sequence"].detail


def test_docs_table_names_every_check():
    """docs/compliance.md has a row per check (the code's names)."""
    from dronefly.harness.compliance.checker import CHECK_NAMES

    text = (ROOT / "docs" / "compliance.md").read_text(encoding="utf-8")
    for name in [*CHECK_NAMES, "fuzz"]:
        assert f"| `{name}` |" in text, name


# -- the master on the Reference-FMUs: against fmpy.simulate_fmu and the reference results -------
#: the models whose reference result (results/<model>_out.csv) is of their default experiment
#: and of outputs the master records (Roberts_out.csv holds BouncingBall's columns: not used)
MASTER_MODELS = ["BouncingBall", "Dahlquist", "Stair", "VanDerPol", "Resource", "StateSpace"]


def _reference_csv(model: str):
    """(column names, time, values) of a reference result; an array column (``y`` written as
    "1 2 3") becomes one column per element, ``y[1]``, ``y[2]``, ..."""
    import numpy as np

    lines = (REF / "results" / f"{model}_out.csv").read_text().splitlines()
    heads = lines[0].split(",")[1:]
    first = lines[1].split(",")[1:]
    names = [f"{h}[{k + 1}]" if len(c.split()) > 1 else h
             for h, c in zip(heads, first) for k in range(len(c.split()))]
    rows = np.array([[float(x) for cell in ln.split(",") for x in cell.split()]
                     for ln in lines[1:]])
    return names, rows[:, 0], rows[:, 1:]


@pytest.mark.parametrize("model, version", [
    (m, v) for m in MASTER_MODELS for v in ("fmi2", "fmi3")
    if (m, v) != ("StateSpace", "fmi2")])  # StateSpace has no FMI 2.0 build: not a case
def test_master_equals_fmpy_and_the_reference_results(ref, model, version):
    """The system master on one Reference-FMU at the reference result's communication step:
    its Real and Integer outputs equal FMPy's simulate_fmu (the same FMU and the same steps:
    up to the rounding of the time grid, 1e-12) and the reference result written by fmusim
    (printed with 8 significant digits: 1e-7 relative). Stair's run ends at 9 s, the last row
    recorded there, as FMPy's. StateSpace (FMI 3.0 only): an array output, read element-wise
    on the master's raw path."""
    import fmpy
    import numpy as np

    from dronefly.harness.cosim.system import System
    from dronefly.harness.cosim.system_master import SystemMaster

    path = ref / version / f"{model}.fmu"
    need_shared(path, f"the {version} build of {model}")
    names, t_ref, y_ref = _reference_csv(model)
    h = float(t_ref[1] - t_ref[0])
    stop = float(fmpy.read_model_description(str(path)).defaultExperiment.stopTime)
    n = int(round(stop / h))
    with SystemMaster(System({"m": path})) as master:
        run = master.run(h, n)
    assert run.failure is None
    ours = {name.split(".", 1)[1]: run.signals[:, j] for j, name in enumerate(run.names)}
    plain = sorted({n.split("[")[0] for n in names})
    fm = fmpy.simulate_fmu(str(path), fmi_type="CoSimulation", output_interval=h,
                           stop_time=stop, output=plain)

    def fmpy_column(name: str):
        base, _, index = name.partition("[")
        col = fm[base]
        return (col[:, int(index[:-1]) - 1] if index else col).astype(float)

    assert len(run.time) == len(fm["time"]) == len(t_ref)
    np.testing.assert_allclose(run.time, fm["time"], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(run.time, t_ref, rtol=1e-7, atol=1e-12)
    for j, name in enumerate(names):
        np.testing.assert_allclose(ours[name], fmpy_column(name), rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(ours[name], y_ref[:, j], rtol=1e-7, atol=1e-9)


@pytest.mark.parametrize("version", ["fmi2", "fmi3"])
def test_master_on_feedthrough_equals_fmpy_and_the_reference_result(ref, version):
    """Feedthrough, every output the master records (Float32 and Float64, the integer types up
    to Int32, Boolean, Enumeration) against FMPy's simulate_fmu and fmusim's reference result
    (of the FMI 3.0 build; its run set no inputs: every output holds its start value, which a
    master that read a type with the wrong call, or the wrong variable, would not return).
    UInt32, Int64 and UInt64 are not recorded (the master's rows are doubles, exact only to
    2^53), String and Binary are not numbers: the reference's columns of those are left out,
    and the master says it cannot record them."""
    import fmpy
    import numpy as np

    from dronefly.harness.cosim.system import System, SystemSpecError
    from dronefly.harness.cosim.system_master import SystemMaster

    path = ref / version / "Feedthrough.fmu"
    lines = (REF / "results" / "Feedthrough_out.csv").read_text().splitlines()
    heads = lines[0].split(",")
    cells = [ln.split(",") for ln in lines[1:]]
    t_ref = np.array([float(c[0]) for c in cells])
    h = float(t_ref[1] - t_ref[0])
    with SystemMaster(System({"m": path})) as master:
        run = master.run(h, len(t_ref) - 1)
        assert run.failure is None
        with pytest.raises(SystemSpecError, match="cannot record 'm.String_output'"):
            master.run(h, 1, record=["m.String_output"])
        unrecordable = set(master.unrecordable)
    # every output of the reference result (of the FMI 3.0 build) is compared below or said
    # not to be recorded (the run's summary lists them, harness.stability.system_verdicts)
    assert unrecordable <= {f"m.{n}" for n in heads[1:]}
    if version == "fmi3":
        assert {f"m.{n}" for n in heads[1:]} == unrecordable | set(run.names)
    ours = {n.split(".", 1)[1]: run.signals[:, j] for j, n in enumerate(run.names)}
    assert {"Float64_continuous_output", "Int32_output", "Boolean_output",
            "Enumeration_output"} <= set(ours)
    fm = fmpy.simulate_fmu(str(path), fmi_type="CoSimulation", output_interval=h,
                           stop_time=float(t_ref[-1]), output=sorted(ours))
    np.testing.assert_allclose(run.time, t_ref, rtol=1e-7, atol=1e-12)
    compared = 0
    for j, name in enumerate(heads):
        if name not in ours:
            continue
        col = np.array([{"true": 1.0, "false": 0.0}[c[j]] if c[j] in ("true", "false")
                        else float(c[j]) for c in cells])
        np.testing.assert_array_equal(ours[name], fm[name].astype(float), err_msg=name)
        np.testing.assert_array_equal(ours[name], col, err_msg=name)  # exact: start values
        compared += 1
    assert compared == len(ours)


def test_cosim_system_on_reference_fmus(ref, tmp_path, capsys):
    """`dronefly cosim --system` on one-FMU systems of Reference-FMUs: time in seconds (no
    wing-beat frequency), Stair (FMI 3.0, terminateSimulation at 9 s) ends there with its
    last row recorded, equal to the reference result; --open-loop says there is no plant;
    the SSP's DefaultExperiment startTime is the run's start (Dahlquist, dx/dt = -k x, does
    not depend on time: its run from 1 s is the reference run from 0 s, shifted by 1 s)."""
    import csv

    import numpy as np

    from dronefly.harness.cosim.system import System
    from dronefly.harness.cosim.ssp import write_system_ssp

    ssp = write_system_ssp(System({"stair": ref / "fmi3" / "Stair.fmu"}), tmp_path / "s.ssp",
                           stop_s=10.0)
    assert main(["cosim", "--system", str(ssp), "--step", "0.2", "--no-plot", "--open-loop",
                 "--out", str(tmp_path / "o")]) == 0
    out = capsys.readouterr().out
    assert "step 0.2 s, 45 steps to 10 s, 1 outputs recorded" in out
    assert "an FMU ended the run at t = 9 s" in out
    assert "open loop: nothing to identify: the system has no plant" in out
    (path,) = (tmp_path / "o").glob("*.csv")
    rows = list(csv.reader(path.open()))
    data = np.array([[float(x) for x in r] for r in rows[1:]])
    _, t_ref, y_ref = _reference_csv("Stair")
    np.testing.assert_allclose(data[:, 0], t_ref, rtol=1e-7, atol=1e-12)
    np.testing.assert_array_equal(data[:, 1], y_ref[:, 0])  # whole numbers, exactly

    # startTime: Dahlquist (dx/dt = -k x, from x = 1) from 1 s is the run from 0 s, shifted
    shifted = System({"d": ref / "fmi2" / "Dahlquist.fmu"})
    shifted.start_s = 1.0
    ssp = write_system_ssp(shifted, tmp_path / "d.ssp", stop_s=3.0)
    assert System.from_ssp(ssp).start_s == 1.0
    assert main(["cosim", "--system", str(ssp), "--step", "0.1", "--no-plot", "--out",
                 str(tmp_path / "d")]) == 0
    capsys.readouterr()
    (path,) = (tmp_path / "d").glob("*.csv")
    data = np.array([[float(x) for x in r] for r in list(csv.reader(path.open()))[1:]])
    _, t_ref, y_ref = _reference_csv("Dahlquist")
    assert len(data) == 21  # 2 s in steps of 0.1 s
    np.testing.assert_allclose(data[:, 0], 1.0 + t_ref[:21], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(data[:, 1], y_ref[:21, 0], rtol=1e-7, atol=1e-9)


@pytest.mark.parametrize("call, version, name", [
    ("fmi2DoStep", 3, "fmi3DoStep"), ("fmi2DoStep", 2, "fmi2DoStep"),
    ("fmi2SetReal of k", 3, "fmi3SetFloat64 of k"), ("fmi2GetInteger", 3, "fmi3GetInt*"),
    ("fmi2SetupExperiment", 3, "fmi3EnterInitializationMode"), ("initialization", 3,
                                                                "initialization"),
])
def test_failures_name_the_fmi_versions_call(call, version, name):
    """The master says its calls in FMI 2.0 terms; a failure names the FMU's own call."""
    from dronefly.harness.cosim.system_master import call_name

    assert call_name(call, version) == name


def test_a_step_longer_than_the_run_is_a_failed_experiment(ref, capsys):
    """--step 100 on Dahlquist (0 s to 10 s): the user's option leaves no step, bad input
    (exit 2, one line naming the option, the FMU and the run), refused before any check; the
    same step from the FMU's own default experiment is a failed ``experiment`` check, with no
    FMI call past the stop time; a step that does not divide the run ends at the last whole
    step."""
    assert main(["check", "--step", "100", str(ref / "fmi2" / "Dahlquist.fmu")]) == 2
    err = capsys.readouterr().err
    assert "--step 100.0 on " in err and "step 100.0 s is longer than the run from 0.0 s to " \
        "10.0 s" in err and err.count("\n") == 1
    report = check_fmu(ref / "fmi2" / "Dahlquist.fmu", fuzz=False, isolate=False,
                       options=CheckOptions(step=100.0))
    assert [(c.name, c.passed, c.detail) for c in report.checks] == [
        ("experiment", False, "step 100.0 s is longer than the run from 0.0 s to 10.0 s")]
    report = _check(ref, "fmi2/Dahlquist.fmu", step=6.0, only=("call-sequence",))
    assert report.passed
    assert report.checks[0].detail.startswith("1 steps of 6 s to 6 s (the stop time 10 s")
