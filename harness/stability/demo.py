"""The main job: open loop and the paper's gains, co-simulated, in one verdict table."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping

from .run import CosimResult, cosimulate

__all__ = ["demo_runs", "format_table", "verdict_table"]


def demo_runs(out_dir: str | Path = "build/cosim", *, plot: bool = True,
              set_values: Mapping[str, Any] | None = None,
              build_dir: str | Path = "build", plant: str | Path | None = None,
              controller: str | Path | None = None) -> list[CosimResult]:
    """Co-simulate open loop and Eq. (27) (Gauss-Seidel, 0.1 wing beat, 300 wing beats).

    Parameters
    ----------
    out_dir : path
        Folder of the CSVs (and PNGs).
    plot : bool
        Write the PNGs (needs matplotlib).
    set_values : mapping, optional
        Parameter values of either FMU for both runs, as
        :func:`~dronefly.harness.stability.run.cosimulate` takes them.
    build_dir : path
        Where the project's FMUs are built if missing or out of date.
    plant, controller : path, optional
        The FMUs to run (default: the project's pythonfmu FMUs, as ``cosimulate``).

    Returns
    -------
    list of CosimResult
        The open loop, then Eq. (27); each with its ``check_failures``.
    """
    return [cosimulate(plant, controller, gains=gains, out_dir=out_dir, plot=plot,
                       set_values=set_values, build_dir=build_dir) for gains in ("open", "paper")]


def format_table(results: list[CosimResult]) -> str:
    """The verdict table of :func:`demo_runs` (a failed cross-check is marked in it)."""
    rows = []
    for gains, r in zip(("open", "paper"), results):
        ev = ", ".join(f"{e.real:+.4f}" + (f"{e.imag:+.4f}i" if abs(e.imag) > 5e-5 else "")
                       for e in r.identification.eigenvalues)
        verdict = r.verdict + (" (cross-check failed)" if r.check_failures else "")
        rows.append((gains, ev, verdict, str(r.csv), str(r.plot) if r.plot else "-"))
    head = ("gains", "identified eigenvalues per wing beat", "verdict", "csv", "plot")
    widths = [max(len(x[i]) for x in [head, *rows]) for i in range(len(head))]
    line = lambda cells: "  ".join(c.ljust(w) for c, w in zip(cells, widths))  # noqa: E731
    return "\n".join([line(head), line(["-" * w for w in widths]), *(line(r) for r in rows)])


def verdict_table(out_dir: str | Path = "build/cosim", **options: Any) -> str:
    """:func:`format_table` of :func:`demo_runs` (``options`` as it takes them)."""
    return format_table(demo_runs(out_dir, **options))
