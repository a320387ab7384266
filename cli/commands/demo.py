"""``dronefly demo``: open loop and the paper's gains, co-simulated, in one table."""

from __future__ import annotations

import argparse
import sys

from ...harness.builder.native import native_pair
from ...harness.stability.demo import demo_runs, format_table
from . import EXIT_FAILED, EXIT_OK, feature

__all__ = ["run"]


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
