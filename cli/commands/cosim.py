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
from ...harness.paper.gains import parse_gains
from ...harness.stability.run import cosimulate, parse_x0
from ...harness.stability.system_verdicts import cosimulate_system
from .args import converter, out_dir, parse_names, parse_setting, positive
from . import EXIT_FAILED, EXIT_OK, feature

__all__ = ["EPILOG", "SAYS_WHAT_IT_BUILT", "add_arguments", "run"]

#: its summary and JSON name what it built: the command line adds no line of its own
SAYS_WHAT_IT_BUILT = True

#: the units of the options, the last lines of the epilog
_UNITS = ("\nunits: --step/--stop in wing beats (1 wing beat = 1/n = 6.1 ms); --x0 non-dimensional "
          "x+ = (dv/U, dp/n, dr/n, dgamma); --gains non-dimensional (rad per unit of x+); --set "
          "values in the FMU's SI unit (rad, m/s, rad/s, Hz)")
#: the examples of ``dronefly cosim --help`` (after its options)
EPILOG = ("examples:\n  dronefly cosim\n  dronefly cosim --native\n  dronefly cosim --gains open --json\n"
          "  dronefly cosim --gains=-0.3,-0.3,-0.2,-0.1 --step 1 --master jacobi\n"
          "  (a value starting with '-' needs the form --gains=... or --x0=...)\n"
          "  dronefly cosim --plant my/Plant.fmu --controller my/Controller.fmu\n"
          "  dronefly cosim --plant build/DroneFlyLongitudinal.fmu "
          "--controller build/StateFeedbackLongitudinal.fmu\n"
          "  dronefly cosim --gains='-0.3,-0.3,-0.2,-0.1;0,0,0,0;0.1,0,0,0'  (rows: "
          "delta_Phi_a; delta_alpha_1a; delta_alpha_2a)\n"
          "  dronefly cosim --gains my_gains.json --set plant.Lv_plus=0.25 --set u_max=0.3\n"
          "  dronefly cosim --system build/DroneFlyHover.ssp\n"
          "  dronefly cosim --system build/DroneFlyHover.ssp --open-loop\n"
          "  dronefly cosim --system my.ssp --set lateral.delta_p_start=1 "
          "--record lateral.delta_p,lateral.delta_gamma\n"
          "  dronefly cosim --step 1 --set controller.sensing_delay=0.036585365853658534 "
          "--set controller.sample_period=0.006097560975609756\n"
          "exit codes: 0 ok, 1 the run stopped early (partial result kept) or its "
          "cross-check failed: the identified loop against the exact sampled-data loop "
          "(with --system: against eig(A + B K), open loop eig(A); outputs kept), 2 bad "
          "input (also plant and controller with different n or U, without "
          "--allow-scale-mismatch), 130 interrupted" + _UNITS)


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Add the options of ``dronefly cosim`` to its subparser ``p``."""
    p.add_argument("--system", default=None, metavar="SSP",
                   help="co-simulate the system of an SSP file (any number of FMI 2.0 or 3.0 "
                        "CS FMUs); "
                        "--set takes instance.NAME=VALUE; not with --plant/--controller/--gains/"
                        "--x0")
    p.add_argument("--open-loop", action="store_true",
                   help="with --system: also identify each plant's open loop, from runs with the "
                        "gains K[i,j] of the controller that drives it set to zero, and "
                        "cross-check it against eig(A)")
    p.add_argument("--record", type=converter(parse_names), default=None,
                   metavar="INST.NAME,...", help="the variables to record, any Real, Integer "
                   "or Boolean variable of any instance, e.g. lateral.delta_p,"
                   "lateral_controller.K[1,1] with --system (default: every Real, Integer and "
                   "Boolean output); with "
                   "--plant/--controller, plant.NAME or controller.NAME, recorded after the "
                   "states and controls")
    p.add_argument("--native", action="store_true",
                   help="run the native (C) FMUs, DIR/native/DroneFlyLateral.fmu and "
                        "StateFeedback.fmu, built on demand (needs a C compiler; docs/native.md)")
    p.add_argument("--plant", default=None, metavar="FMU",
                   help="plant FMU (default: build/DroneFlyLateral.fmu, built on demand)")
    p.add_argument("--controller", default=None, metavar="FMU",
                   help="controller FMU (default: build/StateFeedback.fmu, built on demand)")
    p.add_argument("--gains", type=converter(parse_gains), default=None, metavar="GAINS",
                   help="non-dimensional 3x4 gain matrix u = K x+ of the lateral pair: paper "
                        "(Eq. 27), stabilising, open, 'k1,k2,k3,k4' (delta_Phi_a only), "
                        "'row1;row2;row3', or a .csv/.json file (default paper; for another "
                        "pair, e.g. the longitudinal one, the controller's own K, and open)")
    p.add_argument("--x0", type=converter(parse_x0), default=None,
                   metavar="dv+,dp+,dr+,dgamma",
                   help="non-dimensional initial state x+, one value per state of the plant "
                        "(default 0,0,0,0.1: a 0.1 rad roll; for another plant 0.1 rad on its "
                        "first angle; or what --set plant.<state>_start gives; not both)")
    p.add_argument("--set", dest="set_values", action="append", default=[],
                   type=parse_setting, metavar="NAME=VALUE",
                   help="set a parameter of the plant or controller (repeatable): plant.NAME=VALUE, "
                        "controller.NAME=VALUE, or NAME=VALUE if only one FMU has NAME; with "
                        "--system, instance.NAME=VALUE of any parameter or input; SI units; the "
                        "value of its declared type (a number, a whole number, true/false/1/0, "
                        "text)")
    p.add_argument("--allow-scale-mismatch", action="store_true",
                   help="accept a plant and a controller whose n or U differ (refused otherwise: "
                        "the controller reads the plant's state with its own n and U)")
    p.add_argument("--build", type=out_dir, default="build", metavar="DIR",
                   help="where the project's FMUs are built if --plant/--controller are not given")
    p.add_argument("--step", type=positive, default=0.1, help="communication step in wing beats (default 0.1)")
    p.add_argument("--stop", type=positive, default=None,
                   help="stop time in wing beats (default 300, or the SSP's DefaultExperiment)")
    p.add_argument("--master", choices=("gauss-seidel", "jacobi"), default="gauss-seidel",
                   help="ordering of the FMU calls (default gauss-seidel)")
    p.add_argument("--out", type=out_dir, default="build/cosim", metavar="DIR", help="folder of CSV, PNG and JSON")
    p.add_argument("--json", action="store_true", help="print a machine-readable summary")
    p.add_argument("--no-plot", action="store_true", help="do not write the PNG")


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
