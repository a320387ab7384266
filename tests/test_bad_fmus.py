"""FMUs that cannot be loaded safely are refused in one line before anything of them is loaded.

A pythonfmu FMU without its Python sources crashed the host (signal 11) in cosim, sweep and
check; an FMU without a binary for this platform gave fmpy's traceback; an FMI 1.0 model
description gave four lines of schema errors.
"""

from __future__ import annotations

import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from dronefly.harness.cosim.fmu import FMU, FMUError

pytestmark = pytest.mark.integration


def _rewrite(src: Path, dst: Path, drop=lambda name: False, patch=None) -> Path:
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w") as zout:
        for info in zin.infolist():
            if drop(info.filename):
                continue
            data = zin.read(info)
            if patch is not None:
                data = patch(info.filename, data)
            zout.writestr(info, data)
    return dst


@pytest.fixture
def broken(built_fmus, tmp_path):
    plant = built_fmus["DroneFlyLateral"]
    return {
        "no sources": _rewrite(plant, tmp_path / "nosrc.fmu",
                               drop=lambda n: n.startswith("resources/") and n.endswith("_slave.py")),
        "no binary": _rewrite(plant, tmp_path / "nobin.fmu",
                              drop=lambda n: n.startswith("binaries/linux64/")),
        "fmi 1.0": _rewrite(plant, tmp_path / "fmi1.fmu", patch=lambda n, d: d.replace(
            b'fmiVersion="2.0"', b'fmiVersion="1.0"') if n == "modelDescription.xml" else d),
        "not a zip": tmp_path / "text.fmu",
    }


@pytest.mark.parametrize("case,fragment", [
    ("no sources", "is missing \\(the FMU.s Python sources\\)"),
    ("no binary", "has no binary for this platform"),
    ("fmi 1.0", "is an FMI 1.0 FMU"),
    ("not a zip", "not a zip archive"),
])
def test_refused_in_one_line(broken, case, fragment):
    if case == "not a zip":
        broken[case].write_text("hello")
    with pytest.raises(FMUError, match=fragment) as e:
        FMU(broken[case])
    assert "\n" not in str(e.value)


@pytest.mark.parametrize("command", ["cosim", "check"])
def test_cli_refuses_an_fmu_without_sources_without_crashing(broken, built_fmus, tmp_path,
                                                             command):
    """In a child process, so that a crash would be seen: exit 2, one line, nothing written."""
    out = tmp_path / "out"
    args = (["cosim", "--plant", str(broken["no sources"]), "--controller",
             str(built_fmus["StateFeedback"]), "--out", str(out)] if command == "cosim"
            else ["check", "--no-fuzz", str(broken["no sources"])])
    r = subprocess.run([sys.executable, "-m", "dronefly", *args], capture_output=True,
                       text=True, timeout=120)
    assert r.returncode == (2 if command == "cosim" else 1), r.stderr
    if command == "cosim":
        assert r.stderr.count("\n") == 1 and "is missing" in r.stderr, r.stderr
        assert not out.exists()
