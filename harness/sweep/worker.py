"""Worker side of ``dronefly sweep``: FMUs opened once per process, one case per Loop.run.

Each worker process extracts each FMU once and instantiates plant and controller once
(module-level cache keyed by the FMUs' digests, one pair of instances per thread); every
case reuses them through fmi2Reset. :func:`run_chunk` is what the local pool and the Dask
workers execute.
"""

from __future__ import annotations

import atexit
import hashlib
import math
import os
import shutil
import signal
import tempfile
import threading
import time
from dataclasses import dataclass
from multiprocessing import util
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from ...core.extras import MissingExtra, optional
from ...core.interrupt import pending as interrupt_pending
from ...models.feedback import gain_name
from ...models.lateral_interface import STATE_NAMES, plant_scales
from ..cosim.fmu import FMU
from ..cosim.master import Loop
from ..latency.grid import timing_params
from .cases import AXES, CONTROL_BOUND, STATE_BOUNDS_SECT36, Case, one_line
from .two_systems import compare_runs
from .results import RESULT_COLUMNS
from .system_cases import SystemRef, close_systems, open_system, run_system_case

__all__ = ["ChunkInterrupted", "FmuRef", "blas_single_thread", "close_all", "init_worker", "loop_for", "run_chunk",
           "warm"]

_TOL = 1e-9  # a ratio up to 1 + _TOL counts as on the bound (a = 1 starts on the face)
_CONTROL_SHORT = {"delta_Phi_a": "dPhi_a", "delta_alpha_1a": "dalpha_1a",
                  "delta_alpha_2a": "dalpha_2a"}


@dataclass(frozen=True)
class FmuRef:
    """An FMU file and the SHA-1 of its bytes (the worker cache key)."""

    path: str
    digest: str

    @classmethod
    def of(cls, path: str | Path) -> "FmuRef":
        return cls(str(Path(path).resolve()), hashlib.sha1(Path(path).read_bytes()).hexdigest())


# ----------------------------------------------------------------------------- worker side
_LOCK = threading.Lock()
_FMUS: dict[str, Any] = {}  # digest -> harness.cosim.fmu.FMU (extracted once per process)
_LOOPS: dict[tuple[int, str, str], tuple[Any, Any, Any, np.ndarray]] = {}
_TMP: list[str] = []
#: set by the parent of a process pool on Ctrl-C (:func:`init_worker`): a chunk stops before its
#: next case and hands back the cases it finished
_STOP: Any = None


def _open_fmu(ref: FmuRef, data: bytes | None) -> Any:
    with _LOCK:
        if ref.digest not in _FMUS:
            path = ref.path
            if data is not None and not (os.path.isfile(path) and FmuRef.of(path) == ref):
                d = tempfile.mkdtemp(prefix="dronefly_sweep_")
                _TMP.append(d)
                path = os.path.join(d, os.path.basename(ref.path))
                Path(path).write_bytes(data)
            _FMUS[ref.digest] = FMU(path)
        return _FMUS[ref.digest]


def loop_for(refs: tuple[FmuRef, FmuRef], data: tuple[bytes | None, bytes | None]) -> tuple:
    """(Loop, plant instance, controller instance, x+ scale) of this thread, made once."""

    key = (threading.get_ident(), refs[0].digest, refs[1].digest)
    if key not in _LOOPS:
        pf, cf = _open_fmu(refs[0], data[0]), _open_fmu(refs[1], data[1])
        loop = Loop(pf, cf)
        scale = np.array(plant_scales(pf.start_values()))  # x = x+ * scale
        _LOOPS[key] = (loop, pf.instantiate(logging=False), cf.instantiate(logging=False), scale)
    return _LOOPS[key]


def warm(refs: tuple) -> None:
    """Open the FMUs (or the system: ``refs = (SystemRef,)``) before any case is timed."""
    if isinstance(refs[0], SystemRef):
        for ref in refs:
            open_system(ref)
    else:
        loop_for(refs, (None, None))


def close_all() -> None:
    """Free every cached instance and delete every extraction (worker exit)."""

    close_systems()

    for loop, p, c, _ in list(_LOOPS.values()):
        for inst in (p, c):
            try:
                inst.free()
            except Exception:  # pragma: no cover - best effort at exit
                pass
    _LOOPS.clear()
    for f in list(_FMUS.values()):
        f.close()
    _FMUS.clear()
    for d in _TMP:
        shutil.rmtree(d, ignore_errors=True)
    _TMP.clear()


def blas_single_thread(required: bool = False) -> Any:
    """Limit BLAS to one thread (threadpoolctl); returns the limiter (``.restore_original_limits()``).

    The plant steps call BLAS on 4x4 matrices; an idle OpenBLAS thread spins on the other
    core after each call, so two worker processes would fight over 2 cores. Without
    threadpoolctl (the ``sweep`` extra) and not ``required`` (one process: nothing to fight
    over), a limiter that does nothing; the results do not depend on it (4x4 products).

    Raises
    ------
    MissingExtra
        threadpoolctl is not installed and ``required``.
    """
    try:
        threadpool_limits = optional("threadpoolctl", "threadpool_limits",
                                     alternative="pass --workers 1")
    except MissingExtra:
        if required:
            raise
        return _NoLimit()
    return threadpool_limits(limits=1, user_api="blas")


class _NoLimit:
    """What :func:`blas_single_thread` returns without threadpoolctl."""

    def restore_original_limits(self) -> None:
        """Nothing to restore."""


def init_worker(refs: tuple[FmuRef, FmuRef], stop: Any = None) -> None:
    """Process-pool initializer: ignore Ctrl-C (the parent handles it and sets ``stop``, a
    ``multiprocessing.Event``: then each chunk ends before its next case), open the FMUs once."""

    global _STOP
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _STOP = stop
    _LOOPS.clear()  # forked: these belong to the parent (which also deletes its extractions)
    _FMUS.clear()
    _TMP.clear()
    close_systems(forget=True)
    atexit.register(close_all)
    util.Finalize(None, close_all, exitpriority=10)
    blas_single_thread()
    warm(refs)


def _measure(run: Any, loop: Any, scale: np.ndarray, case: Case) -> dict[str, Any]:
    """Peaks, first exit and final state of a run (ratios to the scaled bounds)."""
    S = run.signals
    idx = [loop.names.index(n) for n in ("delta_v", "delta_p", "delta_r", "delta_gamma")]
    nu = len(loop.controls)
    x = S[:, idx] / scale
    ns = len(loop.states)
    r = np.abs(np.hstack([x / np.array(STATE_BOUNDS_SECT36),
                          S[:, ns:ns + nu] / CONTROL_BOUND])) / case.scale
    out: dict[str, Any] = {"error": "", "t_exit_wb": math.nan}
    peaks = r.max(axis=0) if len(r) else np.full(4 + nu, math.nan)
    out.update({f"peak_{a}": float(v) for a, v in zip(AXES, peaks[:4])})
    out["peak_u"] = float(peaks[4:].max())
    out["peak"] = float(peaks.max())
    out.update({f"final_{a}": float(v) for a, v in zip(AXES, x[-1] if len(x) else [math.nan] * 4)})
    over = r > 1.0 + _TOL
    hit = over.any(axis=1)
    names = [*AXES, *(_CONTROL_SHORT.get(c, c) for c in loop.controls)]
    if hit.any():
        k = int(np.argmax(hit))
        out["t_exit_wb"] = round(k * case.step_wb, 12)
        out["verdict"] = "left " + names[int(np.argmax(np.where(over[k], r[k], -1.0)))]
    else:
        out["verdict"] = "within"
    if not run.complete:
        out["verdict"], out["error"] = "error", one_line(str(run.failure))
    return out


def _failed(case: Case, e: BaseException) -> dict[str, Any]:
    out: dict[str, Any] = {c: math.nan for c in RESULT_COLUMNS}
    out.update(verdict="error", error=one_line(f"{type(e).__name__}: {e}"))
    return out


def run_chunk(refs: tuple[FmuRef, FmuRef], cases: Sequence[Case],
              data: tuple[bytes | None, bytes | None] = (None, None)) -> tuple[list, float, float]:
    """Run cases on this worker's cached instances.

    Returns
    -------
    results : list of (key, result dict)
    loop_s : float
        Time inside ``Loop.run``, s.
    wall_s : float
        Wall time of the whole chunk in the worker, s.
    """

    t_chunk = time.perf_counter()
    loop_s, out = 0.0, []
    for case in cases:
        if _STOP is not None and _STOP.is_set():  # a pool worker: the parent saw Ctrl-C
            break  # the cases finished so far are the chunk's result
        try:
            if interrupt_pending():  # the command line's deferred Ctrl-C
                raise KeyboardInterrupt
            t0 = time.perf_counter()
            extra: dict[str, Any] = {}
            if isinstance(refs[0], SystemRef):
                run, loop, scale = run_system_case(refs[0], case, data[0])
                if len(refs) == 2:  # --compare: the same case through the second system
                    run2, loop2, _ = run_system_case(refs[1], case, data[1])
                    extra = compare_runs(run, loop, run2, loop2, scale,
                                         _measure(run2, loop2, scale, case))
            else:
                loop, p, c, scale = loop_for(refs, data)
                if case.plant_values:  # n or U may be among them
                    scale = np.array(plant_scales({**loop.plant.start_values(),
                                                   **dict(case.plant_values)}))
                start = {**dict(case.plant_values), **{f"{s}_start": float(v)
                         for s, v in zip(STATE_NAMES, np.asarray(case.x0) * scale)}}
                t0 = time.perf_counter()
                run = loop.run(case.step_wb / scale[2], case.n_steps, master=case.master,
                               plant_start=start,
                               controller_params={**dict(case.controller_values),
                                                  **{gain_name(i, j): v
                                                     for i, row in enumerate(case.K)
                                                     for j, v in enumerate(row)},
                                                  **timing_params(case, scale[2])},
                               instances=(p, c))
            loop_s += time.perf_counter() - t0
            out.append((case.key, {**_measure(run, loop, scale, case), **extra}))
        except KeyboardInterrupt:  # Ctrl-C between steps: hand back what is finished
            raise ChunkInterrupted((out, loop_s, time.perf_counter() - t_chunk)) from None
        except Exception as e:  # recorded; the sweep goes on with fresh instances
            out.append((case.key, _failed(case, e)))
            _drop_thread_loop(refs)
    return out, loop_s, time.perf_counter() - t_chunk


class ChunkInterrupted(KeyboardInterrupt):
    """SIGINT during a chunk run in this process; ``partial`` is what finished before it."""

    def __init__(self, partial: tuple[list, float, float]) -> None:
        super().__init__("interrupted")
        self.partial = partial


def _drop_thread_loop(refs: tuple[FmuRef, FmuRef]) -> None:
    """After an exception: free this thread's instances; the next case makes new ones."""
    if isinstance(refs[0], SystemRef):
        return  # the system master frees its instances after every run
    entry = _LOOPS.pop((threading.get_ident(), refs[0].digest, refs[1].digest), None)
    for inst in (entry[1:3] if entry else ()):
        try:
            inst.free()
        except Exception:  # pragma: no cover - already broken
            pass
