"""``dronefly build``: every FMU of the project, FMI 2.0 and 3.0, and its systems."""

from __future__ import annotations

import argparse
from pathlib import Path

from ...builder.build import FMI3_OUT, build_all
from . import EXIT_OK

__all__ = ["SAYS_WHAT_IT_BUILT", "run"]

#: prints every path it writes: the command line adds no line of its own
SAYS_WHAT_IT_BUILT = True


def run(args: argparse.Namespace) -> int:
    """Run ``dronefly build`` with the parsed arguments; returns the exit code."""
    for path in [*build_all(args.out), *build_all(Path(args.out) / FMI3_OUT, fmi=3)]:
        print(path)
    return EXIT_OK
