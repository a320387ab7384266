"""The ``dronefly`` command line.

Each subcommand maps onto one Python function; imports are lazy so that
``dronefly --help`` is instant. Exit codes: 0 success, 1 a check failed,
2 bad input (one-line message on stderr, no traceback, no partial files).
"""

from __future__ import annotations

import argparse
import sys
from typing import Callable, Sequence

__all__ = ["main"]

EXIT_OK, EXIT_FAILED, EXIT_USAGE = 0, 1, 2


class UsageError(ValueError):
    """Bad command-line input; reported in one line with exit code 2."""


def _cmd_build(args: argparse.Namespace) -> int:
    from .build import build_all

    for path in build_all(args.out):
        print(path)
    return EXIT_OK


def _cmd_simulate(args: argparse.Namespace) -> int:
    from .simulate import simulate_plant

    result = simulate_plant(stop_wingbeats=args.stop, step_wingbeats=args.step,
                            gamma0=args.gamma0, out_dir=args.out)
    print(result.summary())
    return EXIT_OK if result.complete else EXIT_FAILED


def _cmd_cosim(args: argparse.Namespace) -> int:
    import json

    from .harness.cosim.run import cosimulate

    result = cosimulate(args.plant, args.controller, gains=args.gains, x0=args.x0,
                        step_wingbeats=args.step, stop_wingbeats=args.stop, master=args.master,
                        out_dir=args.out, plot=not args.no_plot)
    print(json.dumps(result.to_json(), indent=2) if args.json else result.summary())
    if not result.run.complete:
        print(f"dronefly cosim: error: run incomplete: {result.run.failure}", file=sys.stderr)
        return EXIT_FAILED
    return EXIT_OK


def _cmd_check(args: argparse.Namespace) -> int:
    import json
    from pathlib import Path

    from .harness.compliance.checker import check_fmu, format_reports

    paths = [Path(p) for p in args.fmus]
    if not paths:
        from .build import build_all

        paths = [p for p in build_all(args.build) if p.suffix == ".fmu"]
    for p in paths:
        if not p.is_file():
            raise UsageError(f"FMU {str(p)!r} " + ("is a folder, not an FMU file" if p.is_dir()
                                                  else "does not exist"))
    reports = [check_fmu(p) for p in paths]
    if args.json:
        print(json.dumps([{"fmu": str(r.path), "passed": r.passed,
                           "checks": [c.__dict__ for c in r.checks]} for r in reports], indent=2))
    else:
        print(format_reports(reports))
    return EXIT_OK if all(r.passed for r in reports) else EXIT_FAILED


def _cmd_demo(args: argparse.Namespace) -> int:
    from .harness.cosim.demo import verdict_table

    print(verdict_table(out_dir=args.out))
    return EXIT_OK


def _cmd_analyze(args: argparse.Namespace) -> int:
    from .harness.paper.report import render
    from .harness.paper.reproduction import analyze

    result = analyze(targets=args.targets, design_input=args.input)
    text = render(result, "json" if args.json else "markdown" if args.markdown else "text")
    if args.out:
        from .files import write_text_atomic

        print(write_text_atomic(args.out, text))
    else:
        print(text, end="" if text.endswith("\n") else "\n")
    return EXIT_OK


def _cmd_sweep(args: argparse.Namespace) -> int:
    import json

    from .harness.sweep.run import run_sweep
    from .harness.sweep.cases import SweepSpec, parse_floats, parse_int
    from .harness.sweep.results import format_summary

    spec = SweepSpec.from_text(disturbances=args.disturbances, slices=args.slices, grid=args.grid,
                               lhs=args.lhs, directions=args.directions,
                               amplitudes=args.amplitudes, gains=args.gains, steps=args.steps,
                               scales=args.scales, stop=args.stop, master=args.master,
                               seed=args.seed)
    workers = None if args.workers is None else parse_int(args.workers, "workers", 1)
    timeout = parse_floats(args.connect_timeout, "connect timeout")[0]
    result = run_sweep(spec, args.out, plant=args.plant, controller=args.controller,
                       workers=workers, scheduler=args.scheduler, connect_timeout_s=timeout,
                       fresh=args.fresh, plot=not args.no_plot,
                       progress_bar=False if args.no_progress else None)
    print(json.dumps(result.summary, indent=2) if args.json else format_summary(result.summary))
    if result.summary["errors"]:
        print(f"dronefly sweep: error: {result.summary['errors']} case(s) failed (see the "
              f"'error' column of {result.csv})", file=sys.stderr)
        return EXIT_FAILED
    return EXIT_OK


_EPILOG = {
    "cosim": "examples:\n  dronefly cosim\n  dronefly cosim --gains open --json\n"
             "  dronefly cosim --gains=-0.3,-0.3,-0.2,-0.1 --step 1 --master jacobi\n"
             "  (a value starting with '-' needs the form --gains=... or --x0=...)\n"
             "  dronefly cosim --plant my/Plant.fmu --controller my/Controller.fmu\n"
             "exit codes: 0 ok, 1 the run stopped early (partial result kept), 2 bad input",
    "demo": "examples:\n  dronefly demo",
    "check": "examples:\n  dronefly check\n  dronefly check build/DroneFlyLateral.fmu --json\n"
             "exit codes: 0 all checks passed, 1 a check failed, 2 bad input",
    "analyze": "examples:\n  dronefly analyze\n  dronefly analyze --json\n"
               "  dronefly analyze --markdown --out docs/reproduction.md\n"
               "  dronefly analyze --targets=-0.2,-0.089+0.057j,-0.089-0.057j,-0.51 "
               "--input delta_Phi_a",
    "sweep": "examples:\n  dronefly sweep\n  dronefly sweep --gains paper,stabilising,open "
             "--steps 0.1,0.5,1,2,3\n"
             "  dronefly sweep --disturbances lhs --lhs 500 --scales 1,1.5,2 --out build/lhs\n"
             "  dronefly sweep --scheduler tcp://10.0.0.5:8786\n"
             "rerun with the same --out to resume an interrupted sweep (--fresh starts over)\n"
             "exit codes: 0 ok, 1 some cases failed (recorded in the CSV), 2 bad input",
    "build": "examples:\n  dronefly build\n  dronefly build --out /tmp/fmus",
    "simulate": "examples:\n  dronefly simulate\n  dronefly simulate --gamma0 0.05 --stop 50",
}


class _Parser(argparse.ArgumentParser):
    """argparse with a one-line error (the usage is one ``--help`` away)."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message}\n")


def _parser() -> argparse.ArgumentParser:
    p = _Parser(
        prog="dronefly",
        description="FMUs and analysis of the lateral stabilization control of a hovering "
                    "model drone fly (Zhang & Sun).",
        epilog="examples:\n  dronefly build\n  dronefly simulate --stop 100",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")

    def add(name: str, helptext: str, fn: Callable[[argparse.Namespace], int]) -> argparse.ArgumentParser:
        sp = sub.add_parser(name, help=helptext, description=helptext, epilog=_EPILOG.get(name),
                            formatter_class=argparse.RawDescriptionHelpFormatter)
        sp.set_defaults(func=fn)
        return sp

    b = add("build", "build every FMU of the project", _cmd_build)
    b.add_argument("--out", default="build", metavar="DIR", help="output folder (default: build/)")

    s = add("simulate", "simulate the open-loop plant FMU with fmpy from a roll disturbance",
            _cmd_simulate)
    s.add_argument("--stop", type=_positive, default=30.0, help="stop time in wing beats (default 30)")
    s.add_argument("--step", type=_positive, default=0.1, help="communication step in wing beats (default 0.1)")
    s.add_argument("--gamma0", type=_finite, default=0.1, help="initial roll angle in rad (default 0.1)")
    s.add_argument("--out", default="build", metavar="DIR", help="folder of the FMU and the result CSV")

    c = add("cosim", "co-simulate plant and controller FMUs with fmpy and check neutral stability",
            _cmd_cosim)
    c.add_argument("--plant", default=None, metavar="FMU",
                   help="plant FMU (default: build/DroneFlyLateral.fmu, built on demand)")
    c.add_argument("--controller", default=None, metavar="FMU",
                   help="controller FMU (default: build/StateFeedback.fmu, built on demand)")
    c.add_argument("--gains", default="paper", metavar="paper|open|k1,k2,k3,k4",
                   help="Eq. (27) gains, no control, or four gains on delta_Phi_a (default paper)")
    c.add_argument("--x0", default="0,0,0,0.1", metavar="dv,dp,dr,dgamma",
                   help="non-dimensional initial state (default 0,0,0,0.1: a 0.1 rad roll)")
    c.add_argument("--step", type=_positive, default=0.1, help="communication step in wing beats (default 0.1)")
    c.add_argument("--stop", type=_positive, default=300.0, help="stop time in wing beats (default 300)")
    c.add_argument("--master", choices=("gauss-seidel", "jacobi"), default="gauss-seidel",
                   help="ordering of the FMU calls (default gauss-seidel)")
    c.add_argument("--out", default="build/cosim", metavar="DIR", help="folder of CSV, PNG and JSON")
    c.add_argument("--json", action="store_true", help="print a machine-readable summary")
    c.add_argument("--no-plot", action="store_true", help="do not write the PNG")

    k = add("check", "FMI 2.0 co-simulation compliance suite (fmpy validate, call sequence, reset, "
            "state, bad input, reference results)", _cmd_check)
    k.add_argument("fmus", nargs="*", metavar="FMU", help="FMUs to check (default: build the project "
                   "into --build and check every FMU there)")
    k.add_argument("--build", default="build", metavar="DIR", help="where to build (default build/)")
    k.add_argument("--json", action="store_true", help="machine-readable report")

    d = add("demo", "open loop and closed loop with the paper's gains: the verdict table",
            _cmd_demo)
    d.add_argument("--out", default="build/cosim", metavar="DIR", help="folder of CSVs and plots")

    a = add("analyze", "reproduce every number of the paper (Tables 2-3, Eqs. 12-32) from the model",
            _cmd_analyze)
    a.add_argument("--json", action="store_true", help="print JSON (table, matrices, eigenvalues, gains)")
    a.add_argument("--markdown", action="store_true", help="print the Markdown report (docs/reproduction.md)")
    a.add_argument("--targets", default=None, metavar="LIST",
                   help="comma-separated closed-loop eigenvalues per wing beat for an extra "
                        "gain design; write --targets=... when the first one is negative")
    a.add_argument("--input", default="delta_Phi_a", metavar="NAME",
                   help="control input of that design: delta_Phi_a (default), delta_alpha_1a, "
                        "delta_alpha_2a")
    a.add_argument("--out", default=None, metavar="FILE", help="write to FILE instead of stdout")
    w = add("sweep", "co-simulate many disturbed closed loops: where do they stay within the "
            "Sect. 3.6 bounds?", _cmd_sweep)
    w.add_argument("--out", default="build/sweep", metavar="DIR",
                   help="folder of sweep.csv, sweep.json and map_*.png; rerun to resume "
                        "(default build/sweep)")
    w.add_argument("--plant", default=None, metavar="FMU", help="plant FMU (default: built)")
    w.add_argument("--controller", default=None, metavar="FMU",
                   help="controller FMU (default: built)")
    w.add_argument("--disturbances", default="grid,directions", metavar="LIST",
                   help="initial disturbances: grid, lhs, directions (default grid,directions)")
    w.add_argument("--slices", default="dgamma:dv,dgamma:dp,dr:dp", metavar="X:Y,...",
                   help="2-D slices of the box for grid (axes dv, dp, dr, dgamma; "
                        "default dgamma:dv,dgamma:dp,dr:dp)")
    w.add_argument("--grid", default="21", metavar="N", help="grid points per axis (default 21)")
    w.add_argument("--lhs", default="200", metavar="N", help="Latin-hypercube samples (default 200)")
    w.add_argument("--directions", default=",".join(f"{s}{a}" for a in ("dv", "dp", "dr", "dgamma",
                                                                        "mode1") for s in "+-"),
                   metavar="LIST", help="directions for 'directions' (default: +-dv, +-dp, +-dr, "
                                        "+-dgamma, +-mode1 = the unstable eigenvector)")
    w.add_argument("--amplitudes", default="10", metavar="N",
                   help="amplitudes 1/N..1 of the box per direction (default 10)")
    w.add_argument("--gains", default="paper,stabilising", metavar="LIST",
                   help="gain sets: paper (Eq. 27), stabilising (lambda1 -> -0.1), open "
                        "(default paper,stabilising)")
    w.add_argument("--steps", default="0.1,1,3", metavar="LIST",
                   help="communication steps = how often the insect senses and acts, wing beats "
                        "(default 0.1,1,3)")
    w.add_argument("--scales", default="1", metavar="LIST", help="factors on the bounds (default 1)")
    w.add_argument("--stop", default="200", metavar="WB", help="wing beats per case (default 200)")
    w.add_argument("--master", choices=("gauss-seidel", "jacobi"), default="gauss-seidel",
                   help="ordering of the FMU calls (default gauss-seidel)")
    w.add_argument("--seed", default="0", metavar="N", help="seed of the Latin hypercube")
    w.add_argument("--workers", default=None, metavar="N",
                   help="local worker processes (default: all cores; 1 = in this process)")
    w.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="run on an existing Dask cluster, e.g. tcp://host:8786")
    w.add_argument("--connect-timeout", default="10", metavar="S",
                   help="seconds to reach the scheduler (default 10)")
    w.add_argument("--fresh", action="store_true", help="discard earlier results in --out")
    w.add_argument("--no-plot", action="store_true", help="do not write the PNG maps")
    w.add_argument("--no-progress", action="store_true", help="no progress bar")
    w.add_argument("--json", action="store_true", help="print the JSON summary")
    return p


def _finite(text: str) -> float:
    import math

    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text!r} is not finite")
    return value


def _positive(text: str) -> float:
    value = _finite(text)
    if value <= 0.0:
        raise argparse.ArgumentTypeError(f"{text!r} must be > 0")
    return value


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI; returns the exit code (also used by ``python -m dronefly``)."""
    parser = _parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as e:  # argparse already printed its one-line error or the help
        return int(e.code or 0)
    try:
        return int(args.func(args))
    except (UsageError, ValueError, OSError) as e:
        print(f"dronefly {args.command}: error: {e}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print(f"dronefly {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
