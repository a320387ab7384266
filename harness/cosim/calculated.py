"""Calculated parameters read from an FMU: the plant matrices as the FMU itself computes them.

The plant FMUs expose their state-space matrices as calculated parameters ``A[i,j]`` and
``B[i,j]`` (per wing beat, from the tunable derivatives). The analyses that compare a
co-simulation with eig(A + B K) read them here, from an instance initialised with the same
parameter values as the run, so that the cross-check uses the FMU's numbers, not ours.
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

__all__ = ["calculated_matrix", "plant_matrices"]


def calculated_matrix(fmu: Any, name: str, rows: int, cols: int,
                      values: Mapping[str, Any] | None = None) -> np.ndarray | None:
    """The calculated-parameter matrix ``name[i,j]`` (1-based) as the FMU computes it.

    Parameters
    ----------
    fmu : harness.cosim.fmu.FMU
        An extracted FMU.
    name : str
        The matrix's variable name stem, e.g. ``"A"``.
    rows, cols : int
        Its shape.
    values : mapping, optional
        Variable name -> value set in initialization mode first (each with the setter of its
        declared type).

    Returns
    -------
    numpy.ndarray or None
        ``rows`` x ``cols``; None if the FMU has not every element.
    """
    names = [f"{name}[{i + 1},{j + 1}]" for i in range(rows) for j in range(cols)]
    if not all(n in fmu.variables for n in names):
        return None
    with fmu.instantiate(logging=False) as inst:
        s = inst.slave
        s.setupExperiment(startTime=0.0)
        s.enterInitializationMode()
        for key, value in (values or {}).items():
            getattr(s, f"set{fmu.variables[key].type}")([fmu.vr(key)], [value])
        s.exitInitializationMode()
        matrix = np.reshape(s.getReal(inst.vrs(names)), (rows, cols))
        s.terminate()
    return matrix


def plant_matrices(fmu: Any, n_states: int, n_inputs: int,
                   values: Mapping[str, Any] | None = None
                   ) -> tuple[np.ndarray, np.ndarray] | None:
    """A (``n_states`` square, per wing beat) and B (``n_states`` x ``n_inputs``) of a plant
    FMU with ``values`` set, or None if it does not expose both (see
    :func:`calculated_matrix`)."""
    A = calculated_matrix(fmu, "A", n_states, n_states, values)
    B = calculated_matrix(fmu, "B", n_states, n_inputs, values)
    return None if A is None or B is None else (A, B)
