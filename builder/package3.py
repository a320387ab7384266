"""What an FMI 3.0 package adds to :mod:`dronefly.builder.build`'s: pythonfmu3's binaries, the FMI 3.0
side of the slave base, and the FMI 3.0 model description (the entry module pythonfmu3 reads:
:func:`dronefly.builder.entry.entry3`).

The FMI 3.0 FMU ships the same model and controller code as the FMI 2.0 one, plus
:mod:`dronefly.fmi.fmi3` and :mod:`dronefly.fmi.table3`, in its own content-addressed package
(``dronefly3_<name>_<hash>``). The shared slave base derives from pythonfmu 0.7.0's pure-Python
``Fmi2Slave`` (its facade, no binary), so pythonfmu's Python files are shipped too; the
binary is pythonfmu3's (``binaries/x86_64-linux/<model>.so``).
"""

from __future__ import annotations

import importlib
from importlib.metadata import PackageNotFoundError, distribution
from pathlib import Path
from typing import Any

from .modeldescription3 import model_description3_bytes

__all__ = ["FMI3_FILES", "model_description3", "wrapper3_binaries"]

#: the sources an FMI 3.0 FMU ships besides its FMI 2.0 twin's
FMI3_FILES = ("fmi/fmi3.py", "fmi/table3.py")

def wrapper3_binaries() -> dict[str, bytes]:
    """pythonfmu3's binaries as the FMU ships them (``{model}`` stands for the model name).

    Raises
    ------
    ImportError
        pythonfmu3 is not installed, or has no binaries.
    """

    try:
        root = Path(str(distribution("pythonfmu3").locate_file("pythonfmu3"))).resolve()
    except PackageNotFoundError as e:
        raise ImportError("pythonfmu3 is not installed: pip install pythonfmu3==0.3.4") from e
    out = {f"binaries/{f.parent.name}/{{model}}{f.suffix}": f.read_bytes()
           for f in sorted((root / "resources" / "binaries").rglob("*"))
           if f.suffix in (".so", ".dll", ".dylib")}
    if not out:
        raise ImportError(f"no pythonfmu3 binaries under {root}: reinstall pythonfmu3")
    return out


def model_description3(pkg: str, module: str, cls: str, token: str) -> bytes:
    """The FMI 3.0 XML of class ``cls`` of ``pkg.module`` (already importable)."""

    fmi3 = importlib.import_module(f"{pkg}.fmi.fmi3")
    model: Any = getattr(importlib.import_module(f"{pkg}.{module}"), cls)
    return model_description3_bytes(fmi3.fmi3_class(model), token)
