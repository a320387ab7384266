"""The gain matrices a user names or writes: the named sets and the 3 x 4 matrix readers.

The named gain sets: ``paper`` (Eq. 27 on delta_Phi_a), ``stabilising`` (the paper's
coefficient matching with lambda1 moved to -0.1), ``open`` (no control). A full 3 x 4 matrix is
read inline, from a CSV or from a JSON file. The functions double as argparse ``type=``
converters.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from ...models import lateral_dynamics
from ...models.feedback import default_gains
from ...models.lateral_interface import CONTROL_NAMES, STATE_NAMES
from ..cosim.params import ParameterError

__all__ = ["GAIN_SETS", "STABILISING_LAMBDA1", "as_gain_matrix", "gain_matrix", "parse_gains"]

#: Named gain sets (rows: controls, columns: x+; rad per unit of x+).
GAIN_SETS: tuple[str, ...] = ("paper", "stabilising", "open")
#: lambda1 of the ``stabilising`` set, per wing beat (the other eigenvalues kept).
STABILISING_LAMBDA1 = -0.1
_SHAPE = (len(CONTROL_NAMES), len(STATE_NAMES))


def gain_matrix(name: str) -> np.ndarray:
    """The 3x4 gain matrix of a named gain set."""
    if name == "paper":
        return np.array(default_gains(), dtype=float)
    if name == "open":
        return np.zeros(_SHAPE)
    if name == "stabilising":
        # the design pulls in scipy (slow to import): imported for this set only, so that what reads
        # gains (the CLI's converters, the sweep's cases and workers) starts without it
        from .design import move_lambda1_gains

        A, B = lateral_dynamics.system_matrices(lateral_dynamics.default_parameters())
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
