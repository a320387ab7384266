"""The ``dronefly`` subcommands: one module per subcommand, each with ``run(args) -> int``.

:mod:`dronefly.cli.app` parses the command line and imports only the chosen subcommand's
module (:data:`COMMANDS`), so that ``dronefly --help`` does not load the analyses.
"""

__all__ = ["COMMANDS", "EXIT_FAILED", "EXIT_OK", "EXIT_USAGE"]

EXIT_OK, EXIT_FAILED, EXIT_USAGE = 0, 1, 2
#: the subcommands, each the name of its module in this package
COMMANDS = ("build", "simulate", "cosim", "check", "demo", "analyze", "sweep", "aero",
            "floquet")
