"""``dronefly aero``: the quasi-steady wing model beside the paper's derivatives."""

from __future__ import annotations

import argparse
import json

from ...core.errors import DroneflyError
from ...harness.aero import QuasiSteadyModel, Terms, parity_report
from ...models.quasisteady import FORCES
from .args import parse_setting
from . import EXIT_OK

__all__ = ["EPILOG", "RUNS_FMUS", "add_arguments", "run"]

#: no FMU runs here: Ctrl-C stops the command at once (:func:`dronefly.core.interrupt.sigint_at_once`)
RUNS_FMUS = False

#: the examples of ``dronefly aero --help`` (after its options)
EPILOG = ("examples:\n  dronefly aero\n  dronefly aero --json --coefficients wang2004\n"
          "  dronefly aero forces --state delta_v=0.1 --control delta_Phi_a=0.2 --json\n"
          "  dronefly aero --no-rotational --added-mass-form sane2001\n"
          "units: states non-dimensional (x+: dv/U, dp t_w, ...), controls in rad; forces "
          "over 0.5 rho U^2 S_t, moments over 0.5 rho U^2 S_t c")


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Add the options of ``dronefly aero`` to its subparser ``p``."""
    p.add_argument("what", nargs="?", choices=("table", "forces"), default="table",
                   help="table (default): trim, derivatives, eigenvalues, Eq. (27); forces: the "
                        "cycle-averaged X, Y, Z, L, M, N at --state and --control")
    p.add_argument("--state", action="append", default=[], type=parse_setting,
                   metavar="NAME=VALUE", help="with forces: a state delta_u ... delta_r "
                   "(non-dimensional, repeatable)")
    p.add_argument("--control", action="append", default=[], type=parse_setting,
                   metavar="NAME=VALUE", help="with forces: a control delta_Phi_a ... "
                   "delta_alpha_2 in rad (repeatable)")
    p.add_argument("--coefficients", default="dickinson1999", metavar="NAME",
                   help="translational coefficients: dickinson1999 (default), wang2004")
    for term in ("translational", "rotational", "added-mass"):
        p.add_argument(f"--no-{term}", action="store_true", help=f"switch off the {term} term")
    p.add_argument("--added-mass-form", choices=("impulse", "sane2001"), default="impulse",
                   help="added mass as the rate of change of the fluid impulse (default; "
                        "averages to zero over a cycle) or Sane & Dickinson 2001's normal "
                        "acceleration alone")
    p.add_argument("--json", action="store_true", help="print JSON")


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
        loads = model.forces_vector({k: number(k, v) for k, v in args.state},
                                    {k: number(k, v) for k, v in args.control})
        forces = dict(zip(FORCES, (float(v) for v in loads)))
        print(json.dumps(forces, indent=2) if args.json
              else "  ".join(f"{k}+ = {v:+.6f}" for k, v in forces.items()))
        return EXIT_OK
    report = parity_report(model)
    print(json.dumps(report.to_json(), indent=2) if args.json else report.table())
    return EXIT_OK
