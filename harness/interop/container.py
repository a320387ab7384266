"""The closed loop as fmpy's container FMU runs it (``DroneFlyClosedLoop.fmu``, written by
:mod:`dronefly.harness.builder.closedloop`): one run per unit initial state, and its verdict."""

from __future__ import annotations

import tempfile
from pathlib import Path
from typing import Mapping

import fmpy
import numpy as np
from fmpy import read_model_description

from ..builder.closedloop import plant_md_scales
from ...models.lateral_interface import STATE_NAMES
from ..cosim.identification import Verdict, unit_start_values, verdict_of

__all__ = ["container_verdict", "run_container"]


def run_container(fmu: str | Path, *, start_values: Mapping[str, float] | None = None,
                  stop_s: float | None = None) -> np.ndarray:
    """``fmpy.simulate_fmu`` with the container's default experiment (output every step).

    The FMU is extracted into a temporary folder of ours, removed whatever happens (FMPy removes
    its own extraction only when the run ends normally: a container that fails to instantiate
    left it behind)."""

    md = read_model_description(fmu)
    step = float(md.defaultExperiment.stepSize)
    stop = float(md.defaultExperiment.stopTime) if stop_s is None else stop_s
    with tempfile.TemporaryDirectory(prefix="dronefly_container_") as tmp:
        return fmpy.simulate_fmu(fmpy.extract(str(fmu), tmp), stop_time=stop,
                                 output_interval=step, model_description=md,
                                 start_values=dict(start_values or {}),
                                 output=[v.name for v in md.modelVariables
                                         if v.causality == "output"])


def container_verdict(fmu: str | Path, n_steps: int = 20) -> Verdict:
    """Identify and classify the loop as the container runs it (one run per unit x+_0).

    The container's master, measured (``tests/test_interop.py``,
    ``test_container_is_the_gauss_seidel_loop``): it resolves its connections in
    initialization, where the plant's outputs already hold x_0, so u_0 = K x_0, and after every
    step (plant -> controller -> plant; the controller is direct feedthrough): u_k = K x_k. The
    rows are the Gauss-Seidel loop from x_0, and the identification uses them without delay.

    Raises
    ------
    CrossCheckError
        The fit's residual exceeds :data:`~dronefly.harness.cosim.identification.FIT_RESIDUAL_TOL`
        (the runs are not the loop identified, e.g. a controller with a sensing delay).
    """
    md = read_model_description(fmu)
    n, scale = plant_md_scales(md)
    step = float(md.defaultExperiment.stepSize)
    runs = []
    for start in unit_start_values(scale):
        res = run_container(fmu, start_values=start, stop_s=(n_steps + 1) * step)
        runs.append(np.column_stack([res[x] for x in STATE_NAMES]) / scale)
    return verdict_of(runs, step * n, delay=False, where=f"container {fmu}")
