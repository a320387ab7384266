"""Optional packages, named by the extra of ``dronefly-fmu`` that installs them.

A command that needs one checks it before it writes anything and, if it is missing, stops
with one line naming the extra to install (exit code 2).
"""

from __future__ import annotations

import importlib.util

from .errors import DroneflyError

__all__ = ["EXTRAS", "MissingExtra", "require"]

#: module -> (extra, what needs it)
EXTRAS: dict[str, tuple[str, str]] = {
    "matplotlib": ("plot", "plots"),
    "tqdm": ("sweep", "the sweep's progress bar"),
    "threadpoolctl": ("sweep", "the sweep's worker threads"),
    "distributed": ("sweep", "a Dask cluster"),
    "libcosimpy": ("interop", "the libcosim importer"),
}


class MissingExtra(DroneflyError):
    """An optional package is not installed."""


def require(module: str, alternative: str = "") -> None:
    """Raise :class:`MissingExtra` naming the extra if ``module`` cannot be imported."""
    import sys

    if module in sys.modules:  # imported already, or blocked (None: as if not installed)
        found = sys.modules[module] is not None
    else:
        try:
            found = importlib.util.find_spec(module) is not None
        except (ImportError, ValueError):
            found = False
    if not found:
        extra, what = EXTRAS[module]
        raise MissingExtra(f"{module} is not installed ({what}): pip install 'dronefly-fmu[{extra}]'"
                           + (f", or {alternative}" if alternative else ""))
