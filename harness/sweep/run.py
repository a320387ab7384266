"""``dronefly sweep``: where do closed-loop trajectories stay inside the Sect. 3.6 bounds?

Each case (see :mod:`harness.sweep.cases`) is one co-simulation of the real plant
and controller FMUs through :class:`harness.cosim.master.Loop`, or of a whole system of
FMUs (``system=FILE.ssp``, :mod:`harness.sweep.system_cases`) on the system master. Bounds are checked at
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
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

from fmpy import read_model_description

from ..builder.build import BuildError, project_fmus
from ...core.errors import DroneflyError
from ...core.extras import missing
from ...core.files import check_output_dir, write_text_atomic
from ...core.interrupt import checkpoint
from ...models.lateral_interface import CONTROL_NAMES, STATE_NAMES
from ..cosim.fmu import FMU, FMUError, start_values
from ..cosim.master import CoSimError, Loop
from ..cosim.pair import pair_layout
from ..cosim.params import resolve_assignments, scale_ratios
from ..cosim.system import System
from .backends import (chunk_cases, connect_scheduler, make_progress_bar, run_dask, run_here,
                       run_pool, stderr_is_tty)
from .cases import Case, SweepInputError, SweepSpec
from .two_systems import compare_summary
from .comparemaps import write_compare_maps
from .delays import delay_results, delay_summary
from .results import (COLUMNS, column_units, csv_header, load_done, read_rows, result_row,
                      summarize, write_maps,
                      write_results)
from .system_cases import SystemRef, check_system
from .worker import FmuRef

__all__ = ["COLUMNS", "FmuRef", "SweepInputError", "SweepResult", "SweepSettings", "read_rows",
           "run_sweep"]


@dataclass
class SweepResult:
    """What :func:`run_sweep` wrote: rows (strings, sorted by case), summary, file paths."""

    rows: list[dict[str, str]]
    summary: dict[str, Any]
    csv: Path
    json: Path
    maps: list[Path]


def _check_pair(refs: tuple[FmuRef, FmuRef]) -> None:
    """Open both FMUs, connect them by name and identify their states here, before any file
    is written: the sweep's box (Sect. 3.6), disturbances and gain sets are the lateral
    plant's, so a pair with other states is refused with the reason."""

    try:
        with FMU(refs[0].path) as p, FMU(refs[1].path) as c:
            Loop(p, c)
            layout = pair_layout(p, c)
    except (FMUError, CoSimError) as e:
        raise SweepInputError(str(e)) from e
    if layout.states != tuple(STATE_NAMES) or layout.controls != tuple(CONTROL_NAMES):
        raise SweepInputError(
            f"--plant {str(refs[0].path)!r} has the states {', '.join(layout.states)} and the "
            f"controls {', '.join(layout.controls)}; the sweep's box (the Sect. 3.6 bounds), "
            f"disturbances and gain sets are on the lateral states {', '.join(STATE_NAMES)} "
            f"and controls {', '.join(CONTROL_NAMES)} only: run this pair with dronefly cosim")


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
        master = (spec or SweepSpec()).master
        loop, values = check_system(ref, _values_for(ref, set_values), master)
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


@dataclass(frozen=True)
class SweepSettings:
    """How :func:`run_sweep` runs a sweep: every option but the spec and the output folder.

    Parameters
    ----------
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
        Discard the results in the output folder instead of resuming.
    plot : bool
        Write the PNG maps.
    progress_bar : bool, optional
        tqdm bar on stderr (default: when stderr is a terminal and tqdm is installed).
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
        :mod:`dronefly.harness.sweep.system_cases`); not with ``plant``/``controller``.
    compare : path, optional
        A second SSP: every case also runs on it, and the rows get the comparison
        columns of :mod:`dronefly.harness.sweep.two_systems` (needs ``system``).

    Notes
    -----
    Nothing is checked on construction; :func:`run_sweep` checks the values (raising
    :class:`SweepInputError`) before it writes anything.
    """

    plant: str | Path | None = None
    controller: str | Path | None = None
    workers: int | None = None
    scheduler: str | None = None
    connect_timeout_s: float = 10.0
    cases: Sequence[Case] | None = None
    fresh: bool = False
    plot: bool = True
    progress_bar: bool | None = None
    on_chunk: Callable[[int, int], None] | None = None
    chunk_steps: int | None = None
    flush_s: float = 5.0
    set_values: Mapping[str, float | bool] | None = None
    system: str | Path | None = None
    compare: str | Path | None = None


def _inputs(spec: SweepSpec | None, s: SweepSettings) -> tuple[tuple, list[Case], Any]:
    """(FMU or system references, cases, the system's LateralLoop or None), all checked."""
    if s.compare is not None and s.system is None:
        raise SweepInputError("--compare needs --system (the reference system)")
    if s.system is not None:
        refs, values, lateral = _system_refs(s.system, s.plant, s.controller, s.set_values,
                                             spec, s.compare)
    else:
        refs = _fmu_paths(s.plant, s.controller)
        _check_pair(refs)
        values, lateral = _resolve_values(refs, s.set_values), None
    cases = list(s.cases) if s.cases is not None else (spec or SweepSpec()).cases(values)
    if not cases:
        raise SweepInputError("the sweep has no cases")
    if lateral is not None:
        _check_gains_reach(cases, lateral)
    return refs, cases, lateral


def _local_workers(s: SweepSettings) -> int:
    """The local worker count (``workers`` or all cores), after checking the backend options."""
    workers = s.workers if s.workers is not None else os.cpu_count() or 1
    if not isinstance(workers, int) or isinstance(workers, bool) or workers < 1:
        raise SweepInputError(f"workers = {workers!r} must be an integer >= 1")
    timeout = s.connect_timeout_s
    if not (math.isfinite(timeout) and timeout > 0):
        raise SweepInputError(f"connect timeout = {timeout!r} s must be finite and > 0")
    if s.scheduler is not None and not s.scheduler.strip():
        raise SweepInputError("scheduler address is empty")
    return workers


class _Results:
    """The results of a sweep's cases, kept and written to ``sweep.csv`` as chunks finish.

    Parameters
    ----------
    cases : list of Case
        All cases of the sweep, in order (duplicates share a key and a result).
    refs : tuple
        The FMU or system references (for the loop's verdicts per delay).
    csv : Path
        The results file; its finished cases are kept unless ``s.fresh``.
    s : SweepSettings
        The options (``fresh``, ``compare``, ``flush_s``, ``on_chunk``).

    Attributes
    ----------
    done : dict
        Result per case key: loaded from ``csv`` and then computed.
    todo : list of Case
        The cases to compute, one per key, in order.
    resumed : int
        How many keys were done before this run.
    computed, loop_s, wall_s : int, float, float
        Cases computed in this run, and their loop and worker times summed [s].
    """

    def __init__(self, cases: list[Case], refs: tuple, csv: Path, s: SweepSettings) -> None:
        self.cases, self.csv, self.settings = cases, csv, s
        self.compare = s.compare is not None
        self.timed = delay_results(cases, refs)  # the loop's verdict per delay, sample period
        keys = {c.key for c in cases}
        self.done = {} if s.fresh else load_done(csv, keys, self.compare)
        self.resumed = len(keys & self.done.keys())
        self.todo = list({c.key: c for c in reversed(cases) if c.key not in self.done}
                         .values())[::-1]
        self.computed, self.loop_s, self.wall_s = 0, 0.0, 0.0
        self.bar: Any = None
        self.last_flush = time.perf_counter()

    def row(self, case: Case) -> dict[str, str]:
        """The CSV row of a done case."""
        return result_row(case, {**self.done[case.key], **self.timed.get(case.key, {})},
                          self.compare)

    def flush(self) -> None:
        """Rewrite ``sweep.csv`` with the rows of the cases done so far."""
        write_results(self.csv, [self.row(c) for c in self.cases if c.key in self.done])
        self.last_flush = time.perf_counter()

    def collect(self, res: tuple[list, float, float]) -> None:
        """Take one finished chunk's (results, loop time, worker time) from a backend."""
        results, loop_s, wall_s = res
        self.done.update(results)
        self.loop_s += loop_s
        self.wall_s += wall_s
        self.computed += len(results)
        self.bar.update(len(results))
        if self.settings.on_chunk is not None:
            self.settings.on_chunk(self.computed, len(self.todo))
        if time.perf_counter() - self.last_flush >= self.settings.flush_s:
            self.flush()

    def run(self, refs: tuple, client: Any, n_workers: int) -> None:
        """Compute the cases to do on the backend, writing ``sweep.csv`` also on an error.

        Parameters
        ----------
        refs : tuple
            The FMU or system references.
        client : distributed.Client or None
            The Dask client (closed here), or None for local workers.
        n_workers : int
            Workers: 1 runs in this process.
        """
        s = self.settings
        chunks = chunk_cases(self.todo, n_workers, s.chunk_steps)
        self.csv.parent.mkdir(parents=True, exist_ok=True)
        if self.todo:  # the summary of an earlier run no longer describes the folder
            self.csv.with_name("sweep.json").unlink(missing_ok=True)
        disable = ((not stderr_is_tty() or missing("tqdm") is not None)  # auto: if it can
                   if s.progress_bar is None else not s.progress_bar)
        self.bar = make_progress_bar(total=len(self.todo), unit="case", desc="sweep",
                                     dynamic_ncols=True, disable=disable)
        self.last_flush = time.perf_counter()
        try:
            if client is not None:
                run_dask(client, refs, chunks, self.collect)
            elif n_workers == 1:
                run_here(refs, chunks, self.collect)
            else:
                run_pool(refs, chunks, n_workers, self.collect)
        finally:
            self.bar.close()
            if client is not None:
                client.close()
            if self.computed or s.fresh or not self.csv.exists():
                self.flush()


def run_sweep(spec: SweepSpec | None = None, out_dir: str | Path = "build/sweep",
              settings: SweepSettings | None = None, **options: Any) -> SweepResult:
    """Run (or resume) a sweep and write ``sweep.csv``, ``sweep.json`` and ``map_*.png``.

    Parameters
    ----------
    spec : SweepSpec, optional
        What to sweep (default: ``SweepSpec()``); ignored if ``cases`` is given.
    out_dir : path
        Output folder; results already there (same cases, matched by key) are kept.
    settings : SweepSettings, optional
        How to run it (default: ``SweepSettings()``).
    **options
        Fields of :class:`SweepSettings` (``workers=1``, ``plot=False``, ...), replacing
        those of ``settings``.

    Returns
    -------
    SweepResult
        The rows of all cases, the summary (also in ``sweep.json``) and the files written.

    Raises
    ------
    SweepInputError
        Empty or bad input, missing FMU, unreachable scheduler, or an output folder
        holding another sweep; nothing is written then.
    TypeError
        An option that is not a field of :class:`SweepSettings`.
    KeyboardInterrupt
        After the finished cases have been written (rerun to resume).
    """
    t_start = time.perf_counter()
    s = replace(settings, **options) if settings is not None else SweepSettings(**options)
    try:  # before anything is built or run
        out = check_output_dir(out_dir)
    except DroneflyError as e:
        raise SweepInputError(str(e)) from e
    refs, cases, lateral = _inputs(spec, s)
    workers = _local_workers(s)
    results = _Results(cases, refs, out / "sweep.csv", s)
    client = (connect_scheduler(s.scheduler, s.connect_timeout_s) if s.scheduler is not None
              else None)
    n_workers = (len(client.scheduler_info()["workers"]) if client
                 else min(workers, max(1, len(results.todo))))
    results.run(refs, client, n_workers)
    checkpoint()  # a Ctrl-C after the last chunk: no maps, no summary that says complete
    rows = [results.row(c) for c in cases]
    maps = write_maps(rows, out) if s.plot else []
    summary = summarize(rows, cases) | (delay_summary(rows) if results.timed else {})
    if results.compare:

        summary["comparison"] = compare_summary(rows)
        summary["compare"] = refs[1].path
        maps += write_compare_maps(rows, out) if s.plot else []
    summary.update(elapsed_s=time.perf_counter() - t_start, workers=n_workers,
                   backend="dask" if client else ("in-process" if n_workers == 1 else "processes"),
                   scheduler=s.scheduler, computed_cases=results.computed,
                   resumed_cases=results.resumed,
                   # cases identical to an earlier one (same initial state, gains, step, stop,
                   # bounds, master: e.g. a direction case that is also a grid point) run once
                   duplicate_cases=len(cases) - len({c.key for c in cases}),
                   loop_run_s=results.loop_s, worker_case_s=results.wall_s,
                   per_case_overhead=(results.wall_s / results.loop_s - 1.0
                                      if results.loop_s > 0 else None),
                   **({"system": refs[0].path, "plant": lateral.plant,
                       "controller": lateral.controller} if lateral is not None else
                      {"plant": refs[0].path, "controller": refs[1].path}),
                   csv=str(results.csv), units=column_units(csv_header(rows)),
                   maps=[str(m) for m in maps])

    json_path = out / "sweep.json"
    write_text_atomic(json_path, json.dumps(summary, indent=2, allow_nan=False) + "\n")
    return SweepResult(rows, summary, results.csv, json_path, maps)
