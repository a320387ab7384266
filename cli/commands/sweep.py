"""``dronefly sweep``: closed-loop trajectories over the Sect. 3.6 bounds."""

from __future__ import annotations

import argparse
import json
import os
import sys
from typing import Any

from ...harness.builder.build import project_systems
from ...harness.builder.native import native_pair
from ...core.errors import DroneflyError
from ...core.files import write_text_atomic
from ...core.extras import require
from ...harness.sweep.backends import stderr_is_tty
from ...harness.sweep.cases import SweepSpec
from ...harness.sweep.results import format_summary
from ...harness.sweep.run import run_sweep
from ...harness.validity.halves import format_halves, halves_summary
from . import EXIT_FAILED, EXIT_OK, EXIT_USAGE, feature

__all__ = ["run"]


#: the sweep's defaults, and those of a comparison (a wider box, one gain set and step)
_SWEEP_DEFAULTS = {"grid": 21, "amplitudes": 10, "gains": "paper,stabilising",
                   "steps": "0.1,1,3", "stop": "200", "extent": 1.0}
_SWEEP_COMPARE_DEFAULTS = {"grid": 25, "amplitudes": 12, "gains": "paper", "steps": "1",
                           "stop": "100", "extent": 3.0}


def _add_halves(result: Any) -> None:
    """``--compare nonlinear --halves``: each half of Sect. 3.6 over the direction cases
    (:func:`dronefly.harness.validity.halves.halves_summary`, on the model classes), into the
    summary and ``sweep.json``."""
    result.summary["comparison"]["halves"] = halves_summary(result.rows)
    write_text_atomic(result.json, json.dumps(result.summary, indent=2, allow_nan=False) + "\n")


def run(args: argparse.Namespace) -> int:
    """Run ``dronefly sweep`` with the parsed arguments; returns the exit code."""
    if args.scheduler is not None:  # asked for: refused without Dask
        require("distributed")
    # the optional features: without their package, skipped with one line each
    feature("sweep", args.scheduler is not None or (args.workers or os.cpu_count() or 1) > 1,
            "threadpoolctl", "one BLAS thread per worker process")
    progress = feature("sweep", not args.no_progress and stderr_is_tty(), "tqdm", "progress bar")
    plot = feature("sweep", not args.no_plot, "matplotlib", "maps")
    system, compare = args.system, args.compare
    if args.native:
        given = [f"--{k}" for k in ("plant", "controller", "system", "compare")
                 if getattr(args, k) is not None]
        if given:
            raise DroneflyError(f"--native cannot be combined with {', '.join(given)} (it runs "
                                "the project's native plant and controller)")
        args.plant, args.controller = native_pair()
    if args.halves and compare != "nonlinear":
        print("dronefly sweep: error: --halves needs --compare nonlinear (the halves are "
              "those of the project's plants)", file=sys.stderr)
        return EXIT_USAGE
    d = _SWEEP_COMPARE_DEFAULTS if compare is not None else _SWEEP_DEFAULTS
    opt = {k: getattr(args, k) if getattr(args, k) is not None else v for k, v in d.items()}
    spec = SweepSpec.from_text(disturbances=args.disturbances, slices=args.slices,
                               grid=opt["grid"], lhs=args.lhs, directions=args.directions,
                               amplitudes=opt["amplitudes"], gains=opt["gains"],
                               steps=opt["steps"], scales=args.scales, stop=opt["stop"],
                               master=args.master, seed=args.seed, extent=opt["extent"],
                               delays=args.delays, sample_periods=args.sample_periods)
    if compare == "nonlinear":
        linear, nonlinear = project_systems()
        system, compare = system or linear, nonlinear
    workers, timeout = args.workers, args.connect_timeout
    result = run_sweep(spec, args.out, plant=args.plant, controller=args.controller,
                       workers=workers, scheduler=args.scheduler, connect_timeout_s=timeout,
                       fresh=args.fresh, plot=plot, progress_bar=progress,
                       set_values=dict(args.set_values), system=system, compare=compare)
    halves = args.halves and "comparison" in result.summary
    if halves:
        _add_halves(result)
    print(json.dumps(result.summary, indent=2) if args.json else format_summary(result.summary))
    if halves and not args.json:
        print("\n".join(format_halves(result.summary["comparison"].get("halves", []))))
    code = EXIT_OK
    if result.summary["errors"]:
        print(f"dronefly sweep: error: {result.summary['errors']} case(s) failed (see the "
              f"'error' column of {result.csv})", file=sys.stderr)
        code = EXIT_FAILED
    if result.summary.get("stability_disagreements"):
        print(f"dronefly sweep: error: cross-check failed: the verdict identified from the runs "
              f"disagrees with the loop's model in {result.summary['stability_disagreements']} "
              f"configuration(s) (columns stability, stability_identified of {result.csv})",
              file=sys.stderr)
        code = EXIT_FAILED
    return code
