"""``dronefly aero``: the quasi-steady wing model beside the paper's derivatives."""

from __future__ import annotations

import argparse
import json

from ...core.errors import DroneflyError
from ...harness.aero import QuasiSteadyModel, Terms, parity_report
from . import EXIT_OK

__all__ = ["RUNS_FMUS", "run"]

#: no FMU runs here: Ctrl-C stops the command at once (:func:`dronefly.core.interrupt.sigint_at_once`)
RUNS_FMUS = False


def run(args: argparse.Namespace) -> int:
    """Run ``dronefly aero`` with the parsed arguments; returns the exit code."""
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
