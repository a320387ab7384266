"""What a command will write is checked before it works, and options that cannot take
effect are refused (exit 2, one line naming the option and the value)."""

from __future__ import annotations

import argparse
import errno
from pathlib import Path

import pytest

from dronefly.cli import app
from dronefly.cli.app import main
from dronefly.cli.args import out_dir, out_file
from dronefly.core.files import write_csv_atomic, write_text_atomic

#: (command, option, what it names) of every output path option but those of ``check``
OUTPUTS = [("build", "--out", "DIR"), ("simulate", "--out", "DIR"), ("cosim", "--out", "DIR"),
           ("cosim", "--build", "DIR"), ("demo", "--out", "DIR"), ("demo", "--build", "DIR"),
           ("analyze", "--out", "FILE"), ("sweep", "--out", "DIR"), ("floquet", "--build", "DIR")]
#: bad values by kind: (value, what the message says)
BAD = {"DIR": [("afile", "is a file, not a folder"), ("afile/sub", "'afile' is a file")],
       "FILE": [("nodir/x.md", "the folder 'nodir' does not exist"),
                ("afile/x.md", "'afile' is a file"), (".", "is a folder")]}


def test_every_output_option_is_checked_when_the_command_line_is_parsed():
    """Every DIR or FILE option of every command but check (the paths a command writes) has the
    converter that checks it; a new one without it fails here."""
    parser = app._parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    found = []
    for name, sp in sub.choices.items():
        for action in sp._actions:
            if action.metavar in ("DIR", "FILE") and name != "check":
                assert action.type is (out_dir if action.metavar == "DIR" else out_file), (
                    name, action.option_strings)
                found.append((name, action.option_strings[-1], action.metavar))
    assert sorted(found) == sorted(OUTPUTS)


@pytest.mark.parametrize("command, option, kind", OUTPUTS)
def test_a_bad_output_path_is_refused_before_any_work(command, option, kind, tmp_path,
                                                       monkeypatch, capsys):
    """A file where a folder is wanted, a folder under a file, a missing folder of a file, a
    folder given as the file: exit 2 and one line naming the option and the value; the command
    never starts and nothing is written."""
    monkeypatch.chdir(tmp_path)
    Path("afile").write_text("x")

    def no_work(name):
        raise AssertionError(f"{name} started")

    monkeypatch.setattr(app, "_command", no_work)
    for value, why in BAD[kind]:
        assert main([command, f"{option}={value}"]) == 2
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1, err
        assert f"argument {option}: {value!r}" in err and why in err, err
        assert ".part" not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile"]


def test_analyze_out_in_a_missing_folder_is_refused_before_the_analysis(tmp_path, monkeypatch,
                                                                         capsys):
    """The issue's case: ``analyze --out nodir/x.md`` ran the whole analysis, then failed naming
    ``nodir/x.md.part``."""
    from dronefly.cli.commands import analyze

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(analyze, "analyze", lambda **kw: pytest.fail("the analysis ran"))
    assert main(["analyze", "--out", "nodir/x.md"]) == 2
    assert capsys.readouterr().err.strip() == (
        "dronefly analyze: error: argument --out: 'nodir/x.md': the folder 'nodir' does not exist"
        " ('dronefly analyze --help' shows the usage)")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("write", [lambda p: write_text_atomic(p, "text"),
                                   lambda p: write_csv_atomic(p, ["a"], [[1.0]])])
def test_an_atomic_write_that_fails_names_the_file_asked_for(tmp_path, write):
    """The result files are written to NAME.part and renamed; an error names NAME."""
    target = tmp_path / "nodir" / "x.csv"
    with pytest.raises(OSError) as e:
        write(target)
    assert e.value.errno == errno.ENOENT and e.value.filename == str(target)
    assert ".part" not in str(e.value)


# --- options that cannot take effect ----------------------------------------------------------
def test_analyze_json_and_markdown_together_are_refused(capsys, monkeypatch):
    """One report per run: --json with --markdown printed JSON alone; now refused."""
    from dronefly.cli.commands import analyze

    monkeypatch.setattr(analyze, "analyze", lambda **kw: pytest.fail("the analysis ran"))
    assert main(["analyze", "--json", "--markdown"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == ("dronefly analyze: error: argument --markdown: not allowed with argument --json"
                   " ('dronefly analyze --help' shows the usage)")


def test_analyze_input_without_targets_is_refused(capsys, monkeypatch):
    """--input is the input of the design for --targets; alone it was silently ignored."""
    from dronefly.cli.commands import analyze

    monkeypatch.setattr(analyze, "analyze", lambda **kw: pytest.fail("the analysis ran"))
    assert main(["analyze", "--input", "delta_alpha_1a"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert err.startswith("dronefly analyze: error: --input 'delta_alpha_1a' needs --targets")


# --- builds said ------------------------------------------------------------------------------
@pytest.mark.integration
@pytest.mark.parametrize("argv", [
    ["demo", "--no-plot"],
    ["floquet"],
    ["sweep", "--workers", "1", "--no-plot", "--no-progress", "--grid", "2", "--slices",
     "dgamma:dp", "--disturbances", "grid", "--gains", "paper", "--steps", "1", "--stop", "2"],
    ["sweep", "--compare", "nonlinear", "--workers", "1", "--no-plot", "--no-progress",
     "--disturbances", "directions", "--directions", "+dv", "--amplitudes", "1", "--stop", "1"],
    ["cosim", "--native", "--no-plot", "--stop", "2"],
    ["demo", "--native", "--no-plot"],
], ids=["demo", "floquet", "sweep", "sweep-compare-nonlinear", "cosim-native", "demo-native"])
def test_a_command_that_builds_fmus_says_what_it_built_and_where(argv, tmp_path, monkeypatch,
                                                                  capsys):
    """In an empty folder each builds the project's FMUs into build/: one line on stderr per
    artefact written, naming its path; stdout is left to the result (JSON stays JSON)."""
    monkeypatch.chdir(tmp_path)
    assert main(argv) in (0, 1)  # a verdict is not what is tested here
    err = capsys.readouterr().err.splitlines()
    said = sorted(line.split(": built ", 1)[1] for line in err if ": built " in line)
    assert all(line.startswith(f"dronefly {argv[0]}: built ") for line in err
               if ": built " in line)
    written = sorted(str(p.relative_to(tmp_path)) for p in (tmp_path / "build").rglob("*.*")
                     if p.suffix in (".fmu", ".ssp"))
    assert said and said == written
