"""SIGINT deferred to the master's next check between steps."""

from __future__ import annotations

import os
import signal
from pathlib import Path

import pytest

from dronefly.core.interrupt import deferred_sigint


def test_sigint_sets_a_flag_instead_of_raising(sigint_as_in_a_terminal):
    with deferred_sigint() as stop:
        assert not stop.requested
        os.kill(os.getpid(), signal.SIGINT)
        signal.getsignal(signal.SIGINT)  # bytecodes run: the handler has been called
        assert stop.requested
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_third_sigint_raises(sigint_as_in_a_terminal):
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
    """SIGINT in the middle of a run (delivered at a known point, see tests/sigint_at.py):
    exit 130 with one line, no crash; the sweep keeps the cases it finished."""
    import subprocess
    import sys

    out = tmp_path / "out"
    build = tmp_path / "fmus"
    build.mkdir()
    for name in ("DroneFlyLateral", "StateFeedback"):
        (build / f"{name}.fmu").write_bytes(built_fmus[name].read_bytes())
    extra = ["--plant", str(build / "DroneFlyLateral.fmu"), "--controller",
             str(build / "StateFeedback.fmu"), "--out", str(out)]
    for _ in range(2):  # twice: the first and a later run in the same folder
        proc = subprocess.run([sys.executable, str(Path(__file__).with_name("sigint_at.py")),
                               *argv, *extra],
                              capture_output=True, text=True, timeout=300)
        assert proc.returncode == 130, (proc.returncode, proc.stderr[-400:])
        assert proc.stderr.strip().splitlines()[-1].endswith("interrupted"), proc.stderr
    if argv[0] == "sweep":  # the finished cases were written before the exit
        assert len((out / "sweep.csv").read_text().splitlines()) > 1

