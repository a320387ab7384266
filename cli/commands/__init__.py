"""The ``dronefly`` subcommands: one module per subcommand, and their registry.

Each module of this package owns one subcommand: ``add_arguments(p)`` adds its options to its
subparser, ``EPILOG`` is the end of its ``--help`` (examples, exit codes, units), and
``run(args) -> int`` runs it. :data:`COMMANDS` names each, in the order of ``dronefly --help``,
with the line that ``dronefly --help`` shows for it (also the first line of its own ``--help``).
A new subcommand is a new module here and one entry in :data:`COMMANDS`; :mod:`.args` holds
the argument converters that the modules share.

:mod:`dronefly.cli.app` imports only the chosen subcommand's module (:func:`load`), so that
``dronefly --help`` does not load the analyses.
"""

import importlib
import sys
from types import ModuleType

from ...core.extras import missing

__all__ = ["COMMANDS", "EXIT_FAILED", "EXIT_OK", "EXIT_USAGE", "feature", "load"]

EXIT_OK, EXIT_FAILED, EXIT_USAGE = 0, 1, 2
#: the subcommands: the name of each one's module in this package -> its line of help
COMMANDS = {
    "build": "build every FMU of the project: FMI 2.0 in DIR, FMI 3.0 in DIR/fmi3",
    "simulate": "simulate the open-loop plant FMU with fmpy from a roll disturbance",
    "cosim": ("co-simulate plant and controller FMUs, or any system of FMUs from an SSP "
              "file, with fmpy and check the stability of each loop"),
    "check": ("FMI 2.0 and 3.0 co-simulation compliance checks, each naming its rule of "
              "the standard (validate, archive, binary, call sequence, start values, "
              "dependencies, reset, state, Model Exchange, bad input, reference results, "
              "logger; for the project's FMUs also the dronefly profile and the fuzz)"),
    "demo": "open loop and closed loop with the paper's gains: the verdict table",
    "analyze": ("reproduce every number of the paper (Tables 2-3, Eqs. 12-32) from the "
                "model"),
    "sweep": ("co-simulate many disturbed closed loops: where do they stay within the "
              "Sect. 3.6 bounds?"),
    "aero": ("quasi-steady blade-element model of the wings: its derivatives beside the "
             "paper's CFD values, or its cycle-averaged forces"),
    "floquet": ("periodic orbit and Floquet exponents of a plant FMU through FMI (get/set "
                "FMU state), beside the averaged model's eigenvalues for the flapping plant"),
}


def load(name: str) -> ModuleType:
    """The module of subcommand ``name`` (a key of :data:`COMMANDS`), imported on first use:
    each loads its own analyses, and ``dronefly --help`` none."""
    if name not in COMMANDS:
        raise KeyError(f"subcommand {name!r} has no module; known: {', '.join(COMMANDS)}")
    return importlib.import_module(f"{__name__}.{name}")


def feature(command: str, wanted: bool, module: str, what: str) -> bool:
    """Whether a command can have an optional feature (``wanted`` and ``module`` installed); if
    it is wanted but the package is missing, one line on stderr says that ``what`` is skipped
    and which extra installs the package (the command goes on without it)."""
    if not wanted:
        return False
    why = missing(module)
    if why is not None:
        print(f"dronefly {command}: {what} skipped: {why}", file=sys.stderr)
    return why is None
