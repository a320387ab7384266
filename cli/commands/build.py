"""``dronefly build``: every FMU of the project, FMI 2.0 and 3.0, pythonfmu and native, and its
systems."""

from __future__ import annotations

import argparse
from pathlib import Path

from ...builder.build import FMI3_OUT, build_all
from ...builder.native import NATIVE_OUT, build_native_all
from . import EXIT_OK

__all__ = ["run"]


def run(args: argparse.Namespace) -> int:
    """Run ``dronefly build`` with the parsed arguments; returns the exit code."""
    out = Path(args.out)
    for path in [*build_all(out), *build_all(out / FMI3_OUT, fmi=3)]:
        print(path)
    native = out / NATIVE_OUT
    paths2, platforms = build_native_all(native, 2)
    paths3, _ = build_native_all(native / FMI3_OUT, 3)
    for path in [*paths2, *paths3]:
        print(path)
    if not platforms:
        print(f"no C compiler: the native FMUs in {native} are source-code FMUs (sources/ only; "
              "pip install ziglang for binaries)")
    return EXIT_OK
