"""The checking processes of ``dronefly check`` (harness/compliance/child.py, forkserver.py):
forked from the fork server or started as fresh interpreters (``DRONEFLY_CHECK_FORK=0``), each
is a process of its own and ends as a process ends, and the parent sees how it ended."""

from __future__ import annotations

import os
import signal
import sys
import time
from pathlib import Path

import pytest

from dronefly.harness.compliance import child
from dronefly.harness.compliance.child import run_function

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"),
                                reason="fork and PR_SET_PDEATHSIG: Linux")


@pytest.fixture(params=["fork server", "fresh interpreter"])
def mode(request, monkeypatch):
    monkeypatch.setenv("DRONEFLY_CHECK_FORK", "1" if request.param == "fork server" else "0")
    # tests/forked_targets.py: importable in a fresh interpreter too (the forked child takes
    # the parent's sys.path)
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join(
        [str(Path(__file__).parent), *filter(None, [os.environ.get("PYTHONPATH")])]))
    return request.param


def _run(function: str, *args: str, timeout_s: float = 20.0, tmp: str | None = None):
    # the functions end within a second; 20 s covers a fresh interpreter on a loaded machine
    return run_function("forked_targets", function, list(args), timeout_s, tmp)


def test_exit_codes_crashes_and_exceptions_are_reported(mode):
    # sys.exit's convention: no code is 0, a text is printed and is 1
    quiet = [_run("exit_without_code"), _run("exit_with", "1")]
    assert [(r.returncode, r.stderr) for r in quiet] == [(0, ""), (1, "")]
    text = _run("exit_with_text", "bye")
    assert text.returncode == 1 and text.stderr.strip() == "bye"
    assert _run("close_stdout_and_return").returncode == 0
    empty = _run("read_stdin", timeout_s=20.0)  # a child reads /dev/null, not the server's input
    assert (empty.returncode, empty.stdout) == (0, "0\n")
    assert _run("exit_with", "0").returncode == 0
    assert _run("exit_with", "3").returncode == 3
    assert _run("crash").returncode == -signal.SIGSEGV
    failed = _run("fail")
    assert failed.returncode == 1
    assert "RuntimeError: a bug of the function" in failed.stderr


def test_the_child_has_its_own_session_environment_and_temporary_folder(mode, tmp_path,
                                                                        monkeypatch):
    """The parent's environment as it is at the call (not as it was when the server started),
    its working folder, the private TMPDIR, a session of its own."""
    monkeypatch.setenv("DRONEFLY_TEST_VALUE", f"set at {time.monotonic()}")
    monkeypatch.chdir(tmp_path)
    folder = tmp_path / "private"
    folder.mkdir()
    r = _run("report", "DRONEFLY_TEST_VALUE", tmp=str(folder))
    assert r.returncode == 0, r.stderr
    assert r.stdout.split(" ", 1)[0] == os.environ["DRONEFLY_TEST_VALUE"].split(" ", 1)[0]
    assert os.environ["DRONEFLY_TEST_VALUE"] in r.stdout
    assert r.stdout.endswith(f" {folder} {tmp_path} True\n")


def test_the_child_ends_as_a_process_ends(mode, tmp_path):
    """``atexit`` functions run and the C library's buffered output is flushed: an FMU's
    exit-time code runs in the child as in a fresh process."""
    marker = tmp_path / "marker"
    r = _run("printf_and_atexit", str(marker))
    assert r.returncode == 0, r.stderr
    assert r.stdout == "buffered by the C library"
    assert marker.read_text() == "atexit ran"


def test_a_hanging_child_is_killed_at_the_timeout_and_its_folder_removed(mode, tmp_path,
                                                                          monkeypatch):
    monkeypatch.setattr("tempfile.tempdir", str(tmp_path))
    t0 = time.monotonic()
    r = _run("hang", timeout_s=1.0)
    assert r.returncode is None
    # killed at the timeout, not before it, within polls of 0.05 s and the kill (a second
    # late would fail)
    assert 1.0 <= time.monotonic() - t0 < 1.0 + 0.7
    assert list(tmp_path.iterdir()) == []


def test_ctrl_c_kills_the_child_within_a_poll(mode, monkeypatch, tmp_path):
    """A deferred SIGINT (core/interrupt.py) stops the wait: the child is killed, then
    KeyboardInterrupt."""
    calls = []
    pid_file = tmp_path / "hang.pid"

    def pending() -> bool:  # Ctrl-C once the child runs (it wrote its id), or after 10 s
        calls.append(time.monotonic())
        return len(calls) > 3 and (pid_file.exists() or len(calls) > 200)

    monkeypatch.setattr(child, "pending", pending)
    t0 = time.monotonic()
    with pytest.raises(KeyboardInterrupt):
        _run("hang", tmp=str(tmp_path))
    assert time.monotonic() - t0 < 30
    # asked every poll of 0.05 s (a loaded machine: well under half a second between two)
    assert max(b - a for a, b in zip(calls, calls[1:])) < 0.5
    # the child is gone: killed and reaped
    with pytest.raises(ProcessLookupError):
        os.kill(int(pid_file.read_text()), 0)


def test_the_fork_server_ends_with_its_parent(tmp_path):
    """A parent killed with SIGKILL (no exit code of its own runs): the server sees the end
    of its stdin and exits, and a child that still ran dies with it."""
    import subprocess

    code = ("import sys; sys.path.insert(0, sys.argv[1])\n"
            "from dronefly.harness.compliance.child import run_function\n"
            "run_function('forked_targets', 'hang', [], 600)\n")
    # (the killed parent cannot remove its temporary folder: it is in tmp_path)
    parent = subprocess.Popen([sys.executable, "-c", code, str(Path(__file__).parent)],
                              env={**os.environ, "DRONEFLY_CHECK_FORK": "1",
                                   "TMPDIR": str(tmp_path)})
    try:
        deadline = time.monotonic() + 60
        pids: list[str] = []
        while time.monotonic() < deadline and len(pids) < 2:
            servers = subprocess.run(["pgrep", "-P", str(parent.pid)], capture_output=True,
                                     text=True).stdout.split()
            pids = servers + [c for s in servers for c in subprocess.run(
                ["pgrep", "-P", s], capture_output=True, text=True).stdout.split()]
            time.sleep(0.1)
        assert len(pids) == 2, pids  # the server and the hanging child
    finally:
        parent.send_signal(signal.SIGKILL)
        parent.wait()
    for _ in range(100):
        if not any(Path(f"/proc/{p}").exists() and "Z" not in _state(p) for p in pids):
            break
        time.sleep(0.1)
    assert not any(Path(f"/proc/{p}").exists() and "Z" not in _state(p) for p in pids), pids


def _state(pid: str) -> str:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return "Z"


def test_the_later_modules_are_preloaded_from_the_second_child_on(monkeypatch):
    """A fresh server imports the checks; SciPy (the reference check's, through FMPy) from the
    second child on: a one-FMU check does not pay for it, several FMUs pay once."""
    monkeypatch.setenv("DRONEFLY_CHECK_FORK", "1")
    monkeypatch.setattr(child, "_SERVER", None)  # a server of this test's own
    name = child.PRELOAD_LATER[0]
    seen = [_run("loaded", name).stdout.strip() for _ in range(3)]
    assert seen == ["False", "True", "True"], seen
    assert _run("loaded", child.PRELOAD[0]).stdout.strip() == "True"


def test_no_fork_server_where_it_is_turned_off(monkeypatch):
    """``DRONEFLY_CHECK_FORK=0``: no fork server, the checks run in a fresh interpreter."""
    monkeypatch.setenv("DRONEFLY_CHECK_FORK", "0")
    assert child._server() is None
    monkeypatch.setenv("DRONEFLY_CHECK_FORK", "1")
    assert child._server() is not None


def test_a_child_that_ends_as_it_is_killed_is_waited_for_once(monkeypatch, tmp_path):
    """At the timeout the child is killed and waited for until the server says it ended,
    whatever its exit code (here 0: it ended on its own as the kill came): the call returns
    the timeout, at once (a fake server)."""
    import itertools
    import threading

    class Server:
        ids = itertools.count(10)
        killed = False

        def send(self, request):
            self.killed = self.killed or "kill" in request
            return True

        def wait(self, rid, timeout_s):
            if self.killed:
                return True, 0
            time.sleep(timeout_s)
            return False, None

    monkeypatch.setattr(child, "_server", lambda: Server())
    got = []
    worker = threading.Thread(target=lambda: got.append(
        run_function("m", "f", [], timeout_s=0.2, tmp=str(tmp_path))), daemon=True)
    worker.start()
    worker.join(10.0)
    assert not worker.is_alive(), "the wait for the killed child did not end"
    assert got == [child.ChildRun(None, "", "")]


class _Pipe:
    """A server's stdin that fails as told."""

    def __init__(self, error=None):
        self.error, self.closed = error, False

    def write(self, data):
        if self.error:
            raise self.error

    def flush(self):
        pass

    def close(self):
        self.closed = True


def _bare_server(**attrs):
    import threading

    server = object.__new__(child._ForkServer)
    server.lock, server.replies = threading.Lock(), threading.Condition()
    server.code, server.alive = {}, True
    for k, v in attrs.items():
        setattr(server, k, v)
    return server


@pytest.mark.parametrize("error", [BrokenPipeError(32, "gone"), OSError(5, "I/O error"),
                                   ValueError("write to closed file")])
def test_a_request_to_a_server_that_is_gone_is_refused(error):
    """A server whose pipe is broken or closed: send says False (the caller then runs the
    function in a fresh interpreter)."""
    from types import SimpleNamespace

    assert _bare_server(proc=SimpleNamespace(stdin=_Pipe())).send({"run": 1}) is True
    assert _bare_server(proc=SimpleNamespace(stdin=_Pipe(error))).send({"run": 1}) is False


def test_the_servers_replies_and_its_end():
    """Each reply is kept for its request; at the end of the server's output the server is
    gone: a wait for a request it did not answer ends at once with no code."""
    import io
    from types import SimpleNamespace

    server = _bare_server(proc=SimpleNamespace(stdout=io.BytesIO(
        b'{"id": 3, "code": 0}\n{"id": 4, "code": -9}\n')))
    server._read()
    assert server.code == {3: 0, 4: -9} and server.alive is False
    assert server.wait(4, 5.0) == (True, -9) and server.wait(3, 5.0) == (True, 0)
    t0 = time.monotonic()
    assert server.wait(5, 5.0) == (True, None)
    assert time.monotonic() - t0 < 1.0


def test_no_fork_server_where_it_cannot_start(monkeypatch):
    def fails():
        raise OSError(24, "Too many open files")

    monkeypatch.setenv("DRONEFLY_CHECK_FORK", "1")
    monkeypatch.setattr(child, "_SERVER", None)
    monkeypatch.setattr(child, "_ForkServer", fails)
    assert child._server() is None


def test_closing_the_server_ends_its_input_and_reaps_it_or_kills_it():
    import subprocess
    from types import SimpleNamespace

    calls = []

    def proc(wait_error=None):
        def wait(timeout):
            calls.append(("wait", timeout))
            if wait_error:
                raise wait_error
        return SimpleNamespace(stdin=_Pipe(), wait=wait, kill=lambda: calls.append(("kill",)))

    server = _bare_server(proc=proc())
    server.close()
    assert server.proc.stdin.closed and calls == [("wait", 10)]
    calls.clear()
    server = _bare_server(proc=proc(subprocess.TimeoutExpired("server", 10)))
    server.close()
    assert calls == [("wait", 10), ("kill",)]
    calls.clear()
    server = _bare_server(proc=proc(OSError(10, "no child")))
    server.close()
    assert calls == [("wait", 10), ("kill",)]


def test_what_the_function_prints_is_kept_where_python_buffers_it(monkeypatch):
    """A server started without PYTHONUNBUFFERED (Python buffers what a child prints to its
    file): the child flushes its streams before its C exit, nothing printed is lost."""
    monkeypatch.delenv("PYTHONUNBUFFERED", raising=False)
    monkeypatch.setenv("DRONEFLY_CHECK_FORK", "1")
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join(
        [str(Path(__file__).parent), *filter(None, [os.environ.get("PYTHONPATH")])]))
    server = child._ForkServer()
    try:
        monkeypatch.setattr(child, "_server", lambda: server)
        r = _run("report", "DRONEFLY_CHECK_FORK")
        assert r.returncode == 0 and r.stdout.startswith("1 ") and r.stdout.endswith(" True\n")
    finally:
        server.close()


def test_the_server_keeps_its_replies_clean_and_reads_every_request_of_a_chunk(tmp_path):
    """The protocol of the fork server itself: a module it preloads prints at import (kept
    out of the replies, which are one JSON object a line), and a preload, a kill and a run
    request written in one chunk are all served."""
    import json
    import select
    import subprocess

    (tmp_path / "noisy_import.py").write_text("print('noise at import')\n")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(tmp_path), str(Path(__file__).parent), *filter(None, [os.environ.get("PYTHONPATH")])])}
    server = subprocess.Popen([sys.executable, "-m", "dronefly.harness.compliance.forkserver",
                               "noisy_import"], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                              stderr=subprocess.DEVNULL, env=env)
    try:
        run = {"run": 7, "module": "forked_targets", "function": "exit_with", "args": ["3"],
               "env": env, "cwd": str(tmp_path), "path": [str(Path(__file__).parent), *sys.path],
               "stdout": str(tmp_path / "out"), "stderr": str(tmp_path / "err")}
        server.stdin.write((json.dumps({"preload": ["noisy_import"]}) + "\n"
                            + json.dumps({"kill": 99}) + "\n"  # no such child: nothing to do
                            + json.dumps(run) + "\n").encode())
        server.stdin.flush()
        ready, _, _ = select.select([server.stdout], [], [], 20.0)
        assert ready, "no reply to a request written with a preload in one chunk"
        assert json.loads(server.stdout.readline()) == {"id": 7, "code": 3}
    finally:
        server.stdin.close()
        server.wait(timeout=10)


def test_a_child_that_removes_its_own_folder_is_no_error(mode):
    """The private temporary folder is removed after the child, which may have removed it
    itself already."""
    assert _run("remove_own_folder").returncode == 0


def test_how_a_child_ended_is_a_value():
    import dataclasses

    with pytest.raises(dataclasses.FrozenInstanceError):
        child.ChildRun(0, "", "").returncode = 1


def test_a_forked_childs_output_files_are_the_users_own(tmp_path, monkeypatch):
    """What a forked child prints goes to files only its user may read (0600, less the
    umask), in the child's folder."""
    monkeypatch.setenv("DRONEFLY_CHECK_FORK", "1")
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join(
        [str(Path(__file__).parent), *filter(None, [os.environ.get("PYTHONPATH")])]))
    umask = os.umask(0o022)
    os.umask(umask)
    assert _run("exit_with", "0", tmp=str(tmp_path)).returncode == 0
    for name in (".stdout", ".stderr"):
        assert (tmp_path / name).stat().st_mode & 0o777 == 0o600 & ~umask, name
