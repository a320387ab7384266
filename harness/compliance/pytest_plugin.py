"""pytest plugin of ``dronefly check`` (entry point ``dronefly_check`` in the ``pytest11`` group).

``pytest --fmu build/*.fmu`` makes one pytest test per FMU and check (``A.fmu::reset``); a
check that does not apply is a skipped test with its reason, a failed one fails with its detail
and rule. Each FMU is checked once, in a child process (as ``dronefly check`` does), when its
first test runs. ``--fmu-profile`` and ``--fmu-no-fuzz`` are ``--profile`` and ``--no-fuzz``.
Without ``--fmu`` the plugin adds nothing.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import fmpy
import pytest

from .checker import CHECKS, listed
from .driver import profile_for
from .rules import CheckOptions, FMUReport
from .suite import check_fmu, interfaces_of, not_checked

__all__ = ["FMUCheckItem", "pytest_addoption", "pytest_collection_modifyitems"]


def pytest_addoption(parser: Any) -> None:
    group = parser.getgroup("dronefly-check", "FMI compliance of FMUs (dronefly check)")
    group.addoption("--fmu", action="extend", nargs="+", default=[], metavar="FMU",
                    help="check these FMUs: a test per FMU and check")
    group.addoption("--fmu-profile", choices=("auto", "standard", "dronefly"), default="auto",
                    help="the profile of the checks (default auto, as dronefly check)")
    group.addoption("--fmu-no-fuzz", action="store_true", help="without the fuzz")


class _Profile:
    """Stands for an FMU before it is loaded: what :func:`profile_for` reads."""

    def __init__(self, md: Any) -> None:
        self.model_description = md


def _planned(path: Path, options: CheckOptions, fuzz: bool) -> list[str]:
    """The checks ``dronefly check`` runs on the FMU (read from its modelDescription.xml)."""
    if not_checked(path) is not None:
        return ["fmu"]
    try:
        md = fmpy.read_model_description(str(path), validate=False)
    except Exception:
        return ["load"]
    version = 3 if str(md.fmiVersion).startswith("3") else 2
    profile = options.profile or profile_for(_Profile(md))
    names = [c.name for c in CHECKS if listed(c, version, profile, interfaces_of(path))
             and options.wants(c.name)]
    if fuzz and profile == "dronefly" and options.wants("fuzz"):
        names.append("fuzz")
    return names


class FMUCheckItem(pytest.Item):
    """One check of one FMU."""

    def __init__(self, *, fmu: Path, check: str, reports: dict, options: CheckOptions,
                 fuzz: bool, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.fmu, self.check, self._reports = fmu, check, reports
        self._options, self._fuzz = options, fuzz

    def _report(self) -> FMUReport:
        if self.fmu not in self._reports:
            self._reports[self.fmu] = check_fmu(self.fmu, fuzz=self._fuzz, options=self._options)
        return self._reports[self.fmu]

    def runtest(self) -> None:
        report = self._report()
        if report.skipped:
            raise pytest.skip.Exception(report.skipped, _use_item_location=True)
        by_name = {c.name: c for c in report.checks}
        c = by_name.get(self.check)
        if c is None:  # the FMU could not be loaded, or its checking process died before
            reasons = [r for r in report.checks if not r.passed]
            raise FMUCheckFailed(f"{self.check} was not run: " + ("; ".join(
                f"{r.name}: {r.detail}" for r in reasons) if reasons else "no result"))
        if c.skipped:
            raise pytest.skip.Exception(c.detail, _use_item_location=True)
        if not c.passed:
            raise FMUCheckFailed(f"{c.detail}\nrule: {c.rule}")

    def repr_failure(self, excinfo: Any, style: Any = None) -> str:
        if isinstance(excinfo.value, FMUCheckFailed):
            return str(excinfo.value)
        return super().repr_failure(excinfo)

    def reportinfo(self) -> tuple[Path, int, str]:
        return self.fmu, 0, f"{self.fmu.name}::{self.check}"


class FMUCheckFailed(AssertionError):
    """A check of an FMU failed (its detail and rule)."""


def pytest_collection_modifyitems(session: Any, config: Any, items: list) -> None:
    paths = [Path(p) for p in config.getoption("fmu") or []]
    if not paths:
        return
    profile = config.getoption("fmu_profile")
    options = CheckOptions(profile=None if profile == "auto" else profile)
    fuzz = not config.getoption("fmu_no_fuzz")
    reports: dict = {}
    for path in paths:
        if not path.is_file():
            raise pytest.UsageError(f"--fmu {str(path)!r}: no such FMU file")
        for check in _planned(path, options, fuzz):
            items.append(FMUCheckItem.from_parent(
                session, name=f"{path.name}::{check}", fmu=path, check=check, reports=reports,
                options=options, fuzz=fuzz))
