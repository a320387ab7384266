"""What a user sets on a co-simulation: gain matrices and ``NAME=VALUE`` parameter values.

One home for the named gain sets (``paper``: Eq. 27 on delta_Phi_a; ``stabilising``: the
paper's coefficient matching with lambda1 moved to -0.1; ``open``: no control), for reading a
full 3 x 4 gain matrix (inline, CSV or JSON file), and for checking ``--set`` values against
the FMUs' model descriptions. The functions double as argparse ``type=`` converters.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from ...models.feedback import default_gains
from ...core.errors import DroneflyError
from ...models.lateral import CONTROL_NAMES, STATE_NAMES

__all__ = ["GAIN_SETS", "SHARED_SCALES", "STABILISING_LAMBDA1", "ParameterError", "as_gain_matrix",
           "gain_matrix", "parse_gains", "resolve_assignments", "scale_ratios"]

#: Named gain sets (rows: controls, columns: x+; rad per unit of x+).
GAIN_SETS: tuple[str, ...] = ("paper", "stabilising", "open")
#: lambda1 of the ``stabilising`` set, per wing beat (the other eigenvalues kept).
STABILISING_LAMBDA1 = -0.1
_SHAPE = (len(CONTROL_NAMES), len(STATE_NAMES))


class ParameterError(DroneflyError):
    """A gain matrix or a ``NAME=VALUE`` that cannot be used (names the value)."""


def gain_matrix(name: str) -> np.ndarray:
    """The 3x4 gain matrix of a named gain set."""
    if name == "paper":
        return np.array(default_gains(), dtype=float)
    if name == "open":
        return np.zeros(_SHAPE)
    if name == "stabilising":
        from ..paper.design import move_lambda1_gains
        from ...models import lateral_dynamics as model

        A, B = model.system_matrices(model.default_parameters())
        K = np.zeros(_SHAPE)
        K[0] = move_lambda1_gains(A, B, CONTROL_NAMES[0], STABILISING_LAMBDA1)
        return K
    raise ParameterError(f"unknown gain set {name!r}; choose from {', '.join(GAIN_SETS)}")


def _matrix(rows: Any, what: str) -> np.ndarray:
    try:
        rows = [[float(v) for v in row] for row in rows]
    except (TypeError, ValueError):
        raise ParameterError(f"gains {what}: every entry must be a number") from None
    if len(rows) == 1 and len(rows[0]) == _SHAPE[1]:  # one row: delta_Phi_a, as Eq. (22)
        rows += [[0.0] * _SHAPE[1] for _ in range(_SHAPE[0] - 1)]
    if len(rows) not in (1, _SHAPE[0]):
        raise ParameterError(f"gains {what}: {len(rows)} rows, expected {_SHAPE[0]} "
                             f"({', '.join(CONTROL_NAMES)}) or 1")
    for i, row in enumerate(rows):  # a short row is named before a missing one
        if len(row) != _SHAPE[1]:
            raise ParameterError(f"gains {what}: row {i + 1} has {len(row)} values, expected "
                                 f"{_SHAPE[1]} (on {', '.join(STATE_NAMES)} as x+)")
        for j, v in enumerate(row):
            if not math.isfinite(v):
                raise ParameterError(f"gains {what}: K[{i + 1},{j + 1}] = {v!r} is not finite")
    return np.array(rows)  # (3, 4): a single row of 4 was padded above


def as_gain_matrix(gains: str | Any) -> np.ndarray:
    """A 3x4 gain matrix from text (see :func:`parse_gains`) or an array_like (a row of 4 is
    delta_Phi_a's), checked the same way."""
    if isinstance(gains, str):
        return parse_gains(gains)
    return _matrix(np.atleast_2d(np.asarray(gains, dtype=float)).tolist(), "array")


def parse_gains(text: str) -> np.ndarray:
    """A 3x4 gain matrix from a named set, an inline matrix or a file.

    ``paper`` | ``stabilising`` | ``open``; ``k1,k2,k3,k4`` (row 1, the others zero);
    ``k11,...,k14;k21,...;k31,...`` (rows separated by ``;``); or the path of a ``.csv``
    (rows of 4 numbers, an optional header line) or ``.json`` file (a nested list, or
    ``{"K": [[...], ...]}``).
    """
    t = text.strip()
    if t.lower() in GAIN_SETS:
        return gain_matrix(t.lower())
    if t.lower().endswith((".csv", ".json")):
        return _gains_file(Path(t))
    return _matrix([row.split(",") for row in t.split(";")], repr(text))


def _gains_file(path: Path) -> np.ndarray:
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as e:
        raise ParameterError(f"gains file {str(path)!r}: {e.strerror or e}") from e
    if path.suffix.lower() == ".json":
        try:
            data = json.loads(text)
        except ValueError as e:
            raise ParameterError(f"gains file {str(path)!r} is not JSON: {e}") from None
        if isinstance(data, dict):
            data = data.get("K")
        if not isinstance(data, list):
            raise ParameterError(f"gains file {str(path)!r}: expected a list of rows or {{\"K\": ...}}")
        return _matrix(data, f"in {str(path)!r}")
    rows = [r for r in csv.reader(text.splitlines()) if r and any(c.strip() for c in r)]
    if rows:
        try:
            [float(c) for c in rows[0]]
        except ValueError:
            rows = rows[1:]  # a header line
    return _matrix(rows, f"in {str(path)!r}")


def resolve_assignments(values: Mapping[str, Any],
                        model_descriptions: Mapping[str, Any]) -> dict[str, dict[str, Any]]:
    """Values by instance, converted to the declared types of the FMUs' variables.

    A name is ``instance.NAME`` or a bare ``NAME`` that exactly one instance has. It must be
    a parameter (fixed or tunable) or an input; its value (a number, a boolean or text, as
    ``--set`` gives it) is converted as the system master converts every value
    (:func:`dronefly.harness.cosim.values.typed_value`: Real a finite number, Integer a whole
    number, Boolean true/false/1/0, String text). Values are in the FMU's own (SI) unit.

    Raises
    ------
    ParameterError
        An unknown or ambiguous name, a variable that cannot be set, a value its type cannot
        take (one line naming ``instance.NAME`` and the value).
    """
    from .system import SystemSpecError
    from .values import settable, typed_value

    out: dict[str, dict[str, Any]] = {}
    for key, value in values.items():
        inst, dot, name = key.partition(".")
        if dot and inst in model_descriptions:
            where = [inst]
        else:
            name = key
            where = [i for i, md in model_descriptions.items()
                     if any(v.name == key for v in md.modelVariables)]
            if len(where) > 1:
                raise ParameterError(f"{key!r} is a variable of {' and '.join(where)}: write "
                                     f"{where[0]}.{key} or {where[1]}.{key}")
            if not where:
                raise ParameterError(f"{key!r}: no such variable in {', '.join(model_descriptions)}")
        inst = where[0]
        v = next((x for x in model_descriptions[inst].modelVariables if x.name == name), None)
        if v is None:
            raise ParameterError(f"{key!r}: {inst} has no variable {name!r}")
        if name not in settable(model_descriptions[inst]):
            raise ParameterError(f"{key!r} is a {v.causality} {v.variability} variable of "
                                 f"{inst}; only parameters and inputs can be set")
        try:
            out.setdefault(inst, {})[name] = typed_value(f"{inst}.{name}", v, value)
        except SystemSpecError as e:
            raise ParameterError(str(e)) from e
    return out


#: The reference scales a plant/controller pair must share: the controller reads the plant's
#: state as x+ = x / (U, n, n, 1) with its own ``U`` [m/s] and ``n`` [Hz], and the harness
#: reads x+, times and gains with the plant's.
SHARED_SCALES: tuple[str, ...] = ("n", "U")


def scale_ratios(plant_start: Mapping[str, Any], controller_start: Mapping[str, Any], *,
                 allow_mismatch: bool = False,
                 override: str | None = "--allow-scale-mismatch") -> np.ndarray | None:
    """Per state, the plant's scale over the controller's, (U_p/U_c, n_p/n_c, n_p/n_c, 1).

    Parameters
    ----------
    plant_start, controller_start : mapping
        Each FMU's start values with the values set on it (``U`` in m/s, ``n`` in Hz).
    allow_mismatch : bool
        Accept scales that differ (the user intends it); otherwise they must be equal.
    override : str or None
        The option that says so, named in the message (None: the caller has none).

    Returns
    -------
    ndarray or None
        The ratios (all 1 when the scales agree); None when either FMU has no ``n`` or ``U``
        (nothing to compare).

    Raises
    ------
    ParameterError
        A scale differs and ``allow_mismatch`` is false (names both values).
    """
    if any(start.get(k) is None for start in (plant_start, controller_start)
           for k in SHARED_SCALES):
        return None
    p = {k: float(plant_start[k]) for k in SHARED_SCALES}
    c = {k: float(controller_start[k]) for k in SHARED_SCALES}
    for k, unit in zip(SHARED_SCALES, ("Hz", "m/s")):
        if not allow_mismatch and p[k] != c[k]:
            raise ParameterError(
                f"plant.{k} = {p[k]!r} {unit} and controller.{k} = {c[k]!r} {unit} disagree: "
                f"the controller reads the plant's state with its own {k}; set both (e.g. "
                f"--set plant.{k}={p[k]!r} --set controller.{k}={p[k]!r})"
                + (f", or pass {override} if the mismatch is intended" if override else ""))
    return np.array([p["U"] / c["U"], p["n"] / c["n"], p["n"] / c["n"], 1.0])
