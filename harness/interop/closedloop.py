"""The closed loop as one artefact: shared pieces of the SSP file and the container FMU.

See :mod:`.ssp` and :mod:`.container`. Both archives are reproducible (fixed zip timestamps, sorted entries, GUID derived from the
two FMUs' GUIDs), like the FMUs themselves.
"""

from __future__ import annotations

import math
import uuid
from dataclasses import dataclass

import numpy as np

from ...models.feedback import default_gains, gain_name
from ..cosim.fmu import start_values
from ...models.lateral import STATE_NAMES, plant_scales
from ..cosim.master import CoSimError

__all__ = ["CLOSED_LOOP", "CONTAINER_TYPES", "CONTROLLER", "GUID_NAMESPACE", "PLANT", "ClosedLoopSpec",
           "parameter_values", "reference_scales"]

CLOSED_LOOP = "DroneFlyClosedLoop"
PLANT, CONTROLLER = "DroneFlyLateral", "StateFeedback"
#: FMI 2 type name -> container type name; the mapping fmpy's write_configuration already
#: applies to container variables.
CONTAINER_TYPES = {"Real": "Float64", "Integer": "Int32"}
GUID_NAMESPACE = uuid.UUID("0b6f8a8e-4f1d-4e55-9d0b-7c1e2f3a4b5c")


@dataclass(frozen=True)
class ClosedLoopSpec:
    """What the artefacts fix: initial state x+ (non-dimensional), gains, step and stop."""

    x0: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.1)
    gains: tuple[tuple[float, ...], ...] = default_gains()
    step_wingbeats: float = 0.1
    stop_wingbeats: float = 300.0

    def __post_init__(self) -> None:
        for name in ("step_wingbeats", "stop_wingbeats"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise CoSimError(f"{name} = {value!r} wing beats must be finite and > 0")


def reference_scales(plant_md) -> tuple[float, np.ndarray]:
    """n [Hz] and the scale vector [U, n, n, 1] of a plant's model description."""
    scale = np.array(plant_scales(start_values(plant_md)))
    return float(scale[1]), scale


def parameter_values(plant_md, spec: ClosedLoopSpec) -> dict[str, float]:
    """Hierarchical name -> value: the plant's initial state and the controller's gains."""
    _, scale = reference_scales(plant_md)
    out = {f"plant.{s}_start": float(v) for s, v in zip(STATE_NAMES, np.array(spec.x0) * scale)}
    for i, row in enumerate(spec.gains):
        for j, k in enumerate(row):
            out[f"controller.{gain_name(i, j)}"] = float(k)
    return out
