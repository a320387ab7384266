"""``dronefly simulate``: the plant FMU in open loop against the exact solution."""

from __future__ import annotations

import argparse

from ...harness.stability.simulate import simulate_plant
from .args import finite, out_dir, positive
from . import EXIT_FAILED, EXIT_OK

__all__ = ["EPILOG", "SAYS_WHAT_IT_BUILT", "add_arguments", "run"]

#: its summary names what it built: the command line adds no line of its own
SAYS_WHAT_IT_BUILT = True

#: the examples of ``dronefly simulate --help`` (after its options)
EPILOG = ("examples:\n  dronefly simulate\n  dronefly simulate --gamma0 0.05 --stop 50\n"
          "units: --stop/--step in wing beats; --gamma0 in rad (SI)")


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Add the options of ``dronefly simulate`` to its subparser ``p``."""
    p.add_argument("--stop", type=positive, default=30.0, help="stop time in wing beats (default 30)")
    p.add_argument("--step", type=positive, default=0.1, help="communication step in wing beats (default 0.1)")
    p.add_argument("--gamma0", type=finite, default=0.1,
                   help="initial roll angle delta_gamma in rad, SI (default 0.1)")
    p.add_argument("--out", type=out_dir, default="build", metavar="DIR", help="folder of the FMU and the result CSV")


def run(args: argparse.Namespace) -> int:
    """Run ``dronefly simulate`` with the parsed arguments; returns the exit code."""
    result = simulate_plant(stop_wingbeats=args.stop, step_wingbeats=args.step,
                            gamma0=args.gamma0, out_dir=args.out)
    print(result.summary())
    return EXIT_OK if result.complete else EXIT_FAILED
