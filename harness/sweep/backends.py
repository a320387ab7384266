"""Where the chunks of a sweep run: in this process, a process pool or a Dask cluster.

Each backend calls ``collect((results, loop_s, wall_s))`` once per finished chunk; every
worker limits BLAS to one thread and frees its FMU instances at the end.

Ctrl-C (the command line's deferred SIGINT, :mod:`dronefly.core.interrupt`) is seen while the
backend waits for chunks: the chunks not started are cancelled; in a pool the chunks already
handed to a worker end before their next case and hand back the cases they finished (on Dask the
running chunks are cancelled); then ``KeyboardInterrupt`` is raised. So a sweep stops within one
chunk and keeps every finished case for the rerun that resumes it.
"""

from __future__ import annotations

import multiprocessing
import sys
import time
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from pathlib import Path
from typing import Any, Callable

from ...core.extras import optional
from ...core.interrupt import pending as interrupt_pending
from .cases import Case, SweepInputError, one_line
from .worker import (ChunkInterrupted, FmuRef, blas_single_thread, close_all, init_worker,
                     run_chunk, warm)

__all__ = ["POLL_S", "chunk_cases", "connect_scheduler", "make_progress_bar", "run_dask", "run_here", "run_pool",
           "stderr_is_tty"]


#: how often a backend waiting for chunks looks for a Ctrl-C, s
POLL_S = 0.1


def chunk_cases(cases: list[Case], workers: int, chunk_steps: int | None) -> list[list[Case]]:
    total = sum(c.n_steps for c in cases)
    target = chunk_steps or min(max(total / (workers * 16), 4000), 60000)
    chunks: list[list[Case]] = [[]]
    cost = 0
    for c in cases:
        if cost >= target:
            chunks.append([])
            cost = 0
        chunks[-1].append(c)
        cost += c.n_steps
    return [ch for ch in chunks if ch]


def connect_scheduler(address: str, timeout_s: float) -> Any:
    parse_address, parse_host_port = optional("distributed.comm", "parse_address",
                                              "parse_host_port")

    try:  # a malformed address fails here, before a Client exists to be torn down
        scheme, location = parse_address(address)
        if scheme in ("tcp", "tls"):
            parse_host_port(location)
    except Exception as e:
        raise SweepInputError(f"scheduler address {address!r} is malformed: "
                              f"{one_line(str(e))}") from None
    try:
        Client = optional("distributed", "Client")
        return Client(address, timeout=timeout_s, set_as_default=False)
    except Exception as e:
        raise SweepInputError(f"scheduler {address!r} unreachable: {one_line(str(e))}") from None


class _NoBar:
    """The progress bar when it is disabled: no tqdm needed (the ``sweep`` extra)."""

    def update(self, n: int = 1) -> None:
        """Nothing to show."""

    def close(self) -> None:
        """Nothing to close."""


def make_progress_bar(**kw: Any) -> Any:
    """A tqdm bar without tqdm's monitor thread (the pool forks after it exists); with
    ``disable=True`` a bar that shows nothing and needs no tqdm."""
    if kw.get("disable"):
        return _NoBar()
    tqdm = optional("tqdm", "tqdm")

    class Bar(tqdm):
        monitor_interval = 0

    return Bar(**kw)


def stderr_is_tty() -> bool:
    return bool(getattr(sys.stderr, "isatty", lambda: False)())


def run_here(refs: tuple[FmuRef, FmuRef], chunks: list[list[Case]], collect: Callable) -> None:
    limiter = blas_single_thread()
    try:
        warm(refs)  # instantiate once, before any case is timed
        for ch in chunks:
            try:
                collect(run_chunk(refs, ch))
            except ChunkInterrupted as e:  # keep the finished cases of this chunk
                collect(e.partial)
                raise KeyboardInterrupt from None
    finally:
        close_all()
        limiter.restore_original_limits()


def run_pool(refs: tuple[FmuRef, FmuRef], chunks: list[list[Case]], n: int,
              collect: Callable) -> None:
    # fork: no re-import of __main__ (``python -m dronefly`` has no main guard); the
    # workers drop the inherited caches and open their own FMUs in the initializer
    method = "fork" if "fork" in multiprocessing.get_all_start_methods() else "spawn"
    ctx = multiprocessing.get_context(method)
    stop = ctx.Event()  # set on Ctrl-C: the workers' chunks end before their next case

    def cancel(left: list) -> list:
        stop.set()
        return [f for f in left if not f.cancel()]  # queued or running: they end at once

    with ProcessPoolExecutor(n, mp_context=ctx, initializer=init_worker,
                             initargs=(refs, stop)) as ex:
        futs = [ex.submit(run_chunk, refs, ch) for ch in chunks]
        try:
            _gather(futs, collect, cancel, lambda left: wait(left, POLL_S, FIRST_COMPLETED))
        except BaseException:
            for f in futs:
                f.cancel()
            raise


def _gather(futs: list, collect: Callable, cancel: Callable[[list], list],
            wait_some: Callable[[list], Any]) -> None:
    """Collect each future's chunk as it finishes, in the order they finish; on a deferred
    Ctrl-C, ``cancel(left)`` (returning the futures that still finish), collect those, then
    raise ``KeyboardInterrupt``.

    ``wait_some(left)`` returns after one of ``left`` finished or :data:`POLL_S` seconds.
    """
    left, stopping = list(futs), False
    while left:
        wait_some(left)
        for f in [f for f in left if f.done()]:
            left.remove(f)
            collect(f.result())
        if left and not stopping and interrupt_pending():
            left, stopping = cancel(left), True
    if stopping or interrupt_pending():
        raise KeyboardInterrupt


def run_dask(client: Any, refs: tuple[FmuRef, FmuRef], chunks: list[list[Case]],
              collect: Callable) -> None:
    WorkerPlugin = optional("distributed.diagnostics.plugin", "WorkerPlugin")

    class Cleanup(WorkerPlugin):
        """Deletes the worker's FMU extractions when the Dask worker closes."""

        name = "dronefly-sweep-cleanup"

        def setup(self, worker: Any) -> None:
            blas_single_thread()

        def teardown(self, worker: Any) -> None:
            close_all()

    client.register_plugin(Cleanup())
    data = client.scatter([Path(r.path).read_bytes() for r in refs], broadcast=True)
    futs = [client.submit(run_chunk, refs, ch, tuple(data), pure=False) for ch in chunks]

    def wait_some(left: list) -> None:  # (distributed.wait needs a default client)
        end = time.monotonic() + POLL_S
        while not any(f.done() for f in left) and time.monotonic() < end:
            time.sleep(POLL_S / 10)

    def cancel(left: list) -> list:  # running tasks are cancelled too: nothing more to wait for
        client.cancel(left)
        return []

    try:
        _gather(futs, collect, cancel, wait_some)
    except BaseException:
        client.cancel(futs)
        raise
