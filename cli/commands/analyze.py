"""``dronefly analyze``: the reproduction table of the paper's printed numbers."""

from __future__ import annotations

import argparse

from ...core.errors import DroneflyError
from ...core.files import write_text_atomic
from ...harness.paper.report import render
from ...harness.paper.reproduction import analyze
from . import EXIT_OK

__all__ = ["RUNS_FMUS", "run"]

#: no FMU runs here: Ctrl-C stops the command at once (:func:`dronefly.core.interrupt.sigint_at_once`)
RUNS_FMUS = False


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
