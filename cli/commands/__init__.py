"""The ``dronefly`` subcommands: one module per subcommand, each with ``run(args) -> int``.

:mod:`dronefly.cli.app` parses the command line and imports only the chosen subcommand's
module (:data:`COMMANDS`), so that ``dronefly --help`` does not load the analyses.
"""

import sys

from ...core.extras import missing

__all__ = ["COMMANDS", "EXIT_FAILED", "EXIT_OK", "EXIT_USAGE", "feature"]

EXIT_OK, EXIT_FAILED, EXIT_USAGE = 0, 1, 2
#: the subcommands, each the name of its module in this package
COMMANDS = ("build", "simulate", "cosim", "check", "demo", "analyze", "sweep", "aero",
            "floquet")


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
