"""The ``dronefly`` command line: the top-level parser, the dispatch and the exit codes.

Each subcommand is one module of :mod:`dronefly.cli.commands` (its options, its examples and
its ``run``, which calls one Python function), listed in
:data:`~dronefly.cli.commands.COMMANDS`; only the chosen one is imported. Exit codes: 0 success; 1 a check failed or a run stopped early (its partial result
is kept); 2 bad input (a :class:`~dronefly.core.errors.DroneflyError` or an ``OSError`` on a file:
one line naming the value, nothing written); 130 interrupted (Ctrl-C). Any other exception is
a bug: one line saying so and exit 1 (``--debug`` shows the traceback).

Units: options that are times of the co-simulation are in wing beats (t_w = 1/n); initial
states given with ``--x0`` are non-dimensional (x+ of Sect. 2.1); ``--gamma0`` and ``--set``
values are SI (the FMU's own unit: rad, m/s, rad/s, Hz).
"""

from __future__ import annotations

import argparse
import sys
import traceback
from pathlib import Path
from types import ModuleType
from typing import Callable, Iterable, Sequence

from .. import __version__
from ..harness.builder.build import reporting
from .commands import COMMANDS, EXIT_FAILED, EXIT_USAGE, load
from ..core.errors import CrossCheckError, DroneflyError
from ..core.interrupt import EXIT_INTERRUPTED, deferred_sigint, sigint_at_once

__all__ = ["main"]


class _Parser(argparse.ArgumentParser):
    """argparse with a one-line error (the usage is one ``--help`` away)."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message} ('{self.prog} --help' shows "
                              "the usage)\n")


def _parser(commands: Iterable[str] = tuple(COMMANDS)) -> argparse.ArgumentParser:
    """The parser of the command line: every subcommand of :data:`COMMANDS`, with its line of
    help; the options and the epilog of those in ``commands`` (from their modules, which this
    imports; :func:`main` asks for the chosen one alone)."""
    p = _Parser(
        prog="dronefly",
        description="FMUs and analysis of the lateral stabilization control of a hovering "
                    "model drone fly (Zhang & Sun).",
        epilog="examples:\n  dronefly build\n  dronefly simulate --stop 100\n  dronefly cosim --json\n"
               "exit codes: 0 ok, 1 a check failed or a run stopped early, 2 bad input, "
               "130 interrupted; an internal error (a bug) exits 1",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--version", action="version", version=f"dronefly {__version__}")
    p.add_argument("--debug", action="store_true",
                   help="show the traceback of an internal error (a bug) or of bad input")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")
    wanted = set(commands)
    for name, helptext in COMMANDS.items():
        module = load(name) if name in wanted else None
        sp = sub.add_parser(name, help=helptext, description=helptext,
                            epilog=module.EPILOG if module else None,
                            formatter_class=argparse.RawDescriptionHelpFormatter)
        # also after the subcommand; SUPPRESS keeps a --debug given before it
        sp.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                        help="show the traceback of an internal error (a bug) or of bad input")
        if module:
            module.add_arguments(sp)
    return p


def _chosen(argv: Sequence[str]) -> tuple[str, ...]:
    """The subcommand that ``argv`` names (none, or one of :data:`COMMANDS`): its first word
    that is not an option, as the top-level options take no value."""
    name = next((a for a in argv if not a.startswith("-")), None)
    return (name,) if name in COMMANDS else ()


def _say_built(command: str, module: ModuleType) -> Callable[[Path], None]:
    """What a command that builds the project's FMUs says for each (one line on stderr), unless
    it says so itself (``SAYS_WHAT_IT_BUILT`` in its module: build, cosim, simulate)."""

    def say(path: Path) -> None:
        if not getattr(module, "SAYS_WHAT_IT_BUILT", False):
            print(f"dronefly {command}: built {path}", file=sys.stderr, flush=True)

    return say


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI; returns the exit code (also used by ``python -m dronefly``)."""
    argv = sys.argv[1:] if argv is None else list(argv)
    chosen = _chosen(argv)
    who = " ".join(("dronefly", *chosen))
    try:
        parser = _parser(chosen)  # imports the chosen subcommand's module
    except KeyboardInterrupt:
        print(f"{who}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except Exception as e:  # a module that does not import: a bug (or a broken install)
        return _bug(who, e, "--debug" in argv)
    try:
        args = parser.parse_args(argv)
    except SystemExit as e:  # argparse already printed its one-line error, the help or version
        return int(e.code or 0)
    try:
        module = load(args.command)
        # Ctrl-C lands between steps, never in an FMU; a command that runs none stops at once
        guard = deferred_sigint if getattr(module, "RUNS_FMUS", True) else sigint_at_once
        with guard() as interrupt, reporting(_say_built(args.command, module)):
            code = int(module.run(args))
        if interrupt.requested:
            raise KeyboardInterrupt
        return code
    except CrossCheckError as e:  # a result its own check contradicts: a failed check
        print(f"dronefly {args.command}: error: cross-check failed: {e}", file=sys.stderr)
        return EXIT_FAILED
    except (DroneflyError, OSError) as e:
        if args.debug:
            traceback.print_exc()
        text = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        print(f"dronefly {args.command}: error: {text}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print(f"dronefly {args.command}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except Exception as e:  # a bug, never reported as bad input
        return _bug(f"dronefly {args.command}", e, args.debug)


def _bug(who: str, e: Exception, debug: bool) -> int:
    """Report an internal error (a bug, never bad input) in one line, the traceback with
    ``--debug``; returns exit code 1."""
    if debug:
        traceback.print_exc()
    print(f"{who}: internal error (a bug, please report it): {type(e).__name__}: {e}"
          + ("" if debug else " (--debug shows the traceback)"), file=sys.stderr)
    return EXIT_FAILED


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
