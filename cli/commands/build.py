"""``dronefly build``: every FMU of the project, FMI 2.0 and 3.0, and its systems."""

from __future__ import annotations

import argparse
from pathlib import Path

from ...builder.build import FMI3_OUT, build_all
from ...core.files import check_output_folder
from . import EXIT_OK

__all__ = ["run"]


def run(args: argparse.Namespace) -> int:
    """Run ``dronefly build`` with the parsed arguments; returns the exit code."""
    check_output_folder(args.out)
    for path in [*build_all(args.out), *build_all(Path(args.out) / FMI3_OUT, fmi=3)]:
        print(path)
    return EXIT_OK
