"""Functions that tests/test_forkserver.py runs in checking processes (importable by name)."""

from __future__ import annotations

import atexit
import ctypes
import os
import signal
import sys
import tempfile
import time


def exit_with(code: str) -> None:
    sys.exit(int(code))


def exit_without_code() -> None:
    sys.exit()


def exit_with_text(text: str) -> None:
    sys.exit(text)


def close_stdout_and_return() -> None:
    sys.stdout.close()


def read_stdin() -> None:
    """Print how much standard input holds (a child's is empty: /dev/null)."""
    print(len(sys.stdin.read()))


def crash() -> None:
    os.kill(os.getpid(), signal.SIGSEGV)


def hang() -> None:
    """Sleep 10 minutes, its process id written first to ``hang.pid`` in its temporary
    folder (the caller's ``tmp``)."""
    with open(os.path.join(tempfile.gettempdir(), "hang.pid"), "w") as f:
        f.write(str(os.getpid()))
    time.sleep(600)


def remove_own_folder() -> None:
    """Remove the process's own temporary folder (a child that cleans up after itself)."""
    import shutil

    shutil.rmtree(tempfile.gettempdir())


def fail() -> None:
    raise RuntimeError("a bug of the function")


def report(name: str) -> None:
    """Print where the process stands: an environment variable, the temporary folder, the
    working folder, and whether it leads a session of its own."""
    print(os.environ.get(name), tempfile.gettempdir(), os.getcwd(), os.getsid(0) == os.getpid())


def printf_and_atexit(path: str) -> None:
    """C stdio output left in its buffer (no newline, no flush) and an ``atexit`` function:
    both reach their files only if the process ends as a process ends."""
    atexit.register(lambda: open(path, "w").write("atexit ran"))
    libc = ctypes.CDLL(None)
    libc.printf(b"%s", b"buffered by the C library")


def loaded(name: str) -> None:
    """Print whether the module ``name`` was imported before this function ran."""
    print(name in sys.modules)
