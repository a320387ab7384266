"""What a user sets on a co-simulation: ``NAME=VALUE`` parameter values, checked against the
FMUs' model descriptions, and the reference scales both FMUs must share.

The gain matrices a user names or writes are :mod:`dronefly.harness.paper.gains`'.
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from ...core.errors import DroneflyError
from ...core.text import a_or_an
from .system import SystemSpecError
from .typed_values import settable, typed_value

__all__ = ["SHARED_SCALES", "ParameterError", "resolve_assignments", "scale_ratios"]


class ParameterError(DroneflyError):
    """A gain matrix or a ``NAME=VALUE`` that cannot be used (names the value)."""


def resolve_assignments(values: Mapping[str, Any],
                        model_descriptions: Mapping[str, Any]) -> dict[str, dict[str, Any]]:
    """Values by instance, converted to the declared types of the FMUs' variables.

    A name is ``instance.NAME`` or a bare ``NAME`` that exactly one instance has. It must be
    a parameter (fixed or tunable) or an input; its value (a number, a boolean or text, as
    ``--set`` gives it) is converted as the system master converts every value
    (:func:`dronefly.harness.cosim.typed_values.typed_value`: Real a finite number, Integer a whole
    number, Boolean true/false/1/0, String text). Values are in the FMU's own (SI) unit.

    Raises
    ------
    ParameterError
        An unknown or ambiguous name, a variable that cannot be set, a value its type cannot
        take (one line naming ``instance.NAME`` and the value).
    """

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
            raise ParameterError(f"{key!r} is {a_or_an(v.causality)} {v.variability} variable of "
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
                 override: str | None = "--allow-scale-mismatch",
                 scales: tuple[str, ...] = ("U", "n", "n", "1")) -> np.ndarray | None:
    """Per state, the plant's scale over the controller's: for the lateral ``scales``
    (U_p/U_c, n_p/n_c, n_p/n_c, 1).

    Parameters
    ----------
    plant_start, controller_start : mapping
        Each FMU's start values with the values set on it (``U`` in m/s, ``n`` in Hz).
    allow_mismatch : bool
        Accept scales that differ (the user intends it); otherwise they must be equal.
    override : str or None
        The option that says so, named in the message (None: the caller has none).
    scales : tuple of str
        Per state, the scale that makes it non-dimensional: ``"U"``, ``"n"`` or ``"1"``
        (:attr:`~dronefly.harness.cosim.pair.PairLayout.scales`).

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
    ratio = {"U": p["U"] / c["U"], "n": p["n"] / c["n"], "1": 1.0}
    return np.array([ratio[s] for s in scales])
