"""``dronefly floquet``: the periodic orbit and Floquet exponents of a plant FMU through FMI."""

from __future__ import annotations

import argparse
import json

from ...harness.flapping import floquet_analysis, floquet_text
from .args import int_arg, out_dir, positive
from . import EXIT_OK

__all__ = ["EPILOG", "add_arguments", "run"]

#: the examples of ``dronefly floquet --help`` (after its options)
EPILOG = ("examples:\n  dronefly floquet\n  dronefly floquet --json\n"
          "  dronefly floquet --plant build/DroneFlyLateral.fmu --period 0.006097560975609756\n"
          "units: --period in s (default 1/n, one wing beat); exponents per wing beat")


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Add the options of ``dronefly floquet`` to its subparser ``p``."""
    p.add_argument("--plant", default=None, metavar="FMU",
                   help="any FMI 2.0 or 3.0 CS FMU that can get and set its state, with an x_start "
                        "parameter per state output x (default: build/DroneFlyFlapping.fmu, "
                        "built if missing)")
    p.add_argument("--period", type=positive, default=None, metavar="S",
                   help="the period in s (default 1/n from the FMU's parameter n)")
    p.add_argument("--steps", type=int_arg("steps", 1), default=1, metavar="N",
                   help="communication steps per period (default 1)")
    p.add_argument("--build", type=out_dir, default="build", metavar="DIR",
                   help="where the default plant is built (default build/)")
    p.add_argument("--json", action="store_true", help="print JSON")


def run(args: argparse.Namespace) -> int:
    """Run ``dronefly floquet`` with the parsed arguments; returns the exit code."""
    result = floquet_analysis(args.plant, args.period, args.steps, args.build)
    print(json.dumps(result, indent=2) if args.json else floquet_text(result))
    return EXIT_OK
