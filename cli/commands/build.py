"""``dronefly build``: every FMU of the project, FMI 2.0 and 3.0, and its systems; with
``--native`` also the native FMUs for every platform the toolchain builds for."""

from __future__ import annotations

import argparse
from pathlib import Path

from ...harness.builder.build import FMI3_OUT, build_all
from ...harness.builder.native import NATIVE_OUT, build_native_all, build_native_container
from .args import out_dir
from . import EXIT_OK

__all__ = ["EPILOG", "SAYS_WHAT_IT_BUILT", "add_arguments", "run"]

#: prints every path it writes: the command line adds no line of its own
SAYS_WHAT_IT_BUILT = True

#: the examples of ``dronefly build --help`` (after its options)
EPILOG = "examples:\n  dronefly build\n  dronefly build --out /tmp/fmus\n  dronefly build --native"


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Add the options of ``dronefly build`` to its subparser ``p``."""
    p.add_argument("--out", type=out_dir, default="build", metavar="DIR", help="output folder (default: build/)")
    p.add_argument("--native", action="store_true",
                   help="also the native (C) FMUs in DIR/native and DIR/native/fmi3, with binaries "
                        "for every platform the toolchain builds for (zig cc: Linux, Windows, "
                        "macOS; a minute or more) and the closed-loop container (docs/native.md)")


def run(args: argparse.Namespace) -> int:
    """Run ``dronefly build`` with the parsed arguments; returns the exit code."""
    out = Path(args.out)
    for path in [*build_all(out), *build_all(out / FMI3_OUT, fmi=3)]:
        print(path)
    if not getattr(args, "native", False):
        return EXIT_OK
    native = out / NATIVE_OUT
    paths2, platforms = build_native_all(native, 2)
    paths3, _ = build_native_all(native / FMI3_OUT, 3)
    for path in [*paths2, *paths3]:
        print(path)
    if platforms:  # the container runs binaries: none from source-code FMUs
        print(build_native_container(native))
    else:
        print(f"no C compiler: the native FMUs in {native} are source-code FMUs (sources/ only, "
              "no closed-loop container; pip install ziglang for binaries)")
    return EXIT_OK
