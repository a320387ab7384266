"""The fork server of ``dronefly check``: checking processes that start in milliseconds.

A fresh interpreter spends half a second or more importing the checker, FMPy, NumPy and SciPy
before it checks anything. The fork server imports them once (the modules named on its
command line), then forks one child per request; the child is as isolated as a fresh process
(its own session, environment, working folder, temporary folder and output files; the FMU's
binaries are loaded in the child only) and ends as a process ends: the ``atexit`` functions,
then the C library's ``exit`` (the loaded libraries' exit-time code runs and what they
printed is flushed), so a crash at exit is seen. What a forked child skips is the
interpreter's final teardown; the fuzz, which looks for crashes there, runs fresh
interpreters (:mod:`.fuzz`).

Protocol, one JSON object per line. On stdin: ``{"run": id, "module", "function", "args",
"env", "cwd", "path", "stdout", "stderr"}`` forks a child that runs
``module.function(*args)`` with ``sys.path = path``; ``{"kill": id}`` sends SIGKILL to that
child if it still runs; ``{"preload": [module, ...]}`` imports more modules for the children
to come. On stdout: ``{"id": id, "code": code}`` when the child ended (0, the exit code,
or minus the signal that ended it; 1 for an exception, whose traceback is on the child's
stderr). The server ignores SIGINT
(a Ctrl-C typed in the terminal is the parent's to handle) and exits at the end of its stdin,
that is when the parent ends, however it ends; each child dies with it (SIGKILL, Linux).

Usage: ``python -m dronefly.harness.compliance.forkserver MODULE ...`` (the modules to import
first), started and spoken to by :func:`dronefly.harness.compliance.child.run_function`.
"""

from __future__ import annotations

import atexit
import ctypes
import importlib
import json
import os
import select
import signal
import sys
import tempfile
import traceback
from typing import Any, NoReturn

from .child import die_with_parent

__all__ = ["serve"]

#: how often the server reaps ended children while no request comes [s]
_REAP_S = 0.01


def _child(req: dict[str, Any], reply_fd: int) -> NoReturn:
    """The forked child: a process of its own, then the function, then the end of a process."""
    code = 1
    try:
        os.close(reply_fd)
        os.setsid()  # a Ctrl-C typed in the terminal reaches only the parent
        die_with_parent()
        signal.signal(signal.SIGINT, signal.default_int_handler)
        os.chdir(req["cwd"])
        sys.path[:] = req["path"]
        os.environ.clear()
        os.environ.update(req["env"])
        tempfile.tempdir = None  # TMPDIR is read again: the child's own folder
        sys.argv = [req["module"], *req["args"]]
        null = os.open(os.devnull, os.O_RDONLY)
        os.dup2(null, 0)
        os.close(null)
        for fd, path in ((1, req["stdout"]), (2, req["stderr"])):
            f = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
            os.dup2(f, fd)
            os.close(f)
        code = 0
        getattr(importlib.import_module(req["module"]), req["function"])(*req["args"])
    except SystemExit as e:
        code = e.code if isinstance(e.code, int) else 0 if e.code is None else 1
        if code == 1 and not isinstance(e.code, int):  # sys.exit("text"): the interpreter's way
            print(e.code, file=sys.stderr)
    except BaseException:
        traceback.print_exc()
        code = 1
    try:
        atexit._run_exitfuncs()  # the instances left live are freed, as at a normal exit
    finally:
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (OSError, ValueError):
                pass
        ctypes.CDLL(None).exit(code)  # C exit handlers and library destructors; stdio flushed
    os._exit(code)  # (not reached)


def serve(preload: list[str]) -> None:
    """Import ``preload``, then answer requests on stdin until it ends (module docstring)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    reply_fd = os.dup(1)
    os.dup2(2, 1)  # anything the preloaded modules print stays out of the replies
    for name in preload:
        importlib.import_module(name)
    running: dict[int, int] = {}  # pid -> request id
    pids: dict[int, int] = {}  # request id -> pid

    def send(msg: dict[str, int]) -> None:
        os.write(reply_fd, (json.dumps(msg) + "\n").encode())

    def reap() -> None:
        while running:
            try:
                pid, status = os.waitpid(-1, os.WNOHANG)
            except ChildProcessError:
                return
            if pid == 0:
                return
            rid = running.pop(pid, None)
            if rid is not None:
                pids.pop(rid, None)
                send({"id": rid, "code": os.waitstatus_to_exitcode(status)})

    buffer = b""
    while True:
        readable, _, _ = select.select([0], [], [], _REAP_S if running else None)
        reap()
        if not readable:
            continue
        chunk = os.read(0, 65536)
        if not chunk:
            return  # the parent ended: the children die with this process
        buffer += chunk
        while b"\n" in buffer:
            line, buffer = buffer.split(b"\n", 1)
            req = json.loads(line)
            if "preload" in req:  # more modules for the children to come
                for name in req["preload"]:
                    importlib.import_module(name)
                continue
            if "kill" in req:
                pid = pids.get(req["kill"])
                if pid is not None:
                    os.kill(pid, signal.SIGKILL)
                continue
            pid = os.fork()
            if pid == 0:
                _child(req, reply_fd)
            running[pid], pids[req["run"]] = req["run"], pid


if __name__ == "__main__":
    serve(sys.argv[1:])
