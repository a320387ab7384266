"""``dronefly simulate``: the plant FMU in open loop against the exact solution."""

from __future__ import annotations

import argparse

from ...core.files import check_output_folder
from ...harness.stability.simulate import simulate_plant
from . import EXIT_FAILED, EXIT_OK

__all__ = ["run"]


def run(args: argparse.Namespace) -> int:
    """Run ``dronefly simulate`` with the parsed arguments; returns the exit code."""
    check_output_folder(args.out)
    result = simulate_plant(stop_wingbeats=args.stop, step_wingbeats=args.step,
                            gamma0=args.gamma0, out_dir=args.out)
    print(result.summary())
    return EXIT_OK if result.complete else EXIT_FAILED
