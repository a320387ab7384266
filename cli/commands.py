"""The ``dronefly`` subcommands: one function per subcommand, each calling one Python function.

Each takes the parsed arguments and returns the exit code; :mod:`dronefly.cli` parses and
maps errors to exit codes. Imports are lazy so that ``dronefly --help`` is instant.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from ..core.errors import DroneflyError
from ..core.extras import require

__all__ = ["EXIT_FAILED", "EXIT_OK", "EXIT_USAGE", "aero", "analyze", "build", "check", "cosim", "demo",
           "simulate", "sweep"]

EXIT_OK, EXIT_FAILED, EXIT_USAGE = 0, 1, 2


def build(args: argparse.Namespace) -> int:
    from ..builder.build import build_all
    from ..builder.build3 import FMI3_OUT, build_all3

    for path in [*build_all(args.out), *build_all3(Path(args.out) / FMI3_OUT)]:
        print(path)
    return EXIT_OK


def simulate(args: argparse.Namespace) -> int:
    from ..harness.stability.simulate import simulate_plant

    result = simulate_plant(stop_wingbeats=args.stop, step_wingbeats=args.step,
                            gamma0=args.gamma0, out_dir=args.out)
    print(result.summary())
    return EXIT_OK if result.complete else EXIT_FAILED


def cosim(args: argparse.Namespace) -> int:
    if not args.no_plot:
        require("matplotlib", "pass --no-plot")
    if args.system is not None:
        return _cosim_system(args)
    if args.open_loop:
        raise DroneflyError("--open-loop needs --system (the plant/controller pair opens its "
                            "loop with --gains open)")
    from ..harness.stability.run import cosimulate

    # the --set values as text: converted to the variables' types by cosimulate
    result = cosimulate(args.plant, args.controller,
                        gains="paper" if args.gains is None else args.gains,
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
    import json

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
    from ..harness.stability.system import cosimulate_system

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


def _check_names(values: list[str], option: str) -> tuple[str, ...]:
    from ..harness.compliance.checker import CHECK_NAMES
    from ..harness.compliance.fmi3checks import FMI3_CHECKS

    known = [*CHECK_NAMES, *(n for n, _ in FMI3_CHECKS), "fuzz"]
    names = tuple(n.strip() for v in values for n in v.split(",") if n.strip())
    for n in names:
        if n not in known:
            raise DroneflyError(f"{option} {n!r}: no such check; known: {', '.join(known)}")
    return names


def check(args: argparse.Namespace) -> int:
    import json

    from ..harness.compliance.checker import CheckOptions
    from ..harness.compliance.suite import check_fmus, format_reports, reports_json, reports_junit

    options = CheckOptions(profile=None if args.profile == "auto" else args.profile,
                           stop_time=args.stop_time, step=args.step,
                           only=_check_names(args.check, "--check"),
                           skip=_check_names(args.skip, "--skip"))
    if args.junit and Path(args.junit).is_dir():
        raise DroneflyError(f"--junit {args.junit!r} is a folder; give the file to write")
    paths = [Path(p) for p in args.fmus]
    if not paths:
        from ..builder.build import FMUS, build_all, build_fmu

        paths = [p for p in build_all(args.build) if p.suffix == ".fmu"]
        paths += [build_fmu(name, Path(args.build) / "fmi3", fmi=3) for name in FMUS]
    for p in paths:
        if not p.is_file():
            raise DroneflyError(f"FMU {str(p)!r} " + ("is a folder, not an FMU file" if p.is_dir()
                                                  else "does not exist"))
    reports = check_fmus(paths, jobs=args.jobs, fuzz=not args.no_fuzz, options=options,
                         timeout_s=args.timeout)
    if args.junit:
        from ..core.files import write_text_atomic

        write_text_atomic(args.junit, reports_junit(reports))
    if args.json:
        print(json.dumps(reports_json(reports), indent=2))
    else:
        print(format_reports(reports, verbose=args.verbose))
    return EXIT_OK if all(r.passed for r in reports) else EXIT_FAILED


def demo(args: argparse.Namespace) -> int:
    from ..harness.stability.demo import demo_runs, format_table

    if not args.no_plot:
        require("matplotlib", "pass --no-plot")
    results = demo_runs(out_dir=args.out, plot=not args.no_plot,
                        set_values=dict(args.set_values), build_dir=args.build)
    print(format_table(results))
    failed = [(g, f) for g, r in zip(("open", "paper"), results) for f in r.check_failures]
    for gains, failure in failed:
        print(f"dronefly demo: error: cross-check failed ({gains}): {failure}", file=sys.stderr)
    return EXIT_FAILED if failed else EXIT_OK


def analyze(args: argparse.Namespace) -> int:
    from ..harness.paper.report import render
    from ..harness.paper.reproduction import analyze

    if args.out and Path(args.out).is_dir():
        raise DroneflyError(f"--out {args.out!r} is a folder; give the file to write")
    result = analyze(targets=args.targets, design_input=args.input)
    text = render(result, "json" if args.json else "markdown" if args.markdown else "text")
    if args.out:
        from ..core.files import write_text_atomic

        print(write_text_atomic(args.out, text))
    else:
        print(text, end="" if text.endswith("\n") else "\n")
    return EXIT_OK


#: the sweep's defaults, and those of a comparison (a wider box, one gain set and step)
_SWEEP_DEFAULTS = {"grid": 21, "amplitudes": 10, "gains": "paper,stabilising",
                   "steps": "0.1,1,3", "stop": "200", "extent": 1.0}
_SWEEP_COMPARE_DEFAULTS = {"grid": 25, "amplitudes": 12, "gains": "paper", "steps": "1",
                           "stop": "100", "extent": 3.0}


def sweep(args: argparse.Namespace) -> int:
    import json

    from ..harness.sweep.run import run_sweep
    from ..harness.sweep.cases import SweepSpec
    from ..harness.sweep.results import format_summary

    if args.scheduler is not None or args.workers != 1:  # one BLAS thread per worker process
        import os

        if args.scheduler is not None or (args.workers or os.cpu_count() or 1) > 1:
            require("threadpoolctl", "pass --workers 1")
    if not args.no_progress:
        require("tqdm", "pass --no-progress")
    if not args.no_plot:
        require("matplotlib", "pass --no-plot")
    if args.scheduler is not None:
        require("distributed")
    system, compare = args.system, args.compare
    d = _SWEEP_COMPARE_DEFAULTS if compare is not None else _SWEEP_DEFAULTS
    opt = {k: getattr(args, k) if getattr(args, k) is not None else v for k, v in d.items()}
    spec = SweepSpec.from_text(disturbances=args.disturbances, slices=args.slices,
                               grid=opt["grid"], lhs=args.lhs, directions=args.directions,
                               amplitudes=opt["amplitudes"], gains=opt["gains"],
                               steps=opt["steps"], scales=args.scales, stop=opt["stop"],
                               master=args.master, seed=args.seed, extent=opt["extent"],
                               delays=args.delays, sample_periods=args.sample_periods)
    if compare == "nonlinear":
        from ..builder.build import project_systems

        linear, nonlinear = project_systems()
        system, compare = system or linear, nonlinear
    workers, timeout = args.workers, args.connect_timeout
    result = run_sweep(spec, args.out, plant=args.plant, controller=args.controller,
                       workers=workers, scheduler=args.scheduler, connect_timeout_s=timeout,
                       fresh=args.fresh, plot=not args.no_plot,
                       progress_bar=False if args.no_progress else None,
                       set_values=dict(args.set_values), system=system, compare=compare)
    print(json.dumps(result.summary, indent=2) if args.json else format_summary(result.summary))
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


def aero(args: argparse.Namespace) -> int:
    import json

    from ..harness.aero import QuasiSteadyModel, Terms, parity_report

    if args.what != "forces" and (args.state or args.control):
        raise DroneflyError("--state and --control need 'dronefly aero forces'")

    def number(name: str, text: str) -> float:
        try:
            return float(text)
        except ValueError:
            raise DroneflyError(f"{name}={text!r} is not a number") from None

    model = QuasiSteadyModel(args.coefficients, Terms(
        translational=not args.no_translational, rotational=not args.no_rotational,
        added_mass=not args.no_added_mass, added_mass_form=args.added_mass_form))
    if args.what == "forces":
        forces = model.forces({k: number(k, v) for k, v in args.state},
                              {k: number(k, v) for k, v in args.control})
        print(json.dumps(forces, indent=2) if args.json
              else "  ".join(f"{k}+ = {v:+.6f}" for k, v in forces.items()))
        return EXIT_OK
    report = parity_report(model)
    print(json.dumps(report.to_json(), indent=2) if args.json else report.table())
    return EXIT_OK
