"""The core install (``pip install dronefly-fmu``, no extra) runs every command with its defaults:
every command's ``--help`` and every example its help prints exit 0 there.
The documented examples (README, docs/) run in the same environment: tests/test_docs.py.

A missing optional package costs only its feature, with one line saying so (a plot skipped,
the BLAS limit of the sweep's workers skipped; the progress bar needs a terminal anyway); an
option that asks for one (``sweep --scheduler``: Dask) is refused naming the extra.
"""

from __future__ import annotations

import json
import shlex
import subprocess
from pathlib import Path

import pytest

from dronefly.cli.app import _parser
from dronefly.cli.commands import COMMANDS, load

pytestmark = pytest.mark.integration

#: options appended to an example (argparse takes the last value) to make it small: the
#: install is what is tested here, the sizes are the sweep's and check's own tests' business
_SMALLER = {"sweep": ["--grid", "2", "--slices", "dgamma:dv", "--lhs", "4", "--directions",
                      "+dv,-dgamma", "--amplitudes", "1", "--stop", "6",
                      "--fresh"],  # (the examples share the default --out folder)
            "check": ["--no-fuzz"]}
#: examples not run as they are: why, and the exit code they give as run
_NEEDS = {"dronefly sweep --scheduler tcp://10.0.0.5:8786": ("a Dask cluster and the sweep "
                                                             "extra: refused, naming it", 2),
          # placeholders for the user's FMU and its results: refused, naming the missing file
          "dronefly check Model.fmu --ref Model_ref.csv --in Model_in.csv": (
              "the user's FMU and CSV files: refused, naming the missing --ref file", 2),
          # every check of every FMU, built for FMI 2.0 and 3.0 (minutes): run on one FMU
          "dronefly check": ("run as: dronefly check build/DroneFlyFlapping.fmu", 0)}

#: run in the core environment: every example (argv lists) in one process, as ``dronefly``
_RUNNER = r'''
import contextlib, io, json, sys, time
from dronefly.cli.app import main

report = []
for argv in json.load(open(sys.argv[1])):
    out, err, t0 = io.StringIO(), io.StringIO(), time.perf_counter()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(argv)
        except SystemExit as e:  # --help: argparse exits
            code = e.code
    report.append({"argv": argv, "code": code, "stderr": err.getvalue()[-1500:],
                   "stdout": out.getvalue()[-3000:], "seconds": time.perf_counter() - t0})
json.dump(report, open(sys.argv[2], "w"))
'''


def _examples() -> list[str]:
    """Every ``dronefly ...`` line of the help texts (the top level's first)."""
    texts = [_parser().epilog or "", *(load(c).EPILOG for c in COMMANDS)]
    return [line.strip().partition("  (")[0] for text in texts for line in text.splitlines()
            if line.startswith("  dronefly ")]  # less a comment: "  (rows: ...)"


def _scratch(folder: Path) -> None:
    """The files the examples name as the user's own: my/Plant.fmu, my_gains.json, ...
    (copies of the project's, after ``dronefly build``), and a docs/ folder."""
    build = folder / "build"
    (folder / "my").mkdir()
    for name, source in (("Plant", "DroneFlyLateral"), ("Controller", "StateFeedback")):
        (folder / "my" / f"{name}.fmu").write_bytes((build / f"{source}.fmu").read_bytes())
    (folder / "my.ssp").write_bytes((build / "DroneFlyHover.ssp").read_bytes())
    gains = [[-0.3, -0.3, -0.2, -0.1], [0.0] * 4, [0.0] * 4]
    (folder / "my_gains.json").write_text(json.dumps(gains))
    (folder / "my_gains.csv").write_text("\n".join(",".join(map(str, r)) for r in gains) + "\n")
    (folder / "docs").mkdir()


def test_every_help_and_every_help_example_runs_on_the_core_install(core_env, tmp_path):
    """``dronefly --help`` and ``dronefly COMMAND --help`` for every command, then every example
    of the help texts in a scratch folder (``dronefly build`` first, as the user would), in the
    environment with no extra: each exits 0 (the Dask one: 2, naming the extra). A default that
    needs an optional package (plots, the sweep's BLAS limit) says it is skipped in one line."""
    # the console script once; every command's --help in the runner's one process, below
    r = subprocess.run([str(core_env / "dronefly"), "--help"], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0 and "examples:" in r.stdout, r.stderr[-500:]
    helps = [[c, "--help"] for c in COMMANDS]
    examples = _examples()
    assert len(examples) >= 30 and examples[0] == "dronefly build"
    # a folder in /tmp (build --out /tmp/fmus) is made in this test's own
    runs = [shlex.split(_NEEDS[e][0].partition("run as: ")[2] or e if e in _NEEDS else
                        e.replace(" /tmp/", f" {tmp_path}/"))[1:]
            + _SMALLER.get(shlex.split(e)[1], []) for e in examples]
    folder = tmp_path / "scratch"
    folder.mkdir()
    jobs, report = tmp_path / "jobs.json", tmp_path / "report.json"
    runner = tmp_path / "runner.py"
    runner.write_text(_RUNNER)
    first = subprocess.run([str(core_env / "dronefly"), "build"], cwd=folder,
                           capture_output=True, text=True, timeout=300)
    assert first.returncode == 0, first.stderr[-1500:]
    _scratch(folder)
    jobs.write_text(json.dumps(helps + runs[1:]))
    r = subprocess.run([str(core_env / "python"), str(runner), str(jobs), str(report)],
                       cwd=folder, capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, r.stderr[-3000:]
    ran = json.loads(report.read_text())
    for argv, run in zip(helps, ran):
        assert run["code"] == 0 and "examples:" in run["stdout"], (argv, run["stderr"][-500:])
    ran = ran[len(helps):]
    failed = []
    for example, run in zip(examples[1:], ran):
        expected = _NEEDS.get(example, ("", 0))[1]
        if run["code"] != expected:
            failed.append((example, run["code"], run["stderr"]))
        if "--scheduler" in example:
            assert "dronefly-fmu[sweep]" in run["stderr"], run
    print("\n".join(f"{run['seconds']:6.2f} s  {' '.join(run['argv'])}" for run in ran))
    assert not failed, failed
    said = "".join(run["stderr"] for run in ran)
    assert "plot skipped: matplotlib is not installed" in said  # cosim, with the extra to install
    assert "one BLAS thread per worker process skipped: threadpoolctl" in said  # sweep


@pytest.mark.parametrize("terminal", [True, False])
def test_the_progress_bar_is_skipped_without_tqdm_or_without_a_terminal(
        terminal, built_fmus, tmp_path, monkeypatch, capsys):
    """Without tqdm the sweep runs without its bar: one line says so when there is a terminal
    to show it on; without a terminal there is no bar to skip, and no line."""
    import sys

    from dronefly.cli.app import main
    from dronefly.cli.commands import sweep

    monkeypatch.setitem(sys.modules, "tqdm", None)  # import fails as if not installed
    monkeypatch.setattr(sweep, "stderr_is_tty", lambda: terminal)
    argv = ["sweep", "--plant", str(built_fmus["DroneFlyLateral"]), "--controller",
            str(built_fmus["StateFeedback"]), "--workers", "1", "--no-plot", "--disturbances",
            "directions", "--directions", "+dv", "--amplitudes", "1", "--gains", "paper",
            "--steps", "1", "--stop", "2", "--out", str(tmp_path / "out")]
    assert main(argv) == 0
    said = [line for line in capsys.readouterr().err.splitlines() if "skipped" in line]
    assert said == ([] if not terminal else [
        "dronefly sweep: progress bar skipped: tqdm is not installed (the sweep's progress "
        "bar): pip install 'dronefly-fmu[sweep]'"])


def test_no_optional_package_is_said_to_drive_worker_threads():
    """The sweep's workers are processes; threadpoolctl limits BLAS threads in each."""
    from dronefly.core.extras import EXTRAS

    assert all("worker thread" not in what for _, what in EXTRAS.values())
