"""``dronefly check``: the compliance suite on FMUs (ours, built, or anyone's)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from ...builder.build import FMUS, build_all, build_fmu
from ...core.errors import DroneflyError
from ...core.files import write_text_atomic
from ...harness.compliance.checker import CHECK_NAMES, CheckOptions
from ...harness.compliance.fmi3checks import FMI3_CHECKS
from ...harness.compliance.suite import check_fmus, format_reports, reports_json, reports_junit
from . import EXIT_FAILED, EXIT_OK

__all__ = ["run"]


def _check_names(values: list[str], option: str) -> tuple[str, ...]:
    known = [*CHECK_NAMES, *(n for n, _ in FMI3_CHECKS), "fuzz"]
    names = tuple(n.strip() for v in values for n in v.split(",") if n.strip())
    for n in names:
        if n not in known:
            raise DroneflyError(f"{option} {n!r}: no such check; known: {', '.join(known)}")
    return names


def run(args: argparse.Namespace) -> int:
    """Run ``dronefly check`` with the parsed arguments; returns the exit code."""
    options = CheckOptions(profile=None if args.profile == "auto" else args.profile,
                           stop_time=args.stop_time, step=args.step,
                           only=_check_names(args.check, "--check"),
                           skip=_check_names(args.skip, "--skip"))
    if args.junit and Path(args.junit).is_dir():
        raise DroneflyError(f"--junit {args.junit!r} is a folder; give the file to write")
    paths = [Path(p) for p in args.fmus]
    if not paths:
        paths = [p for p in build_all(args.build) if p.suffix == ".fmu"]
        paths += [build_fmu(name, Path(args.build) / "fmi3", fmi=3) for name in FMUS]
    for p in paths:
        if not p.is_file():
            raise DroneflyError(f"FMU {str(p)!r} " + ("is a folder, not an FMU file" if p.is_dir()
                                                  else "does not exist"))
    reports = check_fmus(paths, jobs=args.jobs, fuzz=not args.no_fuzz, options=options,
                         timeout_s=args.timeout)
    if args.junit:
        write_text_atomic(args.junit, reports_junit(reports))
    if args.json:
        print(json.dumps(reports_json(reports), indent=2))
    else:
        print(format_reports(reports, verbose=args.verbose))
    return EXIT_OK if all(r.passed for r in reports) else EXIT_FAILED
