"""The CLI, tested in-process: exit codes, one-line errors, no partial files."""

from __future__ import annotations

import subprocess
import sys
import zipfile

import numpy as np
import pytest
from numpy.testing import assert_allclose

from dronefly.harness.builder.build import FMUS
from dronefly.cli.app import main
from dronefly.harness.stability.simulate import exact_open_loop


def test_help_lists_subcommands(capsys):
    """The commands --help lists are the ones the CLI runs: each answers its own --help, and
    a name it does not list is refused as bad input (exit 2)."""
    assert main(["--help"]) == 0
    out = capsys.readouterr().out
    listing = out.split("COMMAND\n", 1)[1].split("\n\n", 1)[0]
    listed = [line.split()[0] for line in listing.splitlines() if line.startswith("    ")
              and not line.startswith("      ")]
    assert {"build", "simulate", "cosim", "check", "sweep"} <= set(listed), listed
    for name in listed:
        assert main([name, "--help"]) == 0, name
        assert capsys.readouterr().out.startswith(f"usage: dronefly {name} "), name
    assert main(["nosuchcommand"]) == 2
    assert "examples:" in out


#: prints the subcommand modules that ``main(argv)`` imported, after running it
_IMPORTED = (
    "import contextlib, io, sys\n"
    "from dronefly.cli.app import main\n"
    "with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):\n"
    "    code = main(sys.argv[1:])\n"
    "print(code, sorted(m.rpartition('.')[2] for m in sys.modules\n"
    "                   if m.startswith('dronefly.cli.commands.') and m != 'dronefly.cli.commands.args'))")


@pytest.mark.parametrize("argv, code, imported", [
    (["--help"], 0, []),
    (["nosuchcommand"], 2, []),
    (["cosim", "--help"], 0, ["cosim"]),
    (["--debug", "aero", "--no-such-option"], 2, ["aero"]),
])
def test_only_the_chosen_subcommand_module_is_imported(argv, code, imported):
    """``dronefly --help`` imports no subcommand's module (none of the analyses); a subcommand
    imports its own module alone, for its options, its --help and its run."""
    r = subprocess.run([sys.executable, "-c", _IMPORTED, *argv], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0, r.stderr[-1500:]
    assert r.stdout.split(None, 1) == [str(code), f"{imported}\n"], r.stdout


def test_a_subcommand_module_that_fails_to_import_is_a_bug(monkeypatch, capsys):
    """A subcommand module that cannot be imported (a broken install) is an internal error: one
    line naming it and exit 1, never bad input; --debug adds the traceback."""
    from dronefly.cli import commands

    def broken(name):
        raise ImportError(f"cannot import {name}")

    monkeypatch.setattr(commands, "load", broken)
    monkeypatch.setattr("dronefly.cli.app.load", broken)
    assert main(["aero", "--json"]) == 1
    err = capsys.readouterr().err
    assert err == ("dronefly aero: internal error (a bug, please report it): ImportError: cannot "
                   "import aero (--debug shows the traceback)\n")
    assert main(["--debug", "aero"]) == 1
    err = capsys.readouterr().err
    assert "Traceback" in err and err.endswith("ImportError: cannot import aero\n")


@pytest.mark.integration
def test_build_and_simulate_reproduce_reference(tmp_path, capsys):
    assert main(["build", "--out", str(tmp_path)]) == 0
    assert (tmp_path / "DroneFlyLateral.fmu").is_file()
    fmi3 = {p.name for p in (tmp_path / "fmi3").iterdir()}  # the FMI 3.0 half (docs/fmi3.md)
    assert fmi3 == {f"{n}.fmu" for n in FMUS} | {"DroneFlyClosedLoop.ssp", "DroneFlyHover.ssp",
                                                "DroneFlyHover6DOF.ssp"}
    with zipfile.ZipFile(tmp_path / "fmi3" / "DroneFlyLateral.fmu") as z:
        assert 'fmiVersion="3.0"' in z.read("modelDescription.xml").decode()
    assert main(["simulate", "--stop", "30", "--step", "0.1", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "max relative deviation from the exact solution" in out
    new = np.loadtxt(tmp_path / "DroneFlyLateral_open_loop.csv", delimiter=",", skiprows=1)
    assert new.shape == (301, 5)
    exact = exact_open_loop(np.array([0.0, 0.0, 0.0, 0.1]), new[:, 0])
    assert_allclose(new[:, 1:] / np.abs(exact).max(axis=0), exact / np.abs(exact).max(axis=0),
                    rtol=0, atol=1e-12, err_msg="open loop from a 0.1 rad roll vs Eq. (9) exact")


@pytest.mark.parametrize("argv, fragment", [
    (["simulate", "--step", "-1"], "'-1' must be > 0"),
    (["simulate", "--stop", "nan"], "'nan' is not finite"),
    (["simulate", "--gamma0", "abc"], "'abc' is not a number"),
    (["frobnicate"], "invalid choice"),
])
def test_bad_arguments_exit_2_with_one_line(argv, fragment, capsys, tmp_path):
    assert main([*argv, *(["--out", str(tmp_path)] if argv[0] == "simulate" else [])]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert fragment in err[-1] and "Traceback" not in "\n".join(err)
    assert list(tmp_path.iterdir()) == []


def test_step_longer_than_stop_is_refused(capsys, tmp_path):
    assert main(["simulate", "--stop", "0.05", "--step", "0.1", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "step (0.1)" in err[0]


@pytest.mark.integration
def test_simulate_that_stops_early_exits_1(tmp_path, capsys):
    """The open loop overflows the linear state after about 9,000 wing beats: the plant
    refuses the step; the command says so and exits 1, keeping what was computed."""
    assert main(["simulate", "--stop", "20000", "--step", "1", "--out", str(tmp_path)]) == 1
    out = capsys.readouterr().out
    assert "INCOMPLETE" in out
    assert (tmp_path / "DroneFlyLateral_open_loop.csv").is_file()
