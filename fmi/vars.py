"""The variable table of :class:`dronefly.fmi.SlaveBase`: units and one scalar variable.

Shipped inside every FMU; the model description generator reads the same table.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["UNITS", "Var"]

_DEG = 180.0 / math.pi

#: unit name -> (base-unit exponents, {display unit: factor})
UNITS: dict[str, tuple[dict[str, int], dict[str, float]]] = {
    "1": ({}, {}),
    "s": ({"s": 1}, {"ms": 1000.0}),
    "Hz": ({"s": -1}, {}),
    "m": ({"m": 1}, {"mm": 1000.0}),
    "m/s": ({"m": 1, "s": -1}, {}),
    "rad": ({"rad": 1}, {"deg": _DEG}),
    "rad/s": ({"rad": 1, "s": -1}, {"deg/s": _DEG}),
}


@dataclass(frozen=True)
class Var:
    """One scalar variable of an FMU's interface.

    ``dependencies`` is for outputs and calculated parameters: a tuple of the
    names of the knowns the value depends on (``()`` = none), or ``None`` for
    "all knowns" (the attribute is then omitted).
    """

    name: str
    causality: str
    variability: str
    description: str
    unit: str | None = "1"
    display_unit: str | None = None
    start: float | bool | None = None
    initial: str | None = None
    type: str = "Real"
    dependencies: tuple[str, ...] | None = None
    initial_dependencies: tuple[str, ...] | None = None
