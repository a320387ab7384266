"""``dronefly cosim``: co-simulate a plant/controller pair or a system, with verdicts."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from ...harness.builder.build import reporting
from ...harness.builder.native import native_pair
from ...core.errors import DroneflyError
from ...harness.stability.run import cosimulate
from ...harness.stability.system_verdicts import cosimulate_system
from . import EXIT_FAILED, EXIT_OK, feature

__all__ = ["SAYS_WHAT_IT_BUILT", "run"]

#: its summary and JSON name what it built: the command line adds no line of its own
SAYS_WHAT_IT_BUILT = True


def run(args: argparse.Namespace) -> int:
    """Run ``dronefly cosim`` with the parsed arguments; returns the exit code."""
    args.no_plot = not feature("cosim", not args.no_plot, "matplotlib", "plot")
    if args.native:
        given = [f"--{k}" for k in ("plant", "controller", "system")
                 if getattr(args, k) is not None]
        if given:
            raise DroneflyError(f"--native cannot be combined with {', '.join(given)} (it runs "
                                "the project's native plant and controller)")
        # the summary names what cosimulate builds; what --native builds is said here
        with reporting(lambda p: print(f"dronefly cosim: built {p}", file=sys.stderr,
                                       flush=True)):
            args.plant, args.controller = native_pair(args.build)
    if args.system is not None:
        return _cosim_system(args)
    if args.open_loop:
        raise DroneflyError("--open-loop needs --system (the plant/controller pair opens its "
                            "loop with --gains open)")
    # the --set values as text: converted to the variables' types by cosimulate
    result = cosimulate(args.plant, args.controller,
                        gains=args.gains,
                        x0=args.x0,
                        step_wingbeats=args.step,
                        stop_wingbeats=300.0 if args.stop is None else args.stop,
                        master=args.master, out_dir=args.out, plot=not args.no_plot,
                        set_values=dict(args.set_values), record=args.record or (),
                        build_dir=args.build, allow_scale_mismatch=args.allow_scale_mismatch)
    return _cosim_report(result, args.json)


def _cosim_report(result: Any, as_json: bool) -> int:
    """Print the summary (or the JSON) of a co-simulation; exit 1 if it stopped early or one
    of its cross-checks failed (the outputs are kept)."""
    print(json.dumps(result.to_json(), indent=2) if as_json else result.summary())
    code = EXIT_OK
    if not result.run.complete:
        print(f"dronefly cosim: error: run incomplete: {result.run.failure}", file=sys.stderr)
        code = EXIT_FAILED
    for failure in result.check_failures:
        print(f"dronefly cosim: error: cross-check failed: {failure}", file=sys.stderr)
        code = EXIT_FAILED
    return code


def _cosim_system(args: argparse.Namespace) -> int:
    given = [f"--{k}" for k in ("plant", "controller", "gains", "x0")
             if getattr(args, k) is not None]
    if given:
        raise DroneflyError(f"{', '.join(given)} cannot be combined with --system (set values "
                            "of the system's instances with --set instance.NAME=VALUE)")
    if not Path(args.system).is_file():
        raise DroneflyError(f"--system {args.system!r} " + (
            "is a folder, not an SSP file" if Path(args.system).is_dir() else "does not exist"))
    result = cosimulate_system(args.system, step_wingbeats=args.step, stop_wingbeats=args.stop,
                               master=args.master, set_values=dict(args.set_values),
                               record=args.record, out_dir=args.out, plot=not args.no_plot,
                               open_loop=args.open_loop)
    return _cosim_report(result, args.json)
