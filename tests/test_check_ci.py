"""`dronefly check` for CI: the JSON schema shipped as a file, the pytest plugin (pytest11 entry
point), the pre-commit hook."""

from __future__ import annotations

import json
import subprocess
import sys
from importlib.metadata import entry_points
from pathlib import Path

import pytest

from dronefly.cli.app import main
from dronefly.harness.compliance.suite import JSON_SCHEMA, JSON_SCHEMA_FILE

ROOT = Path(__file__).resolve().parents[1]
REF = ROOT.parent / "shared" / "reference-fmus"
pytestmark = pytest.mark.skipif(not REF.is_dir(), reason=f"the Reference-FMUs are not beside "
                                                         f"the checkout ({REF})")


def test_json_output_validates_against_the_shipped_schema(tmp_path, capsys):
    """--json on a passing, a failing (Stair: reset), a not-checked (Clocks), a skipped-check
    and an unreadable FMU validates against check-schema.json (shipped with the package);
    the schema is strict (a status it does not know, or a missing key, is refused)."""
    import jsonschema

    schema = json.loads(JSON_SCHEMA_FILE.read_text(encoding="utf-8"))
    assert schema["properties"]["schema"]["const"] == JSON_SCHEMA
    jsonschema.Draft202012Validator.check_schema(schema)
    bad = tmp_path / "bad.fmu"
    bad.write_bytes(b"PK\x03\x04 not an FMU")
    code = main(["check", "--json", "--no-fuzz", str(REF / "fmi2" / "Dahlquist.fmu"),
                 str(REF / "fmi2" / "Stair.fmu"), str(REF / "fmi3" / "Clocks.fmu"), str(bad)])
    assert code == 1
    doc = json.loads(capsys.readouterr().out)
    jsonschema.validate(doc, schema)
    assert [f["status"] for f in doc["fmus"]] == ["passed", "failed", "skipped", "failed"]
    wrong = json.loads(json.dumps(doc))
    wrong["fmus"][0]["checks"][0]["status"] = "ok"
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.validate(wrong, schema)
    del wrong["fmus"][1]["checks"][0]["rule"]
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.validate(wrong, schema)


def test_the_schema_ships_with_the_package():
    text = (ROOT / "pyproject.toml").read_text(encoding="utf-8")  # tomllib: Python 3.11+
    assert '"dronefly.harness.compliance" = ["*.json"]' in text
    assert JSON_SCHEMA_FILE.parent == ROOT / "harness" / "compliance"


def test_pytest_plugin_a_test_per_fmu_and_check(tmp_path):
    """`pytest --fmu A.fmu B.fmu`: the plugin (entry point dronefly_check of pytest11) makes a
    test per FMU and check: Stair at its default experiment fails `reset` only (its detail and
    rule in the failure), Dahlquist passes, Clocks is skipped with the reason, a check that does
    not apply is skipped."""
    assert [e.value for e in entry_points(group="pytest11") if e.name == "dronefly_check"] == \
        ["dronefly.harness.compliance.pytest_plugin"]
    (tmp_path / "pytest.ini").write_text("[pytest]\n")
    proc = subprocess.run([sys.executable, "-m", "pytest", "-p", "no:randomly", "-p",
                           "no:cacheprovider", "-rA", "--fmu-no-fuzz", "--fmu",
                           str(REF / "fmi2" / "Dahlquist.fmu"), str(REF / "fmi2" / "Stair.fmu"),
                           str(REF / "fmi3" / "Clocks.fmu")],
                          cwd=tmp_path, capture_output=True, text=True, timeout=300)
    out = proc.stdout
    assert proc.returncode == 1, out[-2000:]
    failed = [ln.split(" - ")[0] for ln in out.splitlines() if ln.startswith("FAILED ")]
    assert len(failed) == 1 and failed[0].endswith("Stair.fmu::reset"), out[-3000:]
    assert "the run after fmi2Reset differs from the first" in out
    assert "rule: FMI 2.0 2.1.6" in out
    assert "Dahlquist.fmu::call-sequence" in out
    assert "SKIPPED [1] " in out and "Scheduled Execution only" in out
    assert "not applicable: no inputs or no outputs" in out
    passed = sum(ln.startswith("PASSED ") and "Dahlquist.fmu::" in ln for ln in out.splitlines())
    assert passed >= 9, out


def test_pre_commit_hook_runs_dronefly_check():
    """.pre-commit-hooks.yaml: a hook `dronefly-check` running `dronefly check` on the staged
    FMU files."""
    text = (ROOT / ".pre-commit-hooks.yaml").read_text(encoding="utf-8")
    assert "- id: dronefly-check\n" in text
    assert "  entry: dronefly check\n" in text
    assert "  files: \\.fmu$\n" in text and "  language: python\n" in text


# -- reference results for anyone's FMU -----------------------------------------------------------
@pytest.mark.parametrize("version", ["fmi2", "fmi3"])
@pytest.mark.parametrize("model", ["BouncingBall", "Dahlquist", "VanDerPol"])
def test_reference_fmus_match_their_reference_results(capsys, model, version):
    """--ref with the Reference-FMUs' own results (results/<Model>_out.csv, written by fmusim):
    every output within FMPy's validation band."""
    ref = REF / "results" / f"{model}_out.csv"
    assert main(["check", "--check", "reference", "--ref", str(ref),
                 str(REF / version / f"{model}.fmu")]) == 0
    out = capsys.readouterr().out
    assert f"output(s) within FMPy's validation band of {model}_out.csv" in out


def test_cross_check_layout_beside_the_fmu_and_a_wrong_reference(tmp_path, capsys):
    """<Model>_ref.csv and <Model>_ref.opt beside the FMU are found without --ref; a reference
    whose values are 1.5 times the FMU's (Dahlquist's x) fails ``reference`` with the share of
    samples outside the band and where."""
    import shutil

    shutil.copy(REF / "fmi2" / "Dahlquist.fmu", tmp_path / "Dahlquist.fmu")
    lines = (REF / "results" / "Dahlquist_out.csv").read_text().splitlines()
    (tmp_path / "Dahlquist_ref.csv").write_text("\n".join(lines) + "\n")
    (tmp_path / "Dahlquist_ref.opt").write_text("StartTime,0\nStopTime,10\nStepSize,0.1\n"
                                                "RelTol,1e-4\n")
    assert main(["check", "--check", "reference", str(tmp_path / "Dahlquist.fmu")]) == 0
    assert "within FMPy's validation band of Dahlquist_ref.csv" in capsys.readouterr().out
    scaled = [lines[0]] + [f"{t},{1.5 * float(x)!r}" for t, x in (ln.split(",") for ln in lines[1:])]
    (tmp_path / "Dahlquist_ref.csv").write_text("\n".join(scaled) + "\n")
    assert main(["check", "--check", "reference", str(tmp_path / "Dahlquist.fmu")]) == 1
    out = capsys.readouterr().out
    assert "of the samples outside FMPy's validation band of Dahlquist_ref.csv (first outside: " \
           "x at t = " in out, out


@pytest.mark.parametrize("argv, message", [
    (["--ref", "r.csv", "A.fmu", "B.fmu"], "--ref 'r.csv' is the reference result of one FMU; "
                                           "2 given"),
    (["--in", "i.csv", "A.fmu"], "--in 'i.csv' needs --ref"),
    (["--ref", "missing.csv", "A.fmu"], "--ref 'missing.csv': no such file"),
])
def test_reference_options_refused_before_the_work(tmp_path, monkeypatch, capsys, argv, message):
    monkeypatch.chdir(tmp_path)
    for name in ("A.fmu", "B.fmu", "r.csv", "i.csv"):
        (tmp_path / name).write_bytes(b"")
    assert main(["check", *argv]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1, err
