"""Reference results following the FMI cross-check rules.

For each FMU of the project, its folder holds ``<Model>_in.csv`` (inputs at every
communication point; none for the closed loop, which has no inputs), ``<Model>_ref.opt`` (StartTime, StopTime, StepSize, RelTol)
and ``<Model>_ref.csv`` (time and every output), produced by fmpy.simulate_fmu with
the default start values. :func:`check_reference` simulates an FMU with the same
settings and compares with fmpy's cross-check band (``fmpy.util.validate_result``)
and with a tight numeric tolerance, since both FMUs are exact for held inputs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import fmpy
import numpy as np
from fmpy.util import read_csv, read_ref_opt_file, validate_result

from ...core.files import write_csv_atomic, write_text_atomic
from ...models import longitudinal_interface
from ...models.hover6dof import OUTPUT_NAMES
from ...models.lateral_interface import CONTROL_NAMES, N_HZ, STATE_NAMES

__all__ = ["REFERENCES", "ReferenceCheck", "check_reference", "reference_outputs",
           "reference_paths", "write_reference"]


def _plant_inputs(t: np.ndarray) -> dict[str, np.ndarray]:
    """A doublet on delta_Phi_a (+0.01 rad for 5 wing beats, -0.01 for 5), a pulse on alpha_2a."""
    wb = t * N_HZ
    return {
        "delta_Phi_a": np.where(wb < 5 - 1e-9, 0.01, np.where(wb < 10 - 1e-9, -0.01, 0.0)),
        "delta_alpha_1a": np.zeros_like(t),
        "delta_alpha_2a": np.where((wb >= 15 - 1e-9) & (wb < 17 - 1e-9), 0.005, 0.0),
    }


def _controller_inputs(t: np.ndarray) -> dict[str, np.ndarray]:
    """A decaying oscillation of the four states (dimensional), like a disturbed hover."""
    wb = t * N_HZ
    env = np.exp(-wb / 20.0)
    return {
        "delta_v": 0.2 * env * np.sin(2 * np.pi * wb / 15.0),
        "delta_p": 8.0 * env * np.cos(2 * np.pi * wb / 15.0),
        "delta_r": -3.0 * env * np.sin(2 * np.pi * wb / 10.0),
        "delta_gamma": 0.1 * env * np.cos(2 * np.pi * wb / 25.0),
    }


def _longitudinal_plant_inputs(t: np.ndarray) -> dict[str, np.ndarray]:
    """A doublet on delta_phibar (+/-0.01 rad, 5 wing beats each), a pulse on delta_Phi."""
    wb = t * N_HZ
    return {
        "delta_Phi": np.where((wb >= 20 - 1e-9) & (wb < 25 - 1e-9), 0.02, 0.0),
        "delta_alpha_1": np.zeros_like(t),
        "delta_phibar": np.where(wb < 5 - 1e-9, 0.01, np.where(wb < 10 - 1e-9, -0.01, 0.0)),
        "delta_alpha_2": np.where((wb >= 30 - 1e-9) & (wb < 32 - 1e-9), -0.005, 0.0),
    }


def _longitudinal_controller_inputs(t: np.ndarray) -> dict[str, np.ndarray]:
    """A decaying oscillation of the four longitudinal states (dimensional)."""
    wb = t * N_HZ
    env = np.exp(-wb / 30.0)
    return {
        "delta_u": 0.3 * env * np.sin(2 * np.pi * wb / 64.0),
        "delta_w": -0.05 * env * np.cos(2 * np.pi * wb / 40.0),
        "delta_q": 10.0 * env * np.cos(2 * np.pi * wb / 64.0),
        "delta_theta": 0.1 * env * np.sin(2 * np.pi * wb / 64.0),
    }


_PACKAGE_ROOT = Path(__file__).resolve().parents[2]  # harness/compliance/../..


@dataclass(frozen=True)
class _Setup:
    folder: str  # the folder holding the files, below the package root
    inputs: Callable[[np.ndarray], dict[str, np.ndarray]]
    outputs: tuple[str, ...] | None  # None: every output of the model description, in its order
    stop_wingbeats: float = 30.0
    step_wingbeats: float = 0.1
    rel_tol: float = 1e-6


def _no_inputs(t: np.ndarray) -> dict[str, np.ndarray]:
    return {}


def _hover6dof_inputs(t: np.ndarray) -> dict[str, np.ndarray]:
    """Both plants' inputs at once: the lateral and the longitudinal doublets and pulses."""
    return {**_plant_inputs(t), **_longitudinal_plant_inputs(t)}


def _flapping_inputs(t: np.ndarray) -> dict[str, np.ndarray]:
    """Both axes' controls as pulses a wing beat or two long, some set within a beat (they
    act from the next beat's start)."""
    wb = t * N_HZ
    zero = np.zeros_like(t)
    return {
        "delta_Phi_a": np.where((wb >= 1 - 1e-9) & (wb < 3 - 1e-9), 0.05, 0.0),
        "delta_alpha_1a": zero, "delta_alpha_2a": np.where(wb >= 3.5 - 1e-9, -0.03, 0.0),
        "delta_Phi": zero, "delta_alpha_1": zero,
        "delta_phibar": np.where((wb >= 2 - 1e-9) & (wb < 4 - 1e-9), 0.05, 0.0),
        "delta_alpha_2": zero,
    }


REFERENCES: dict[str, _Setup] = {
    "DroneFlyLateral": _Setup("fmu_src/lateral", _plant_inputs, STATE_NAMES),
    "StateFeedback": _Setup("controller", _controller_inputs, (*CONTROL_NAMES, "saturated")),
    "DroneFlyLongitudinal": _Setup("fmu_src/longitudinal", _longitudinal_plant_inputs,
                                   longitudinal_interface.STATE_NAMES, stop_wingbeats=60.0),
    "StateFeedbackLongitudinal": _Setup("controller", _longitudinal_controller_inputs,
                                        (*longitudinal_interface.CONTROL_NAMES, "saturated"), stop_wingbeats=60.0),
    # the same inputs through the controllers with the default sensing delay of one wing beat
    "StateFeedbackDelayed": _Setup("controller", _controller_inputs, (*CONTROL_NAMES, "saturated")),
    "StateFeedbackLongitudinalDelayed": _Setup("controller", _longitudinal_controller_inputs,
                                               (*longitudinal_interface.CONTROL_NAMES, "saturated"),
                                               stop_wingbeats=60.0),
    "DroneFlyHover6DOF": _Setup("fmu_src/hover6dof", _hover6dof_inputs, OUTPUT_NAMES,
                                stop_wingbeats=60.0),
    # the flapping plant: a few wing beats, four communication points in each (every output,
    # the wing angles and the instantaneous loads too)
    "DroneFlyFlapping": _Setup("fmu_src/flapping", _flapping_inputs, None, stop_wingbeats=6.0,
                               step_wingbeats=0.25),
    # the container FMU: the closed loop from its default initial state (a 0.1 rad roll)
    "DroneFlyClosedLoop": _Setup("harness/interop", _no_inputs, (*STATE_NAMES, *CONTROL_NAMES),
                                 stop_wingbeats=100.0),
}


@dataclass(frozen=True)
class ReferenceCheck:
    model: str
    cross_check_outliers: float  # fraction of samples outside fmpy's band (0 = pass)
    max_rel_error: float  # max |y - y_ref| / max |y_ref| over all outputs

    @property
    def passed(self) -> bool:
        return self.cross_check_outliers == 0.0 and self.max_rel_error <= 1e-9


def reference_paths(model: str) -> tuple[Path, Path, Path]:
    """(``_in.csv``, ``_ref.opt``, ``_ref.csv``) of a model in the source tree."""
    folder = _PACKAGE_ROOT / REFERENCES[model].folder
    return (folder / f"{model}_in.csv", folder / f"{model}_ref.opt", folder / f"{model}_ref.csv")


def _opt(setup: _Setup) -> dict[str, float]:
    return {"StartTime": 0.0, "StopTime": setup.stop_wingbeats / N_HZ,
            "StepSize": setup.step_wingbeats / N_HZ, "RelTol": setup.rel_tol}


def _simulate(fmu: Path, model: str, inputs: np.ndarray) -> np.ndarray:
    setup = REFERENCES[model]
    o = _opt(setup)
    return fmpy.simulate_fmu(str(fmu), start_time=o["StartTime"], stop_time=o["StopTime"],
                             output_interval=o["StepSize"],
                             input=inputs if len(inputs.dtype.names) > 1 else None,
                             output=reference_outputs(model, fmu))


def reference_outputs(model: str, fmu: str | Path) -> list[str]:
    """The outputs a model's reference records: those of :data:`REFERENCES`, or (where it
    gives None) every output of the FMU's model description, in its order; the checker reads
    those names from the FMU, not from the code that made it."""
    outputs = REFERENCES[model].outputs
    if outputs is not None:
        return list(outputs)
    return [v.name for v in fmpy.read_model_description(str(fmu)).modelVariables
            if v.causality == "output"]


def _input_table(model: str) -> np.ndarray:
    setup = REFERENCES[model]
    n = int(round(setup.stop_wingbeats / setup.step_wingbeats))
    t = np.arange(n + 1) * (setup.step_wingbeats / N_HZ)
    cols = setup.inputs(t)
    table = np.empty(len(t), dtype=[("time", float)] + [(k, float) for k in cols])
    table["time"] = t
    for k, v in cols.items():
        table[k] = v
    return table


def _write_table(path: Path, table: np.ndarray) -> None:
    """A structured array as a cross-check CSV: quoted names, floats exact, flags as 0/1."""
    rows = [[float(v) if isinstance(v, (float, np.floating)) else int(v) for v in row]
            for row in table]
    write_csv_atomic(path, table.dtype.names, rows, quote_header=True)


def write_reference(model: str, fmu: Path) -> tuple[Path, Path, Path]:
    """Simulate ``fmu`` and (re)write the model's ``_in.csv``, ``_ref.opt``, ``_ref.csv``."""
    inp, opt, ref = reference_paths(model)
    table = _input_table(model)
    result = _simulate(fmu, model, table)
    if len(table.dtype.names) > 1:  # an _in.csv only for a model with inputs
        _write_table(inp, table)
    write_text_atomic(opt, "".join(f"{k},{v!r}\n" for k, v in _opt(REFERENCES[model]).items()))
    _write_table(ref, result)
    return inp, opt, ref


def check_reference(model: str, fmu: Path, folder: Path | None = None) -> ReferenceCheck:
    """Simulate ``fmu`` as the ``.opt`` file says and compare with ``_ref.csv``."""

    inp, opt, ref = reference_paths(model)
    if folder is not None:
        inp, opt, ref = (folder / p.name for p in (inp, opt, ref))
    opts = read_ref_opt_file(str(opt))
    expected = _opt(REFERENCES[model])
    for key in ("StartTime", "StopTime", "StepSize"):
        if not math.isclose(opts[key], expected[key], rel_tol=1e-12, abs_tol=1e-15):
            raise ValueError(f"{opt.name}: {key} = {opts[key]!r}, expected {expected[key]!r}")
    reference = read_csv(str(ref))
    result = _simulate(fmu, model, read_csv(str(inp)) if inp.exists() else _input_table(model))
    outliers = float(validate_result(result, reference, stop_time=opts["StopTime"]))
    worst = 0.0
    for name in reference.dtype.names[1:]:
        y, y_ref = np.asarray(result[name], float), np.asarray(reference[name], float)
        scale = max(float(np.max(np.abs(y_ref))), 1e-300)
        worst = max(worst, float(np.max(np.abs(y - y_ref))) / scale)
    return ReferenceCheck(model, outliers, worst)
