"""Helpers shared by the integration tests that drive FMUs through fmpy."""

from __future__ import annotations

import zipfile
from pathlib import Path
from typing import Any
from xml.etree import ElementTree as ET

__all__ = ["model_description", "set_values", "start"]


def model_description(path: Path) -> ET.Element:
    """The parsed modelDescription.xml of an FMU file."""
    with zipfile.ZipFile(path) as z:
        return ET.fromstring(z.read("modelDescription.xml"))


def set_values(inst: Any, values: dict[str, Any]) -> None:
    """Set Real or Boolean variables by name on a harness ``Instance``."""
    for name, value in values.items():
        if isinstance(value, bool):
            inst.slave.setBoolean([inst.fmu.vr(name)], [value])
        else:
            inst.slave.setReal([inst.fmu.vr(name)], [value])


def start(inst: Any, values: dict[str, Any] | None = None, t0: float = 0.0) -> None:
    """setupExperiment, set ``values`` in initialization mode, exit initialization."""
    s = inst.slave
    s.setupExperiment(startTime=t0)
    s.enterInitializationMode()
    set_values(inst, values or {})
    s.exitInitializationMode()
