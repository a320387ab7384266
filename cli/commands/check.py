"""``dronefly check``: the compliance suite on FMUs (ours, built, or anyone's)."""

from __future__ import annotations

import argparse
import contextlib
import json
import signal
import sys
import threading
from pathlib import Path
from typing import Iterator

import fmpy

from ...harness.builder.build import FMUS, build_all, build_fmu
from ...core.errors import DroneflyError
from ...core.files import write_text_atomic
from ...harness.compliance.checker import CHECK_NAMES, CheckOptions, experiment
from ...harness.compliance.suite import (CheckInterrupted, check_fmus, format_reports,
                                         reports_json, reports_junit)
from ...harness.cosim.fmu import FMUError
from .args import int_arg, positive
from . import EXIT_FAILED, EXIT_OK

__all__ = ["EPILOG", "add_arguments", "run"]

#: the examples of ``dronefly check --help`` (after its options)
EPILOG = ("examples:\n  dronefly check\n  dronefly check build/DroneFlyLateral.fmu --json\n"
          "  dronefly check Model.fmu --ref Model_ref.csv --in Model_in.csv\n"
          "exit codes: 0 all checks passed, 1 a check failed, 2 bad input")


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Add the options of ``dronefly check`` to its subparser ``p``."""
    p.add_argument("fmus", nargs="*", metavar="FMU", help="FMUs to check (default: build the project "
                   "into --build, FMI 2.0 and FMI 3.0, and check every FMU there)")
    p.add_argument("--build", default="build", metavar="DIR",
                   help="where to build (default build/; the FMI 3.0 FMUs in DIR/fmi3)")
    p.add_argument("--json", action="store_true", help="machine-readable report (with a schema "
                   "version, each check passed/failed/skipped, durations)")
    p.add_argument("--junit", default=None, metavar="FILE",
                   help="also write JUnit XML: a test case per check and FMU")
    p.add_argument("--verbose", action="store_true",
                   help="also show each rule and what the FMU's binaries printed while checked")
    p.add_argument("--no-fuzz", action="store_true", help="skip the short fuzz (faster)")
    p.add_argument("--profile", choices=("auto", "standard", "dronefly"), default="auto",
                   help="standard: the FMI standard alone; dronefly: also the project's stricter "
                        "promises (NaN refused, log wording, corrupt states, fuzz); auto "
                        "(default): dronefly for the project's FMUs, standard for any other")
    p.add_argument("--check", action="append", default=[], metavar="NAME",
                   help="run only this check (repeat, or NAME,NAME)")
    p.add_argument("--skip", action="append", default=[], metavar="NAME",
                   help="do not run this check (repeat, or NAME,NAME)")
    p.add_argument("--stop-time", type=positive, default=None, metavar="S",
                   help="stop time in seconds (default: the FMU's default experiment)")
    p.add_argument("--step", type=positive, default=None, metavar="S",
                   help="communication step in seconds (default: the default experiment's "
                        "stepSize, or a hundredth of the run)")
    p.add_argument("-j", "--jobs", type=int_arg("-j", 1), default=1, metavar="N",
                   help="check N FMUs at once (default 1)")
    p.add_argument("--timeout", type=positive, default=600.0, metavar="S",
                   help="how long the checks of one FMU may take before it is reported as hung "
                        "(default 600 s)")
    p.add_argument("--ref", default=None, metavar="CSV",
                   help="reference result of the one FMU given (FMI cross-check CSV: time, then "
                        "outputs), compared by the reference check (default: <Model>_ref.csv "
                        "beside the FMU, if there)")
    p.add_argument("--in", dest="inputs", default=None, metavar="CSV",
                   help="with --ref: the inputs of the reference run (cross-check CSV)")


def _check_names(values: list[str], option: str) -> tuple[str, ...]:
    known = [*CHECK_NAMES, "fuzz"]
    names = tuple(n.strip() for v in values for n in v.split(",") if n.strip())
    for n in names:
        if n not in known:
            raise DroneflyError(f"{option} {n!r}: no such check; known: {', '.join(known)}")
    return names


def _selection(args: argparse.Namespace, options: CheckOptions) -> None:
    """Refuse a selection of checks that selects nothing or cannot take effect."""
    if options.only and not [n for n in options.only if n not in options.skip]:
        raise DroneflyError(f"--check {','.join(options.only)} with --skip "
                            f"{','.join(options.skip)}: selects no check")
    if args.no_fuzz and "fuzz" in options.only:
        raise DroneflyError("--check fuzz cannot take effect with --no-fuzz")


def _experiments(paths: list[Path], options: CheckOptions) -> None:
    """Refuse --stop-time / --step that leave no whole step on some FMU (before any check)."""
    if options.stop_time is None and options.step is None:
        return  # the FMUs' own default experiments: a bad one is a failed check of that FMU
    given = " ".join(f"{o} {v!r}" for o, v in (("--stop-time", options.stop_time),
                                               ("--step", options.step)) if v is not None)
    if options.stop_time is not None and options.step is not None \
            and options.step > options.stop_time:
        raise DroneflyError(f"{given}: the step is longer than the run")
    for p in paths:
        try:
            md = fmpy.read_model_description(str(p), validate=False)
        except Exception:  # not a readable FMU: its load check says so
            continue
        try:
            experiment(md, options)
        except FMUError as e:
            raise DroneflyError(f"{given} on {str(p)!r}: {e}") from None


def _reference(args: argparse.Namespace) -> None:
    """Refuse --ref / --in that cannot take effect: not one FMU, --in alone, a missing file."""
    if args.ref is None and args.inputs is None:
        return
    if args.ref is None:
        raise DroneflyError(f"--in {args.inputs!r} needs --ref (the reference result of that run)")
    if len(args.fmus) != 1:
        raise DroneflyError(f"--ref {args.ref!r} is the reference result of one FMU; "
                            f"{len(args.fmus)} given")
    for option, path in (("--ref", args.ref), ("--in", args.inputs)):
        if path is not None and not Path(path).is_file():
            raise DroneflyError(f"{option} {path!r}: no such file")


def _junit_target(junit: str | None) -> None:
    if not junit:
        return
    target = Path(junit)
    if target.is_dir():
        raise DroneflyError(f"--junit {junit!r} is a folder; give the file to write")
    folder = target.parent
    if not folder.is_dir():
        raise DroneflyError(f"--junit {junit!r}: the folder {str(folder)!r} "
                            + ("is a file" if folder.exists() else "does not exist"))


@contextlib.contextmanager
def _sigterm_exits() -> Iterator[None]:
    """SIGTERM (a CI job's timeout, ``kill``) ends the checks as SystemExit(143), so that the
    checking processes are stopped and their temporary folders removed on the way out."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def stop(signum: int, frame: object) -> None:
        raise SystemExit(128 + signal.SIGTERM)

    previous = signal.signal(signal.SIGTERM, stop)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def run(args: argparse.Namespace) -> int:
    """Run ``dronefly check`` with the parsed arguments; returns the exit code."""
    options = CheckOptions(profile=None if args.profile == "auto" else args.profile,
                           stop_time=args.stop_time, step=args.step,
                           only=_check_names(args.check, "--check"),
                           skip=_check_names(args.skip, "--skip"),
                           ref=args.ref, inputs=args.inputs)
    _selection(args, options)
    _reference(args)
    _junit_target(args.junit)
    paths = [Path(p) for p in args.fmus]
    for p in paths:
        if not p.is_file():
            raise DroneflyError(f"FMU {str(p)!r} " + ("is a folder, not an FMU file" if p.is_dir()
                                                  else "does not exist"))
    _experiments(paths, options)
    if not paths:
        paths = [p for p in build_all(args.build) if p.suffix == ".fmu"]
        paths += [build_fmu(name, Path(args.build) / "fmi3", fmi=3) for name in FMUS]
        _experiments(paths, options)
    try:
        with _sigterm_exits():
            reports = check_fmus(paths, jobs=args.jobs, fuzz=not args.no_fuzz, options=options,
                                 timeout_s=args.timeout)
    except CheckInterrupted as stop:  # the finished FMUs shown; no report file claims more
        if not args.json and stop.reports:
            print(format_reports(stop.reports, verbose=args.verbose))
        print(f"dronefly check: {len(stop.reports)} of {len(paths)} FMUs checked when "
              "interrupted" + (f"; --junit {args.junit!r} not written" if args.junit else ""),
              file=sys.stderr)
        raise KeyboardInterrupt from None
    if args.junit:
        write_text_atomic(args.junit, reports_junit(reports))
    if args.json:
        print(json.dumps(reports_json(reports), indent=2))
    else:
        print(format_reports(reports, verbose=args.verbose))
    return EXIT_OK if all(r.passed for r in reports) else EXIT_FAILED
