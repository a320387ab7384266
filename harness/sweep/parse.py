"""Parsing of the sweep's list and number options, and its one input error class.

Each parser takes the command-line text (``"0.1,1,3"``) or the Python values and
returns a tuple; a bad value raises :class:`SweepInputError` naming it.
"""

from __future__ import annotations

import math
from typing import Iterable, Sequence

from ...core.errors import DroneflyError

__all__ = ["AXES", "SweepInputError", "one_line", "parse_floats", "parse_int", "parse_names",
           "parse_slices"]

#: Short names of the non-dimensional state components (x+ order).
AXES: tuple[str, ...] = ("dv", "dp", "dr", "dgamma")


class SweepInputError(DroneflyError):
    """Bad sweep input; the message names the offending value."""


def one_line(text: str) -> str:
    return " ".join(str(text).split())


def parse_floats(text: str | Iterable[float], name: str) -> tuple[float, ...]:
    """``"0.1,1,3"`` (or numbers) -> finite floats; empty or non-finite raises."""
    items = [p.strip() for p in text.split(",")] if isinstance(text, str) else list(text)
    if not items or items == [""]:
        raise SweepInputError(f"{name} = {text!r} is empty")
    out = []
    for p in items:
        try:
            v = float(p)
        except (TypeError, ValueError):
            raise SweepInputError(f"{name} = {text!r}: {p!r} is not a number") from None
        if not math.isfinite(v):
            raise SweepInputError(f"{name} = {text!r}: {p!r} is not finite")
        out.append(v)
    return tuple(out)


def parse_int(text: str | int, name: str, lo: int) -> int:
    """``"17"`` -> 17; not an integer or below ``lo`` raises."""
    try:
        v = int(str(text).strip())
    except ValueError:
        raise SweepInputError(f"{name} = {text!r} is not an integer") from None
    if v < lo:
        raise SweepInputError(f"{name} = {v} must be >= {lo}")
    return v


def parse_names(text: str | Iterable[str], name: str, allowed: Sequence[str]) -> tuple[str, ...]:
    """``"paper,open"`` -> names, each one of ``allowed`` (duplicates dropped, order kept)."""
    items = [p.strip() for p in text.split(",")] if isinstance(text, str) else list(text)
    if not items or items == [""]:
        raise SweepInputError(f"{name} = {text!r} is empty")
    for p in items:
        if p not in allowed and not (name == "gains" and p.lower().endswith((".csv", ".json"))):
            raise SweepInputError(f"{name}: unknown {p!r}; choose from {', '.join(allowed)}"
                                  + (" or a .csv/.json gain matrix" if name == "gains" else ""))
    return tuple(dict.fromkeys(items))


def parse_slices(text: str | Iterable[Sequence[str]]) -> tuple[tuple[str, str], ...]:
    """``"dgamma:dv,dp:dr"`` -> ((x axis, y axis), ...), two different state axes each."""
    items = ([p.strip().split(":") for p in text.split(",")] if isinstance(text, str)
             else [tuple(p) for p in text])
    if not items or items == [[""]]:
        raise SweepInputError(f"slices = {text!r} is empty")
    out = []
    for pair in items:
        if len(pair) != 2 or any(a not in AXES for a in pair) or pair[0] == pair[1]:
            raise SweepInputError(f"slice {':'.join(pair)!r}: expected two different axes "
                                  f"of {', '.join(AXES)} as X:Y")
        out.append((pair[0], pair[1]))
    return tuple(dict.fromkeys(out))
