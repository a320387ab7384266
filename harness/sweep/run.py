"""``dronefly sweep``: where do closed-loop trajectories stay inside the Sect. 3.6 bounds?

Each case (see :mod:`harness.sweep.cases`) is one co-simulation of the real plant
and controller FMUs through :class:`harness.cosim.master.Loop`, or of a whole system of
FMUs (``system=FILE.ssp``, :mod:`harness.sweep.system`) on the system master. Bounds are checked at
every communication point on the non-dimensional state (|x_i| / (scale bound_i))
and on the controls (|u| / (scale 0.4 rad)).

Execution: each worker process extracts each FMU once and instantiates plant and
controller once (module-level cache keyed by the FMUs' digests, one pair of
instances per thread); every case reuses them through fmi2Reset. Cases run in
chunks, in-process (``workers=1``), on a local process pool, or on an existing
Dask cluster (``scheduler=ADDRESS``; see :mod:`harness.sweep.backends`); the rows are the
same whichever backend.
Results go to ``sweep.csv`` (one row per case, sorted by case number), rewritten atomically
after chunks complete; a rerun with the same ``out_dir`` resumes: finished cases are not rerun.
"""

from __future__ import annotations

import json
import math
import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

from fmpy import read_model_description

from ...builder.build import BuildError, project_fmus
from ...core.files import write_text_atomic
from ..cosim.fmu import FMU, FMUError, start_values
from ..cosim.master import CoSimError, Loop
from ..cosim.params import resolve_assignments, scale_ratios
from ..cosim.system import System
from .backends import (chunk_cases, connect_scheduler, make_progress_bar, run_dask, run_here,
                       run_pool, stderr_is_tty)
from .cases import Case, SweepInputError, SweepSpec
from .compare import compare_summary
from .comparemaps import write_compare_maps
from .delays import delay_results, delay_summary
from .results import (COLUMNS, load_done, read_rows, result_row, summarize, write_maps,
                      write_results)
from .system import SystemRef, check_system
from .worker import FmuRef

__all__ = ["COLUMNS", "FmuRef", "SweepInputError", "SweepResult", "read_rows", "run_sweep"]


@dataclass
class SweepResult:
    """What :func:`run_sweep` wrote: rows (strings, sorted by case), summary, file paths."""

    rows: list[dict[str, str]]
    summary: dict[str, Any]
    csv: Path
    json: Path
    maps: list[Path]


def _check_pair(refs: tuple[FmuRef, FmuRef]) -> None:
    """Open both FMUs and connect them by name here, before any file is written."""

    try:
        with FMU(refs[0].path) as p, FMU(refs[1].path) as c:
            Loop(p, c)
    except (FMUError, CoSimError) as e:
        raise SweepInputError(str(e)) from e


def _resolve_values(refs: tuple[FmuRef, FmuRef],
                    set_values: Mapping[str, Any] | None) -> dict[str, dict[str, Any]]:
    mds = {k: read_model_description(str(r.path)) for k, r in zip(("plant", "controller"), refs)}
    try:
        values = resolve_assignments(dict(set_values), mds) if set_values else {}
        starts = sorted(k for k in values.get("plant", {}) if k.endswith("_start"))
        if starts:
            raise SweepInputError(f"--set plant.{starts[0]}: the sweep sets every case's "
                                  "initial state from its disturbances (--disturbances)")
        # the cases' x0 and the verdicts read the plant's scales; the controller its own
        scale_ratios({**start_values(mds["plant"]), **values.get("plant", {})},
                     {**start_values(mds["controller"]), **values.get("controller", {})},
                     override=None)
    except ValueError as e:
        raise SweepInputError(str(e)) from e
    return values


def _system_refs(system: str | Path, plant: Any, controller: Any,
                 set_values: Mapping[str, Any] | None, spec: SweepSpec | None,
                 compare: str | Path | None = None) -> tuple:
    """((SystemRef,) or (SystemRef, SystemRef), case values, LateralLoop) of ``--system``
    (and ``--compare``), checked here; ``--set`` values go to the systems that have the
    instance (the same typed value in both)."""

    if plant is not None or controller is not None:
        raise SweepInputError("--plant/--controller cannot be combined with --system (set "
                              "values of the system's instances with --set instance.NAME=VALUE)")
    refs, lateral, typed = [], None, {}
    for option, given in (("--system", system), ("--compare", compare)):
        if given is None:
            continue
        if not (path := Path(given)).is_file():
            raise SweepInputError(f"{option} {str(given)!r} " + (
                "is a folder, not an SSP file" if path.is_dir() else "does not exist"))
        ref = SystemRef(**vars(FmuRef.of(path)))
        loop, values = check_system(ref, _values_for(ref, set_values), (spec or SweepSpec()).master)
        for key, value in values.items():  # a case's --set value serves both systems
            if (type(typed.setdefault(key, value)), typed[key]) != (type(value), value):
                raise SweepInputError(f"--set {key}={set_values[key]!r} is {typed[key]!r} in "
                                      f"{refs[0].path} but {value!r} in {ref.path}")
        lateral = lateral or loop
        refs.append(ref)
    unused = sorted(set(set_values or {}) - set(typed))
    if unused:
        raise SweepInputError(f"--set {unused[0]}: no system has that instance")
    return tuple(refs), {"plant": typed}, lateral


def _values_for(ref: Any, set_values: Mapping[str, Any] | None) -> dict[str, Any]:
    """The ``instance.NAME`` values whose instance the system has."""

    instances = set(System.from_ssp(ref.path).fmus)
    return {k: v for k, v in (set_values or {}).items() if k.partition(".")[0] in instances}


def _check_gains_reach(cases: Sequence[Case], lateral: Any) -> None:
    """A non-zero gain that no connection of the system carries is an error, not ignored."""
    reach = {(a, b) for a, b, _ in lateral.gains}
    for c in cases:
        for a, row in enumerate(c.K):
            for b, k in enumerate(row):
                if k != 0.0 and (a, b) not in reach:
                    raise SweepInputError(
                        f"gains {c.gains!r}: K[{a + 1},{b + 1}] = {k:g} acts through a "
                        f"connection the system does not have (controls driven: "
                        f"{', '.join(lateral.controls) or 'none'})")


def _fmu_paths(plant: str | Path | None, controller: str | Path | None) -> tuple[FmuRef, FmuRef]:
    try:
        plant, controller = project_fmus(plant, controller)
    except BuildError as e:
        raise SweepInputError(str(e)) from e
    return FmuRef.of(plant), FmuRef.of(controller)


def run_sweep(spec: SweepSpec | None = None, out_dir: str | Path = "build/sweep", *,
              plant: str | Path | None = None, controller: str | Path | None = None,
              workers: int | None = None, scheduler: str | None = None,
              connect_timeout_s: float = 10.0, cases: Sequence[Case] | None = None,
              fresh: bool = False, plot: bool = True, progress_bar: bool | None = None,
              on_chunk: Callable[[int, int], None] | None = None, chunk_steps: int | None = None,
              flush_s: float = 5.0,
              set_values: Mapping[str, float | bool] | None = None,
              system: str | Path | None = None,
              compare: str | Path | None = None) -> SweepResult:
    """Run (or resume) a sweep and write ``sweep.csv``, ``sweep.json`` and ``map_*.png``.

    Parameters
    ----------
    spec : SweepSpec, optional
        What to sweep (default: ``SweepSpec()``); ignored if ``cases`` is given.
    out_dir : path
        Output folder; results already there (same cases, matched by key) are kept.
    plant, controller : path, optional
        FMUs (default: the project's, built into ``build/``).
    workers : int, optional
        Local worker processes (default: all cores; 1 runs in this process).
    scheduler : str, optional
        Address of an existing Dask scheduler; the cases then run on its workers.
    connect_timeout_s : float
        How long to try reaching the scheduler, s.
    cases : sequence of Case, optional
        Explicit cases instead of ``spec.cases()``.
    fresh : bool
        Discard the results in ``out_dir`` instead of resuming.
    plot : bool
        Write the PNG maps.
    progress_bar : bool, optional
        tqdm bar on stderr (default: when stderr is a terminal).
    on_chunk : callable(done, total), optional
        Called after each chunk (cases done so far, cases to do); may raise to stop.
    chunk_steps : int, optional
        Communication steps per chunk (default: about total / (16 workers)).
    flush_s : float
        Rewrite ``sweep.csv`` at most this often while running, s.
    set_values : mapping, optional
        ``{"plant.Lv_plus": 0.2, ...}``: parameter values in each FMU's unit for every case
        (as ``dronefly sweep --set``); checked against the model descriptions first.
        With ``system``: ``{"instance.NAME": value}`` for any instance of the system.
    system : path, optional
        An SSP file: every case runs the whole system on the system master, the lateral
        plant's initial state and its controller's gains set per case (see
        :mod:`dronefly.harness.sweep.system`); not with ``plant``/``controller``.
    compare : path, optional
        A second SSP: every case also runs on it, and the rows get the comparison
        columns of :mod:`dronefly.harness.sweep.compare` (needs ``system``).

    Raises
    ------
    SweepInputError
        Empty or bad input, missing FMU, unreachable scheduler, or an output folder
        holding another sweep; nothing is written then.
    KeyboardInterrupt
        After the finished cases have been written (rerun to resume).
    """
    t_start = time.perf_counter()
    if compare is not None and system is None:
        raise SweepInputError("--compare needs --system (the reference system)")
    if system is not None:
        refs, values, lateral = _system_refs(system, plant, controller, set_values, spec,
                                             compare)
    else:
        refs = _fmu_paths(plant, controller)
        _check_pair(refs)
        values, lateral = _resolve_values(refs, set_values), None
    all_cases = list(cases) if cases is not None else (spec or SweepSpec()).cases(values)
    if not all_cases:
        raise SweepInputError("the sweep has no cases")
    if lateral is not None:
        _check_gains_reach(all_cases, lateral)
    if workers is None:
        workers = os.cpu_count() or 1
    if not isinstance(workers, int) or isinstance(workers, bool) or workers < 1:
        raise SweepInputError(f"workers = {workers!r} must be an integer >= 1")
    if not (math.isfinite(connect_timeout_s) and connect_timeout_s > 0):
        raise SweepInputError(f"connect timeout = {connect_timeout_s!r} s must be finite and > 0")
    if scheduler is not None and not scheduler.strip():
        raise SweepInputError("scheduler address is empty")
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise SweepInputError(f"output folder {str(out)!r} is a file")
    timed = delay_results(all_cases, refs)  # the loop's verdict per delay and sample period
    csv_path, json_path = out / "sweep.csv", out / "sweep.json"
    keys = {c.key for c in all_cases}
    cmp = compare is not None
    done = {} if fresh else load_done(csv_path, keys, cmp)
    resumed = len(keys & done.keys())
    client = connect_scheduler(scheduler, connect_timeout_s) if scheduler is not None else None
    todo = list({c.key: c for c in reversed(all_cases) if c.key not in done}.values())[::-1]
    n_workers = len(client.scheduler_info()["workers"]) if client else min(workers, max(1, len(todo)))
    chunks = chunk_cases(todo, n_workers, chunk_steps)
    stats = {"loop_s": 0.0, "wall_s": 0.0, "computed": 0}
    out.mkdir(parents=True, exist_ok=True)
    bar = make_progress_bar(total=len(todo), unit="case", desc="sweep", dynamic_ncols=True,
                            disable=(not stderr_is_tty()) if progress_bar is None else not progress_bar)
    last_flush = [time.perf_counter()]

    def flush() -> None:
        write_results(csv_path, [result_row(c, {**done[c.key], **timed.get(c.key, {})}, cmp)
                                 for c in all_cases if c.key in done])
        last_flush[0] = time.perf_counter()

    def collect(res: tuple[list, float, float]) -> None:
        results, loop_s, wall_s = res
        done.update(results)
        stats["loop_s"] += loop_s
        stats["wall_s"] += wall_s
        stats["computed"] += len(results)
        bar.update(len(results))
        if on_chunk is not None:
            on_chunk(stats["computed"], len(todo))
        if time.perf_counter() - last_flush[0] >= flush_s:
            flush()

    try:
        if client is not None:
            run_dask(client, refs, chunks, collect)
        elif n_workers == 1:
            run_here(refs, chunks, collect)
        else:
            run_pool(refs, chunks, n_workers, collect)
    finally:
        bar.close()
        if client is not None:
            client.close()
        if stats["computed"] or fresh or not csv_path.exists():
            flush()
    rows = [result_row(c, {**done[c.key], **timed.get(c.key, {})}, cmp) for c in all_cases]
    maps = write_maps(rows, out) if plot else []
    summary = summarize(rows, all_cases) | (delay_summary(rows) if timed else {})
    if cmp:
        summary["comparison"] = compare_summary(rows)
        summary["compare"] = refs[1].path
        maps += write_compare_maps(rows, out) if plot else []
    summary.update(elapsed_s=time.perf_counter() - t_start, workers=n_workers,
                   backend="dask" if client else ("in-process" if n_workers == 1 else "processes"),
                   scheduler=scheduler, computed_cases=stats["computed"], resumed_cases=resumed,
                   # cases identical to an earlier one (same initial state, gains, step, stop,
                   # bounds, master: e.g. a direction case that is also a grid point) run once
                   duplicate_cases=len(all_cases) - len(keys),
                   loop_run_s=stats["loop_s"], worker_case_s=stats["wall_s"],
                   per_case_overhead=(stats["wall_s"] / stats["loop_s"] - 1.0
                                      if stats["loop_s"] > 0 else None),
                   **({"system": refs[0].path, "plant": lateral.plant,
                       "controller": lateral.controller} if lateral is not None else
                      {"plant": refs[0].path, "controller": refs[1].path}),
                   csv=str(csv_path),
                   maps=[str(m) for m in maps])

    write_text_atomic(json_path, json.dumps(summary, indent=2, allow_nan=False) + "\n")
    return SweepResult(rows, summary, csv_path, json_path, maps)
