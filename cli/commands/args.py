"""Argument converters of the ``dronefly`` command line (argparse ``type=`` functions).

Each turns one option's text into a value or raises :class:`argparse.ArgumentTypeError`
with one line naming the bad value; the parsing itself lives with the code that owns the
value (assignments in :mod:`dronefly.harness.cosim.params`, lists in
:mod:`dronefly.harness.sweep.parse`; the gains and the initial state of ``dronefly cosim`` in
:mod:`dronefly.harness.paper.gains` and :mod:`dronefly.harness.stability.run`, converted in
:mod:`dronefly.cli.commands.cosim`).
"""

from __future__ import annotations

import argparse
import math
import re
from typing import Any, Callable

from ...core.errors import DroneflyError
from ...core.files import check_output_dir, check_output_file
from ...harness.sweep.parse import parse_floats, parse_int

__all__ = ["converter", "finite", "floats_arg", "int_arg", "out_dir", "out_file", "parse_names",
           "parse_setting", "positive"]


def converter(fn: Callable[[str], Any]) -> Callable[[str], Any]:
    """An argparse ``type=`` from a parser that raises :class:`DroneflyError` (one line)."""

    def convert(text: str) -> Any:
        try:
            return fn(text)
        except DroneflyError as e:
            raise argparse.ArgumentTypeError(str(e)) from e

    convert.__name__ = fn.__name__
    return convert


@converter
def out_dir(text: str) -> str:
    """An output folder option (``--out DIR``, ``--build DIR``), checked when the command line
    is parsed, before any work, its default too (:func:`dronefly.core.files.check_output_dir`)."""
    check_output_dir(text)
    return text


@converter
def out_file(text: str) -> str:
    """An output file option (``--out FILE``): :func:`dronefly.core.files.check_output_file`."""
    check_output_file(text)
    return text


def int_arg(name: str, lo: int) -> Callable[[str], int]:
    def parse(text: str) -> int:
        return parse_int(text, name, lo)

    return converter(parse)


def floats_arg(name: str) -> Callable[[str], tuple[float, ...]]:
    def parse(text: str) -> tuple[float, ...]:
        return parse_floats(text, name)

    return converter(parse)


def parse_names(text: str) -> list[str]:
    """``a.x,b.K[1,2]`` -> ["a.x", "b.K[1,2]"]; each name must be instance.NAME (commas inside
    brackets belong to the name)."""

    names = [t.strip() for t in re.split(r",(?![^\[\]]*\])", text) if t.strip()]
    bad = [n for n in names if not n.partition(".")[2]]
    if not names or bad:
        raise ValueError(f"{text!r}: expected instance.NAME[,instance.NAME...]")
    return names


def parse_setting(text: str) -> tuple[str, str]:
    """``NAME=VALUE`` -> (NAME, VALUE as text): converted later to the variable's declared
    type (:mod:`dronefly.harness.cosim.typed_values`)."""
    name, sep, value = text.partition("=")
    if not sep or not name.strip() or not value.strip():
        raise argparse.ArgumentTypeError(f"{text!r}: expected NAME=VALUE, e.g. "
                                         "plant.Lv_plus=0.2")
    return name.strip(), value.strip()


def finite(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text!r} is not finite")
    return value


def positive(text: str) -> float:
    value = finite(text)
    if value <= 0.0:
        raise argparse.ArgumentTypeError(f"{text!r} must be > 0")
    return value
