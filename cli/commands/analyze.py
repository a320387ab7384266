"""``dronefly analyze``: the reproduction table of the paper's printed numbers."""

from __future__ import annotations

import argparse

from ...core.errors import DroneflyError
from ...core.files import write_text_atomic
from ...harness.paper.report import render
from ...harness.paper.reproduction import analyze
from .args import out_file
from . import EXIT_OK

__all__ = ["EPILOG", "RUNS_FMUS", "add_arguments", "run"]

#: no FMU runs here: Ctrl-C stops the command at once (:func:`dronefly.core.interrupt.sigint_at_once`)
RUNS_FMUS = False

#: the examples of ``dronefly analyze --help`` (after its options)
EPILOG = ("examples:\n  dronefly analyze\n  dronefly analyze --json\n"
          "  dronefly analyze --markdown --out docs/reproduction.md\n"
          "  dronefly analyze --targets=-0.2,-0.089+0.057j,-0.089-0.057j,-0.51 "
          "--input delta_Phi_a")


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Add the options of ``dronefly analyze`` to its subparser ``p``."""
    form = p.add_mutually_exclusive_group()  # one report: both are refused (exit 2)
    form.add_argument("--json", action="store_true",
                      help="print JSON (table, matrices, eigenvalues, gains); not with --markdown")
    form.add_argument("--markdown", action="store_true",
                      help="print the Markdown report (docs/reproduction.md); not with --json")
    p.add_argument("--targets", default=None, metavar="LIST",
                   help="comma-separated closed-loop eigenvalues per wing beat for an extra "
                        "gain design; write --targets=... when the first one is negative")
    p.add_argument("--input", default=None, metavar="NAME",
                   help="with --targets: the control input of that design: delta_Phi_a "
                        "(default), delta_alpha_1a, delta_alpha_2a")
    p.add_argument("--out", type=out_file, default=None, metavar="FILE", help="write to FILE instead of stdout")


def run(args: argparse.Namespace) -> int:
    """Run ``dronefly analyze`` with the parsed arguments; returns the exit code."""
    if args.input is not None and args.targets is None:
        raise DroneflyError(f"--input {args.input!r} needs --targets (it is the control input "
                            "of the extra design for those eigenvalues)")
    result = analyze(targets=args.targets,
                     design_input="delta_Phi_a" if args.input is None else args.input)
    text = render(result, "json" if args.json else "markdown" if args.markdown else "text")
    if args.out:
        print(write_text_atomic(args.out, text))
    else:
        print(text, end="" if text.endswith("\n") else "\n")
    return EXIT_OK
