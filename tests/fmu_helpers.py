"""Helpers shared by the integration tests that drive FMUs through fmpy."""

from __future__ import annotations

import subprocess
import zipfile
from pathlib import Path
from typing import Any
from xml.etree import ElementTree as ET

import fmpy


__all__ = ["build_crashing_fmu", "model_description", "set_values", "start"]


def model_description(path: Path) -> ET.Element:
    """The parsed modelDescription.xml of an FMU file."""
    with zipfile.ZipFile(path) as z:
        return ET.fromstring(z.read("modelDescription.xml"))


def set_values(inst: Any, values: dict[str, Any]) -> None:
    """Set Real, Boolean or Integer variables by name on a harness
    ``Instance``."""
    for name, value in values.items():
        if isinstance(value, bool):
            inst.slave.setBoolean([inst.fmu.vr(name)], [value])
        elif inst.fmu.variables[name].type == "Integer":
            inst.slave.setInteger([inst.fmu.vr(name)], [value])
        else:
            inst.slave.setReal([inst.fmu.vr(name)], [value])


def start(inst: Any, values: dict[str, Any] | None = None, t0: float = 0.0) -> None:
    """setupExperiment, set ``values`` in initialization mode, exit initialization."""
    s = inst.slave
    s.setupExperiment(startTime=t0)
    s.enterInitializationMode()
    set_values(inst, values or {})
    s.exitInitializationMode()


_CRASHING = """
import ctypes
from pythonfmu import Fmi2Slave, Real, Fmi2Causality, Fmi2Variability


class Crashing(Fmi2Slave):
    \"\"\"doStep dereferences a null pointer: a real segfault of the host.\"\"\"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.u = 0.0
        self.y = 0.0
        self.register_variable(Real("u", causality=Fmi2Causality.input,
                                    variability=Fmi2Variability.continuous))
        self.register_variable(Real("y", causality=Fmi2Causality.output,
                                    variability=Fmi2Variability.continuous))

    def do_step(self, t, h):
        ctypes.string_at(0)
        return True
"""


def _pythonfmu_fmu(folder: Path, name: str, source: str) -> Path:
    """The pythonfmu FMU of the slave class ``name`` written in ``source``, built in ``folder``."""
    from pythonfmu import FmuBuilder

    src = folder / f"{name}.py"
    src.write_text(source)
    return Path(FmuBuilder.build_FMU(src, dest=folder))


def build_crashing_fmu(folder: Path) -> Path:
    """A pythonfmu FMU (not ours) whose fmi2DoStep segfaults the host."""
    return _pythonfmu_fmu(folder, "Crashing", _CRASHING)


_HANGING = '''
import time

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real


class Hanging(Fmi2Slave):
    """y = u; its step from t >= 0.05 s never returns (sleeps an hour)."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.u = 0.0
        self.register_variable(Real("u", causality=Fmi2Causality.input,
                                    variability=Fmi2Variability.continuous))
        self.register_variable(Real("y", causality=Fmi2Causality.output,
                                    variability=Fmi2Variability.continuous,
                                    getter=lambda: self.u))

    def do_step(self, t, h):
        if t >= 0.05:
            time.sleep(3600)
        return True
'''


def build_hanging_fmu(folder: Path) -> Path:
    """A pythonfmu FMU (not ours) whose fmi2DoStep from t >= 0.05 s never returns."""
    return _pythonfmu_fmu(folder, "Hanging", _HANGING)


def rebuilt_reference_fmu(src: Path, dst: Path, work: Path, edits: dict[str, list[tuple[str, str]]]) -> Path:
    """A copy of an FMI 2.0 Reference-FMU whose linux64 binary is rebuilt with gcc from its own
    sources after the edits (file -> [(old, new)], each old found once)."""
    with zipfile.ZipFile(src) as z:
        z.extractall(work)
    for source, pairs in edits.items():
        path = work / "sources" / source
        text = path.read_text()
        for old, new in pairs:
            assert text.count(old) == 1, old
            text = text.replace(old, new)
        path.write_text(text)
    (lib,) = (work / "binaries" / "linux64").glob("*.so")
    headers = Path(fmpy.__file__).parent / "c-code"
    subprocess.run(["gcc", "-shared", "-fPIC", "-O1", f"-I{work / 'sources'}", f"-I{headers}",
                    "-o", str(lib), str(work / "sources" / "all.c"), "-lm"], check=True,
                   capture_output=True, timeout=120)
    with zipfile.ZipFile(dst, "w", zipfile.ZIP_DEFLATED) as z:
        for f in sorted(work.rglob("*")):
            if f.is_file():
                z.write(f, f.relative_to(work).as_posix())
    return dst
