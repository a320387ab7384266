"""Optional packages, named by the extra of ``dronefly-fmu`` that installs them.

A missing optional package costs only its feature: a command asks :func:`missing` before any
work and, if the package is absent, goes on without the feature (a plot, the progress bar, one
BLAS thread per worker) and says so in one line naming the extra to install. A feature the user
asked for by an option that needs the package (``sweep --scheduler``: Dask) is refused instead,
with the same line (:func:`require`, exit code 2).
"""

from __future__ import annotations

import importlib
import importlib.util
import sys
from types import ModuleType
from typing import Any

from .errors import DroneflyError

__all__ = ["EXTRAS", "MissingExtra", "missing", "optional", "pyplot", "require"]

#: module -> (extra, what needs it)
EXTRAS: dict[str, tuple[str, str]] = {
    "matplotlib": ("plot", "plots"),
    "tqdm": ("sweep", "the sweep's progress bar"),
    "threadpoolctl": ("sweep", "BLAS thread limits"),
    "distributed": ("sweep", "a Dask cluster"),
    "libcosimpy": ("interop", "the libcosim importer"),
}


class MissingExtra(DroneflyError):
    """An optional package is not installed."""


def missing(module: str) -> str | None:
    """None if ``module`` can be imported, else the line that says what is missing and the extra
    that installs it (as :class:`MissingExtra` would)."""
    try:
        require(module)
    except MissingExtra as e:
        return str(e)
    return None


def require(module: str, alternative: str = "") -> None:
    """Raise :class:`MissingExtra` naming the extra if ``module`` cannot be imported."""
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


def optional(module: str, *names: str, alternative: str = "") -> Any:
    """A module of an optional package, imported when first needed (the packages of
    :data:`EXTRAS` take a second or more to import, and most runs need none of them).

    ``optional("matplotlib.figure")`` is the module; with ``names``, the attribute of that name
    (one name) or a tuple of them: ``Figure = optional("matplotlib.figure", "Figure")``.

    Raises
    ------
    MissingExtra
        The package is not installed (names the extra, and ``alternative`` if given).
    """
    require(module.partition(".")[0], alternative)
    mod: ModuleType = importlib.import_module(module)
    if not names:
        return mod
    values = tuple(getattr(mod, n) for n in names)
    return values[0] if len(values) == 1 else values


def pyplot() -> ModuleType:
    """matplotlib's pyplot on the Agg backend (figures written to files, never shown).

    Raises
    ------
    MissingExtra
        matplotlib is not installed.
    """
    optional("matplotlib").use("Agg")
    return optional("matplotlib.pyplot")
