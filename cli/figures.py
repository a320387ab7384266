"""Regenerate the figures of docs/ (``make figures``): each from the command that makes it.

``python -m dronefly.cli.figures [--small] [--only NAME,...] DIR`` writes each figure of
:data:`FIGURES` into DIR under the name docs/ gives it (``make figures``: DIR = docs). A figure
drawn by a ``dronefly`` command (a co-simulation, a sweep) runs that command in-process with
``--out`` a scratch folder and copies the PNG it writes; the quasi-steady model's figures are drawn
by :mod:`dronefly.harness.aero.plots`. FMUs are built into ``build/`` of the working directory
where missing or out of date, as the commands do. ``--small`` runs each on small inputs (a few
cases, a few wing beats: seconds), for the test that checks what the figures draw; the full run
takes minutes (the sweeps: see docs/benchmarks.md). Exit 0 when every figure was written, 1 when
a command failed (its own message on stderr), 2 on bad input, 130 on Ctrl-C (the figures
already written are kept).
"""

from __future__ import annotations

import argparse
import shlex
import shutil
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence

from ..harness.aero.plots import plot_fig2, plot_linearity_maps
from ..harness.sweep.delaytable import MAP_COMMAND
from ..core.interrupt import EXIT_INTERRUPTED
from ..models.quasisteady import QuasiSteadyModel
from . import app
from .commands import EXIT_FAILED, EXIT_OK, EXIT_USAGE

__all__ = ["FIGURES", "Figure", "main", "regenerate"]


@dataclass(frozen=True)
class Figure:
    """One figure of docs/: its file name, the document that shows it, and how it is made.

    Either ``command`` (the ``dronefly`` arguments, without ``--out``) and ``made`` (the glob
    of the PNG it writes under ``--out``), or ``draw`` (a function of the output path and
    ``small``). ``small`` arguments replace or extend the command's for the small run.
    """

    name: str
    doc: str
    command: tuple[str, ...] = ()
    made: str = ""
    small: tuple[str, ...] = ()
    draw: Callable[[Path, bool], Path] | None = None

    def argv(self, small: bool) -> list[str]:
        """The command's arguments, on small inputs if ``small`` (a later option wins)."""
        return [*self.command, *(self.small if small else ())]


def _aero_fig2(path: Path, small: bool) -> Path:
    return plot_fig2(QuasiSteadyModel(), path, points=5 if small else 33)


def _aero_linearity(path: Path, small: bool) -> Path:
    return plot_linearity_maps(QuasiSteadyModel(), path, points=3 if small else 17)


_QUIET = ("--no-progress", "--workers", "1")

#: every figure of docs/ (a test checks that docs/*.png is exactly this list)
FIGURES: tuple[Figure, ...] = (
    Figure("aero_fig2.png", "docs/aerodynamics.md", draw=_aero_fig2),
    Figure("aero_linearity.png", "docs/aerodynamics.md", draw=_aero_linearity),
    # the Eq. (27) loop of `dronefly demo` (Gauss-Seidel, 0.1 wing beat, 300 wing beats)
    Figure("cosim_paper.png", "README.md", ("cosim", "--gains", "paper"),
           "cosim_paper_gauss-seidel*.png", ("--stop", "20")),
    # slice dgamma x dp of the default sweep
    Figure("sweep_map.png", "docs/sweep.md", ("sweep", "--no-progress"), "map_dgamma_dp.png",
           ("--slices", "dgamma:dp", "--disturbances", "grid", "--grid", "3", "--steps",
            "0.5,1", "--stop", "10", *_QUIET)),
    # slice dr x dp of the comparison sweep
    Figure("validity_map.png", "docs/validity.md",
           ("sweep", "--compare", "nonlinear", "--no-progress"), "compare_dr_dp.png",
           ("--slices", "dr:dp", "--disturbances", "grid", "--grid", "3", "--stop", "5",
            *_QUIET)),
    # the sensing delay x sample period map of docs/latency.md
    Figure("latency_map.png", "docs/latency.md",
           (*shlex.split(MAP_COMMAND)[1:], "--no-progress"), "map_delay_period.png",
           ("--amplitudes", "1", "--directions", "+dp,+dgamma", "--delays", "0,1",
            "--sample-periods", "0,1", "--stop", "10", *_QUIET)),
)


def regenerate(out_dir: str | Path, *, small: bool = False, only: Sequence[str] | None = None,
               work_dir: str | Path | None = None) -> list[Path]:
    """Write the figures of :data:`FIGURES` (those named in ``only``) into ``out_dir``.

    Parameters
    ----------
    out_dir : path
        Where the PNGs go, each under its docs/ name (created if missing).
    small : bool
        Small inputs (seconds; for the test), not the documents' runs (minutes).
    only : sequence of str, optional
        File names of :data:`FIGURES` to make (default all).
    work_dir : path, optional
        Keep each command's output folder (its CSV, JSON and PNGs) as ``work_dir/STEM``, STEM
        the figure's name without ``.png`` (default: a temporary folder, removed).

    Returns
    -------
    list of Path
        The figures written, in the order of :data:`FIGURES`.

    Raises
    ------
    RuntimeError
        A command exited with a code other than 0 (its message is on stderr).
    KeyboardInterrupt
        Ctrl-C (the figures already written are kept, no scratch folder is left).
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    for fig in FIGURES:
        if only is not None and fig.name not in only:
            continue
        target = out / fig.name
        if fig.draw is not None:
            written.append(fig.draw(target, small))
            continue
        with tempfile.TemporaryDirectory(prefix="figure-") as scratch:
            work = Path(scratch) if work_dir is None else Path(work_dir) / Path(fig.name).stem
            argv = [*fig.argv(small), "--out", str(work)]
            code = app.main(argv)
            if code == EXIT_INTERRUPTED:  # the command said so; the figures written are kept
                raise KeyboardInterrupt
            if code != EXIT_OK:
                raise RuntimeError(f"dronefly {shlex.join(argv)} exited {code}")
            made = sorted(work.glob(fig.made))
            if len(made) != 1:
                raise RuntimeError(f"dronefly {shlex.join(argv)} wrote {len(made)} files "
                                   f"{fig.made}, not one")
            shutil.copyfile(made[0], target)
        written.append(target)
    return written


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m dronefly.cli.figures``: see the module text."""
    parser = argparse.ArgumentParser(
        prog="python -m dronefly.cli.figures", description=__doc__.split("\n")[0],
        epilog="example: python -m dronefly.cli.figures docs   (make figures)\n"
               "         python -m dronefly.cli.figures --small --only aero_fig2.png /tmp/f",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("out", metavar="DIR", help="folder of the PNGs (docs for docs/)")
    parser.add_argument("--small", action="store_true", help="small inputs (seconds)")
    parser.add_argument("--only", metavar="NAME,...",
                        help="comma-separated file names of the figures to make")
    try:
        args = parser.parse_args(argv)
    except SystemExit as e:
        return int(e.code or 0)
    names = {f.name for f in FIGURES}
    only = None if args.only is None else args.only.split(",")
    unknown = sorted(set(only or ()) - names)
    if unknown:
        print(f"figures: error: --only {unknown[0]!r} is not a figure of docs/ "
              f"({', '.join(sorted(names))})", file=sys.stderr)
        return EXIT_USAGE
    try:
        for path in regenerate(args.out, small=args.small, only=only):
            print(path)
    except RuntimeError as e:
        print(f"figures: error: {e}", file=sys.stderr)
        return EXIT_FAILED
    except KeyboardInterrupt:
        print("figures: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    return EXIT_OK


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
