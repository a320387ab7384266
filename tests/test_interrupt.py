"""SIGINT deferred to the master's next check between steps."""

from __future__ import annotations

import os
import signal

import pytest

from dronefly.interrupt import deferred_sigint


def test_sigint_sets_a_flag_instead_of_raising():
    with deferred_sigint() as stop:
        assert not stop.requested
        os.kill(os.getpid(), signal.SIGINT)
        signal.getsignal(signal.SIGINT)  # bytecodes run: the handler has been called
        assert stop.requested
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_third_sigint_raises():
    with pytest.raises(KeyboardInterrupt):
        with deferred_sigint():
            for _ in range(3):
                os.kill(os.getpid(), signal.SIGINT)
                signal.getsignal(signal.SIGINT)


@pytest.mark.integration
@pytest.mark.parametrize("argv", [
    ["cosim", "--stop", "500000", "--no-plot", "--step", "0.5"],
    ["sweep", "--workers", "1", "--no-progress", "--no-plot", "--grid", "5", "--stop", "2000",
     "--disturbances", "grid", "--slices", "dgamma:dv"],
])
def test_ctrl_c_during_an_in_process_run_stops_cleanly(built_fmus, tmp_path, argv):
    """SIGINT after a few seconds: exit 130 with one line, no crash; the sweep keeps its
    finished rows."""
    import subprocess
    import sys
    import time

    out = tmp_path / "out"
    build = tmp_path / "fmus"
    build.mkdir()
    for name in ("DroneFlyLateral", "StateFeedback"):
        (build / f"{name}.fmu").write_bytes(built_fmus[name].read_bytes())
    extra = ["--plant", str(build / "DroneFlyLateral.fmu"), "--controller",
             str(build / "StateFeedback.fmu"), "--out", str(out)]
    for _ in range(2):  # twice: the first and a later run in the same folder (suite time)
        proc = subprocess.Popen([sys.executable, "-m", "dronefly", *argv, *extra],
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        if argv[0] == "sweep":  # its output folder appears once the cases start running
            deadline = time.monotonic() + 60
            while not out.is_dir() and time.monotonic() < deadline and proc.poll() is None:
                time.sleep(0.1)
        time.sleep(1.5)  # some steps (and for the sweep, some cases) done by then
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=60)
        assert proc.returncode == 130, (proc.returncode, err[-400:])
        assert err.strip().splitlines()[-1].endswith("interrupted"), err
    if argv[0] == "sweep":  # the finished cases were written before the exit
        assert len((out / "sweep.csv").read_text().splitlines()) > 1
