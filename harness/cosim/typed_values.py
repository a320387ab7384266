"""Parameter and input values of a system's instances, converted to each variable's declared type.

A value comes from the command line (text), an SSV file or Python (numbers, booleans, text).
:func:`typed_values` converts every value of an instance against its FMU's model description
when a system is opened, so that a value of the wrong type is refused naming
``instance.NAME`` and the value before anything runs, never passed to an FMI setter:

- Real: a number (not a boolean) or its text, finite;
- Integer (and Enumeration): a whole number (``3``, ``3.0``, ``"3"``) in the 32-bit range;
  FMI 3.0's Int8 ... UInt64: a whole number in the type's range;
- Enumeration: also an item name (``"left"``), its value from the variable's type definition;
- Boolean: ``true``/``false``/``1``/``0`` (a boolean, 0 or 1, or that text);
- String: text.
"""

from __future__ import annotations

import math
import numbers
from typing import Any, Mapping

import numpy as np

from ...core.text import a_or_an
from .system import SystemSpecError

__all__ = ["SETTER", "settable", "shown", "typed_value", "typed_values"]

#: the integer types (FMI 2.0's Integer and Enumeration, FMI 3.0's Int8 ... UInt64) and
#: their ranges
_INT_RANGES = {"Integer": (-2 ** 31, 2 ** 31 - 1), "Enumeration": (-2 ** 31, 2 ** 31 - 1),
               **{f"{u}Int{b}": (0, 2 ** b - 1) if u else (-2 ** (b - 1), 2 ** (b - 1) - 1)
                  for u in ("", "U") for b in (8, 16, 32, 64)}}
#: the setter of each type (``set<SETTER>`` of fmpy's FMU2Slave or of the FMI 3.0 adapter,
#: :class:`~dronefly.harness.cosim.fmu3.FMU3Adapter`)
SETTER = {"Real": "Real", **{t: "Integer" for t in _INT_RANGES}, "Boolean": "Boolean",
          "String": "String"}
_BOOLS = (bool, np.bool_)


def settable(md: Any) -> dict[str, Any]:
    """The variables of a model description that a system may set: parameters and inputs,
    by name (not constants, not calculated parameters)."""
    return {v.name: v for v in md.modelVariables
            if v.causality in ("parameter", "input")
            and v.variability in ("fixed", "tunable", "continuous", "discrete")}


def shown(value: Any, limit: int = 40) -> str:
    """``repr(value)``, cut to about ``limit`` characters (a 400-digit value is named by its
    first digits and its length)."""
    text = repr(value)
    return text if len(text) <= limit else f"{text[:limit - 10]}... ({len(text)} characters)"


def _real(where: str, value: Any) -> float:
    if isinstance(value, str):
        try:
            x = float(value.strip())
        except ValueError:
            raise SystemSpecError(f"{where} = {shown(value)} is not a number (a Real)") from None
    elif isinstance(value, numbers.Real) and not isinstance(value, _BOOLS):
        try:
            x = float(value)
        except OverflowError:  # a Python int (or Fraction) beyond the double range
            raise SystemSpecError(f"{where} = {shown(value)} is beyond the range of a Real "
                                  "(a double)") from None
    else:
        raise SystemSpecError(f"{where} = {shown(value)}: a Real takes a number")
    if not math.isfinite(x):
        raise SystemSpecError(f"{where} = {shown(value)} is not finite")
    return x


def _whole(value: Any) -> int | None:
    """``value`` (text or number) as a whole number, or None; no float of a huge int."""
    if isinstance(value, str):
        text = value.strip()
        try:
            return int(text)
        except ValueError:
            try:
                value = float(text)
            except ValueError:
                return None
    if isinstance(value, _BOOLS) or not isinstance(value, numbers.Real):
        return None
    if isinstance(value, numbers.Integral):
        return int(value)
    if isinstance(value, numbers.Rational) and value.denominator == 1:
        return int(value.numerator)
    try:
        x = float(value)
    except OverflowError:  # a Fraction beyond the double range
        return None
    return int(x) if math.isfinite(x) and x == int(x) else None


def _integer(where: str, value: Any, kind: str = "Integer") -> int:
    x = _whole(value)
    if x is None:
        raise SystemSpecError(f"{where} = {shown(value)}: an Integer takes a whole number")
    low, high = _INT_RANGES[kind]
    if not low <= x <= high:
        raise SystemSpecError(f"{where} = {shown(value)} is outside the "
                              f"{'Integer' if kind == 'Enumeration' else kind} range "
                              f"{low}..{high}")
    return x


def _item(where: str, v: Any, name: str) -> int:
    """The value of the Enumeration item ``name`` in the variable's type definition."""
    items = getattr(getattr(v, "declaredType", None), "items", None) or []
    for item in items:
        if item.name == name.strip():
            return _integer(where, item.value)
    known = ", ".join(f"{i.name} = {i.value}" for i in items) or "none declared"
    raise SystemSpecError(f"{where} = {shown(name)} is not an item of the variable's "
                          f"Enumeration (items: {known})")


def _boolean(where: str, value: Any) -> bool:
    if isinstance(value, _BOOLS):
        return bool(value)
    if isinstance(value, str) and value.strip().lower() in ("true", "false", "1", "0"):
        return value.strip().lower() in ("true", "1")
    if isinstance(value, numbers.Real) and value in (0, 1):
        return bool(value)
    raise SystemSpecError(f"{where} = {shown(value)}: a Boolean takes true, false, 1 or 0")


def typed_value(where: str, v: Any, value: Any) -> Any:
    """``value`` as the type of the fmpy model variable ``v``.

    Parameters
    ----------
    where : str
        ``instance.NAME``, named in the error.
    v : fmpy ScalarVariable
        The variable (its ``type``: Real, Integer, Enumeration, Int8 ... UInt64, Boolean or
        String).
    value : object
        The value given (number, boolean or text).

    Raises
    ------
    SystemSpecError
        A value that the type cannot take (names ``where`` and the value).
    """
    if v.type == "Real":
        return _real(where, value)
    if v.type == "Enumeration" and isinstance(value, str) and _whole(value) is None:
        return _item(where, v, value)
    if v.type in _INT_RANGES:
        return _integer(where, value, v.type)
    if v.type == "Boolean":
        return _boolean(where, value)
    if v.type == "String":
        if not isinstance(value, str):
            raise SystemSpecError(f"{where} = {shown(value)}: a String takes text")
        return value
    raise SystemSpecError(f"{where} is {a_or_an(v.type)} variable, which a system cannot set")


def typed_values(inst: str, variables: Mapping[str, Any], values: Mapping[str, Any],
                 fmu_name: str = "") -> dict[str, Any]:
    """``values`` of instance ``inst`` converted to their variables' types.

    ``variables`` are the instance's settable variables (:func:`settable`).

    Raises
    ------
    SystemSpecError
        A name that is not a parameter or input, or a value of the wrong type.
    """
    out = {}
    for name, value in values.items():
        v = variables.get(name)
        if v is None:
            raise SystemSpecError(f"{inst}.{name}: no parameter or input of that name"
                                  + (f" in {fmu_name}" if fmu_name else ""))
        out[name] = typed_value(f"{inst}.{name}", v, value)
    return out
