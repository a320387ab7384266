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
from .args import floats_arg, int_arg, out_dir, parse_setting, positive
from . import EXIT_FAILED, EXIT_OK, EXIT_USAGE, feature

__all__ = ["EPILOG", "add_arguments", "run"]


#: the sweep's defaults, and those of a comparison (a wider box, one gain set and step)
_SWEEP_DEFAULTS = {"grid": 21, "amplitudes": 10, "gains": "paper,stabilising",
                   "steps": "0.1,1,3", "stop": "200", "extent": 1.0}
_SWEEP_COMPARE_DEFAULTS = {"grid": 25, "amplitudes": 12, "gains": "paper", "steps": "1",
                           "stop": "100", "extent": 3.0}

#: the units of the options, the last lines of the epilog
_UNITS = ("\nunits: --steps/--delays/--sample-periods/--stop in wing beats (1 wing beat = "
          "1/n = 6.1 ms); --gains non-dimensional (rad per unit of x+ = (dv/U, dp/n, dr/n, "
          "dgamma)); --set values in the FMU's SI unit (rad, m/s, rad/s, Hz)")
#: the examples of ``dronefly sweep --help`` (after its options)
EPILOG = ("examples:\n  dronefly sweep\n  dronefly sweep --native\n  dronefly sweep --gains paper,stabilising,open "
          "--steps 0.1,0.5,1,2,3\n"
          "  dronefly sweep --disturbances lhs --lhs 500 --scales 1,1.5,2 --out build/lhs\n"
          "  dronefly sweep --scheduler tcp://10.0.0.5:8786\n"
          "rerun with the same --out to resume an interrupted sweep (--fresh starts over)\n"
          "  dronefly sweep --gains paper,my_gains.csv --set plant.Nr_plus=-5\n"
          "  dronefly sweep --system build/DroneFlyHover.ssp --disturbances directions\n"
          "  dronefly sweep --compare nonlinear --out build/validity\n"
          "  dronefly sweep --steps 0.5 --delays 0,1,2,4 --sample-periods 0,1,2 "
          "--disturbances directions\n"
          "exit codes: 0 ok, 1 some cases failed (recorded in the CSV), 2 bad input, "
          "130 interrupted (rerun to resume)" + _UNITS)


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Add the options of ``dronefly sweep`` to its subparser ``p``."""
    p.add_argument("--out", type=out_dir, default="build/sweep", metavar="DIR",
                   help="folder of sweep.csv, sweep.json and map_*.png; rerun to resume "
                        "(default build/sweep)")
    p.add_argument("--plant", default=None, metavar="FMU", help="plant FMU (default: built)")
    p.add_argument("--native", action="store_true",
                   help="run the native (C) FMUs, build/native/DroneFlyLateral.fmu and "
                        "StateFeedback.fmu, built on demand (needs a C compiler; docs/native.md)")
    p.add_argument("--controller", default=None, metavar="FMU",
                   help="controller FMU (default: built)")
    p.add_argument("--compare", default=None, metavar="SSP",
                   help="run every case also on this system and measure how far the two "
                        "trajectories differ; 'nonlinear' = the 6-DOF plant "
                        "(build/DroneFlyHover6DOF.ssp) against the linear plants "
                        "(build/DroneFlyHover.ssp), built on demand. Defaults then: --gains "
                        "paper, --steps 1, --stop 100, --grid 25, --amplitudes 12, --extent 3")
    p.add_argument("--halves", action="store_true",
                   help="with --compare nonlinear: also the error of each half of Sect. 3.6 "
                        "(the rigid body, the quasi-steady aerodynamics, both) over the "
                        "direction cases, on the model classes (docs/validity.md; about 1 s "
                        "per case, so not by default)")
    p.add_argument("--extent", type=positive, default=None, metavar="X",
                   help="the disturbances cover X times the Sect. 3.6 box (default 1; 3 with "
                        "--compare)")
    p.add_argument("--system", default=None, metavar="SSP",
                   help="run every case on this system of FMUs (its lateral plant and the "
                        "controller driving it get x0 and gains; --set takes instance.NAME=VALUE)")
    p.add_argument("--disturbances", default="grid,directions", metavar="LIST",
                   help="initial disturbances: grid, lhs, directions (default grid,directions)")
    p.add_argument("--slices", default="dgamma:dv,dgamma:dp,dr:dp", metavar="X:Y,...",
                   help="2-D slices of the box for grid (axes dv, dp, dr, dgamma; "
                        "default dgamma:dv,dgamma:dp,dr:dp)")
    p.add_argument("--grid", type=int_arg("grid", 2), default=None, metavar="N",
                   help="grid points per axis (default 21)")
    p.add_argument("--lhs", type=int_arg("lhs", 1), default=200, metavar="N",
                   help="Latin-hypercube samples (default 200)")
    p.add_argument("--directions", default=",".join(f"{s}{a}" for a in ("dv", "dp", "dr", "dgamma",
                                                                        "mode1") for s in "+-"),
                   metavar="LIST", help="directions for 'directions' (default: +-dv, +-dp, +-dr, "
                                        "+-dgamma, +-mode1 = the unstable eigenvector)")
    p.add_argument("--amplitudes", type=int_arg("amplitudes", 1), default=None, metavar="N",
                   help="amplitudes 1/N..1 of the box per direction (default 10)")
    p.add_argument("--gains", default=None, metavar="LIST",
                   help="gain sets: paper (Eq. 27), stabilising (lambda1 -> -0.1), open, or a "
                        ".csv/.json file with a 3x4 matrix (default paper,stabilising)")
    p.add_argument("--set", dest="set_values", action="append", default=[],
                   type=parse_setting, metavar="NAME=VALUE",
                   help="set a parameter of the plant or controller for every case (repeatable; "
                        "SI units)")
    p.add_argument("--steps", type=floats_arg("steps"), default=None, metavar="LIST",
                   help="communication steps = how often the insect senses and acts, wing beats "
                        "(default 0.1,1,3)")
    p.add_argument("--delays", type=floats_arg("delays"), default="0", metavar="LIST",
                   help="the controller's sensing delays, wing beats (1 wb = 1000/n ms, 6.1 ms "
                        "at 164 Hz; default 0 = not set); adds the loop's verdict with the "
                        "delay states to every row")
    p.add_argument("--sample-periods", type=floats_arg("sample-periods"), default="0",
                   metavar="LIST", help="the controller's sample periods, wing beats (default "
                                        "0 = every communication step)")
    p.add_argument("--scales", type=floats_arg("scales"), default="1", metavar="LIST",
                   help="factors on the bounds (default 1)")
    p.add_argument("--stop", type=floats_arg("stop"), default=None, metavar="WB",
                   help="wing beats per case (default 200)")
    p.add_argument("--master", choices=("gauss-seidel", "jacobi"), default="gauss-seidel",
                   help="ordering of the FMU calls (default gauss-seidel)")
    p.add_argument("--seed", type=int_arg("seed", 0), default=0, metavar="N",
                   help="seed of the Latin hypercube")
    p.add_argument("--workers", type=int_arg("workers", 1), default=None, metavar="N",
                   help="local worker processes (default: all cores; 1 = in this process)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="run on an existing Dask cluster, e.g. tcp://host:8786")
    p.add_argument("--connect-timeout", type=positive, default=10.0, metavar="S",
                   help="seconds to reach the scheduler (default 10)")
    p.add_argument("--fresh", action="store_true", help="discard earlier results in --out")
    p.add_argument("--no-plot", action="store_true", help="do not write the PNG maps")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--json", action="store_true", help="print the JSON summary")


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
