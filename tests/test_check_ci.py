"""`dronefly check` for CI: the JSON schema shipped as a file, the pytest plugin (pytest11 entry
point), the pre-commit hook."""

from __future__ import annotations

import json
import subprocess
import sys
import tomllib
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
    data = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    assert "*.json" in data["tool"]["setuptools"]["package-data"]["dronefly.harness.compliance"]
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
