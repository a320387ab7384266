"""Messages in the user's words: FMI status names and plain floats, the SSP
and the component by name, one line for an output folder that is a file, the FMU's own message
from ``simulate``, grammar, and the hints of the bare command and ``--debug``."""

from __future__ import annotations

import json
import shutil
import zipfile

import numpy as np
import pytest

from dronefly.cli.app import main
from dronefly.core.text import status_name
from dronefly.harness.cosim.records import StepFailure


def test_step_failure_names_the_status_and_prints_a_plain_float():
    text = str(StepFailure("DroneFlyLateral", "fmi2DoStep", np.float64(1.3365853658536586), 2,
                           "why"))
    assert text == ("DroneFlyLateral: fmi2DoStep at t = 1.3365853658536586 s returned "
                    "fmi2Discard (why)")
    assert status_name(3, "fmi3DoStep") == "fmi3Error"
    assert status_name(5, "fmi3DoStep") == "status 5 (not an FMI status)"  # fmi2Pending only


def test_cosim_failure_in_summary_and_json_is_in_the_users_words(built_fmus, tmp_path, capsys):
    argv = ["cosim", "--plant", str(built_fmus["DroneFlyLateral"]), "--controller",
            str(built_fmus["StateFeedback"]), "--gains", "open", "--x0=0,0,0,1e300",
            "--no-plot", "--json", "--out", str(tmp_path)]
    assert main(argv) == 1
    out, err = capsys.readouterr()
    failure = json.loads(out)["failure"]
    for text in (failure, err):
        assert "returned fmi2Discard" in text and "np.float64" not in text
        assert "status 2" not in text


def test_ssp_missing_its_fmu_names_the_ssp_and_the_component(built_fmus, tmp_path, capsys):
    ssp = tmp_path / "missing.ssp"
    with zipfile.ZipFile(built_fmus["DroneFlyHover.ssp"]) as src, \
            zipfile.ZipFile(ssp, "w") as dst:
        for item in src.infolist():
            if item.filename != "resources/StateFeedback.fmu":
                dst.writestr(item, src.read(item))
    assert main(["cosim", "--system", str(ssp), "--no-plot", "--out",
                 str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert str(ssp) in err and "'lateral_controller'" in err
    assert "resources/StateFeedback.fmu" in err and "dronefly_ssp_" not in err


@pytest.mark.parametrize("command", [["cosim", "--no-plot"], ["simulate"],
                                     ["demo", "--no-plot"], ["build"],
                                     ["sweep", "--no-plot", "--no-progress"]])
def test_out_that_is_a_file_is_one_line(tmp_path, capsys, monkeypatch, command):
    monkeypatch.chdir(tmp_path)  # where the default build/ would go
    afile = tmp_path / "afile"
    afile.write_text("mine")
    assert main([*command, "--out", str(afile)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    # argparse's form: the option, then the value (checked when the command line is read)
    assert err == [f"dronefly {command[0]}: error: argument --out: {str(afile)!r} is a file, "
                   f"not a folder ('dronefly {command[0]} --help' shows the usage)"]
    assert afile.read_text() == "mine"
    assert [p.name for p in tmp_path.iterdir()] == ["afile"]  # refused before any build


def test_simulate_shows_the_fmus_message(built_fmus, tmp_path, capsys):
    shutil.copy(built_fmus["DroneFlyLateral"], tmp_path)  # up to date: not rebuilt
    assert main(["simulate", "--gamma0", "1e300", "--stop", "300", "--out", str(tmp_path)]) == 1
    out = capsys.readouterr().out
    assert "INCOMPLETE: the FMU refused the step after" in out
    assert "fmi2Discard: DroneFlyLateral: step refused at t = " in out and "overflow" in out
    assert "debug logging" not in out


def test_setting_an_output_says_an_output(built_fmus, tmp_path, capsys):
    argv = ["cosim", "--plant", str(built_fmus["DroneFlyLateral"]), "--controller",
            str(built_fmus["StateFeedback"]), "--set", "plant.delta_v=1", "--no-plot",
            "--out", str(tmp_path)]
    assert main(argv) == 2
    assert "is an output continuous variable of plant" in capsys.readouterr().err


def test_bare_command_hints_at_help(capsys):
    assert main([]) == 2
    err = capsys.readouterr().err.strip()
    assert "COMMAND" in err and "'dronefly --help'" in err and len(err.splitlines()) == 1


@pytest.mark.parametrize("where", ["before", "after"])
def test_debug_before_or_after_the_subcommand(built_fmus, tmp_path, capsys, where):
    # a mistake found by the run, not by argparse: --debug shows its traceback
    rest = ["--plant", str(built_fmus["DroneFlyLateral"]), "--controller",
            str(built_fmus["StateFeedback"]), "--set", "plant.no_such_name=1", "--no-plot",
            "--out", str(tmp_path)]
    argv = ["--debug", "cosim", *rest] if where == "before" else ["cosim", "--debug", *rest]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "Traceback" in err and "no_such_name" in err
