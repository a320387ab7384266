"""``dronefly floquet``: the periodic orbit and Floquet exponents of a plant FMU through FMI."""

from __future__ import annotations

import argparse
import json

from ...harness.flapping import floquet_analysis, floquet_text
from . import EXIT_OK

__all__ = ["run"]


def run(args: argparse.Namespace) -> int:
    """Run ``dronefly floquet`` with the parsed arguments; returns the exit code."""
    result = floquet_analysis(args.plant, args.period, args.steps, args.build)
    print(json.dumps(result, indent=2) if args.json else floquet_text(result))
    return EXIT_OK
