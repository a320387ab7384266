"""``dronefly simulate``: the plant FMU in open loop against the exact solution."""

from __future__ import annotations

import argparse

from ...harness.stability.simulate import simulate_plant
from . import EXIT_FAILED, EXIT_OK

__all__ = ["SAYS_WHAT_IT_BUILT", "run"]

#: its summary names what it built: the command line adds no line of its own
SAYS_WHAT_IT_BUILT = True


def run(args: argparse.Namespace) -> int:
    """Run ``dronefly simulate`` with the parsed arguments; returns the exit code."""
    result = simulate_plant(stop_wingbeats=args.stop, step_wingbeats=args.step,
                            gamma0=args.gamma0, out_dir=args.out)
    print(result.summary())
    return EXIT_OK if result.complete else EXIT_FAILED
