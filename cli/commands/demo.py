"""``dronefly demo``: open loop and the paper's gains, co-simulated, in one table."""

from __future__ import annotations

import argparse
import sys

from ...harness.builder.native import native_pair
from ...harness.stability.demo import demo_runs, format_table
from .args import out_dir, parse_setting
from . import EXIT_FAILED, EXIT_OK, feature

__all__ = ["EPILOG", "add_arguments", "run"]

#: the examples of ``dronefly demo --help`` (after its options)
EPILOG = ("examples:\n  dronefly demo\n  dronefly demo --native --no-plot\n  dronefly demo --no-plot --set plant.Nr_plus=-5\n"
          "exit codes: 0 ok, 1 a run's cross-check failed (outputs kept), 2 bad input")


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Add the options of ``dronefly demo`` to its subparser ``p``."""
    p.add_argument("--out", type=out_dir, default="build/cosim", metavar="DIR", help="folder of CSVs and plots")
    p.add_argument("--no-plot", action="store_true", help="do not write the PNGs")
    p.add_argument("--set", dest="set_values", action="append", default=[],
                   type=parse_setting, metavar="NAME=VALUE",
                   help="set a parameter of the plant or controller for both runs (repeatable; "
                        "SI units), as cosim --set")
    p.add_argument("--build", type=out_dir, default="build", metavar="DIR",
                   help="where the project's FMUs are built if missing or out of date")
    p.add_argument("--native", action="store_true",
                   help="run the native (C) FMUs, DIR/native/DroneFlyLateral.fmu and "
                        "StateFeedback.fmu, built on demand (needs a C compiler; docs/native.md)")


def run(args: argparse.Namespace) -> int:
    """Run ``dronefly demo`` with the parsed arguments; returns the exit code."""
    plot = feature("demo", not args.no_plot, "matplotlib", "plots")
    plant, controller = native_pair(args.build) if args.native else (None, None)
    results = demo_runs(out_dir=args.out, plot=plot,
                        set_values=dict(args.set_values), build_dir=args.build, plant=plant,
                        controller=controller)
    print(format_table(results))
    failed = [(g, f) for g, r in zip(("open", "paper"), results) for f in r.check_failures]
    for gains, failure in failed:
        print(f"dronefly demo: error: cross-check failed ({gains}): {failure}", file=sys.stderr)
    return EXIT_FAILED if failed else EXIT_OK
