"""A checking process of its own: crash, hang and Ctrl-C proof, and no temporary file left.

``dronefly check`` runs the checks of an FMU (and the fuzz) in child processes. :func:`run_child`
runs one with its own temporary folder as ``TMPDIR`` (where the FMU is extracted), removed
whatever the end: success, failure, a crash of the FMU, the timeout, Ctrl-C. The child is in
a session of its own (a Ctrl-C typed in the terminal reaches only ``dronefly check``); the
parent asks :func:`dronefly.core.interrupt.pending` while it waits and, on Ctrl-C, kills the
child and raises :class:`KeyboardInterrupt` within one poll. On Linux the child also dies with
the parent (SIGKILL when the parent ends), whatever ends it.
"""

from __future__ import annotations

import ctypes
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from typing import Sequence

from ...core.interrupt import pending

__all__ = ["ChildRun", "POLL_S", "die_with_parent", "run_child"]

#: how often the parent asks whether Ctrl-C came while a child works [s]
POLL_S = 0.05
_PR_SET_PDEATHSIG = 1  # linux/prctl.h


@dataclass(frozen=True)
class ChildRun:
    """How a child process ended: ``returncode`` (None: killed at the timeout), its output."""

    returncode: int | None
    stdout: str
    stderr: str


def _text(b: bytes | str | None) -> str:
    if isinstance(b, bytes):
        return b.decode("utf-8", "replace")
    return b or ""


def die_with_parent() -> None:
    """Called first in a checking process (Linux): it gets SIGKILL when the thread of
    ``dronefly check`` that started it ends, whatever ends it (a signal it cannot handle): no
    checking process outlives ``dronefly check``."""
    if not sys.platform.startswith("linux"):
        return
    parent = os.getppid()
    try:
        ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL))
    except (OSError, AttributeError):
        return
    if os.getppid() != parent:  # the parent ended before the request was made
        os._exit(1)


def run_child(cmd: Sequence[str], timeout_s: float, tmp: str | None = None) -> ChildRun:
    """Run ``cmd`` with a private ``TMPDIR`` (``tmp`` if given, kept; else made and removed).

    Raises
    ------
    KeyboardInterrupt
        Ctrl-C came while it ran (the child is killed first, its temporary files removed).
    """
    own = tmp is None
    folder = tempfile.mkdtemp(prefix="dronefly_check_") if own else tmp
    try:
        env = {**os.environ, "TMPDIR": folder, "TEMP": folder, "TMP": folder}
        proc = subprocess.Popen(list(cmd), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                env=env, start_new_session=True)
        deadline = time.monotonic() + timeout_s
        try:
            while True:
                if pending():
                    raise KeyboardInterrupt
                left = deadline - time.monotonic()
                if left <= 0:
                    proc.kill()
                    o, e = proc.communicate()
                    return ChildRun(None, _text(o), _text(e))
                try:
                    o, e = proc.communicate(timeout=min(POLL_S, left))
                    return ChildRun(proc.returncode, _text(o), _text(e))
                except subprocess.TimeoutExpired:
                    continue  # communicate again: no output is lost
        finally:
            if proc.poll() is None:  # interrupted, or an error of the parent's
                proc.kill()
                proc.communicate()
    finally:
        if own:
            shutil.rmtree(folder, ignore_errors=True)
