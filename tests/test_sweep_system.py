"""``dronefly sweep --system``: the sweep's cases on a whole system of FMUs.

Oracle: the plant/controller sweep (harness.cosim's pair master) of the same cases. The
hover system's axes are not coupled, so its lateral loop must give the same rows bit for
bit (only the case key, which includes the ``--set`` names, differs).
"""

from __future__ import annotations

from pathlib import Path

import pytest

from dronefly.cli.app import main
from dronefly.harness.sweep.cases import SweepInputError, SweepSpec
from dronefly.harness.sweep.run import read_rows, run_sweep
from dronefly.harness.cosim.system import System
from dronefly.harness.cosim.ssp import write_system_ssp

pytestmark = pytest.mark.integration

SPEC = SweepSpec(disturbances=("directions",), directions=("+dp", "-mode1", "+dgamma"),
                 amplitudes=2, gains=("paper", "stabilising"), steps_wb=(1.0,), stop_wb=40.0)


def _rows(folder: Path) -> list[dict[str, str]]:
    return [{k: v for k, v in r.items() if k != "key"} for r in read_rows(folder / "sweep.csv")]


@pytest.mark.parametrize("master, pair_set, system_set", [
    ("gauss-seidel", {}, {}),
    ("jacobi", {"plant.Lv_plus": 0.2}, {"lateral.Lv_plus": 0.2,
                                        "longitudinal.delta_q_start": 0.05}),
])
def test_system_sweep_equals_the_pair_sweep(built_fmus, tmp_path, master, pair_set,
                                            system_set):
    spec = SweepSpec(**{**SPEC.__dict__, "master": master})
    pair = run_sweep(spec, tmp_path / "pair", workers=1, progress_bar=False, plot=False,
                     plant=built_fmus["DroneFlyLateral"],
                     controller=built_fmus["StateFeedback"], set_values=pair_set)
    system = run_sweep(spec, tmp_path / "system", workers=1, progress_bar=False, plot=False,
                       system=built_fmus["DroneFlyHover.ssp"], set_values=system_set)
    assert len(system.rows) == 2 * 3 * 2 and system.summary["errors"] == 0
    assert _rows(tmp_path / "system") == _rows(tmp_path / "pair")
    assert {r["verdict"] for r in system.rows} >= {"within"}
    assert system.summary["plant"] == "lateral"
    assert system.summary["controller"] == "lateral_controller"
    # the --set values are part of the case, converted to their declared types: a rerun
    # with the same values as text (as --set gives them) resumes every case
    again = run_sweep(spec, tmp_path / "system", workers=1, progress_bar=False, plot=False,
                      system=built_fmus["DroneFlyHover.ssp"],
                      set_values={k: str(v) for k, v in system_set.items()})
    assert again.summary["resumed_cases"] == len(system.rows)
    assert again.summary["computed_cases"] == 0


def test_process_pool_on_a_system(built_fmus, tmp_path):
    one = run_sweep(SPEC, tmp_path / "one", workers=1, progress_bar=False, plot=False,
                    system=built_fmus["DroneFlyHover.ssp"])
    two = run_sweep(SPEC, tmp_path / "two", workers=2, progress_bar=False, plot=False,
                    system=built_fmus["DroneFlyHover.ssp"])
    assert two.summary["backend"] == "processes"
    assert read_rows(two.csv) == read_rows(one.csv)


def _phi_a_only_ssp(built_fmus, tmp_path) -> Path:
    """The lateral pair with only delta_Phi_a wired: gains on the other controls act nowhere."""
    from dronefly.harness.cosim.system import Connection
    from dronefly.models.lateral_interface import STATE_NAMES

    cons = [Connection("plant", s, "ctrl", s) for s in STATE_NAMES]
    cons.append(Connection("ctrl", "delta_Phi_a", "plant", "delta_Phi_a"))
    system = System({"plant": built_fmus["DroneFlyLateral"], "ctrl": built_fmus["StateFeedback"]},
                    cons, name="phi_a_only")
    return write_system_ssp(system, tmp_path / "phi_a_only.ssp")


def test_gains_that_no_connection_carries_are_refused(built_fmus, tmp_path):
    ssp = _phi_a_only_ssp(built_fmus, tmp_path)
    ok = run_sweep(SweepSpec(**{**SPEC.__dict__, "gains": ("paper",)}), tmp_path / "ok",
                   workers=1, progress_bar=False, plot=False, system=ssp)
    assert ok.summary["errors"] == 0  # Eq. (27) acts through delta_Phi_a only
    gains = tmp_path / "k.csv"
    gains.write_text("0,0,0,0\n0.1,0,0,0\n0,0,0,0\n")
    with pytest.raises(SweepInputError, match=r"K\[2,1\] = 0\.1 .*delta_Phi_a"):
        run_sweep(SweepSpec(**{**SPEC.__dict__, "gains": (str(gains),)}), tmp_path / "bad",
                  workers=1, progress_bar=False, plot=False, system=ssp)
    assert not (tmp_path / "bad").exists()


def test_a_system_without_a_lateral_plant_is_refused(built_fmus, tmp_path):
    system = System.by_name({"lon": built_fmus["DroneFlyLongitudinal"],
                             "ctrl": built_fmus["StateFeedbackLongitudinal"]}, name="lon")
    ssp = write_system_ssp(system, tmp_path / "lon.ssp")
    with pytest.raises(SweepInputError, match="0 lateral plants"):
        run_sweep(SPEC, tmp_path / "out", workers=1, system=ssp)


@pytest.mark.parametrize("extra, fragment", [
    (["--plant", "x.fmu"], "cannot be combined with --system"),
    (["--set", "lateral.nosuch=1"], "lateral.nosuch"),
    (["--set", "nobody.K[1,1]=1"], "nobody"),
    (["--set", "lateral_controller.limit_enabled=maybe"],
     "lateral_controller.limit_enabled = 'maybe': a Boolean takes true, false, 1 or 0"),
])
def test_cli_sweep_system_bad_input(built_fmus, tmp_path, capsys, extra, fragment):
    out = tmp_path / "out"
    code = main(["sweep", "--system", str(built_fmus["DroneFlyHover.ssp"]), "--out", str(out),
                 "--disturbances", "directions", "--amplitudes", "1", "--no-plot",
                 "--no-progress", *extra])
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.count("\n") == 1 and fragment in err and "Traceback" not in err
    assert not out.exists()


def test_cli_sweep_system_missing_file(tmp_path, capsys):
    code = main(["sweep", "--system", str(tmp_path / "none.ssp"), "--out", str(tmp_path / "o"),
                 "--no-plot", "--no-progress"])
    err = capsys.readouterr().err
    assert code == 2 and "does not exist" in err and err.count("\n") == 1
