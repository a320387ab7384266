"""A checking process of its own: crash, hang and Ctrl-C proof, and no temporary file left.

``dronefly check`` runs the checks of an FMU (and the fuzz) in child processes. :func:`run_child`
runs one with its own temporary folder as ``TMPDIR`` (where the FMU is extracted), removed
whatever the end: success, failure, a crash of the FMU, the timeout, Ctrl-C. The child is in
a session of its own (a Ctrl-C typed in the terminal reaches only ``dronefly check``); the
parent asks :func:`dronefly.core.interrupt.pending` while it waits and, on Ctrl-C, kills the
child and raises :class:`KeyboardInterrupt` within one poll. On Linux the child also dies with
the parent (SIGKILL when the parent ends), whatever ends it.

:func:`run_function` runs a function of a module the same way, in a child forked from the
fork server (:mod:`.forkserver`: the checker, FMPy, NumPy and SciPy imported once per parent
process) where the platform can fork, else in a fresh interpreter (``python -m module args``).
"""

from __future__ import annotations

import atexit
import ctypes
import itertools
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

from ...core.interrupt import pending

__all__ = ["ChildRun", "POLL_S", "PRELOAD", "PRELOAD_LATER", "die_with_parent", "run_child",
           "run_function"]

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


#: what the fork server imports before it forks: the checks
PRELOAD = ("dronefly.harness.compliance.suite",)
#: what it imports once a second child is asked for: what FMPy imports only on use (SciPy, in
#: the reference check's ``validate_result``), worth importing once for several FMUs, not for
#: one (a child that needs it imports it)
PRELOAD_LATER = ("scipy.interpolate", "scipy.ndimage")


#: the fresh interpreter's program: ``python -c _FRESH module function args...``
_FRESH = ("import importlib, sys\n"
          "from dronefly.harness.compliance.child import die_with_parent\n"
          "die_with_parent()\n"
          "getattr(importlib.import_module(sys.argv[1]), sys.argv[2])(*sys.argv[3:])\n")


class _ForkServer:
    """The parent's end of :mod:`.forkserver`: requests written under a lock, replies read by
    one thread and handed to the waiting callers."""

    def __init__(self) -> None:
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "dronefly.harness.compliance.forkserver", *PRELOAD],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
        self.ids = itertools.count(1)
        self.lock = threading.Lock()
        self.replies = threading.Condition()
        self.code: dict[int, int] = {}
        self.alive = True
        threading.Thread(target=self._read, name="dronefly-forkserver", daemon=True).start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            msg = json.loads(line)
            with self.replies:
                self.code[msg["id"]] = msg["code"]
                self.replies.notify_all()
        with self.replies:
            self.alive = False
            self.replies.notify_all()

    def send(self, msg: dict[str, Any]) -> bool:
        """Write a request; False if the server is gone."""
        assert self.proc.stdin is not None
        try:
            with self.lock:
                self.proc.stdin.write((json.dumps(msg) + "\n").encode())
                self.proc.stdin.flush()
            return True
        except (BrokenPipeError, OSError, ValueError):
            return False

    def wait(self, rid: int, timeout_s: float) -> tuple[bool, int | None]:
        """(ended, code) of request ``rid``, waiting at most ``timeout_s``; ended with code
        None: the server is gone."""
        with self.replies:
            if rid not in self.code and self.alive:
                self.replies.wait(timeout_s)
            if rid in self.code:
                return True, self.code.pop(rid)
            return (not self.alive), None

    def close(self) -> None:
        """End the server (the end of its stdin) and reap it."""
        try:
            if self.proc.stdin is not None:
                self.proc.stdin.close()
            self.proc.wait(timeout=10)
        except (OSError, subprocess.TimeoutExpired):
            self.proc.kill()


_SERVER: _ForkServer | None = None
_SERVER_LOCK = threading.Lock()


def _server() -> _ForkServer | None:
    """The fork server of this process (started on first use), or None where there is none:
    a platform without ``fork``, or a server that failed."""
    global _SERVER
    if not hasattr(os, "fork") or os.environ.get("DRONEFLY_CHECK_FORK") == "0":
        return None
    with _SERVER_LOCK:
        if _SERVER is None or not _SERVER.alive:
            try:
                _SERVER = _ForkServer()
            except OSError:
                return None
            atexit.register(_SERVER.close)
        return _SERVER


def run_function(module: str, function: str, args: Sequence[str], timeout_s: float,
                 tmp: str | None = None) -> ChildRun:
    """``module.function(*args)`` in a child process with a private ``TMPDIR`` (``tmp`` if
    given, kept; else made and removed): forked from the fork server (:mod:`.forkserver`),
    or in a fresh interpreter (:func:`run_child`) where there is none or
    ``DRONEFLY_CHECK_FORK=0``.

    ``returncode``: 0, the function's exit code, 1 for an exception (its traceback in
    ``stderr``), minus the signal that ended the child, or None for the timeout.

    Raises
    ------
    KeyboardInterrupt
        Ctrl-C came while it ran (the child is killed first, its temporary files removed).
    """
    fresh = [sys.executable, "-c", _FRESH, module, function, *args]
    server = _server()
    if server is None:
        return run_child(fresh, timeout_s, tmp)
    own = tmp is None
    folder = tempfile.mkdtemp(prefix="dronefly_check_") if own else tmp
    try:
        out, err = Path(folder, ".stdout"), Path(folder, ".stderr")
        rid = next(server.ids)
        request = {"run": rid, "module": module, "function": function, "args": list(args),
                   "env": {**os.environ, "TMPDIR": folder, "TEMP": folder, "TMP": folder},
                   "cwd": os.getcwd(), "path": sys.path, "stdout": str(out), "stderr": str(err)}
        if rid == 2:  # (the ids count this server's children)
            server.send({"preload": list(PRELOAD_LATER)})
        if not server.send(request):
            return run_child(fresh, timeout_s, tmp)
        deadline = time.monotonic() + timeout_s
        code: int | None = None
        ended = False
        try:
            while not ended:
                if pending():
                    raise KeyboardInterrupt
                left = deadline - time.monotonic()
                if left <= 0:
                    break  # the timeout: killed below
                ended, code = server.wait(rid, min(POLL_S, left))
            if ended and code is None:  # the server died with the child: a fresh interpreter
                return run_child(fresh, timeout_s, tmp)
        finally:
            if not ended:  # the timeout, Ctrl-C or an error of the parent's: kill, then wait
                server.send({"kill": rid})
                while not server.wait(rid, POLL_S)[0]:
                    pass
        read = (lambda f: f.read_text(encoding="utf-8", errors="replace") if f.exists() else "")
        return ChildRun(code if ended else None, read(out), read(err))
    finally:
        if own:
            shutil.rmtree(folder, ignore_errors=True)
